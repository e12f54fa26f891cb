"""Builders: turn generator output (polygons, polyhedra, typed cells) into a :class:`Mesh`."""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..core.errors import MeshError
from ..core.ragged import INDEX, Ragged
from .mesh import Mesh, assemble_mesh

# Outward-oriented local faces (right-hand rule) of VTK/gmsh-ordered 3D cells.
CELL_FACES_3D = {
    "tetra": [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
    "hexahedron": [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]],
    "wedge": [[0, 2, 1], [3, 4, 5], [0, 1, 4, 3], [1, 2, 5, 4], [2, 0, 3, 5]],
    "pyramid": [[0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]],
}


def _void_keys(rows: np.ndarray) -> np.ndarray:
    rows = np.ascontiguousarray(np.sort(rows, axis=1).astype(INDEX))
    return rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()


def mesh_from_polygons(nodes: np.ndarray, polygons: Ragged, *, cell_region=None, region_names=None,
                       boundary: Mapping[str, np.ndarray] | None = None) -> Mesh:
    """2D mesh from polygons given as node loops (any orientation; made counter-clockwise).

    Parameters
    ----------
    nodes : (n, 2) float
    polygons : Ragged
        One node loop per cell.
    boundary : mapping name -> (k, 2) int node pairs
        Extra named boundary parts, given by their segments' end nodes.
    """
    nodes = np.asarray(nodes, float)
    cnt = polygons.counts
    if np.any(cnt < 3):
        raise MeshError("cells", "a polygon needs at least 3 nodes")
    vals = polygons.values.copy()
    nxt = np.empty_like(vals)
    # next node in each loop, then the signed area decides the orientation
    for m, rows, conn in polygons.groups():
        pos = polygons.positions(rows, m)
        X = nodes[conn]
        Xn = np.roll(X, -1, axis=1)
        area2 = (X[:, :, 0] * Xn[:, :, 1] - Xn[:, :, 0] * X[:, :, 1]).sum(1)
        rev = area2 < 0
        c = conn.copy()
        c[rev] = c[rev, ::-1]
        vals[pos] = c
        nxt[pos] = np.roll(c, -1, axis=1)
    a, b = vals, nxt
    edges = np.stack([a, b], axis=1)
    keys = _void_keys(edges)
    _, first, inv = np.unique(keys, return_index=True, return_inverse=True)
    face_nodes = Ragged.from_dense(edges[first])
    sign = np.where(edges[first][inv, 0] == a, 1, -1).astype(np.int8)
    cell_faces = Ragged(polygons.offsets, inv.astype(INDEX))
    extra = None
    if boundary:
        extra = {name: _faces_of_segments(face_nodes, np.asarray(seg)) for name, seg in boundary.items()}
    return assemble_mesh(2, nodes, face_nodes, cell_faces, sign, extra, cell_region, region_names)


def _faces_of_segments(face_nodes: Ragged, seg: np.ndarray) -> np.ndarray:
    keys = _void_keys(face_nodes.values.reshape(-1, 2))
    want = _void_keys(seg.reshape(-1, 2))
    order = np.argsort(keys)
    pos = np.searchsorted(keys[order], want)
    pos = np.minimum(pos, len(order) - 1)
    ok = keys[order][pos] == want
    return order[pos[ok]].astype(INDEX)


def _packed_keys(conn: np.ndarray, n_nodes: int) -> np.ndarray:
    """One int64 key per loop from its three smallest nodes (8 bytes instead of 4m), or the
    void keys of whole rows when node ids do not fit in 21 bits."""
    if n_nodes >= 2 ** 21:
        return _void_keys(conn)
    k3 = np.sort(conn, axis=1)[:, :3].astype(np.int64) if conn.shape[1] > 3 else np.sort(conn, axis=1).astype(np.int64)
    return (k3[:, 0] << 42) | (k3[:, 1] << 21) | k3[:, 2]


def _same_node_sets(conn: np.ndarray, first: np.ndarray, inv: np.ndarray, batch: int = 65536) -> bool:
    """True if every loop has the node set of its group's representative (checked in batches)."""
    for a in range(0, len(conn), batch):
        c = np.sort(conn[a:a + batch], axis=1)
        r = np.sort(conn[first[inv[a:a + batch]]], axis=1)
        if not np.array_equal(c, r):
            return False
    return True


