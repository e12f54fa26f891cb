"""The block preconditioners of :mod:`.block_contact` with PETSc: the solvers of ``block-petsc``.

Two structures apply the same preconditioner. The default, "condensed" (:mod:`.petsc_condensed`),
eliminates the multipliers in polypore and gives PETSc only the blocks it applies (a petsc4py
``python`` PC around two AMG KSPs); ``pc_type = "fieldsplit"`` (``[solver.petsc]`` or
``-poro_pc_type fieldsplit``) builds it from PETSc's PCFIELDSPLIT as below, at the price of
several copies of P's blocks (docs/parallel.md). This docstring describes the fieldsplit form.

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
small meshes) have zero rows in the rigid-body modes (docs/parallel.md). Every option can be
overridden through ``options`` (without the solver's prefix, ``contact_`` or ``poro_`` by default)
or on PETSc's command line with it.

On N ranks (``mpiexec``, :mod:`polypore.parallel.layout`): each rank has only its rows of J (the models assemble
them, :class:`~polypore.parallel.layout.OwnedRows`; a whole J is cut with the registered
:class:`~polypore.parallel.layout.DofLayout`) and builds its rows of P from them: Cl̂ and Cû are row-local (a
fracture face's rows are one rank's), Ŝ_p's diagonal needs G_up,ji / A_jj of displacement rows j
held by other ranks, which one Alltoallv brings (:func:`lumped_coupling`). The index sets of the
splits are each rank's owned rows of a field, and the solution is gathered on every rank.
"""

from __future__ import annotations

import hashlib
import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..core.errors import InputError
from ..core.memory import trim_heap
from .block_contact import ContactCondensation, _diag_blocks
from ..parallel.layout import DofLayout, OwnedRows, _mpi, layout_for
from ..parallel.context import context
from .petsc import (AMG_KINDS, KrylovDriver, PetscStats, aij, amg_defaults, collect_garbage,
                    interleaved_block_size, krylov_defaults, near_nullspace, petsc, petsc_options, vec)
from .interface import BlockOptions, SolverDefaults
from .petsc_condensed import CondensedPreconditioner, csr_keys as _keys
from ..core.timing import SPLIT

log = logging.getLogger("polypore")

PRESSURE_SOLVERS = ("auto", "amg", "gamg", "hypre", "lu", "pardiso")


def modified_contact_blocks(cond: ContactCondensation, Cu, Cl):
    """(Cl̂ as (nf, d, d) blocks, Cû csr): ContactCondensation.condense without forming S.

    DP̂_σ = DP_σ − g nᵀ (friction–normal coupling dropped), Cl̂_σ = c_σ (I − (1 − ρ) DP̂_σ),
    Cû = Cu − g (nᵀ Cu) face by face; see block_contact's module docstring.
    """
    nf, d = cond.normal.shape
    return _modified(cond, _diag_blocks(Cl, nf, d), Cu)


def _modified(cond: ContactCondensation, Cl_blocks: np.ndarray, Cu):
    """Cl̂ (nf, d, d) and Cû (csr, Cu's shape) from the diagonal blocks of C_λ (nf, d, d) and the
    contact rows' displacement part Cu (nf d, any columns): :func:`modified_contact_blocks`."""
    nf, d = cond.normal.shape
    c, n = cond.scale, cond.normal
    DP = np.eye(d)[None] - Cl_blocks / c[:, None, None]
    DPn = np.einsum("fij,fj->fi", DP, n)
    g = DPn - np.einsum("fi,fi->f", n, DPn)[:, None] * n
    DPs = DP - np.einsum("fi,fj->fij", g, n)
    Clhat = c[:, None, None] * (np.eye(d)[None] - (1.0 - cond.rho) * DPs)
    N = sp.csr_matrix((n.ravel(), (np.repeat(np.arange(nf), d), np.arange(nf * d))), shape=(nf, nf * d))
    Gm = sp.csr_matrix((g.ravel(), (np.arange(nf * d), np.repeat(np.arange(nf), d))), shape=(nf * d, nf))
    Cu_s = (sp.csr_matrix(Cu) - Gm @ (N @ Cu)).tocsr()
    return Clhat, Cu_s


