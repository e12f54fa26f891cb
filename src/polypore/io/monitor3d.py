"""Data behind the monitor plots of 3D poromechanics runs (:mod:`polypore.io.plots3d`).

Everything a figure draws is prepared here, in plain NumPy and without matplotlib, so that it
can be tested against the run's own files (summary.json, fractures.csv, the VTU series):

- :class:`StepRecorder`: per time step, the fraction of each fault's area that slips and that
  is open, each face's slip onset time, the overpressure p − p⁰ at the wells' cells (volume
  mean and maximum), its maximum over the domain and the largest fracture overpressure per
  fault. ``polypore run`` records one row per step (finer than the VTU outputs) and writes the
  series into summary.json (``monitor``).
- :func:`fault_frame`, :func:`project_faces`: a fault's best-fit plane and its faces drawn in
  it (along strike against elevation, or against the up-dip distance for gently dipping faults).
- :func:`raster_pick`, :func:`column_max_map`, :func:`vertical_section`: a cell field drawn as
  an image, by cell bounding boxes (any polyhedral mesh, no slicing); :func:`interest_box` the
  part of the map worth showing; :func:`section_traces`, :func:`outline_segments` the faults in
  a section and in map view.
- :class:`PlotData`, :func:`collect`, :func:`from_run_directory`: what the figures need, from a
  run in memory or from a finished run's folder (older runs included: then the fault series are
  taken at the output times of fractures.csv).

Contact states are coded 0 open, 1 stick, 2 slip (``models.contact``).
"""

from __future__ import annotations

import base64
import csv
import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..models.contact import OPEN, SLIP, STICK

STATE_CODES = {"open": OPEN, "stick": STICK, "slip": SLIP}
STEEP_DIP = 30.0      # degrees: faults at least this steep are drawn against elevation z
AREA_ONSET = 0.01     # "onset by area": the first time this fraction of a fault's area slips


# --------------------------------------------------------------------------- fault series

def area_fractions(fracture, area, state, n_fractures: int) -> tuple[np.ndarray, np.ndarray]:
    """(slip, open) fractions of each fracture's area, (n_fractures,) each.

    fracture : (n_ff,) fracture index of each face; area : (n_ff,) face areas (m²);
    state : (n_ff,) contact states (0 open, 1 stick, 2 slip).
    """
    fracture = np.asarray(fracture, np.int64)
    area = np.asarray(area, float)
    state = np.asarray(state)
    total = np.bincount(fracture, weights=area, minlength=n_fractures)
    slip = np.bincount(fracture, weights=area * (state == SLIP), minlength=n_fractures)
    opn = np.bincount(fracture, weights=area * (state == OPEN), minlength=n_fractures)
    safe = np.where(total > 0, total, 1.0)
    return slip / safe, opn / safe


def final_states(names, fracture, area, state, onset, time) -> dict:
    """Fault -> {time, faces, open, stick, slip, slip_area_fraction, open_area_fraction,
    ever_slipped} of face states (n_ff,) and onset times (n_ff,; NaN: never) at ``time``: the
    one summary of a fault's faces that summary.json reports and the fault maps draw."""
    fracture = np.asarray(fracture, np.int64)
    state = np.asarray(state)
    names = tuple(names)
    if state.size != fracture.size:
        raise ValueError(f"{state.size} face states for {fracture.size} fracture faces")
    sf, of = area_fractions(fracture, area, state, len(names))
    k = len(names)
    count = {c: np.bincount(fracture, weights=(state == code), minlength=k).astype(int)
             for c, code in STATE_CODES.items()}
    ever = np.bincount(fracture, weights=np.isfinite(np.asarray(onset, float)), minlength=k).astype(int)
    faces = np.bincount(fracture, minlength=k)
    return {n: {"time": None if time is None else float(time), "faces": int(faces[i]),
                **{c: int(count[c][i]) for c in STATE_CODES}, "slip_area_fraction": float(sf[i]),
                "open_area_fraction": float(of[i]), "ever_slipped": int(ever[i])} for i, n in enumerate(names)}


def first_time(times, values, threshold: float = 0.0):
    """The first time at which ``values`` exceeds ``threshold`` (> 0 for the default 0, ≥ otherwise),
    or None."""
    v = np.asarray(values, float)
    hit = v > 0.0 if threshold == 0.0 else v >= threshold
    return float(np.asarray(times, float)[np.argmax(hit)]) if hit.any() else None


