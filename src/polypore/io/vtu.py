"""VTK XML UnstructuredGrid (.vtu) and ParaView collection (.pvd) writers.

Files are written with numpy only, in binary (``header_type="UInt64"``, little
endian): inline base64 by default (VTK, ParaView and meshio read it), or one raw
``AppendedData`` block with ``encoding="raw"`` (VTK/ParaView; smaller, ~4x faster).
A 1e5-cell polyhedral mesh takes well under a second. Index arrays are Int32 when
they fit. Every file goes through :func:`~polypore.io.atomic.atomic_path`.

Cells
-----
* 2D bulk cells: ``VTK_POLYGON`` (7), the cell's boundary as one counter-clockwise
  node loop; nodes get z = 0.
* 3D bulk cells: ``VTK_POLYHEDRON`` (42) with ``faces``/``faceoffsets`` (each face's
  node loop, counter-clockwise seen from outside the cell) and the cell's node set
  as ``connectivity``.
* Fracture faces: ``VTK_LINE`` (3) in 2D, ``VTK_POLYGON`` in 3D, oriented so that
  their right-hand normal is n⁺.

Arrays
------
2-vectors are padded to 3 components (z = 0). Stress tensors are written by
:func:`symmetric_tensor` with VTK ``ComponentName`` attributes (ParaView shows them by
name): in 3D the independent components ``xx, yy, zz, xy, yz, xz`` — VTK's order of a
symmetric tensor, which ParaView treats as one; in 2D the full 3×3 tensor (9 components,
row by row), the in-plane tensor with zero z row and column (σ_zz is not computed). Three
components, as 2D tensors were written before, are what ParaView takes for a vector.
"""

from __future__ import annotations

import base64
import weakref
from pathlib import Path
from typing import Mapping, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from ..core.ragged import Ragged
from .atomic import atomic_path, atomic_write_text

__all__ = ["VTK_LINE", "VTK_POLYGON", "VTK_POLYHEDRON", "bulk_cells", "fracture_cells", "symmetric_tensor",
           "write_bulk_vtu", "write_fracture_vtu", "write_pvd", "write_unstructured_vtu"]

VTK_LINE, VTK_POLYGON, VTK_POLYHEDRON = 3, 7, 42
TENSOR_COMPONENTS = {2: ("xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"),
                     3: ("xx", "yy", "zz", "xy", "yz", "xz")}

_VTK_TYPE = {
    ("f", 4): "Float32", ("f", 8): "Float64",
    ("i", 1): "Int8", ("i", 2): "Int16", ("i", 4): "Int32", ("i", 8): "Int64",
    ("u", 1): "UInt8", ("u", 2): "UInt16", ("u", 4): "UInt32", ("u", 8): "UInt64",
}


# --------------------------------------------------------------------------- data arrays

def _vtk_array(a, n: int, what: str) -> np.ndarray:
    """``a`` as a C-contiguous little-endian (n,) or (n, k) array VTK can store.

    Booleans become UInt8, float16 Float32; 2-vectors are padded to 3 components
    (ParaView shows only 3-component arrays as vectors); (n, a, b) tensors are flattened.
    """
    a = np.asarray(a)
    if a.ndim == 0 or a.shape[0] != n:
        raise ValueError(f"{what}: expected {n} rows, got an array of shape {a.shape}")
    if a.dtype.kind == "b":
        a = a.astype(np.uint8)
    elif a.dtype.kind == "f" and a.dtype.itemsize < 4:
        a = a.astype(np.float32)
    elif a.dtype.kind == "f" and a.dtype.itemsize > 8:
        a = a.astype(np.float64)
    if (a.dtype.kind, a.dtype.itemsize) not in _VTK_TYPE:
        raise ValueError(f"{what}: cannot store dtype {a.dtype} in a VTK file")
    if a.ndim > 2:
        a = a.reshape(n, -1)
    if a.ndim == 2 and a.shape[1] == 2:
        a = np.concatenate([a, np.zeros((n, 1), a.dtype)], axis=1)
    return np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))


