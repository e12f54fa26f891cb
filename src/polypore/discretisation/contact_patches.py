"""Multiplier patches: P0 contact multipliers on agglomerates of small fracture faces.

The scheme's multiplier is constant per fracture face (scheme.md §4). Its discrete inf-sup
constant is controlled face by face by the bubble v_Kσ: testing with it gives |σ| λ_σ against the
bubble's energy. With the scheme's stabilisation weight h_K^{d−2} that energy does not shrink
with the face, and the constant scales like √(|σ| / A_K), A_K = |K| / w_K the cross-section of
the cell normal to σ (w_K: its extent along n_σ). On shape-regular meshes |σ| / A_K ≥ 1/3; on
corner-point faults, where faces are overlaps of displaced columns, it falls to 10⁻³ on slivers
and thin strips, and the multipliers there picked up tractions no stress path produces
(docs/contact_patches.md, on Emerald).

Two cures, both on by default: the bubbles' stabilisation weighted by |σ|²/|K|
(:func:`~polypore.assembly.elasticity.elasticity_matrix`), which keeps the constant on its own,
and the one here: the multiplier is constant on a **patch**, a connected set of faces of one
fracture whose area is at least ``ratio`` × the largest A_σ = min(A_K⁺, A_K⁻) of its faces;
faces that reach it alone stay their own patch (regular meshes are untouched). The contact
conditions are exact per multiplier, on the patch-mean jump [[u]]_P = Σ_{σ∈P} |σ| [[u]]_σ / |P|,
and the equilibrium coupling Σ_P |P| λ_P·[[v]]_P = Σ_σ |σ| λ_{P(σ)}·[[v]]_σ keeps the discrete
energy identity with λ_σ := λ_{P(σ)}. The patch multipliers are a subspace of the face-wise ones,
so their inf-sup constant is at least as large (tests/unit/discretisation/test_contact_patches.py measures both).

A patch also joins a neighbour while it is **narrower** than ``ratio`` × the thickness of the
thicker cell at its faces (width |P| / diam_P^{d−2}, thickness t_K = |K| / K's largest face): the
fault face of a pinched-out wedge (b.grdecl: a triangle 783 m long and 0–1.6 m high between a
0.4 m-thick wedge and a 45 m-thick cell) is a regular face of the wedge by cross-section, so the
area rule keeps it alone, but its bubble takes up the misfit between the wedge's poorly resolved
stress and the fault's multiplier: it slipped 19.5 mm beside neighbours at 1–3 mm, where the
2 × 2 × 2 refinement slips 0.3 mm (docs/contact_patches.md, "Wedge faces").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..core.ragged import frozen
from ..mesh.geometry import cell_thickness

__all__ = ["ContactPatches", "contact_patches", "cross_section_ratio", "side_cross_sections", "width_ratio"]

# faces of one patch must not turn by more than this (cos of 60°): the patch's normal is their
# mean, and a larger turn would mix normal and tangential jumps of the faces
MIN_NORMAL_COSINE = 0.5
MAX_ROUNDS = 12


@dataclass(frozen=True, eq=False)
class ContactPatches:
    """Multiplier patches of a fracture network.

    Attributes
    ----------
    face_patch : (n_ff,) int64, the patch of each fracture face
    area : (n_p,) |P| (m² in 3D, m in 2D)
    normal : (n_p, d) unit normal n_P ∝ Σ_{σ∈P} |σ| n_σ⁺
    diameter : (n_p,) largest face diameter of the patch, m
    plus_cell : (n_p,) the + cell of the patch's largest face (owner of its multiplier)
    fracture : (n_p,) fracture index
    mean : (n_p, n_ff) csr, |σ| / |P| for σ ∈ P: patch means of face values
    ratio : (n_ff,) |σ| / A_K, the face's own area against its cells' cross-sections
    patch_ratio : (n_p,) |P| / max A_σ over the patch's faces (A_σ: :func:`cross_section_ratio`)
    width_ratio : (n_ff,) the face's width |σ| / h_σ^{d−2} against the thicker of its cells
        (:func:`width_ratio`)
    """

    face_patch: np.ndarray
    area: np.ndarray
    normal: np.ndarray
    diameter: np.ndarray
    plus_cell: np.ndarray
    fracture: np.ndarray
    mean: sp.csr_array
    ratio: np.ndarray
    patch_ratio: np.ndarray
    width_ratio: np.ndarray

    @property
    def n(self) -> int:
        return int(self.area.size)

    @property
    def identity(self) -> bool:
        """True when every face is its own patch (the scheme's face-wise multipliers)."""
        return self.n == self.face_patch.size

    def expand(self, values: np.ndarray) -> np.ndarray:
        """Face values (n_ff, ...) of patch values (n_p, ...)."""
        return values[self.face_patch]

    def summary(self) -> dict:
        """Counts for run reports: patches, faces, faces merged, smallest face ratio."""
        merged = np.bincount(self.face_patch, minlength=self.n)
        return {"patches": self.n, "faces": int(self.face_patch.size), "faces_in_shared_patches":
                int(np.sum(merged[self.face_patch] > 1)), "largest_patch_faces": int(merged.max(initial=0)),
                "smallest_face_ratio": float(self.ratio.min(initial=np.inf)) if self.ratio.size else None,
                "smallest_patch_ratio": float(self.patch_ratio.min(initial=np.inf)) if self.n else None,
                "smallest_face_width_ratio": float(self.width_ratio.min(initial=np.inf)) if self.width_ratio.size
                else None}


def _extent_along(mesh, cells: np.ndarray, origin: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(k,) extent max − min of (x_s − origin)·n over the nodes of each cell, m."""
    sub = mesh.cell_nodes.take(cells)
    rows = sub.rows_of_entries()
    proj = np.einsum("kd,kd->k", mesh.nodes[sub.values] - origin[rows], normal[rows])
    starts = sub.offsets[:-1]
    return np.maximum.reduceat(proj, starts) - np.minimum.reduceat(proj, starts)


def side_cross_sections(fm) -> np.ndarray:
    """(2, n_ff) A_K = |K| / w_K of the + and − cells of every fracture face (m² in 3D), w_K the
    cell's extent along the face normal: the cross-section of K normal to σ."""
    net, g, mesh = fm.network, fm.mesh.geometry, fm.mesh
    if net.n_faces == 0:
        return np.zeros((2, 0))
    xc, n = g.face_centroid[net.faces], net.normal
    out = np.empty((2, net.n_faces))
    for k, cells in enumerate((net.plus_cell, net.minus_cell)):
        w = _extent_along(mesh, cells, xc, n)
        out[k] = g.cell_volume[cells] / np.maximum(w, 1e-300)
    return out


def cross_section_ratio(fm) -> np.ndarray:
    """(n_ff,) |σ| / min(A_K⁺, A_K⁻) with A_K = |K| / w_K the cross-section of K normal to σ.

    1/3 or more on simplices, 1 for a face covering a hexahedron's side, ≪ 1 for slivers and
    thin strips (the factor of the face's inf-sup constant, module docstring). The smaller
    cell decides: a face that covers a fine cell's side where a coarse cell lies across the
    fault (a reservoir layer against its cap rock) is a regular face of the fine cell, and its
    bubble lives there (:meth:`~polypore.discretisation.DisplacementSpace.build`, side "regular")."""
    net, g = fm.network, fm.mesh.geometry
    if net.n_faces == 0:
        return np.zeros(0)
    area = g.face_area[net.faces]
    return area / np.maximum(side_cross_sections(fm).min(axis=0), 1e-300)


def _face_widths(fm) -> tuple[np.ndarray, np.ndarray]:
    """Per fracture face: its width |σ| / h_σ^{d−2} (m; the length of a 2D face) and the thickness
    t_K = |K| / (K's largest face measure) of the thicker of its two cells (m)."""
    net, mesh = fm.network, fm.mesh
    g = mesh.geometry
    if net.n_faces == 0:
        return np.zeros(0), np.zeros(0)
    t = cell_thickness(mesh)
    width = g.face_area[net.faces] / g.face_diameter[net.faces] ** (mesh.dim - 2)
    return width, np.maximum(t[net.plus_cell], t[net.minus_cell])


def width_ratio(fm) -> np.ndarray:
    """(n_ff,) a face's width |σ| / h_σ^{d−2} over the thickness of the thicker of its cells:
    about 1 on regular faces and on the lateral faces of layers of equal thickness, ≪ 1 on the
    faces of wedges and thin layers against thick cells (module docstring)."""
    width, t = _face_widths(fm)
    return width / np.maximum(t, 1e-300)


def _face_links(fm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (a, b) of fracture faces of one fracture sharing a fracture edge with at most a
    60° turn, and the edge's measure (length in 3D, 1 in 2D)."""
    net = fm.network
    ef = net.edge_faces
    two = np.flatnonzero(ef.counts == 2)
    if two.size == 0:
        z = np.zeros(0, np.int64)
        return z, z, np.zeros(0)
    a = ef.values[ef.offsets[two]].astype(np.int64)
    b = ef.values[ef.offsets[two] + 1].astype(np.int64)
    if fm.mesh.dim == 3:
        en = net.edge_nodes[two]
        w = np.linalg.norm(fm.mesh.nodes[en[:, 1]] - fm.mesh.nodes[en[:, 0]], axis=1)
    else:
        w = np.ones(two.size)
    ok = (net.fracture[a] == net.fracture[b]) & (np.einsum("kd,kd->k", net.normal[a], net.normal[b])
                                                  > MIN_NORMAL_COSINE)
    return a[ok], b[ok], w[ok]


def contact_patches(fm, ratio: float = 0.0) -> ContactPatches:
    """Agglomerate fracture faces into multiplier patches.

    Parameters
    ----------
    fm : FracturedMesh
    ratio : float
        Smallest |P| / A_σ a patch may have (A_σ: the smaller cross-section of a face's cells normal
        to its faces, :func:`cross_section_ratio`), and smallest width |P| / diam_P^{d−2} against
        the thickness of the thicker cell at its faces (:func:`width_ratio`; diam_P: its largest
        face diameter); 0 keeps one multiplier per face.

    Returns
    -------
    ContactPatches
        Each patch is connected (faces sharing a fracture edge) and lies on one fracture; a
        patch below ``ratio`` joins, round by round, the neighbouring patch with which it shares
        the longest edges, until none is below or none can join.
    """
    net, g = fm.network, fm.mesh.geometry
    nf = net.n_faces
    area = g.face_area[net.faces]
    r = cross_section_ratio(fm)
    ref = area / np.maximum(r, 1e-300)
    width, thick = _face_widths(fm)
    fdiam = g.face_diameter[net.faces]
    d = fm.mesh.dim
    patch = np.arange(nf, dtype=np.int64)
    if ratio > 0 and nf:
        a, b, w = _face_links(fm)
        for _ in range(MAX_ROUNDS):
            n_p = int(patch.max()) + 1
            p_area = np.bincount(patch, area, n_p)
            p_ref, p_diam, p_thick = np.zeros(n_p), np.zeros(n_p), np.zeros(n_p)
            np.maximum.at(p_ref, patch, ref)
            np.maximum.at(p_diam, patch, fdiam)
            np.maximum.at(p_thick, patch, thick)
            bad = (p_area < ratio * p_ref) | (p_area / p_diam ** (d - 2) < ratio * p_thick)
            pa, pb = patch[a], patch[b]
            cross = pa != pb
            # shared boundary between neighbouring patches, both directions
            src = np.concatenate([pa[cross], pb[cross]])
            dst = np.concatenate([pb[cross], pa[cross]])
            ww = np.concatenate([w[cross], w[cross]])
            sel = bad[src]
            if not np.any(sel):
                break
            src, dst, ww = src[sel], dst[sel], ww[sel]
            key = src * n_p + dst
            ukey, inv = np.unique(key, return_inverse=True)
            wsum = np.bincount(inv, ww)
            us, ud = ukey // n_p, ukey % n_p
            # for each bad patch its neighbour with the longest shared boundary (ties: lowest index)
            order = np.lexsort((ud, -wsum, us))
            first = np.r_[True, us[order][1:] != us[order][:-1]]
            ls, ld = us[order][first], ud[order][first]
            G = sp.coo_array((np.ones(ls.size), (ls, ld)), shape=(n_p, n_p))
            _, lab = connected_components(G, directed=False)
            # relabel in order of first face so that labels are stable and dense
            _, patch = np.unique(lab[patch], return_inverse=True)
            patch = patch.astype(np.int64)
        _, first_face = np.unique(patch, return_index=True)
        rank = np.empty(first_face.size, np.int64)
        rank[np.argsort(first_face)] = np.arange(first_face.size)
        patch = rank[patch]
    n_p = int(patch.max()) + 1 if nf else 0
    p_area = np.bincount(patch, area, n_p)
    vec = np.stack([np.bincount(patch, area * net.normal[:, k], n_p) for k in range(fm.mesh.dim)], 1)
    normal = vec / np.maximum(np.linalg.norm(vec, axis=1), 1e-300)[:, None]
    diam = np.zeros(n_p)
    np.maximum.at(diam, patch, g.face_diameter[net.faces])
    # largest face of each patch: owner cell of the multiplier (and its fracture)
    order = np.lexsort((-area, patch))
    head = order[np.r_[True, patch[order][1:] != patch[order][:-1]]] if nf else np.zeros(0, np.int64)
    p_ref = np.zeros(n_p)
    np.maximum.at(p_ref, patch, ref)
    W = sp.csr_array((area / p_area[patch], (patch, np.arange(nf))), shape=(n_p, nf))
    return ContactPatches(frozen(patch), frozen(p_area), frozen(normal), frozen(diam),
                          frozen(net.plus_cell[head].astype(np.int64)), frozen(net.fracture[head].astype(np.int64)),
                          W, frozen(r), frozen(p_area / np.maximum(p_ref, 1e-300)),
                          frozen(width / np.maximum(thick, 1e-300)))
