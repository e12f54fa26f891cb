"""PETSc linear solvers through petsc4py (optional: ``polypore[mpi]`` plus Debian's petsc4py, docs/parallel.md).

Matrices arrive as SciPy CSR rows owned by this rank (all rows on one rank) and become PETSc AIJ
matrices with explicit (local, global) sizes, so the same code runs on one or N ranks: rank r owns
the contiguous rows [start_r, start_r + n_r) in rank order, n_r being the number of rows it passes.

Options are PETSc's own: a mapping ``{"ksp_type": "cg", "pc_gamg_threshold": 0.02, ...}`` (the
``[solver.petsc]`` table; names with or without the leading ``-``) is put into PETSc's options
database under the solver's prefix while the solver sets up and solves, on top of polypore's
defaults. Options given on PETSc's command line or in ``PETSC_OPTIONS`` (with the prefix, e.g.
``-poro_ksp_monitor``) win over both, as PETSc users expect. A name that PETSc did not use (a typo,
or an option of a preconditioner that is not selected) is an :class:`InputError`.

Preconditioner set-up is reused across solves (Newton iterations) by :class:`ReusePolicy`: rebuilt
after ``max_age`` solves, when the Krylov iterations grow past ``growth`` × those of the first
solve after the last rebuild, and at once (the solve repeated) when a solve with a stale
preconditioner fails.
"""

from __future__ import annotations

import ctypes
import logging
import resource
import time
from collections.abc import Mapping
from typing import Any
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..core.errors import InputError, RunError
from ..core.timing import SPLIT
from .interface import SolverDefaults

log = logging.getLogger("polypore")

FIELD = "petsc_options"
INSTALL = ("the PETSc backends need petsc4py and mpi4py, which polypore takes from Debian "
           "(apt-get install python3-petsc4py python3-mpi4py) in a venv with numpy<2: run `make test-mpi` "
           "once, then use .venv-mpi/bin/polypore (docs/parallel.md)")

# options whose value PETSc checks against a list of names: checked here first, so that the error
# names the option and what is allowed instead of PETSc's "Unknown type" with a traceback
_CHOICES = {
    "ksp_type": lambda P: _names(P.KSP.Type),
    "pc_type": lambda P: _names(P.PC.Type),
    "pc_gamg_type": lambda P: ("agg", "geo", "classical"),
    "pc_hypre_type": lambda P: ("boomeramg", "pilut", "parasails", "euclid", "ams", "ads"),
    "pc_fieldsplit_type": lambda P: ("additive", "multiplicative", "symmetric_multiplicative", "special", "schur",
                                     "gkb"),
    "pc_fieldsplit_schur_fact_type": lambda P: ("diag", "lower", "upper", "full"),
    "pc_fieldsplit_schur_precondition": lambda P: ("self", "selfp", "a11", "user", "full"),
}


def _names(cls) -> tuple:
    return tuple(sorted(str(v) for k, v in vars(cls).items() if k.isupper() and isinstance(v, str)))


def have_petsc() -> bool:
    """Whether petsc4py (and so PETSc) can be imported."""
    try:
        import petsc4py  # noqa: F401
    except ImportError:
        return False
    return True


def petsc():
    """The ``petsc4py.PETSc`` module; InputError with the install route when it is missing."""
    try:
        from petsc4py import PETSc
    except ImportError:
        raise InputError("backend", INSTALL) from None
    return PETSc


def peak_memory_mb() -> float:
    """Peak resident memory of this process (this rank), MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# ---- distributed layout ------------------------------------------------------------------------
def comm_world():
    """PETSc's COMM_WORLD (all ranks of ``mpiexec``; one rank otherwise)."""
    return petsc().COMM_WORLD


