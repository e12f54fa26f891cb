"""One small interface for sparse linear solves, with pluggable backends.

Backends
--------
``superlu``  scipy's SuperLU (always available; fine in 2D and for small 3D systems).
``pardiso``  Intel MKL PARDISO through pypardiso (extra ``fast``); the 3D direct default.
``amg``      pyamg smoothed aggregation (optionally with a near-nullspace such as rigid-body
             modes) preconditioning CG (symmetric) or GMRES (extra ``amg``).
``block-amg`` for contact Newton systems: GMRES preconditioned by AMG on the condensed
             displacement block (:mod:`.block_contact`), built by :mod:`.factory` from the model's
             block problem.
``petsc``    PETSc through petsc4py (extra ``mpi`` + Debian's petsc4py, docs/parallel.md): CG
             (symmetric) or GMRES with GAMG or BoomerAMG, tuned by PETSc options
             (``petsc_options``); on N ranks each rank passes its rows (:mod:`.petsc`).
``block-direct`` as ``block-amg`` with the condensed displacement block factorised (PARDISO when
             installed, else SuperLU) instead of AMG: on the flat cells of corner-point grids AMG
             on that block costs 5× the GMRES iterations (docs/iterative_cornerpoint.md). Coupled
             models only; a mechanics-only model solves directly.
``block-petsc`` the block preconditioners of ``block-amg`` in PETSc (multipliers condensed by
             polypore, :mod:`.petsc_condensed`, or PCFIELDSPLIT, :mod:`.petsc_fieldsplit`); built
             by :mod:`.factory`.
``auto``     pardiso if installed, else superlu; for coupled 3D systems the setup may pick a block
             solver instead (:func:`polypore.setup.poromechanics.resolve_linear`).

In Newton's loops only the block backends take per-iteration targets (row weights and the
Eisenstat–Walker forcing term, :mod:`.newton`); ``rtol`` is then their tolerance outside Newton
(and with ``solver.forcing = "fixed"``). Direct backends solve to round-off in any case.
"""

from __future__ import annotations

import contextlib
import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..core import live
from ..core.interruptible import interruptible
from ..core.errors import InputError, RunError
from ..core.memory import trim_heap
from ..core.timing import SPLIT
from .interface import SolverDefaults

log = logging.getLogger("polypore")

BACKENDS = ("auto", "superlu", "pardiso", "amg", "block-amg", "block-direct", "petsc", "block-petsc")
BLOCK_BACKENDS = ("block-amg", "block-direct", "block-petsc")      # built from a model's block problem


def release_solver(solver) -> None:
    """Free a solver's matrices and preconditioner set-ups (its ``release``: the PETSc solvers';
    the others hold nothing to free) and return the freed heap, once no solve follows. On N ranks every
    rank calls this at the same point, so the collective destroys happen while PETSc runs: a
    block-petsc solver left to the interpreter's teardown was destroyed after PETSc's finalisation
    and crashed a 2-rank static run at exit."""
    solver.release()
    trim_heap()


def resolve_backend(backend: str, petsc_options=None) -> tuple[str, dict | None]:
    """(backend, petsc_options) as they run here: under mpiexec the PETSc counterpart
    (:func:`distributed_backend`), "auto" as "pardiso" when installed else "superlu". Raises
    InputError("backend") for an unknown backend or one whose optional extra is missing."""
    if backend not in BACKENDS:
        raise InputError("backend", f"unknown linear solver {backend!r}; allowed: {', '.join(BACKENDS)}")
    from ..parallel.context import context

    if context() is not None:
        backend, petsc_options = distributed_backend(backend, petsc_options)
    if backend == "auto":
        backend = "pardiso" if have_pardiso() else "superlu"
    if backend == "pardiso" and not have_pardiso():
        raise InputError("backend", "'pardiso' needs the optional extra: pip install 'polypore[fast]'")
    if backend in ("amg", "block-amg", "block-direct"):
        try:
            import pyamg  # noqa: F401
        except ImportError:
            raise InputError("backend", "'amg' needs the optional extra: pip install 'polypore[amg]'") from None
    if backend in ("petsc", "block-petsc"):
        from .petsc import petsc

        petsc()                 # InputError with the install route when petsc4py is missing
    return backend, petsc_options