class StepRecorder:
    """Per-step series of a poromechanics run for its monitor plots and summary.json.

    names : fracture names; fracture : (n_ff,) index of each face; area : (n_ff,) m²;
    wells : {name: cells} (may be empty); cell_volume : (n_cells,) m³.
    """

    def __init__(self, names, fracture, area, wells: dict, cell_volume):
        self.names = tuple(names)
        self.fracture = np.asarray(fracture, np.int64)
        self.area = np.asarray(area, float)
        self.wells = {k: np.asarray(c, np.int64) for k, c in wells.items()}
        self.volume = np.asarray(cell_volume, float)
        self.times: list[float] = []
        self.slip_fraction = {n: [] for n in self.names}
        self.open_fraction = {n: [] for n in self.names}
        self.max_fracture_overpressure = {n: [] for n in self.names}
        self.well_mean = {k: [] for k in self.wells}
        self.well_max = {k: [] for k in self.wells}
        self.max_overpressure: list[float] = []
        self.peak_cell: list[int] = []
        self.onset = np.full(self.fracture.size, np.nan)    # per face: first time in the slip state
        self.state = np.zeros(0, np.int8)                   # the face states of the last recorded time
        self._pf0 = None

    def add(self, t: float, state, overpressure, p_f=None) -> None:
        """Record time ``t``: face states (n_ff,), cell overpressure p − p⁰ (n_cells,) and the
        fracture pressure p_f (n_ff,; its first value is the reference of the fracture overpressure)."""
        state = np.asarray(state)
        self.times.append(float(t))
        sf, of = area_fractions(self.fracture, self.area, state, len(self.names))
        if p_f is not None:
            p_f = np.asarray(p_f, float)
            if self._pf0 is None:
                self._pf0 = p_f.copy()
            dpf = p_f - self._pf0
        for i, n in enumerate(self.names):
            self.slip_fraction[n].append(float(sf[i]))
            self.open_fraction[n].append(float(of[i]))
            sel = self.fracture == i
            if p_f is not None and sel.any():
                self.max_fracture_overpressure[n].append(float(dpf[sel].max()))
        new = (state == SLIP) & np.isnan(self.onset)
        self.onset[new] = t
        # kept for the fault maps and final_states: the very states of the series' last value
        self.state = state.copy()
        op = np.asarray(overpressure, float)
        for k, cells in self.wells.items():
            v = self.volume[cells]
            self.well_mean[k].append(float((op[cells] * v).sum() / v.sum()))
            self.well_max[k].append(float(op[cells].max()))
        i = int(np.argmax(op)) if op.size else 0
        self.peak_cell.append(i)
        self.max_overpressure.append(float(op[i]) if op.size else 0.0)

    def onsets(self) -> dict:
        """Fault -> {"first_slip": first recorded time with a slipping face (s) or None,
        "area_1pct": first time with AREA_ONSET of its area slipping or None}."""
        return {n: {"first_slip": first_time(self.times, self.slip_fraction[n]),
                    "area_1pct": first_time(self.times, self.slip_fraction[n], AREA_ONSET)} for n in self.names}

    def final_states(self) -> dict:
        """Fault -> the face counts at the last recorded time: time (s), faces, open, stick, slip,
        slip_area_fraction and open_area_fraction (the series' last values) and ever_slipped
        (faces with an onset time): what the fault maps draw."""
        return final_states(self.names, self.fracture, self.area, self.state, self.onset,
                            self.times[-1] if self.times else None)

    def summary(self, cell_centroid=None) -> dict:
        """The series for summary.json's ``monitor`` (time = the recorded times)."""
        out = {"slip_area_fraction": self.slip_fraction, "open_area_fraction": self.open_fraction,
               "final_fault_states": self.final_states(),
               "max_fracture_overpressure": self.max_fracture_overpressure, "fault_onset": self.onsets(),
               "max_overpressure": self.max_overpressure,
               "wells": {k: {"cells": int(c.size), "mean_overpressure": self.well_mean[k],
                             "max_overpressure": self.well_max[k]} for k, c in self.wells.items()}}
        if cell_centroid is not None and self.peak_cell:
            out["max_overpressure_at"] = np.round(np.asarray(cell_centroid)[self.peak_cell[-1]], 3).tolist()
        return out


# --------------------------------------------------------------------------- fault geometry

@dataclass
class FaultFrame:
    """A fault's best-fit plane: origin (area-weighted centre), unit normal, strike (horizontal,
    in the plane) and up-dip directions, dip (degrees) and the vertical coordinate used to draw it:
    "z" (elevation, faults at least STEEP_DIP steep) or "updip" (distance up the plane)."""

    origin: np.ndarray
    normal: np.ndarray
    strike: np.ndarray
    updip: np.ndarray
    dip: float
    vertical: str

    def coords(self, x) -> np.ndarray:
        """(n, 2) drawing coordinates of points (n, 3): along strike from the origin, and z or up dip."""
        x = np.asarray(x, float)
        d = x - self.origin
        v = x[:, 2] if self.vertical == "z" else d @ self.updip
        return np.column_stack([d @ self.strike, v])


