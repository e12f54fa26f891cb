"""Agglomerated meshes: general (non-convex) polytopes made of neighbouring base cells.

Each round matches neighbouring cells in pairs (a random greedy matching over the
interior faces that are not kept) and merges every pair, so the cell count roughly
halves per round. A merged cell's faces are the base faces it does not contain
(coplanar faces are not merged; two cells may share several faces). A pair is only
merged when the union stays a simple polytope: in 2D its boundary is one simple
loop, in 3D the shared faces form a disc and the two cells touch nowhere else.
"""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError, MeshError
from ...core.ragged import INDEX, Ragged
from ..build import mesh_from_polygons, mesh_from_polyhedra
from ..mesh import Mesh

BOX_NAMES = frozenset(f"{a}{s}" for a in "xyz" for s in ("min", "max"))


def outward_loops(mesh: Mesh, incidences: np.ndarray | None = None):
    """Faces of cells as node loops running counter-clockwise seen from outside the cell.

    Parameters
    ----------
    incidences : (k,) int, optional
        Positions in ``mesh.cell_faces.values`` to take, in the wanted order (default all).

    Returns
    -------
    loops : Ragged
        One loop per incidence (3D: polygon, 2D: the directed segment).
    loop_cell : (k,) int32
        Cell of each loop.
    """
    cf = mesh.cell_faces
    inc = np.arange(cf.nnz) if incidences is None else np.asarray(incidences)
    loops = mesh.face_nodes.take(cf.values[inc])
    vals = loops.values.copy()
    rev = np.flatnonzero(mesh.cell_face_sign[inc] < 0)
    for m in np.unique(loops.counts[rev]):
        rows = rev[loops.counts[rev] == m]
        pos = loops.positions(rows, m)
        vals[pos] = vals[pos][:, ::-1]
    return Ragged(loops.offsets, vals), cf.rows_of_entries()[inc]


def order_cycles(group: np.ndarray, a: np.ndarray, b: np.ndarray, n_nodes: int) -> np.ndarray:
    """Order directed edges a -> b that form one simple cycle per group.

    Returns
    -------
    (k,) int permutation of the edges: grouped by increasing group, each group's
    edges in cycle order (starting with its lowest-numbered edge).

    Raises
    ------
    MeshError
        If a group's edges are not one simple cycle.
    """
    k = group.size
    g = group.astype(np.int64)
    start = g * n_nodes + a
    order = np.argsort(start, kind="stable")
    pos = np.searchsorted(start[order], g * n_nodes + b)
    pos = np.minimum(pos, k - 1)
    succ = order[pos]
    if np.any(start[succ] != g * n_nodes + b) or np.unique(start).size != k:
        raise MeshError("cells", "a polygon's boundary is not a simple loop")
    ng = int(g.max()) + 1 if k else 0
    first = np.full(ng, k, dtype=np.int64)
    np.minimum.at(first, g, np.arange(k))
    idx = np.arange(k)
    succ = np.where(succ == first[g], idx, succ)              # cut each cycle before its first edge
    dist = (succ != idx).astype(np.int64)
    # pointer jumping: distance of every edge to its cycle's last edge
    for _ in range(int(np.ceil(np.log2(max(k, 2)))) + 2):
        if np.all(succ[succ] == succ):
            break
        dist = dist + dist[succ]
        succ = succ[succ]
    else:
        raise MeshError("cells", "a polygon's boundary is not a single loop")
    return np.lexsort((-dist, g))


def polygon_loops(mesh: Mesh, cell_of_incidence: np.ndarray | None = None, keep: np.ndarray | None = None):
    """Counter-clockwise boundary node loops of 2D cells (or of unions of cells).

    Parameters
    ----------
    cell_of_incidence : (nnz(cell_faces),) int, optional
        Output polygon of every cell-face incidence (default: its cell).
    keep : (nnz(cell_faces),) bool, optional
        Incidences whose face is on the output polygon's boundary (default all).

    Returns
    -------
    Ragged
        One node loop per output polygon.
    """
    loops, cell = outward_loops(mesh)
    if cell_of_incidence is not None:
        cell = cell_of_incidence
    ab = loops.values.reshape(-1, 2)
    sel = np.arange(len(cell)) if keep is None else np.flatnonzero(keep)
    order = sel[order_cycles(cell[sel], ab[sel, 0], ab[sel, 1], mesh.n_nodes)]
    return Ragged.from_counts(np.bincount(cell[order]), ab[order, 0])


