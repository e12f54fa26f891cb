"""Per-fracture-face geometric quantities used by data and outputs (tip distance, arc length)."""

from __future__ import annotations

import numpy as np

from ..mesh import FracturedMesh
from ..mesh.fractures import TIP


def _segment_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(n, m) distances from points P (n, d) to segments [A_j, B_j] (m, d)."""
    AB = B - A
    L2 = np.maximum(np.einsum("md,md->m", AB, AB), 1e-300)
    t = np.clip(np.einsum("nmd,md->nm", P[:, None, :] - A[None], AB) / L2, 0.0, 1.0)
    Q = A[None] + t[..., None] * AB[None]
    return np.linalg.norm(P[:, None, :] - Q, axis=2)


def tip_distance(fm: FracturedMesh, chunk: int = 4096) -> np.ndarray:
    """(n_ff,) distance (m) from each fracture face centroid to the nearest tip of its own fracture.

    Faces of a fracture without tips get +inf.
    """
    mesh, net = fm.mesh, fm.network
    c = mesh.geometry.face_centroid[net.faces]
    out = np.full(net.n_faces, np.inf)
    tips = np.flatnonzero(net.edge_kind == TIP)
    if tips.size == 0:
        return out
    # fracture of each tip edge: that of its (single) fracture face
    tip_frac = net.fracture[net.edge_faces.values[net.edge_faces.offsets[tips]]]
    for i in range(len(net.names)):
        e = tips[tip_frac == i]
        if e.size == 0:
            continue
        en = net.edge_nodes[e]
        A = mesh.nodes[en[:, 0]]
        B = mesh.nodes[en[:, -1]]
        faces = np.flatnonzero(net.fracture == i)
        for s in range(0, faces.size, chunk):
            f = faces[s:s + chunk]
            out[f] = _segment_distance(c[f], A, B).min(axis=1)
    return out


def arc_length(fm: FracturedMesh) -> np.ndarray:
    """(n_ff,) 2D: arc length (m) from the fracture's first vertex to the face centroid along its
    polyline; 3D: NaN."""
    mesh, net = fm.mesh, fm.network
    out = np.full(net.n_faces, np.nan)
    if mesh.dim != 2:
        return out
    c = mesh.geometry.face_centroid[net.faces]
    for i, spec in enumerate(net.specs):
        V = np.asarray(spec.vertices, float)
        if V.shape[0] < 2:
            continue
        f = np.flatnonzero(net.fracture == i)
        seglen = np.linalg.norm(np.diff(V, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seglen)])
        dist = _segment_distance(c[f], V[:-1], V[1:])
        k = dist.argmin(axis=1)
        out[f] = cum[k] + np.linalg.norm(c[f] - V[k], axis=1)
    return out