def fault_frame(normals, areas, centroids) -> FaultFrame:
    """Best-fit plane of faces with unit normals (n, 3), areas (n,) and centroids (n, 3).

    The normal is the principal axis of Σ A n nᵀ (independent of the faces' normal signs, and
    robust for warped faults); strike = e_z × n (x if the plane is horizontal), signed so that
    its largest component is positive; up dip = n × strike, signed so that it rises.
    """
    n = np.asarray(normals, float)
    A = np.asarray(areas, float)
    T = np.einsum("f,fi,fj->ij", A, n, n)
    w, V = np.linalg.eigh(T)
    nrm = V[:, -1]
    h = math.hypot(nrm[0], nrm[1])
    strike = np.array([1.0, 0.0, 0.0]) if h < 1e-9 else np.array([-nrm[1], nrm[0], 0.0]) / h
    if strike[np.argmax(np.abs(strike))] < 0:
        strike = -strike
    up = np.cross(nrm, strike)
    if up[2] < 0 or (abs(up[2]) < 1e-12 and up[np.argmax(np.abs(up))] < 0):
        up = -up
    dip = float(np.degrees(np.arccos(min(1.0, abs(nrm[2])))))
    origin = (np.asarray(centroids, float) * A[:, None]).sum(axis=0) / max(A.sum(), 1e-300)
    return FaultFrame(origin, nrm, strike, up, dip, "z" if dip >= STEEP_DIP else "updip")


def polygon_area(poly2d) -> float:
    """Shoelace area of a (k, 2) polygon."""
    x, y = poly2d[:, 0], poly2d[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def project_faces(frame: FaultFrame, points, connectivity, offsets, faces) -> list[np.ndarray]:
    """The polygons of the fault faces ``faces`` (indices into the offsets) in the frame's
    drawing coordinates: a list of (k, 2) arrays."""
    uv = frame.coords(np.asarray(points, float))
    conn = np.asarray(connectivity, np.int64)
    ends = np.asarray(offsets, np.int64)
    starts = np.concatenate([[0], ends[:-1]])
    return [uv[conn[starts[f]:ends[f]]] for f in np.asarray(faces, np.int64)]


def vertical_exaggeration(width: float, height: float, max_ratio: float = 3.0) -> float:
    """A round factor (1, 2, 5, 10, 20, ...) by which to stretch the vertical axis so that a
    panel of the given data extents is at most ``max_ratio`` times wider than high."""
    if height <= 0 or width <= 0 or width / height <= max_ratio:
        return 1.0
    need = width / (max_ratio * height)
    for k in (2, 5, 10, 20, 50, 100, 200, 500, 1000):
        if k >= need:
            return float(k)
    return 1000.0


# --------------------------------------------------------------------------- cell fields as images

def cell_boxes(nodes, cell_nodes_values, cell_nodes_offsets) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): per cell the bounding box (n_cells, 3) of its nodes (offsets: n_cells + 1 starts)."""
    x = np.asarray(nodes, float)[np.asarray(cell_nodes_values, np.int64)]
    starts = np.asarray(cell_nodes_offsets, np.int64)[:-1]
    return np.minimum.reduceat(x, starts, axis=0), np.maximum.reduceat(x, starts, axis=0)


@dataclass
class Grid2D:
    """Pixel centres x0 + (i + ½) dx, i < nx, and y0 + (j + ½) dy, j < ny."""

    x0: float
    dx: float
    nx: int
    y0: float
    dy: float
    ny: int

    @property
    def extent(self) -> tuple[float, float, float, float]:
        return self.x0, self.x0 + self.nx * self.dx, self.y0, self.y0 + self.ny * self.dy

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x0 + (np.arange(self.nx) + 0.5) * self.dx, self.y0 + (np.arange(self.ny) + 0.5) * self.dy


def make_grid(lo, hi, cell_size: float, max_pixels: int = 400, aspect: float = 1.0) -> Grid2D:
    """A pixel grid over the box lo..hi (2,): at most ``max_pixels`` along the wider side (after
    stretching y by ``aspect``), pixels no smaller than a quarter of ``cell_size`` (in x)."""
    w, h = float(hi[0] - lo[0]), float(hi[1] - lo[1]) * aspect
    dx = max(max(w, h) / max_pixels, cell_size / 4.0, 1e-300)
    dy = dx / aspect
    nx, ny = max(1, int(math.ceil(w / dx))), max(1, int(math.ceil(float(hi[1] - lo[1]) / dy)))
    return Grid2D(float(lo[0]), dx, nx, float(lo[1]), dy, ny)


def raster_pick(lo2, hi2, priority, grid: Grid2D):
    """Per pixel of ``grid`` the cell whose 2D box [lo2, hi2] (n, 2) contains the pixel centre and
    whose priority is smallest; -1 where no box contains it.

    priority : (n,) per cell, or a function (cell, px, py) -> per incidence (arrays).
    Returns (ny, nx) int64.
    """
    lo2, hi2 = np.asarray(lo2, float), np.asarray(hi2, float)
    i0 = np.ceil((lo2[:, 0] - grid.x0) / grid.dx - 0.5).astype(np.int64).clip(0, grid.nx)
    i1 = np.floor((hi2[:, 0] - grid.x0) / grid.dx - 0.5).astype(np.int64).clip(-1, grid.nx - 1)
    j0 = np.ceil((lo2[:, 1] - grid.y0) / grid.dy - 0.5).astype(np.int64).clip(0, grid.ny)
    j1 = np.floor((hi2[:, 1] - grid.y0) / grid.dy - 0.5).astype(np.int64).clip(-1, grid.ny - 1)
    ni, nj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    cnt = ni * nj
    pick = np.full(grid.nx * grid.ny, -1, np.int64)
    if cnt.sum() == 0:
        return pick.reshape(grid.ny, grid.nx)
    cell = np.repeat(np.arange(cnt.size), cnt)
    local = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    ii = i0[cell] + local % ni[cell]
    jj = j0[cell] + local // ni[cell]
    pix = jj * grid.nx + ii
    if callable(priority):
        prio = priority(cell, grid.x0 + (ii + 0.5) * grid.dx, grid.y0 + (jj + 0.5) * grid.dy)
    else:
        prio = np.asarray(priority, float)[cell]
    order = np.lexsort((prio, pix))
    first = np.unique(pix[order], return_index=True)[1]
    chosen = order[first]
    pick[pix[chosen]] = cell[chosen]
    return pick.reshape(grid.ny, grid.nx)


def image_of(pick, values) -> np.ndarray:
    """(ny, nx) values of the picked cells, NaN where no cell was picked."""
    v = np.asarray(values, float)
    out = np.full(pick.shape, np.nan)
    m = pick >= 0
    out[m] = v[pick[m]]
    return out


def typical_size(lo, hi, axes=(0, 1)) -> float:
    """Median extent of the cells' boxes along the given axes (the smallest of them)."""
    ext = np.asarray(hi, float) - np.asarray(lo, float)
    return float(min(np.median(ext[:, a]) for a in axes))