def symmetric_tensor(S) -> tuple[np.ndarray, tuple]:
    """(n, d, d) symmetric tensors as VTK stores tensors, and their component names.

    Returns (array, names ``TENSOR_COMPONENTS[d]``): in 3D the (n, 6) independent components
    (VTK's symmetric-tensor order); in 2D the (n, 9) 3×3 tensor row by row, the z row and
    column zero, which ParaView recognises as a tensor (a 3-component array it takes for a
    vector). Off-diagonal entries are ½(S_ij + S_ji).
    """
    S = np.asarray(S, float)
    if S.ndim != 3 or S.shape[1] != S.shape[2] or S.shape[1] not in (2, 3):
        raise ValueError(f"symmetric_tensor: expected an (n, 2, 2) or (n, 3, 3) array, got shape {S.shape}")
    d = S.shape[1]
    names = TENSOR_COMPONENTS[d]
    if d == 2:
        sym = 0.5 * (S + S.transpose(0, 2, 1))
        full = np.zeros((S.shape[0], 3, 3))
        full[:, :2, :2] = sym
        return full.reshape(-1, 9), names
    ij = ["xyz".index(a) for a in "".join(names)]
    i, j = np.array(ij[0::2]), np.array(ij[1::2])
    return 0.5 * (S[:, i, j] + S[:, j, i]), names


class _DataWriter:
    """Turns arrays into ``DataArray`` elements: inline base64 or one raw appended block.

    ``"base64"``: header (UInt64 byte count) and data encoded together inside the
    element — read by VTK, ParaView and meshio. ``"raw"``: the bytes go to an
    ``AppendedData`` block after the XML — smaller and faster, read by VTK/ParaView
    (meshio mis-assigns raw blocks whose offsets collide with its re-encoded ones).
    """

    def __init__(self, encoding: str):
        if encoding not in ("base64", "raw"):
            raise ValueError(f"encoding must be 'base64' or 'raw', got {encoding!r}")
        self.raw = encoding == "raw"
        self.blocks: list[np.ndarray] = []
        self.offset = 0

    def tag(self, name: str, a: np.ndarray, indent: str = "        ", components=()) -> bytes:
        # NumberOfComponents only for vectors (VTK's default is 1; meshio then reads 1D arrays)
        comps = f'NumberOfComponents="{a.shape[1]}" ' if a.ndim == 2 else ""
        comps += "".join(f"ComponentName{i}={quoteattr(str(c))} " for i, c in enumerate(components))
        vtype = _VTK_TYPE[(a.dtype.kind, a.dtype.itemsize)]
        head = f'{indent}<DataArray type="{vtype}" Name={quoteattr(name)} {comps}'
        size = np.array([a.nbytes], dtype="<u8").tobytes()
        if self.raw:
            self.blocks.append(a)
            tag = f'{head}format="appended" offset="{self.offset}"/>\n'.encode()
            self.offset += 8 + a.nbytes
            return tag
        return (f'{head}format="binary">\n'.encode() + indent.encode() + b"  "
                + base64.b64encode(size + a.tobytes())
                + f"\n{indent}</DataArray>\n".encode())

    def write_appended(self, f) -> None:
        if not self.raw:
            return
        f.write(b'  <AppendedData encoding="raw">\n   _')
        for a in self.blocks:
            f.write(np.array([a.nbytes], dtype="<u8").tobytes())
            if a.size:
                f.write(memoryview(a).cast("B"))
        f.write(b"\n  </AppendedData>\n")


def _ids(a) -> np.ndarray:
    """Index array as little-endian Int32 when it fits (half the bytes), else Int64."""
    a = np.asarray(a)
    small = a.size == 0 or (a.min() >= -2**31 and a.max() < 2**31)
    return np.ascontiguousarray(a, dtype="<i4" if small else "<i8")


def _data_section(w: _DataWriter, tag: str, data: Mapping[str, np.ndarray], n: int, what: str,
                  names: Mapping[str, Sequence[str]]) -> list:
    if not data:
        return []
    body = []
    for k, v in data.items():
        a = _vtk_array(v, n, f"{what}[{k!r}]")
        comps = tuple(names.get(k, ()))
        if comps and (a.ndim != 2 or len(comps) != a.shape[1]):
            raise ValueError(f"component_names[{k!r}]: {len(comps)} names for an array of shape {a.shape}")
        body.append(w.tag(str(k), a, components=comps))
    return [f"      <{tag}>\n".encode(), *body, f"      </{tag}>\n".encode()]


