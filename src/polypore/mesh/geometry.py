"""Vectorised geometry of polytopal meshes (scheme.md §3, "Weights").

Every face is split into sub-simplices around its node average x_c (in 3D the
triangles (x_c, s_i, s_{i+1}); in 2D the face is its own segment) and every cell
into the sub-simplices spanned by its node average x_0 and those face pieces.
Volumes, centroids and the node weights ω follow exactly from that
decomposition, so that for every affine v

    Σ_s ω_s^σ v(x_s) = v(x̄_σ),        Σ_s ω_s^K v(x_s) = v(x̄_K),

and, per cell, Σ_σ M_{Kσ} = |K| I with the face moment M_σ = Σ_i c_i ⊗ a_i
(c_i, a_i: centroid and vector area of the sub-triangle i). For a planar face
M_σ = |σ| x̄_σ ⊗ n_σ; for a non-planar face it is not a rank-one tensor, which is
why the discrete gradient uses :func:`face_node_vector_areas` (the sub-triangle
form of "|σ| n_{Kσ}") rather than a single face centroid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import MeshError
from ..core.ragged import INDEX, Ragged, frozen


@dataclass(frozen=True, eq=False)
class Geometry:
    """Geometric quantities of a mesh, computed once when the mesh is built.

    Attributes (n_f faces, n_c cells, d the dimension; lengths in m)
    ----------------------------------------------------------------
    face_area : (n_f,) |σ| in m^(d-1): norm of the vector area.
    face_normal : (n_f, d) unit normal, oriented by the face's node order.
    face_centroid : (n_f, d) x̄_σ.
    face_diameter : (n_f,) h_σ.
    face_node_weight : (nnz(face_nodes),) ω_s^σ, aligned with ``face_nodes.values``.
    face_nonplanarity : (n_f,) max distance of a node to the face plane / h_σ.
    cell_volume : (n_c,) |K| in m^d.
    cell_centroid : (n_c, d) x̄_K.
    cell_diameter : (n_c,) h_K.
    cell_node_weight : (nnz(cell_nodes),) ω_s^K, aligned with ``cell_nodes.values``.
    """

    face_area: np.ndarray
    face_normal: np.ndarray
    face_centroid: np.ndarray
    face_diameter: np.ndarray
    face_node_weight: np.ndarray
    face_nonplanarity: np.ndarray
    cell_volume: np.ndarray
    cell_centroid: np.ndarray
    cell_diameter: np.ndarray
    cell_node_weight: np.ndarray

    def __post_init__(self):
        for name in self.__dataclass_fields__:
            object.__setattr__(self, name, frozen(getattr(self, name)))

    @property
    def face_vector_area(self) -> np.ndarray:
        """(n_f, d) |σ| n_σ."""
        return self.face_area[:, None] * self.face_normal

    def nbytes(self) -> int:
        return sum(getattr(self, n).nbytes for n in self.__dataclass_fields__)


CHUNK = 8192  # rows per batch: bounds the temporaries of the batched kernels


def _chunks(idx: np.ndarray, m: int):
    """Split an index array into batches of about CHUNK * 4 / m rows."""
    step = max(256, CHUNK * 4 // max(m, 1))
    for a in range(0, len(idx), step):
        yield a, idx[a:a + step]


def _diameters(nodes: np.ndarray, rows: Ragged, chunk_entries: int = 100_000) -> np.ndarray:
    """(len(rows),) max pairwise distance between the nodes of each row."""
    out = np.zeros(len(rows))
    counts = rows.counts
    for m in np.unique(counts):
        ids = np.flatnonzero(counts == m).astype(INDEX)
        step = max(1, chunk_entries // (m * m))
        for a in range(0, len(ids), step):
            X = nodes[rows.values[rows.positions(ids[a:a + step], int(m))]]
            X = X - X[:, :1]                        # local frame: no cancellation in the Gram form
            sq = np.einsum("kmd,kmd->km", X, X)
            d2 = sq[:, :, None] + sq[:, None, :] - 2.0 * np.matmul(X, X.transpose(0, 2, 1))
            out[ids[a:a + step]] = np.sqrt(np.maximum(d2.reshape(len(X), -1).max(1), 0.0))
    return out


def _accumulate(out: np.ndarray, idx: np.ndarray, w: np.ndarray) -> None:
    """out[idx] += w for indices spanning a short range (a batch of consecutive cells)."""
    lo = int(idx.min())
    hi = int(idx.max()) + 1
    out[lo:hi] += np.bincount(idx - lo, weights=w, minlength=hi - lo)


def _face_pieces_3d(X: np.ndarray):
    """Sub-triangles of a batch of faces: X (k, m, 3) -> (x_c, Y, a).

    ``Y[:, i] = x_i - x_c`` and ``a[:, i]`` the vector area of (x_c, s_i, s_{i+1}).
    """
    xc = X.mean(axis=1)
    Y = X - xc[:, None, :]
    a = 0.5 * np.cross(Y, np.roll(Y, -1, axis=1))
    return xc, Y, a


def cell_thickness(mesh) -> np.ndarray:
    """(n_cells,) t_K = |K| / (K's largest face measure), m: the cell's thickness (about h_K on
    shape-regular cells, the layer's thickness on flat ones)."""
    g, cf = mesh.geometry, mesh.cell_faces
    largest = np.maximum.reduceat(g.face_area[cf.values], cf.offsets[:-1])
    return g.cell_volume / np.maximum(largest, 1e-300)


def face_node_vector_areas(mesh) -> np.ndarray:
    """(nnz(face_nodes), d) vectors g_{σ,s} with Σ_s v_s ⊗ g_{σ,s} the exact ∫_σ v ⊗ n.

    For affine v, Σ_s v(x_s) ⊗ g_{σ,s} = Σ_i v(c_i) ⊗ a_i over the sub-triangles of σ;
    summed over the faces of a cell (with their orientation) this is |K| ∇v exactly,
    planar faces or not. For a planar face g_{σ,s} = ω_s^σ |σ| n_σ.
    """
    fn = mesh.face_nodes
    g = np.empty((fn.nnz, mesh.dim))
    if mesh.dim == 2:
        g[:] = np.repeat(0.5 * mesh.geometry.face_vector_area, 2, axis=0)
        return g
    for m, rows, conn in fn.groups():
        _, _, a = _face_pieces_3d(mesh.nodes[conn])
        A = a.sum(axis=1)
        gm = (A[:, None, :] / m + a + np.roll(a, 1, axis=1)) / 3.0
        g[fn.positions(rows, m)] = gm
    return g


def face_moments(mesh) -> np.ndarray:
    """(n_f, d, d) M_σ = Σ_s x_s ⊗ g_{σ,s} (= |σ| x̄_σ ⊗ n_σ for planar faces)."""
    g = face_node_vector_areas(mesh)
    X = mesh.nodes[mesh.face_nodes.values]
    rows = mesh.face_nodes.rows_of_entries()
    out = np.zeros((mesh.n_faces, mesh.dim, mesh.dim))
    np.add.at(out, rows, X[:, :, None] * g[:, None, :])
    return out


def _faces(dim, nodes, face_nodes: Ragged):
    nf = len(face_nodes)
    area = np.empty(nf)
    normal = np.empty((nf, dim))
    centroid = np.empty((nf, dim))
    weight = np.empty(face_nodes.nnz)
    nonplanar = np.zeros(nf)
    for m, rows_all, conn_all in face_nodes.groups():
        for start, rows in _chunks(rows_all, m):
            conn = conn_all[start:start + len(rows)]
            X = nodes[conn]
            if dim == 2:
                if m != 2:
                    raise MeshError("faces", f"a 2D face must have 2 nodes, found {m}")
                t = X[:, 1] - X[:, 0]
                L = np.hypot(t[:, 0], t[:, 1])
                area[rows] = L
                with np.errstate(invalid="ignore", divide="ignore"):
                    normal[rows] = np.stack([t[:, 1], -t[:, 0]], axis=1) / L[:, None]
                centroid[rows] = X.mean(axis=1)
                weight[face_nodes.positions(rows, m)] = 0.5
                continue
            if m < 3:
                raise MeshError("faces", f"a 3D face must have at least 3 nodes, found {m}")
            xc, Y, a = _face_pieces_3d(X)
            A = a.sum(axis=1)
            absA = np.linalg.norm(A, axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                n = A / absA[:, None]
            w = np.einsum("kmi,ki->km", a, n)
            area[rows] = absA
            normal[rows] = n
            with np.errstate(invalid="ignore", divide="ignore"):
                centroid[rows] = xc + np.einsum("km,kmi->ki", w, Y + np.roll(Y, -1, axis=1)) / (3.0 * absA[:, None])
                weight[face_nodes.positions(rows, m)] = (absA[:, None] / m + w + np.roll(w, 1, axis=1)) / (3.0 * absA[:, None])
            nonplanar[rows] = np.abs(np.einsum("kmi,ki->km", Y, n)).max(axis=1)
    diameter = _diameters(nodes, face_nodes)
    tiny = area <= 1e-12 * np.maximum(diameter, 1e-300) ** (dim - 1)
    if np.any(tiny | ~np.isfinite(area)):
        bad = np.flatnonzero(tiny | ~np.isfinite(area))
        raise MeshError("faces", f"{bad.size} degenerate face(s) with zero area, first: face {bad[0]} "
                        f"(nodes {face_nodes.row(bad[0]).tolist()}); every face needs a positive measure")
    with np.errstate(invalid="ignore", divide="ignore"):
        nonplanar = nonplanar / diameter
    return area, normal, centroid, diameter, weight, nonplanar


def compute_geometry(dim: int, nodes: np.ndarray, face_nodes: Ragged, cell_faces: Ragged,
                     cell_face_sign: np.ndarray, cell_nodes: Ragged) -> Geometry:
    """Compute :class:`Geometry` from the topology (all kernels batched by face size)."""
    area, normal, fcent, fdiam, fweight, nonplanar = _faces(dim, nodes, face_nodes)
    nc = len(cell_faces)
    n_nodes = nodes.shape[0]
    cn_cell = cell_nodes.rows_of_entries()
    cn_count = cell_nodes.counts
    x0 = np.empty((nc, dim))
    for k in range(dim):
        x0[:, k] = np.bincount(cn_cell, weights=nodes[cell_nodes.values, k], minlength=nc) / cn_count
    cn_keys = cn_cell.astype(np.int64) * n_nodes + cell_nodes.values
    del cn_cell

    inc_cell = cell_faces.rows_of_entries()
    inc_face = cell_faces.values
    inc_sign = cell_face_sign
    fcount = face_nodes.counts[inc_face].astype(np.int32)
    vol = np.zeros(nc)
    cnum = np.zeros((nc, dim))
    cweight = np.zeros(cell_nodes.nnz)
    share = 1.0 / (dim + 1)
    for m in np.unique(fcount):
        for _, sel in _chunks(np.flatnonzero(fcount == m).astype(INDEX), m):
            conn = face_nodes.values[face_nodes.positions(inc_face[sel], m)]
            X = nodes[conn]
            cells = inc_cell[sel]
            p0 = x0[cells]
            if dim == 2:
                # triangle (x0, a, b) with (a, b) in the face's order; sign makes it counter-clockwise
                e1 = X[:, 0] - p0
                e2 = X[:, 1] - p0
                v = inc_sign[sel] * 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
                v = v[:, None]                      # (k, 1): one piece per face
                pc = (p0 + X[:, 0] + X[:, 1]) * share
                _accumulate(vol, cells, v[:, 0])
                for k in range(dim):
                    _accumulate(cnum[:, k], cells, v[:, 0] * pc[:, k])
                node_w = np.repeat(v * share, 2, axis=1)      # (k, 2)
            else:
                xc, Y, a = _face_pieces_3d(X)
                a *= inc_sign[sel][:, None, None]
                v = np.einsum("kmi,ki->km", a, xc - p0) / 3.0        # sub-tetrahedra (x0, x_c, s_i, s_{i+1})
                pc = (p0[:, None, :] + xc[:, None, :] + X + np.roll(X, -1, axis=1)) * share
                _accumulate(vol, cells, v.sum(1))
                for k in range(dim):
                    _accumulate(cnum[:, k], cells, (v * pc[:, :, k]).sum(1))
                vf = v.sum(axis=1, keepdims=True)
                node_w = (v + np.roll(v, 1, axis=1)) * share + vf * share / m
            keys = np.repeat(cells.astype(np.int64) * n_nodes, m) + conn.ravel()
            # incidences are in cell order, so a batch covers consecutive cells: search their keys only
            k0, k1 = cell_nodes.offsets[cells[0]], cell_nodes.offsets[cells[-1] + 1]
            pos = k0 + np.searchsorted(cn_keys[k0:k1], keys)
            _accumulate(cweight, pos, node_w.ravel())
    bad = ~(vol > 0)
    if np.any(bad):
        b = np.flatnonzero(bad)
        raise MeshError("cells", f"{b.size} cell(s) with non-positive volume, first: cell {b[0]} "
                        f"(volume {vol[b[0]]:.3e}); cells must be non-degenerate and their faces "
                        "oriented consistently")
    centroid = cnum / vol[:, None]
    cweight += np.repeat(vol * share / cn_count, cn_count)
    cweight /= np.repeat(vol, cn_count)
    cdiam = _diameters(nodes, cell_nodes)
    return Geometry(area, normal, fcent, fdiam, fweight, nonplanar, vol, centroid, cdiam, cweight)
