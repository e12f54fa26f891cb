"""Exceptions that map to the command line's exit statuses (interface.md).

``InputError`` (exit 2) is raised once, at the boundary, for anything the user
can fix; its message names the field, the bad value and what is allowed.
``RunError`` (exit 1) is raised when a well-posed run fails (no convergence).
"""

from __future__ import annotations


class PolyporeError(Exception):
    """Base class of polypore's own errors."""

    exit_status = 1


class InputError(PolyporeError, ValueError):
    """Bad user input: a case file, a mesh file, an option (exit status 2).

    Parameters
    ----------
    field : str
        Dotted name of the offending input (``"fractures.F1.vertices"``).
    message : str
        What is wrong and what is allowed.
    """

    exit_status = 2

    def __init__(self, field: str, message: str):
        self.field = field
        self.detail = message
        super().__init__(f"{field}: {message}" if field else message)


class MeshError(InputError):
    """A mesh that cannot be used: degenerate cells, non-conforming fractures."""


class RunError(PolyporeError):
    """A run that failed after its input was accepted (exit status 1)."""

    # what a failed attempt cost, set (when known) by the Newton loop and the model that gave up;
    # read with getattr by runs/march.py
    newton_iterations: int | None
    linear_iterations: int | None
