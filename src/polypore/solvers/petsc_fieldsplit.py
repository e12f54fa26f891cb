"""The block preconditioners of :mod:`.block_contact` expressed with PETSc's PCFIELDSPLIT.

Same systems, same call signatures (``solve(J, rhs)``, ``iterations``, ``seconds``,
``pressure_nullspace``), so a model switches by name. GMRES (right-preconditioned, true residual)
on the Jacobian J; the preconditioner is built from a matrix P that is J with the contact rows
replaced by the condensation's Cl̂ and Cû (block_contact's module docstring), and for coupled
systems the pressure block F replaced by the fixed-stress-type Ŝ_p = F − diag(G_pu diag(A)⁻¹ G_up).
P keeps one nonzero pattern (J's, with whole d×d face blocks and the pressure diagonal added), so
its values are updated in place and PETSc reuses its structures.

Contact (unknowns [u, l])::

    -pc_type fieldsplit -pc_fieldsplit_type schur -pc_fieldsplit_schur_fact_type full
    -pc_fieldsplit_schur_precondition selfp          # S = A − Bt blockdiag(Cl̂)⁻¹ Cû, formed by PETSc
    -fieldsplit_l_ksp_type preonly -fieldsplit_l_pc_type pbjacobi   # Cl̂ is block diagonal: exact
    -fieldsplit_u_mat_schur_complement_ainv_type blockdiag
    -fieldsplit_u_ksp_type preonly -fieldsplit_u_pc_type hypre      # BoomerAMG, nodal coarsening

Splits are named ``l`` (multipliers, eliminated first) and ``u``; with ``fact_type full`` this is
exactly BlockContactSolver's apply: x_u = S⁻¹(r_u − Bt Cl̂⁻¹ r_l), x_l = Cl̂⁻¹(r_l − Cû x_u).

Coupled (unknowns [u, l, p]): the multipliers are eliminated the same way from the split ``m``
= (u, p), whose Schur complement is preconditioned by a multiplicative (block lower-triangular)
fieldsplit with splits ``u`` (AMG on S) and ``p`` (AMG on Ŝ_p, set up once per time step)::

    -fieldsplit_m_pc_type fieldsplit -fieldsplit_m_pc_fieldsplit_type multiplicative
    -fieldsplit_m_fieldsplit_u_pc_type hypre -fieldsplit_m_fieldsplit_p_pc_type gamg

which is BlockPoroSolver's x_u = S⁻¹(r_u − Bt Cl̂⁻¹ r_l), x_p = Ŝ_p⁻¹(r_p − G_pu x_u),
x_l = Cl̂⁻¹(r_l − Cû x_u).

The displacement AMG is BoomerAMG (nodal coarsening): GAMG with the rigid-body near-null space is fast
on plain elasticity but its set-up degenerates on these blocks, whose bubble dofs (a third of them on
small meshes) have zero rows in the rigid-body modes (5.7 s instead of 0.05 s on 5k dofs; operator
complexity 17), docs/parallel.md. Every option can be overridden through ``options`` (without the
solver's prefix, ``contact_`` or ``poro_`` by default) or on PETSc's command line with it.

On N ranks (``mpiexec``, :mod:`.distributed`): every rank holds the whole J and computes Cl̂, Cû
and Ŝ_p from it (they are row-local); a :class:`~.distributed.DofLayout` from the mesh partition
gives each rank its rows of J and P for PETSc, the index sets of the splits are each rank's owned
rows of a field, and the solution is gathered on every rank.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..core.errors import InputError, RunError
from .block_contact import ContactCondensation, _diag_blocks
from .distributed import context, layout_for
from .petsc import (AMG_KINDS, FIELD, KrylovDriver, PetscStats, ReusePolicy, aij, amg_defaults, interleaved_block_size,
                    krylov_defaults, near_nullspace, petsc, vec)

log = logging.getLogger("polypore")

PRESSURE_SOLVERS = ("auto", "amg", "gamg", "hypre", "lu", "pardiso")


def modified_contact_blocks(cond: ContactCondensation, Cu, Cl):
    """(Cl̂ as (nf, d, d) blocks, Cû csr): ContactCondensation.condense without forming S.

    DP̂_σ = DP_σ − g nᵀ (friction–normal coupling dropped), Cl̂_σ = c_σ (I − (1 − ρ) DP̂_σ),
    Cû = Cu − g (nᵀ Cu) face by face; see block_contact's module docstring.
    """
    nf, d = cond.normal.shape
    c, n = cond.scale, cond.normal
    DP = np.eye(d)[None] - _diag_blocks(Cl, nf, d) / c[:, None, None]
    DPn = np.einsum("fij,fj->fi", DP, n)
    g = DPn - np.einsum("fi,fi->f", n, DPn)[:, None] * n
    DPs = DP - np.einsum("fi,fj->fij", g, n)
    Clhat = c[:, None, None] * (np.eye(d)[None] - (1.0 - cond.rho) * DPs)
    N = sp.csr_matrix((n.ravel(), (np.repeat(np.arange(nf), d), np.arange(nf * d))), shape=(nf, nf * d))
    Gm = sp.csr_matrix((g.ravel(), (np.arange(nf * d), np.repeat(np.arange(nf), d))), shape=(nf * d, nf))
    Cu_s = (sp.csr_matrix(Cu) - Gm @ (N @ Cu)).tocsr()
    return Clhat, Cu_s


def _keys(indptr, indices, ncols, row0=0):
    rows = np.repeat(np.arange(len(indptr) - 1, dtype=np.int64), np.diff(indptr)) + row0
    return rows * ncols + indices.astype(np.int64)


class _PreconditionerPattern:
    """Fixed CSR pattern of P ⊇ pattern(J) ∪ whole d×d blocks in the contact rows (each face's rows
    get the union of their columns) ∪ the pressure diagonal; maps J's and the modified blocks'
    values into it."""

    def __init__(self, J: sp.csr_matrix, nu: int, nl: int, d: int, po: int):
        n = J.shape[0]
        S = sp.csr_matrix((np.ones(J.nnz), J.indices, J.indptr), shape=J.shape)
        if nl:
            face = sp.kron(sp.identity(nl // d, format="csr"), np.ones((d, d)), format="csr")
            rows = sp.csr_matrix(S[nu:po])
            rows.data[:] = 1.0
            S = sp.vstack([S[:nu], face @ rows + sp.hstack([sp.csr_matrix((nl, nu)), face,
                                                            sp.csr_matrix((nl, n - po))]), S[po:]]).tocsr()
        S = (S + sp.diags(np.r_[np.zeros(po), np.ones(n - po)])).tocsr()
        S.sum_duplicates()
        S.sort_indices()
        self.indptr, self.indices, self.shape = S.indptr, S.indices, S.shape
        keys = _keys(S.indptr, S.indices, n)
        self.pos_J = np.searchsorted(keys, _keys(J.indptr, J.indices, n))
        self.a, self.b = int(S.indptr[nu]), int(S.indptr[po])
        self.keys_l = keys[self.a:self.b]
        diag = np.arange(po, n, dtype=np.int64)
        self.pos_pdiag = np.searchsorted(keys, diag * n + diag)
        self.nu, self.po, self.n = nu, po, n

    def values(self, J: sp.csr_matrix, Ml: sp.csr_matrix | None, pdiag_shift) -> np.ndarray:
        """P's data: J's values, the contact rows from Ml (nl × n, csr), the pressure diagonal − shift."""
        out = np.zeros(len(self.indices))
        out[self.pos_J] = J.data
        if Ml is not None:
            out[self.a:self.b] = 0.0
            k = _keys(Ml.indptr, Ml.indices, self.n, self.nu)
            pos = np.searchsorted(self.keys_l, k)
            out[self.a + pos] = Ml.data
        if pdiag_shift is not None:
            out[self.pos_pdiag] -= pdiag_shift
        return out

    def matrix(self, data) -> sp.csr_matrix:
        return sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)


def _canonical(J) -> sp.csr_matrix:
    J = sp.csr_matrix(J)
    J.sum_duplicates()
    J.sort_indices()
    return J


class _FieldSplitBase:
    """Shared machinery: PETSc matrices updated in place, the driver, the true-residual check."""

    def _init_common(self, prefix, defaults, options, reuse):
        if self.amg not in AMG_KINDS:
            raise InputError(f"{FIELD}.amg", f"unknown AMG {self.amg!r}; allowed: {', '.join(AMG_KINDS)}")
        self.P = petsc()
        if self.P.COMM_WORLD.getSize() > 1 and context() is None:
            raise InputError("solver.linear", "the PETSc block solvers run on N ranks in a distributed run "
                             "only (polypore.solvers.distributed.activate(); docs/parallel.md)")
        self._lay = None
        self.bs_u = interleaved_block_size(self.near_nullspace, self.d)
        self.driver = KrylovDriver(prefix, defaults, options, reuse, self.rtol, self.maxiter, self.accept_rtol,
                                   configure=self._configure)
        self._Jm = self._Pm = self._pat = self._key = None
        self._nsp_u = None

    @property
    def stats(self) -> PetscStats:
        return self.driver.stats

    @property
    def iterations(self) -> list[int]:
        return self.driver.iterations

    @iterations.setter
    def iterations(self, value):
        self.driver.iterations = value

    def _matrices(self, J, Ml, shift, nu, nl, po):
        """Update (or create, for a new pattern of J) the PETSc J and P; True if the pattern is new."""
        t0 = time.perf_counter()
        key = (J.shape, J.nnz)
        new = self._key is None or key != self._key[0] or not (np.array_equal(J.indptr, self._key[1])
                                                               and np.array_equal(J.indices, self._key[2]))
        if new:
            self._key = (key, J.indptr.copy(), J.indices.copy())
            self._pat = _PreconditionerPattern(J, nu, nl, self.d, po)
            self._Jm = self._Pm = None
        Pcsr = self._pat.matrix(self._pat.values(J, Ml, shift))
        lay = self._lay = layout_for(self, J.shape[0])
        self._Jm = aij(J if lay is None else lay.rows(J), mat=self._Jm)
        self._Pm = aij(Pcsr if lay is None else lay.rows(Pcsr), mat=self._Pm)
        self.driver.stats.convert_seconds += time.perf_counter() - t0
        return new

    def _forcing(self, target):
        """Newton's forcing term (a KrylovTarget, or None: ``rtol``) as the KSP's rtol of this solve.

        Pass-through only: PETSc's GMRES tests the plain 2-norm, the row weights of the target are
        not applied (row-scaling J would row-scale the pressure block that GAMG coarsens), so η is
        used as the relative reduction of the unweighted residual. An rtol set by the user
        (``[solver.petsc]`` or PETSc's command line) wins.
        """
        if "ksp_rtol" in self.driver.user or self.P.Options().hasName(self.prefix + "ksp_rtol"):
            return
        rtol = self.rtol if target is None else float(target.rtol)
        self.driver.defaults["ksp_rtol"] = repr(rtol)         # read by set-ups (setFromOptions)
        self.driver.ksp.setTolerances(rtol=rtol)              # and by a reused preconditioner's KSP

    def _run(self, J, rhs, Ml, shift, nu, nl, po, new_step: bool = False, target=None):
        new = self._matrices(J, Ml, shift, nu, nl, po)
        self._sizes = (nu, nl, po, J.shape[0])
        if new:
            self._nsp_u = None if self.near_nullspace is None else near_nullspace(self._rows(self.near_nullspace,
                                                                                                np.arange(nu)))
        self.driver.operators(self._Jm, self._Pm, changed_pattern=new)
        self._forcing(target)
        if new:
            self._build_pc(nu, nl, po, J.shape[0])
        self._new_step = new_step
        lay = self._lay
        b = vec(rhs if lay is None else lay.local(rhs))
        x = self._Jm.createVecRight()
        r = x.duplicate()
        bn = b.norm()
        if bn == 0.0:
            self.driver.iterations.append(0)
            return np.zeros(len(rhs))

        def residual(xv):
            self._Jm.mult(xv, r)
            r.aypx(-1.0, b)
            return r.norm() / bn

        self.driver.solve(b, x, residual, rebuild=new_step)
        return x.getArray().copy() if lay is None else lay.gather(x.getArray())

    def _rows(self, data, serial):
        """This rank's rows of per-unknown ``data`` indexed by the serial unknowns ``serial`` (in the
        order of the field's index set)."""
        if self._lay is None:
            return data
        return np.asarray(data)[self._lay.field_rows(serial) - int(serial[0]) if len(serial) else []]

    def _is(self, idx, bs=1):
        """Index set of the field with the serial unknowns ``idx``: on N ranks this rank's owned
        rows of it in the distributed numbering."""
        lay = self._lay
        if lay is not None:
            idx = lay.field(idx)
        s = self.P.IS().createGeneral(np.asarray(idx, dtype=self.P.IntType),
                                      comm=self.P.COMM_SELF if lay is None else self.P.COMM_WORLD)
        if bs > 1:
            s.setBlockSize(bs)
        return s

    def _sub_is(self, idx):
        """Index set in the numbering of a sub-matrix whose rows are given (as this rank's part)."""
        lay = self._lay
        return self.P.IS().createGeneral(np.asarray(idx, dtype=self.P.IntType),
                                         comm=self.P.COMM_SELF if lay is None else self.P.COMM_WORLD)


def _amg_options(kind, prefix, nullspace, sym_graph=False):
    out = amg_defaults(kind, prefix, nullspace)
    if kind == "gamg" and sym_graph:
        # S from selfp is symmetric only up to the scaling of the contact rows
        out[f"{prefix}pc_gamg_sym_graph"] = "true"
    return out


def _multiplier_schur(rest: str) -> dict[str, str]:
    """Options of the outer split of GEOS's recipe: the multipliers "l" eliminated by a full Schur
    factorisation preconditioned by selfp, point-block Jacobi on them; the rest (split ``rest``:
    "u" for contact, "m" = (u, p) for poromechanics) with A⁻¹ approximated block-diagonally in S."""
    return {"pc_type": "fieldsplit", "pc_fieldsplit_type": "schur", "pc_fieldsplit_schur_fact_type": "full",
            "pc_fieldsplit_schur_precondition": "selfp", "fieldsplit_l_ksp_type": "preonly",
            "fieldsplit_l_pc_type": "pbjacobi", f"fieldsplit_{rest}_ksp_type": "preonly",
            f"fieldsplit_{rest}_mat_schur_complement_ainv_type": "blockdiag"}


@dataclass
class PetscBlockContactSolver(_FieldSplitBase):
    """GMRES + PCFIELDSPLIT (Schur, multipliers eliminated, AMG on S) for the contact Jacobian.

    Parameters as :class:`~polypore.solvers.block_contact.BlockContactSolver`, and
    amg : "hypre" (BoomerAMG, default) or "gamg" for the displacement block
    options : PETSc options without the prefix (``[solver.petsc]``)
    prefix : options prefix (default ``contact_``)
    reuse : ReusePolicy of the whole preconditioner across Newton iterations
    """

    takes_target = True          # solve() accepts Newton's KrylovTarget (its rtol: _forcing)
    n_u: int
    d: int
    condensation: ContactCondensation
    near_nullspace: np.ndarray | None = None
    rtol: float = 1e-8
    maxiter: int = 300
    restart: int = 100
    accept_rtol: float = 1e-6
    amg: str = "hypre"
    options: Mapping | None = None
    prefix: str = "contact_"
    reuse: ReusePolicy = field(default_factory=ReusePolicy)
    seconds: float = 0.0
    layouts: dict | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        nf = self.condensation.normal.shape[0]
        defaults = krylov_defaults(False, self.rtol, self.maxiter, self.restart)
        if nf:
            defaults.update({**_multiplier_schur("u"),
                             **_amg_options(self.amg, "fieldsplit_u_", self.near_nullspace is not None, True)})
        else:
            defaults.update(_amg_options(self.amg, "", self.near_nullspace is not None))
        self._init_common(self.prefix, defaults, self.options, self.reuse)

    def _build_pc(self, nu, nl, po, n):
        pc = self.driver.ksp.getPC()
        if nl:
            pc.setType("fieldsplit")
            pc.setFieldSplitIS(("l", self._is(np.arange(nu, po), self.d)), ("u", self._is(np.arange(nu), self.bs_u)))
        elif self._nsp_u is not None:
            self._Pm.setNearNullSpace(self._nsp_u)
            self._Pm.setBlockSize(self.bs_u) if self.bs_u > 1 else None

    def _configure(self, ksp):
        """After PCSetUp: the rigid-body modes on S (formed anew by selfp at each set-up)."""
        if self._nsp_u is None or not self.condensation.normal.shape[0]:
            return
        pc = ksp.getPC()
        if pc.getType() != "fieldsplit":
            return
        schur = pc.getFieldSplitSubKSP()[-1]
        S = schur.getOperators()[1]
        if self.bs_u > 1 and S.getBlockSize() != self.bs_u:
            S.setBlockSizes(self.bs_u, self.bs_u)
        S.setNearNullSpace(self._nsp_u)

    def solve(self, J, rhs, target=None) -> np.ndarray:
        """x with J x ≈ rhs: J (n, n) sparse, rhs (n,); ``target`` a KrylovTarget or None (rtol)."""
        t0 = time.perf_counter()
        J = _canonical(J)
        nu = self.n_u
        nl = J.shape[0] - nu
        Ml = None
        if nl:
            Clhat, Cu_s = modified_contact_blocks(self.condensation, J[nu:, :nu], J[nu:, nu:])
            nf, d = Clhat.shape[:2]
            Cl = sp.csr_matrix((Clhat.reshape(nf, -1).ravel(),
                                np.tile(np.arange(d), nf * d) + np.repeat(np.arange(nf) * d, d * d),
                                np.arange(0, nf * d * d + 1, d)), shape=(nl, nl))
            Ml = sp.hstack([Cu_s, Cl]).tocsr()
        x = self._run(J, rhs, Ml, None, nu, nl, nu + nl, target=target)
        self.seconds += time.perf_counter() - t0
        log.debug("PETSc block contact solver: %d GMRES iterations, %.2f s", self.iterations[-1],
                  time.perf_counter() - t0)
        return x


@dataclass
class PetscBlockPoroSolver(_FieldSplitBase):
    """GMRES + nested PCFIELDSPLIT for the coupled step Jacobian [u, l, p] (module docstring).

    Parameters as :class:`~polypore.solvers.block_contact.BlockPoroSolver`, and
    pressure : "auto"/"amg"/"gamg" (GAMG), "hypre" (BoomerAMG) or "lu"/"pardiso" (PETSc's LU,
        MUMPS): the Ŝ_p solve, set up again only when the flow block changes (a new time step)
    amg, options, prefix (default ``poro_``), reuse : as :class:`PetscBlockContactSolver`
    """

    takes_target = True          # solve() accepts Newton's KrylovTarget (its rtol: _forcing)
    n_u: int
    d: int
    n_l: int
    condensation: ContactCondensation
    near_nullspace: np.ndarray | None = None
    pressure_nullspace: np.ndarray | None = None
    pressure: str = "auto"
    rtol: float = 1e-8
    maxiter: int = 400
    restart: int = 100
    accept_rtol: float = 1e-6
    amg: str = "hypre"
    options: Mapping | None = None
    prefix: str = "poro_"
    reuse: ReusePolicy = field(default_factory=ReusePolicy)
    seconds: float = 0.0
    layouts: dict | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if self.pressure not in PRESSURE_SOLVERS:
            raise InputError("solver.pressure", f"unknown pressure solver {self.pressure!r}; allowed: "
                             f"{', '.join(PRESSURE_SOLVERS)}")
        m = "fieldsplit_m_" if self.n_l else ""
        u, p = m + "fieldsplit_u_", m + "fieldsplit_p_"
        defaults = krylov_defaults(False, self.rtol, self.maxiter, self.restart)
        if self.n_l:
            defaults.update(_multiplier_schur("m"))
        defaults.update({f"{m}pc_type": "fieldsplit", f"{m}pc_fieldsplit_type": "multiplicative",
                         f"{u}ksp_type": "preonly", f"{p}ksp_type": "preonly",
                         **_amg_options(self.amg, u, self.near_nullspace is not None, bool(self.n_l))})
        kind = {"auto": "gamg", "amg": "gamg", "gamg": "gamg", "hypre": "hypre"}.get(self.pressure)
        if kind:
            defaults.update(_amg_options(kind, p, False))
        else:
            defaults.update({f"{p}pc_type": "lu", f"{p}pc_factor_mat_solver_type": "mumps"})
        self._init_common(self.prefix, defaults, self.options, self.reuse)
        self._fkey = None
        self._lump = None
        self.pressure_builds = 0

    def _build_pc(self, nu, nl, po, n):
        pc = self.driver.ksp.getPC()
        if nl:
            pc.setType("fieldsplit")
            pc.setFieldSplitIS(("l", self._is(np.arange(nu, po), self.d)),
                               ("m", self._is(np.r_[np.arange(nu), np.arange(po, n)])))
        else:
            pc.setType("fieldsplit")
            pc.setFieldSplitIS(("u", self._is(np.arange(nu), self.bs_u)), ("p", self._is(np.arange(nu, n))))
        self._inner_split = False

    def _inner(self, ksp):
        """The multiplicative (u, p) fieldsplit PC: the outer one, or the Schur KSP's."""
        pc = ksp.getPC()
        if not self.n_l:
            return pc
        inner = pc.getFieldSplitSubKSP()[-1].getPC()
        if inner.getType() == "fieldsplit" and not self._inner_split:
            nu, _, po, n = self._sizes
            lay = self._lay
            if lay is None:
                nm = inner.getOperators()[1].getSize()[0]
                iu, ip = np.arange(nu), np.arange(nu, nm)
            else:
                # m = (u, p) is numbered by the ranks' owned rows of u and p in turn
                old = lay.perm[lay.field(np.r_[np.arange(nu), np.arange(po, n)])]
                m0 = int(lay.comm.exscan(len(old)) or 0)
                iu, ip = m0 + np.flatnonzero(old < nu), m0 + np.flatnonzero(old >= po)
            su = self._sub_is(iu)
            if self.bs_u > 1:
                su.setBlockSize(self.bs_u)
            inner.setFieldSplitIS(("u", su), ("p", self._sub_is(ip)))
            self._inner_split = True
        return inner

    def _configure(self, ksp):
        """After PCSetUp: inner splits, near-null spaces, and the pressure set-up kept within a step."""
        inner = self._inner(ksp)
        if inner.getType() != "fieldsplit":
            return
        inner.setUp()
        subs = inner.getFieldSplitSubKSP()
        if len(subs) != 2:
            return
        ku, kp = subs
        Su = ku.getOperators()[1]
        if self._nsp_u is not None:
            if self.bs_u > 1 and Su.getBlockSize() != self.bs_u:
                Su.setBlockSizes(self.bs_u, self.bs_u)
            Su.setNearNullSpace(self._nsp_u)
        if self.pressure_nullspace is not None:
            nu, _, po, n = self._sizes
            pns = self._rows(np.asarray(self.pressure_nullspace, float), np.arange(po, n))
            kp.getOperators()[1].setNearNullSpace(near_nullspace(pns))
        # Ŝ_p depends on the step only (F, and diag(A) in the lumped coupling): its set-up is kept
        # across the Newton iterations of a step, as BlockPoroSolver's _PressureSolve does
        kp.getPC().setReusePreconditioner(not self._new_step)
        if self._new_step:
            self.pressure_builds += 1

    def solve(self, J, rhs, target=None) -> np.ndarray:
        """x with J x ≈ rhs: J (n, n) sparse, rhs (n,); ``target`` a KrylovTarget or None (rtol)."""
        t0 = time.perf_counter()
        J = _canonical(J)
        nu, nl = self.n_u, self.n_l
        po = nu + nl
        A, Gup = J[:nu, :nu], J[:nu, po:]
        Gpu, F = J[po:, :nu], J[po:, po:]
        fkey = (F.shape, F.nnz)
        new_step = self._fkey is None or self._fkey[0] != fkey or not np.array_equal(self._fkey[1], F.data)
        if new_step:
            self._lump = np.asarray((Gpu @ sp.diags(1.0 / A.diagonal())).multiply(Gup.T).sum(axis=1)).ravel()
            self._fkey = (fkey, F.data.copy())
        Ml = None
        if nl:
            Clhat, Cu_s = modified_contact_blocks(self.condensation, J[nu:po, :nu], J[nu:po, nu:po])
            nf, d = Clhat.shape[:2]
            Cl = sp.csr_matrix((Clhat.reshape(nf, -1).ravel(),
                                np.tile(np.arange(d), nf * d) + np.repeat(np.arange(nf) * d, d * d),
                                np.arange(0, nf * d * d + 1, d)), shape=(nl, nl))
            Ml = sp.hstack([Cu_s, Cl, sp.csr_matrix((nl, J.shape[0] - po))]).tocsr()
        x = self._run(J, rhs, Ml, self._lump, nu, nl, po, new_step, target)
        self.seconds += time.perf_counter() - t0
        log.debug("PETSc block poro solver: %d GMRES iterations, %.2f s", self.iterations[-1],
                  time.perf_counter() - t0)
        return x