def extra_boundary(mesh: Mesh) -> dict:
    """Named boundary parts other than the bounding-box planes, as node rows.

    2D: name -> (k, 2) node pairs; 3D: name -> Ragged face loops (the builders' input).
    """
    out = {}
    for name, faces in mesh.boundary.items():
        if name in BOX_NAMES:
            continue
        sub = mesh.face_nodes.take(faces)
        out[name] = sub.values.reshape(-1, 2) if mesh.dim == 2 else sub
    return out


def _face_edges(mesh: Mesh) -> np.ndarray:
    """(nnz(face_nodes),) id of the edge from each face node to the next one (3D)."""
    fn = mesh.face_nodes
    nxt = np.arange(1, fn.nnz + 1)
    nxt[fn.offsets[1:] - 1] = fn.offsets[:-1]
    a, b = fn.values.astype(np.int64), fn.values[nxt].astype(np.int64)
    _, eid = np.unique(np.minimum(a, b) * mesh.n_nodes + np.maximum(a, b), return_inverse=True)
    return eid


def _group_items(face_items: Ragged, faces: np.ndarray, groups: np.ndarray, n_items: int):
    """Sorted keys group * n_items + item of the distinct items on the given (face, group) incidences."""
    sub = face_items.take(faces)
    return np.unique(np.repeat(groups.astype(np.int64), sub.counts) * n_items + sub.values)


