"""Corner-point cells -> polypore's polytopal :class:`~polypore.mesh.mesh.Mesh`, edge-conformal.

The algorithm follows MRST's processGRDECL (stack the cells along the pillars, intersect the
lateral faces of laterally adjacent columns, drop inactive and collapsed cells) but builds a
*conforming* surface mesh, so that every cell's faces close exactly (Σ_σ |σ| n_Kσ = 0 to
round-off):

1. **Nodes on pillars.** Corner depths of active cells are made monotone along each pillar
   (running maximum down a column of corners: a cell overlapping the cell above is cut by
   it), then snapped: depths on one pillar closer than ``ztol`` are one node. A node is the
   pair (pillar, depth).
2. **Collapse.** An active cell whose four corner thicknesses are all zero (pinched out,
   zero volume) is dropped; the cells above and below it then share their coinciding faces,
   as in Eclipse's PINCH. A cell with zero thickness at some corners only is kept (a wedge).
3. **Lateral faces.** On each pillar pair (the two pillars shared by two laterally adjacent
   columns) every cell side is a strip between two *lines* (top and bottom edge; a line
   joins a node on each pillar). The side of a cell on one column is intersected with every
   cell side and every void (gap, inactive or missing cell) on the other column: the
   overlap polygons, convex in the (position along the pair, depth) plane, are the faces
   (interior when both are cells, boundary otherwise). The crossing point of two lines is
   computed once, from the canonical pair of lines, and is one node for all the faces that
   touch it; it sits at (1 − s) P₀(z) + s P₁(z) (P₀, P₁ the pillars, z its depth), on both
   straight edges when the pillars are parallel, between them when they are skew.
4. **Edge conformity.** Every node lying on a line or on a pillar segment is inserted into
   every face having an edge along that line or segment: the lateral faces, and the top
   and bottom faces whose edges are the lines. Each edge of each cell surface then appears
   exactly twice with opposite orientations, so the polyhedra are closed.
5. **Top and bottom faces** are the bilinear (non-planar in general) quadrilaterals of the
   cells plus the inserted nodes; two vertically consecutive kept cells share one when
   their four corners coincide, otherwise both are boundary faces (a void between them).
6. **Planar faces.** Warped faces are split into triangles around a centre node (option
   ``nonplanar``), so that polypore's HFV flow is exact on affine pressures.

Coordinates: MAPAXES applied (map x, y) minus a local origin (``info.origin``), z = −depth
(elevation, upwards), metres. Everything is vectorised over cells, lines and faces: sorting
and grouping by pillar pair, no loop over pillars, cells or faces.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ...core.errors import InputError, MeshError
from ...core.ragged import INDEX, Ragged, frozen
from ..mesh import Mesh, assemble_mesh
from .faults import detect_faults
from .reader import CornerPointGrid

BIG = 1.0e30                     # depth of the sentinel lines above / below every column
CELL, ABOVE, INNER, BELOW, EMPTY = 0, 1, 2, 3, 4
W, E, S, N = 0, 1, 2, 3          # cell sides: i-min, i-max, j-min, j-max
FACE_I, FACE_J, FACE_K = 0, 1, 2
BOUNDARY_NAMES = ("west", "east", "south", "north", "top", "bottom", "internal")


@dataclass(frozen=True, eq=False)
class CornerPointInfo:
    """What the processed mesh keeps of its corner-point grid.

    Attributes (n_c mesh cells, n_f mesh faces)
    ------------------------------------------
    dims : (nx, ny, nz)
    origin : (2,) float64, m
        Map x, y of the mesh's origin (map coordinates = mesh coordinates + origin).
    cell_ijk : (n_c, 3) int32
        0-based (i, j, k) of every mesh cell.
    cell_index : (n_c,) int32
        Natural (Eclipse) index i + nx (j + ny k) of every mesh cell.
    face_kind : (n_f,) int8
        0: lateral face between i-neighbours (on an i pillar pair), 1: between j-neighbours,
        2: top / bottom face.
    face_pair : (n_f,) int32
        Pillar pair of lateral faces (i pairs (i, j) -> i·ny + j, then j pairs (i, j) ->
        (nx+1)·ny + i·(ny+1) + j), −1 for top / bottom faces.
    face_displaced : (n_f,) bool
        Interior lateral faces whose two cells' corners do not coincide (fault faces).
    boundary : mapping name -> (k,) int32
        ``west``, ``east``, ``south``, ``north``: lateral faces towards −i, +i, −j, +j whose
        void is open to that side of the grid (no kept cell beyond them along their row or
        column in the void's layers); ``top``, ``bottom``: top / bottom faces of the columns'
        extreme cells and the fault scarps exposed above / below the neighbouring column;
        ``internal``: the other voids (holes of inactive cells, vertical gaps). They
        partition the boundary faces.
    faults : mapping name -> (k,) int32
        Fault faces (see :mod:`.faults`): named from FAULTS, else ``fault_1``, ``fault_2``...
    handedness : str
        ``"right"`` if (i, j, up) is a right-handed frame in the output coordinates.
    ztol : float
        Depth tolerance used to merge corner depths on a pillar (m).
    n_active, n_collapsed : int
        Active cells in the grid; active cells dropped as collapsed (zero thickness).
    seconds : mapping stage -> s
        Processing time per stage: ``nodes`` (corner depths, pillar nodes), ``faces``
        (lines, overlaps, edge insertion, splitting), ``mesh`` (topology checks and
        geometry), ``faults``.
    """

    dims: tuple
    origin: np.ndarray
    cell_ijk: np.ndarray
    cell_index: np.ndarray
    face_kind: np.ndarray
    face_pair: np.ndarray
    face_displaced: np.ndarray
    boundary: Mapping[str, np.ndarray]
    faults: Mapping[str, np.ndarray] = field(default_factory=dict)
    handedness: str = "right"
    ztol: float = 0.0
    n_active: int = 0
    n_collapsed: int = 0
    seconds: Mapping[str, float] = field(default_factory=dict)

    def cell_values(self, values: np.ndarray) -> np.ndarray:
        """Per-mesh-cell values of an (nx, ny, nz) array, e.g. ``grid.properties["PORO"]``."""
        values = np.asarray(values)
        if values.shape[:3] != tuple(self.dims):
            raise InputError("cell_values", f"expected an array of shape {tuple(self.dims)}, got {values.shape}")
        i, j, k = self.cell_ijk.T
        return values[i, j, k]

    def cell_name(self, cell: int) -> str:
        """"(i, j, k)" of mesh cell ``cell``, 1-based as in the GRDECL file (for messages)."""
        i, j, k = (int(a) + 1 for a in self.cell_ijk[cell])
        return f"({i}, {j}, {k})"

    def cells_in(self, i=None, j=None, k=None) -> np.ndarray:
        """(m,) int32 mesh cells whose 0-based (i, j, k) lie in the given ranges.

        Each of i, j, k is None (all), an int or an inclusive (first, last) pair; e.g. a
        vertical well through column (10, 12) in layers 3 to 7: ``cells_in(10, 12, (3, 7))``.
        """
        keep = np.ones(self.cell_ijk.shape[0], bool)
        for axis, r in enumerate((i, j, k)):
            if r is None:
                continue
            lo, hi = (r, r) if np.isscalar(r) else (int(r[0]), int(r[1]))
            keep &= (self.cell_ijk[:, axis] >= lo) & (self.cell_ijk[:, axis] <= hi)
        return np.flatnonzero(keep).astype(INDEX)


# -- pillars ------------------------------------------------------------------------------------
def pillar_points(grid: CornerPointGrid, apply_mapaxes: bool = True):
    """(NP, 3) top and bottom pillar points (x, y map coordinates, depth), pillar p = i (ny+1) + j."""
    c = grid.coord.reshape(-1, 6).copy()
    if apply_mapaxes and grid.mapaxes is not None:
        p1, p0, p2 = grid.mapaxes
        ex, ey = p2 - p0, p1 - p0
        lx, ly = np.linalg.norm(ex), np.linalg.norm(ey)
        if lx == 0 or ly == 0 or abs(ex[0] * ey[1] - ex[1] * ey[0]) < 1e-12 * lx * ly:
            raise InputError(f"{grid.source}:MAPAXES", f"degenerate axes {grid.mapaxes.tolist()}: the points "
                             "on the x and y axes must differ from the origin and not be aligned with it")
        ex, ey = ex / lx, ey / ly
        for o in (0, 3):
            x, y = c[:, o].copy(), c[:, o + 1].copy()
            c[:, o] = p0[0] + x * ex[0] + y * ey[0]
            c[:, o + 1] = p0[1] + x * ex[1] + y * ey[1]
    return c[:, :3], c[:, 3:]


def _on_pillar(top, bot, p, z):
    """(k, 2) x, y of the points at depth z on pillars p (straight lines top–bottom)."""
    zt, zb = top[p, 2], bot[p, 2]
    dz = zb - zt
    flat = np.abs(dz) <= 1e-12 * np.maximum(1.0, np.abs(zt))
    t = np.where(flat, 0.0, (z - zt) / np.where(flat, 1.0, dz))
    return top[p, :2] + t[:, None] * (bot[p, :2] - top[p, :2])


def _handedness(top, bot, nx, ny) -> bool:
    """True if e_i × e_j points up (towards smaller depth) on average over the columns."""
    xy = 0.5 * (top[:, :2] + bot[:, :2])
    P = xy.reshape(nx + 1, ny + 1, 2)
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    area2 = ((c[..., 0] - a[..., 0]) * (d[..., 1] - b[..., 1]) - (c[..., 1] - a[..., 1]) * (d[..., 0] - b[..., 0]))
    return bool(area2.sum() > 0)


MILLIDARCY = 9.869233e-16      # m²


def cell_permeability(grid: CornerPointGrid, info: CornerPointInfo, *, apply_mapaxes: bool = True,
                      ntg: bool = True) -> np.ndarray:
    """(n_c, 3, 3) permeability tensors in m² from PERMX, PERMY, PERMZ (mD).

    The tensor is diag(PERMX, PERMY, PERMZ) in the frame of the cell's column: e_i along the
    mean direction of its i edges (map x, y, horizontal), e_j orthogonal to it in the
    horizontal plane on the side of the j edges, e_z vertical; PERMY defaults to PERMX and
    PERMZ to PERMX too when absent. With ``ntg`` the horizontal values are multiplied by NTG
    (as Eclipse does for transmissibilities). Dip is not followed (fine for gentle dips).
    """
    if "PERMX" not in grid.properties:
        raise InputError(f"{grid.source}:PERMX", "missing: the permeability needs PERMX (mD)")
    kx = info.cell_values(grid.properties["PERMX"])
    ky = info.cell_values(grid.properties["PERMY"]) if "PERMY" in grid.properties else kx
    kz = info.cell_values(grid.properties["PERMZ"]) if "PERMZ" in grid.properties else kx
    if ntg and "NTG" in grid.properties:
        f = info.cell_values(grid.properties["NTG"])
        kx, ky = kx * f, ky * f
    vals = np.stack([kx, ky, kz], 1) * MILLIDARCY
    if np.any(vals < 0) or not np.all(np.isfinite(vals)):
        raise InputError(f"{grid.source}:PERMX", "permeabilities must be finite and ≥ 0")
    nx, ny, _ = grid.dims
    top, bot = pillar_points(grid, apply_mapaxes)
    P = (0.5 * (top[:, :2] + bot[:, :2])).reshape(nx + 1, ny + 1, 2)
    i, j = info.cell_ijk[:, 0], info.cell_ijk[:, 1]
    ei = 0.5 * (P[i + 1, j] - P[i, j] + P[i + 1, j + 1] - P[i, j + 1])
    ej = 0.5 * (P[i, j + 1] - P[i, j] + P[i + 1, j + 1] - P[i + 1, j])
    ei /= np.maximum(np.linalg.norm(ei, axis=1), 1e-300)[:, None]
    perp = np.stack([-ei[:, 1], ei[:, 0]], 1)
    ej = perp * np.where(np.einsum("ki,ki->k", perp, ej) >= 0, 1.0, -1.0)[:, None]
    R = np.zeros((i.size, 3, 3))
    R[:, :2, 0], R[:, :2, 1], R[:, 2, 2] = ei, ej, 1.0
    return np.einsum("kab,kb,kcb->kac", R, vals, R)


# -- the processor ------------------------------------------------------------------------------
def _cell_name(nat, nx, ny):
    i, j, k = nat % nx, (nat // nx) % ny, nat // (nx * ny)
    return f"({i + 1}, {j + 1}, {k + 1})"


def _corner_nodes(grid: CornerPointGrid, ztol: float | None):
    """Active cells, their snapped corner nodes and the pillar nodes."""
    nx, ny, nz = grid.dims
    src = grid.source
    nat = np.flatnonzero(grid.actnum.transpose(2, 1, 0).ravel())
    if nat.size == 0:
        raise InputError(f"{src}:ACTNUM", "all cells are inactive; at least one cell needs ACTNUM = 1")
    ci, cj, ck = nat % nx, (nat // nx) % ny, nat // (nx * ny)
    Z = grid.cell_corners()                                   # (nx, ny, nz, di, dj, dk)
    zr = Z[ci, cj, ck]
    if not np.all(np.isfinite(zr)):
        bad = nat[np.flatnonzero(~np.isfinite(zr).all(axis=(1, 2, 3)))[0]]
        raise InputError(f"{src}:ZCORN", f"cell {_cell_name(bad, nx, ny)} has a depth that is not a finite number")
    xy = grid.coord.reshape(-1, 6)
    span = float(max(np.ptp(zr), np.ptp(xy[:, [0, 3]]), np.ptp(xy[:, [1, 4]]), 1e-300))
    if ztol is None:
        ztol = 1e-7 * span
    inv = (zr[..., 1] < zr[..., 0] - ztol).any(axis=(1, 2))
    if inv.any():
        a = int(np.flatnonzero(inv)[0])
        di, dj = np.argwhere(zr[a, :, :, 1] < zr[a, :, :, 0] - ztol)[0]
        raise InputError(f"{src}:ZCORN", f"cell {_cell_name(nat[a], nx, ny)} is inverted: at its corner (di, dj) = "
                         f"({di}, {dj}) the bottom depth {zr[a, di, dj, 1]:.6g} is above the top depth "
                         f"{zr[a, di, dj, 0]:.6g}; ZCORN must not decrease from a cell's top to its bottom "
                         f"({int(inv.sum())} inverted active cell(s))")
    # monotone corner depths down every column of corners, over active cells only: a cell
    # overlapping the one above is cut by it (running maximum)
    Zm = np.where(grid.actnum[:, :, :, None, None, None], Z, -np.inf).transpose(0, 1, 3, 4, 2, 5)
    Zm = np.maximum.accumulate(Zm.reshape(nx, ny, 2, 2, 2 * nz), axis=-1).reshape(nx, ny, 2, 2, nz, 2)
    zc = Zm.transpose(0, 1, 4, 2, 3, 5)[ci, cj, ck]          # (na, di, dj, dk)
    del Zm
    na = nat.size
    di = np.arange(2)[None, :, None, None]
    dj = np.arange(2)[None, None, :, None]
    pil = np.broadcast_to((ci[:, None, None, None] + di) * (ny + 1) + cj[:, None, None, None] + dj,
                          (na, 2, 2, 2)).ravel()
    z = zc.ravel()
    zmin, zspan = float(z.min()), float(np.ptp(z)) + 1.0
    kmax = (float(pil.max()) + 1.0) * zspan
    if ztol > 1e3 * np.spacing(kmax):
        # one float sort instead of two: its round-off (≪ ztol) cannot split or join clusters
        order = np.argsort(pil * zspan + (z - zmin))
    else:
        order = np.lexsort((z, pil))
    zs, ps = z[order], pil[order]
    new = np.empty(zs.size, bool)
    new[0] = True
    new[1:] = (ps[1:] != ps[:-1]) | (zs[1:] - zs[:-1] > ztol)
    cid = np.cumsum(new) - 1
    nid = np.empty(z.size, dtype=np.int64)
    nid[order] = cid
    node_pillar = ps[new].astype(np.int64)
    node_z = zs[new]
    return nat, ci, cj, ck, nid.reshape(na, 2, 2, 2), node_pillar, node_z, ztol


def _lines(q, n0, n1, node_rank, R):
    """Unique lines (pair, node at s=0, node at s=1): ids of the given ones and the first occurrences."""
    key = (q.astype(np.int64) * R + node_rank[n0]) * R + node_rank[n1]
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    return inv.reshape(q.shape), first


def _cross(L, M, Z0, Z1):
    """Crossing of lines L and M strictly between the pillars, computed from the ordered pair."""
    a, b = np.minimum(L, M), np.maximum(L, M)
    a0, a1, b0, b1 = Z0[a], Z1[a], Z0[b], Z1[b]
    d0, d1 = a0 - b0, a1 - b1
    ok = ((d0 < 0) & (d1 > 0)) | ((d0 > 0) & (d1 < 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(ok, d0 / np.where(ok, d0 - d1, 1.0), 0.5)
    return ok, s, a0 + s * (a1 - a0), a, b


def _at(L, s, Z0, Z1):
    return Z0[L] + s * (Z1[L] - Z0[L])


def process_grid(grid: CornerPointGrid, *, ztol: float | None = None, apply_mapaxes: bool = True,
                 origin="auto", nonplanar: str = "centre", regions: str | None = None,
                 find_faults: bool = True) -> tuple[Mesh, CornerPointInfo]:
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
    right = _handedness(top, bot, nx, ny)
    nat, ci, cj, ck, nid, node_pillar, node_z, ztol = _corner_nodes(grid, ztol)
    n_active = nat.size
    kept = (nid[..., 1] != nid[..., 0]).any(axis=(1, 2))
    if not kept.any():
        raise InputError(f"{grid.source}:ZCORN", f"all {n_active} active cells have zero thickness")
    nat, ci, cj, ck, nid = nat[kept], ci[kept], cj[kept], ck[kept], nid[kept]
    nc = nat.size
    NT, NB = nid[..., 0], nid[..., 1]                        # (nc, di, dj) node ids
    n_pnodes = node_z.size
    pstart = np.searchsorted(node_pillar, np.arange((nx + 1) * (ny + 1) + 1))
    node_rank = np.arange(n_pnodes) - pstart[node_pillar]
    R = int(node_rank.max()) + 1
    NI = (nx + 1) * ny                                       # i pairs, then j pairs
    NQ = NI + nx * (ny + 1)

    seconds["nodes"] = time.perf_counter() - t0
    # -- cell sides on pillar pairs: lines --------------------------------------------------
    Q = np.stack([ci * ny + cj, (ci + 1) * ny + cj, NI + ci * (ny + 1) + cj, NI + ci * (ny + 1) + cj + 1], 1)
    s0 = [(0, 0), (1, 0), (0, 0), (0, 1)]                    # corner (di, dj) at s = 0 per side
    s1 = [(0, 1), (1, 1), (1, 0), (1, 1)]
    n0t = np.stack([NT[:, a, b] for a, b in s0], 1)
    n1t = np.stack([NT[:, a, b] for a, b in s1], 1)
    n0b = np.stack([NB[:, a, b] for a, b in s0], 1)
    n1b = np.stack([NB[:, a, b] for a, b in s1], 1)
    lid, first = _lines(np.concatenate([Q, Q], 1), np.concatenate([n0t, n0b], 1),
                        np.concatenate([n1t, n1b], 1), node_rank, R)
    LT, LB = lid[:, :4], lid[:, 4:]
    NL = first.size
    ln0 = np.concatenate([n0t, n0b], 1).ravel()[first]
    ln1 = np.concatenate([n1t, n1b], 1).ravel()[first]
    del n0t, n1t, n0b, n1b
    # two sentinel lines (ids NL, NL+1) above and below everything
    Z0 = np.concatenate([node_z[ln0], [-BIG, BIG]])
    Z1 = np.concatenate([node_z[ln1], [-BIG, BIG]])
    N0 = np.concatenate([ln0, [-1, -1]])
    N1 = np.concatenate([ln1, [-1, -1]])
    ST, SB = NL, NL + 1

    # -- regions: cell sides and the voids between them, per (pair, role) -------------------
    role = np.array([1, 0, 1, 0])                            # west/south sides are role B (1)
    g = (Q * 2 + role).ravel()
    kk = np.repeat(ck, 4)
    order = np.lexsort((kk, g))
    gs, ks = g[order], kk[order]
    cs = np.repeat(np.arange(nc), 4)[order]
    ts, bs = LT.ravel()[order], LB.ravel()[order]
    del order, g, kk
    head = np.ones(gs.size, bool)
    head[1:] = gs[1:] != gs[:-1]
    tail = np.ones(gs.size, bool)
    tail[:-1] = head[1:]
    inner = ~head.copy()
    inner[1:] &= bs[:-1] != ts[1:]
    inner_idx = np.flatnonzero(inner)
    empty_g = np.setdiff1d(np.arange(2 * NQ), gs[head])
    rg = np.concatenate([gs, gs[head], gs[inner_idx], gs[tail], empty_g])
    rord = np.concatenate([2 * ks, 2 * ks[head] - 1, 2 * ks[inner_idx] - 1, 2 * ks[tail] + 1,
                           np.zeros(empty_g.size, np.int64)])
    rtop = np.concatenate([ts, np.full(head.sum(), ST), bs[inner_idx - 1], bs[tail], np.full(empty_g.size, ST)])
    rbot = np.concatenate([bs, ts[head], ts[inner_idx], np.full(tail.sum(), SB), np.full(empty_g.size, SB)])
    rcell = np.concatenate([cs, np.full(head.sum() + inner_idx.size + tail.sum() + empty_g.size, -1)])
    rkind = np.concatenate([np.full(cs.size, CELL), np.full(head.sum(), ABOVE), np.full(inner_idx.size, INNER),
                            np.full(tail.sum(), BELOW), np.full(empty_g.size, EMPTY)]).astype(np.int8)
    # layers of the void regions between kept cells (k_lo > k_hi: a gap without missing cells)
    rk0 = np.concatenate([ks, np.zeros(head.sum(), np.int64), ks[inner_idx - 1] + 1, ks[tail] + 1,
                          np.full(empty_g.size, -1)])
    rk1 = np.concatenate([ks, ks[head] - 1, ks[inner_idx] - 1, np.full(tail.sum(), nz - 1),
                          np.full(empty_g.size, -1)])
    del gs, ks, cs, ts, bs, head, tail, inner, inner_idx
    o = np.lexsort((rord, rg))
    rg, rtop, rbot, rcell, rkind, rk0, rk1 = rg[o], rtop[o], rbot[o], rcell[o], rkind[o], rk0[o], rk1[o]
    del rord, o
    rq = rg // 2
    isB = (rg % 2).astype(bool)
    A = np.flatnonzero(~isB)
    B = np.flatnonzero(isB)

    # -- candidate pairs of regions (bounding depth ranges overlap) -------------------------
    zlo, zhi = float(node_z.min()), float(node_z.max())
    scale = 0.5 / max(zhi - zlo, 1e-300)

    def key(q, z):
        return q + 0.25 + (np.clip(z, zlo, zhi) - zlo) * scale

    rzmin = np.minimum(Z0[rtop], Z1[rtop])
    rzmax = np.maximum(Z0[rbot], Z1[rbot])
    pad = 1e-7
    kBmax = key(rq[B], rzmax[B])
    kBmin = key(rq[B], rzmin[B])
    lo = np.searchsorted(kBmax, key(rq[A], rzmin[A]) - pad, side="right")
    hi = np.searchsorted(kBmin, key(rq[A], rzmax[A]) + pad, side="left")
    cnt = np.maximum(hi - lo, 0)
    ca = np.repeat(A, cnt)
    cb = B[np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(cnt.sum())]
    del kBmax, kBmin, lo, hi, cnt, rzmin, rzmax
    # a cell side of zero thickness at both pillars (top line = bottom line) has no face
    keep = ((rcell[ca] >= 0) | (rcell[cb] >= 0)) & (rq[ca] == rq[cb]) & (rtop[ca] != rbot[ca]) & (rtop[cb] != rbot[cb])
    ca, cb = ca[keep], cb[keep]
    # exact pre-test: strips lying on one side of each other at both pillars (touching at
    # most) have no overlap of positive area; the others do
    tA, bA, tB, bB = rtop[ca], rbot[ca], rtop[cb], rbot[cb]
    below = (Z0[tA] >= Z0[bB]) & (Z1[tA] >= Z1[bB])
    above = (Z0[bA] <= Z0[tB]) & (Z1[bA] <= Z1[tB])
    keep = ~(below | above)
    ca, cb = ca[keep], cb[keep]
    del tA, bA, tB, bB, below, above, keep
    poly = _polygons(rtop[ca], rbot[ca], rtop[cb], rbot[cb], Z0, Z1, N0, N1)
    ok = poly["count"] >= 3
    # crossing nodes: one per crossing pair of lines, numbered after the pillar nodes
    sub = poly["sub"]
    xmask = poly["xa"] >= 0
    xmask &= ok[sub][:, None]
    xr, xc = np.nonzero(xmask)
    xa, xb = poly["xa"][xr, xc].astype(np.int64), poly["xb"][xr, xc].astype(np.int64)
    ukey, xfirst, xinv = np.unique(xa * (NL + 2) + xb, return_index=True, return_inverse=True)
    n_x = ukey.size
    node = poly["node"]
    node[sub[xr], xc] = n_pnodes + xinv
    x_s, x_z = poly["s"][xr, xc][xfirst], poly["z"][xr, xc][xfirst]
    x_a, x_b = xa[xfirst], xb[xfirst]
    x_q = rq[ca[sub[xr[xfirst]]]]
    ca, cb = ca[ok], cb[ok]
    valid = poly["valid"][ok]
    node = node[ok]
    stype_all = poly["stype"][ok]
    lines_all = poly["lines"][ok]
    del poly, xmask, xr, xc, xa, xb
    nL = ca.size
    pq = rq[ca]
    # lateral face loops (flat, slot order) and the carrier of every edge
    rows, cols = np.nonzero(valid)
    lat_face = rows
    lat_node = node[rows, cols]
    lat_st = stype_all[rows, cols]
    lat_lines = lines_all[rows, cols]                        # (e, 4)
    del stype_all, lines_all
    cntf = np.bincount(rows, minlength=nL)
    offs = np.zeros(nL + 1, np.int64)
    np.cumsum(cntf, out=offs[1:])
    nxt = np.arange(rows.size) + 1
    nxt[offs[1:] - 1] = offs[:-1]
    st_v, lines_v = lat_st[nxt], lat_lines[nxt]
    on_pillar = (lat_st == st_v) & (lat_st < 2)
    # the edge runs along the line both ends lie on: most share their first line
    common = np.where(lat_lines[:, 0] == lines_v[:, 0], lat_lines[:, 0], -1)
    slow = np.flatnonzero((common < 0) & ~on_pillar)
    if slow.size:
        lu, lv = lat_lines[slow], lines_v[slow]
        match = (lu[:, :, None] == lv[:, None, :]).any(2) & (lu >= 0)
        common[slow] = np.where(match.any(1), lu[np.arange(slow.size), np.argmax(match, 1)], -1)
        if np.any(common[slow] < 0):
            raise AssertionError("corner-point processing: an edge of a lateral face has no carrier line")
    pair_i = pq < NI
    qi, qj = np.where(pair_i, pq // ny, (pq - NI) // (ny + 1)), np.where(pair_i, pq % ny, (pq - NI) % (ny + 1))
    p0 = qi * (ny + 1) + qj
    p1 = np.where(pair_i, p0 + 1, p0 + ny + 1)
    pil_car = NL + np.where(lat_st == 0, p0[rows], p1[rows])
    lat_car = np.where(on_pillar, pil_car, common)
    del valid, rows, cols, nxt, st_v, lines_v, lat_lines, common, pil_car, slow

    # -- top and bottom faces --------------------------------------------------------------
    col = ci * ny + cj
    corder = np.lexsort((ck, col))
    same_col = col[corder][1:] == col[corder][:-1]
    shared = np.zeros(nc, bool)                              # bottom of cell shared with the next cell below
    nb_next = np.full(nc, -1)
    up, dn = corder[:-1], corder[1:]
    sh = same_col & (NB[up] == NT[dn]).all(axis=(1, 2))
    shared[up[sh]] = True
    nb_next[up[sh]] = dn[sh]
    is_top = np.ones(nc, bool)                               # topmost kept cell of its column
    is_top[dn[same_col]] = False
    is_bottom = np.ones(nc, bool)
    is_bottom[up[same_col]] = False
    top_cells = np.flatnonzero(~np.isin(np.arange(nc), nb_next[shared]))   # tops not shared with the cell above
    corners = [(0, 0), (1, 0), (1, 1), (0, 1)]
    sides = [S, E, N, W]

    def hloops(cells, Nn, L):
        v = np.stack([Nn[cells, a, b] for a, b in corners], 1)
        c = np.stack([L[cells, s_] for s_ in sides], 1)
        return v.ravel(), c.ravel()
    hv_t, hc_t = hloops(top_cells, NT, LT)
    hv_b, hc_b = hloops(np.arange(nc), NB, LB)
    nH = top_cells.size + nc

    # -- carriers: lines and pillars with the nodes on them, in order -----------------------
    # one block per line (its node at s=0, its crossings by s, its node at s=1), then one per
    # pillar (its used nodes by depth); an edge end's position in its carrier's block is found
    # by gathers (no search), and the nodes strictly between an edge's ends are inserted
    NP = (nx + 1) * (ny + 1)
    used_p = np.zeros(n_pnodes, bool)
    used_p[NT.ravel()] = True
    used_p[NB.ravel()] = True
    up_nodes = np.flatnonzero(used_p)                        # sorted by (pillar, depth): cluster order
    up_pil = node_pillar[up_nodes]
    p_count = np.bincount(up_pil, minlength=NP)
    inc_line = np.concatenate([x_a, x_b])
    inc_x = np.concatenate([np.arange(n_x), np.arange(n_x)])
    o = np.lexsort((inc_x, np.concatenate([x_s, x_s]), inc_line))
    ncross = np.bincount(inc_line, minlength=NL)
    cstart = np.zeros(NL + NP + 1, np.int64)
    np.cumsum(np.concatenate([ncross + 2, p_count]), out=cstart[1:])
    cnode = np.empty(int(cstart[-1]), np.int64)
    cnode[cstart[:NL]] = ln0
    cnode[cstart[1:NL + 1] - 1] = ln1
    il = inc_line[o]
    first_inc = np.cumsum(ncross) - ncross
    pos_inc = cstart[il] + 1 + (np.arange(o.size) - first_inc[il])
    cnode[pos_inc] = n_pnodes + inc_x[o]
    xpos = np.empty(2 * n_x, np.int64)
    xpos[o] = pos_inc
    ppos = np.zeros(n_pnodes, np.int64)
    pfirst = np.cumsum(p_count) - p_count
    ppos[up_nodes] = cstart[NL + up_pil] + (np.arange(up_nodes.size) - pfirst[up_pil])
    cnode[ppos[up_nodes]] = up_nodes
    del inc_line, inc_x, o, il, first_inc, pos_inc, up_pil, pfirst
    NN = n_pnodes + n_x

    def position(c, v):
        pos_ = np.empty(c.size, np.int64)
        on_pillar = c >= NL
        pos_[on_pillar] = ppos[v[on_pillar]]
        isx = np.flatnonzero(~on_pillar & (v >= n_pnodes))
        if isx.size:
            xi = v[isx] - n_pnodes
            pos_[isx] = np.where(x_a[xi] == c[isx], xpos[xi], xpos[n_x + xi])
        ln = np.flatnonzero(~on_pillar & (v < n_pnodes))
        cl = c[ln]
        pos_[ln] = np.where(N0[cl] == v[ln], cstart[cl], cstart[cl + 1] - 1)
        if not np.array_equal(cnode[pos_], v):
            raise AssertionError("corner-point processing: an edge end is not on its carrier")
        return pos_

    # -- all face loops, edges expanded with the nodes on them -------------------------------
    e_face = np.concatenate([lat_face, nL + np.repeat(np.arange(top_cells.size), 4),
                             nL + top_cells.size + np.repeat(np.arange(nc), 4)])
    e_u = np.concatenate([lat_node, hv_t, hv_b])
    e_car = np.concatenate([lat_car, hc_t, hc_b])
    fo = np.zeros(nL + nH + 1, np.int64)
    np.cumsum(np.bincount(e_face, minlength=nL + nH), out=fo[1:])
    e_next = np.arange(e_u.size) + 1
    e_next[fo[1:] - 1] = fo[:-1]
    iu = position(e_car, e_u)
    iv = position(e_car, e_u[e_next])
    del e_next, lat_node, lat_car, hv_t, hv_b, hc_t, hc_b
    n_ins = np.abs(iv - iu) - 1
    if (n_ins < 0).any():
        raise AssertionError("corner-point processing: a degenerate edge")
    start = np.zeros(e_u.size, np.int64)                    # output position of every edge's first node
    np.cumsum(1 + n_ins[:-1], out=start[1:])
    total = int(start[-1] + 1 + n_ins[-1]) if e_u.size else 0
    fnodes = np.empty(total, np.int64)
    is_vertex = np.zeros(total, bool)                        # a polygon vertex, not an inserted node
    fnodes[start] = e_u
    is_vertex[start] = True
    ins = np.flatnonzero(n_ins > 0)
    if ins.size:
        k = n_ins[ins]
        eid = np.repeat(ins, k)
        j = np.arange(eid.size) - np.repeat(np.cumsum(k) - k, k) + 1
        fnodes[start[eid] + j] = cnode[iu[eid] + j * np.sign(iv[eid] - iu[eid])]
        del k, eid, j
    fcount = np.bincount(e_face, weights=1 + n_ins, minlength=nL + nH).astype(np.int64)
    del start, iu, iv, n_ins, ins, e_u, e_car, e_face

    # -- orientation, cells of every face ---------------------------------------------------
    cA, cB = rcell[ca], rcell[cb]
    nat_to_B = (~pair_i) ^ (not right)          # natural lateral loop normal points from A to B
    plus_l = np.where(cA >= 0, cA, cB)
    minus_l = np.where(cA >= 0, cB, -1)
    flip_l = np.where(cA >= 0, ~nat_to_B, nat_to_B)
    # top faces: normal up (out of the cell); bottom faces: normal down (out of the upper cell)
    plus_h = np.concatenate([top_cells, np.arange(nc)])
    minus_h = np.concatenate([np.full(top_cells.size, -1), nb_next])
    flip_h = np.concatenate([np.full(top_cells.size, not right), np.full(nc, right)])
    plus = np.concatenate([plus_l, plus_h])
    minus = np.concatenate([minus_l, minus_h])
    flip = np.concatenate([flip_l, flip_h])
    foff = np.zeros(fcount.size + 1, np.int64)
    np.cumsum(fcount, out=foff[1:])
    frow = np.repeat(np.arange(fcount.size), fcount)
    local = np.arange(fnodes.size) - foff[frow]
    src_idx = np.where(flip[frow], foff[frow] + fcount[frow] - 1 - local, np.arange(fnodes.size))
    fnodes = fnodes[src_idx]
    is_vertex = is_vertex[src_idx]
    del frow, local, src_idx

    # -- compact the nodes and compute their coordinates ------------------------------------
    used = np.zeros(NN, bool)
    used[fnodes] = True
    new_id = np.cumsum(used) - 1
    ids = np.flatnonzero(used)
    P = ids < n_pnodes
    X = np.empty((ids.size, 3))
    pn = ids[P]
    X[P, :2] = _on_pillar(top, bot, node_pillar[pn], node_z[pn])
    X[P, 2] = -node_z[pn]
    xn = ids[~P] - n_pnodes
    xs, xz, xq = x_s[xn], x_z[xn], x_q[xn]
    xpi = xq < NI
    xi, xj = np.where(xpi, xq // ny, (xq - NI) // (ny + 1)), np.where(xpi, xq % ny, (xq - NI) % (ny + 1))
    xp0 = xi * (ny + 1) + xj
    xp1 = np.where(xpi, xp0 + 1, xp0 + ny + 1)
    X[~P, :2] = (1 - xs)[:, None] * _on_pillar(top, bot, xp0, xz) + xs[:, None] * _on_pillar(top, bot, xp1, xz)
    X[~P, 2] = -xz
    face_nodes = Ragged.from_counts(fcount, new_id[fnodes].astype(INDEX))
    del fnodes, used, new_id

    # -- boundary groups ---------------------------------------------------------------------
    # A lateral face towards a void is on the west (east, south, north) side when no kept cell
    # lies beyond it in the void's layers along its row (column): the void is open to that
    # side of the grid (missing columns, inactive cells at the edge); otherwise the void is
    # inside (a hole: "internal"). Voids above / below the neighbour column's cells: top / bottom.
    nF = plus.size
    group = np.full(nF, -1, np.int8)
    first_ik = np.full((ny, nz), nx)
    last_ik = np.full((ny, nz), -1)
    first_jk = np.full((nx, nz), ny)
    last_jk = np.full((nx, nz), -1)
    np.minimum.at(first_ik, (cj, ck), ci)
    np.maximum.at(last_ik, (cj, ck), ci)
    np.minimum.at(first_jk, (ci, ck), cj)
    np.maximum.at(last_jk, (ci, ck), cj)
    bl = np.flatnonzero(minus_l < 0)
    void = np.where(cA[bl] >= 0, cb[bl], ca[bl])
    kind_v = rkind[void]
    cell_l = plus_l[bl]
    li, lj, lk = ci[cell_l], cj[cell_l], ck[cell_l]
    k0 = np.where(kind_v == EMPTY, lk, rk0[void])
    k1 = np.where(kind_v == EMPTY, lk, rk1[void])
    on_A = cA[bl] >= 0                                       # the void lies on the +i / +j side
    is_i = pair_i[bl]

    def range_ext(table, row, fn, fill):
        """fn (min or max) of table[row, k0..k1] per face (fill where the range is empty)."""
        flat = np.append(table.ravel(), fill)
        st = row * nz + np.clip(k0, 0, nz - 1)
        en = row * nz + np.clip(k1, 0, nz - 1) + 1
        ok = k1 >= k0
        idx = np.stack([np.where(ok, st, flat.size - 1), np.where(ok, en, flat.size - 1)], 1).ravel()
        out = fn.reduceat(flat, np.minimum(idx, flat.size - 1))[0::2]
        return np.where(ok, out, fill)
    open_w = range_ext(first_ik, lj, np.minimum, -1) >= li
    open_e = range_ext(last_ik, lj, np.maximum, nx) <= li
    open_s = range_ext(first_jk, li, np.minimum, -1) >= lj
    open_n = range_ext(last_jk, li, np.maximum, ny) <= lj
    side_g = np.where(is_i, np.where(on_A, np.where(open_e, 1, 6), np.where(open_w, 0, 6)),
                      np.where(on_A, np.where(open_n, 3, 6), np.where(open_s, 2, 6)))
    group[bl] = np.select([kind_v == ABOVE, kind_v == BELOW], [4, 5], side_g)
    group[nL:nL + top_cells.size] = np.where(is_top[top_cells], 4, 6)
    hb = minus_h[top_cells.size:] < 0
    group[nL + top_cells.size:][hb] = np.where(is_bottom[hb], 5, 6)

    face_kind = np.concatenate([np.where(pair_i, FACE_I, FACE_J), np.full(nH, FACE_K)]).astype(np.int8)
    face_pair = np.concatenate([pq, np.full(nH, -1)]).astype(INDEX)
    displaced = np.zeros(nF, bool)
    displaced[:nL] = (cA >= 0) & (cB >= 0) & ((rtop[ca] != rtop[cb]) | (rbot[ca] != rbot[cb]))

    # -- local origin, planar faces ---------------------------------------------------------
    if origin is None:
        origin = np.zeros(2)
    elif isinstance(origin, str):
        if origin != "auto":
            raise InputError("origin", f"must be 'auto', None or (x0, y0), got {origin!r}")
        # round to 1 km: map coordinates stay easy to restore, local ones are small (round-off)
        origin = np.round(0.5 * (X[:, :2].min(0) + X[:, :2].max(0)), -3)
    origin = np.asarray(origin, float).reshape(2)
    X[:, :2] -= origin
    # lateral faces on a pair of coplanar pillars (parallel or meeting) are planar: not checked
    Tq = top[np.stack([p0, p1], 1)]
    Dq = bot[np.stack([p0, p1], 1)] - Tq
    w = np.einsum("ki,ki->k", Tq[:, 1] - Tq[:, 0], np.cross(Dq[:, 0], Dq[:, 1]))
    mag = (np.linalg.norm(Tq[:, 1] - Tq[:, 0], axis=1) * np.linalg.norm(Dq[:, 0], axis=1)
           * np.linalg.norm(Dq[:, 1], axis=1))
    maybe = np.ones(nL + nH, bool)
    maybe[:nL] = np.abs(w) > 1e-14 * mag
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


    cell_region, region_names = None, None
    if regions is not None:
        key_ = regions.upper()
        if key_ not in grid.properties:
            raise InputError("regions", f"no cell keyword {regions!r} in {grid.source}; it has "
                             f"{sorted(grid.properties)}")
        vals = grid.properties[key_][ci, cj, ck]
        if not np.all(vals == np.round(vals)):
            raise InputError("regions", f"{key_} must hold integers to define regions")
        uv, cell_region = np.unique(vals.astype(np.int64), return_inverse=True)
        region_names = tuple(f"{key_}_{v}" for v in uv)
    seconds["faces"] = time.perf_counter() - t0 - seconds["nodes"]
    try:
        mesh = assemble_mesh(3, X, face_nodes, cell_faces, cell_sign, boundary, cell_region, region_names)
    except MeshError:
        # name the grid cell (i, j, k) when a processed cell is folded; else the builder's message
        _check_volumes(X, face_nodes, inc_cell, inc_face, inc_sign, nc, nat, nx, ny, grid.source)
        raise
    seconds["mesh"] = time.perf_counter() - t0 - seconds["nodes"] - seconds["faces"]
    info = CornerPointInfo(
        dims=(nx, ny, nz), origin=frozen(origin.copy()), cell_ijk=frozen(np.stack([ci, cj, ck], 1).astype(INDEX)),
        cell_index=frozen(nat.astype(INDEX)), face_kind=frozen(face_kind), face_pair=frozen(face_pair),
        face_displaced=frozen(displaced),
        boundary=MappingProxyType({k: mesh.boundary[k] for k in BOUNDARY_NAMES}),
        handedness="right" if right else "left", ztol=float(ztol), n_active=int(n_active),
        n_collapsed=int(n_active - nc))
    if find_faults:
        info = detect_faults(mesh, info, grid)
    seconds["faults"] = time.perf_counter() - t0 - sum(seconds.values())
    info = dataclasses.replace(info, seconds=MappingProxyType(seconds))
    return mesh, info


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
        raise InputError(f"{source}:COORD/ZCORN", f"cell {_cell_name(nat[bad[0]], nx, ny)} has a non-positive volume "
                         f"({vol[bad[0]]:.3e} m³) once processed: its corners are folded or its pillars cross "
                         f"({bad.size} such cell(s)); corner depths must increase downwards on straight, "
                         "non-crossing pillars")


NONPLANAR_TOL = 1e-12      # relative distance of a node to its face's plane above which a face is split


def split_nonplanar_faces(X: np.ndarray, faces: Ragged, mode: str = "centre", is_vertex: np.ndarray | None = None,
                          tol: float = NONPLANAR_TOL, candidates: np.ndarray | None = None):
    """Split warped faces into planar triangles (see ``nonplanar`` of :func:`process_grid`).

    The centre node of a split face is the average of its polygon vertices (``is_vertex``,
    aligned with ``faces.values``; default all nodes), not of the nodes inserted on its edges:
    for a quadrilateral whose edges carry collinear inserted nodes the triangles then cover
    exactly the four triangles around the bilinear face's midpoint, so that the cell volume
    stays the trilinear (corner-point) one. ``candidates`` (n_faces,) bool: the faces that may
    be warped (default all).

    Returns ``(X, faces, parent)``: the nodes (new centre nodes appended), the faces (kept
    ones first, in order, then the triangles) and the original face of every face.
    Triangles keep the orientation of their face.
    """
    if mode not in ("centre", "diagonal", "keep"):
        raise InputError("nonplanar", f"must be 'centre', 'diagonal' or 'keep', got {mode!r}")
    nf = len(faces)
    if mode == "keep":
        return X, faces, np.arange(nf)
    warped = np.zeros(nf, bool)
    for m, rows, conn in faces.groups():
        if m == 3:
            continue
        if candidates is not None:
            sel = candidates[rows]
            rows, conn = rows[sel], conn[sel]
        if m == 4:
            # a quadrilateral's nodes are all ±w·n/4 off its vector-area plane, w = a − b + c − d
            a, b, c, d = (X[conn[:, i]] for i in range(4))
            n = np.cross(c - a, d - b)
            w = a - b + c - d
            dist = np.abs(np.einsum("ki,ki->k", w, n)) / (4 * np.maximum(np.linalg.norm(n, axis=1), 1e-300))
            size = np.maximum(np.linalg.norm(c - a, axis=1), np.linalg.norm(d - b, axis=1))
            warped[rows] = dist > tol * size
            continue
        P = X[conn]
        c = P.mean(1)
        Y = P - c[:, None]
        A = 0.5 * np.cross(Y, np.roll(Y, -1, axis=1)).sum(1)
        n = A / np.maximum(np.linalg.norm(A, axis=1), 1e-300)[:, None]
        dist = np.abs(np.einsum("kmi,ki->km", Y, n)).max(1)
        warped[rows] = dist > tol * 2 * np.linalg.norm(Y, axis=2).max(1)
    keep = np.flatnonzero(~warped)
    counts, values, parent = [faces.counts[keep]], [faces.take(keep).values], [keep]
    new_nodes = []
    n0 = X.shape[0]
    for m, rows, conn in faces.groups():
        sel = warped[rows]
        if not sel.any():
            continue
        rows, conn = rows[sel], conn[sel]
        if mode == "diagonal" and m == 4:
            a, b, c, d = (X[conn[:, i]] for i in range(4))

            def cosang(p, q, r, t):
                n1, n2 = np.cross(q - p, r - p), np.cross(r - p, t - p)
                return np.einsum("ki,ki->k", n1, n2) / np.maximum(
                    np.linalg.norm(n1, axis=1) * np.linalg.norm(n2, axis=1), 1e-300)
            c1, c2 = cosang(a, b, c, d), cosang(b, c, d, a)
            ok = np.maximum(c1, c2) > 0
            first = c1 >= c2
            q = conn[ok]
            tri = np.where(first[ok][:, None, None], np.stack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], 1),
                           np.stack([q[:, [1, 2, 3]], q[:, [1, 3, 0]]], 1))
            counts.append(np.full(2 * tri.shape[0], 3))
            values.append(tri.ravel())
            parent.append(np.repeat(rows[ok], 2))
            rows, conn = rows[~ok], conn[~ok]
            if not rows.size:
                continue
        cid = n0 + sum(len(v) for v in new_nodes) + np.arange(rows.size)
        if is_vertex is None:
            new_nodes.append(X[conn].mean(1))
        else:
            w = is_vertex[faces.positions(rows, m)].astype(float)
            new_nodes.append(np.einsum("km,kmi->ki", w, X[conn]) / w.sum(1)[:, None])
        tri = np.stack([np.broadcast_to(cid[:, None], conn.shape), conn, np.roll(conn, -1, axis=1)], 2)
        counts.append(np.full(tri.shape[0] * m, 3))
        values.append(tri.ravel())
        parent.append(np.repeat(rows, m))
    if new_nodes:
        X = np.vstack([X] + new_nodes)
    return X, Ragged.from_counts(np.concatenate(counts), np.concatenate(values).astype(INDEX)), np.concatenate(parent)


def _polygons(tA, bA, tB, bB, Z0, Z1, N0, N1) -> dict:
    """Overlap polygons of the strips [tA, bA] and [tB, bB] on a pillar pair, in 8 slots.

    Slots, in loop order (upper chain left to right, lower chain right to left):
    0 top at s=0, 1 crossing tA×tB, 2 top at s=1, 3 right pinch, 4 bottom at s=1,
    5 crossing bA×bB, 6 bottom at s=0, 7 left pinch. A slot is valid if the polygon has
    that vertex; ``stype`` is 0 / 1 (on the pillar at s = 0 / 1) or 2 (a crossing);
    ``lines`` (n, 8, 4) the lines the vertex lies on, −1 padded (the edge between two
    vertices runs along their common line, or along the pillar when both are on it);
    crossings: ``s``, ``z`` (position along the pair, depth) and ``xa`` < ``xb`` their lines.
    """
    n = tA.size
    shape = (n, 8)
    valid = np.zeros(shape, bool)
    node = np.full(shape, -1, np.int64)
    stype = np.full(shape, 2, np.int8)
    lines = np.full(shape + (4,), -1, INDEX)
    h_end = []
    for end, Zs, Ns, slot_t, slot_b in ((0, Z0, N0, 0, 6), (1, Z1, N1, 2, 4)):
        zta, ztb, zba, zbb = Zs[tA], Zs[tB], Zs[bA], Zs[bB]
        upper_a = zta >= ztb
        lower_a = zba <= zbb
        h = np.where(lower_a, zba, zbb) - np.where(upper_a, zta, ztb)
        lt = np.where(upper_a, tA, tB)
        lb = np.where(lower_a, bA, bB)
        lt2 = np.where(zta == ztb, np.where(upper_a, tB, tA), lt)
        lb2 = np.where(zba == zbb, np.where(lower_a, bB, bA), lb)
        valid[:, slot_t] = h >= 0
        node[:, slot_t] = Ns[lt]
        stype[:, slot_t] = end
        # a vertex pinched on the pillar (h = 0) also lies on the bottom line(s)
        lines[:, slot_t, 0], lines[:, slot_t, 1] = lt, lt2
        pinched = h == 0
        lines[pinched, slot_t, 2], lines[pinched, slot_t, 3] = lb[pinched], lb2[pinched]
        valid[:, slot_b] = h > 0
        node[:, slot_b] = Ns[lb]
        stype[:, slot_b] = end
        lines[:, slot_b, 0], lines[:, slot_b, 1] = lb, lb2
        h_end.append(h)
    both_ends = (h_end[0] >= 0) & (h_end[1] >= 0)

    # crossings: only where two of the four lines swap order between the pillars (faults)
    def swaps(L, M):
        return (Z0[L] - Z0[M]) * (Z1[L] - Z1[M]) < 0
    sub = np.flatnonzero(swaps(tA, tB) | swaps(bA, bB) | swaps(tA, bB) | swaps(tB, bA))
    s = np.zeros((sub.size, 8))
    z = np.zeros((sub.size, 8))
    xa = np.full((sub.size, 8), -1, INDEX)
    xb = np.full((sub.size, 8), -1, INDEX)
    tA, bA, tB, bB, both = tA[sub], bA[sub], tB[sub], bB[sub], both_ends[sub]
    vs = valid[sub]
    ls = lines[sub]

    def put(slot, ok, sx, zx, a, b, la, lb_):
        vs[:, slot] |= ok
        s[ok, slot], z[ok, slot] = sx[ok], zx[ok]
        ls[ok, slot, 0], ls[ok, slot, 1] = la[ok], lb_[ok]
        xa[ok, slot], xb[ok, slot] = a[ok], b[ok]

    # upper chain kink tA×tB: inside both strips (always, by concavity, when both ends are)
    ok, sx, zx, a, b = _cross(tA, tB, Z0, Z1)
    ok &= both | ((zx <= _at(bA, sx, Z0, Z1)) & (zx <= _at(bB, sx, Z0, Z1)))
    put(1, ok, sx, zx, a, b, tA, tB)
    ok, sx, zx, a, b = _cross(bA, bB, Z0, Z1)
    ok &= both | ((zx >= _at(tA, sx, Z0, Z1)) & (zx >= _at(tB, sx, Z0, Z1)))
    put(5, ok, sx, zx, a, b, bA, bB)
    # pinches: the top of one strip meets the bottom of the other on the polygon's boundary
    for t_, b_, t_o, b_o in ((tA, bB, tB, bA), (tB, bA, tA, bB)):
        ok, sx, zx, a, b = _cross(t_, b_, Z0, Z1)
        ok &= (zx >= _at(t_o, sx, Z0, Z1)) & (zx <= _at(b_o, sx, Z0, Z1)) & ~both
        right_end = Z0[t_] < Z0[b_]                 # the polygon lies on the left of the pinch
        for slot, side in ((3, right_end), (7, ~right_end)):
            put(slot, ok & side & ~vs[:, slot], sx, zx, a, b, t_, b_)
    valid[sub] = vs
    lines[sub] = ls
    return {"valid": valid, "node": node, "stype": stype, "lines": lines, "sub": sub, "s": s, "z": z,
            "xa": xa, "xb": xb, "count": valid.sum(1)}