def owned_range(n: int, comm=None, bs: int = 1) -> tuple[int, int]:
    """PETSc's default split of n rows over the ranks of comm, in whole blocks of bs: (start, end)."""
    P = petsc()
    comm = comm or P.COMM_WORLD
    size, rank = comm.getSize(), comm.getRank()
    nb = n // bs
    counts = [(nb // size + (r < nb % size)) * bs for r in range(size)]
    counts[-1] += n - nb * bs
    start = sum(counts[:rank])
    return start, start + counts[rank]


def _row_start(n_local: int, comm) -> tuple[int, int]:
    """(first global row of this rank, global row count) for contiguous rows in rank order."""
    m = comm.tompi4py()
    return int(m.exscan(n_local) or 0), int(m.allreduce(n_local))


def aij(A_rows, comm=None, bs: int = 1, mat=None):
    """PETSc AIJ matrix from the CSR rows this rank owns (global column indices).

    Parameters
    ----------
    A_rows : scipy.sparse matrix (n_local, n_global)
        Rows [start, start + n_local) of the global matrix, start = the row counts of lower ranks.
    comm : PETSc communicator (default COMM_WORLD)
    bs : block size (interleaved dofs, e.g. d for displacements): GAMG aggregates whole blocks
    mat : PETSc.Mat or None
        A matrix built by this function for the same pattern: its values are overwritten in place
        (no new allocation, and preconditioners see the same nonzero pattern).
    """
    P = petsc()
    comm = comm or P.COMM_WORLD
    A = sp.csr_matrix(A_rows)
    A.sum_duplicates()
    A.sort_indices()
    n_local, n_global = A.shape
    _, N = _row_start(n_local, comm)
    ip, ix = A.indptr.astype(P.IntType, copy=False), A.indices.astype(P.IntType, copy=False)
    if mat is None:
        mat = P.Mat().createAIJ(((n_local, N), (n_local, n_global)), bsize=bs, comm=comm)
        mat.setPreallocationCSR((ip, ix))
        # a pattern entry that is exactly zero stays in the pattern: the preconditioners and the
        # in-place updates rely on a fixed structure
        mat.setOption(P.Mat.Option.IGNORE_ZERO_ENTRIES, False)
        mat.setOption(P.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
    mat.setValuesCSR(ip, ix, A.data.astype(P.ScalarType, copy=False), addv=False)
    mat.assemble()
    return mat


def collect_garbage(comm=None) -> None:
    """Destroy the PETSc objects that Python has let go of (collective on ``comm``).

    petsc4py ≥ 3.18 does not destroy an object on a parallel communicator when its Python
    wrapper is garbage-collected (a destroy is collective, and ranks collect in different
    orders): it waits in the communicator's garbage until ``garbage_cleanup``. Without this every
    work vector, null space and index set made per Newton iteration stayed allocated, and memory
    grew step by step (docs/parallel.md). Called at the start of
    every Krylov solve, a point every rank reaches together.
    """
    P = petsc()
    cleanup = getattr(P, "garbage_cleanup", None)
    if cleanup is not None:
        cleanup(comm or P.COMM_WORLD)


def vec(x_local, comm=None):
    """PETSc vector with this rank's part x_local (copied)."""
    P = petsc()
    comm = comm or P.COMM_WORLD
    x = np.ascontiguousarray(x_local, dtype=P.ScalarType)
    _, N = _row_start(len(x), comm)
    v = P.Vec().createMPI((len(x), N), comm=comm)
    v.setArray(x)
    return v


def near_nullspace(B_local, comm=None):
    """MatNullSpace spanned by the columns of B_local (this rank's rows), orthonormalised as PETSc
    requires (modified Gram–Schmidt over all ranks)."""
    P = petsc()
    comm = comm or P.COMM_WORLD
    B = np.asarray(B_local, float)
    B = B.reshape(len(B), -1)
    vecs = [vec(B[:, j], comm) for j in range(B.shape[1])]
    out = []
    for v in vecs:
        for q in out:
            v.axpy(-v.dot(q), q)
        nrm = v.norm()
        if nrm > 1e-12 * max(1.0, np.sqrt(v.getSize())):
            v.scale(1.0 / nrm)
            out.append(v)
    return P.NullSpace().create(constant=False, vectors=out, comm=comm)


def interleaved_block_size(B, d: int) -> int:
    """d if the translation columns of the rigid-body modes B (n, ≥ d) show whole interleaved
    blocks (x, y, [z]) of d rows (or d zero rows: bubbles), else 1."""
    if B is None or d <= 1 or len(B) % d:
        return 1
    T = np.asarray(B)[:, :d].reshape(-1, d, d)
    ok = np.all(np.isclose(T, np.eye(d)[None]), axis=(1, 2)) | np.all(T == 0, axis=(1, 2))
    return d if bool(np.all(ok)) else 1


def _mpi_max():
    from mpi4py import MPI

    return MPI.MAX


# ---- options -----------------------------------------------------------------------------------
class SharedOptions(dict):
    """A ``[solver.petsc]`` table handed to an auxiliary solver of a run as well as to its principal
    one (the contact solve of a coupled run's initial state, its flow solve). The options apply
    there too, but one the auxiliary solver does not read is no error there: it may belong to the
    principal solver's structure only (``fieldsplit_m_*`` of the coupled fieldsplit), and the
    principal solver checks every name."""


def shared(options: Mapping | None) -> SharedOptions | None:
    """``options`` marked as shared (:class:`SharedOptions`); None stays None."""
    return None if options is None else SharedOptions(options)


def petsc_options(options: Mapping | None, field_: str = FIELD) -> dict[str, str]:
    """Normalise a ``[solver.petsc]`` mapping to PETSc option names (no ``-``) → string values.

    True/None give a flag (``-ksp_view``), False ``false``; numbers their ``repr``. Values of the
    options in ``_CHOICES`` are checked against PETSc's names. Raises InputError naming the option.
    """
    out = {}
    for k, v in (options or {}).items():
        name = str(k).lstrip("-")
        where = f"{field_}.{name}"
        if not name or not all(c.isalnum() or c == "_" for c in name):
            raise InputError(where, "a PETSc option name has letters, digits and '_' only (e.g. ksp_type)")
        if isinstance(v, bool) or v is None:
            val = "" if v is None or v else "false"
        elif isinstance(v, (int, float, np.integer, np.floating)):
            val = repr(v.item() if hasattr(v, "item") else v)
        elif isinstance(v, str):
            val = v
        else:
            raise InputError(where, f"must be a string, number or boolean, got {type(v).__name__}")
        for suffix, allowed in _CHOICES.items():
            if name == suffix or name.endswith("_" + suffix):
                names = allowed(petsc())
                if val.lower() not in names:
                    raise InputError(where, f"unknown value {val!r}; allowed: {', '.join(names)}")
                val = val.lower()
        out[name] = val
    return out


class OptionScope:
    """Puts options into PETSc's database under a prefix for the duration of a ``with`` block.

    Entries already in the database (command line, ``PETSC_OPTIONS``) are kept: they win. Only the
    entries this scope added are removed afterwards, so solvers with the same prefix and different
    tables do not see each other's.
    """

    def __init__(self, prefix: str, *layers: Mapping[str, str]):
        self.prefix = prefix
        self.values: dict[str, str] = {}
        for layer in layers:
            self.values.update(layer)
        self.added: list[str] = []

    def __enter__(self):
        db = petsc().Options()
        for k, v in self.values.items():
            name = self.prefix + k
            if not db.hasName(name):
                db.setValue(name, v)
                self.added.append(name)
        return self

    def __exit__(self, *exc):
        db = petsc().Options()
        for name in self.added:
            db.delValue(name)
        self.added = []
        return False


_LIB: Any = None          # ctypes.CDLL of libpetsc, False when not found


def unused_options(names) -> list[str]:
    """Full option names (prefix included, no ``-``) that PETSc has not read so far.

    petsc4py does not wrap PetscOptionsUsed; it is called from the loaded libpetsc through ctypes.
    Returns [] when that library cannot be found (the check is then skipped).
    """
    global _LIB
    if _LIB is None:
        petsc()
        try:
            path = sorted({ln.split()[-1] for ln in open("/proc/self/maps") if "libpetsc" in ln})[0]
            _LIB = ctypes.CDLL(path)
            _LIB.PetscOptionsUsed.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
        except (OSError, IndexError, AttributeError):
            _LIB = False
    if not _LIB:
        return []
    out = []
    for n in names:
        flag = ctypes.c_int(0)
        if _LIB.PetscOptionsUsed(None, n.encode(), ctypes.byref(flag)) == 0 and not flag.value:
            out.append(n)
    return out


# ---- Krylov driver -----------------------------------------------------------------------------
@dataclass
class ReusePolicy:
    """When to rebuild a preconditioner that is reused across solves (Newton iterations).

    Parameters
    ----------
    max_age : solves with one set-up (1: rebuild for every solve, as the SciPy backends do)
    growth : rebuild when a solve takes more than growth × the iterations of the first solve after
        the last rebuild (the operator has moved away from the one the set-up was built for)
    """

    max_age: int = 1
    growth: float = 1.5

    def __post_init__(self):
        if int(self.max_age) < 1:
            raise InputError("max_age", f"must be an integer ≥ 1, got {self.max_age!r}")
        if not self.growth >= 1.0:
            raise InputError("growth", f"must be ≥ 1, got {self.growth!r}")


@dataclass
class PetscStats:
    """Counters: set-ups, their wall and CPU seconds (CPU: this process, robust on a shared machine),
    the same for the Krylov solves, seconds converting SciPy matrices, repeated solves."""

    setups: int = 0
    setup_seconds: float = 0.0
    krylov_seconds: float = 0.0
    setup_cpu: float = 0.0
    krylov_cpu: float = 0.0
    convert_seconds: float = 0.0
    retries: int = 0


class KrylovDriver:
    """One KSP with an options prefix, user options, set-up reuse and the true-residual check.

    The caller gives the operators with :meth:`operators` (``changed_pattern`` when the nonzero
    structure is new: then everything is rebuilt) and calls :meth:`solve`.
    """

    def __init__(self, prefix: str, defaults: Mapping[str, str], options: Mapping | None, reuse: ReusePolicy,
                 rtol: float, maxiter: int, accept_rtol: float, comm=None, configure=None):
        self.P = petsc()
        self.comm = comm or self.P.COMM_WORLD
        self.prefix = prefix
        self.defaults = dict(defaults)
        self.user = petsc_options(options)
        self.reuse = reuse
        # a shared table is checked by the run's principal solver, not here (SharedOptions)
        self.rtol, self.maxiter, self.accept_rtol = rtol, maxiter, accept_rtol
        self.configure = configure          # callback(ksp) after set-up (near-null spaces of sub-blocks)
        self.ksp: Any = None            # petsc4py KSP (no type stubs)
        self.age = 0
        self.base_its = None
        self.checked = isinstance(options, SharedOptions)
        self.stats = PetscStats()
        self.iterations: list[int] = []

    def _new_ksp(self):
        if self.ksp is not None:
            self.ksp.destroy()
        ksp = self.P.KSP().create(comm=self.comm)
        ksp.setOptionsPrefix(self.prefix)
        self.ksp = ksp
        self.age = 0
        self.base_its = None

    def scope(self) -> OptionScope:
        return OptionScope(self.prefix, self.defaults, self.user)

    def operators(self, A, Pmat=None, changed_pattern: bool = False):
        if self.ksp is None or changed_pattern:
            self._new_ksp()
        self.ksp.setOperators(A, A if Pmat is None else Pmat)

    def _setup(self, fresh: bool):
        ksp = self.ksp
        if fresh:
            ksp.getPC().setReusePreconditioner(False)
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                ksp.setFromOptions()
                ksp.setUp()
                if self.configure is not None:
                    self.configure(ksp)
                ksp.setUpOnBlocks()
            except self.P.Error as exc:
                raise InputError(FIELD, f"PETSc could not set up the solver with the options "
                                 f"{self._shown()} (error {exc.ierr}; run with -{self.prefix}ksp_view and "
                                 "-info for details)") from None
            self.stats.setups += 1
            self.stats.setup_seconds += time.perf_counter() - t0
            self.stats.setup_cpu += time.process_time() - c0
            SPLIT.add("preconditioner", time.perf_counter() - t0, time.process_time() - c0)
            self.age = 0
            self.base_its = None
        else:
            ksp.getPC().setReusePreconditioner(True)

    def _shown(self) -> str:
        return ", ".join(f"-{self.prefix}{k} {v}".strip() for k, v in {**self.defaults, **self.user}.items()) or "none"

    def solve(self, b, x, residual, rebuild: bool = False) -> int:
        """Solve into x; ``residual(x)`` gives the true relative residual; ``rebuild`` forces a new
        preconditioner set-up. Returns the iterations."""
        collect_garbage(self.comm)
        with self.scope():
            fresh = rebuild or self.age == 0 or self.age >= self.reuse.max_age or (
                self.base_its is not None and self.iterations and
                self.iterations[-1] > self.reuse.growth * max(self.base_its, 1))
            self._setup(fresh or self.stats.setups == 0)
            its, res, ok = self._krylov(b, x, residual)
            if not ok and not fresh:
                # a stale preconditioner failed: rebuild it and solve again from zero
                self.stats.retries += 1
                log.debug("PETSc solver %r: reused preconditioner failed (%d iterations, residual %.2e); rebuilt",
                          self.prefix, its, res)
                self._setup(True)
                x.set(0.0)
                its2, res, ok = self._krylov(b, x, residual)
                its += its2
            if not self.checked:
                self._check_used()
        self.age += 1
        if self.base_its is None:
            self.base_its = its
        self.iterations.append(its)
        if not ok:
            raise RunError(f"the PETSc Krylov solver ({self.ksp.getType()}) did not reach rtol={self.rtol:g}: "
                           f"{its} iterations, converged reason {self.last_reason}, true relative residual "
                           f"{res:.2e}; raise ksp_max_it ([solver.petsc] in a case file) or choose another "
                           "preconditioner (docs/parallel.md)")
        return its

    def _krylov(self, b, x, residual):
        ksp = self.ksp
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            ksp.solve(b, x)
        except self.P.Error as exc:
            raise RunError(f"PETSc failed in the Krylov solve (error {exc.ierr}) with options {self._shown()}") \
                from None
        self.stats.krylov_seconds += time.perf_counter() - t0
        self.stats.krylov_cpu += time.process_time() - c0
        SPLIT.add("krylov", time.perf_counter() - t0, time.process_time() - c0)
        its = ksp.getIterationNumber()
        reason = ksp.getConvergedReason()
        res = residual(x)
        rtol = ksp.getTolerances()[0]
        self.last_reason = reason
        if not np.isfinite(res):
            ok = False
        elif reason > 0 and ksp.getNormType() != self.P.KSP.NormType.UNPRECONDITIONED:
            ok = True                                   # the user's norm (e.g. MINRES's): PETSc's verdict
        else:
            # GMRES's residual estimate can fall below rtol while the true residual stays at a
            # round-off floor (block_contact._gmres): accept up to accept_rtol, as the SciPy path does
            ok = res <= max(10.0 * rtol if reason > 0 else rtol, self.accept_rtol)
        return its, res, bool(ok)

    def _check_used(self):
        self.checked = True
        bad = unused_options([self.prefix + k for k in self.user])
        if bad:
            names = ", ".join(n[len(self.prefix):] for n in bad)
            raise InputError(f"{FIELD}.{bad[0][len(self.prefix):]}",
                             f"PETSc did not use the option(s) {names}: not a PETSc option name, or one of a "
                             f"method that is not selected (check ksp_type/pc_type; -{self.prefix}help lists them)")

    def destroy(self):
        if self.ksp is not None:
            self.ksp.destroy()
            self.ksp = None


def krylov_defaults(symmetric: bool, rtol: float, maxiter: int, restart: int = 100) -> dict[str, str]:
    """KSP options of the SciPy paths: CG, or right-preconditioned GMRES whose residual is the true
    one (so rtol means ‖b − Ax‖ ≤ rtol ‖b‖ as in block_contact._gmres)."""
    base = {"ksp_rtol": repr(rtol), "ksp_atol": "0", "ksp_max_it": str(int(maxiter))}
    if symmetric:
        return {"ksp_type": "cg", "ksp_norm_type": "unpreconditioned", **base}
    return {"ksp_type": "gmres", "ksp_pc_side": "right", "ksp_gmres_restart": str(int(restart)),
            "ksp_gmres_modifiedgramschmidt": "", **base}


def amg_defaults(kind: str = "gamg", prefix: str = "", nullspace: bool = True) -> dict[str, str]:
    """Options of one AMG preconditioner for elasticity-like (nullspace) or scalar blocks.

    ``gamg``: smoothed aggregation, one prolongator smoothing, Chebyshev/Jacobi smoothers.
    ``hypre``: BoomerAMG, HMIS coarsening and ext+i interpolation; with ``nullspace`` (a vector
    field: elasticity) nodal coarsening of the block-size blocks.
    """
    p = prefix
    if kind == "gamg":
        out = {f"{p}pc_type": "gamg", f"{p}pc_gamg_type": "agg", f"{p}pc_gamg_agg_nsmooths": "1",
               f"{p}pc_gamg_threshold": "0.01", f"{p}pc_gamg_coarse_eq_limit": "1000",
               f"{p}mg_levels_ksp_type": "chebyshev", f"{p}mg_levels_pc_type": "jacobi",
               f"{p}mg_levels_ksp_max_it": "2"}
        return out
    if kind == "hypre":
        out = {f"{p}pc_type": "hypre", f"{p}pc_hypre_type": "boomeramg",
               f"{p}pc_hypre_boomeramg_coarsen_type": "HMIS", f"{p}pc_hypre_boomeramg_interp_type": "ext+i",
               f"{p}pc_hypre_boomeramg_P_max": "4", f"{p}pc_hypre_boomeramg_agg_nl": "1",
               f"{p}pc_hypre_boomeramg_strong_threshold": "0.5" if nullspace else "0.25"}
        if nullspace:
            # nodal coarsening only: the rigid-body interpolation (vec_interp_variant) of PETSc
            # 3.18's hypre crashed on C5's Newton systems, and the solves were
            # no cheaper with it (docs/parallel.md)
            out[f"{p}pc_hypre_boomeramg_nodal_coarsen"] = "6"
        return out
    raise InputError("amg", f"unknown AMG {kind!r}; allowed: gamg, hypre")


AMG_KINDS = ("gamg", "hypre")


# ---- single-matrix solver ----------------------------------------------------------------------
@dataclass
class PetscLinearSolver(SolverDefaults):
    """A x = b with PETSc: CG (symmetric) or GMRES, preconditioned by GAMG or BoomerAMG.

    The ``petsc`` backend of :class:`~polypore.solvers.linear.LinearSolver`. On N ranks, ``solve``
    takes this rank's rows of A (global columns) and of b and returns this rank's part of x.

    Parameters
    ----------
    symmetric : CG instead of GMRES
    rtol, maxiter : relative residual tolerance and iteration cap
    near_nullspace : (n_local, k) near-null vectors of A (rigid-body modes) or None
    block_size : interleaved block size of the unknowns (d for displacements); None: d from the
        rigid-body modes if they show whole blocks, else 1
    amg : "gamg" or "hypre" (the defaults of :func:`amg_defaults`; ``pc_type`` in options overrides)
    options : PETSc options without prefix (the ``[solver.petsc]`` table)
    prefix : PETSc options prefix of this solver
    reuse : ReusePolicy (default: rebuild every solve)
    """

    symmetric: bool = False
    rtol: float = 1e-10
    maxiter: int = 500
    near_nullspace: np.ndarray | None = None
    block_size: int | None = None
    amg: str = "gamg"
    options: Mapping | None = None
    prefix: str = ""
    reuse: ReusePolicy = field(default_factory=ReusePolicy)
    accept_rtol: float = 0.0
    comm: object = None

    def __post_init__(self):
        if self.amg not in AMG_KINDS:
            raise InputError("amg", f"unknown AMG {self.amg!r}; allowed: {', '.join(AMG_KINDS)}")
        B = self.near_nullspace
        if self.block_size is None:
            d = 3 if B is not None and B.shape[1] == 6 else 2 if B is not None and B.shape[1] == 3 else 1
            self.block_size = interleaved_block_size(B, d)
        defaults = {**krylov_defaults(self.symmetric, self.rtol, self.maxiter),
                    **amg_defaults(self.amg, nullspace=B is not None)}
        if any(str(k).lstrip("-") == "ksp_type" for k in (self.options or {})):
            # the norm and side chosen for CG/GMRES may not exist for the user's method (MINRES)
            defaults.pop("ksp_norm_type", None)
            defaults.pop("ksp_pc_side", None)
        self.driver = KrylovDriver(self.prefix, defaults, self.options, self.reuse, self.rtol, self.maxiter,
                                   max(self.accept_rtol, self.rtol), self.comm)
        self._mat = self._key = None
        self.seconds = 0.0

    backend = "petsc"

    @property
    def iterations(self) -> list[int]:
        return self.driver.iterations

    @property
    def krylov_iterations(self) -> list[int]:
        return self.driver.iterations

    @property
    def stats(self) -> PetscStats:
        return self.driver.stats

    def solve(self, A, b) -> np.ndarray:
        t0 = time.perf_counter()
        comm = self.driver.comm
        A = sp.csr_matrix(A)
        A.sum_duplicates()
        A.sort_indices()
        key = (A.shape, A.nnz)
        # the last pattern's arrays are kept by reference (a model refills one pattern: no copy)
        same = self._mat is not None and key == self._key[0] and np.array_equal(A.indptr, self._key[1]) \
            and np.array_equal(A.indices, self._key[2])
        if comm.getSize() > 1:            # the matrix is collective: rebuilt on every rank or none
            same = not comm.tompi4py().allreduce(not same, op=_mpi_max())
        assert self.block_size is not None          # set by __post_init__
        self._mat = aij(A, comm, self.block_size, self._mat if same else None)
        if not same:
            self._key = (key, A.indptr, A.indices)
            if self.near_nullspace is not None:
                self._mat.setNearNullSpace(near_nullspace(self.near_nullspace, comm))
        self.driver.stats.convert_seconds += time.perf_counter() - t0
        self.driver.operators(self._mat, changed_pattern=not same)
        cols = np.asarray(b, float).reshape(A.shape[0], -1)
        out = np.empty_like(cols)
        bv, xv = vec(cols[:, 0], comm), self._mat.createVecRight()
        r = xv.duplicate()
        for j in range(cols.shape[1]):
            bv.setArray(cols[:, j])
            bn = bv.norm()
            if bn == 0.0:
                out[:, j] = 0.0
                self.driver.iterations.append(0)
                continue
            xv.set(0.0)

            def residual(x, bv=bv, bn=bn):
                self._mat.mult(x, r)
                r.aypx(-1.0, bv)
                return r.norm() / bn

            self.driver.solve(bv, xv, residual)
            out[:, j] = xv.getArray()
        for v in (bv, xv, r):
            v.destroy()
        self.seconds += time.perf_counter() - t0
        return out.reshape(np.shape(b))
