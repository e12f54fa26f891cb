"""Nodes on pillars: corner depths of the active cells -> pillar nodes (pillar, depth).

Three steps, vectorised over the corners of all active cells:

1. **Monotone corner depths.** Down every column of corners, over active cells only, the depths
   are made non-decreasing (running maximum: a cell overlapping the cell above is cut by it).
   An active cell whose bottom is above its top by more than ``ztol`` is refused (inverted).
2. **Merging.** Depths on one pillar closer than ``ztol`` are one node.
3. **Snapping** (:func:`snap_nodes`): nodes of *different* columns on one pillar closer than
   ``snap`` × the thickness of the thinnest cell touching them are merged too (to their mean
   depth weighted by 1 / that thickness), provided that no cell's volume changes by more than
   ``max_volume_change`` (relative; default :data:`VOLUME_CHANGE` = 1e-3): merges that would are
   undone. Displaced columns (faults) whose corners nearly coincide otherwise produce sliver
   faces: thin triangles between the pillar and a nearby crossing of two lines, or thin
   strips, whose contact multipliers are poorly determined (docs/cornerpoint.md, "Sliver fault
   faces"). A node never merges with another node of its own column, so no cell loses
   thickness at a corner and the depths stay monotone in every column.

Then the **collapse**: an active cell whose four corner thicknesses are all zero (pinched out)
is dropped (:func:`pillar_nodes`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.errors import InputError
from .reader import CornerPointGrid

SNAP = 0.2      # default of process_grid(snap=): relative to the thinnest cell at the nodes
VOLUME_CHANGE = 1e-3   # default of process_grid(max_volume_change=): relative, per cell
_ROUNDS = 50           # rounds of undoing merges (each undoes at least one; a handful in practice)


def cell_name(nat, nx, ny):
    """"(i, j, k)", 1-based, of the grid cell with natural index ``nat``."""
    i, j, k = nat % nx, (nat // nx) % ny, nat // (nx * ny)
    return f"({i + 1}, {j + 1}, {k + 1})"


@dataclass(frozen=True, eq=False)
class PillarNodes:
    """The kept cells (nc), their corner nodes and the pillar nodes (sorted by pillar, depth)."""

    nat: np.ndarray            # (nc,) natural index of every kept cell
    ci: np.ndarray             # (nc,) i, j, k
    cj: np.ndarray
    ck: np.ndarray
    nid: np.ndarray            # (nc, di, dj, dk) node ids
    node_pillar: np.ndarray    # (n,) pillar of every node
    node_z: np.ndarray         # (n,) depth of every node
    ztol: float
    n_active: int
    n_snapped: int             # nodes merged away by snapping
    nid0: np.ndarray | None    # (nc, di, dj, dk) node ids before snapping (None: nothing snapped)


def pillar_nodes(grid: CornerPointGrid, ztol: float | None, snap: float,
                 max_volume_change: float | None = VOLUME_CHANGE) -> PillarNodes:
    """Corner nodes of the active cells, snapped (no cell's volume changed by more than
    ``max_volume_change``, relative; None: no bound), with the collapsed cells dropped."""
    nat, ci, cj, ck, nid, node_pillar, node_z, ztol = corner_nodes(grid, ztol)
    n_active = nat.size
    nx, ny, _ = grid.dims
    n_snapped, nid0 = 0, None
    if snap > 0:
        nid0 = nid
        pillars = ((ci[:, None, None] + np.arange(2)[None, :, None]) * (ny + 1)
                   + cj[:, None, None] + np.arange(2)[None, None, :])                  # (na, di, dj)
        volume = None if max_volume_change is None else _TrilinearVolume(grid.coord.reshape(-1, 6), pillars)
        nid, node_pillar, node_z, n_snapped = snap_nodes(nid, node_pillar, node_z, ci * ny + cj, snap,
                                                         volume, max_volume_change)
        if not n_snapped:
            nid0 = None
    kept = (nid[..., 1] != nid[..., 0]).any(axis=(1, 2))
    if not kept.any():
        raise InputError(f"{grid.source}:ZCORN", f"all {n_active} active cells have zero thickness")
    if not kept.all():
        nat, ci, cj, ck, nid = nat[kept], ci[kept], cj[kept], ck[kept], nid[kept]
        nid0 = None if nid0 is None else nid0[kept]
    return PillarNodes(nat, ci, cj, ck, nid, node_pillar, node_z, float(ztol), int(n_active), int(n_snapped), nid0)


def corner_nodes(grid: CornerPointGrid, ztol: float | None):
    """Active cells, their corner nodes (depths merged within ``ztol``) and the pillar nodes."""
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
        raise InputError(f"{src}:ZCORN", f"cell {cell_name(bad, nx, ny)} has a depth that is not a finite number")
    xy = grid.coord.reshape(-1, 6)
    span = float(max(np.ptp(zr), np.ptp(xy[:, [0, 3]]), np.ptp(xy[:, [1, 4]]), 1e-300))
    if ztol is None:
        ztol = 1e-7 * span
    inv = (zr[..., 1] < zr[..., 0] - ztol).any(axis=(1, 2))
    if inv.any():
        a = int(np.flatnonzero(inv)[0])
        di, dj = np.argwhere(zr[a, :, :, 1] < zr[a, :, :, 0] - ztol)[0]
        raise InputError(f"{src}:ZCORN", f"cell {cell_name(nat[a], nx, ny)} is inverted: at its corner (di, dj) = "
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


class _TrilinearVolume:
    """Volumes of trilinear corner-point cells from their corner depths (2 × 2 × 2 Gauss points:
    exact for a trilinear hexahedron), vectorised over cells.

    ``coord`` (NP, 6) pillars' top and bottom points (x, y, depth) in the grid's frame (MAPAXES
    left out: it does not change relative volumes), ``pillars`` (na, 2, 2) the pillar of every
    cell corner (di, dj)."""

    _G = 0.5 + np.array([-0.5, 0.5]) / np.sqrt(3.0)

    def __init__(self, coord: np.ndarray, pillars: np.ndarray):
        self.top, self.bot = coord[:, :3], coord[:, 3:]
        self.pillars = pillars

    def __call__(self, cells: np.ndarray, z: np.ndarray) -> np.ndarray:
        """(m,) volumes (m³, signed: left-handed grids negative) of ``cells`` with corner depths
        ``z`` (m, di, dj, dk)."""
        p = self.pillars[cells][..., None]                    # (m, 2, 2, 1)
        zt, zb = self.top[p, 2], self.bot[p, 2]
        dz = zb - zt
        flat = np.abs(dz) <= 1e-12 * np.maximum(1.0, np.abs(zt))
        t = np.where(flat, 0.0, (z - zt) / np.where(flat, 1.0, dz))
        P = np.empty(z.shape + (3,))                         # (m, di, dj, dk, xyz)
        P[..., :2] = self.top[p, :2] + t[..., None] * (self.bot[p, :2] - self.top[p, :2])
        P[..., 2] = z
        P -= P[:, :1, :1, :1]                                # round-off: relative to a corner
        vol = np.zeros(len(cells))
        d = np.array([-1.0, 1.0])
        for a in self._G:
            for b in self._G:
                for c in self._G:
                    w = [np.array([1.0 - u, u]) for u in (a, b, c)]
                    J = np.stack([np.einsum("p,q,r,npqrx->nx", d, w[1], w[2], P),
                                  np.einsum("p,q,r,npqrx->nx", w[0], d, w[2], P),
                                  np.einsum("p,q,r,npqrx->nx", w[0], w[1], d, P)], -1)
                    vol += np.linalg.det(J) / 8.0
        return vol


def snap_nodes(nid: np.ndarray, node_pillar: np.ndarray, node_z: np.ndarray, column: np.ndarray, snap: float,
               volume=None, max_volume_change: float = VOLUME_CHANGE):
    """Merge nearly coincident nodes of different columns on a pillar, within a volume bound.

    Consecutive nodes on a pillar are linked when their depths differ by less than ``snap`` ×
    h, h the smallest mean thickness of the cells having a corner at either node; a run of
    linked nodes (a cluster) becomes one node at their mean depth weighted by 1/h (a node of
    thin cells moves least), unless two of its nodes belong to one column (a thin cell's top
    and bottom, a gap): such a cluster is left as it is. Cells of zero mean thickness
    (collapsed) do not count. With ``volume``, a merge is undone when a cell with a corner in
    it would change its volume by more than ``max_volume_change`` × its volume; undoing
    merges changes the other cells at them, so this is repeated until no cell is beyond the
    bound (each round undoes at least one merge; a few rounds in practice).

    Parameters: ``nid`` (na, 2, 2, 2) node ids of the active cells' corners, ``node_pillar``,
    ``node_z`` (n,) sorted by (pillar, depth), ``column`` (na,) column id of every cell,
    ``volume`` a :class:`_TrilinearVolume` of the cells (None: no volume bound).
    Returns ``(nid, node_pillar, node_z, n_merged)`` (nodes renumbered, still sorted).
    """
    nn = node_z.size
    gap = np.diff(node_z)
    same = node_pillar[1:] == node_pillar[:-1]
    zt, zb = node_z[nid[..., 0]], node_z[nid[..., 1]]
    hc = (zb - zt).mean(axis=(1, 2))                         # mean thickness of every cell
    live = hc > 0
    if not live.any():
        return nid, node_pillar, node_z, 0
    cand = same & (gap < snap * hc[live].max())              # cheap pre-filter
    if not cand.any():
        return nid, node_pillar, node_z, 0
    near = np.zeros(nn, bool)
    near[1:] |= cand
    near[:-1] |= cand
    flat = nid.reshape(nid.shape[0], -1)
    sel = near[flat] & live[:, None]
    rows, _ = np.nonzero(sel)
    h = np.full(nn, np.inf)
    np.minimum.at(h, flat[sel], hc[rows])
    link = cand & (gap < snap * np.minimum(h[1:], h[:-1]))
    if not link.any():
        return nid, node_pillar, node_z, 0
    start = np.ones(nn, bool)
    start[1:] = ~link
    cl = np.cumsum(start) - 1
    # clusters holding two nodes of one column are not merged
    multi = np.bincount(cl)[cl] > 1
    ent = multi[flat]
    e_rows, _ = np.nonzero(ent)
    ncol = int(column.max()) + 1
    key = np.unique(flat[ent].astype(np.int64) * ncol + column[e_rows])   # (node, column) used
    per = np.unique(cl[key // ncol] * ncol + key % ncol, return_counts=True)
    bad = np.zeros(int(cl[-1]) + 1, bool)
    bad[per[0][per[1] > 1] // ncol] = True
    start |= bad[cl]
    w = np.where(np.isfinite(h), 1.0 / np.where(np.isfinite(h), h, 1.0), 0.0)   # 1/h; 0: only collapsed cells

    def merged(start):
        """Cluster of every node, their count, sizes and depths (1/h-weighted mean)."""
        cl = np.cumsum(start) - 1
        n_new = int(cl[-1]) + 1
        size = np.bincount(cl, minlength=n_new)
        wsum = np.bincount(cl, weights=w, minlength=n_new)
        z_mean = np.bincount(cl, weights=node_z, minlength=n_new) / size
        z_new = np.where(wsum > 0, np.bincount(cl, weights=w * node_z, minlength=n_new) / np.where(wsum > 0, wsum, 1),
                         z_mean)
        z_new[size == 1] = node_z[start][size == 1]          # exact for unmerged nodes
        return cl, n_new, size, z_new

    cl, n_new, size, z_new = merged(start)
    if volume is None or n_new == nn:
        return cl[nid], node_pillar[start], z_new, nn - n_new
    # 1. each merge alone: the cells with a corner in it, only its nodes moved
    moved = size[cl] > 1
    rows, corner = np.nonzero(moved[flat])
    key = np.unique(rows.astype(np.int64) * n_new + cl[flat[rows, corner]])
    pc, pg = key // n_new, key % n_new                        # (cell, merge) pairs
    z0 = node_z[nid[pc]]
    z1 = np.where(cl[nid[pc]] == pg[:, None, None, None], z_new[pg][:, None, None, None], z0)
    v0 = volume(pc, z0)
    change = np.abs(volume(pc, z1) - v0) / np.maximum(np.abs(v0), np.finfo(float).tiny)
    worst = np.zeros(n_new)
    np.maximum.at(worst, pg, change)
    start |= moved & (worst > max_volume_change)[cl]
    worst_node = np.where(moved, worst[cl], -1.0)             # (nn,) ranks the merges to undo below
    # 2. all merges together: undo the worst merge at each cell beyond the bound, and repeat
    for _ in range(_ROUNDS):
        cl, n_new, size, z_new = merged(start)
        if n_new == nn:
            break
        moved = size[cl] > 1
        cells = np.flatnonzero(moved[flat].any(axis=1))
        v0 = volume(cells, node_z[nid[cells]])
        over = np.abs(volume(cells, z_new[cl[nid[cells]]]) - v0) > max_volume_change * np.abs(v0)
        if not over.any():
            break
        f = flat[cells[over]]
        pick = f[np.arange(f.shape[0]), np.argmax(np.where(moved[f], worst_node[f], -np.inf), axis=1)]
        start |= np.isin(cl, cl[pick]) & moved
    else:   # pragma: no cover - every round undoes a merge; this many rounds never happened
        start[:] = True
        cl, n_new, size, z_new = merged(start)
    return cl[nid], node_pillar[start], z_new, nn - n_new
