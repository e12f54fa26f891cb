"""Solvers: the linear-solver interface and the semi-smooth Newton loop (no physics here)."""