def column_max_map(lo, hi, values, max_pixels: int = 400, window=None):
    """Map view: per pixel (x, y) the largest value over the cells whose box covers it (the
    maximum over depth), over the cells' extent or ``window`` = (lo (2,), hi (2,)).
    Returns (image (ny, nx), Grid2D)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    if window is None:
        window = (lo[:, :2].min(axis=0), hi[:, :2].max(axis=0))
    g = make_grid(window[0], window[1], typical_size(lo, hi), max_pixels)
    pick = raster_pick(lo[:, :2], hi[:, :2], -np.asarray(values, float), g)
    return image_of(pick, values), g


def vertical_section(lo, hi, centroid, values, axis: int, at: float, aspect: float = 1.0,
                     max_pixels: int = 400, window=None):
    """Vertical section at coordinate ``axis`` (0: x, 1: y) = ``at``: image over (the other
    horizontal coordinate h, z), each pixel from the cell whose box contains the point and whose
    centroid is nearest in the cell's own box units; ``aspect`` the vertical exaggeration;
    ``window`` = (h_min, h_max) limits the section's horizontal extent.
    Returns (image (nz, nh), Grid2D, h) with h the horizontal axis (1 - axis)."""
    lo, hi, c = np.asarray(lo, float), np.asarray(hi, float), np.asarray(centroid, float)
    h = 1 - axis
    keep = (lo[:, axis] <= at) & (hi[:, axis] >= at)
    if window is not None:
        keep &= (hi[:, h] >= window[0]) & (lo[:, h] <= window[1])
    cut = np.flatnonzero(keep)
    box_lo, box_hi = lo[cut][:, [h, 2]], hi[cut][:, [h, 2]]
    if cut.size == 0:
        g = make_grid(lo[:, [h, 2]].min(axis=0), hi[:, [h, 2]].max(axis=0), 1.0, max_pixels, aspect)
        return np.full((g.ny, g.nx), np.nan), g, h
    g_lo, g_hi = box_lo.min(axis=0), box_hi.max(axis=0)
    if window is not None:
        g_lo[0], g_hi[0] = max(g_lo[0], window[0]), min(g_hi[0], window[1])
    g = make_grid(g_lo, g_hi, typical_size(lo, hi, (h,)), max_pixels, aspect)
    size = np.maximum(hi[cut] - lo[cut], 1e-300)

    def prio(cell, px, pz):
        k = cut[cell]
        return (((c[k, h] - px) / size[cell, h]) ** 2 + ((c[k, axis] - at) / size[cell, axis]) ** 2
                + ((c[k, 2] - pz) / size[cell, 2]) ** 2)

    pick = raster_pick(box_lo, box_hi, prio, g)
    vals = np.asarray(values, float)[cut]
    return image_of(pick, vals), g, h


def interest_box(lo, hi, values, points=(), frac: float = 0.02, pad: float = 0.12):
    """The (x, y) box worth showing in a map: the boxes of the cells where |values| is at least
    ``frac`` of its largest, and the given points (k, ≥2) (faults, wells), padded by ``pad`` of
    its size and clipped to the cells' extent. Returns (lo (2,), hi (2,))."""
    lo, hi = np.asarray(lo, float)[:, :2], np.asarray(hi, float)[:, :2]
    v = np.abs(np.asarray(values, float))
    big = v >= frac * v.max() if v.size and v.max() > 0 else np.zeros(v.size, bool)
    parts_lo, parts_hi = [lo[big]], [hi[big]]
    p = np.asarray(points, float).reshape(-1, np.asarray(points).shape[-1] if len(points) else 2)[:, :2]
    parts_lo.append(p)
    parts_hi.append(p)
    a, b = np.concatenate(parts_lo), np.concatenate(parts_hi)
    all_lo, all_hi = lo.min(axis=0), hi.max(axis=0)
    if a.size == 0:
        return all_lo, all_hi
    w_lo, w_hi = a.min(axis=0), b.max(axis=0)
    margin = pad * np.maximum(w_hi - w_lo, 0.05 * (all_hi - all_lo))
    return np.maximum(w_lo - margin, all_lo), np.minimum(w_hi + margin, all_hi)


