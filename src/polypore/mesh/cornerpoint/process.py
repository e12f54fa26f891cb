"""Corner-point cells -> polypore's polytopal :class:`~polypore.mesh.mesh.Mesh`, edge-conformal.

The algorithm follows MRST's processGRDECL (stack the cells along the pillars, intersect the
lateral faces of laterally adjacent columns, drop inactive and collapsed cells) but builds a
*conforming* surface mesh, so that every cell's faces close exactly (Σ_σ |σ| n_Kσ = 0 to
round-off):

1. **Nodes on pillars** (:mod:`.nodes`). Corner depths of active cells are made monotone along
   each pillar (running maximum down a column of corners: a cell overlapping the cell above is
   cut by it), then merged: depths on one pillar closer than ``ztol`` are one node. A node is
   the pair (pillar, depth). Nodes of different columns closer than ``snap`` × the thinnest
   cell at them are snapped together (no sliver faces on faults).
2. **Collapse.** An active cell whose four corner thicknesses are all zero (pinched out,
   zero volume) is dropped; the cells above and below it then share their coinciding faces,
   as in Eclipse's PINCH. A cell with zero thickness at some corners only is kept (a wedge).
3. **Lateral faces** (:mod:`.strips`, :mod:`.overlap`). On each pillar pair (the two pillars
   shared by two laterally adjacent columns) every cell side is a strip between two *lines*
   (top and bottom edge; a line joins a node on each pillar). The side of a cell on one
   column is intersected with every cell side and every void (gap, inactive or missing cell)
   on the other column: the overlap polygons, convex in the (position along the pair, depth)
   plane, are the faces (interior when both are cells, boundary otherwise). The crossing
   point of two lines is computed once, from the canonical pair of lines, and is one node
   for all the faces that touch it; it sits at (1 − s) P₀(z) + s P₁(z) (P₀, P₁ the pillars,
   z its depth), on both straight edges when the pillars are parallel, between them when
   they are skew.
4. **Edge conformity** (:mod:`.conform`). Every node lying on a line or on a pillar segment
   is inserted into every face having an edge along that line or segment: the lateral faces,
   and the top and bottom faces whose edges are the lines. Each edge of each cell surface
   then appears exactly twice with opposite orientations, so the polyhedra are closed.
5. **Top and bottom faces** (:mod:`.horizontal`) are the bilinear (non-planar in general)
   quadrilaterals of the cells plus the inserted nodes; two vertically consecutive kept
   cells share one when their four corners coincide, otherwise both are boundary faces (a
   void between them).
6. **Planar faces** (:mod:`.planar`). Warped faces are split into triangles around a centre
   node (option ``nonplanar``), so that polypore's HFV flow is exact on affine pressures.

Boundary parts: :mod:`.boundary`. Coordinates: MAPAXES applied (map x, y) minus a local
origin (``info.origin``), z = −depth (elevation, upwards), metres. Everything is vectorised
over cells, lines and faces: sorting and grouping by pillar pair, no loop over pillars,
cells or faces.
"""

from __future__ import annotations

import dataclasses
import time
from types import MappingProxyType

import numpy as np

from ...core.errors import InputError, MeshError
from ...core.ragged import INDEX, Ragged, frozen
from ..mesh import Mesh, assemble_mesh
from .boundary import boundary_groups
from .conform import carriers, insert_edge_nodes, orient_loops
from .faults import detect_faults
from .horizontal import horizontal_faces
from .info import BOUNDARY_NAMES, FACE_I, FACE_J, FACE_K, CornerPointInfo
from .nodes import SNAP, VOLUME_CHANGE, cell_name, pillar_nodes
from .overlap import lateral_faces, pair_pillars
from .pillars import on_pillar, pillar_points, right_handed
from .planar import pairs_may_warp, split_nonplanar_faces
from .reader import CornerPointGrid
from .strips import E, N, make_lines, overlapping_pairs, side_nodes, side_pairs, strips

__all__ = ["process_grid", "split_nonplanar_faces"]


