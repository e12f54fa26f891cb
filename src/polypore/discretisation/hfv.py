"""Hybrid finite volume (HFV / SUSHI) local operators (scheme.md §5).

For a "cell" K with "faces" σ (matrix cells and their mesh faces, or fracture faces
and their fracture edges) and unknowns p_K, p_σ, with δ_σ = p_σ − p_K:

    ∇_K p   = (1/|K|) Σ_σ A_σ δ_σ                     (A_σ = |σ| n_Kσ, the vector area)
    R_Kσ(p) = δ_σ − ∇_K p·(x̄_σ − x_K)
    ∇_Kσ p  = ∇_K p + (α/d_Kσ) R_Kσ(p) n_Kσ,           d_Kσ = (x̄_σ − x_K)·n_Kσ
    a_K(p, q) = Σ_σ (|σ| d_Kσ / d') Λ ∇_Kσ p·∇_Kσ q = δq^T T_K δp,

with d' the dimension of the cell (d for matrix cells, d − 1 for fracture faces) and
Λ the conductivity (K_m/η for the matrix, C_f/η for fractures, in m²/(Pa·s) resp.
m³/(Pa·s)). The flux out of K through σ is F_Kσ(p) = Σ_σ' T_K[σ, σ'] (p_K − p_σ'),
so that a_K(p, q) = Σ_σ F_Kσ(p)(q_K − q_σ).

T_K is built per group of cells with the same number of faces, by batched einsum,
without forming the per-face gradient operators (k, m, d, m). Non-planar faces use
their vector area and centroid (geometry.py); on planar faces the scheme is exact
on affine p (∇_Kσ p = ∇p, R = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import MeshError
from ..core.ragged import INDEX, Ragged

CHUNK = 8192  # cells per batch of the local kernels (bounds the (k, m, m) temporaries)


def hfv_local_matrices(centre, volume, vector_area, face_point, conductivity, dim: int,
                       alpha: float) -> np.ndarray:
    """Batched local HFV matrices T_K (scheme.md §5).

    Parameters
    ----------
    centre : (k, d) x_K in m.
    volume : (k,) |K| in m^d' (d' = ``dim``).
    vector_area : (k, m, d) A_Kσ = |σ| n_Kσ (outward), m^(d'−1).
    face_point : (k, m, d) x̄_σ in m.
    conductivity : (k, d, d) or (k,) Λ, symmetric positive definite (scalar: Λ I).
    dim : int
        Dimension d' of the cells (weights |σ| d_Kσ / d').
    alpha : float
        Stabilisation parameter α > 0.

    Returns
    -------
    T : (k, m, m) symmetric positive definite, units of Λ · m^(d'−2).
    """
    area = np.linalg.norm(vector_area, axis=2)                       # (k, m)
    n = vector_area / area[:, :, None]
    X = face_point - centre[:, None, :]                              # (k, m, d)
    dist = np.einsum("ksi,ksi->ks", X, n)                            # d_Kσ
    if np.any(dist <= 0):
        k = int(np.argwhere(dist <= 0)[0, 0])
        raise MeshError("cells", f"HFV needs every face plane to be at a positive distance from the cell "
                        f"centroid; cell batch entry {k} has d_Kσ = {dist[k].min():.3e} m (a strongly non-convex "
                        "cell whose centroid lies outside or on a face plane)")
    w = area * dist / dim                                            # |σ| d_Kσ / d'
    Gm = vector_area.transpose(0, 2, 1) / volume[:, None, None]      # (k, d, m): ∇_K = Gm δ
    m = vector_area.shape[1]
    Rm = np.eye(m)[None] - np.einsum("ksi,kij->ksj", X, Gm)          # R = Rm δ
    c = alpha / dist                                                 # (k, m)
    Lam = np.asarray(conductivity, float)
    if Lam.ndim == 1:
        W = w.sum(1) * Lam
        T = W[:, None, None] * np.einsum("kdi,kdj->kij", Gm, Gm)
        Ln = Lam[:, None, None] * n
    else:
        T = w.sum(1)[:, None, None] * np.einsum("kdi,kde,kej->kij", Gm, Lam, Gm)
        Ln = np.einsum("kde,kse->ksd", Lam, n)
    # Σ_σ w_σ c_σ (Gm^T Λ n_σ) ⊗ r_σ and its transpose (vanishes on planar faces, kept for warped ones)
    U = np.einsum("kdi,ksd->kis", Gm, Ln)
    mid = np.einsum("kis,ks,ksj->kij", U, w * c, Rm)
    T += mid + mid.transpose(0, 2, 1)
    nLn = np.einsum("ksd,ksd->ks", n, Ln)
    T += np.einsum("ks,ksi,ksj->kij", w * c * c * nLn, Rm, Rm)
    return 0.5 * (T + T.transpose(0, 2, 1))


@dataclass(frozen=True, eq=False)
class HFVBlock:
    """Cells with the same number m of faces.

    Attributes
    ----------
    cells : (k,) int32 cell ids.
    pos : (k, m) int64 positions into the operator's ``cell_faces.values``.
    T : (k, m, m) local matrices.
    A : (k, m, d) outward vector areas; X : (k, m, d) x̄_σ − x_K; volume : (k,).
    """

    cells: np.ndarray
    pos: np.ndarray
    T: np.ndarray
    A: np.ndarray
    X: np.ndarray
    volume: np.ndarray


@dataclass(frozen=True, eq=False)
class HFVOperator:
    """Local HFV matrices of a collection of cells (matrix cells or fracture faces).

    Attributes
    ----------
    cell_faces : Ragged
        The "faces" of every cell (mesh face ids, or fracture edge ids).
    blocks : tuple of HFVBlock
    dim : int
        Cell dimension d' (d for the matrix, d − 1 for the fracture mesh).
    alpha : float
    points : (n_cells, d) x_K, the points the cell unknowns stand for (m)
    """

    cell_faces: Ragged
    blocks: tuple
    dim: int
    alpha: float
    points: np.ndarray

    @property
    def n_cells(self) -> int:
        return len(self.cell_faces)

    def scaled(self, factor: np.ndarray) -> "HFVOperator":
        """Operator with T_K multiplied by ``factor[K]`` (a scalar conductivity change)."""
        blocks = tuple(HFVBlock(b.cells, b.pos, b.T * factor[b.cells][:, None, None], b.A, b.X, b.volume)
                       for b in self.blocks)
        return HFVOperator(self.cell_faces, blocks, self.dim, self.alpha, self.points)

    def row_sums(self) -> tuple[np.ndarray, np.ndarray]:
        """t = T_K 1 aligned with ``cell_faces.values`` (nnz,) and τ_K = 1^T T_K 1 (n_cells,)."""
        t = np.zeros(self.cell_faces.nnz)
        tau = np.zeros(self.n_cells)
        for b in self.blocks:
            tb = b.T.sum(2)
            t[b.pos] = tb
            tau[b.cells] = tb.sum(1)
        return t, tau

    def fluxes(self, p_cell: np.ndarray, p_face: np.ndarray) -> np.ndarray:
        """F_Kσ = Σ_σ' T_K[σ, σ'] (p_K − p_σ') (nnz,), outward, in m³/s (m²/s per m in 2D).

        ``p_face`` (nnz,) are the face values seen from each cell (aligned with cell_faces).
        """
        out = np.zeros(self.cell_faces.nnz)
        for b in self.blocks:
            delta = p_cell[b.cells][:, None] - p_face[b.pos]
            out[b.pos] = np.einsum("kij,kj->ki", b.T, delta)
        return out

    def gradients(self, p_cell: np.ndarray, p_face: np.ndarray):
        """Cell gradients ∇_K p (n_cells, d), face gradients ∇_Kσ p (nnz, d) and weights (nnz,).

        The weights |σ| d_Kσ / d' sum to |K| on planar cells, so Σ w |∇_Kσ p − g|² is the
        discrete L2 norm of the broken gradient error against g (scheme.md §5).
        """
        d = self.blocks[0].A.shape[2] if self.blocks else 0
        gK = np.zeros((self.n_cells, d))
        gKs = np.zeros((self.cell_faces.nnz, d))
        wKs = np.zeros(self.cell_faces.nnz)
        for b in self.blocks:
            delta = p_face[b.pos] - p_cell[b.cells][:, None]
            g = np.einsum("ksi,ks->ki", b.A, delta) / b.volume[:, None]
            area = np.linalg.norm(b.A, axis=2)
            n = b.A / area[:, :, None]
            dist = np.einsum("ksi,ksi->ks", b.X, n)
            R = delta - np.einsum("ksi,ki->ks", b.X, g)
            gKs[b.pos] = g[:, None, :] + (self.alpha * R / dist)[:, :, None] * n
            wKs[b.pos] = area * dist / self.dim
            gK[b.cells] = g
        return gK, gKs, wKs


def _build(cell_faces: Ragged, centre, volume, A_entries, X_entries, conductivity, dim, alpha) -> HFVOperator:
    """Group by face count, batch the kernel in chunks of CHUNK cells."""
    blocks = []
    for m, rows, _ in cell_faces.groups():
        for a in range(0, len(rows), CHUNK):
            r = rows[a:a + CHUNK]
            pos = cell_faces.positions(r, m).astype(np.int64)
            A = A_entries[pos]
            X = X_entries[pos]
            lam = conductivity[r]
            T = hfv_local_matrices(centre[r], volume[r], A, X + centre[r][:, None, :], lam, dim, alpha)
            blocks.append(HFVBlock(r, pos, T, A, X, volume[r]))
    return HFVOperator(cell_faces, tuple(blocks), dim, float(alpha), np.asarray(centre))


CELL_POINTS = ("auto", "centroid")
# "auto": a cell whose local matrix T_K, scaled to unit diagonal, has λ_min/λ_max below this with
# x_K at its centroid gets x_K at the area-weighted mean of its face centroids instead (when that
# point is inside and the matrix is better conditioned with it)
SLIVER_RATIO = 1e-3


def matrix_hfv(mesh, conductivity: np.ndarray, alpha: float | None = None, cell_point: str = "auto") -> HFVOperator:
    """HFV operator of the matrix cells (scheme.md §5, "Matrix HFV").

    Parameters
    ----------
    mesh : Mesh
    conductivity : (n_cells, d, d) K_m/η in m²/(Pa·s), symmetric positive definite.
    alpha : float, optional
        Stabilisation α; default √d (scheme.md §5 **Choice**).
    cell_point : "auto" (default) or "centroid"
        The cell points x_K: the centroid (`cell_points`), except, with "auto", on cells where
        that leaves T_K near-singular (`sliver_points`).

    Returns
    -------
    HFVOperator over ``mesh.cell_faces`` (faces = mesh faces).
    """
    if cell_point not in CELL_POINTS:
        raise ValueError(f"cell_point must be one of {CELL_POINTS}, got {cell_point!r}")
    g = mesh.geometry
    d = mesh.dim
    alpha = np.sqrt(d) if alpha is None else float(alpha)
    cf = mesh.cell_faces
    sgn = mesh.cell_face_sign.astype(float)[:, None]
    A = sgn * g.face_vector_area[cf.values]
    cond = np.asarray(conductivity, float)
    rows = cf.rows_of_entries()

    def build(xK):
        return _build(cf, xK, g.cell_volume, A, g.face_centroid[cf.values] - xK[rows], cond, d, alpha)

    xK = cell_points(mesh)
    op = build(xK)
    if cell_point == "auto":
        ratio = conditioning(op)
        moved = sliver_points(mesh, xK, ratio < SLIVER_RATIO)
        if moved is not None:
            op2 = build(moved)
            better = conditioning(op2) > ratio
            if np.all(better | np.all(moved == xK, axis=1)):
                return op2
            xK = np.where(better[:, None], moved, xK)
            op = build(xK)
    return op


def conditioning(op: "HFVOperator") -> np.ndarray:
    """(n_cells,) λ_min/λ_max of every local matrix T_K scaled to unit diagonal."""
    out = np.ones(op.n_cells)
    for b in op.blocks:
        dg = np.sqrt(np.einsum("kii->ki", b.T))
        w = np.linalg.eigvalsh(b.T / dg[:, :, None] / dg[:, None, :])
        out[b.cells] = w[:, 0] / w[:, -1]
    return out


def sliver_points(mesh, xK: np.ndarray, cells: np.ndarray, margin: float = 0.05):
    """Cell points moved to the area-weighted mean of the face centroids on ``cells`` (mask), where
    that point is at least ``margin`` × |K|/|∂K| from every face plane; None if none moves.

    Why: in a wedge-shaped sliver (a corner-point cell 840 m wide, 0.06–0.3 m thick) the centroid
    lies far from below its top face's centroid, so the top face's stabilisation term
    (α/d_Kσ) R_Kσ, with d_Kσ of centimetres, ties every face through ∇_K p·(x̄_σ − x_K): the
    lateral faces' diagonal grows by 10⁵ over their flux coupling and T_K becomes near-singular
    (λ_min/λ_max 10⁻⁸ on b.grdecl), which no preconditioner built from cells reaches. With x_K at
    the face-area mean, Σ_σ |σ| (x̄_σ − x_K) = 0 and the thin faces' offsets are normal to them:
    b.grdecl's worst ratio becomes 0.04. Affine pressures stay exact for any interior x_K
    (scheme.md §5), which is why it is free to choose.
    """
    if not np.any(cells):
        return None
    cell, n, area, perim = _face_planes(mesh)
    fc = mesh.geometry.face_centroid[mesh.cell_faces.values]
    xa = np.stack([np.bincount(cell, weights=area * fc[:, i], minlength=mesh.n_cells)
                   for i in range(mesh.dim)], 1) / perim[:, None]
    ok = np.asarray(cells, bool) & (_min_distance(mesh, xa, cell, n) >= margin * mesh.geometry.cell_volume / perim)
    if not np.any(ok):
        return None
    return np.where(ok[:, None], xa, xK)


def _face_planes(mesh):
    """Per (cell, face) entry of ``mesh.cell_faces``: its cell (nnz,), outward unit normal (nnz, d)
    and area (nnz,); and every cell's boundary measure |∂K| (n_cells,)."""
    g = mesh.geometry
    cell = mesh.cell_faces.rows_of_entries()
    vec = mesh.cell_face_sign.astype(float)[:, None] * g.face_vector_area[mesh.cell_faces.values]
    area = np.linalg.norm(vec, axis=1)
    return cell, vec / area[:, None], area, np.bincount(cell, weights=area, minlength=mesh.n_cells)


def _min_distance(mesh, points, cell, n) -> np.ndarray:
    """(n_cells,) the smallest signed distance from each cell's point to its face planes."""
    dist = np.einsum("ki,ki->k", mesh.geometry.face_centroid[mesh.cell_faces.values] - points[cell], n)
    mind = np.full(mesh.n_cells, np.inf)
    np.minimum.at(mind, cell, dist)
    return mind


def cell_points(mesh, margin: float = 0.05) -> np.ndarray:
    """(n_cells, d) the HFV cell points x_K (scheme.md §5 **Choice**: the centroid).

    HFV needs every face plane at a positive distance d_Kσ from x_K. Where the centroid is
    closer to a face plane than ``margin`` × the cell's inscribed-ball scale |K|/|∂K| (or
    outside it: strongly non-convex cells, e.g. agglomerated ones), x_K is the Chebyshev
    centre of the face half-spaces (the point farthest from every face plane, a small LP per
    such cell); a cell without an interior point at positive distance from all its face
    planes is not star-shaped and is rejected.
    """
    g = mesh.geometry
    cf = mesh.cell_faces
    cell, n, _, perim = _face_planes(mesh)
    scale = g.cell_volume / perim
    xK = g.cell_centroid.copy()
    bad = np.flatnonzero(_min_distance(mesh, xK, cell, n) < margin * scale)
    if bad.size:
        from scipy.optimize import linprog

        for k in bad:   # few cells; each a (d + 1)-variable LP
            rows = slice(cf.offsets[k], cf.offsets[k + 1])
            N = n[rows]
            b = np.einsum("ki,ki->k", g.face_centroid[cf.values[rows]], N)
            # max r  s.t.  N x + r ≤ N·x̄_σ  (x inside every face half-space by at least r)
            res = linprog(np.r_[np.zeros(mesh.dim), -1.0], A_ub=np.c_[N, np.ones(len(b))], b_ub=b,
                          bounds=[(None, None)] * mesh.dim + [(0, None)], method="highs")
            if not res.success or res.x[-1] <= 1e-9 * scale[k]:
                raise MeshError("cells", f"cell {k} is not star-shaped with respect to any interior point "
                                "(no point at a positive distance from all its face planes): HFV cannot use it")
            xK[k] = res.x[:-1]
    return xK


@dataclass(frozen=True, eq=False)
class FractureCells:
    """The fracture mesh seen as (d−1)-dimensional cells: fracture faces and their edges.

    Attributes
    ----------
    face_edges : Ragged
        Fracture edges (network edge ids) of every fracture face, in loop order.
    vector_area : (nnz, d) |e| n_σe in the fracture's tangent plane, pointing out of σ
        (|e| = 1 in 2D, the edge length in 3D).
    edge_point : (nnz, d) x_e (the node in 2D, the edge midpoint in 3D).
    centre : (n_ff, d) x̄_σ; measure : (n_ff,) |σ|.
    """

    face_edges: Ragged
    vector_area: np.ndarray
    edge_point: np.ndarray
    centre: np.ndarray
    measure: np.ndarray


def fracture_cells(mesh, network) -> FractureCells:
    """Geometry of the fracture mesh (scheme.md §5: HFV in dimension d − 1)."""
    g = mesh.geometry
    faces = network.faces
    sub = mesh.face_nodes.take(faces)
    owner = sub.rows_of_entries()
    nn = mesh.n_nodes
    centre = g.face_centroid[faces]
    if mesh.dim == 2:
        keys = sub.values.astype(np.int64)
        ekeys = network.edge_nodes[:, 0].astype(np.int64)
        P = mesh.nodes[sub.values]
        V = P - centre[owner]
        A = V / np.linalg.norm(V, axis=1)[:, None]
    else:
        nxt = np.arange(sub.nnz) + 1
        nxt[sub.offsets[1:] - 1] = sub.offsets[:-1]
        a, b = sub.values, sub.values[nxt]
        keys = np.minimum(a, b).astype(np.int64) * nn + np.maximum(a, b)
        en = network.edge_nodes.astype(np.int64)
        ekeys = en[:, 0] * nn + en[:, 1]
        Xa, Xb = mesh.nodes[a], mesh.nodes[b]
        P = 0.5 * (Xa + Xb)
        # in-plane outward normal times length: (b − a) × n_σ has length |e| and lies in σ's plane
        A = np.cross(Xb - Xa, g.face_normal[faces][owner])
        flip = np.einsum("ki,ki->k", A, P - centre[owner]) < 0
        A[flip] *= -1
    order = np.argsort(ekeys)
    pos = np.searchsorted(ekeys[order], keys)
    edge = order[np.minimum(pos, len(order) - 1)]
    if not np.array_equal(ekeys[edge], keys):
        raise MeshError("network", "fracture faces and fracture edges disagree (internal error)")
    return FractureCells(Ragged(sub.offsets, edge.astype(INDEX)), A, P, centre, g.face_area[faces])


def fracture_hfv(fcells: FractureCells, conductivity: np.ndarray, alpha: float | None = None,
                 dim: int = 2) -> HFVOperator:
    """HFV operator on the fracture mesh with scalar conductivity per fracture face.

    Parameters
    ----------
    fcells : FractureCells
    conductivity : (n_ff,) C_f/η in m³/(Pa·s) (use ones and :meth:`HFVOperator.scaled`
        to refresh it when the aperture changes).
    alpha : float, optional
        Default √(d − 1).
    dim : int
        Ambient dimension d (the fracture cells have dimension d − 1).
    """
    alpha = np.sqrt(dim - 1) if alpha is None else float(alpha)
    fe = fcells.face_edges
    X = fcells.edge_point - fcells.centre[fe.rows_of_entries()]
    return _build(fe, fcells.centre, fcells.measure, fcells.vector_area, X,
                  np.asarray(conductivity, float), dim - 1, alpha)
