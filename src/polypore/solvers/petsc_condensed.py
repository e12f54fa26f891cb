"""The block preconditioners of :mod:`.block_contact` with the multipliers condensed by polypore
and the AMG sub-solves in PETSc: a petsc4py ``python`` PC (the default of the ``block-petsc``
solvers; ``pc_type = "fieldsplit"`` selects PETSc's PCFIELDSPLIT instead, :mod:`.petsc_fieldsplit`).

It applies exactly what the fieldsplit recipe applies (full Schur factorisation on the multipliers
with point-block Jacobi, ``selfp``, then a multiplicative (u, p) split of the Schur block)::

    y_l = Cl̂⁻¹ r_l
    z   = r_m − Bt y_l                                   (m = u, p)
    x_u = AMG(S_uu) z_u
    x_p = AMG(S_pp) (z_p − S_pu x_u)
    x_l = y_l − (Cl̂⁻¹ Cû) x_m

with S = P_mm − Bt Cl̂⁻¹ Cû (P: J with Cl̂, Cû in the contact rows and Ŝ_p in the pressure block),
but holds only the blocks it applies. PCFIELDSPLIT extracts P's whole (u, p) block, forms S from it
(MatMatMult and MatAXPY into a new matrix at every Newton iteration), then copies S's rows of each
inner split and its diagonal blocks: about five matrices of J's size besides J and P. Here PETSc holds
J, S_uu, S_pp, S_pu and two small contact matrices; the product Bt (Cl̂⁻¹ Cû), nonzero near the
fractures only, is the one PETSc product (it needs the contact rows of other ranks' faces). PETSc's own
allocations per rank fall by about a third and the set-up scales better with ranks (docs/parallel.md).

Every matrix keeps one nonzero pattern per Jacobian pattern (values refilled in place), so the
AMG set-ups and the product reuse PETSc's structures. Option names are those of the fieldsplit
recipe: the displacement AMG reads ``fieldsplit_m_fieldsplit_u_*`` (``fieldsplit_u_*`` without
multipliers or pressures), the pressure AMG ``fieldsplit_m_fieldsplit_p_*`` (``fieldsplit_p_*``
without multipliers), each under the solver's prefix.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.sparse as sp

from .petsc import aij, near_nullspace, petsc


def field_index(blk) -> tuple[np.ndarray, np.ndarray]:
    """(index, totals): the index of every global column within its own field (u, l or p), every
    field numbered rank by rank (the layout of a PETSc matrix of one field), and the global sizes
    (3,) of the fields. ``blk`` is the solver's :class:`~.petsc_fieldsplit._RowBlocks`."""
    lay = blk.layout
    mine = (blk.nu, blk.po - blk.nu, blk.n_rows - blk.po)
    counts = [mine] if lay is None else lay.comm.allgather(mine)
    starts = [0] if lay is None else [int(s) for s in lay.displs]
    it = np.int32 if blk.n < 2**31 - 1 else np.int64
    idx = np.empty(blk.n, it)
    off = np.zeros(3, np.int64)
    for s, c in zip(starts, counts, strict=True):           # one pass per rank, not per unknown
        for f in range(3):
            idx[s:s + c[f]] = off[f] + np.arange(c[f])
            s += c[f]
        off += c
    return idx, off


