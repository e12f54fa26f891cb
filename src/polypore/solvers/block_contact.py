"""Krylov solvers for the semi-smooth Newton systems of contact and coupled problems (3D sizes).

The contact Newton Jacobian has the block form (u: displacement dofs, l: multiplier dofs)

    [ A    Bt ] [du]   [ru]
    [ Cu   Cl ] [dl] = [rc]

with, per fracture face σ (scaled multipliers λ̃ = λ/β, rows multiplied by β),
Cl_σ = c_σ (I − DP_σ), Cu_σ = −c_σ DP_σ [[·]]_σ and c_σ = |σ| β_σ, where DP_σ is the
generalised derivative of the projection P (scheme.md §4): 0 on open faces, I on stuck ones,
n nᵀ + g nᵀ + T on slipping ones (g = F ŷ the friction–normal coupling, T the tangential
part, symmetric and ⪯ the tangent projector).

**Condensation used by the preconditioner.** Closed faces make Cl singular, so the
multipliers cannot be eliminated exactly. The preconditioner replaces DP_σ by
DP̂_σ = DP_σ − g nᵀ (the friction–normal coupling dropped, which makes it symmetric) and
Cl_σ by Cl̂_σ = c_σ (I − (1 − ρ) DP̂_σ). Open faces and the sliding direction of slipping
faces are then eliminated exactly; closed directions become penalty springs of stiffness
c_σ/ρ (a face-size multiple of the neighbouring cells' stiffness), and

    S = A − Bt Cl̂⁻¹ Cû

is symmetric positive definite and elasticity-like: smoothed-aggregation AMG with the
rigid-body near-nullspace works on it. (Regularising with ρ c_σ I on the unmodified block
perturbs the sliding direction too and costs several times the GMRES iterations,
docs/iterative_cornerpoint.md.) The regularisation only enters the preconditioner, never the solution.

**Coupled systems** (:class:`BlockPoroSolver`) add the pressures p with the Biot blocks
G_up, G_pu and the flow block F. The pressure Schur complement F − G_pu S⁻¹ G_up is
replaced by the fixed-stress-type diagonal approximation

    Ŝ_p = F − diag(Σ_j G_pu,ij G_up,ji / A_jj),

which keeps F's sparsity (the full product couples every pair of cells sharing a node and
costs 10× more to factorise) and does not depend on the contact state: it is set up once per time
step (with ``mechanics = "direct"`` PARDISO when installed, otherwise the two-level preconditioner
of :mod:`.pressure_twolevel`) and reused by every Newton iteration. S is solved by AMG
(``mechanics = "amg"``, 3D with the line
smoother of :mod:`.line_smoother`) or factorised (``"direct"``), set up again only when it changed.
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..core import live
from ..core.csr import csr_positions_in_rows
from ..core.errors import RunError
from ..core.interruptible import interruptible
from .block_jacobian import BlockJacobian, BorrowedValues, Unchanged, abs_matvec, block_diag_csr
from .interface import BlockOptions, SolverDefaults
from .linear import repeatable_random
from ..core.timing import SPLIT

log = logging.getLogger("polypore")

PRESSURE_SOLVERS = ("auto", "pardiso", "twolevel", "amg")
MECHANICS_SOLVERS = ("amg", "direct")


class _PardisoCall:
    """One PARDISO phase on factors held by a ``pypardiso.PyPardisoSolver``, with the matrix's
    1-based index arrays made once (pypardiso's own call rebuilds them, a copy of the whole
    pattern, on every call) and without pypardiso's per-solve check that the matrix is the
    factorised one (a comparison of every entry)."""

    def __init__(self, ps, A: sp.csr_matrix):
        self.ps, self.A = ps, A
        self.n = A.shape[0]
        self.ia = np.ascontiguousarray(A.indptr + 1, dtype=np.int32)
        self.ja = np.ascontiguousarray(A.indices + 1, dtype=np.int32)

    def __call__(self, phase: int, b: np.ndarray) -> np.ndarray:
        """Phase ``phase`` on right-hand sides ``b`` (n,) or (n, k)."""
        ps = self.ps
        b = np.asfortranarray(b, dtype=float)       # PARDISO reads k right-hand sides column-major
        x = np.zeros_like(b, order="F")
        err = ctypes.c_int32(0)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        one = ctypes.byref(ctypes.c_int32(1))
        ps._mkl_pardiso(ps.pt.ctypes.data_as(ctypes.POINTER(ps._pt_type[0])), one, one,
                        ctypes.byref(ctypes.c_int32(ps.mtype)), ctypes.byref(ctypes.c_int32(phase)),
                        ctypes.byref(ctypes.c_int32(self.n)), self.A.data.ctypes.data_as(f64),
                        self.ia.ctypes.data_as(i32), self.ja.ctypes.data_as(i32), ps.perm.ctypes.data_as(i32),
                        ctypes.byref(ctypes.c_int32(1 if b.ndim == 1 else b.shape[1])),
                        ps.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)), b.ctypes.data_as(f64),
                        x.ctypes.data_as(f64), ctypes.byref(err))
        if err.value != 0:
            raise RunError(f"PARDISO phase {phase} failed with error {err.value}")
        return np.ascontiguousarray(x)


class _Factorised:
    """S⁻¹ by a sparse LU of S (PARDISO when installed, else SuperLU), applied with ``@``."""

    def __init__(self, S):
        from .linear import have_pardiso

        S = sp.csr_matrix(S)
        if have_pardiso():
            import pypardiso

            # S is symmetric positive definite (module docstring): Cholesky-type factors on its
            # upper triangle have half the entries of the unsymmetric LU and solve faster
            # (docs/iterative_cornerpoint.md).
            U = sp.triu(S, format="csr")
            U.sort_indices()
            ps = pypardiso.PyPardisoSolver(mtype=2)
            interruptible(ps.factorize, U)
            call = _PardisoCall(ps, U)

            def solve(r):
                # forward, diagonal and backward substitution as three phases instead of phase 33:
                # 33 adds two steps of iterative refinement per solve (iparm(7) reports 2 even on
                # these pivot-free Cholesky factors), each a further pair of substitutions and a
                # product with S, for the same residual (docs/iterative_cornerpoint.md, eleventh session).
                # A preconditioner needs no refinement.
                r = np.asarray(r, float)
                for phase in (331, 332, 333):
                    r = call(phase, r)
                return r

            self._solve = solve
            self._free = lambda: ps.free_memory(everything=True)
        else:
            lu = interruptible(spla.splu, S.tocsc(), permc_spec="MMD_AT_PLUS_A")
            self._solve = lambda r: lu.solve(np.asarray(r, float))
            self._free = lambda: None

    def __matmul__(self, r):
        return self._solve(r)

    def __del__(self):
        try:
            self._free()
        except Exception:       # noqa: BLE001 - interpreter teardown
            pass


def _amg_hierarchy(S, B=None):
    """pyamg's smoothed-aggregation hierarchy of S (rigid-body near-null space B)."""
    from .amg_setup import sa_hierarchy

    # splu on the coarsest level: pyamg's default dense pinv is recomputed per cycle in some
    # versions (docs/iterative_cornerpoint.md); the finest level built without pyamg's copies of S
    # (amg_setup.py: the same hierarchy, a lower set-up peak)
    with repeatable_random():        # the set-up's random start vectors (linear.repeatable_random)
        return sa_hierarchy(S, B, max_coarse=1000, coarse_solver="splu")


