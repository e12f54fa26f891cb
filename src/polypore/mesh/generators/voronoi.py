"""Clipped Voronoi meshes of a box that conform to axis-aligned fractures and interfaces.

Seeds lie on a jittered tensor lattice of spacing about ``size``. Every axis-aligned
plane (a line in 2D) carrying a fracture, a fracture edge or a tip is extended across
the box and split by the lattice: the two seed layers next to a plane sit at the same
distance from it and their tangential jitter is shared, so that the seeds near the
plane come in mirror pairs and the plane is a union of Voronoi faces. Reflecting the
seeds near the box walls across them clips the real seeds' cells exactly to the box.
The cells are convex and their faces planar.
"""

from __future__ import annotations

from itertools import chain

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Voronoi, cKDTree

from ...core.errors import InputError, MeshError
from ...core.ragged import INDEX, Ragged
from ..build import mesh_from_polygons, mesh_from_polyhedra
from ..mesh import Mesh

MERGE = 1e-8  # Voronoi vertices closer than MERGE * size are one node (symmetric seeds are degenerate)


def _spec_vertices(spec, dim):
    V = np.asarray(getattr(spec, "vertices", spec), float)
    name = getattr(spec, "name", "?")
    if V.ndim != 2 or V.shape[1] != dim or len(V) < dim:
        raise InputError(f"fracture {name}", f"vertices must be at least {dim} {dim}D points, got shape {V.shape}")
    return name, V


def axis_planes(lower, upper, fractures, tol: float) -> list[np.ndarray]:
    """Interior axis-aligned planes a Voronoi mesh must contain, per axis.

    For every fracture (2D polyline, 3D polygon): its own plane(s) and the planes
    through its boundary (2D: perpendicular lines through the segment ends; 3D: the
    planes through the polygon's edges), each extended across the box.

    Returns
    -------
    list of d sorted arrays of plane coordinates strictly inside (lower, upper), m.

    Raises
    ------
    MeshError
        A fracture, segment or polygon edge that is not axis-aligned.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    dim = lower.size
    coords = [[] for _ in range(dim)]
    hint = ("voronoi meshes conform only to axis-aligned fractures; use generator = 'agglomerated' "
            "or 'simplicial' for general fractures")
    for spec in fractures:
        name, V = _spec_vertices(spec, dim)
        span = max(float(np.ptp(V, axis=0).max()), tol)
        if dim == 2:
            seg = np.diff(V, axis=0)
            moving = np.abs(seg) > tol
            if np.any(moving.sum(1) != 1):
                k = int(np.flatnonzero(moving.sum(1) != 1)[0])
                raise MeshError("voronoi_mesh", f"fracture {name!r}: segment {V[k].tolist()}–{V[k + 1].tolist()} "
                                f"is not parallel to an axis; {hint}")
            for k in range(len(seg)):
                j = int(np.argmax(moving[k]))             # direction of the segment
                coords[1 - j].append(V[k, 1 - j])         # its line
                coords[j] += [V[k, j], V[k + 1, j]]       # lines through its ends (tips, kinks)
            continue
        flat = np.ptp(V, axis=0) <= 1e-9 * span
        if not flat.any():
            raise MeshError("voronoi_mesh", f"fracture {name!r} (vertices {V.tolist()}) is not perpendicular to "
                            f"an axis; {hint}")
        k = int(np.argmax(flat))
        coords[k].append(V[0, k])
        edge = np.roll(V, -1, axis=0) - V
        moving = np.abs(edge) > 1e-9 * span
        if np.any(moving.sum(1) != 1):
            raise MeshError("voronoi_mesh", f"fracture {name!r}: its polygon edges must be parallel to the axes "
                            f"(vertices {V.tolist()}); {hint}")
        for e in range(len(V)):
            j = int(np.argmax(moving[e]))
            m = 3 - k - j                                  # the edge lies on the plane x_m = V[e, m]
            coords[m].append(V[e, m])
    out = []
    for k in range(dim):
        c = np.sort(np.asarray(coords[k], float))
        c = c[(c > lower[k] + tol) & (c < upper[k] - tol)]
        if c.size:
            c = c[np.concatenate([[True], np.diff(c) > tol])]
        out.append(c)
    return out


def _axis_layers(lo: float, hi: float, planes: np.ndarray, size: float, jitter: float):
    """Seed layer coordinates along one axis.

    Returns ``(pos, amp, cls)``: layer coordinates (n,), the amplitude of each layer's
    jitter along this axis (0 next to an interior plane), and a class id per layer,
    shared by the two layers on either side of an interior plane (mirror partners
    must share their tangential jitter).
    """
    walls = np.concatenate([[lo], planes, [hi]])
    w = np.diff(walls)
    n = np.maximum(1, np.round(w / size)).astype(int)
    h = w / n
    dl, dr = h / 2, h / 2                                  # distance of the end layers to the slab walls
    d = 0.5 * np.minimum(h[:-1], h[1:])                    # one half-gap per interior plane, both sides
    dr[:-1], dl[1:] = d, d
    # a one-layer slab must sit midway between its walls, or it gets two layers
    n = np.where((n == 1) & (np.abs(dl + dr - w) > 1e-9 * w), 2, n)
    pos, link, adj = [], [], []
    for s in range(w.size):                                # loop over slabs (few)
        p = np.linspace(walls[s] + dl[s], walls[s + 1] - dr[s], n[s])
        pos.append(p)
        a = np.zeros(n[s], bool)
        if s > 0:
            a[0] = True
        if s < w.size - 1:
            a[-1] = True
        adj.append(a)
        lk = np.zeros(n[s], bool)
        lk[0] = s > 0
        link.append(lk)
    pos, adj, link = np.concatenate(pos), np.concatenate(adj), np.concatenate(link)
    gaps = np.diff(np.concatenate([[2 * lo - pos[0]], pos, [2 * hi - pos[-1]]]))
    amp = jitter * np.minimum(gaps[:-1], gaps[1:])
    amp[adj] = 0.0
    cls = np.cumsum(~link) - 1
    return pos, amp, cls


def voronoi_seeds(lower, upper, size: float, fractures=(), *, seed: int = 0, jitter: float = 0.35):
    """Jittered lattice seeds, mirror-symmetric about every plane of :func:`axis_planes`.

    Returns
    -------
    (n, d) float seed coordinates, m; and the per-axis plane coordinates.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    dim = lower.size
    tol = 1e-9 * float(np.max(upper - lower))
    planes = axis_planes(lower, upper, fractures, tol)
    layers = [_axis_layers(lower[k], upper[k], planes[k], size, jitter) for k in range(dim)]
    rng = np.random.default_rng(seed)
    shape = tuple(lay[0].size for lay in layers)
    ncls = tuple(int(lay[2].max()) + 1 for lay in layers)
    idx = np.meshgrid(*[np.arange(s) for s in shape], indexing="ij")
    idx = [i.ravel() for i in idx]
    cls_idx = tuple(layers[k][2][idx[k]] for k in range(dim))
    X = np.empty((idx[0].size, dim))
    for k in range(dim):
        R = rng.uniform(-0.5, 0.5, ncls)                   # one value per class tuple: mirror pairs agree
        X[:, k] = layers[k][0][idx[k]] + layers[k][1][idx[k]] * R[cls_idx]
    return X, planes


