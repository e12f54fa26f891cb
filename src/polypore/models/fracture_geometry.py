"""Per-fracture-face geometric quantities used by data and outputs (tip distance, arc length)."""

from __future__ import annotations

import numpy as np

from ..mesh import FracturedMesh
from ..mesh.fractures import TIP, segment_distances


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
            out[f] = segment_distances(c[f], A, B).min(axis=1)
    return out


def arc_length(fm: FracturedMesh) -> np.ndarray:
    """(n_ff,) 2D: arc length (m) from the fracture's start to each face centroid; 3D: NaN.

    A fracture given by its vertices is measured along that polyline from its first vertex.
    A fracture read from a mesh file has no vertex list: it is measured along its own faces,
    from the end node with the smallest (x, y) of each connected piece (a tip if it has one).
    """
    mesh, net = fm.mesh, fm.network
    out = np.full(net.n_faces, np.nan)
    if mesh.dim != 2:
        return out
    c = mesh.geometry.face_centroid[net.faces]
    for i, spec in enumerate(net.specs):
        f = np.flatnonzero(net.fracture == i)
        V = np.asarray(spec.vertices, float)
        if V.ndim != 2 or V.shape[0] < 2:
            out[f] = _chain_length(mesh, net.faces[f])
            continue
        seglen = np.linalg.norm(np.diff(V, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seglen)])
        dist = segment_distances(c[f], V[:-1], V[1:])
        k = dist.argmin(axis=1)
        out[f] = cum[k] + np.linalg.norm(c[f] - V[k], axis=1)
    return out


def _chain_length(mesh, faces: np.ndarray) -> np.ndarray:
    """(n,) distance (m) along the segments ``faces`` (2D mesh faces) to each segment's midpoint."""
    from scipy.sparse import coo_array
    from scipy.sparse.csgraph import connected_components, dijkstra

    if faces.size == 0:
        return np.zeros(0)
    fn = mesh.face_nodes.values.reshape(-1, 2)[faces]  # 2D: every face is a segment
    nodes, local = np.unique(fn, return_inverse=True)
    local = local.reshape(-1, 2)
    x = mesh.nodes[nodes]
    w = np.linalg.norm(x[local[:, 0]] - x[local[:, 1]], axis=1)
    n = nodes.size
    graph = coo_array((w, (local[:, 0], local[:, 1])), shape=(n, n)).tocsr()
    ncomp, comp = connected_components(graph, directed=False)
    degree = np.bincount(local.ravel(), minlength=n)
    starts = np.empty(ncomp, dtype=int)
    for k in range(ncomp):  # one per connected piece of the fracture: a handful
        cand = np.flatnonzero((comp == k) & (degree == 1))
        if cand.size == 0:
            cand = np.flatnonzero(comp == k)
        starts[k] = cand[np.lexsort((x[cand, 1], x[cand, 0]))[0]]
    dist = dijkstra(graph, directed=False, indices=starts, min_only=True)
    return 0.5 * (dist[local[:, 0]] + dist[local[:, 1]])
