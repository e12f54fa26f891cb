"""Random node perturbation of a mesh, keeping the box, the fractures and the topology.

Every node moves by a random vector of length at most ``amplitude`` times its shortest
edge. Nodes on a box wall or a fracture/interface move only tangentially to it (their
displacement is projected onto the intersection of the tangent spaces); nodes on a
fracture's boundary (tips, polygon edges, kinks) or on two fractures are fixed. In 3D
the faces of a perturbed hexahedral mesh become non-planar.
"""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError, MeshError
from ..build import mesh_from_polygons, mesh_from_polyhedra
from ..fractures import _inside_polygon, _point_segment_distance, validate_spec
from ..mesh import Mesh
from .agglomerate import extra_boundary, outward_loops, polygon_loops


def _restrict(Pr: np.ndarray, mask: np.ndarray, n: np.ndarray) -> None:
    """Restrict the projectors Pr[mask] (k, d, d) to the plane ⊥ n (unit (d,) or (k, d)), in place."""
    if not mask.any():
        return
    P = Pr[mask]
    q = np.einsum("kij,...j->ki", P, n)                     # n's part inside the allowed subspace
    q2 = np.einsum("ki,ki->k", q, q)
    big = q2 > 1e-20
    P[big] -= q[big, :, None] * q[big, None, :] / q2[big, None, None]
    Pr[mask] = P


def _shortest_edge(mesh: Mesh) -> np.ndarray:
    """(n_nodes,) length of the shortest face edge at every node, m."""
    fn = mesh.face_nodes
    nxt = np.arange(1, fn.nnz + 1)
    nxt[fn.offsets[1:] - 1] = fn.offsets[:-1]
    a, b = fn.values, fn.values[nxt]
    if mesh.dim == 2:                                       # a 2D face is its own edge
        a, b = a[0::2], a[1::2]
    L = np.linalg.norm(mesh.nodes[a] - mesh.nodes[b], axis=1)
    h = np.full(mesh.n_nodes, np.inf)
    np.minimum.at(h, a, L)
    np.minimum.at(h, b, L)
    return h


def node_projectors(mesh: Mesh, fractures=(), tol: float | None = None) -> np.ndarray:
    """(n_nodes, d, d) orthogonal projectors onto the directions each node may move in.

    Box walls and fracture planes (lines) remove their normal direction; fracture
    boundaries (2D: segment ends; 3D: polygon edges) and nodes on two or more
    fractures get the zero projector.
    """
    X = mesh.nodes
    d = mesh.dim
    lo, hi = X.min(0), X.max(0)
    span = float(np.max(hi - lo))
    tol = 1e-8 * span if tol is None else tol
    Pr = np.broadcast_to(np.eye(d), (len(X), d, d)).copy()
    for k in range(d):
        e = np.eye(d)[k]
        _restrict(Pr, np.abs(X[:, k] - lo[k]) <= tol, e)
        _restrict(Pr, np.abs(X[:, k] - hi[k]) <= tol, e)
    fixed = np.zeros(len(X), bool)
    n_on = np.zeros(len(X), int)
    for spec in fractures:
        geo = validate_spec(spec, d)
        V = geo["vertices"]
        if d == 2:
            on_any = np.zeros(len(X), bool)
            for s in range(len(V) - 1):                     # loop over segments
                on = _point_segment_distance(X, V[s], V[s + 1]) <= tol
                _restrict(Pr, on, geo["normal"][s])
                on_any |= on
            ends = np.min(np.linalg.norm(X[:, None, :] - V[None, :, :], axis=2), axis=1) <= tol
            fixed |= ends
        else:
            Y = X - geo["centre"]
            near = np.abs(Y @ geo["normal"]) <= tol
            Pp = np.stack([Y[near] @ geo["e1"], Y[near] @ geo["e2"]], axis=1)
            on_any = np.zeros(len(X), bool)
            on_any[near] = _inside_polygon(Pp, geo["poly2d"], tol)
            _restrict(Pr, on_any, geo["normal"])
            poly = geo["poly2d"]
            edge = np.zeros(near.sum(), bool)
            for s in range(len(poly)):                      # loop over polygon edges
                edge |= _point_segment_distance(Pp, poly[s], poly[(s + 1) % len(poly)]) <= tol
            fixed[np.flatnonzero(near)[edge]] = True
        n_on += on_any
    fixed |= n_on >= 2
    Pr[fixed] = 0.0
    return Pr