def section_traces(points, connectivity, offsets, axis: int, at: float) -> np.ndarray:
    """Segments (m, 2, 2) where polygons (VTK-style, end offsets) cross the plane coordinate
    ``axis`` = ``at``, in (the other horizontal coordinate, z); polygons that cross it at other
    than two points are left out."""
    P = np.asarray(points, float)
    e, face = polygon_edges(connectivity, offsets)
    n_poly = np.asarray(offsets).size
    a, b = P[e[:, 0]], P[e[:, 1]]
    sa, sb = a[:, axis] - at, b[:, axis] - at
    cross = (sa < 0) != (sb < 0)
    t = np.where(cross, sa / np.where(cross, sa - sb, 1.0), 0.0)
    x = a + t[:, None] * (b - a)
    h = 1 - axis
    f = face[cross]
    pts = x[cross][:, [h, 2]]
    n = np.bincount(f, minlength=n_poly)
    two = n[f] == 2
    pts = pts[two]
    return pts.reshape(-1, 2, 2)


def polygon_edges(connectivity, offsets) -> tuple[np.ndarray, np.ndarray]:
    """(edges (nnz, 2) point ids, polygon of each edge): every polygon's edges, closing edge included."""
    conn = np.asarray(connectivity, np.int64)
    ends = np.asarray(offsets, np.int64)
    counts = np.diff(np.concatenate([[0], ends]))
    starts = ends - counts
    idx = np.arange(conn.size)
    nxt = np.where(idx + 1 == np.repeat(ends, counts), np.repeat(starts, counts), idx + 1)
    return np.column_stack([conn, conn[nxt]]), np.repeat(np.arange(ends.size), counts)


def outline_segments(points, connectivity, offsets, fracture) -> np.ndarray:
    """Segments (m, 2, 3) of each fracture's outline: the polygon edges that belong to one face
    of that fracture only."""
    e, poly = polygon_edges(connectivity, offsets)
    key = np.column_stack([np.asarray(fracture, np.int64)[poly], np.sort(e, axis=1)])
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = cnt[inv.ravel()] == 1
    return np.asarray(points, float)[e[once]]


# --------------------------------------------------------------------------- what the figures need

@dataclass
class PlotData:
    """Inputs of the 3D monitor figures (SI units; times in s).

    fault_times : (n_t,) times of the fault series (every step in a run); slip_fraction,
    open_fraction : fault -> (n_t,) area fractions; max_slip : fault -> (n_t,) m, the largest slip
    since the start; fault faces: fracture (n_ff,), area, normal (n_ff, 3), centroid (n_ff, 3),
    polygons (points, connectivity, offsets); slip (n_ff,) since the start and state (n_ff,) at
    t_final; onset (n_ff,) time each face first slipped (NaN: never).
    pressure_times : (n_p,); well_mean, well_max : well -> (n_p,) overpressure (Pa); points :
    monitor point -> (n_p,); max_fracture_overpressure : fault -> (n_p,); max_overpressure (n_p,);
    well_cells_xyz : well -> (k, 3) centroids of its cells; point_xyz : point -> (3,);
    cell boxes lo, hi (n_cells, 3), centroid, and overpressure (n_cells,) at t_final.
    """

    case: str
    t_end: float
    names: tuple
    fault_times: np.ndarray
    slip_fraction: dict
    open_fraction: dict
    max_slip: dict
    fracture: np.ndarray
    area: np.ndarray
    normal: np.ndarray
    centroid: np.ndarray
    polygons: tuple
    slip: np.ndarray
    state: np.ndarray
    onset: np.ndarray
    t_final: float
    pressure_times: np.ndarray
    well_mean: dict
    well_max: dict
    points: dict
    max_fracture_overpressure: dict
    max_overpressure: np.ndarray
    well_cells_xyz: dict
    point_xyz: dict
    lo: np.ndarray
    hi: np.ndarray
    cell_centroid: np.ndarray
    overpressure: np.ndarray
    notes: list = field(default_factory=list)
    delta_cfs: np.ndarray | None = None         # (n_ff,) ΔCFS since the start at t_final, Pa (older runs: None)
    slip_tendency: np.ndarray | None = None     # (n_ff,) τ/σ_n′ at t_final (NaN: open)

    def frames(self) -> dict:
        """Fault name -> FaultFrame of its faces (faults with faces only)."""
        out = {}
        for i, n in enumerate(self.names):
            sel = self.fracture == i
            if sel.any():
                out[n] = fault_frame(self.normal[sel], self.area[sel], self.centroid[sel])
        return out

    def first_slip(self) -> dict:
        return {n: first_time(self.fault_times, self.slip_fraction[n]) for n in self.names}

    def final_states(self) -> dict:
        """:func:`final_states` of the faces at t_final (what the fault maps draw)."""
        return final_states(self.names, self.fracture, self.area, self.state, self.onset, self.t_final)

    def series_at_final(self) -> dict:
        """Fault -> (slip, open) area fractions of the series (summary.json's) at t_final; None
        for a fault when the series has no value at t_final."""
        t = np.asarray(self.fault_times, float)
        k = int(np.argmin(np.abs(t - self.t_final))) if t.size else -1
        ok = t.size and abs(t[k] - self.t_final) <= 1e-9 * max(abs(self.t_final), 1.0)
        return {n: (float(self.slip_fraction[n][k]), float(self.open_fraction[n][k])) if ok else None
                for n in self.names}

    def area_onset(self) -> dict:
        return {n: first_time(self.fault_times, self.slip_fraction[n], AREA_ONSET) for n in self.names}


