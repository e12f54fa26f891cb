"""Discretisation layer: the displacement spaces (nodal + bubble; P2 on simplices) and their operators."""

from .operators import Operators
from .quadratic import QuadraticOperators, QuadraticSpace
from .space import DisplacementSpace

__all__ = ["DisplacementSpace", "Operators", "QuadraticOperators", "QuadraticSpace"]