def write_unstructured_vtu(path, points: np.ndarray, connectivity: np.ndarray, offsets: np.ndarray,
                           types: np.ndarray, *, faces: np.ndarray | None = None,
                           faceoffsets: np.ndarray | None = None,
                           cell_data: Mapping[str, np.ndarray] | None = None,
                           point_data: Mapping[str, np.ndarray] | None = None,
                           encoding: str = "base64",
                           component_names: Mapping[str, Sequence[str]] | None = None) -> Path:
    """Write a VTK XML UnstructuredGrid from raw VTK cell arrays (atomically).

    Parameters
    ----------
    path : str or os.PathLike
    points : (n_points, 2 or 3) float
        Coordinates in m; 2D points get z = 0.
    connectivity : (nnz,) int
        Point ids of all cells, concatenated.
    offsets : (n_cells,) int
        End of every cell in ``connectivity``.
    types : (n_cells,) int
        VTK cell type codes.
    faces, faceoffsets : int arrays, optional
        Polyhedron face streams and their end offsets (-1 for non-polyhedral cells).
    cell_data, point_data : mapping name -> (n_cells, ...) / (n_points, ...) array
    encoding : {"base64", "raw"}
        Inline base64 (default; any reader) or raw appended binary (VTK/ParaView only).
    component_names : mapping array name -> one name per component, optional
        Written as VTK ``ComponentName`` attributes (e.g. from :func:`symmetric_tensor`).

    Returns
    -------
    pathlib.Path
    """
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"points: expected an (n, 2) or (n, 3) array, got shape {points.shape}")
    n_pts, n_cells = points.shape[0], len(types)
    w = _DataWriter(encoding)
    # build every element before touching the disk: bad data raise before a file exists
    parts = [b'<?xml version="1.0"?>\n',
             b'<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n',
             b"  <UnstructuredGrid>\n",
             f'    <Piece NumberOfPoints="{n_pts}" NumberOfCells="{n_cells}">\n'.encode(),
             *_data_section(w, "PointData", point_data or {}, n_pts, "point_data", component_names or {}),
             *_data_section(w, "CellData", cell_data or {}, n_cells, "cell_data", component_names or {}),
             b"      <Points>\n",
             w.tag("Points", _vtk_array(points, n_pts, "points")),
             b"      </Points>\n      <Cells>\n",
             w.tag("connectivity", _ids(connectivity)),
             w.tag("offsets", _ids(offsets)),
             w.tag("types", np.ascontiguousarray(types, np.uint8))]
    if faces is not None:
        parts += [w.tag("faces", _ids(faces)),
                  w.tag("faceoffsets", _ids(faceoffsets))]
    parts.append(b"      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n")
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.writelines(parts)
        w.write_appended(f)
        f.write(b"</VTKFile>\n")
    return Path(path)


# --------------------------------------------------------------------------- topology

def _reversed_values(r: Ragged, flip: np.ndarray) -> np.ndarray:
    """(nnz,) values of ``r`` with the rows where ``flip`` (n,) bool reversed."""
    cnt = r.counts.astype(np.int64)
    start = np.repeat(r.offsets[:-1].astype(np.int64), cnt)
    local = np.arange(r.nnz, dtype=np.int64) - start
    src = np.where(np.repeat(flip, cnt), start + np.repeat(cnt, cnt) - 1 - local, start + local)
    return r.values[src]


def _polygon_loops(mesh) -> tuple[np.ndarray, np.ndarray]:
    """Counter-clockwise boundary node loop of every 2D cell.

    Each incidence (cell, face (a, b), sign) is the directed edge a→b (sign +1) or
    b→a (sign -1), counter-clockwise around the cell; the loop follows the successor
    map "edge ending at node v → edge of the same cell starting at v", found by one
    sort. The walk is vectorised over cells (one step per loop position).

    Returns
    -------
    connectivity : (nnz(cell_faces),) int64
    offsets : (n_cells + 1,) int64
    """
    cf = mesh.cell_faces
    ab = mesh.face_nodes.values.reshape(-1, 2)[cf.values].astype(np.int64)
    plus = mesh.cell_face_sign > 0
    tail = np.where(plus, ab[:, 0], ab[:, 1])
    head = np.where(plus, ab[:, 1], ab[:, 0])
    cell = cf.rows_of_entries().astype(np.int64)
    nn = np.int64(mesh.n_nodes)
    key = cell * nn + tail
    order = np.argsort(key, kind="stable")
    skey = key[order]
    want = cell * nn + head
    pos = np.minimum(np.searchsorted(skey, want), skey.size - 1)
    if not np.array_equal(skey[pos], want) or np.any(np.diff(skey) == 0):
        raise ValueError("write_bulk_vtu: a 2D cell's faces do not form one closed loop")
    nxt = order[pos]

    counts = cf.counts.astype(np.int64)
    offsets = cf.offsets.astype(np.int64)
    conn = np.empty(cf.nnz, dtype=np.int64)
    by_len = np.argsort(-counts, kind="stable")  # longest loops first: active cells are a prefix
    neg = -counts[by_len]
    n_steps = int(counts.max(initial=0))
    n_longer = np.searchsorted(neg, -np.arange(n_steps), side="left")  # cells with more than s edges
    cur = offsets[:-1][by_len].copy()
    first = cur.copy()
    visited = np.zeros(cf.nnz, dtype=bool)
    for s in range(n_steps):
        k = int(n_longer[s])
        cur = cur[:k]
        conn[offsets[by_len[:k]] + s] = tail[cur]
        visited[cur] = True
        cur = nxt[cur]
        done = counts[by_len[:k]] == s + 1
        if np.any(cur[done] != first[:k][done]):
            raise ValueError("write_bulk_vtu: a 2D cell's boundary is not a single closed loop")
    if not visited.all():  # e.g. a cell bounded by two loops: the walk misses one
        raise ValueError("write_bulk_vtu: a 2D cell's boundary is not a single closed loop")
    return conn, offsets


