"""Meshes mirror-symmetric about fractures near their tips or along them (``mesh.mirror``).

Why: next to a crack tip the shear (mode II) part of the displacement is singular. On a
mesh that is not symmetric about the crack line, its discretisation error leaks into the
normal multiplier λ_n of the last faces before each tip, by O(K_II / sqrt(h)) on faces of
length h, so the L2 error of λ_n over the whole crack stays O(1) under refinement
(docs/contact.md, C3). On a mesh symmetric about the crack line with two-sided bubbles the
discrete problem splits exactly into a symmetric part (the closed-crack compression, which
the scheme reproduces) and an antisymmetric part (the slip), which exerts no normal
traction on the crack.

Modes:

* ``"fractures"``: a band around every fracture (straight ones only), ``BAND`` of its
  length beyond each tip and to each side. λ_n is then free of tip error altogether.
* ``"tips"``: a square patch around every tip, aligned with the tip segment, of half-side
  ``TIP`` of that segment's length, shrunk to keep clear of other fractures, interfaces and
  the boundary. Works on any 2D network; the singular region is symmetric and λ_n converges
  at first order over the whole fracture.

Each region is split by the fracture line; gmsh meshes its n^+ half and copies it to the
n^- half by reflection (periodic meshing with a reflection map).

In 3D, ``"fractures"`` mirrors a prism around every planar fracture (:mod:`.mirror3d`);
``"tips"`` is 2D only.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ...core.errors import InputError
from ..fractures import segment_distances
from .mirror3d import MirrorPrism, add_prism_volumes, prisms, reflect_halves, set_mirror_3d

log = logging.getLogger("polypore")

MODES = ("none", "tips", "fractures")
BAND = 0.25  # "fractures": band margin beyond the tips and to each side, fraction of the fracture's length
TIP = 0.1    # "tips": patch half-side, fraction of the tip segment's length
CLEAR = 0.5 / np.sqrt(2.0)  # "tips": patch half-side at most this fraction of the tip's clearance


@dataclass(frozen=True)
class MirrorRegion:
    """One mirrored rectangle: its halves on the n^+ / n^- side of a fracture line.

    Attributes
    ----------
    label : str
        What it surrounds ("fracture 'F1'", "tip of 'F1' at (x, y)") for messages.
    upper, lower : (4, 2) float, m
        Corners of the two halves, counter-clockwise.
    affine : (16,) float
        Row-major 4x4 affine map of the reflection about the fracture line (gmsh's format).
    """

    label: str
    upper: np.ndarray
    lower: np.ndarray
    affine: np.ndarray


def _region(label, centre, t, n, a, w) -> MirrorRegion:
    """Rectangle centre ± a t ± w n, split along t; reflection about the line (centre, t)."""
    up = np.array([centre - a * t, centre + a * t, centre + a * t + w * n, centre - a * t + w * n])
    lo = np.array([centre - a * t - w * n, centre + a * t - w * n, centre + a * t, centre - a * t])
    M = np.eye(2) - 2.0 * np.outer(n, n)
    shift = centre - M @ centre
    affine = np.array([M[0, 0], M[0, 1], 0.0, shift[0], M[1, 0], M[1, 1], 0.0, shift[1],
                       0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    return MirrorRegion(label, up, lo, affine)


def _frame(a, b):
    t = (b - a) / np.linalg.norm(b - a)
    return t, np.array([t[1], -t[0]])


def mirror_regions(mode: str, fractures, lower, upper, interfaces=(), fracture_size: float | None = None
                   ) -> list[MirrorRegion] | list[MirrorPrism]:
    """The regions to mesh mirror-symmetrically for ``mode`` (see the module docstring).

    Parameters
    ----------
    mode : {"none", "tips", "fractures"}
    fractures, interfaces : sequences of FractureSpec (2D polylines / 3D planar polygons)
    lower, upper : (d,) float, m
        The box domain.
    fracture_size : float, m, optional
        Mesh size on the fractures: a 2D tip patch under two cells across is logged; in 3D
        the smallest prism margin and boundary clearance accepted.

    Raises
    ------
    InputError
        ``mesh.mirror``: unknown mode, "tips" on a 3D box, no fracture; for "fractures" also
        a kinked 2D fracture, a region leaving the box, overlapping another region or meeting
        another fracture or an interface.
    """
    if mode not in MODES:
        raise InputError("mirror", f"unknown value {mode!r}; allowed: {', '.join(MODES)}")
    if mode == "none":
        return []
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if lower.size == 3:
        if mode == "tips":
            raise InputError("mirror", "\"tips\" is available for 2D meshes only; in 3D use \"fractures\" "
                             "(a mirrored prism around each planar fracture)")
        return prisms(fractures, lower, upper, interfaces, fracture_size)
    if not fractures:
        raise InputError("mirror", "needs at least one fracture to mirror the mesh about")
    # (owner, segment number within it, name, a, b) for every fracture and interface segment
    segments = [(i, j, s.name, a, b) for i, s in enumerate(list(fractures) + list(interfaces))
                for j, (a, b) in enumerate(zip(np.asarray(s.vertices, float)[:-1], np.asarray(s.vertices, float)[1:]))]
    if mode == "fractures":
        return _bands(fractures, lower, upper, segments)
    return _tips(fractures, lower, upper, segments, fracture_size)


def _bands(fractures, lower, upper, segments):
    regions = []
    for i, s in enumerate(fractures):
        V = np.asarray(s.vertices, float)
        if V.shape[0] != 2:
            raise InputError("mirror", f"fracture {s.name!r} has {V.shape[0] - 1} segments; \"fractures\" "
                             "mirrors bands around straight fractures (two vertices) only; \"tips\" takes any")
        t, n = _frame(V[0], V[1])
        length = float(np.linalg.norm(V[1] - V[0]))
        r = _region(f"fracture {s.name!r}", V.mean(axis=0), t, n, (0.5 + BAND) * length, BAND * length)
        corners = np.vstack([r.upper, r.lower])
        if np.any(corners < lower) or np.any(corners > upper):
            raise InputError("mirror", f"the mirror band around fracture {s.name!r} ({BAND:g} of its length "
                             f"beyond its tips and to each side) leaves the domain {lower.tolist()}–"
                             f"{upper.tolist()}; use mirror = \"tips\" for fractures that end near the boundary")
        quad = np.vstack([r.lower[:2], r.upper[2:]])
        for owner, _, name, a, b in segments:
            if owner != i and _convex_overlap(np.array([a, b]), quad):
                raise InputError("mirror", f"the mirror band around fracture {s.name!r} meets {name!r}; "
                                 "use mirror = \"tips\" for fractures this close")
        for other in regions:
            if _convex_overlap(quad, np.vstack([other.lower[:2], other.upper[2:]])):
                raise InputError("mirror", f"the mirror bands around the {other.label} and the fracture "
                                 f"{s.name!r} overlap; use mirror = \"tips\" for fractures this close")
        regions.append(r)
    return regions


def _tips(fractures, lower, upper, segments, fracture_size):
    regions = []
    tol = 1e-9 * float(np.max(upper - lower))
    key = np.array([(owner, j) for owner, j, _, _, _ in segments])
    A = np.array([a for *_, a, _ in segments])
    B = np.array([b for *_, b in segments])
    for i, s in enumerate(fractures):
        V = np.asarray(s.vertices, float)
        for end, prev, k in ((V[-1], V[-2], len(V) - 2), (V[0], V[1], 0)):
            if np.any(end <= lower + tol) or np.any(end >= upper - tol):
                continue  # on the boundary: not a tip
            # distance to everything but the segment the tip ends
            other = (key[:, 0] != i) | (key[:, 1] != k)
            dist = segment_distances(end[None], A[other], B[other])[0]
            if dist.size and dist.min() <= tol:
                continue  # ends on another fracture or interface: a junction, not a tip
            clearance = min(float(dist.min(initial=np.inf)), *(end - lower), *(upper - end))
            seg_len = float(np.linalg.norm(end - prev))
            a = min(TIP * seg_len, CLEAR * clearance)
            t, n = _frame(prev, end)
            label = f"tip of {s.name!r} at {np.round(end, 6).tolist()}"
            if fracture_size is not None and a < fracture_size:
                log.warning("mesh.mirror: the mirrored patch at the %s is %.3g m across, under two cells of "
                            "fracture_size %.3g m; refine fracture_size for it to pay off", label, 2 * a,
                            fracture_size)
            regions.append(_region(label, end, t, n, a, a))
    if not regions:
        raise InputError("mirror", "\"tips\" found no fracture tip inside the domain to mirror the mesh at")
    return regions


def _convex_overlap(P: np.ndarray, Q: np.ndarray) -> bool:
    """Whether two convex polygons (k, 2) overlap (separating-axis test; touching counts).

    A polygon may be a segment (2, 2).
    """
    P, Q = np.asarray(P, float), np.asarray(Q, float)
    for poly in (P, Q):
        edges = np.roll(poly, -1, axis=0) - poly
        for e in edges:
            axis = np.array([-e[1], e[0]])
            p, q = P @ axis, Q @ axis
            if p.max() < q.min() or q.max() < p.min():
                return False
    return True


def add_region_surfaces(occ, regions) -> list[tuple[int, int]]:
    """OCC entities of the region halves, in the order [upper_0, lower_0, upper_1, ...]:
    plane surfaces in 2D, volumes in 3D (:func:`.mirror3d.add_prism_volumes`)."""
    if regions and isinstance(regions[0], MirrorPrism):
        return add_prism_volumes(occ, regions)
    ents = []
    for r in regions:
        for quad in (r.upper, r.lower):
            pts = [occ.addPoint(x, y, 0.0) for x, y in quad]
            loop = occ.addCurveLoop([occ.addLine(a, b) for a, b in zip(pts, pts[1:] + pts[:1])])
            ents.append((2, occ.addPlaneSurface([loop])))
    return ents


def set_mirror(gmsh, regions, children) -> list[tuple[int, int]]:
    """Make each n^- half's mesh the reflection of its n^+ half's (before meshing).

    ``children`` holds, per half (same order as :func:`add_region_surfaces`), its pieces
    after the fragment; each half must have stayed a single surface (volume in 3D).

    Returns
    -------
    list of (int, int)
        3D: the (n^+, n^-) volume tags per region, for :func:`mirror_volumes` after meshing
        (only the bounding surfaces can be periodic in gmsh). 2D: empty, the periodic
        surfaces are the whole mirrored mesh.
    """
    if regions and isinstance(regions[0], MirrorPrism):
        return set_mirror_3d(gmsh, regions, children)
    for k, r in enumerate(regions):
        up = [tag for d, tag in children[2 * k] if d == 2]
        lo = [tag for d, tag in children[2 * k + 1] if d == 2]
        if len(up) != 1 or len(lo) != 1:
            raise InputError("mirror", f"the mirrored region around the {r.label} is cut by another "
                             "fracture or interface; move them apart")
        gmsh.model.mesh.setPeriodic(2, lo, up, r.affine.tolist())
    return []


def mirror_volumes(gmsh, regions, pairs, tags, X, cells, etags):
    """3D, after meshing: the n^- halves' tetrahedra replaced by the reflections of the n^+
    halves' (:func:`.mirror3d.reflect_halves`); returns (X, cells) unchanged without pairs."""
    if not pairs:
        return X, cells
    return reflect_halves(gmsh, regions, pairs, tags, X, cells, etags)
