"""The one place where a linear-solver choice becomes a solver.

The set-up turns ``[solver]`` into a :class:`SolverChoice` (resolved for this install and run:
"auto" as PARDISO or SuperLU, the PETSc counterparts under mpiexec). A model receives either a
ready solver (:class:`~.interface.LinearSystemSolver`) or a choice, and turns a choice into a
solver once, with :func:`build`: the plain backends directly, the block backends from the small
:class:`BlockProblem` the model describes itself with (sizes, contact condensation, rigid-body
modes, pressure groups). The coupled model's auxiliary solvers (its initial equilibrium and its
flow model) come from :func:`coupled_solvers`. No model looks at a backend name.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable, Union

import numpy as np

from ..core.errors import InputError
from .interface import LinearSystemSolver
from .linear import BLOCK_BACKENDS, LinearSolver, resolve_backend

if TYPE_CHECKING:
    from .block_contact import ContactCondensation


@dataclass(frozen=True)
class SolverChoice:
    """A linear-solver choice (``[solver]``: linear, linear_tolerance, petsc), resolved on creation.

    Parameters
    ----------
    backend : one of :data:`~.linear.BACKENDS`; after creation the backend that runs here
    symmetric : the matrices are symmetric (CG instead of GMRES for the plain iterative backends)
    rtol : relative tolerance of the plain iterative backends; a block contact solver takes it
        when below 1e-6 (else 1e-8)
    maxiter : iteration cap of the plain iterative backends
    petsc_options : PETSc options of the PETSc backends (name -> value) or None
    """

    backend: str = "auto"
    symmetric: bool = False
    rtol: float = 1e-10
    maxiter: int = 500
    petsc_options: dict | None = None

    def __post_init__(self):
        backend, options = resolve_backend(self.backend, self.petsc_options)
        object.__setattr__(self, "backend", backend)
        object.__setattr__(self, "petsc_options", options)

    @property
    def block(self) -> bool:
        """A block backend: built from a model's :class:`BlockProblem`."""
        return self.backend in BLOCK_BACKENDS


@dataclass(frozen=True)
class BlockProblem:
    """What a block solver needs of its model (plain data).

    Parameters
    ----------
    n_free : free displacement unknowns (the first block)
    dim : space dimension (the multipliers' block size)
    n_multipliers : multiplier unknowns (patches × dim)
    condensation : :class:`~.block_contact.ContactCondensation` of the contact rows
    near_nullspace : (n_free, 3 or 6) rigid-body modes of the free displacement unknowns
    pressure_groups : coupled problems only, ((n_p,) bool, (n_p,) bool): the two-level pressure
        preconditioner's coarse unknowns and its smoother's fracture subsystem; None for contact
    coupled : the system has pressure unknowns after the multipliers
    """

    n_free: int
    dim: int
    n_multipliers: int
    condensation: ContactCondensation
    near_nullspace: np.ndarray | None
    pressure_groups: tuple | None = None
    coupled: bool = False


# the coupled model's flow solver for a block backend (coupled_solvers)
FLOW_BACKENDS = {"block-amg": "amg", "block-petsc": "petsc", "block-direct": "auto"}

# what a model accepts as its solver: a ready one, a choice (built by the model's problem) or None
SolverSource = Union[LinearSystemSolver, SolverChoice, None]


def linear_solver(choice: SolverChoice) -> LinearSolver:
    """The ready solver of a plain (non-block) choice."""
    if choice.block:
        raise InputError("backend", f"{choice.backend!r} is a block solver: it needs a model's block problem "
                         "(contact mechanics or the coupled model)")
    return LinearSolver(choice.backend, symmetric=choice.symmetric, rtol=choice.rtol, maxiter=choice.maxiter,
                        petsc_options=choice.petsc_options)