def _polyhedron_faces(mesh) -> tuple[np.ndarray, np.ndarray]:
    """VTK ``faces`` stream and ``faceoffsets`` of every 3D cell, faces oriented outward.

    Per cell the stream is ``[n_faces, m_0, loop_0..., m_1, loop_1..., ...]`` with
    global point ids; ``faceoffsets`` holds the end of every cell's stream.
    """
    cf = mesh.cell_faces
    loops = mesh.face_nodes.take(cf.values)                  # one loop per incidence
    vals = _reversed_values(loops, mesh.cell_face_sign < 0)  # sign -1: face normal points inwards
    m = loops.counts.astype(np.int64)
    cell = cf.rows_of_entries().astype(np.int64)
    block = 1 + m                                            # count + loop
    acc = np.concatenate(([0], np.cumsum(block)))            # stream length of earlier incidences
    n_cells = len(cf)
    ncell = np.arange(n_cells, dtype=np.int64)
    head = acc[cf.offsets[:-1]] + ncell                      # each earlier cell adds one header entry
    inc_pos = acc[:-1] + cell + 1
    stream = np.empty(n_cells + int(acc[-1]), dtype=np.int64)
    stream[head] = cf.counts
    stream[inc_pos] = m
    stream[np.repeat(inc_pos + 1, m) + loops.local_index()] = vals
    ends = acc[cf.offsets[1:]] + ncell + 1
    return stream, ends


_CELLS_CACHE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def bulk_cells(mesh) -> dict:
    """VTK cell arrays of a mesh (cached per mesh object, so time series reuse them).

    Returns
    -------
    dict with ``points`` (n_nodes, 3), ``connectivity``, ``offsets`` (n_cells,) end
    offsets, ``types`` (n_cells,) uint8 and, in 3D, ``faces`` and ``faceoffsets``.
    """
    try:
        return _CELLS_CACHE[mesh]
    except (KeyError, TypeError):
        pass
    nodes = np.asarray(mesh.nodes, float)
    points = np.zeros((mesh.n_nodes, 3))
    points[:, :mesh.dim] = nodes
    if mesh.dim == 2:
        conn, off = _polygon_loops(mesh)
        out = {"points": points, "connectivity": conn, "offsets": off[1:],
               "types": np.full(mesh.n_cells, VTK_POLYGON, np.uint8)}
    else:
        faces, faceoffsets = _polyhedron_faces(mesh)
        out = {"points": points, "connectivity": mesh.cell_nodes.values.astype(np.int64),
               "offsets": mesh.cell_nodes.offsets[1:].astype(np.int64),
               "types": np.full(mesh.n_cells, VTK_POLYHEDRON, np.uint8),
               "faces": faces, "faceoffsets": faceoffsets}
    for a in out.values():
        a.flags.writeable = False
    try:
        _CELLS_CACHE[mesh] = out
    except TypeError:  # not weak-referenceable: no caching
        pass
    return out


def fracture_cells(fm) -> dict:
    """VTK arrays of the fracture faces of a FracturedMesh.

    Returns
    -------
    dict with ``points`` (n_used, 3), ``node_ids`` (n_used,) mesh node of every point,
    ``connectivity``, ``offsets``, ``types``: one cell per fracture face, in
    fracture-face order, oriented so that the right-hand normal is n⁺.
    """
    mesh, net = fm.mesh, fm.network
    faces = np.asarray(net.faces, dtype=np.int64)
    loops = mesh.face_nodes.take(faces)
    # face normals follow the mesh's face orientation; flip loops whose normal opposes n⁺
    flip = np.einsum("ij,ij->i", mesh.geometry.face_normal[faces], np.asarray(net.normal, float)) < 0
    vals = _reversed_values(loops, flip)
    used, conn = np.unique(vals, return_inverse=True)
    points = np.zeros((used.size, 3))
    points[:, :mesh.dim] = mesh.nodes[used]
    ctype = VTK_LINE if mesh.dim == 2 else VTK_POLYGON
    return {"points": points, "node_ids": used.astype(np.int64), "connectivity": conn.astype(np.int64).ravel(),
            "offsets": loops.offsets[1:].astype(np.int64), "types": np.full(faces.size, ctype, np.uint8)}