def collect(case_name, t_end, fm, face_area, recorder: StepRecorder, monitor: dict, last: dict, points: dict,
            overpressure) -> PlotData:
    """PlotData of a run in memory: ``fm`` the FracturedMesh, ``face_area`` (n_ff,), the run's
    StepRecorder, its ``monitor`` dict (time, points, fault_slip), the ``last`` state's time and
    slip since the start, monitor points {name: cell} and the final overpressure (n_cells,).

    The face states and onsets are the recorder's, the arrays behind summary.json's series and
    ``final_fault_states``, at the recorder's last time (which must be ``last["time"]``)."""
    from .vtu import fracture_cells

    mesh, net = fm.mesh, fm.network
    g = mesh.geometry
    fc = fracture_cells(fm)
    lo, hi = cell_boxes(mesh.nodes, mesh.cell_nodes.values, mesh.cell_nodes.offsets)
    t = np.asarray(recorder.times)
    if not t.size or abs(t[-1] - float(last["time"])) > 1e-9 * max(abs(t[-1]), 1.0):
        raise ValueError(f"the last recorded time {t[-1] if t.size else None} is not the final time {last['time']}")
    return PlotData(
        case=case_name, t_end=float(t_end), names=tuple(net.names), fault_times=t,
        slip_fraction={k: np.asarray(v) for k, v in recorder.slip_fraction.items()},
        open_fraction={k: np.asarray(v) for k, v in recorder.open_fraction.items()},
        max_slip={k: np.asarray(v) for k, v in monitor["fault_slip"].items()},
        fracture=np.asarray(net.fracture), area=np.asarray(face_area, float), normal=np.asarray(net.normal, float),
        centroid=np.asarray(g.face_centroid[net.faces], float),
        polygons=(fc["points"], fc["connectivity"], fc["offsets"]),
        slip=np.asarray(last["slip"], float), state=recorder.state.copy(), onset=recorder.onset.copy(),
        t_final=float(t[-1]), pressure_times=t,
        well_mean={k: np.asarray(v) for k, v in recorder.well_mean.items()},
        well_max={k: np.asarray(v) for k, v in recorder.well_max.items()},
        points={k: np.asarray(v) for k, v in monitor["points"].items()},
        max_fracture_overpressure={k: np.asarray(v) for k, v in recorder.max_fracture_overpressure.items()},
        max_overpressure=np.asarray(recorder.max_overpressure),
        well_cells_xyz={k: np.asarray(g.cell_centroid[c]) for k, c in recorder.wells.items()},
        point_xyz={k: np.asarray(g.cell_centroid[c]) for k, c in points.items()},
        lo=lo, hi=hi, cell_centroid=np.asarray(g.cell_centroid), overpressure=np.asarray(overpressure, float),
        delta_cfs=last.get("delta_cfs"), slip_tendency=last.get("slip_tendency"))


# --------------------------------------------------------------------------- a finished run's folder

_VTK_TYPES = {"Float64": np.float64, "Float32": np.float32, "Int32": np.int32, "Int64": np.int64,
              "UInt8": np.uint8, "UInt32": np.uint32, "UInt64": np.uint64, "Int8": np.int8}