def _amg(S, B=None):
    return _amg_hierarchy(S, B).aspreconditioner(cycle="V")


# An AMG hierarchy is kept for a new S while at most this fraction of its rows changed diagonal
REUSE_ROWS = 0.1
_SMOOTHER = ("block_gauss_seidel", {"sweep": "symmetric"})      # pyamg's default for SA


def _refit(ml, S) -> None:
    """Make hierarchy ``ml`` precondition S: S becomes its finest operator and the finest
    smoother is set up on it again (its inverse diagonal); transfers and coarse levels stay."""
    from pyamg.relaxation.smoothing import change_smoothers

    ml.levels[0].A = S
    change_smoothers(ml, _SMOOTHER, _SMOOTHER)


class _CondensedSolve:
    """S⁻¹ of the condensed displacement block as an operator (``@``), set up again only when S
    changed: AMG (3D: around a line smoother) or, with ``mechanics = "direct"``, S factorised
    (PARDISO when installed, else SuperLU). The elastic block is constant and the condensed
    contact rows change only with the faces' states and slip directions, so on faults that stay
    stuck one set-up serves the whole run. S is recognised by a SHA-1 digest of its pattern and
    values (copies to compare against cost memory, docs/iterative_cornerpoint.md, third session).

    With AMG, a changed S keeps the AMG hierarchy (aggregates, transfers, coarse operators) of
    an earlier S while it differs from that one on few rows (``REUSE_ROWS`` of them changed
    diagonal: the condensed contact rows of fault dofs); S replaces the finest operator and its
    smoother (`_refit`), and in 3D the line smoother keeps its lines, colours and band orders and
    takes S's values (:meth:`.line_smoother.LineSmoothedAMG.refit`). The coupled GMRES counts
    stay the same and the set-up time falls (docs/iterative_cornerpoint.md, fifth session).
    """

    def __init__(self, mechanics: str, near_nullspace=None):
        if mechanics not in MECHANICS_SOLVERS:
            raise ValueError(f"mechanics must be one of {MECHANICS_SOLVERS}, got {mechanics!r}")
        self.mechanics, self.near_nullspace = mechanics, near_nullspace
        self._key = self._op = None
        self._ml = self._ml_diag = None        # the kept hierarchy and its S's diagonal
        self._ls = None                        # the kept line smoother (3D), around self._ml
        self.setups = 0                        # operators made (a new S)
        self.hierarchies = 0                   # AMG hierarchies built among them

    def _close(self, d) -> bool:
        """Whether the kept hierarchy serves an S with diagonal d (few rows changed)."""
        d0 = self._ml_diag
        return self._ml is not None and d0.shape == d.shape and \
            np.count_nonzero(np.abs(d - d0) > 1e-12 * np.abs(d0)) <= REUSE_ROWS * d.size

    def _hierarchy(self, S):
        """An AMG hierarchy fitted to S: the kept one when S is close to its own, else a new one."""
        d = S.diagonal()
        if self._close(d):
            _refit(self._ml, S)
            return self._ml
        self._ml = None
        ml = _amg_hierarchy(S, self.near_nullspace)
        self._ml, self._ml_diag = ml, d
        self.hierarchies += 1
        return ml

    def _line_smoothed(self, S):
        """The line-smoothed AMG of S (3D): the kept one refitted while S is close to its S (its
        lines, colours, band orders and hierarchy kept), else a new one."""
        from .line_smoother import LineSmoothedAMG

        d = S.diagonal()
        ls = self._ls
        if ls is not None and self._close(d):
            self._ml.levels[0].A = None         # the old S goes before the new one's copies are made
            try:
                return ls.refit(S, lambda S_: _refit(self._ml, S_) or self._ml.aspreconditioner(cycle="V"))
            except ValueError:                  # another size: start again
                pass
        self._ls = self._ml = None

        def factory(S_, B_):
            self._ml = _amg_hierarchy(S_, B_)
            return self._ml.aspreconditioner(cycle="V")

        with repeatable_random():
            ls = LineSmoothedAMG(S, self.near_nullspace, factory)
        self._ls, self._ml_diag = ls, d
        self.hierarchies += 1
        return ls

    @staticmethod
    def _digest(S) -> tuple:
        h = hashlib.sha1()
        for a in (S.indptr, S.indices, S.data):
            h.update(np.ascontiguousarray(a))       # type: ignore[arg-type]  # numpy's stubs: no Buffer
        return S.shape, S.nnz, h.digest()

    def __call__(self, S):
        S = sp.csr_matrix(S)
        key = self._digest(S)
        if key == self._key:
            # the kept operator reads S from now on: an S that borrows a matrix's values
            # (condense(borrow=True)) is valid only while that matrix lends them
            if self._ls is not None:
                self._ls.S = S
            if self._ml is not None:
                self._ml.levels[0].A = S
            return self._op
        self._op = self._key = None            # the old factors go before the new ones are made
        B = self.near_nullspace
        if self.mechanics == "direct":
            self._op = _Factorised(S)
        elif B is not None and np.ndim(B) == 2 and B.shape[1] == 6:
            # 3D: line Gauss–Seidel around the V-cycle (line_smoother.py): on flat cells the
            # point smoothers miss the short edges' direction (PCG on emerald's S: 176 -> 101)
            self._op = self._line_smoothed(S)
        else:
            self._op = self._hierarchy(S).aspreconditioner(cycle="V")
        self._key = key
        self.setups += 1
        return self._op

    def release(self) -> None:
        self._op = self._key = self._ml = self._ml_diag = self._ls = None