# --------------------------------------------------------------------------- public writers

def write_bulk_vtu(path, mesh, cell_data: Mapping[str, np.ndarray] | None = None,
                   point_data: Mapping[str, np.ndarray] | None = None, *, encoding: str = "base64",
                   component_names: Mapping[str, Sequence[str]] | None = None) -> Path:
    """Write the mesh's cells as a .vtu file (polygons in 2D, polyhedra in 3D).

    Parameters
    ----------
    path : str or os.PathLike
    mesh : Mesh
    cell_data : mapping name -> (n_cells,) or (n_cells, k) array, optional
        Written after an automatic int32 ``region`` array (a given ``region`` replaces it).
    point_data : mapping name -> (n_nodes,) or (n_nodes, k) array, optional
    encoding : {"base64", "raw"}
        See :func:`write_unstructured_vtu`.
    component_names : mapping array name -> component names, optional
        See :func:`write_unstructured_vtu`.

    Returns
    -------
    pathlib.Path
    """
    c = bulk_cells(mesh)
    cd = {"region": np.asarray(mesh.cell_region, np.int32)}
    cd.update(cell_data or {})
    return write_unstructured_vtu(path, c["points"], c["connectivity"], c["offsets"], c["types"],
                                  faces=c.get("faces"), faceoffsets=c.get("faceoffsets"),
                                  cell_data=cd, point_data=point_data, encoding=encoding,
                                  component_names=component_names)


def write_fracture_vtu(path, fm, cell_data: Mapping[str, np.ndarray] | None = None,
                       point_data: Mapping[str, np.ndarray] | None = None, *, encoding: str = "base64") -> Path:
    """Write the fracture faces as a .vtu file (lines in 2D, polygons in 3D).

    Only the mesh nodes used by fracture faces are written, renumbered in increasing
    mesh-node order.

    Parameters
    ----------
    path : str or os.PathLike
    fm : FracturedMesh
    cell_data : mapping name -> (n_fracture_faces, ...) array, optional
        Per fracture face, in fracture-face order; written after the automatic int32
        ``fracture`` index and the ``normal`` n⁺ (3 components).
    point_data : mapping name -> (n_nodes, ...) array, optional
        Per *mesh* node; restricted to the written nodes.
    encoding : {"base64", "raw"}

    Returns
    -------
    pathlib.Path
    """
    net = fm.network
    c = fracture_cells(fm)
    cd = {"fracture": np.asarray(net.fracture, np.int32), "normal": np.asarray(net.normal, float)}
    cd.update(cell_data or {})
    pd = None
    if point_data:
        n = fm.mesh.n_nodes
        pd = {k: _vtk_array(v, n, f"point_data[{k!r}]")[c["node_ids"]] for k, v in point_data.items()}
    return write_unstructured_vtu(path, c["points"], c["connectivity"], c["offsets"], c["types"],
                                  cell_data=cd, point_data=pd, encoding=encoding)


def write_pvd(path, entries: Sequence[tuple]) -> Path:
    """Write a ParaView collection (.pvd) of time steps.

    Parameters
    ----------
    path : str or os.PathLike
    entries : sequence of (time, file) or (time, file, part)
        ``time`` in s; ``file`` relative to the .pvd's directory; ``part`` (default 0)
        distinguishes several data sets of one time step (e.g. bulk and fractures).

    Returns
    -------
    pathlib.Path
    """
    lines = ['<?xml version="1.0"?>\n',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n',
             "  <Collection>\n"]
    for e in entries:
        if len(e) not in (2, 3):
            raise ValueError(f"write_pvd: entries must be (time, file) or (time, file, part), got {e!r}")
        t, name = float(e[0]), str(Path(e[1]).as_posix())
        part = int(e[2]) if len(e) == 3 else 0
        lines.append(f'    <DataSet timestep="{t!r}" group="" part="{part}" file={quoteattr(name)}/>\n')
    lines.append("  </Collection>\n</VTKFile>\n")
    return atomic_write_text(path, "".join(lines))