def dedupe_faces(loops: Ragged):
    """Merge equal face loops (same node set) into faces.

    Returns ``(face_nodes, loop_face, loop_sign)``: the distinct faces (each with the node
    order of its first loop), the face of every loop and +1/-1 when the loop runs the
    same/opposite way as its face.
    """
    n = len(loops)
    loop_face = np.empty(n, dtype=INDEX)
    loop_sign = np.empty(n, dtype=np.int8)
    face_blocks = []
    base = 0
    n_nodes = int(loops.values.max()) + 1 if loops.nnz else 0
    for m, rows, conn in loops.groups():
        keys = _packed_keys(conn, n_nodes)
        _, first, inv = np.unique(keys, return_index=True, return_inverse=True)
        del keys
        if m > 3 and not _same_node_sets(conn, first, inv):
            # two different faces share their three smallest nodes (hanging nodes on an edge)
            _, first, inv = np.unique(_void_keys(conn), return_index=True, return_inverse=True)
        inv = inv.astype(INDEX).ravel()
        rep = conn[first]                                 # face loops
        a0 = rep[inv, 0]                                  # first two nodes of each loop's face
        a1 = rep[inv, 1]
        start = np.argmax(conn == a0[:, None], axis=1)    # where the face's first node sits in my loop
        nxt = conn[np.arange(len(rows)), (start + 1) % m]
        del start, a0
        loop_sign[rows] = np.where(nxt == a1, 1, -1)
        loop_face[rows] = base + inv
        face_blocks.append(rep)
        base += len(first)
    counts = np.concatenate([np.full(len(b), b.shape[1]) for b in face_blocks]) if face_blocks else np.zeros(0, int)
    values = np.concatenate([b.ravel() for b in face_blocks]) if face_blocks else np.zeros(0, INDEX)
    return Ragged.from_counts(counts, values), loop_face, loop_sign


def mesh_from_polyhedra(nodes: np.ndarray, loops: Ragged, loop_cell: np.ndarray, *, oriented: bool = True,
                        cell_region=None, region_names=None,
                        boundary: Mapping[str, np.ndarray] | None = None) -> Mesh:
    """3D mesh from polyhedra given as face loops.

    Parameters
    ----------
    nodes : (n, 3) float
    loops : Ragged
        Every face of every cell as a node loop (shared faces appear twice).
    loop_cell : (len(loops),) int
        Owning cell of each loop, cells numbered 0..n_cells-1; loops of one cell
        must be contiguous and cells in increasing order.
    oriented : bool
        True if every loop already runs counter-clockwise seen from outside its cell;
        otherwise loops are oriented geometrically (valid for star-shaped cells).
    boundary : mapping name -> list of loop-like node rows (a Ragged) or face ids
    """
    nodes = np.asarray(nodes, float)
    loop_cell = np.asarray(loop_cell, dtype=INDEX)
    if np.any(np.diff(loop_cell) < 0):
        raise MeshError("cells", "face loops must be grouped by cell in increasing cell order")
    if not oriented:
        loops = _orient_loops(nodes, loops, loop_cell)
    face_nodes, loop_face, loop_sign = dedupe_faces(loops)
    nc = int(loop_cell.max()) + 1 if loop_cell.size else 0
    cell_faces = Ragged.from_counts(np.bincount(loop_cell, minlength=nc), loop_face)
    extra = None
    if boundary:
        extra = {}
        for name, rows in boundary.items():
            extra[name] = _faces_of_loops(face_nodes, rows) if isinstance(rows, Ragged) else np.asarray(rows, INDEX)
    return assemble_mesh(3, nodes, face_nodes, cell_faces, loop_sign, extra, cell_region, region_names)