def process_grid(grid: CornerPointGrid, *, ztol: float | None = None, apply_mapaxes: bool = True,
                 origin="auto", nonplanar: str = "centre", regions: str | None = None,
                 find_faults: bool = True, snap: float = SNAP,
                 max_volume_change: float = VOLUME_CHANGE) -> tuple[Mesh, CornerPointInfo]:
    """Turn a corner-point grid into an edge-conformal polytopal mesh.

    Parameters
    ----------
    grid : CornerPointGrid
    ztol : float, optional
        Corner depths on one pillar closer than this are merged (m); default 1e-7 × the
        grid's extent. Cells thinner than it at every corner are collapsed.
    apply_mapaxes : bool
        Map the grid's local x, y with MAPAXES (when present).
    origin : "auto", None or (x0, y0)
        Subtracted from the map x, y (m) so that the mesh coordinates are small (the
        geometric identities and exactness then hold to round-off: with UTM coordinates of
        6e6 m they would lose ~6 digits). "auto": the centre of the grid rounded to 1 km.
        Map coordinates = mesh coordinates + ``info.origin``.
    nonplanar : "centre", "diagonal" or "keep"
        What to do with non-planar faces (warped quadrilaterals of real grids): "centre"
        (default) splits each into the triangles around a new centre node, the average of
        its vertices (not of the nodes inserted on its edges), so that a cell keeps the
        volume of the trilinear corner-point cell; "diagonal" splits warped quadrilaterals
        along their flatter diagonal (no new node, but the volumes of flat cells change by
        up to tens of per cent) and the other warped faces around their centre; "keep"
        leaves them (polypore's HFV is then not exact on affine pressures, docs/flow.md).
        With planar faces the mechanics and HFV reproduce affine fields exactly.
    regions : str, optional
        An integer cell keyword (e.g. ``"FACIES"``, ``"SATNUM"``) giving the cell regions,
        named ``f"{regions}_{value}"``; default one region ``"domain"``.
    find_faults : bool
        Detect and name the faults (:func:`.faults.detect_faults`).
    snap : float
        Nodes of different columns on one pillar closer than ``snap`` × the mean thickness of
        the thinnest cell touching them are merged (to their mean depth weighted by 1 / that
        thickness), so that displaced columns whose corners nearly coincide do not produce
        sliver faces (thin triangles or strips on faults, whose contact multipliers are poorly
        determined), unless a cell at them would change its volume by more than
        ``max_volume_change``; default 0.2, 0 keeps every corner depth (the mesh then has the
        exact trilinear cell volumes). See :func:`.nodes.snap_nodes`.
    max_volume_change : float
        Bound of the snapping's change of any cell's (trilinear) volume, relative to it;
        default 1e-3. ``inf``: no bound (the snapping of before issue 24, which changed
        Emerald's cells by up to 6.6 %).

    Returns
    -------
    mesh : Mesh
        Nodes in m (x, y map coordinates, z = −depth); boundary parts ``west`` ...
        ``internal`` added to the bounding-box names.
    info : CornerPointInfo

    Raises
    ------
    InputError
        All cells inactive, an inverted active cell (bottom above top, named by its 1-based
        (i, j, k)), a bad MAPAXES or REGION keyword; MeshError if a processed cell is
        degenerate (self-intersecting pillars).
    """
    t0 = time.perf_counter()
    seconds = {}
    nx, ny, nz = grid.dims
    top, bot = pillar_points(grid, apply_mapaxes)
    right = right_handed(top, bot, nx, ny)
    if not (snap >= 0 and np.isfinite(snap)):
        raise InputError("snap", f"must be finite and ≥ 0, got {snap!r}")
    if not max_volume_change >= 0:
        raise InputError("max_volume_change", f"must be ≥ 0 (relative), got {max_volume_change!r}")
    pn = pillar_nodes(grid, ztol, snap, None if max_volume_change == np.inf else max_volume_change)
    ci, cj, ck, nid, node_pillar, node_z = pn.ci, pn.cj, pn.ck, pn.nid, pn.node_pillar, pn.node_z
    nc = ci.size
    NT, NB = nid[..., 0], nid[..., 1]                        # (nc, di, dj) node ids
    n_pnodes = node_z.size
    NP = (nx + 1) * (ny + 1)
    pstart = np.searchsorted(node_pillar, np.arange(NP + 1))
    node_rank = np.arange(n_pnodes) - pstart[node_pillar]
    R = int(node_rank.max()) + 1
    NQ = (nx + 1) * ny + nx * (ny + 1)                       # i pairs, then j pairs
    seconds["nodes"] = time.perf_counter() - t0

    # -- lateral faces: strips on pillar pairs and their overlaps ------------------------------
    Q = side_pairs(ci, cj, nx, ny)
    L = make_lines(Q, NT, NB, node_rank, R, node_z)
    st = strips(Q, L.LT, L.LB, ck, L.NL, NQ, nz)
    del Q
    ca, cb = overlapping_pairs(st, L.Z0, L.Z1, float(node_z.min()), float(node_z.max()))
    lat = lateral_faces(st, ca, cb, L, n_pnodes, nx, ny)
    del ca, cb
    nL = lat.ca.size
    hz = horizontal_faces(ci, cj, ck, ny, NT, NB, L.LT, L.LB)
    nH = hz.n

    # -- edge conformity: all face loops with the nodes on their edges --------------------------
    used = np.zeros(n_pnodes, bool)
    used[NT.ravel()] = True
    used[NB.ravel()] = True
    car = carriers(np.flatnonzero(used), node_pillar, NP, L, lat)
    nt = hz.top_cells.size
    e_face = np.concatenate([lat.face, nL + np.repeat(np.arange(nt), 4), nL + nt + np.repeat(np.arange(nc), 4)])
    fnodes, is_vertex, fcount = insert_edge_nodes(e_face, np.concatenate([lat.node, hz.node]),
                                                  np.concatenate([lat.carrier, hz.carrier]), nL + nH, car)
    del e_face, car

    # -- orientation, cells of every face ------------------------------------------------------
    cA, cB = st.cell[lat.ca], st.cell[lat.cb]
    p0, p1, pair_i = pair_pillars(lat.pq, nx, ny)
    nat_to_B = (~pair_i) ^ (not right)          # natural lateral loop normal points from A to B
    plus = np.concatenate([np.where(cA >= 0, cA, cB), hz.top_cells, np.arange(nc)])
    minus = np.concatenate([np.where(cA >= 0, cB, -1), np.full(nt, -1), hz.nb_next])
    # top faces: normal up (out of the cell); bottom faces: normal down (out of the upper cell)
    flip = np.concatenate([np.where(cA >= 0, ~nat_to_B, nat_to_B), np.full(nt, not right), np.full(nc, right)])
    fnodes, is_vertex = orient_loops(fnodes, is_vertex, fcount, flip)
    del flip

    # -- nodes: compacted, coordinates -----------------------------------------------------------
    X, face_nodes = _coordinates(fnodes, fcount, n_pnodes + lat.x_a.size, node_pillar, node_z, lat, top, bot,
                                 nx, ny)
    del fnodes
    group = boundary_groups(st, lat.ca, lat.cb, pair_i, hz, ci, cj, ck, grid.dims)
    face_kind = np.concatenate([np.where(pair_i, FACE_I, FACE_J), np.full(nH, FACE_K)]).astype(np.int8)
    face_pair = np.concatenate([lat.pq, np.full(nH, -1)]).astype(INDEX)
    displaced = np.zeros(nL + nH, bool)
    displaced[:nL] = (cA >= 0) & (cB >= 0) & ((st.top[lat.ca] != st.top[lat.cb]) | (st.bot[lat.ca] != st.bot[lat.cb]))
    if pn.nid0 is not None:
        # a fault stays a fault where snapping made its corners coincide: displaced before snapping
        both = np.flatnonzero((cA >= 0) & (cB >= 0))
        a_side = np.where(pair_i[both], E, N)
        displaced[both] |= (side_nodes(pn.nid0, cA[both], a_side) != side_nodes(pn.nid0, cB[both], a_side - 1)).any(1)
    del st

    # -- local origin, planar faces --------------------------------------------------------------
    origin = _origin(origin, X)
    X[:, :2] -= origin
    maybe = np.ones(nL + nH, bool)
    maybe[:nL] = pairs_may_warp(top, bot, p0, p1)
    X, face_nodes, parent = split_nonplanar_faces(X, face_nodes, nonplanar, is_vertex, candidates=maybe)
    plus, minus, group = plus[parent], minus[parent], group[parent]
    face_kind, face_pair, displaced = face_kind[parent], face_pair[parent], displaced[parent]
    boundary = {name: np.flatnonzero(group == g_).astype(INDEX) for g_, name in enumerate(BOUNDARY_NAMES)}
    inc_cell = np.concatenate([plus, minus[minus >= 0]])
    inc_face = np.concatenate([np.arange(plus.size), np.flatnonzero(minus >= 0)])
    inc_sign = np.concatenate([np.ones(plus.size, np.int8), -np.ones(int((minus >= 0).sum()), np.int8)])
    o = np.argsort(inc_cell, kind="stable")
    cell_faces = Ragged.from_counts(np.bincount(inc_cell, minlength=nc), inc_face[o].astype(INDEX))
    cell_sign = inc_sign[o]
    cell_region, region_names = _regions(grid, regions, ci, cj, ck)
    seconds["faces"] = time.perf_counter() - t0 - seconds["nodes"]
    try:
        mesh = assemble_mesh(3, X, face_nodes, cell_faces, cell_sign, boundary, cell_region, region_names)
    except MeshError:
        # name the grid cell (i, j, k) when a processed cell is folded; else the builder's message
        _check_volumes(X, face_nodes, inc_cell, inc_face, inc_sign, nc, pn.nat, nx, ny, grid.source)
        raise
    seconds["mesh"] = time.perf_counter() - t0 - seconds["nodes"] - seconds["faces"]
    info = CornerPointInfo(
        dims=(nx, ny, nz), origin=frozen(origin.copy()), cell_ijk=frozen(np.stack([ci, cj, ck], 1).astype(INDEX)),
        cell_index=frozen(pn.nat.astype(INDEX)), face_kind=frozen(face_kind), face_pair=frozen(face_pair),
        face_displaced=frozen(displaced),
        boundary=MappingProxyType({k: mesh.boundary[k] for k in BOUNDARY_NAMES}),
        handedness="right" if right else "left", ztol=float(pn.ztol), n_active=int(pn.n_active),
        n_collapsed=int(pn.n_active - nc), snap=float(snap), n_snapped=int(pn.n_snapped))
    if find_faults:
        info = detect_faults(mesh, info, grid)
    seconds["faults"] = time.perf_counter() - t0 - sum(seconds.values())
    info = dataclasses.replace(info, seconds=MappingProxyType(seconds))
    return mesh, info


