"""What every linear solver offers Newton and the models, and the options the block solvers share.

:class:`LinearSystemSolver` is the protocol: the direct and AMG backends of
:class:`~.linear.LinearSolver`, the block solvers (:mod:`.block_contact`, :mod:`.petsc_fieldsplit`)
and :class:`~.petsc.PetscLinearSolver` satisfy it, so callers use its members instead of probing
for attributes. :class:`SolverDefaults` gives the members' plain values (an assembled matrix, no
Newton target, nothing to free); :class:`BlockOptions` the GMRES and preconditioner settings of the
four block solvers, which they inherit (keyword-only, each class keeping its own defaults).
:mod:`.factory` turns a case's choice into a ready solver.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:
    from .petsc import ReusePolicy


@runtime_checkable
class LinearSystemSolver(Protocol):
    """A solver of the linear systems of Newton's iterations (or of a linear model).

    Members
    -------
    backend : the ``solver.linear`` value it implements ("superlu", "block-amg", …)
    takes_blocks : ``solve`` accepts a :class:`~.block_jacobian.BlockJacobian` (the model then
        assembles no matrix)
    takes_target : ``solve`` accepts ``target=``, Newton's :class:`~.newton.KrylovTarget` (row
        weights, forcing term)
    krylov_iterations : Krylov iterations of each solve so far (empty for direct solves)
    solve(A, b) : x (n,) with A x ≈ b; A (n, n) sparse (or blocks / this rank's rows, see above)
    release() : free matrices and preconditioner set-ups; a later solve builds them again
    set_pressure_nullspace(b) : the near-null space (n_p,) of the pressure block of the coming
        systems (coupled block solvers; the others ignore it)
    """

    @property
    def backend(self) -> str: ...

    @property
    def takes_blocks(self) -> bool: ...

    @property
    def takes_target(self) -> bool: ...

    @property
    def krylov_iterations(self) -> list[int]: ...

    def solve(self, A, b) -> np.ndarray: ...

    def release(self) -> None: ...

    def set_pressure_nullspace(self, b: np.ndarray | None) -> None: ...


class SolverDefaults:
    """The protocol's members but ``backend`` and ``solve`` for a solver of assembled matrices
    without Newton targets, holding nothing to free and counting no Krylov iterations (subclasses
    override what differs)."""

    takes_blocks = False
    takes_target = False

    @property
    def krylov_iterations(self) -> list[int]:
        return []

    def release(self) -> None:
        """Nothing to free."""

    def set_pressure_nullspace(self, b) -> None:
        """No pressure block."""


@dataclass(kw_only=True)
class BlockOptions:
    """GMRES and preconditioner settings shared by the block solvers (keyword-only).

    The defaults are the contact solvers'; :class:`~.block_contact.BlockPoroSolver` takes
    ``maxiter = 400``, ``accept_rtol = 1e-4`` and :class:`~.petsc_fieldsplit.PetscBlockPoroSolver`
    ``maxiter = 400``. A field a class does not use is ignored by it (``mechanics`` by the PETSc
    solvers, ``amg``/``options``/``reuse`` by the SciPy ones, ``pressure`` by the contact ones).

    Parameters
    ----------
    rtol : GMRES relative residual outside Newton's targets
    maxiter : cap on the inner iterations of one solve
    restart : the largest GMRES restart (:func:`~.block_contact.krylov_restart`)
    accept_rtol : relative residual still returned when rtol is not reached (round-off floor)
    mechanics : "amg" or "direct" (the condensed displacement block S factorised), SciPy solvers
    pressure : the Ŝ_p solve of the coupled solvers (see each class)
    amg : "hypre" or "gamg", the PETSc solvers' AMG on the displacement block
    options : PETSc options without prefix (the PETSc solvers)
    reuse : :class:`~.petsc.ReusePolicy` of the PETSc preconditioner across Newton iterations
    """

    rtol: float = 1e-8
    maxiter: int = 300
    restart: int = 100
    accept_rtol: float = 1e-6
    mechanics: str = "amg"
    pressure: str = "auto"
    amg: str = "hypre"
    options: Mapping | None = None
    reuse: ReusePolicy = field(default_factory=lambda: _default_reuse())


def _default_reuse() -> ReusePolicy:
    from .petsc import ReusePolicy            # petsc.py's solver takes SolverDefaults from here

    return ReusePolicy()