@dataclass
class ContactCondensation:
    """Per-face data of the contact rows for the condensation (module docstring).

    Parameters
    ----------
    scale : (n_f,) c_σ = |σ| β_σ, the size of the contact rows in the scaled Jacobian
    normal : (n_f, d) unit normals n⁺
    rho : penalty regularisation of closed directions (dimensionless, 0 < ρ < 1)
    """

    scale: np.ndarray
    normal: np.ndarray
    rho: float = 0.1

    def condense(self, A, Bt, Cu, Cl, borrow: bool = False):
        """(Cl̂⁻¹ csr, Cû csr, S csr) for the blocks of one Jacobian (S has data of its own and
        shares A's index arrays).

        With ``borrow`` (A a csr the caller owns for the solve) S borrows A's value array too
        and a fourth item is returned, a :class:`~.block_jacobian.BorrowedValues` (or
        :class:`~.block_jacobian.Unchanged`) standing for A until its ``restore()``, which the
        caller must call before A is used again; when A is no sorted csr or lacks the contact
        couplings' entries, S has values of its own as without ``borrow`` (and the fourth item
        is an :class:`~.block_jacobian.Unchanged`).
        """
        out = self._condense(A, Bt, Cu, Cl, borrow and sp.issparse(A) and A.format == "csr" and A.has_sorted_indices)
        return out if borrow else out[:3]

    def _condense(self, A, Bt, Cu, Cl, lend: bool):
        """(Cl̂⁻¹, Cû, S, the lent A) of :meth:`condense`; S on A's own arrays when ``lend``."""
        nf, d = self.normal.shape
        if nf == 0:
            return sp.csr_matrix((0, 0)), Cu, (A if lend else _restricted(A)), Unchanged(A)
        c, n = self.scale, self.normal
        DP = np.eye(d)[None] - _diag_blocks(Cl, nf, d) / c[:, None, None]
        DPn = np.einsum("fij,fj->fi", DP, n)
        g = DPn - np.einsum("fi,fi->f", n, DPn)[:, None] * n          # zero unless the face slips
        DPs = DP - np.einsum("fi,fj->fij", g, n)
        Cinv = block_diag_csr(np.linalg.inv(c[:, None, None] * (np.eye(d)[None] - (1.0 - self.rho) * DPs)))
        # Cu = −c DP [[·]]; on closed faces nᵀ DP = nᵀ, so nᵀ Cu_σ = −c nᵀ[[·]] and
        # −c DP̂ [[·]] = Cu_σ − g (nᵀ Cu_σ)
        N = sp.csr_matrix((n.ravel(), (np.repeat(np.arange(nf), d), np.arange(nf * d))), shape=(nf, nf * d))
        Gm = sp.csr_matrix((g.ravel(), (np.arange(nf * d), np.repeat(np.arange(nf), d))), shape=(nf * d, nf))
        Cu_s = (sp.csr_matrix(Cu) - Gm @ (N @ Cu)).tocsr()
        # A is symmetric (to round-off): only the contact term, which lives on the fault dofs, is
        # symmetrised, so that S is built once rather than as S, Sᵀ, S + Sᵀ and ½(S + Sᵀ)
        # (docs/iterative_cornerpoint.md, third session)
        P = (Bt @ Cinv @ Cu_s).tocsr()
        Q = (0.5 * (P + P.T)).tocoo()
        base = A if lend else _restricted(A)
        pos, found = csr_positions_in_rows(base, Q.row, Q.col)
        if not found.all():
            return Cinv, Cu_s, sp.csr_matrix(base - Q.tocsr()), Unchanged(A)
        # the models' elastic matrices hold the contact couplings (explicit zeros, models/
        # mechanics.py): S is A's restriction with those entries changed, no sparse sum (whose
        # temporaries were the Newton iteration's memory peak, docs/iterative_cornerpoint.md); Q is
        # coalesced, so the positions are distinct
        if lend:
            lent = BorrowedValues(A, pos, A.data[pos] - Q.data)
            return Cinv, Cu_s, sp.csr_matrix((A.data, A.indices, A.indptr), shape=A.shape), lent
        base.data[pos] -= Q.data
        return Cinv, Cu_s, base, Unchanged(A)