def _count_common(keys: np.ndarray, n_groups: int, n_items: int, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(len(P),) number of items shared by groups P[i] and Q[i], from sorted group-item keys."""
    grp = keys // n_items
    off = np.searchsorted(grp, np.arange(n_groups + 1))
    cnt = np.diff(off)[P]                                  # P's items are keys[off[P]:off[P + 1]]
    pair = np.repeat(np.arange(P.size), cnt)
    idx = np.repeat(off[P] - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(cnt.sum())
    want = Q[pair].astype(np.int64) * n_items + keys[idx] % n_items
    pos = np.minimum(np.searchsorted(keys, want), max(keys.size - 1, 0))
    hit = keys[pos] == want if keys.size else np.zeros(0, bool)
    return np.bincount(pair[hit], minlength=P.size)


def _distinct_per_pair(face_items: Ragged, faces: np.ndarray, pair: np.ndarray, n_pairs: int, n_items: int):
    """(n_pairs,) number of distinct items on the faces of each pair."""
    keys = _group_items(face_items, faces, pair, n_items)
    return np.bincount(keys // n_items, minlength=n_pairs)


def agglomerate(mesh: Mesh, keep_faces=(), *, rounds: int = 2, seed: int = 0) -> Mesh:
    """Merge neighbouring cells into general polytopes.

    Parameters
    ----------
    mesh : Mesh
        Base mesh (2D or 3D).
    keep_faces : (k,) int
        Interior faces that must stay faces (fractures, interfaces).
    rounds : int
        Rounds of pairwise merging (0 returns an equivalent mesh).
    seed : int
        Random seed of the matchings.

    Returns
    -------
    Mesh
        Cells are unions of base cells of one region, faces are the base faces between
        different unions; nodes used by no face are dropped (nodes renumbered, order kept).
    """
    rounds = int(rounds)
    if rounds < 0:
        raise InputError("rounds", f"must be a non-negative integer, got {rounds}")
    keep = np.zeros(mesh.n_faces, bool)
    kf = np.asarray(keep_faces, dtype=np.int64).ravel()
    if kf.size and (kf.min() < 0 or kf.max() >= mesh.n_faces):
        raise InputError("keep_faces", f"face ids must be in [0, {mesh.n_faces}), got {kf.min()}..{kf.max()}")
    keep[kf] = True
    dim, nn = mesh.dim, mesh.n_nodes
    fc = mesh.face_cells
    interior = fc[:, 1] >= 0
    K, L = fc[:, 0], np.where(interior, fc[:, 1], fc[:, 0])
    region = mesh.cell_region
    fnodes = mesh.face_nodes
    fedges = Ragged(fnodes.offsets, _face_edges(mesh)) if dim == 3 else None
    n_edges = int(fedges.values.max()) + 1 if dim == 3 and fedges.nnz else 0
    label = np.arange(mesh.n_cells)
    rng = np.random.default_rng(seed)
    for _ in range(rounds):
        ng = int(label.max()) + 1
        gK, gL = label[K], label[L]
        between = interior & (gK != gL)                      # interior faces of the current cells
        if not between.any():
            break
        cur = np.flatnonzero(~interior | between)
        cur_int = np.flatnonzero(between)
        lo, hi = np.minimum(gK, gL).astype(np.int64), np.maximum(gK, gL).astype(np.int64)
        pkeys, pinv = np.unique(lo[cur_int] * ng + hi[cur_int], return_inverse=True)
        P, Q = pkeys // ng, pkeys % ng
        s = np.bincount(pinv, minlength=pkeys.size)
        f_int = cur_int
        blocked = keep[f_int] | (region[K[f_int]] != region[L[f_int]])
        ok = np.bincount(pinv, weights=blocked, minlength=pkeys.size) == 0
        # the union must stay simple: every node (and 3D edge) the two cells share is on the
        # shared faces, which form one path (2D) / one disc (3D)
        inc_f = np.concatenate([cur, cur_int])
        inc_g = np.concatenate([gK[cur], gL[cur_int]])
        gnodes = _group_items(fnodes, inc_f, inc_g, nn)
        common_n = _count_common(gnodes, ng, nn, P, Q)
        patch_n = _distinct_per_pair(fnodes, f_int, pinv, pkeys.size, nn)
        if dim == 2:
            ok &= (common_n == patch_n) & (patch_n == s + 1)
        else:
            gedges = _group_items(fedges, inc_f, inc_g, n_edges)
            common_e = _count_common(gedges, ng, n_edges, P, Q)
            patch_e = _distinct_per_pair(fedges, f_int, pinv, pkeys.size, n_edges)
            ok &= (common_n == patch_n) & (common_e == patch_e) & (patch_n - patch_e + s == 1)
        # random greedy matching (Luby): a pair wins if its weight is the smallest at both cells
        w = rng.random(pkeys.size)
        mate = np.full(ng, -1, dtype=np.int64)
        active = ok.copy()
        while active.any():
            idx = np.flatnonzero(active)
            best = np.full(ng, np.inf)
            np.minimum.at(best, P[idx], w[idx])
            np.minimum.at(best, Q[idx], w[idx])
            win = idx[(w[idx] == best[P[idx]]) & (w[idx] == best[Q[idx]])]
            mate[P[win]], mate[Q[win]] = Q[win], P[win]
            active &= (mate[P] < 0) & (mate[Q] < 0)
        root = np.where(mate >= 0, np.minimum(np.arange(ng), mate), np.arange(ng))
        _, new = np.unique(root, return_inverse=True)
        label = new[label]

    gK, gL = label[K], label[L]
    on = ~interior | (gK != gL)
    cf = mesh.cell_faces
    inc_on = on[cf.values]
    inc_group = label[cf.rows_of_entries()]
    ng = int(label.max()) + 1
    reg = np.zeros(ng, dtype=INDEX)
    reg[label] = region
    extra = extra_boundary(mesh)
    if dim == 2:
        polys = polygon_loops(mesh, inc_group, inc_on)
        used, inv = np.unique(polys.values, return_inverse=True)
        remap = np.full(nn, -1, dtype=INDEX)
        remap[used] = np.arange(used.size)
        bnd = {k: remap[v] for k, v in extra.items()}
        return mesh_from_polygons(mesh.nodes[used], Ragged(polys.offsets, inv), cell_region=reg,
                                  region_names=mesh.region_names, boundary=bnd)
    inc = np.flatnonzero(inc_on)
    inc = inc[np.argsort(inc_group[inc], kind="stable")]
    loops, _ = outward_loops(mesh, inc)
    used, inv = np.unique(loops.values, return_inverse=True)
    remap = np.full(nn, -1, dtype=INDEX)
    remap[used] = np.arange(used.size)
    bnd = {k: Ragged(v.offsets, remap[v.values]) for k, v in extra.items()}
    return mesh_from_polyhedra(mesh.nodes[used], Ragged(loops.offsets, inv), inc_group[inc], oriented=True,
                               cell_region=reg, region_names=mesh.region_names, boundary=bnd)
