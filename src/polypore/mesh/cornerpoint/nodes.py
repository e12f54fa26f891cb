"""Nodes on pillars: corner depths of the active cells -> pillar nodes (pillar, depth).

Three steps, vectorised over the corners of all active cells:

1. **Monotone corner depths.** Down every column of corners, over active cells only, the depths
   are made non-decreasing (running maximum: a cell overlapping the cell above is cut by it).
   An active cell whose bottom is above its top by more than ``ztol`` is refused (inverted).
2. **Merging.** Depths on one pillar closer than ``ztol`` are one node.
3. **Snapping** (:func:`snap_nodes`): nodes of *different* columns on one pillar closer than
   ``snap`` × the thickness of the thinnest cell touching them are merged too (to their mean
   depth). Displaced columns (faults) whose corners nearly coincide otherwise produce sliver
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


def pillar_nodes(grid: CornerPointGrid, ztol: float | None, snap: float) -> PillarNodes:
    """Corner nodes of the active cells, snapped, with the collapsed cells dropped."""
    nat, ci, cj, ck, nid, node_pillar, node_z, ztol = corner_nodes(grid, ztol)
    n_active = nat.size
    nx, ny, _ = grid.dims
    n_snapped, nid0 = 0, None
    if snap > 0:
        nid0 = nid
        nid, node_pillar, node_z, n_snapped = snap_nodes(nid, node_pillar, node_z, ci * ny + cj, snap)
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


def snap_nodes(nid: np.ndarray, node_pillar: np.ndarray, node_z: np.ndarray, column: np.ndarray, snap: float):
    """Merge nearly coincident nodes of different columns on a pillar.

    Consecutive nodes on a pillar are linked when their depths differ by less than ``snap`` ×
    h, h the smallest mean thickness of the cells having a corner at either node; a run of
    linked nodes (a cluster) becomes one node at their mean depth, unless two of its nodes
    belong to one column (a thin cell's top and bottom, a gap): such a cluster is left as it
    is. Cells of zero mean thickness (collapsed) do not count.

    Parameters: ``nid`` (na, 2, 2, 2) node ids of the active cells' corners, ``node_pillar``,
    ``node_z`` (n,) sorted by (pillar, depth), ``column`` (na,) column id of every cell.
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
    cl = np.cumsum(start) - 1
    n_new = int(cl[-1]) + 1
    z_new = np.bincount(cl, weights=node_z, minlength=n_new) / np.bincount(cl, minlength=n_new)
    return cl[nid], node_pillar[start], z_new, nn - n_new
