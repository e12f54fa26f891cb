"""Global assembly of the mixed-dimensional HFV flow system (scheme.md §5).

Unknowns (global numbering, in this order):

* ``face``  p_σ on every mesh face that is not a fracture face (boundary faces included);
* ``trace`` p_{K⁺σ}, p_{K⁻σ} on every fracture face (2 per face: + side, − side);
* ``frac``  p_{f,σ} on every fracture face (the fracture mesh's cells);
* ``edge``  p_e on every fracture edge (tips, intersections, kinks, ∂Ω included).

Cell pressures p_K are eliminated cell by cell (static condensation): the balance of K,

    (τ_K + s_K) p_K − t_K·p_F = r_K,      t_K = T_K 1, τ_K = 1^T T_K 1,

gives p_K = (r_K + t_K·p_F)/(τ_K + s_K) and the flux F_K = t_K p_K − T_K p_F =
−S_K p_F + t_K r_K/(τ_K + s_K) with S_K = T_K − t_K t_K^T/(τ_K + s_K) (symmetric, positive
semi-definite, kernel = constants when s_K = 0). s_K is the storage coefficient
|K|/(M Δt) (m³/Pa) and r_K the cell's right-hand side in m³/s. The fracture pressures are
kept: the fracture rows couple a face's traces and its edges only. Every row is written
as "− (outflow balance)" so that the condensed matrix is symmetric; it is positive definite
as soon as one Dirichlet value (or storage) fixes the constants.

The coupling hooks for poromechanics are the right-hand sides: ``cell_rhs`` receives
−b |K| (div^K u^n − div^K u^{n−1})/Δt, ``fracture_rhs`` −|σ|(d_f^n − d_f^{n−1})/Δt, and
:meth:`FlowAssembler.full_matrix` returns the uncondensed matrix with the cell pressures
for a monolithic Newton.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..discretisation.hfv import HFVOperator, fracture_cells, fracture_hfv, matrix_hfv
from .pattern import Pattern


@dataclass(frozen=True, eq=False)
class FlowDofs:
    """Global numbering of the face, trace, fracture and edge pressures.

    Attributes
    ----------
    face : (n_faces,) int64 dof of every mesh face, −1 on fracture faces.
    trace : (n_ff, 2) int64 dofs of the + and − traces of every fracture face.
    frac : (n_ff,) int64; edge : (n_e,) int64.
    slot : (nnz(cell_faces),) int64 dof seen by each (cell, local face) pair: the face
        dof, or on a fracture face the trace of that cell's side.
    n : int total number of dofs.
    """

    face: np.ndarray
    trace: np.ndarray
    frac: np.ndarray
    edge: np.ndarray
    slot: np.ndarray
    n: int

    @classmethod
    def build(cls, mesh, network) -> "FlowDofs":
        nff = network.n_faces
        ne = network.edge_nodes.shape[0]
        is_frac = np.zeros(mesh.n_faces, bool)
        is_frac[network.faces] = True
        face = np.full(mesh.n_faces, -1, np.int64)
        nfd = int(np.count_nonzero(~is_frac))
        face[~is_frac] = np.arange(nfd)
        trace = nfd + np.arange(2 * nff, dtype=np.int64).reshape(nff, 2)
        frac = nfd + 2 * nff + np.arange(nff, dtype=np.int64)
        edge = nfd + 3 * nff + np.arange(ne, dtype=np.int64)
        cf = mesh.cell_faces
        slot = face[cf.values].copy()
        ffi = network.face_index(mesh.n_faces)[cf.values]
        on = ffi >= 0
        cells = cf.rows_of_entries()[on]
        side = np.where(cells == network.plus_cell[ffi[on]], 0, 1)
        slot[on] = trace[ffi[on], side]
        return cls(face, trace, frac, edge, slot, nfd + 3 * nff + ne)


@dataclass(frozen=True, eq=False)
class FlowSystem:
    """A condensed flow matrix and what is needed to build right-hand sides and recover p_K.

    Attributes
    ----------
    A : csr_array (n, n), symmetric; rows are minus the mass balances in m³/s.
    denom : (n_cells,) τ_K + s_K in m³/(Pa·s).
    cell_storage : (n_cells,) s_K; fracture_storage : (n_ff,) in m³/(Pa·s).
    exchange : (n_ff,) |σ| Λ_f/η in m³/(Pa·s).
    fracture_conductivity : (n_ff,) C_f/η in m³/(Pa·s).
    fracture : HFVOperator with the current C_f/η.
    """

    A: sp.csr_array
    denom: np.ndarray
    cell_storage: np.ndarray
    fracture_storage: np.ndarray
    exchange: np.ndarray
    fracture_conductivity: np.ndarray
    fracture: HFVOperator


class FlowAssembler:
    """Builds the local operators, the numbering and the sparsity pattern once.

    Parameters
    ----------
    mesh : Mesh
    network : FractureNetwork
    conductivity : (n_cells, d, d) K_m/η in m²/(Pa·s).
    alpha, fracture_alpha : float, optional
        HFV stabilisation on the matrix (default √d) and on the fracture mesh (√(d−1)).
    cell_point : "auto" or "centroid": the matrix cells' points x_K (`matrix_hfv`).
    """

    def __init__(self, mesh, network, conductivity, alpha=None, fracture_alpha=None, cell_point="auto"):
        t0 = time.perf_counter()
        self.mesh = mesh
        self.network = network
        self.hfv = matrix_hfv(mesh, conductivity, alpha, cell_point)
        self.fcells = fracture_cells(mesh, network)
        self.fhfv_unit = fracture_hfv(self.fcells, np.ones(network.n_faces), fracture_alpha, mesh.dim)
        self.dofs = FlowDofs.build(mesh, network)
        self.t, self.tau = self.hfv.row_sums()
        self.ft_unit, self.ftau_unit = self.fhfv_unit.row_sums()
        self._condensed_pattern = None
        self._full_pattern = None
        self.setup_timings = {"local_operators": time.perf_counter() - t0, "pattern": 0.0}
        self.last_timings = {}

    @property
    def _pattern(self) -> Pattern:
        """The condensed system's pattern, built at the first :meth:`system` (the monolithic
        poromechanics Newton uses :meth:`full_matrix` only, and would hold it for nothing)."""
        if self._condensed_pattern is None:
            t0 = time.perf_counter()
            self._condensed_pattern = self._build_pattern()
            self.setup_timings["pattern"] = time.perf_counter() - t0
        return self._condensed_pattern

    # -- sparsity -------------------------------------------------------------------------
    def _contributions(self, full: bool):
        """Row/col index arrays of every contribution, in the order values are produced."""
        dofs = self.dofs
        rows, cols = [], []
        nd = dofs.n
        for b in self.hfv.blocks:
            loc = dofs.slot[b.pos]                                   # (k, m)
            if full:
                loc = np.concatenate([nd + b.cells[:, None].astype(np.int64), loc], axis=1)
            rows.append(np.repeat(loc[:, :, None], loc.shape[1], 2).ravel())
            cols.append(np.repeat(loc[:, None, :], loc.shape[1], 1).ravel())
        ex = np.stack([dofs.trace, np.repeat(dofs.frac[:, None], 2, 1)], axis=2)   # (n_ff, side, 2)
        rows.append(np.repeat(ex[:, :, :, None], 2, 3).ravel())
        cols.append(np.repeat(ex[:, :, None, :], 2, 2).ravel())
        fe = self.fcells.face_edges
        for b in self.fhfv_unit.blocks:
            loc = np.concatenate([dofs.frac[b.cells][:, None], dofs.edge[fe.values[b.pos]]], axis=1)
            rows.append(np.repeat(loc[:, :, None], loc.shape[1], 2).ravel())
            cols.append(np.repeat(loc[:, None, :], loc.shape[1], 1).ravel())
        n = nd + (self.mesh.n_cells if full else 0)
        return np.concatenate(rows), np.concatenate(cols), n

    def _build_pattern(self, full=False) -> Pattern:
        r, c, n = self._contributions(full)
        return Pattern.build(r, c, (n, n))

    def _values(self, s_cell, exchange, fcond, s_frac, full: bool):
        vals = []
        denom = self.tau + s_cell
        for b in self.hfv.blocks:
            tb = b.T.sum(2)
            if full:
                m = tb.shape[1]
                blk = np.empty((len(b.cells), m + 1, m + 1))
                blk[:, 0, 0] = denom[b.cells]
                blk[:, 0, 1:] = -tb
                blk[:, 1:, 0] = -tb
                blk[:, 1:, 1:] = b.T
            else:
                blk = b.T - tb[:, :, None] * tb[:, None, :] / denom[b.cells][:, None, None]
            vals.append(blk.ravel())
        vals += self._fracture_values(exchange, fcond, s_frac)
        return np.concatenate(vals), denom

    def _fracture_values(self, exchange, fcond, s_frac) -> list:
        """Values of the exchange contributions ((n_ff, side, 2, 2) raveled) and of each fracture-HFV
        block ((k, m + 1, m + 1): fracture cell first, then its edges), in contribution order."""
        lam = np.repeat(np.asarray(exchange, float)[:, None], 2, 1)          # (n_ff, side)
        vals = [np.stack([np.stack([lam, -lam], 2), np.stack([-lam, lam], 2)], 2).ravel()]
        for b in self.fhfv_unit.blocks:
            T = b.T * fcond[b.cells][:, None, None]
            tb = T.sum(2)
            m = tb.shape[1]
            blk = np.empty((len(b.cells), m + 1, m + 1))
            blk[:, 0, 0] = tb.sum(1) + s_frac[b.cells]
            blk[:, 0, 1:] = -tb
            blk[:, 1:, 0] = -tb
            blk[:, 1:, 1:] = T
            vals.append(blk.ravel())
        return vals

    # -- fracture coefficients ------------------------------------------------------------
    def fracture_contributions(self):
        """The contributions of :meth:`full_matrix` that carry the exchange |σ| Λ_f/η and the
        fracture conductivity C_f/η, per unit coefficient (their derivative with respect to it).

        Returns
        -------
        slot : (m,) position of each in ``full_matrix(...).data`` (the pattern is fixed)
        rows, cols : (m,) int64 rows and columns (full numbering)
        face : (m,) int64 fracture face whose coefficient multiplies each
        conductive : (m,) bool, True where the coefficient is C_f/η, False where it is |σ| Λ_f/η
        unit : (m,) the values at coefficient 1 (fracture storage excluded), so that those
            contributions of ``full_matrix(s, ex, fc, s_f)`` are ``unit × where(conductive, fc, ex)[face]``
            plus the storage on the fracture cells' diagonal
        """
        if self._full_pattern is None:
            self._full_pattern = self._build_pattern(full=True)
        r, c, _ = self._contributions(True)
        nh = sum(b.cells.size * (b.T.shape[1] + 1) ** 2 for b in self.hfv.blocks)
        nf = self.network.n_faces
        one, zero = np.ones(nf), np.zeros(nf)
        units = self._fracture_values(one, one, zero)            # every coefficient 1, no storage
        faces = [np.repeat(np.arange(nf, dtype=np.int64), 8)]
        faces += [np.repeat(b.cells.astype(np.int64), (b.T.shape[1] + 1) ** 2) for b in self.fhfv_unit.blocks]
        face = np.concatenate(faces)
        conductive = np.ones(face.size, bool)
        conductive[:8 * nf] = False
        return self._full_pattern.slot[nh:].astype(np.int64), r[nh:], c[nh:], face, conductive, np.concatenate(units)

    # -- public ---------------------------------------------------------------------------
    def system(self, cell_storage, exchange, fracture_conductivity, fracture_storage) -> FlowSystem:
        """Condensed matrix for given coefficients (all per entity, see :class:`FlowSystem`).

        Parameters
        ----------
        cell_storage : (n_cells,) s_K = |K|/(M Δt) in m³/(Pa·s) (0 for a steady solve).
        exchange : (n_ff,) |σ| Λ_f/η in m³/(Pa·s).
        fracture_conductivity : (n_ff,) C_f(d_f)/η in m³/(Pa·s).
        fracture_storage : (n_ff,) |σ| d_f c_f/Δt in m³/(Pa·s).
        """
        t0 = time.perf_counter()
        vals, denom = self._values(cell_storage, exchange, fracture_conductivity, fracture_storage, False)
        t1 = time.perf_counter()
        A = self._pattern.fill(vals)
        self.last_timings = {"condensation": t1 - t0, "fill": time.perf_counter() - t1}
        fc = np.asarray(fracture_conductivity, float)
        return FlowSystem(A, denom, np.asarray(cell_storage, float), np.asarray(fracture_storage, float),
                          np.asarray(exchange, float), fc, self.fhfv_unit.scaled(fc))

    def full_matrix(self, cell_storage, exchange, fracture_conductivity, fracture_storage) -> sp.csr_array:
        """Uncondensed symmetric matrix over [dofs…, p_K…] (cells last, at ``dofs.n + K``).

        Rows of cells are (τ_K + s_K) p_K − t_K·p_F (= storage + outflow of K); the other
        rows are as in :meth:`system`. Meant for a monolithic poromechanics Newton.
        """
        if self._full_pattern is None:
            self._full_pattern = self._build_pattern(full=True)
        vals, _ = self._values(cell_storage, exchange, fracture_conductivity, fracture_storage, True)
        return self._full_pattern.fill(vals)

    def cell_pairs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Neighbouring matrix cells across the interior faces that are not fracture faces.

        Returns
        -------
        faces : (n_pairs,) int64 mesh face ids σ
        cells : (n_pairs, 2) int64, the two cells (K, L) of each
        dist : (n_pairs, 2) d_Kσ and d_Lσ, m: the distance from each side's HFV cell point x_K
            to σ's plane (positive, as HFV requires)
        width : (n_pairs, 2) h_Kσ and h_Lσ, m: the width of each cell across σ, i.e. the largest
            distance from σ's plane of a node of the cell (the height over σ of a simplex, the
            side normal to σ of a box)
        pos : (n_pairs, 2) int64 positions of (K, σ) and (L, σ) in ``mesh.cell_faces.values``
        """
        mesh, cf, cn = self.mesh, self.mesh.cell_faces, self.mesh.cell_nodes
        g = mesh.geometry
        dist = np.zeros(cf.nnz)                      # d_Kσ = (x̄_σ − x_K)·A_Kσ/|A_Kσ| per (cell, face)
        for b in self.hfv.blocks:
            dist[b.pos] = np.einsum("ksi,ksi->ks", b.X, b.A) / np.linalg.norm(b.A, axis=2)
        fc = mesh.face_cells
        faces = np.flatnonzero((fc[:, 1] >= 0) & (self.dofs.face >= 0))
        side = (cf.rows_of_entries() != fc[cf.values, 0]).astype(np.int64)   # 0: K = face_cells[σ, 0], 1: L
        pos = np.full((mesh.n_faces, 2), -1, np.int64)
        pos[cf.values, side] = np.arange(cf.nnz)
        pos = pos[faces].ravel()
        # width: max over the nodes s of K of (x̄_σ − x_s)·n_Kσ, one (entry, node) row per node of K
        cell = cf.rows_of_entries()[pos]
        cnt = cn.counts[cell]
        start = np.zeros(pos.size, np.int64)
        np.cumsum(cnt[:-1], out=start[1:])
        node = cn.values[np.repeat(cn.offsets[cell].astype(np.int64) - start, cnt) + np.arange(cnt.sum())]
        n_out = (mesh.cell_face_sign[pos].astype(float)[:, None] * g.face_normal[cf.values[pos]])
        h = np.einsum("ki,ki->k", g.face_centroid[cf.values[pos]][np.repeat(np.arange(pos.size), cnt)]
                      - mesh.nodes[node], np.repeat(n_out, cnt, axis=0))
        width = np.maximum.reduceat(h, start) if pos.size else np.zeros(0)
        return (faces.astype(np.int64), fc[faces].astype(np.int64), dist[pos].reshape(-1, 2), width.reshape(-1, 2),
                pos.reshape(-1, 2))

    def rhs(self, system: FlowSystem, cell_rhs, fracture_rhs, face_flux=None) -> np.ndarray:
        """Condensed right-hand side (n,) in m³/s.

        Parameters
        ----------
        cell_rhs : (n_cells,) r_K = |K| h_K + s_K p_K^{n−1} (+ coupling terms), m³/s.
        fracture_rhs : (n_ff,) |σ| h_f + storage terms − |σ|Δd_f/Δt, m³/s.
        face_flux : (n_faces,) prescribed outward flux |σ| q_σ on Neumann faces (0 elsewhere), m³/s.
        """
        d = self.dofs
        b = np.zeros(d.n)
        rows = self.mesh.cell_faces.rows_of_entries()
        b += np.bincount(d.slot, weights=self.t * (np.asarray(cell_rhs, float) / system.denom)[rows], minlength=d.n)
        b[d.frac] += fracture_rhs
        if face_flux is not None:
            ok = d.face >= 0
            b[d.face[ok]] -= np.asarray(face_flux, float)[ok]
        return b

    def recover_cells(self, system: FlowSystem, x: np.ndarray, cell_rhs) -> np.ndarray:
        """p_K = (r_K + t_K·p_F)/(τ_K + s_K) (n_cells,), Pa."""
        rows = self.mesh.cell_faces.rows_of_entries()
        tp = np.bincount(rows, weights=self.t * x[self.dofs.slot], minlength=self.mesh.n_cells)
        return (np.asarray(cell_rhs, float) + tp) / system.denom

    def cell_fluxes(self, p_cell: np.ndarray, x: np.ndarray) -> np.ndarray:
        """F_Kσ (nnz(cell_faces),) outward from each cell, m³/s."""
        return self.hfv.fluxes(p_cell, x[self.dofs.slot])

    def fracture_fluxes(self, system: FlowSystem, x: np.ndarray) -> np.ndarray:
        """F_σe (nnz(face_edges),) outward from each fracture face through its edges, m³/s."""
        fe = self.fcells.face_edges
        return system.fracture.fluxes(x[self.dofs.frac], x[self.dofs.edge][fe.values])

    def exchange_fluxes(self, system: FlowSystem, x: np.ndarray) -> np.ndarray:
        """|σ| Λ_f/η (p_{Kσ} − p_{f,σ}) (n_ff, 2) [+ side, − side], matrix → fracture, m³/s."""
        d = self.dofs
        return system.exchange[:, None] * (x[d.trace] - x[d.frac][:, None])
