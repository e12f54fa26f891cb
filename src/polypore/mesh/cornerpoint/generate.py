"""Built-in faulted corner-point grids, and a GRDECL writer.

:func:`generate_grid` builds a :class:`CornerPointGrid` (so that it goes through the same
processor as a file): a box of nx × ny × nz columns and layers, layers sloping with a dip
along x, vertical faults along pillar lines with given throws (tapering to zero where a
fault ends inside the grid), optional pinched-out layers, inactive cells, tilted (non-
parallel) pillars and left-handed ordering. Corner depths are a sum of a function of the
pillar's i and a function of its j in every column, and pillars are vertical unless tilted,
so every cell is a hexahedron with planar faces (wedge where pinched): its volume is
known exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core.errors import InputError
from .reader import CornerPointGrid


@dataclass(frozen=True)
class FaultSpec:
    """A vertical fault on a line of pillars.

    Attributes
    ----------
    axis : "i" or "j"
        ``"i"``: the pillar line of constant i = ``index`` (between columns index−1 and
        index, the fault strikes along y); ``"j"``: constant j.
    index : int
        Pillar line, 1 ≤ index ≤ n−1 (n = nx for axis i, ny for axis j).
    throw : float, m
        Depth offset of the high-index side (positive: it goes down).
    start, stop : int, optional
        Extent along the line in pillar indices (default the whole line). Where the fault
        ends inside the grid its throw tapers linearly to zero over ``taper`` columns.
    taper : int
    name : str
    """

    axis: str
    index: int
    throw: float
    start: int | None = None
    stop: int | None = None
    taper: int = 2
    name: str = ""


def _throw_profile(f: FaultSpec, n_along: int) -> tuple[np.ndarray, int, int]:
    """Throw at every pillar along the fault (n_along + 1 values) and the column range."""
    a = 0 if f.start is None else int(f.start)
    b = n_along if f.stop is None else int(f.stop)
    if not (0 <= a < b <= n_along):
        raise InputError(f"faults.{f.name}", f"start {f.start}, stop {f.stop} must satisfy 0 ≤ start < stop ≤ {n_along}")
    p = np.arange(n_along + 1, dtype=float)
    w = max(int(f.taper), 1)
    ramp = np.ones_like(p)
    if a > 0:
        ramp = np.minimum(ramp, (p - a) / w)
    if b < n_along:
        ramp = np.minimum(ramp, (b - p) / w)
    return f.throw * np.clip(ramp, 0.0, 1.0), a, b


def generate_grid(nx: int, ny: int, nz: int, extent=(1000.0, 1000.0, 100.0), *, top: float = 1000.0,
                  dip: float = 0.0, faults=(), pinchout=(), pinch_range=(0.25, 0.5), inactive=0.0,
                  seed: int = 0, left_handed: bool = False, pillar_tilt: float = 0.0,
                  pillar_angle: float | None = None, mapaxes=None, properties: bool = True,
                  layer_permeability=None) -> CornerPointGrid:
    """A faulted corner-point grid.

    Parameters
    ----------
    nx, ny, nz : int
        Columns along x, y and layers.
    extent : (Lx, Ly, H), m
        Horizontal size and layer stack thickness (layers H/nz thick where not pinched).
    top : float, m
        Depth of the top of the stack at x = 0.
    dip : float, degrees
        Layers dip along +x (depth increases by x·tan(dip)).
    faults : sequence of FaultSpec
    pinchout : sequence of int
        Layers that thin to zero towards x = 0: zero thickness for x ≤ pinch_range[0]·Lx,
        full for x ≥ pinch_range[1]·Lx, linear in between (collapsed cells, then wedges).
    inactive : float or (nx, ny, nz) bool array
        Fraction of randomly inactive cells (seeded) or the inactive cells.
    left_handed : bool
        Number the columns with j decreasing along y (a left-handed grid; FAULTS mirrored).
    pillar_tilt : float
        Pillars fan out: the bottom of the pillar at x is shifted by pillar_tilt·(x − Lx/2)
        along x (non-parallel pillars, non-planar faces).
    layer_permeability : sequence of float, mD, optional
        PERMX = PERMY of the layers from the top, repeated when nz is larger; PERMZ a tenth
        (default 100 mD everywhere).
    pillar_angle : float, degrees, optional
        Instead of ``pillar_tilt``: the angle from vertical of the outermost pillars (x = 0
        and x = Lx), 0 ≤ pillar_angle < 90. Every pillar runs from 1 m above the shallowest
        corner to 1 m below the deepest, over the length L = zmax − zmin + 2 m, so
        ``pillar_tilt = tan(pillar_angle) · L / (Lx/2)``; the pillar at x is then inclined by
        atan(tan(pillar_angle) · |x − Lx/2| / (Lx/2)) in the x-z plane (the ones at x = Lx/2
        vertical), fanning out downwards (:func:`pillar_angles` measures them).
    mapaxes : (3, 2) array, optional
    properties : bool
        Add PORO (0.2), NTG (1), PERMX = PERMY (100 mD), PERMZ (10 mD), FIPNUM (layer + 1).

    Returns
    -------
    CornerPointGrid
        With a FAULTS record per fault (its columns where it has throw, all layers).
    """
    nx, ny, nz = int(nx), int(ny), int(nz)
    if min(nx, ny, nz) < 1:
        raise InputError("generate", f"nx, ny, nz must be positive, got {(nx, ny, nz)}")
    Lx, Ly, H = (float(v) for v in extent)
    xp = np.linspace(0.0, Lx, nx + 1)
    yp = np.linspace(0.0, Ly, ny + 1)
    # layer thickness at every pillar x (pinched layers thin towards x = 0)
    th = np.full((nz, nx + 1), H / nz)
    x0, x1 = (float(pinch_range[0]) * Lx, float(pinch_range[1]) * Lx)
    for k in pinchout:
        th[int(k)] *= np.clip((xp - x0) / max(x1 - x0, 1e-300), 0.0, 1.0)
    horizon = top + np.tan(np.radians(dip)) * xp[None, :] + np.concatenate([np.zeros((1, nx + 1)), np.cumsum(th, 0)])
    # corner depths (2nx, 2ny, 2nz): column (ci, cj), corner (di, dj), layer k, top/bottom dk
    pi = (np.arange(2 * nx) + 1) // 2                     # pillar i of corner index 2ci + di
    pj = (np.arange(2 * ny) + 1) // 2
    colI = np.arange(2 * nx) // 2
    colJ = np.arange(2 * ny) // 2
    kk = np.arange(2 * nz)
    z = horizon[(kk // 2) + (kk % 2)][:, pi].T[:, None, :] * np.ones((1, 2 * ny, 1))   # (2nx, 2ny, 2nz)
    names, records = [], {}
    for n, f in enumerate(faults):
        name = f.name or f"F{n + 1}"
        if name in names:
            raise InputError("faults", f"fault name {name!r} used twice")
        ax = str(f.axis).lower()
        if ax not in ("i", "j"):
            raise InputError(f"faults.{name}", f"axis {f.axis!r} must be 'i' or 'j'")
        n_cross, n_along = (nx, ny) if ax == "i" else (ny, nx)
        if not (1 <= int(f.index) <= n_cross - 1):
            raise InputError(f"faults.{name}", f"index {f.index} must be in 1..{n_cross - 1}")
        T, a, b = _throw_profile(FaultSpec(ax, f.index, f.throw, f.start, f.stop, f.taper, name), n_along)
        if ax == "i":
            z += (np.where(colI[:, None] >= f.index, 1.0, 0.0) * T[pj][None, :])[:, :, None]
            has = (T[:-1] != 0) | (T[1:] != 0)
            cols = np.flatnonzero(has)
            if cols.size:
                records[name] = [(int(f.index), int(f.index), int(cols[0]) + 1, int(cols[-1]) + 1, 1, nz, "X")]
        else:
            z += (np.where(colJ[None, :] >= f.index, 1.0, 0.0) * T[pi][:, None])[:, :, None]
            has = (T[:-1] != 0) | (T[1:] != 0)
            cols = np.flatnonzero(has)
            if cols.size:
                records[name] = [(int(cols[0]) + 1, int(cols[-1]) + 1, int(f.index), int(f.index), 1, nz, "Y")]
        names.append(name)
    zcorn = z
    zmin, zmax = float(zcorn.min()), float(zcorn.max())
    X, Y = np.meshgrid(xp, yp, indexing="ij")
    coord = np.zeros((nx + 1, ny + 1, 6))
    coord[..., 0], coord[..., 1], coord[..., 2] = X, Y, zmin - 1.0
    if pillar_angle is not None:
        if not 0.0 <= float(pillar_angle) < 90.0:
            raise InputError("generate.pillar_angle", f"must be in [0, 90) degrees, got {pillar_angle}")
        pillar_tilt = np.tan(np.radians(float(pillar_angle))) * (zmax - zmin + 2.0) / (0.5 * Lx)
    coord[..., 3] = X + float(pillar_tilt) * (X - 0.5 * Lx)
    coord[..., 4], coord[..., 5] = Y, zmax + 1.0
    if isinstance(inactive, (int, float)):
        rng = np.random.default_rng(seed)
        actnum = rng.random((nx, ny, nz)) >= float(inactive)
    else:
        inactive = np.asarray(inactive, bool)
        if inactive.shape != (nx, ny, nz):
            raise InputError("generate.inactive", f"expected a ({nx}, {ny}, {nz}) array, got {inactive.shape}")
        actnum = ~inactive
    props = {}
    if properties:
        k3 = np.broadcast_to(np.arange(nz)[None, None, :], (nx, ny, nz))
        kh = np.full((nx, ny, nz), 100.0)
        if layer_permeability is not None:
            lp = np.asarray(layer_permeability, float)
            kh = np.broadcast_to(lp[np.arange(nz) % lp.size][None, None, :], (nx, ny, nz)).copy()
        props = {"PORO": np.full((nx, ny, nz), 0.2), "NTG": np.ones((nx, ny, nz)),
                 "PERMX": kh, "PERMY": kh.copy(),
                 "PERMZ": 0.1 * kh, "FIPNUM": (k3 + 1).astype(float)}
    if left_handed:
        coord = coord[:, ::-1].copy()
        zcorn = zcorn[:, ::-1].copy()
        actnum = actnum[:, ::-1].copy()
        props = {k: v[:, ::-1].copy() for k, v in props.items()}
        flipped = {}
        for name, recs in records.items():
            out = []
            for (i1, i2, j1, j2, k1, k2, face) in recs:
                # column j -> ny - 1 - j and the sides along j swap
                face = {"Y": "Y-", "Y-": "Y"}.get(face, face)
                j1, j2 = ny + 1 - j2, ny + 1 - j1
                out.append((i1, i2, j1, j2, k1, k2, face))
            flipped[name] = out
        records = flipped
    return CornerPointGrid((nx, ny, nz), coord, zcorn, actnum, None if mapaxes is None else np.asarray(mapaxes),
                           records, props, "generated")


def pillar_angles(grid: CornerPointGrid) -> np.ndarray:
    """(nx+1, ny+1) angle of every pillar from vertical (degrees), from COORD."""
    c = np.asarray(grid.coord, float)
    d = c[..., 3:] - c[..., :3]
    return np.degrees(np.arctan2(np.hypot(d[..., 0], d[..., 1]), np.abs(d[..., 2])))


# -- writer -------------------------------------------------------------------------------------
def _write_block(f, kw: str, values: np.ndarray, per_line: int, fmt: str):
    f.write(f"{kw}\n")
    v = np.asarray(values).ravel()
    full = v.size // per_line * per_line
    if full:
        np.savetxt(f, v[:full].reshape(-1, per_line), fmt=fmt)
    if v.size > full:
        np.savetxt(f, v[full:][None, :], fmt=fmt)
    f.write("/\n\n")


def _rle(v: np.ndarray) -> str:
    """Run-length text ``n*value`` of an integer array."""
    v = np.asarray(v).ravel()
    starts = np.flatnonzero(np.r_[True, v[1:] != v[:-1]])
    lens = np.diff(np.r_[starts, v.size])
    toks = [f"{n}*{int(x)}" if n > 1 else f"{int(x)}" for n, x in zip(lens.tolist(), v[starts].tolist())]
    lines = [" ".join(toks[i:i + 10]) for i in range(0, len(toks), 10)]
    return "\n".join(lines)


def write_grdecl(grid: CornerPointGrid, path, *, digits: int = 17) -> Path:
    """Write a grid as ASCII GRDECL (SPECGRID, MAPAXES, COORD, ZCORN, ACTNUM, FAULTS, properties).

    ``digits`` significant digits (17: the values read back exactly). ACTNUM and integer
    properties are written with repeat counts.
    """
    path = Path(path)
    nx, ny, nz = grid.dims
    fmt = f"%.{int(digits)}g"
    with open(path, "w") as f:
        f.write(f"-- written by polypore (corner-point grid {nx} x {ny} x {nz})\n\n")
        if grid.mapaxes is not None:
            f.write("MAPAXES\n" + " ".join(fmt % v for v in grid.mapaxes.ravel()) + " /\n\n")
        f.write(f"SPECGRID\n {nx} {ny} {nz} 1 F /\n\n")
        _write_block(f, "COORD", grid.coord.transpose(1, 0, 2).reshape(-1, 6), 6, fmt)
        _write_block(f, "ZCORN", grid.zcorn.T, 8, fmt)
        f.write("ACTNUM\n" + _rle(grid.actnum.T.astype(int)) + "\n/\n\n")
        if grid.faults:
            f.write("FAULTS\n")
            for name, recs in grid.faults.items():
                for r in recs:
                    f.write(f"'{name}' " + " ".join(str(int(x)) for x in r[:6]) + f" '{r[6]}' /\n")
            f.write("/\n\n")
        for name, v in grid.properties.items():
            v = np.asarray(v).T
            if np.all(v == np.round(v)) and np.abs(v).max(initial=0) < 2 ** 31:
                f.write(f"{name}\n" + _rle(v.astype(np.int64)) + "\n/\n\n")
            else:
                _write_block(f, name, v, 6, fmt)
    return path