def _coordinates(fnodes, fcount, NN, node_pillar, node_z, lat, top, bot, nx, ny):
    """The used nodes, compacted (pillar nodes, then crossings), their coordinates (x, y map,
    z = −depth) and the face loops on the new numbering."""
    n_pnodes = node_z.size
    used = np.zeros(NN, bool)
    used[fnodes] = True
    new_id = np.cumsum(used) - 1
    ids = np.flatnonzero(used)
    P = ids < n_pnodes
    X = np.empty((ids.size, 3))
    pn = ids[P]
    X[P, :2] = on_pillar(top, bot, node_pillar[pn], node_z[pn])
    X[P, 2] = -node_z[pn]
    xn = ids[~P] - n_pnodes
    xs, xz = lat.x_s[xn], lat.x_z[xn]
    xp0, xp1, _ = pair_pillars(lat.x_q[xn], nx, ny)
    X[~P, :2] = (1 - xs)[:, None] * on_pillar(top, bot, xp0, xz) + xs[:, None] * on_pillar(top, bot, xp1, xz)
    X[~P, 2] = -xz
    return X, Ragged.from_counts(fcount, new_id[fnodes].astype(INDEX))


def _origin(origin, X):
    if origin is None:
        return np.zeros(2)
    if isinstance(origin, str):
        if origin != "auto":
            raise InputError("origin", f"must be 'auto', None or (x0, y0), got {origin!r}")
        # round to 1 km: map coordinates stay easy to restore, local ones are small (round-off)
        return np.round(0.5 * (X[:, :2].min(0) + X[:, :2].max(0)), -3)
    return np.asarray(origin, float).reshape(2)