def distributed_backend(backend: str, petsc_options=None) -> tuple[str, dict | None]:
    """Under mpiexec (docs/parallel.md): the PETSc counterpart of a backend. The direct ones (auto,
    superlu, pardiso) become MUMPS's distributed LU, ``amg`` the ``petsc`` backend, ``block-amg``
    and ``block-direct`` ``block-petsc``; the [solver.petsc] table still applies on top."""
    was = backend
    if was in ("auto", "superlu", "pardiso"):
        backend = "petsc"
        opts = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps", **(petsc_options or {})}
        petsc_options = type(petsc_options)(opts) if isinstance(petsc_options, dict) else opts
    elif was == "amg":
        backend = "petsc"
    elif was in ("block-amg", "block-direct"):
        backend = "block-petsc"
    if was != backend:
        log.debug("distributed run: linear solver %r runs as %r", was, backend)
    return backend, petsc_options


@contextlib.contextmanager
def repeatable_random(seed: int = 0):
    """NumPy's global generator seeded while the block runs, restored afterwards.

    pyamg draws the start vectors of its spectral-radius estimates (smoother weights, prolongator
    smoothing) from ``np.random``: two set-ups of one matrix gave preconditioners differing by up
    to 1e-3, hence Newton histories that differed between identical runs. Seeding makes every
    AMG set-up a function of its matrix alone, without touching the caller's random stream.
    """
    state = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(state)


def have_pardiso() -> bool:
    try:
        import pypardiso  # noqa: F401
    except Exception:
        return False
    return True


def pardiso_solves(linear: str | None) -> bool:
    """Whether systems of a run with ``solver.linear = linear`` go to PARDISO ("auto" or "pardiso",
    pypardiso installed; None: the default "auto")."""
    return linear in (None, "auto", "pardiso") and have_pardiso()


@dataclass
class SolveStats:
    """Counters of one solver object: calls, seconds, Krylov iterations of the last solve."""

    calls: int = 0
    seconds: float = 0.0
    iterations: list = field(default_factory=list)