def _faces_of_loops(face_nodes: Ragged, rows: Ragged) -> np.ndarray:
    out = []
    fgroups = {m: (ids, _void_keys(conn)) for m, ids, conn in face_nodes.groups()}
    for m, _, conn in rows.groups():
        if m not in fgroups:
            continue
        ids, keys = fgroups[m]
        order = np.argsort(keys)
        want = _void_keys(conn)
        pos = np.minimum(np.searchsorted(keys[order], want), len(order) - 1)
        ok = keys[order][pos] == want
        out.append(ids[order[pos[ok]]])
    return np.concatenate(out).astype(INDEX) if out else np.zeros(0, INDEX)


def _orient_loops(nodes, loops: Ragged, loop_cell) -> Ragged:
    """Reverse loops whose normal points towards their cell's node average."""
    nc = int(loop_cell.max()) + 1
    vals = loops.values.copy()
    owner = np.repeat(loop_cell, loops.counts)
    cnt = np.bincount(owner, minlength=nc)
    centre = np.stack([np.bincount(owner, weights=nodes[vals, k], minlength=nc) / cnt for k in range(3)], 1)
    for m, rows, conn in loops.groups():
        X = nodes[conn]
        xc = X.mean(1)
        Y = X - xc[:, None]
        A = 0.5 * np.cross(Y, np.roll(Y, -1, axis=1)).sum(1)
        rev = np.einsum("ki,ki->k", A, xc - centre[loop_cell[rows]]) < 0
        pos = loops.positions(rows[rev], m)
        vals[pos] = vals[pos][:, ::-1]
    return Ragged(loops.offsets, vals)


def mesh_from_cells(nodes: np.ndarray, blocks: Mapping[str, np.ndarray], *, cell_region=None,
                    region_names=None, boundary=None) -> Mesh:
    """Mesh from typed cell blocks (meshio/gmsh node orderings).

    2D: ``triangle``, ``quad`` (treated as polygons). 3D: ``tetra``, ``hexahedron``,
    ``wedge``, ``pyramid``. Cells are numbered block after block, in the order given.
    Cells with negative orientation (inverted node order) are accepted: their loops are
    re-oriented geometrically.
    """
    nodes = np.asarray(nodes, float)
    dim = nodes.shape[1]
    if dim == 2:
        rows = []
        for kind, conn in blocks.items():
            if kind not in ("triangle", "quad"):
                raise MeshError("cells", f"unsupported 2D cell type {kind!r}; allowed: triangle, quad")
            rows.append(np.asarray(conn, INDEX))
        counts = np.concatenate([np.full(len(r), r.shape[1]) for r in rows])
        polys = Ragged.from_counts(counts, np.concatenate([r.ravel() for r in rows]))
        return mesh_from_polygons(nodes, polys, cell_region=cell_region, region_names=region_names,
                                  boundary=boundary)
    # every block's loops are cell-major (cell by cell, local faces in template order) and blocks
    # are numbered one after the other, so the concatenation is grouped by cell: no sort needed
    counts, values, loop_cell = [], [], []
    start = 0
    needs_orient = False
    for kind, conn in blocks.items():
        if kind not in CELL_FACES_3D:
            raise MeshError("cells", f"unsupported 3D cell type {kind!r}; allowed: {sorted(CELL_FACES_3D)}")
        conn = np.asarray(conn, INDEX)
        nck = len(conn)
        if kind == "tetra" and nck:
            X = nodes[conn]
            vol = np.einsum("ki,ki->k", X[:, 1] - X[:, 0], np.cross(X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]))
            inverted = vol < 0
            del X, vol
            if inverted.any():
                conn = conn.copy()
                conn[inverted] = conn[inverted][:, [0, 2, 1, 3]]
        else:
            needs_orient = True
        tmpl = CELL_FACES_3D[kind]
        sizes = np.array([len(lf) for lf in tmpl])
        flat_idx = np.concatenate(tmpl)
        counts.append(np.tile(sizes, nck))
        values.append(conn[:, flat_idx].ravel())
        loop_cell.append(np.repeat(np.arange(start, start + nck, dtype=INDEX), len(tmpl)))
        start += nck
    loops = Ragged.from_counts(np.concatenate(counts), np.concatenate(values))
    del values
    return mesh_from_polyhedra(nodes, loops, np.concatenate(loop_cell), oriented=not needs_orient,
                               cell_region=cell_region,
                               region_names=region_names, boundary=boundary)