class _Block:
    """One block with a fixed pattern: J's entries of the block (rows, cols: row-major, as in J) ∪
    extra entries (the product's, the pressure diagonal), whose positions :meth:`positions` gives
    while the block is built (``extra`` (rows, cols) pairs). Only the int32 pattern and a mask of
    J's entries are kept; the values live in PETSc's matrix (:meth:`to_petsc`)."""

    def __init__(self, rows, cols, nrows: int, ncols: int, extra=(), want=()):
        kj = rows.astype(np.int64) * ncols + cols
        ke = np.unique(np.concatenate([r.astype(np.int64) * ncols + c for r, c in extra])) if extra else kj[:0]
        keys = np.union1d(kj, ke) if ke.size else kj
        self.from_j = None if keys.size == kj.size else np.isin(keys, kj, assume_unique=True)
        self.size = keys.size
        it = np.int32 if max(ncols, keys.size) < 2**31 - 1 else np.int64
        self.indptr = np.zeros(nrows + 1, it)
        np.cumsum(np.bincount(keys // ncols, minlength=nrows), out=self.indptr[1:])
        self.indices = (keys % ncols).astype(it)
        self.shape = (nrows, ncols)
        # positions of the entries asked for in ``want`` (rows, cols), which the pattern holds
        self.pos = [np.searchsorted(keys, r.astype(np.int64) * ncols + c).astype(it) for r, c in want]
        self.mat = None

    def values(self, jvals) -> np.ndarray:
        """(size,) values with J's entries ``jvals`` (in J's order) and zeros elsewhere."""
        if self.from_j is None:
            return np.array(jvals, float)
        out = np.zeros(self.size)
        out[self.from_j] = jvals
        return out

    def to_petsc(self, data, comm, bs: int = 1):
        """The block's PETSc matrix with values ``data`` (created once, refilled in place)."""
        self.mat = aij(sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape), comm, bs, self.mat)
        return self.mat

    def destroy(self):
        if self.mat is not None:
            self.mat.destroy()
            self.mat = None


class CondensedPreconditioner:
    """petsc4py ``python`` PC context: the multipliers condensed as in the module docstring.

    Built for one pattern of J's rows on this rank (:meth:`build`), refilled for every Newton system
    (:meth:`update`), set up by PETSc's PCSetUp (:meth:`setUp`: the AMG of S_uu, and of S_pp when
    ``new_step``), applied by GMRES (:meth:`apply`).

    Parameters
    ----------
    blk : the solver's _RowBlocks (rows: u [0, nu), l [nu, po), p [po, n_rows))
    d : space dimension (multiplier block size)
    prefix_u, prefix_p : full option prefixes of the displacement and pressure sub-solves (p: None
        for contact)
    bs_u : block size of the displacement unknowns
    nsp_u : rigid-body near-null space (MatNullSpace of this rank's u rows) or None
    on_pressure_build : called at every set-up of the pressure AMG
    """

    def __init__(self, blk, d: int, prefix_u: str, prefix_p: str | None, bs_u: int, nsp_u, on_pressure_build=None):
        self.P = petsc()
        self.blk, self.d = blk, d
        self.comm = self.P.COMM_WORLD          # one rank serially, as everywhere in the PETSc solvers
        self.prefix_u, self.prefix_p = prefix_u, prefix_p
        self.bs_u, self.nsp_u = bs_u, nsp_u
        self.new_step = True
        self.pressure_nullspace = None        # this rank's pressure rows of it, set by the solver
        self.on_pressure_build = on_pressure_build
        self.ku = self.kp = None
        self._vecs = None
        self._nsp_p = None

    # ---- structure (once per pattern of J) --------------------------------------------------
    def build(self, R: sp.csr_matrix, lpattern: sp.csr_matrix):
        """Patterns of every block from this rank's rows R (csr, canonical) and the fixed pattern of
        the contact rows' displacement part (``lpattern``, nl_local × n; no rows without multipliers).
        """
        blk = self.blk
        nu, po, nr, n = blk.nu, blk.po, blk.n_rows, blk.n
        self.fidx, totals = field_index(blk)
        self.has_l, self.has_p = totals[1] > 0, self.prefix_p is not None
        rows = np.repeat(np.arange(nr, dtype=np.int32), np.diff(R.indptr))
        ck = blk.kind[R.indices]
        # which block each of J's entries goes to: 0 S_uu, 1 S_pu, 2 S_pp, 3 Bt, −1 none
        bid = np.full(R.nnz, -1, np.int8)
        isu_row, isp_row = rows < nu, rows >= po
        bid[isu_row & (ck == 0)] = 0
        if self.has_p:
            bid[isp_row & (ck == 0)] = 1
            bid[isp_row & (ck == 2)] = 2
        bid[(isu_row | isp_row) & (ck == 1)] = 3
        self.bid = bid
        del isu_row, isp_row, ck
        none = (np.zeros(0, np.int64), np.zeros(0, np.int64))
        q_uu = q_pu = none
        if self.has_l:
            sel = bid == 3
            self.Bt = _Block(rows[sel], R.indices[sel], nr, n)
            lp = lpattern.tocoo()
            self.M = _Block(lp.row.astype(np.int64) + nu, lp.col, nr, n)
            self._face_rows(lpattern)
            Q = self.Bt.to_petsc(self.Bt.values(R.data[sel]), self.comm).matMult(
                self.M.to_petsc(self.M.values(np.zeros(lpattern.nnz)), self.comm))
            qi, qj, _ = Q.getValuesCSR()
            Q.destroy()
            qr = np.repeat(np.arange(nr, dtype=np.int64), np.diff(qi))
            qk = blk.kind[qj]
            self._q_uu = (qr < nu) & (qk == 0)
            self._q_pu = (qr >= po) & (qk == 0)
            q_uu = (qr[self._q_uu], self.fidx[qj[self._q_uu]])
            q_pu = (qr[self._q_pu], qj[self._q_pu].astype(np.int64))
            self.Q: Any = None          # petsc4py Mat
        sel = bid == 0
        self.Suu = _Block(rows[sel], self.fidx[R.indices[sel]], nu, int(totals[0]), [q_uu], [q_uu])
        if self.has_p:
            sel = bid == 1
            self.Spu = _Block(rows[sel], R.indices[sel], nr, n, [q_pu], [q_pu])
            sel = bid == 2
            pr = np.arange(nr - po, dtype=np.int64)
            diag = (pr, (int(self.fidx[blk.row0 + po]) if nr > po else 0) + pr)
            self.Spp = _Block(rows[sel] - po, self.fidx[R.indices[sel]], nr - po, int(totals[2]), [diag], [diag])

    def _face_rows(self, lpattern):
        """Index arrays for Cl̂⁻¹ Cû on the fixed contact pattern, whose d rows of a face have the same
        columns: entry e of row f d + i at offset j takes Σ_k inv_f[i, k] Cû[f d + k, j]."""
        d = self.d
        L = lpattern
        r = np.repeat(np.arange(L.shape[0]), np.diff(L.indptr))
        j = np.arange(L.nnz) - L.indptr[r]
        f = r // d
        self._ef, self._ei = f, r % d
        self._src = L.indptr[f[:, None] * d + np.arange(d)[None, :]] + j[:, None]
        self._lkeys = csr_keys(L.indptr, L.indices, L.shape[1])

    # ---- values (every Newton system) ---------------------------------------------------------
    def update(self, R: sp.csr_matrix, Clhat: np.ndarray, Cu: sp.csr_matrix, lump):
        """Refill every block from this rank's rows R, the modified contact blocks (Clhat (nfl, d, d),
        Cu (nl_local × n csr, a sub-pattern of the build's)) and the lumped coupling (n_p_local,) or
        None."""
        bid = self.bid
        if self.has_l:
            self.inv = np.linalg.inv(Clhat) if len(Clhat) else np.zeros((0, self.d, self.d))
            cu = np.zeros(len(self._lkeys))
            cu[np.searchsorted(self._lkeys, csr_keys(Cu.indptr, Cu.indices, Cu.shape[1]))] = Cu.data
            mvals = np.einsum("ek,ek->e", self.inv[self._ef, self._ei, :], cu[self._src])
            Mm = self.M.to_petsc(mvals, self.comm)
            Bm = self.Bt.to_petsc(self.Bt.values(R.data[bid == 3]), self.comm)
            self.Q = Bm.matMult(Mm, result=self.Q)
            qv = self.Q.getValuesCSR()[2]
        # the pattern's entries are unique: plain fancy-index updates add each once
        data = self.Suu.values(R.data[bid == 0])
        if self.has_l:
            data[self.Suu.pos[0]] -= qv[self._q_uu]
        self.Suu.to_petsc(data, self.comm, self.bs_u)
        if self.has_p:
            data = self.Spu.values(R.data[bid == 1])
            if self.has_l:
                data[self.Spu.pos[0]] -= qv[self._q_pu]
            self.Spu.to_petsc(data, self.comm)
            data = self.Spp.values(R.data[bid == 2])
            if lump is not None:
                data[self.Spp.pos[0]] -= np.asarray(lump)
            self.Spp.to_petsc(data, self.comm)
        del data

    # ---- PETSc's python PC interface ----------------------------------------------------------
    def _ksp(self, prefix, A):
        ksp = self.P.KSP().create(comm=self.comm)
        ksp.setOptionsPrefix(prefix)
        ksp.setType("preonly")
        ksp.setOperators(A, A)
        return ksp

    def setFromOptions(self, pc):
        for k in (self.ku, self.kp):
            if k is not None:
                k.setFromOptions()

    def setUp(self, pc):
        """The AMG set-ups: S_uu at every PCSetUp, S_pp at the first of a time step (Ŝ_p changes with
        the step only, as BlockPoroSolver's _PressureSolve keeps it). Called inside the KSP's set-up,
        which the Krylov driver times as "preconditioner"."""
        if self.ku is None:
            if self.nsp_u is not None:
                self.Suu.mat.setNearNullSpace(self.nsp_u)
            self.ku = self._ksp(self.prefix_u, self.Suu.mat)
            self.ku.setFromOptions()
            if self.has_p:
                self.kp = self._ksp(self.prefix_p, self.Spp.mat)
                self.kp.setFromOptions()
            self._vecs = self._work()
        # KSPSetUp does nothing once set up: the values changed in place would be taken up at
        # the next solve, inside the Krylov iterations; PCSetUp takes them up here
        self.ku.setUp()
        self.ku.getPC().setUp()
        if self.kp is not None:
            if self.new_step and self.pressure_nullspace is not None:
                old, self._nsp_p = self._nsp_p, near_nullspace(self.pressure_nullspace, self.comm)
                self.Spp.mat.setNearNullSpace(self._nsp_p)
                if old is not None:
                    old.destroy()
            self.kp.getPC().setReusePreconditioner(not self.new_step)
            self.kp.setUp()
            self.kp.getPC().setUp()
            if self.new_step:
                if self.on_pressure_build is not None:
                    self.on_pressure_build()
                self.new_step = False

    def _work(self):
        xu, zu = self.Suu.mat.createVecs()
        out = {"xu": xu, "zu": zu}
        if self.has_p:
            out["xp"], out["zp"] = self.Spp.mat.createVecs()
        if self.has_l or self.has_p:
            out["w"], out["t"] = (self.Spu if self.has_p else self.Bt).mat.createVecs()
        return out

    def apply(self, pc, x, y):
        blk, v = self.blk, self._vecs
        nu, po, d = blk.nu, blk.po, self.d
        r = x.getArray(readonly=True)
        out = np.zeros(len(r))
        z = np.array(r)
        if self.has_l:
            yl = np.einsum("fij,fj->fi", self.inv, r[nu:po].reshape(-1, d)).ravel()
            w = np.zeros(len(r))
            w[nu:po] = yl
            v["w"].setArray(w)
            self.Bt.mat.mult(v["w"], v["t"])
            z -= v["t"].getArray(readonly=True)
        v["zu"].setArray(z[:nu])
        self.ku.solve(v["zu"], v["xu"])
        out[:nu] = v["xu"].getArray(readonly=True)
        if self.has_p:
            v["w"].setArray(out)
            self.Spu.mat.mult(v["w"], v["t"])
            v["zp"].setArray(z[po:] - v["t"].getArray(readonly=True)[po:])
            self.kp.solve(v["zp"], v["xp"])
            out[po:] = v["xp"].getArray(readonly=True)
        if self.has_l:
            v["w"].setArray(out)
            self.M.mat.mult(v["w"], v["t"])
            out[nu:po] = yl - v["t"].getArray(readonly=True)[nu:po]
        y.setArray(out)

    def view(self, pc, viewer):
        viewer.printfASCII("polypore's condensed multipliers (Cl̂ inverted block by block), then\n")
        for k in (self.ku, self.kp):
            if k is not None:
                k.view(viewer)

    def destroy(self, pc=None):
        for k in (self.ku, self.kp):
            if k is not None:
                k.destroy()
        self.ku = self.kp = None
        for v in (self._vecs or {}).values():
            v.destroy()
        self._vecs = None
        for b in ("Bt", "M", "Suu", "Spu", "Spp"):
            blk = getattr(self, b, None)
            if blk is not None:
                blk.destroy()
        if getattr(self, "Q", None) is not None:
            self.Q.destroy()
            self.Q = None
        if self._nsp_p is not None:
            self._nsp_p.destroy()
            self._nsp_p = None


def csr_keys(indptr, indices, ncols: int, row0: int = 0) -> np.ndarray:
    """(nnz,) int64 row-major keys (row0 + row)·ncols + col of a CSR pattern (sorted when it is
    canonical): to find one pattern's entries in another by ``np.searchsorted``."""
    rows = np.repeat(np.arange(len(indptr) - 1, dtype=np.int64), np.diff(indptr)) + row0
    return rows * ncols + indices.astype(np.int64)