@dataclass
class LinearSolver(SolverDefaults):
    """Solve A x = b for sparse A (csr/csc), b of shape (n,) or (n, k).

    Parameters
    ----------
    backend : one of BACKENDS but the block ones (those :mod:`.factory` builds for a model)
    symmetric : bool
        The matrix is symmetric (CG instead of GMRES for ``amg``).
    rtol : float
        Relative residual tolerance of iterative backends.
    near_nullspace : (n, k) array or None
        Near-nullspace vectors for AMG (rigid-body modes for elasticity).
    petsc_options : mapping or None
        PETSc options (``[solver.petsc]``: ``{"pc_type": "hypre", ...}``) of the PETSc backends.
    """

    backend: str = "auto"
    symmetric: bool = False
    rtol: float = 1e-10
    maxiter: int = 500
    near_nullspace: np.ndarray | None = None
    stats: SolveStats = field(default_factory=SolveStats)
    petsc_options: dict | None = None
    layouts: dict | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if self.backend in BLOCK_BACKENDS:
            raise InputError("backend", f"{self.backend!r} is a block solver: polypore.solvers.factory builds it "
                             "from a model's block problem")
        self.backend, self.petsc_options = resolve_backend(self.backend, self.petsc_options)

    @property
    def krylov_iterations(self) -> list[int]:
        return self.stats.iterations

    def solve(self, A, b) -> np.ndarray:
        """x (n,) or (n, k) with A x = b: A (n, n) sparse, or on N ranks this rank's rows
        (:class:`~polypore.parallel.layout.OwnedRows`, the ``petsc`` backend only); b replicated."""
        t0 = time.perf_counter()
        from ..parallel.layout import OwnedRows

        if not isinstance(A, OwnedRows):
            A = sp.csr_matrix(A)
        b = np.asarray(b, float)
        if isinstance(A, OwnedRows) and self.backend != "petsc":
            raise InputError("backend", f"{self.backend!r} cannot take a distributed matrix (docs/parallel.md)")
        if self.backend == "superlu":
            x = self._superlu(A, b)
        elif self.backend == "pardiso":
            import pypardiso

            with SPLIT.timed("preconditioner", "factorising and solving (PARDISO)"):   # in one call
                try:
                    x = interruptible(pypardiso.spsolve, A, b)
                finally:
                    # pypardiso's module-level solver keeps the factors and a copy of A for a repeat
                    # of the same matrix, which Newton iterations never give: the mechanics-only
                    # initial equilibrium's factors stayed resident through whole coupled runs
                    # (about half the study's peak, docs/iterative_cornerpoint.md)
                    pypardiso.scipy_aliases.pypardiso_solver.free_memory(everything=True)
        elif self.backend == "amg":
            x = self._amg(A, b)
        else:
            x = self._petsc(A, b)
        if not np.all(np.isfinite(x)):
            raise RunError("the linear system is singular (the solution has NaN/Inf): check that every part of the "
                           "body is held (Dirichlet conditions) and that the contact data are consistent")
        self.stats.calls += 1
        self.stats.seconds += time.perf_counter() - t0
        return x

    def _superlu(self, A, b):
        try:
            # a symmetric pattern orders better with minimum degree on A^T + A (4x less fill on
            # the 3D HFV face systems than COLAMD)
            with SPLIT.timed("preconditioner", "factorising (SuperLU)"):
                lu = interruptible(spla.splu, A.tocsc(), permc_spec="MMD_AT_PLUS_A" if self.symmetric else "COLAMD")
        except RuntimeError as exc:
            raise RunError(f"the linear system is singular ({exc}): check the Dirichlet conditions and the "
                           "data") from None
        with SPLIT.timed("krylov", "triangular solves"):
            return interruptible(lu.solve, b)

    def _petsc(self, A, b):
        from ..parallel.layout import OwnedRows, layout_for

        n = A.shape[0]
        layout = A.layout if isinstance(A, OwnedRows) else layout_for(self, n)   # None in a serial run
        solvers = self.__dict__.setdefault("_petsc_solvers", {})
        solver = solvers.get(n)
        if solver is None:
            from .petsc import PetscLinearSolver

            B = self.near_nullspace if self.near_nullspace is not None and len(self.near_nullspace) == n else None
            if B is not None and layout is not None:
                B = layout.local(B)
            solver = solvers[n] = PetscLinearSolver(symmetric=self.symmetric, rtol=self.rtol, maxiter=self.maxiter,
                                                    near_nullspace=B, options=self.petsc_options)
        k = len(solver.iterations)
        if layout is None:
            x = solver.solve(A, b)
        else:
            rows = A.rows if isinstance(A, OwnedRows) else layout.rows(A)
            x = layout.gather(solver.solve(rows, layout.local(b)))
        self.stats.iterations.extend(solver.iterations[k:])
        return x

    def _amg(self, A, b):
        import pyamg

        B = self.near_nullspace
        with repeatable_random(), SPLIT.timed("preconditioner", "AMG set-up"):
            ml = pyamg.smoothed_aggregation_solver(A, B=B, strength="evolution" if B is not None else "symmetric",
                                                   max_coarse=500)
        M = ml.aspreconditioner(cycle="V")
        its = [0]

        def cb(_):
            its[0] += 1
            live.krylov_iteration()

        cols = b.reshape(len(b), -1)
        out = np.empty_like(cols)
        for j in range(cols.shape[1]):
            its[0] = 0
            krylov = spla.cg if self.symmetric else spla.gmres
            kw = {"restart": 100} if not self.symmetric else {}
            with SPLIT.timed("krylov"):
                x, info = krylov(A, cols[:, j], rtol=self.rtol, maxiter=self.maxiter, M=M, callback=cb, **kw)
            if info != 0:
                raise RunError(f"the iterative solver did not reach rtol={self.rtol:g} in {self.maxiter} iterations")
            out[:, j] = x
            self.stats.iterations.append(its[0])
        return out.reshape(b.shape)


def rigid_body_modes(points: np.ndarray) -> np.ndarray:
    """(d*n, 3 or 6) rigid motions of points (n, d), components interleaved (x0, y0, [z0], x1, ...)."""
    n, d = points.shape
    c = points - points.mean(0)
    if d == 2:
        B = np.zeros((n, 2, 3))
        B[:, 0, 0] = 1
        B[:, 1, 1] = 1
        B[:, 0, 2] = -c[:, 1]
        B[:, 1, 2] = c[:, 0]
    else:
        B = np.zeros((n, 3, 6))
        B[:, 0, 0] = B[:, 1, 1] = B[:, 2, 2] = 1
        x, y, z = c.T
        B[:, 0, 3], B[:, 1, 3] = -y, x
        B[:, 1, 4], B[:, 2, 4] = -z, y
        B[:, 0, 5], B[:, 2, 5] = z, -x
    return B.reshape(n * d, -1)