def _sub_volumes(mesh: Mesh, X: np.ndarray) -> np.ndarray:
    """(k,) signed volumes of the sub-simplices (x_K, [x_σ,] s_i, s_i+1) of every cell, in a fixed order."""
    cn = mesh.cell_nodes
    nc = mesh.n_cells
    cnt = cn.counts
    x0 = np.stack([np.bincount(cn.rows_of_entries(), weights=X[cn.values, k], minlength=nc) for k in range(mesh.dim)],
                  axis=1) / cnt[:, None]
    loops, cell = outward_loops(mesh)
    out = []
    for m, rows, conn in loops.groups():
        Y = X[conn] - x0[cell[rows]][:, None, :]
        if mesh.dim == 2:
            out.append(0.5 * (Y[:, 0, 0] * Y[:, 1, 1] - Y[:, 0, 1] * Y[:, 1, 0]))
            continue
        c = Y.mean(axis=1, keepdims=True)
        out.append(np.einsum("kmi,kmi->km", np.cross(Y, np.roll(Y, -1, axis=1)), np.broadcast_to(c, Y.shape)).ravel() / 6)
    return np.concatenate(out) if out else np.zeros(0)


def perturb(mesh: Mesh, amplitude: float, fractures=(), *, seed: int = 0) -> Mesh:
    """Randomly move the nodes of a mesh, keeping its topology, box and fractures.

    Parameters
    ----------
    mesh : Mesh
    amplitude : float
        Largest displacement as a fraction of the shortest edge at the node, in [0, 1).
    fractures : sequence of FractureSpec
        Fractures and interfaces the nodes must stay on.
    seed : int
        Random seed.

    Returns
    -------
    Mesh
        Same cells, faces and node numbering (faces may be non-planar in 3D).

    Raises
    ------
    InputError
        Amplitude outside [0, 1).
    MeshError
        If a sub-simplex of a cell changes orientation (amplitude too large).
    """
    amplitude = float(amplitude)
    if not 0 <= amplitude < 1:
        raise InputError("amplitude", f"must be in [0, 1) (fraction of the local edge length), got {amplitude}")
    d = mesh.dim
    rng = np.random.default_rng(seed)
    # uniform in the unit ball, projected onto the allowed directions (never lengthens it)
    u = rng.normal(size=(mesh.n_nodes, d))
    u *= (rng.random(mesh.n_nodes) ** (1.0 / d) / np.linalg.norm(u, axis=1))[:, None]
    u = np.einsum("kij,kj->ki", node_projectors(mesh, fractures), u)
    X = mesh.nodes + amplitude * _shortest_edge(mesh)[:, None] * u
    before, after = _sub_volumes(mesh, mesh.nodes), _sub_volumes(mesh, X)
    h = mesh.geometry.cell_diameter.min()
    flipped = (before > 0) & ~(after > 1e-12 * h ** d) | (before < 0) & ~(after < -1e-12 * h ** d)
    if np.any(flipped):
        raise MeshError("amplitude", f"amplitude {amplitude} inverts {int(flipped.sum())} sub-cell(s) of the mesh "
                        "(a node moved through a face); use a smaller perturbation")
    extra = extra_boundary(mesh)
    if d == 2:
        return mesh_from_polygons(X, polygon_loops(mesh), cell_region=mesh.cell_region,
                                  region_names=mesh.region_names, boundary=extra)
    loops, cell = outward_loops(mesh)
    return mesh_from_polyhedra(X, loops, cell, oriented=True, cell_region=mesh.cell_region,
                               region_names=mesh.region_names, boundary=extra)