def _restricted(A) -> sp.csr_matrix:
    """A as a csr matrix with data of its own (index arrays shared)."""
    A = sp.csr_matrix(A)
    if not A.has_sorted_indices:            # (checked, not assumed) sorted: shared, never sorted in place
        A = A.sorted_indices()
    return sp.csr_matrix((A.data.copy(), A.indices, A.indptr), shape=A.shape)


@dataclass
class BlockContactSolver(SolverDefaults, BlockOptions):
    """Solve the 2×2 contact Newton system with GMRES + AMG on the condensed matrix.

    Parameters
    ----------
    n_u : number of displacement unknowns (the first block)
    d : block size of the multipliers (2 or 3)
    condensation : ContactCondensation
    near_nullspace : (n_u, k) rigid-body modes of the free displacement dofs
    rtol, maxiter, restart, accept_rtol, mechanics (keyword-only) : :class:`~.interface.BlockOptions`;
        Newton's :class:`~.newton.KrylovTarget` overrides rtol per solve
    """

    takes_target = True          # solve() accepts Newton's KrylovTarget (weights, forcing term)
    takes_blocks = True          # solve() accepts a BlockJacobian (models then assemble no matrix)
    n_u: int
    d: int
    condensation: ContactCondensation
    near_nullspace: np.ndarray | None = None
    iterations: list = field(default_factory=list)
    seconds: float = 0.0

    def __post_init__(self):
        self._s = _CondensedSolve(self.mechanics, self.near_nullspace)

    @property
    def backend(self) -> str:
        return "block-direct" if self.mechanics == "direct" else "block-amg"

    @property
    def krylov_iterations(self) -> list[int]:
        return self.iterations

    def release(self) -> None:
        """Free the set-up of S (factors or AMG hierarchy)."""
        self._s.release()

    def solve(self, J, rhs, target=None) -> np.ndarray:
        """x with J x ≈ rhs: J (n, n) sparse, rhs (n,); ``target`` a KrylovTarget or None (rtol)."""
        t0 = time.perf_counter()
        n_u = self.n_u
        if not isinstance(J, BlockJacobian):
            J = BlockJacobian.from_csr(J, n_u, J.shape[0] - n_u)
        with SPLIT.timed("preconditioner", "block preconditioner set-up"):
            Bt = J.ul
            # S borrows A's values until the solve ends (block_jacobian.BorrowedValues)
            Cinv, Cu_s, S, lent = self.condensation.condense(J.uu, Bt, J.lu, J.ll, borrow=True)
        try:
            with SPLIT.timed("preconditioner", "block preconditioner set-up"):
                Ms = self._s(S)
                del S
            J = replace(J, uu=lent)

            def apply(r):
                ru, rc = r[:n_u], r[n_u:]
                xu = Ms @ (ru - Bt @ (Cinv @ rc))
                xc = Cinv @ (rc - Cu_s @ xu)
                return np.concatenate([xu, xc])

            with SPLIT.timed("krylov", "GMRES"):
                x = _gmres(J, rhs, apply, self, target)
        finally:
            lent.restore()
        self.seconds += time.perf_counter() - t0
        log.debug("block contact solver: %d GMRES iterations, %.2f s", self.iterations[-1], time.perf_counter() - t0)
        return x