def read_vtu(path, names=None) -> dict:
    """Arrays of a VTU file written by :mod:`polypore.io.vtu` (inline base64, UInt64 headers):
    name -> array ((n,) or (n, k)); the geometry is under "Points", "connectivity", "offsets".
    ``names`` limits the arrays decoded (all by default); a missing one is a KeyError."""
    root = ET.parse(path).getroot()
    if root.get("header_type", "UInt32") != "UInt64":
        raise ValueError(f"{path}: only UInt64 headers are read")
    out = {}
    for da in root.iter("DataArray"):
        name = da.get("Name")
        if (names is not None and name not in names) or name in out:
            continue
        if da.get("format") != "binary":
            raise ValueError(f"{path}: array {name!r} is not inline base64")
        raw = base64.b64decode("".join((da.text or "").split()))
        size = int(np.frombuffer(raw[:8], "<u8")[0])
        a = np.frombuffer(raw[8:8 + size], np.dtype(_VTK_TYPES[da.get("type")]).newbyteorder("<"))
        k = int(da.get("NumberOfComponents", "1"))
        out[name] = a.reshape(-1, k) if k > 1 else a.copy()
    missing = set(names or ()) - set(out)
    if missing:
        raise KeyError(f"{path}: no array {sorted(missing)}")
    return out


def read_pvd(path) -> list[tuple[float, str, int]]:
    """(time, file, part) of every data set of a .pvd collection."""
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep")), d.get("file"), int(d.get("part", "0"))) for d in root.iter("DataSet")]