class _RowBlocks:
    """Where the fields lie in the rows a rank passes PETSc (all rows serially).

    The rows are the owned unknowns in serial order, so the displacement, multiplier and pressure
    rows are three consecutive ranges [0, nu), [nu, po), [po, n_rows); the columns are global
    (the distributed numbering on N ranks, the serial one on one process).

    Attributes
    ----------
    layout : DofLayout or None (serial)
    row0 : global number of the first row
    nu, po, n_rows : local row ranges (displacements [0, nu), multipliers [nu, po), pressures after)
    n : global number of unknowns
    faces : (nf_local,) fracture faces (serial numbers) whose multiplier rows these are, in row order
    kind : (n,) int8, field of every global column: 0 u, 1 multiplier, 2 pressure
    """

    def __init__(self, lay, n: int, nu_global: int, po_global: int, d: int):
        self.layout, self.n = lay, n
        if lay is None:
            self.row0, self.nu, self.po, self.n_rows = 0, nu_global, po_global, n
            serial = None
        else:
            own = lay.owned
            self.row0, self.n_rows = lay.start, lay.n_local
            self.nu, self.po = (int(v) for v in np.searchsorted(own, [nu_global, po_global]))
            serial = lay.perm
        self.faces = (np.arange(nu_global, po_global, d) if lay is None else lay.owned[self.nu:self.po:d]) - nu_global
        self.faces //= d
        col = np.arange(n) if serial is None else serial
        self.kind = ((col >= nu_global).astype(np.int8) + (col >= po_global)).astype(np.int8)


def contact_rows(cond: ContactCondensation, R: sp.csr_matrix, blk: _RowBlocks) -> sp.csr_matrix | None:
    """The contact rows of P: [Cû | Cl̂] (nl_local, n), columns as R's, from R's contact rows.

    Each face's d rows and its own multiplier columns are this rank's (a face belongs to one rank),
    so Cl̂ and Cû are computed from the rows at hand (:func:`modified_contact_blocks`)."""
    a, b = blk.nu, blk.po
    if b == a:
        return None
    d = cond.normal.shape[1]
    Clhat, Cu_s = contact_blocks(cond, R, blk)
    nfl = (b - a) // d
    rl = (np.arange(nfl)[:, None, None] * d + np.arange(d)[None, :, None]) + 0 * np.arange(d)[None, None, :]
    cl = blk.row0 + a + np.swapaxes(rl, 1, 2)
    Cl = sp.csr_matrix((Clhat.ravel(), (rl.ravel(), cl.ravel())), shape=(b - a, blk.n))
    return (Cu_s + Cl).tocsr()


