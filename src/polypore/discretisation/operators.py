"""Local reconstruction operators of the nodal + bubble space as sparse matrices (scheme.md §3).

All operators act on scalar slot values (one displacement component at a time):
with v of shape (n_slots, d), ``D[j] @ v`` is the (n_cells, d) array of
∂_j-columns of ∇^K v, i.e. (∇^K v)_{ij} = (D[j] @ v)[K, i].

* ∇^K v = (1/|K|) [ Σ_σ Σ_{s∈σ} v_Ks ⊗ o_Kσ g_{σ,s} + Σ_{bubbles} v_Kσ ⊗ |σ| n_Kσ ]
  (g_{σ,s}: sub-triangle vector areas, = ω_s^σ |σ| n_σ on planar faces; exact on affine v);
* v̄_K = Σ_s ω_s^K v_Ks and Π^K v(x) = ∇^K v (x − x̄_K) + v̄_K;
* stabilisation residuals v_Ks − Π^K v(x_s) (one row per (K, s)), and v_Kσ for bubbles;
* face-mean jump [[v]]_σ = v̄_{K⁺σ} − v̄_{K⁻σ} + v_{K⁺σ} (− v_{K⁻σ} two-sided).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..core.ragged import INDEX
from ..mesh.geometry import face_node_vector_areas
from .space import DisplacementSpace


def _csr(rows, cols, vals, shape):
    return sp.csr_array((np.asarray(vals, float).ravel(), (np.asarray(rows).ravel(), np.asarray(cols).ravel())),
                        shape=shape)


@dataclass(frozen=True, eq=False)
class Operators:
    """Sparse local operators of a :class:`DisplacementSpace`.

    Attributes
    ----------
    space : DisplacementSpace
    slot_grad : (nnz(cell_slots), d)
        G_{Ka} with ∇^K v = Σ_a v_a ⊗ G_{Ka}, aligned with ``space.cell_slots``.
    D : tuple of d csr arrays (n_cells, n_slots)
        D[j][K, a] = G_{Ka, j}.
    mean : csr (n_cells, n_slots)
        v̄_K (nodal weights ω_s^K).
    stab : csr (nnz(cell_nodes) + n_bubbles, n_slots)
        Rows (K, s): v_Ks − Π^K v(x_s); then one row v_Kσ per bubble.
    stab_cell : (n_rows of stab,) int32
        Cell of each stabilisation row.
    jump : csr (n_fracture_faces, n_slots)
        [[v]]_σ (face-mean jump).
    """

    space: DisplacementSpace
    slot_grad: np.ndarray
    D: tuple
    mean: sp.csr_array
    stab: sp.csr_array
    stab_cell: np.ndarray
    jump: sp.csr_array

    @classmethod
    def build(cls, space: DisplacementSpace) -> "Operators":
        fm = space.fm
        mesh, net = fm.mesh, fm.network
        g = mesh.geometry
        d = mesh.dim
        nc, ns, nslots = mesh.n_cells, space.n_sides, space.n_slots
        cn = mesh.cell_nodes
        nn = mesh.n_nodes
        vol = g.cell_volume
        # nodal gradient vectors: accumulate o_Kσ g_{σ,s} / |K| on the (K, s) entries
        gvec = face_node_vector_areas(mesh)
        cf = mesh.cell_faces
        inc_cell = cf.rows_of_entries()
        sub = mesh.face_nodes.take(cf.values)
        pos_in_fn = np.repeat(mesh.face_nodes.offsets[cf.values], sub.counts) + (
            np.arange(sub.nnz) - np.repeat(sub.offsets[:-1], sub.counts))
        owner = np.repeat(inc_cell, sub.counts).astype(np.int64)
        sgn = np.repeat(mesh.cell_face_sign, sub.counts).astype(float)
        cn_keys = cn.rows_of_entries().astype(np.int64) * nn + cn.values
        p = np.searchsorted(cn_keys, owner * nn + sub.values)
        Gn = np.zeros((cn.nnz, d))
        for k in range(d):
            Gn[:, k] = np.bincount(p, weights=sgn * gvec[pos_in_fn, k], minlength=cn.nnz)
        Gn /= np.repeat(vol, cn.counts)[:, None]
        # bubble gradient vectors: |σ| n_Kσ / |K| with n_Kσ = ± n⁺
        bf = space.bubble_face
        Gb = (space.bubble_sign[:, None] * g.face_area[net.faces[bf]][:, None] * net.normal[bf]
              / vol[space.bubble_cell][:, None])
        # align with cell_slots (nodal entries first in each cell, then bubbles)
        slots = space.cell_slots
        slot_cell = slots.rows_of_entries()
        is_node = slots.local_index() < np.repeat(space.cell_n_nodes, slots.counts)
        G = np.empty((slots.nnz, d))
        G[is_node] = Gn
        # bubbles appear in cell_slots in bubble order within each cell: map by slot number
        bslot = slots.values[~is_node] - ns
        G[~is_node] = Gb[bslot]
        D = tuple(_csr(slot_cell, slots.values, G[:, j], (nc, nslots)) for j in range(d))
        w = np.zeros(slots.nnz)
        w[is_node] = g.cell_node_weight
        mean = _csr(slot_cell, slots.values, w, (nc, nslots))
        stab, stab_cell = _stabilisation(space, mesh, G, w, is_node)
        jump = _jump(space, mesh, net)
        return cls(space, G, D, mean, stab, stab_cell, jump)

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """(n_cells, d, d) ∇^K v for slot values v (n_slots, d)."""
        return np.stack([Dj @ v for Dj in self.D], axis=2)

    # one "quadrature point" per cell (the centroid, weight |K|): the interface of
    # QuadraticOperators, under which ``D`` and ``value`` are rows per quadrature point
    @property
    def qp_cell(self) -> np.ndarray:
        """(n_cells,) int32 cell of every row of ``D``."""
        return np.arange(self.space.fm.mesh.n_cells, dtype=INDEX)

    @property
    def qp_weight(self) -> np.ndarray:
        """(n_cells,) |K| in m^d."""
        return self.space.fm.mesh.geometry.cell_volume

    @property
    def qp_point(self) -> np.ndarray:
        """(n_cells, d) x̄_K in m."""
        return self.space.fm.mesh.geometry.cell_centroid

    @property
    def value(self) -> sp.csr_array:
        """v̄_K (= Π^K v at x̄_K): the value operator at the quadrature points."""
        return self.mean


def _stabilisation(space, mesh, G, w, is_node):
    """Rows v_Ks − Π^K v(x_s) for every (K, s), then v_Kσ for every bubble."""
    slots = space.cell_slots
    g = mesh.geometry
    cn = mesh.cell_nodes
    nslots = space.n_slots
    rows, cols, vals = [], [], []
    row_of_entry = np.arange(cn.nnz)
    nn_cell = space.cell_n_nodes
    shapes = slots.counts.astype(np.int64) * 10_000 + nn_cell
    for key in np.unique(shapes):
        cells = np.flatnonzero(shapes == key)
        m, nk = int(key // 10_000), int(key % 10_000)
        spos = slots.positions(cells, m)                     # (k, m) entries in cell_slots
        cpos = cn.positions(cells, nk)                       # (k, nk) entries in cell_nodes
        X = mesh.nodes[cn.values[cpos]] - g.cell_centroid[cells][:, None, :]   # (k, nk, d)
        # Π^K v(x_s) = Σ_t v_t (G_t · (x_s − x̄_K) + ω_t)
        coef = np.einsum("ksd,ktd->kst", X, G[spos]) + w[spos][:, None, :]      # (k, nk, m)
        coef = -coef
        coef[:, np.arange(nk), np.arange(nk)] += 1.0         # nodal slots come first, in cell_nodes order
        rows.append(np.broadcast_to(row_of_entry[cpos][:, :, None], coef.shape))
        cols.append(np.broadcast_to(slots.values[spos][:, None, :], coef.shape))
        vals.append(coef)
    nb = space.n_bubbles
    r = np.concatenate([a.ravel() for a in rows] + [cn.nnz + np.arange(nb)])
    c = np.concatenate([a.ravel() for a in cols] + [space.n_sides + np.arange(nb)])
    v = np.concatenate([a.ravel() for a in vals] + [np.ones(nb)])
    stab = _csr(r, c, v, (cn.nnz + nb, nslots))
    stab_cell = np.concatenate([cn.rows_of_entries(), space.bubble_cell]).astype(INDEX)
    return stab, stab_cell


def _jump(space, mesh, net):
    """[[v]]_σ = Σ_s ω_s^σ (v_{K⁺s} − v_{K⁻s}) + bubbles."""
    fn = mesh.face_nodes
    nn = mesh.n_nodes
    cn = mesh.cell_nodes
    cn_keys = cn.rows_of_entries().astype(np.int64) * nn + cn.values
    side = space.fm.sides.cell_node_side
    sub = fn.take(net.faces)
    ff = np.repeat(np.arange(net.n_faces), sub.counts)
    wpos = np.repeat(fn.offsets[net.faces], sub.counts) + (np.arange(sub.nnz) - np.repeat(sub.offsets[:-1], sub.counts))
    w = space.fm.mesh.geometry.face_node_weight[wpos]
    kp = np.repeat(net.plus_cell, sub.counts).astype(np.int64)
    km = np.repeat(net.minus_cell, sub.counts).astype(np.int64)
    sp_ = side[np.searchsorted(cn_keys, kp * nn + sub.values)]
    sm_ = side[np.searchsorted(cn_keys, km * nn + sub.values)]
    nb = space.n_bubbles
    rows = np.concatenate([ff, ff, space.bubble_face])
    cols = np.concatenate([sp_, sm_, space.n_sides + np.arange(nb)])
    vals = np.concatenate([w, -w, space.bubble_sign.astype(float)])
    return _csr(rows, cols, vals, (net.n_faces, space.n_slots))