def block_solver(choice: SolverChoice, problem: BlockProblem) -> LinearSystemSolver:
    """The block solver of ``choice`` (block-amg, block-direct, block-petsc) for ``problem``.

    Contact: GMRES to ``choice.rtol`` when below 1e-6 (else 1e-8); coupled: the solvers' own
    defaults (:class:`~.interface.BlockOptions`). The coupled PETSc solver reads ``petsc_options``
    as given (every name must be used), the others as given too."""
    direct = "direct" if choice.backend == "block-direct" else "amg"
    p = problem
    if p.coupled:
        if choice.backend == "block-petsc":
            from .petsc_fieldsplit import PetscBlockPoroSolver

            return PetscBlockPoroSolver(p.n_free, p.dim, p.n_multipliers, p.condensation,
                                        near_nullspace=p.near_nullspace, options=choice.petsc_options)
        from .block_contact import BlockPoroSolver

        return BlockPoroSolver(p.n_free, p.dim, p.n_multipliers, p.condensation, near_nullspace=p.near_nullspace,
                               mechanics=direct, pressure_groups=p.pressure_groups)
    rtol = choice.rtol if choice.rtol < 1e-6 else 1e-8
    if choice.backend == "block-petsc":
        from .petsc_fieldsplit import PetscBlockContactSolver

        return PetscBlockContactSolver(p.n_free, p.dim, p.condensation, near_nullspace=p.near_nullspace, rtol=rtol,
                                       options=choice.petsc_options)
    from .block_contact import BlockContactSolver

    return BlockContactSolver(p.n_free, p.dim, p.condensation, near_nullspace=p.near_nullspace, rtol=rtol,
                              mechanics=direct)


def build(source: SolverSource, problem: Callable[[], BlockProblem] | None = None,
          default: SolverChoice | None = None) -> LinearSystemSolver:
    """A ready solver from what a model was given: ``source`` itself when it is a solver; for a
    choice (``default``, or ``SolverChoice()``, when None) its plain solver or its block solver
    for ``problem()`` (called only then)."""
    if source is None:
        source = default if default is not None else SolverChoice()
    if not isinstance(source, SolverChoice):
        return source
    if source.block:
        if problem is None:
            raise InputError("backend", f"{source.backend!r} applies to contact mechanics and the coupled model "
                             "only")
        return block_solver(source, problem())
    return linear_solver(source)


@dataclass(frozen=True)
class CoupledSolvers:
    """The coupled model's solvers: ``coupled`` for its steps, ``mechanics`` for its initial
    equilibrium, ``flow`` for its flow model (each ready, or a choice its model builds)."""

    coupled: SolverSource
    mechanics: SolverSource
    flow: SolverSource


def coupled_solvers(source: SolverSource) -> CoupledSolvers:
    """The solvers of the coupled model for ``source`` (a choice, a ready solver or None: "auto").

    The auxiliary ones take the [solver.petsc] table too, but only the coupled solver insists that
    PETSc reads every name (``fieldsplit_m_*`` exists in the coupled fieldsplit only): they get it
    shared (:func:`~.petsc.shared`). With a block backend the flow model gets a plain one
    (:data:`FLOW_BACKENDS`); otherwise the initial equilibrium and the flow model share the
    auxiliary solver (one object, for a plain backend the coupled solver itself). The flow model
    of the coupled model assembles only (its solver never solves): with block-direct it gets the
    direct default."""
    from .petsc import shared

    if source is None:
        source = SolverChoice()
    if isinstance(source, SolverChoice):
        backend, options = source.backend, source.petsc_options
        if not source.block:
            source = linear_solver(source)
    elif isinstance(source, LinearSolver):
        backend, options = source.backend, source.petsc_options
    else:                                   # a ready solver of another kind: the default aside it
        return CoupledSolvers(source, SolverChoice(), SolverChoice(symmetric=True))
    aux = source if options is None else replace(source, petsc_options=shared(options))
    flow = aux
    if backend in BLOCK_BACKENDS:
        flow = linear_solver(SolverChoice(FLOW_BACKENDS[backend], symmetric=True, petsc_options=shared(options)))
    return CoupledSolvers(source, aux, flow)
