"""The case's linear-solver choice (``[solver]`` linear, linear_tolerance, petsc) for
:mod:`polypore.solvers.factory`, with the solvers' errors named by their case-file keys."""

from __future__ import annotations

from ..solvers.factory import SolverChoice
from .translate import SOLVER, case_keys


def solver_choice(linear: str, **kw) -> SolverChoice:
    """``SolverChoice(linear, **kw)`` (resolved for this install and run); an InputError names
    ``solver.linear`` or ``solver.petsc``."""
    with case_keys(SOLVER):
        return SolverChoice(linear, **kw)