# Tight solves (rtol below this) first estimate the accuracy the weighted norm allows.
FLOOR_CHECK = 1e-4


def attainable_rtol(J, x, w, bnorm: float) -> float:
    """ε ‖w∘(|J| |x|)‖ / ‖w∘b‖: the relative weighted residual below which a solution x of J x = b
    cannot be told from round-off (the componentwise backward error of a stable direct solve).

    Flow rows with large weighted terms and a zero right-hand side (the first Newton system of a
    day on the weak-scaling grids) put this floor far above a tight Newton target, where GMRES
    would iterate on round-off (docs/iterative_cornerpoint.md, fifth session).

    Parameters
    ----------
    J : (n, n) csr or :class:`~.block_jacobian.BlockJacobian`;  x : (n,) an (approximate) solution;
        w : (n,) row weights;  bnorm : ‖w∘b‖
    """
    out = abs_matvec(J, np.abs(x))
    return float(np.finfo(float).eps * np.linalg.norm(w * out) / bnorm)


# Bytes the Krylov basis may take before the restart is shortened (krylov_restart)
KRYLOV_BASIS_BYTES = 1.5e9
MIN_RESTART = 40


def krylov_restart(restart: int, n: int) -> int:
    """The restart length for a system of n unknowns: ``restart``, shortened so that the basis
    (restart + 1 vectors of n float64) stays within ``KRYLOV_BASIS_BYTES``, never below
    ``MIN_RESTART``.

    The basis is the largest single item of a 10⁶-cell run; on the weak-scaling systems restart
    40 costs no more iterations than 100, 20 does (docs/iterative_cornerpoint.md, seventh session).
    """
    fit = int(KRYLOV_BASIS_BYTES // (8 * max(n, 1))) - 1
    return int(max(min(restart, fit), min(restart, MIN_RESTART)))


def _gmres(J, rhs, apply, solver, target=None):
    """Restarted GMRES with iteration count and failure message.

    Parameters
    ----------
    J : (n, n) csr
    rhs : (n,)
    apply : the preconditioner, r -> x ≈ J⁻¹ r
    solver : the block solver (rtol, maxiter, restart, accept_rtol, iterations)
    target : KrylovTarget or None (then ``solver.rtol`` in the plain 2-norm, left-preconditioned:
        the behaviour of ``forcing = "fixed"``). With a target, GMRES runs right-preconditioned
        on the row-scaled system diag(w) J x = diag(w) rhs (w = target.weights, or ones), with the
        preconditioner v -> apply(v / w): the operator diag(w) J M diag(w)⁻¹ is similar to J M,
        so the convergence rate is that of the unweighted system, and what GMRES minimises and
        tests is the true residual in Newton's weighted norm (newton.py), to target.rtol. SciPy's
        gmres preconditions from the left (it minimises ‖M (b − J x)‖, which says little about
        ‖b − J x‖), so the right preconditioning is composed here.

    Restart cycles are driven here, one SciPy call each, so that ``solver.maxiter`` caps the
    inner iterations and the true residual is checked after every cycle. On fine meshes it has a
    round-off floor, where SciPy's own loop would restart with ever smaller inner tolerances
    (docs/iterative_cornerpoint.md, "Measurements cited by the code"). A cycle that did not halve
    the true residual, left within ``solver.accept_rtol``, is therefore accepted: Newton only needs
    an inexact step. A tight solve (rtol < ``FLOOR_CHECK``) also stops at :func:`attainable_rtol`
    when that is above rtol.
    """
    n = J.shape[0]
    its = [0]

    def cb(_):
        its[0] += 1
        live.krylov_iteration()

    if target is None:
        rtol, w, b = solver.rtol, None, rhs
        M = spla.LinearOperator((n, n), matvec=apply, dtype=float)
    else:
        rtol = float(target.rtol)
        w = np.ones(n) if target.weights is None else np.asarray(target.weights, float)
        b = w * rhs

        def right(v):                      # M diag(w)⁻¹ v: back to unknowns
            return apply(v / w)

        op = spla.LinearOperator((n, n), matvec=lambda v: w * (J @ right(v)), dtype=float)
    bnorm = np.linalg.norm(b)
    x = np.zeros(n)
    if bnorm == 0.0:
        solver.iterations.append(0)
        return x
    floor = 0.0
    if w is not None and rtol < FLOOR_CHECK:
        # the accuracy the weighted norm allows, from one preconditioner application's x
        floor = attainable_rtol(J, apply(rhs), w, bnorm)
    prev = np.inf
    r = b
    while True:
        restart = min(krylov_restart(solver.restart, n), solver.maxiter - its[0])
        if w is None:
            x, info = spla.gmres(J, rhs, x0=x, M=M, rtol=rtol, restart=restart, maxiter=1,
                                 callback=cb, callback_type="pr_norm")
            res = np.linalg.norm(J @ x - rhs) / bnorm
        else:
            # the correction of this cycle, to the absolute target rtol ‖w∘b‖ (r is the true residual)
            y, info = spla.gmres(op, r, rtol=0.0, atol=max(rtol, floor) * bnorm, restart=restart, maxiter=1,
                                 callback=cb, callback_type="pr_norm")
            x = x + right(y)
            r = b - w * (J @ x)
            res = np.linalg.norm(r) / bnorm
            if floor > rtol:
                floor = attainable_rtol(J, x, w, bnorm)
        if info == 0 and w is None or res <= rtol:
            break
        if res <= floor:
            log.debug("GMRES: relative residual %.2e after %d iterations, at the accuracy the weighted "
                      "norm allows (%.2e) above rtol %.0e; accepted", res, its[0], floor, rtol)
            break
        if res > 0.5 * prev and res <= solver.accept_rtol:     # a whole cycle gained nothing: the floor
            log.debug("GMRES: relative residual %.2e after %d iterations, at the round-off floor above rtol "
                      "%.0e; accepted", res, its[0], rtol)
            break
        prev = res
        if its[0] >= solver.maxiter:
            solver.iterations.append(its[0])
            raise RunError(f"GMRES did not reach rtol={rtol:g} in {its[0]} iterations (relative "
                           f"residual {res:.2e}{', row-weighted' if w is not None else ''}); try "
                           "solver.linear = 'pardiso'")
    solver.iterations.append(its[0])
    return x


def _diag_blocks(C, nf: int, d: int) -> np.ndarray:
    """(nf, d, d) diagonal blocks of a block-diagonal sparse matrix."""
    C = sp.coo_matrix(C)
    out = np.zeros((nf, d, d))
    f = C.row // d
    keep = (C.col // d) == f
    np.add.at(out, (f[keep], C.row[keep] % d, C.col[keep] % d), C.data[keep])
    return out


class _PressureSolve:
    """Ŝ_p⁻¹ (module docstring), rebuilt only when the flow block F changes (once per time step)."""

    def __init__(self, method: str):
        if method == "auto":
            from .linear import have_pardiso

            method = "pardiso" if have_pardiso() else "twolevel"
        self.method = method
        self._key = self._ps = self._fact = self.apply = None
        self._colours = None            # (pattern digest, the two-level cell blocks' colouring)
        self.builds = 0

    def update(self, F, Gpu, Gup, dA, B=None, groups=None):
        """Rebuild for a new F. ``B`` the scaled constant (n_p,); ``groups`` (coarse, block) masks
        (n_p,) bool for :class:`~.pressure_twolevel.TwoLevelPressure` (without them "twolevel"
        falls back to smoothed aggregation on the whole block)."""
        F = sp.csr_matrix(F)
        key = _CondensedSolve._digest(F)        # not a copy of F's values (docs/iterative_cornerpoint.md)
        if key == self._key:
            return
        # the previous step's set-up goes before the new one is made (its apply closure held the
        # old factors through the new factorisation); PARDISO keeps factors until told (without
        # this, peak memory grew step by step: docs/iterative_cornerpoint.md)
        self.release()
        lump = np.asarray((Gpu @ sp.diags(1.0 / dA)).multiply(Gup.T).sum(axis=1)).ravel()
        Sp = sp.csr_matrix(F - sp.diags(lump))
        if self.method == "pardiso":
            import pypardiso

            asym = abs(Sp - Sp.T).max() if Sp.nnz else 0.0
            if asym <= 1e-12 * abs(Sp).max():
                # −Ŝ_p is symmetric positive definite (−F and the lumped Biot term both are):
                # half-size Cholesky-type factors, and no per-solve check of the matrix
                fact = self._fact = _Factorised(-Sp)
                self.apply = lambda r: -(fact @ r)
            else:
                ps = self._ps = pypardiso.PyPardisoSolver()
                interruptible(ps.factorize, Sp)     # a signal stops the run mid-factorisation
                self.apply = lambda r: ps.solve(Sp, np.asarray(r, float))
        elif self.method == "twolevel" and groups is not None:
            from .pressure_twolevel import TwoLevelPressure

            h = hashlib.sha1()
            # the colouring depends on the pattern, its explicit zeros and the masks only
            for a in (Sp.indptr, Sp.indices, np.packbits(Sp.data != 0), groups[0], groups[1]):
                h.update(np.ascontiguousarray(a))
            reuse = self._colours[1] if self._colours is not None and self._colours[0] == h.digest() else None
            with repeatable_random():
                T = TwoLevelPressure(Sp, B, groups[0], groups[1], colours=reuse)
            self._colours = (h.digest(), T.colours)
            self.apply = T.apply
        else:
            sign = -1.0 if np.mean(Sp.diagonal()) < 0 else 1.0   # AMG wants a positive definite operator
            # B: the near-null space (a constant pressure in the scaled unknowns, 1/s); with
            # per-unknown scales, pyamg's default (constants) misses it and GMRES needs more
            # iterations (docs/iterative_cornerpoint.md)
            M = _amg(sign * 0.5 * (Sp + Sp.T), None if B is None else np.asarray(B, float).reshape(-1, 1))
            self.apply = lambda r: sign * (M @ r)
        self._key = key
        self.builds += 1

    def release(self) -> None:
        """Free the set-up (factors, AMG hierarchy); the next update builds it again."""
        if self._ps is not None:
            self._ps.free_memory(everything=True)
        self._ps = self._fact = self.apply = self._key = None


@dataclass
class BlockPoroSolver(SolverDefaults, BlockOptions):
    """GMRES for the coupled step Jacobian [u, l, p] with a block lower-triangular preconditioner.

    The (u, l) part is condensed as in :class:`BlockContactSolver` into S (AMG, set up again only
    when S changed); the pressures use Ŝ_p (module docstring, set up once per step).
    Apply: x_u = S⁻¹ (r_u − Bt Cl̂⁻¹ r_l), x_p = Ŝ_p⁻¹ (r_p − G_pu x_u), x_l = Cl̂⁻¹ (r_l − Cû x_u).

    Parameters
    ----------
    n_u, d, n_l : sizes of the displacement block, the multiplier block size, the multiplier count × d
    condensation : ContactCondensation
    pressure : "auto", "pardiso", "twolevel" (:mod:`.pressure_twolevel`) or "amg" (smoothed
        aggregation on the whole block): the Ŝ_p solve. "auto" is "twolevel" with
        ``mechanics = "amg"`` (no large factorisation on that path; docs/choices.md) and PARDISO,
        where installed, with ``mechanics = "direct"``
    pressure_nullspace : (n_p,) near-null space of Ŝ_p for its AMG (a constant pressure in the
        caller's scaled unknowns); set by the model before each step
    mechanics : "amg" (smoothed aggregation on S) or "direct" (S factorised: PARDISO when
        installed, else SuperLU); ``solver.linear`` "block-amg" and "block-direct"
    pressure_groups : ((n_p,) bool, (n_p,) bool) or None: the unknowns spanning the two-level
        coarse space (cell pressures) and those solved together in its smoother (the fracture
        subsystem); given by the model
    """

    takes_target = True          # solve() accepts Newton's KrylovTarget (weights, forcing term)
    takes_blocks = True          # solve() accepts a BlockJacobian (models then assemble no matrix)
    n_u: int
    d: int
    n_l: int
    condensation: ContactCondensation
    near_nullspace: np.ndarray | None = None
    pressure_nullspace: np.ndarray | None = None
    pressure_groups: tuple | None = None
    maxiter: int = field(default=400, kw_only=True)
    # the coupled systems' round-off floor in Newton's weighted norm is higher than the contact
    # ones': on corner-point grids even PARDISO's own solution stops above 1e-6, where GMRES would
    # stall (docs/iterative_cornerpoint.md)
    accept_rtol: float = field(default=1e-4, kw_only=True)
    iterations: list = field(default_factory=list)
    seconds: float = 0.0

    def __post_init__(self):
        self._s = _CondensedSolve(self.mechanics, self.near_nullspace)
        self._p = _PressureSolve("twolevel" if self.pressure == "auto" and self.mechanics == "amg" else self.pressure)

    @property
    def backend(self) -> str:
        return "block-direct" if self.mechanics == "direct" else "block-amg"

    @property
    def krylov_iterations(self) -> list[int]:
        return self.iterations

    def set_pressure_nullspace(self, b) -> None:
        """The near-null space of Ŝ_p for the coming systems (``pressure_nullspace``)."""
        self.pressure_nullspace = b

    def release(self) -> None:
        """Free the set-ups of S and Ŝ_p (after the last step; a later solve builds them again)."""
        self._s.release()
        self._p.release()

    @property
    def mechanics_setups(self) -> int:
        """How many times S was set up (factorised or its AMG built)."""
        return self._s.setups

    def solve(self, J, rhs, target=None) -> np.ndarray:
        """x with J x ≈ rhs: J (n, n) sparse, rhs (n,); ``target`` a KrylovTarget or None (rtol)."""
        t0 = time.perf_counter()
        nu, nl = self.n_u, self.n_l
        po = nu + nl
        if not isinstance(J, BlockJacobian):
            J = BlockJacobian.from_csr(J, nu, nl)
        with SPLIT.timed("preconditioner", "block preconditioner set-up"):
            Bt, Gpu = J.ul, J.pu
            # S borrows A's values until the solve ends (block_jacobian.BorrowedValues)
            Cinv, Cu_s, S, lent = self.condensation.condense(J.uu, Bt, J.lu, J.ll, borrow=True)
        try:
            with SPLIT.timed("preconditioner", "block preconditioner set-up"):
                J = replace(J, uu=lent)
                self._p.update(J.pp, Gpu, J.up, lent.diagonal(), self.pressure_nullspace, self.pressure_groups)
                Mu, Mp = self._s(S), self._p.apply
                del S

            def apply(r):
                ru, rl, rp = r[:nu], r[nu:po], r[po:]
                xu = Mu @ (ru - Bt @ (Cinv @ rl)) if nl else Mu @ ru
                xp = Mp(rp - Gpu @ xu)
                xl = Cinv @ (rl - Cu_s @ xu) if nl else rl
                return np.concatenate([xu, xl, xp])

            with SPLIT.timed("krylov", "GMRES"):
                x = _gmres(J, rhs, apply, self, target)
        finally:
            lent.restore()
        self.seconds += time.perf_counter() - t0
        log.debug("block poro solver: %d GMRES iterations, %.2f s", self.iterations[-1], time.perf_counter() - t0)
        return x