def read_fractures_csv(path) -> dict:
    """fractures.csv -> {"time": (n_out,), "step": (n_out,), "fracture": (n_ff,) names, "area",
    "state" (n_out, n_ff) codes, "jump" (n_out, n_ff, 3), "p_f" (n_out, n_ff)}."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    step = np.array([int(r["step"]) for r in rows])
    steps, first = np.unique(step, return_index=True)
    n_ff = int(np.sum(step == steps[0]))
    k = len(steps)
    col = lambda key: np.array([float(r[key]) if r[key] != "" else np.nan for r in rows]).reshape(k, n_ff)  # noqa: E731
    return {"step": steps, "time": col("time")[:, 0], "fracture": np.array([r["fracture"] for r in rows[:n_ff]]),
            "area": col("area")[0], "state": np.array([STATE_CODES[r["state"]] for r in rows]).reshape(k, n_ff),
            "jump": np.stack([col("jump_x"), col("jump_y"), col("jump_z")], axis=-1), "p_f": col("p_f"),
            "xyz": np.stack([col("x")[0], col("y")[0], col("z")[0]], axis=-1)}


def tangential(v, normal) -> np.ndarray:
    """|v − (v·n) n| per row."""
    vn = np.einsum("...i,...i->...", v, normal)
    return np.linalg.norm(v - vn[..., None] * normal, axis=-1)


def from_run_directory(folder, wells_of=None) -> PlotData:
    """PlotData of a finished run's folder: summary.json, fractures.csv and the VTU files of
    solution.pvd give everything but the wells (the fault polygons and normals from the last
    fractures VTU, the cells' boxes from the last bulk VTU).

    wells_of : optional function (cell node means (n, 3), box lo, box hi) -> ({well: cells}, note
        or None) that finds the wells' cells (it needs the case: :func:`polypore.runs.coupled.replot`
        rebuilds the mesh from case.toml); without it the wells are left out.

    Series that summary.json holds per step (runs of this version) are taken from it; otherwise
    they are computed at the output times from fractures.csv and the bulk VTU files. ``notes``
    says what was approximated."""
    folder = Path(folder)
    summary = json.loads((folder / "summary.json").read_text())
    mon = summary["monitor"]
    notes = []
    fr = read_fractures_csv(folder / "fractures.csv")
    entries = read_pvd(folder / "solution.pvd")
    bulk = [(t, f) for t, f, part in entries if part == 0]
    frac_vtu = [f for t, f, part in entries if part == 1]
    fv = read_vtu(folder / frac_vtu[-1], ["Points", "connectivity", "offsets", "fracture", "normal"])
    try:                                                    # runs of this version: every step's onset
        onset = np.asarray(read_vtu(folder / frac_vtu[-1], ["first_slip"])["first_slip"], float)
    except KeyError:
        onset = None
    try:                                                    # runs since ΔCFS was written
        cfs = read_vtu(folder / frac_vtu[-1], ["delta_cfs", "slip_tendency"])
    except KeyError:
        cfs = {}
    if fv["offsets"].size != fr["area"].size:
        raise ValueError(f"{folder}: {frac_vtu[-1]} has {fv['offsets'].size} faces, fractures.csv "
                         f"{fr['area'].size}")
    names = tuple(dict.fromkeys(fr["fracture"]))
    names_all = tuple(summary["monitor"].get("max_slip", {}) or names)
    names = tuple(n for n in names_all if n in names) + tuple(n for n in names if n not in names_all)
    idx = {n: i for i, n in enumerate(names)}
    fracture = np.array([idx[n] for n in fr["fracture"]], np.int64)
    normal = np.asarray(fv["normal"], float)
    slip_out = tangential(fr["jump"] - fr["jump"][0], normal)           # (n_out, n_ff)
    bv = read_vtu(folder / bulk[-1][1], ["Points", "connectivity", "offsets", "overpressure"])
    starts = np.concatenate([[0], bv["offsets"].astype(np.int64)])
    lo, hi = cell_boxes(bv["Points"], bv["connectivity"], starts)
    counts = np.diff(starts)
    centroid = np.add.reduceat(bv["Points"][bv["connectivity"]], starts[:-1], axis=0) / counts[:, None]
    wells, note = wells_of(centroid, lo, hi) if wells_of is not None else ({}, None)
    if note:
        notes.append(note)
    if "slip_area_fraction" in mon:
        fault_times = pressure_times = np.asarray(mon["time"], float)
        sf = {k: np.asarray(v) for k, v in mon["slip_area_fraction"].items()}
        of = {k: np.asarray(v) for k, v in mon["open_area_fraction"].items()}
        max_slip = {k: np.asarray(v) for k, v in mon["max_slip"].items()}
        mfo = {k: np.asarray(v) for k, v in mon["max_fracture_overpressure"].items()}
        well_mean = {k: np.asarray(w["mean_overpressure"]) for k, w in mon["wells"].items()}
        well_max = {k: np.asarray(w["max_overpressure"]) for k, w in mon["wells"].items()}
        max_op = np.asarray(mon["max_overpressure"])
        if onset is None:
            notes.append("face onset times at the output times of fractures.csv")
    else:
        fault_times = fr["time"]
        fr_frac = [area_fractions(fracture, fr["area"], s, len(names)) for s in fr["state"]]
        sf = {n: np.array([f[0][i] for f in fr_frac]) for i, n in enumerate(names)}
        of = {n: np.array([f[1][i] for f in fr_frac]) for i, n in enumerate(names)}
        max_slip = {n: slip_out[:, fracture == i].max(axis=1) for i, n in enumerate(names)}
        dpf = fr["p_f"] - fr["p_f"][0]
        mfo = {n: dpf[:, fracture == i].max(axis=1) for i, n in enumerate(names)}
        op_out = [read_vtu(folder / f, ["overpressure"])["overpressure"] for _, f in bulk]
        pressure_times = np.array([t for t, _ in bulk])
        vol = np.prod(hi - lo, axis=1)                        # box volumes: weights of the well mean
        well_mean = {k: np.array([(o[c] * vol[c]).sum() / vol[c].sum() for o in op_out]) for k, c in wells.items()}
        well_max = {k: np.array([o[c].max() for o in op_out]) for k, c in wells.items()}
        max_op = np.array([o.max() for o in op_out])
        notes.append("series at the output times (the run predates per-step monitor series)")
    mt = np.asarray(mon["time"], float)
    if mt.size and abs(fr["time"][-1] - mt[-1]) > 1e-9 * max(abs(mt[-1]), 1.0):
        notes.append(f"fractures.csv ends at t = {fr['time'][-1]:g} s, the series at {mt[-1]:g} s")
    pts = {k: np.interp(pressure_times, mt, np.asarray(v, float)) for k, v in mon["overpressure_at_points"].items()}
    d = PlotData(
        case=summary["case"], t_end=float(max(fr["time"][-1], mt[-1] if mt.size else 0.0)), names=names,
        fault_times=np.asarray(fault_times, float), slip_fraction=sf, open_fraction=of, max_slip=max_slip,
        fracture=fracture, area=fr["area"], normal=normal, centroid=fr["xyz"],
        polygons=(np.asarray(fv["Points"], float), fv["connectivity"].astype(np.int64), fv["offsets"].astype(np.int64)),
        slip=slip_out[-1], state=fr["state"][-1],
        onset=_face_onset(fr["time"], fr["state"]) if onset is None else onset,
        t_final=float(fr["time"][-1]), pressure_times=np.asarray(pressure_times, float),
        well_mean=well_mean, well_max=well_max, points=pts, max_fracture_overpressure=mfo,
        max_overpressure=np.asarray(max_op, float),
        well_cells_xyz={k: centroid[c] for k, c in wells.items()},
        point_xyz={k: np.asarray(v, float) for k, v in mon.get("points", {}).items()},
        lo=lo, hi=hi, cell_centroid=centroid, overpressure=np.asarray(bv["overpressure"], float), notes=notes,
        delta_cfs=cfs.get("delta_cfs"), slip_tendency=cfs.get("slip_tendency"))
    reported = mon.get("final_fault_states")
    if reported:
        mine = d.final_states()
        for n, r in reported.items():
            m = mine.get(n)
            if m is None or any(m[c] != r[c] for c in ("faces", "open", "stick", "slip")):
                notes.append(f"fault {n}: the face states of fractures.csv at t = {d.t_final:g} s are not "
                             "summary.json's final_fault_states")
    return d


def _face_onset(times, states) -> np.ndarray:
    """(n_ff,) first time each face is in the slip state (NaN: never) from (n_out, n_ff) states."""
    slipping = np.asarray(states) == SLIP
    any_ = slipping.any(axis=0)
    return np.where(any_, np.asarray(times, float)[np.argmax(slipping, axis=0)], np.nan)