def _regions(grid, regions, ci, cj, ck):
    """Cell regions from an integer cell keyword (None: one region)."""
    if regions is None:
        return None, None
    key_ = regions.upper()
    if key_ not in grid.properties:
        raise InputError("regions", f"no cell keyword {regions!r} in {grid.source}; it has {sorted(grid.properties)}")
    vals = grid.properties[key_][ci, cj, ck]
    if not np.all(vals == np.round(vals)):
        raise InputError("regions", f"{key_} must hold integers to define regions")
    uv, cell_region = np.unique(vals.astype(np.int64), return_inverse=True)
    return cell_region, tuple(f"{key_}_{v}" for v in uv)


def _check_volumes(X, faces: Ragged, inc_cell, inc_face, inc_sign, nc, nat, nx, ny, source):
    """InputError naming the first cell (1-based i, j, k) whose processed volume is not positive
    (self-intersecting or folded pillars and corners), before the mesh builder sees it."""
    v = faces.values
    nxt = np.arange(v.size) + 1
    nxt[faces.offsets[1:] - 1] = faces.offsets[:-1]
    A = 0.5 * np.add.reduceat(np.cross(X[v], X[v[nxt]]), faces.offsets[:-1], axis=0)
    xf = np.add.reduceat(X[v], faces.offsets[:-1], axis=0) / faces.counts[:, None]
    w = np.einsum("ki,ki->k", xf, A) / 3.0                  # exact for planar faces
    vol = np.bincount(inc_cell, weights=inc_sign * w[inc_face], minlength=nc)
    size = np.bincount(inc_cell, weights=np.linalg.norm(A, axis=1)[inc_face], minlength=nc) ** 1.5
    bad = np.flatnonzero(~(vol > 1e-12 * size))
    if bad.size:
        raise InputError(f"{source}:COORD/ZCORN", f"cell {cell_name(nat[bad[0]], nx, ny)} has a non-positive volume "
                         f"({vol[bad[0]]:.3e} m³) once processed: its corners are folded or its pillars cross "
                         f"({bad.size} such cell(s)); corner depths must increase downwards on straight, "
                         "non-crossing pillars")
