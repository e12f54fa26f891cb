"""Discretisation layer: the nodal + bubble displacement space and its local operators."""

from .operators import Operators
from .space import DisplacementSpace

__all__ = ["DisplacementSpace", "Operators"]