def _ragged_from_lists(rows) -> Ragged:
    counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    vals = np.fromiter(chain.from_iterable(rows), dtype=np.int64, count=int(counts.sum()))
    return Ragged.from_counts(counts, vals)


def _merge_points(X: np.ndarray, tol: float) -> np.ndarray:
    """(n,) representative index of every point, merging clusters closer than tol."""
    pairs = cKDTree(X).query_pairs(tol, output_type="ndarray")
    if pairs.size == 0:
        return np.arange(len(X))
    n = len(X)
    g = coo_array((np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, lab = connected_components(g, directed=False)
    rep = np.full(lab.max() + 1, n)
    np.minimum.at(rep, lab, np.arange(n))
    return rep[lab]


def voronoi_mesh(lower, upper, size: float, fractures=(), *, seed: int = 0, jitter: float = 0.35) -> Mesh:
    """Voronoi mesh of the box [lower, upper] conforming to axis-aligned fractures.

    Parameters
    ----------
    lower, upper : (d,) float, m
        Opposite corners of the box, d = 2 or 3.
    size : float, m
        Seed spacing; the mesh has about prod((upper - lower) / size) cells (a few
        more where planes cut the lattice).
    fractures : sequence of FractureSpec
        Fractures and interfaces, axis-aligned (2D: segments parallel to the axes;
        3D: polygons perpendicular to an axis with edges parallel to the axes).
    seed : int
        Random seed of the jitter.
    jitter : float
        Jitter amplitude as a fraction of the local seed spacing, in [0, 0.8].

    Returns
    -------
    Mesh
        Convex polygons / polyhedra with planar faces.

    Raises
    ------
    InputError
        Bad box, size or jitter. MeshError for a fracture that is not axis-aligned.
    """
    lower, upper = np.asarray(lower, float).ravel(), np.asarray(upper, float).ravel()
    dim = lower.size
    if dim not in (2, 3) or upper.size != dim:
        raise InputError("lower", f"lower and upper must both have 2 or 3 coordinates, got {lower.tolist()} "
                         f"and {upper.tolist()}")
    if np.any(upper <= lower):
        raise InputError("upper", f"must exceed lower {lower.tolist()} in every direction, got {upper.tolist()}")
    size = float(size)
    if not size > 0:
        raise InputError("size", f"must be positive, got {size}")
    if np.prod((upper - lower) / size) > 5e7:
        raise InputError("size", f"{size} gives about {np.prod((upper - lower) / size):.3g} cells; at most 5e7")
    if not 0 <= jitter <= 0.8:
        raise InputError("jitter", f"must be in [0, 0.8], got {jitter}")
    seeds, planes = voronoi_seeds(lower, upper, size, fractures, seed=seed, jitter=jitter)
    n = len(seeds)
    # ghosts: mirror images of the seeds near each wall, so real cells end exactly on the walls
    band = 2.5 * size
    ghosts = []
    for k in range(dim):
        for wall in (lower[k], upper[k]):
            near = np.flatnonzero(np.abs(seeds[:, k] - wall) < band)
            G = seeds[near].copy()
            G[:, k] = 2 * wall - G[:, k]
            ghosts.append(G)
    P = np.concatenate([seeds] + ghosts)
    vor = Voronoi(P)
    rp = vor.ridge_points
    keep = np.flatnonzero(rp.min(1) < n)
    ridges = _ragged_from_lists(vor.ridge_vertices).take(keep)
    rp = rp[keep]
    swap = rp[:, 0] >= n
    rp[swap] = rp[swap][:, ::-1]                              # p = rp[:, 0] is a real seed
    if np.any(ridges.values < 0):
        raise MeshError("voronoi_mesh", "internal error: a Voronoi cell of a seed is unbounded")

    # merge (near-)coincident Voronoi vertices among those used, snap onto planes and walls
    used, vinv = np.unique(ridges.values, return_inverse=True)
    V = vor.vertices[used]
    rep = _merge_points(V, MERGE * size)
    ids, rep = np.unique(rep, return_inverse=True)
    V = V[ids]
    snap = 1e-7 * size
    for k in range(dim):
        for c in np.concatenate([[lower[k], upper[k]], planes[k]]):
            V[np.abs(V[:, k] - c) < snap, k] = c
    rows = ridges.rows_of_entries().astype(np.int64)
    keys = np.unique(rows * len(V) + rep[vinv])                 # distinct nodes of each ridge
    r, v = keys // len(V), keys % len(V)

    if dim == 2:
        # a 2D cell: the distinct vertices of its ridges, sorted by angle (cells are convex)
        cell = np.concatenate([rp[r, 0], np.where(rp[r, 1] < n, rp[r, 1], -1)])
        vv = np.concatenate([v, v])
        ok = cell >= 0
        ck = np.unique(cell[ok].astype(np.int64) * len(V) + vv[ok])
        c, v = ck // len(V), ck % len(V)
        cnt = np.bincount(c, minlength=n)
        cen = np.stack([np.bincount(c, weights=V[v, k], minlength=n) for k in range(2)], 1) / cnt[:, None]
        d = V[v] - cen[c]
        order = np.lexsort((np.arctan2(d[:, 1], d[:, 0]), c))
        return mesh_from_polygons(V, Ragged.from_counts(cnt, v[order]))

    # 3D: order each ridge's vertices counter-clockwise around the direction p -> q (outward for p)
    nr = len(rp)
    cnt = np.bincount(r, minlength=nr)
    nrm = P[rp[:, 1]] - P[rp[:, 0]]
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    a = np.eye(3)[np.argmin(np.abs(nrm), axis=1)]
    e1 = np.cross(nrm, a)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(nrm, e1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cen = np.stack([np.bincount(r, weights=V[v, k], minlength=nr) for k in range(3)], 1) / cnt[:, None]
    d = V[v] - cen[r]
    ang = np.arctan2(np.einsum("ki,ki->k", d, e2[r]), np.einsum("ki,ki->k", d, e1[r]))
    order = np.lexsort((ang, r))
    r, v = r[order], v[order]
    # drop degenerate ridges: fewer than 3 distinct vertices or zero area
    start = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    nxt = np.arange(r.size) + 1
    last = start + cnt - 1
    nxt[last[cnt > 0]] = start[cnt > 0]
    area = np.zeros((nr, 3))
    np.add.at(area, r, 0.5 * np.cross(V[v] - cen[r], V[v[nxt]] - cen[r]))
    good = (cnt >= 3) & (np.einsum("ki,ki->k", area, nrm) > 1e-12 * size ** 2)
    loops = Ragged.from_counts(cnt, v).take(np.flatnonzero(good))
    rp = rp[good]
    # each interior ridge is also a loop of its other cell, reversed
    inner = np.flatnonzero(rp[:, 1] < n)
    back = loops.take(inner)
    loc = back.local_index()
    rev = back.values[np.repeat(back.offsets[:-1] + back.counts - 1, back.counts) - loc]
    counts = np.concatenate([loops.counts, back.counts])
    allv = np.concatenate([loops.values, rev])
    owner = np.concatenate([rp[:, 0], rp[inner, 1]])
    order = np.argsort(owner, kind="stable")
    all_loops = Ragged.from_counts(counts, allv).take(order)
    # drop nodes used by no face (vertices of dropped degenerate ridges)
    usedn, inv = np.unique(all_loops.values, return_inverse=True)
    all_loops = Ragged(all_loops.offsets, inv.astype(INDEX))
    if np.unique(owner).size != n:
        raise MeshError("voronoi_mesh", "internal error: a Voronoi cell lost all its faces")
    return mesh_from_polyhedra(V[usedn], all_loops, owner[order], oriented=True)
