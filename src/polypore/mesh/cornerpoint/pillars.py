"""Pillars: the straight lines through the COORD points, and positions on them."""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError
from .reader import CornerPointGrid


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


def on_pillar(top, bot, p, z):
    """(k, 2) x, y of the points at depth z on pillars p (straight lines top–bottom)."""
    zt, zb = top[p, 2], bot[p, 2]
    dz = zb - zt
    flat = np.abs(dz) <= 1e-12 * np.maximum(1.0, np.abs(zt))
    t = np.where(flat, 0.0, (z - zt) / np.where(flat, 1.0, dz))
    return top[p, :2] + t[:, None] * (bot[p, :2] - top[p, :2])


def right_handed(top, bot, nx, ny) -> bool:
    """True if e_i × e_j points up (towards smaller depth) on average over the columns."""
    xy = 0.5 * (top[:, :2] + bot[:, :2])
    P = xy.reshape(nx + 1, ny + 1, 2)
    a, b, c, d = P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]
    area2 = ((c[..., 0] - a[..., 0]) * (d[..., 1] - b[..., 1]) - (c[..., 1] - a[..., 1]) * (d[..., 0] - b[..., 0]))
    return bool(area2.sum() > 0)