def contact_blocks(cond: ContactCondensation, R: sp.csr_matrix, blk: _RowBlocks):
    """(Cl̂ (nf_local, d, d), Cû csr (nl_local, n), columns as R's) of this rank's faces, from R's
    contact rows (:func:`contact_rows` without summing them into one matrix)."""
    a, b = blk.nu, blk.po
    d = cond.normal.shape[1]
    nfl = (b - a) // d
    M = R[a:b].tocoo()
    f = M.row // d
    loc = M.col.astype(np.int64) - (blk.row0 + a)          # position among this rank's multipliers
    own = (loc >= 0) & (loc < b - a) & (loc // d == f)
    Clb = np.zeros((nfl, d, d))
    np.add.at(Clb, (f[own], M.row[own] % d, loc[own] % d), M.data[own])
    isu = blk.kind[M.col] == 0
    Cu = sp.csr_matrix((M.data[isu], (M.row[isu], M.col[isu])), shape=(b - a, blk.n))
    sub = ContactCondensation(cond.scale[blk.faces], cond.normal[blk.faces], cond.rho)
    return _modified(sub, Clb, Cu)


def contact_pattern(R: sp.csr_matrix, blk: _RowBlocks, d: int) -> sp.csr_matrix:
    """Fixed pattern (ones, nl_local × n) of Cû on this rank: each face's d rows get the union of
    their displacement columns in R (Cû mixes a face's rows: :func:`modified_contact_blocks`)."""
    a, b = blk.nu, blk.po
    if b == a:
        return sp.csr_matrix((0, blk.n))
    rows = sp.csr_matrix(R[a:b])
    rows.data = (blk.kind[rows.indices] == 0).astype(float)
    rows.eliminate_zeros()
    face = sp.kron(sp.identity((b - a) // d, format="csr"), np.ones((d, d)), format="csr")
    L = (face @ rows).tocsr()
    L.sum_duplicates()
    L.sort_indices()
    L.data[:] = 1.0
    return L


def lumped_coupling(R: sp.csr_matrix, blk: _RowBlocks) -> np.ndarray:
    """(n_p_local,) Σ_j G_pu,ij G_up,ji / A_jj for this rank's pressure rows i (Ŝ_p = F − diag(·)).

    The displacement row j that holds G_up,ji and A_jj may be another rank's: each rank sends
    (i, j, G_up,ji / A_jj) of its displacement rows to the owner of the pressure i (one
    Alltoallv; serially the triples stay here), which multiplies by its G_pu,ij. Works on R's CSR
    arrays and the entries of the two coupling blocks only: converting R's rows to coordinates
    was a per-step memory peak (docs/parallel.md).
    """
    nu, po, row0, n = blk.nu, blk.po, blk.row0, blk.n
    lay = blk.layout
    diag = R.diagonal(k=row0)[:nu]                           # A_jj of this rank's rows j
    a = int(R.indptr[po])
    gup = np.flatnonzero(blk.kind[R.indices[:int(R.indptr[nu])]] == 2)        # entries G_up,ji
    gj = np.searchsorted(R.indptr, gup, side="right") - 1                     # their local row j
    gi = R.indices[gup].astype(np.int64)                                      # pressure column i
    w = R.data[gup] / diag[gj]
    gj = gj.astype(np.int64) + row0
    del gup
    if lay is None:
        recv = (gi, gj, w)
    else:
        ends = lay.displs + lay.counts
        dest = np.searchsorted(ends, gi, side="right")
        order = np.argsort(dest, kind="stable")
        send = np.stack([gi[order].astype(float), gj[order].astype(float), w[order]], axis=1)  # < 2^53: exact
        del order, gi, gj, w
        size = lay.comm.Get_size()
        scount = np.bincount(dest, minlength=size).astype(np.int64)
        rcount = np.asarray(lay.comm.alltoall(scount.tolist()), np.int64)
        buf = np.empty((int(rcount.sum()), 3))
        sd = np.concatenate([[0], np.cumsum(scount)[:-1]]) * 3
        rd = np.concatenate([[0], np.cumsum(rcount)[:-1]]) * 3
        MPI = _mpi()
        lay.comm.Alltoallv([np.ascontiguousarray(send), (scount * 3, sd), MPI.DOUBLE],
                           [buf, (rcount * 3, rd), MPI.DOUBLE])
        del send
        recv = (buf[:, 0].astype(np.int64), buf[:, 1].astype(np.int64), buf[:, 2])
    out = np.zeros(blk.n_rows - po)
    gpu = a + np.flatnonzero(blk.kind[R.indices[a:]] == 0)                   # entries G_pu,ij
    if not gpu.size or not recv[0].size:
        return out
    prow = np.searchsorted(R.indptr, gpu, side="right") - 1 - po
    keys = prow.astype(np.int64) * n + R.indices[gpu]                         # sorted: rows, then columns
    ri = recv[0] - row0 - po
    k = ri * n + recv[1]
    pos = np.minimum(np.searchsorted(keys, k), len(keys) - 1)
    hit = keys[pos] == k                       # G_up,ji without a G_pu,ij adds nothing
    np.add.at(out, ri[hit], R.data[gpu[pos[hit]]] * recv[2][hit])
    return out


class _PreconditionerPattern:
    """Fixed CSR pattern of P ⊇ pattern(J) ∪ whole d×d blocks in the contact rows (each face's rows
    get the union of their columns) ∪ the pressure diagonal, for the rows R a rank passes (all rows
    serially); maps J's and the modified blocks' values into it. Indices are kept as int32 where
    they fit: P's pattern is the largest array of the preconditioner's set-up."""

    def __init__(self, R: sp.csr_matrix, blk: _RowBlocks, d: int):
        nu, po, nr, n, row0 = blk.nu, blk.po, blk.n_rows, blk.n, blk.row0
        S = sp.csr_matrix((np.ones(R.nnz), R.indices, R.indptr), shape=R.shape)
        if po > nu:
            nl = po - nu
            face = sp.kron(sp.identity(nl // d, format="csr"), np.ones((d, d)), format="csr")
            rows = sp.csr_matrix(S[nu:po])
            rows.data[:] = 1.0
            own = sp.csr_matrix((np.ones(face.nnz), face.indices + row0 + nu, face.indptr), shape=(nl, n))
            S = sp.vstack([S[:nu], face @ rows + own, S[po:]]).tocsr()
        pr = np.arange(po, nr)
        S = (S + sp.csr_matrix((np.ones(pr.size), (pr, row0 + pr)), shape=S.shape)).tocsr()
        S.sum_duplicates()
        S.sort_indices()
        it = np.int32 if n < 2**31 - 1 and S.nnz < 2**31 - 1 else np.int64
        keys = _keys(S.indptr, S.indices, n)
        if S.nnz == R.nnz:
            # J's pattern has them all already (C5: the face blocks and the pressure diagonal are
            # in it): P shares J's index arrays, its values start as J's
            self.indptr, self.indices, self.pos_J = R.indptr, R.indices, None
        else:
            self.indptr, self.indices = S.indptr.astype(it), S.indices.astype(it)
            self.pos_J = np.searchsorted(keys, _keys(R.indptr, R.indices, n)).astype(it)
        self.shape = S.shape
        self.a, self.b = int(S.indptr[nu]), int(S.indptr[po])
        self.keys_l = keys[self.a:self.b].copy()       # a view would keep all of P's keys alive
        self.pos_pdiag = np.searchsorted(keys, pr * n + row0 + pr).astype(it)
        self.nu, self.n = nu, n

    def values(self, R: sp.csr_matrix, Ml: sp.csr_matrix | None, pdiag_shift) -> np.ndarray:
        """P's data: R's values, the contact rows from Ml (nl × n, csr), the pressure diagonal − shift."""
        if self.pos_J is None:
            out = np.array(R.data, float)
        else:
            out = np.zeros(len(self.indices))
            out[self.pos_J] = R.data
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


def structure(prefix: str, options: Mapping | None) -> str:
    """How a block solver preconditions: "fieldsplit" (PETSc's PCFIELDSPLIT, this module's
    docstring) when ``pc_type = "fieldsplit"`` is asked for in ``options`` or PETSc's options
    database (under ``prefix``), else "condensed" (:mod:`.petsc_condensed`: the same
    preconditioner with a fraction of PCFIELDSPLIT's matrices)."""
    pct = petsc_options(options).get("pc_type")
    if pct is None:
        db = petsc().Options()
        pct = db.getString(prefix + "pc_type") if db.hasName(prefix + "pc_type") else None
    return "fieldsplit" if pct == "fieldsplit" else "condensed"


def _canonical(J) -> sp.csr_matrix:
    J = sp.csr_matrix(J)
    J.sum_duplicates()
    J.sort_indices()
    return J


def _same_buffer(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two arrays are views of one buffer (the model's fixed pattern, refilled)."""
    return (a.shape == b.shape and a.dtype == b.dtype
            and a.__array_interface__["data"][0] == b.__array_interface__["data"][0])


class _FieldSplitBase(SolverDefaults):
    """Shared machinery: PETSc matrices updated in place, the driver, the true-residual check.

    A Jacobian arrives whole (serial numbering; on N ranks each rank cuts out its rows with the
    registered layout) or as this rank's rows (:class:`~polypore.parallel.layout.OwnedRows`, what the models
    assemble on N ranks). Everything after works on the rows at hand: P (Cl̂, Cû, Ŝ_p) is built
    for them only and they go to PETSc as they are.
    """

    backend = "block-petsc"
    # fields and methods of the dataclass subclasses
    d: int
    n_u: int
    _po: Callable[[int], int]
    structure: str
    near_nullspace: np.ndarray | None
    pressure_nullspace: np.ndarray | None
    _build_pc: Callable[..., Any]

    def _init_common(self, prefix, defaults, options, reuse):
        if self.amg not in AMG_KINDS:
            raise InputError("amg", f"unknown AMG {self.amg!r}; allowed: {', '.join(AMG_KINDS)}")
        self.P = petsc()
        if self.P.COMM_WORLD.getSize() > 1 and context() is None:
            raise InputError("backend", "the PETSc block solvers run on N ranks in a distributed run "
                             "only (polypore.parallel.context.activate(); docs/parallel.md)")
        self._lay = None
        self.bs_u = interleaved_block_size(self.near_nullspace, self.d)
        self.driver = KrylovDriver(prefix, defaults, options, reuse, self.rtol, self.maxiter, self.accept_rtol,
                                   configure=self._configure)
        self._Jm = self._Pm = self._pat = self._key = self._blk = None
        self._nsp_u = None
        self._cpc = None

    @property
    def stats(self) -> PetscStats:
        return self.driver.stats

    @property
    def iterations(self) -> list[int]:
        return self.driver.iterations

    @iterations.setter
    def iterations(self, value):
        self.driver.iterations = value

    @property
    def krylov_iterations(self) -> list[int]:
        return self.driver.iterations

    def _rows_of(self, J, nu: int, po: int):
        """(R, blocks): the rows this rank passes PETSc (csr, canonical; all rows serially) and where
        the fields lie in them (:class:`_RowBlocks`, rebuilt when the layout changes)."""
        lay: DofLayout | None
        if isinstance(J, OwnedRows):
            lay = J.layout
            R = _canonical(J.take())
        else:
            J = _canonical(J)
            lay = layout_for(self, J.shape[0])
            R = J if lay is None else lay.rows(J)
        n = lay.n if lay is not None else R.shape[0]
        if self._blk is None or self._blk.layout is not lay or self._blk.n != n:
            self._blk = _RowBlocks(lay, n, nu, po, self.d)
        self._lay = lay
        return R, self._blk

    def _pattern_changed(self, R) -> bool:
        """Whether R's pattern differs from the last solve's (on N ranks: on any rank). The arrays of
        the last pattern are kept by reference only: a model's fixed pattern passes the same buffer
        every time, so nothing is copied."""
        old = self._key
        same = old is not None and old[0] == R.shape and (
            (_same_buffer(old[1], R.indptr) and _same_buffer(old[2], R.indices))
            or (np.array_equal(old[1], R.indptr) and np.array_equal(old[2], R.indices)))
        changed = not same
        if self._lay is not None:
            changed = bool(self._lay.comm.allreduce(int(changed), op=_mpi().MAX))
        if changed:
            self._key = (R.shape, R.indptr, R.indices)
        return changed

    def _matrices(self, R, Ml, shift, blk, new):
        """Update (or create, for a new pattern) the PETSc J and P from this rank's rows R."""
        if new:
            with SPLIT.timed("preconditioner"):
                self._pat = _PreconditionerPattern(R, blk, self.d)
            self._Jm = self._Pm = None
        t0 = time.perf_counter()
        self._Jm = aij(R, mat=self._Jm)
        with SPLIT.timed("preconditioner"):
            Pdata = self._pat.values(R, Ml, shift)
            self._Pm = aij(self._pat.matrix(Pdata), mat=self._Pm)
            del Pdata
        self.driver.stats.convert_seconds += time.perf_counter() - t0

    def _condensed(self, R, blk, new, lump, prefix_u, prefix_p):
        """The condensed preconditioner's blocks (built for a new pattern, refilled always) and J
        into PETSc, from this rank's rows R (:mod:`.petsc_condensed`)."""
        with SPLIT.timed("preconditioner"):
            has_l = blk.po > blk.nu
            Clhat, Cu = contact_blocks(self.condensation, R, blk) if has_l else (np.zeros((0, self.d, self.d)),
                                                                                  sp.csr_matrix((0, blk.n)))
            if new:
                if self._cpc is not None:
                    self._cpc.destroy()
                self._cpc = CondensedPreconditioner(blk, self.d, prefix_u, prefix_p, self.bs_u, None,
                                                    on_pressure_build=self._pressure_built if prefix_p else None)
                self._cpc.build(R, contact_pattern(R, blk, self.d))
            self._cpc.update(R, Clhat, Cu, lump)
            del Clhat, Cu
        t0 = time.perf_counter()
        if new:
            self._Jm = None
        self._Jm = aij(R, mat=self._Jm)
        self._Pm = None
        self.driver.stats.convert_seconds += time.perf_counter() - t0

    def _pressure_built(self):
        self.pressure_builds += 1

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

    def _run(self, blk, rhs, new, new_step: bool = False, target=None):
        """The Krylov solve once :meth:`_matrices` has put J and P into PETSc (the caller has let
        go of its rows by then: they are not needed during the iterations)."""
        n = blk.n
        nu, po = self.n_u, self._po(n)                      # the fields in the serial numbering
        self._sizes = (nu, po - nu, po, n)
        cpc = self._cpc if self.structure == "condensed" else None
        if new:
            self._nsp_u = None if self.near_nullspace is None else near_nullspace(self._rows(self.near_nullspace,
                                                                                                np.arange(nu)))
            if cpc is not None:
                cpc.nsp_u = self._nsp_u
        self.driver.operators(self._Jm, self._Pm, changed_pattern=new)
        self._forcing(target)
        if new:
            if cpc is not None:
                pc = self.driver.ksp.getPC()
                pc.setType("python")
                pc.setPythonContext(cpc)
            else:
                self._build_pc(nu, po - nu, po, n)
        self._new_step = new_step
        if cpc is not None:
            cpc.new_step = cpc.new_step or new_step
            if cpc.has_p and self.pressure_nullspace is not None and (new or new_step):
                cpc.pressure_nullspace = self._rows(np.asarray(self.pressure_nullspace, float), np.arange(po, n))
        lay = self._lay
        b = vec(rhs if lay is None else lay.local(rhs))
        x = self._Jm.createVecRight()
        r = x.duplicate()
        bn = b.norm()
        if bn == 0.0:
            self.driver.iterations.append(0)
            out = np.zeros(len(rhs))
        else:
            def residual(xv):
                self._Jm.mult(xv, r)
                r.aypx(-1.0, b)
                return r.norm() / bn

            self.driver.solve(b, x, residual, rebuild=new_step)
            out = x.getArray().copy() if lay is None else lay.gather(x.getArray())
        for v in (b, x, r):         # collective: not left to Python's garbage (petsc.collect_garbage)
            v.destroy()
        return out

    def release(self) -> None:
        """Free the PETSc matrices, the KSP and P's pattern (a solver that is done, e.g. the initial
        equilibrium's); the next solve builds them again."""
        self.driver.destroy()
        for m in (self._Jm, self._Pm):
            if m is not None:
                m.destroy()
        if self._cpc is not None:
            self._cpc.destroy()
        self._Jm = self._Pm = self._pat = self._key = self._blk = self._cpc = None
        self._nsp_u = None
        collect_garbage(self.driver.comm)

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
class PetscBlockContactSolver(_FieldSplitBase, BlockOptions):
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
    prefix: str = "contact_"
    seconds: float = 0.0
    layouts: dict | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        nf = self.condensation.normal.shape[0]
        self.structure = structure(self.prefix, self.options) if nf else "plain"
        defaults = krylov_defaults(False, self.rtol, self.maxiter, self.restart)
        if nf:
            defaults.update({**(_multiplier_schur("u") if self.structure == "fieldsplit" else
                                {"fieldsplit_u_ksp_type": "preonly"}),
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
        if self._nsp_u is None or self.structure != "fieldsplit":
            return
        pc = ksp.getPC()
        if pc.getType() != "fieldsplit":
            return
        schur = pc.getFieldSplitSubKSP()[-1]
        S = schur.getOperators()[1]
        if self.bs_u > 1 and S.getBlockSize() != self.bs_u:
            S.setBlockSizes(self.bs_u, self.bs_u)
        S.setNearNullSpace(self._nsp_u)

    def _po(self, n: int) -> int:
        return n                                           # [u, l]: the multipliers fill the rest

    def solve(self, J, rhs, target=None) -> np.ndarray:
        """x with J x ≈ rhs: J (n, n) sparse or this rank's rows (OwnedRows), rhs (n,) replicated;
        ``target`` a KrylovTarget or None (rtol)."""
        t0 = time.perf_counter()
        R, blk = self._rows_of(J, self.n_u, J.shape[0])
        new = self._pattern_changed(R)
        if self.structure == "condensed":
            self._condensed(R, blk, new, None, self.prefix + "fieldsplit_u_", None)
        else:
            with SPLIT.timed("preconditioner"):
                Ml = contact_rows(self.condensation, R, blk)
            self._matrices(R, Ml, None, blk, new)
            del Ml
        del R                       # in PETSc now; OwnedRows.take() left no other reference
        x = self._run(blk, rhs, new, target=target)
        self.seconds += time.perf_counter() - t0
        log.debug("PETSc block contact solver: %d GMRES iterations, %.2f s", self.iterations[-1],
                  time.perf_counter() - t0)
        return x


@dataclass
class PetscBlockPoroSolver(_FieldSplitBase, BlockOptions):
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
    prefix: str = "poro_"
    maxiter: int = field(default=400, kw_only=True)
    seconds: float = 0.0
    layouts: dict | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if self.pressure not in PRESSURE_SOLVERS:
            raise InputError("pressure", f"unknown pressure solver {self.pressure!r}; allowed: "
                             f"{', '.join(PRESSURE_SOLVERS)}")
        m = "fieldsplit_m_" if self.n_l else ""
        u, p = m + "fieldsplit_u_", m + "fieldsplit_p_"
        self._prefixes = (self.prefix + u, self.prefix + p)
        self.structure = structure(self.prefix, self.options)
        defaults = krylov_defaults(False, self.rtol, self.maxiter, self.restart)
        if self.structure == "fieldsplit":
            if self.n_l:
                defaults.update(_multiplier_schur("m"))
            defaults.update({f"{m}pc_type": "fieldsplit", f"{m}pc_fieldsplit_type": "multiplicative"})
        defaults.update({f"{u}ksp_type": "preonly", f"{p}ksp_type": "preonly",
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

    def set_pressure_nullspace(self, b) -> None:
        """The near-null space of the pressure block for the coming systems (``pressure_nullspace``)."""
        self.pressure_nullspace = b

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
        if self.structure != "fieldsplit":
            return
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

    def _po(self, n: int) -> int:
        return self.n_u + self.n_l

    def solve(self, J, rhs, target=None) -> np.ndarray:
        """x with J x ≈ rhs: J (n, n) sparse or this rank's rows (OwnedRows), rhs (n,) replicated;
        ``target`` a KrylovTarget or None (rtol)."""
        t0 = time.perf_counter()
        nu, nl = self.n_u, self.n_l
        R, blk = self._rows_of(J, nu, nu + nl)
        new = self._pattern_changed(R)
        with SPLIT.timed("preconditioner"):
            # a new time step when F (the pressure rows' pressure columns) changed: a digest of its
            # values instead of a copy
            a = int(R.indptr[blk.po])
            fv = R.data[a:][blk.kind[R.indices[a:]] == 2]
            fkey = (fv.size, hashlib.blake2b(fv.tobytes(), digest_size=16).digest())
            del fv
            new_step = self._fkey != fkey
            if blk.layout is not None:
                new_step = bool(blk.layout.comm.allreduce(int(new_step), op=_mpi().MAX))
            if new_step:
                self._lump = lumped_coupling(R, blk)
                self._fkey = fkey
                trim_heap()         # its temporaries, before PETSc's set-ups allocate (core/memory.py)
        if self.structure == "condensed":
            self._condensed(R, blk, new, self._lump, *self._prefixes)
        else:
            with SPLIT.timed("preconditioner"):
                Ml = contact_rows(self.condensation, R, blk) if nl else None
            self._matrices(R, Ml, self._lump, blk, new)
            del Ml
        del R                       # in PETSc now; OwnedRows.take() left no other reference
        x = self._run(blk, rhs, new, new_step, target)
        self.seconds += time.perf_counter() - t0
        log.debug("PETSc block poro solver: %d GMRES iterations, %.2f s", self.iterations[-1],
                  time.perf_counter() - t0)
        return x
