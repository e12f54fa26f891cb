"""3D meshes mirror-symmetric about planar fractures (``mesh.mirror = "fractures"``).

Why: see :mod:`.mirror`. Next to a crack edge (tip line) the shear part of the displacement
is singular; on a mesh that is not symmetric about the crack plane its discretisation error
leaks into the normal multipliers λ_n of the faces near the edge (scatter of λ_n, faces that
open spuriously). On a mesh symmetric about the plane, with two-sided bubbles, the discrete
problem splits into a symmetric part (the uniform compression, reproduced exactly) and an
antisymmetric part (the slip), which exerts no normal traction on the crack.

The mirrored region of a fracture is a prism: the fracture polygon's bounding rectangle in
its own plane (axes of the smallest-area rectangle over the polygon's edge directions),
enlarged by a margin ``m`` beyond each side, extruded by ``m`` along ±n. ``m`` is ``BAND``
of the fracture's extent (the longer side of the rectangle), shrunk to keep the prism at
least ``CLEAR * fracture_size`` inside the box (and refused if that leaves a margin under
``CLEAR * fracture_size``).

gmsh cannot mesh volumes periodically, so the symmetric mesh is made in three steps:

1. the two half-prisms are separate OCC volumes, fragmented with the box and the fractures
   (the fracture then lies in the mid-plane, the common face of the halves);
2. every bounding surface of the n^- half except the mid-plane pieces is set periodic to its
   mirror surface of the n^+ half with the reflection as affine map (gmsh accepts reflections
   for surfaces: their meshes are copied node by node);
3. after the volume mesh is generated, the n^- half's tetrahedra are replaced by the
   reflections of the n^+ half's (:func:`reflect_halves`): boundary nodes of the n^+ half map
   onto the n^- half's boundary nodes (mid-plane nodes onto themselves, periodic surfaces onto
   their copies; matched by a KD-tree within a tight tolerance), interior nodes get new
   reflected nodes, and the n^- half's own interior nodes are dropped.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...core.errors import InputError, MeshError
from ..fractures import validate_spec

log = logging.getLogger("polypore")

BAND = 0.25  # prism margin beyond each fracture edge and to each side, fraction of the fracture's extent
# smallest margin, and clearance kept from the box boundary, in units of fracture_size: half a
# cell keeps the prism's faces clear of the boundary's without forcing tiny cells between them
CLEAR = 0.5


@dataclass(frozen=True)
class MirrorPrism:
    """One mirrored prism around a planar fracture.

    Attributes
    ----------
    label : str
        What it surrounds ("fracture 'F'") for messages.
    centre : (3,) float, m
        Centre of the mid-plane rectangle (on the fracture plane).
    frame : (3, 3) float
        Rows e1, e2 (in-plane axes of the rectangle) and n (unit normal of the fracture).
    half : (3,) float, m
        Half-sides along e1 and e2 and the half-thickness δ along n.
    affine : (16,) float
        Row-major 4x4 affine map of the reflection about the fracture plane (gmsh's format).
    """

    label: str
    centre: np.ndarray
    frame: np.ndarray
    half: np.ndarray
    affine: np.ndarray

    def reflect(self, X: np.ndarray) -> np.ndarray:
        """Mirror images (k, 3) of points X (k, 3), m, about the fracture plane."""
        n = self.frame[2]
        return X - 2.0 * ((X - self.centre) @ n)[:, None] * n

    def corners(self) -> np.ndarray:
        """(8, 3) corners of the whole prism, m."""
        s = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
        return self.centre + (s * self.half) @ self.frame


def _bounding_rectangle(P: np.ndarray):
    """Smallest-area rectangle around the polygon P (k, 2) among those with a side along one of
    its edges (for a convex polygon, the smallest-area bounding rectangle of all).

    Returns the unit axis u1 (2,), the rectangle centre (2,) and the half-sides (2,), m.
    """
    E = np.roll(P, -1, axis=0) - P
    u1 = E / np.linalg.norm(E, axis=1)[:, None]
    u2 = np.stack([-u1[:, 1], u1[:, 0]], axis=1)
    s, t = u1 @ P.T, u2 @ P.T  # (edges, points) coordinates along each candidate frame
    w, h = np.ptp(s, axis=1), np.ptp(t, axis=1)
    k = int(np.argmin(w * h))
    centre = 0.5 * (s[k].min() + s[k].max()) * u1[k] + 0.5 * (t[k].min() + t[k].max()) * u2[k]
    return u1[k], centre, 0.5 * np.array([w[k], h[k]])


def _fit_margin(base_c, frame, h, lower, upper, clear) -> float:
    """Largest m ≥ 0 keeping the prism c ± (h1+m) e1 ± (h2+m) e2 ± m n at least ``clear``
    inside the box; -1 when even m = 0 (the fracture's rectangle) does not fit."""
    s = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    base = base_c + (s[:, :2] * h) @ frame[:2]          # (8, 3) corners at m = 0
    slope = s @ frame                                   # (8, 3) d corner / d m
    lo, hi = lower + clear, upper - clear
    if np.any(base < lo) or np.any(base > hi):
        return -1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(slope > 0, (hi - base) / slope, np.where(slope < 0, (lo - base) / slope, np.inf))
    return float(bound.min())


def prisms(fractures, lower, upper, interfaces=(), fracture_size: float | None = None) -> list[MirrorPrism]:
    """The mirrored prisms of ``mesh.mirror = "fractures"`` in 3D (see the module docstring).

    Parameters
    ----------
    fractures, interfaces : sequences of FractureSpec (3D planar polygons)
    lower, upper : (3,) float, m
        The box domain.
    fracture_size : float, m, optional
        Mesh size on the fractures: ``CLEAR`` times it is the clearance kept between a prism and
        the box boundary and the smallest margin accepted (default: 1 % of the box's largest side).

    Raises
    ------
    InputError
        ``mesh.mirror``: no fracture; a prism that cannot fit in the box with a margin of at
        least ``CLEAR * fracture_size``; two prisms that overlap; a prism met by another fracture or
        an interface.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if not fractures:
        raise InputError("mirror", "needs at least one fracture to mirror the mesh about")
    clear = CLEAR * float(fracture_size) if fracture_size is not None else 0.01 * float(np.max(upper - lower))
    out = []
    for s in fractures:
        info = validate_spec(s, 3)
        n, c = info["normal"], info["centre"]
        u1, pc, h = _bounding_rectangle(info["poly2d"])
        e1 = u1[0] * info["e1"] + u1[1] * info["e2"]
        e2 = np.cross(n, e1)
        frame = np.stack([e1, e2, n])
        centre = c + pc[0] * info["e1"] + pc[1] * info["e2"]
        want = BAND * 2.0 * float(h.max())
        fit = _fit_margin(centre, frame, h, lower, upper, clear)
        m = min(want, fit)
        if m < clear * (1 - 1e-9):  # (rounding: a margin of exactly the clearance fits)
            raise InputError("mirror", f"\"fractures\": the mirrored prism around fracture {s.name!r} cannot "
                             f"fit in the domain {lower.tolist()}–{upper.tolist()}: it needs a margin of at least "
                             f"{clear:.3g} m (half the fracture_size) around the fracture and as much clearance from "
                             f"the boundary, but only {max(fit, 0.0):.3g} m fits; \"fractures\" mirrors fractures "
                             "well inside the domain (use mirror = \"none\" for this network)")
        if m < want:
            log.info("mesh.mirror: the prism around fracture %r shrunk to a margin of %.3g m (%.3g wanted) to stay "
                     "inside the domain", s.name, m, want)
        M = np.eye(3) - 2.0 * np.outer(n, n)
        shift = centre - M @ centre
        affine = np.eye(4)
        affine[:3, :3], affine[:3, 3] = M, shift
        out.append(MirrorPrism(f"fracture {s.name!r}", centre, frame, np.array([h[0] + m, h[1] + m, m]),
                               affine.ravel()))
    others = [(i, sp.name, np.asarray(sp.vertices, float), validate_spec(sp, 3)["normal"])
              for i, sp in enumerate(list(fractures) + list(interfaces))]
    for k, p in enumerate(out):
        for i, name, V, normal in others:
            if i == k:
                continue
            # separating axes of a box and a planar polygon: the box's axes, the polygon's
            # normal, and each box axis crossed with each polygon edge
            E = np.roll(V, -1, axis=0) - V
            axes = np.vstack([p.frame, normal[None], np.cross(p.frame[:, None, :], E[None, :, :]).reshape(-1, 3)])
            if _overlap(p.corners(), V, axes):
                raise InputError("mirror", f"the mirrored prism around {p.label} meets {name!r} (a fracture "
                                 "or region interface); \"fractures\" needs each fracture's prism clear of the "
                                 "rest of the network (use mirror = \"none\" for fractures this close)")
        for q in out[:k]:
            axes = np.vstack([p.frame, q.frame, np.cross(p.frame[:, None, :], q.frame[None, :, :]).reshape(-1, 3)])
            if _overlap(p.corners(), q.corners(), axes):
                raise InputError("mirror", f"the mirrored prisms around the {q.label} and the {p.label} "
                                 "overlap; move the fractures apart (or use mirror = \"none\")")
    return out


def _overlap(P: np.ndarray, Q: np.ndarray, axes: np.ndarray) -> bool:
    """Whether the convex hulls of the points P (k, 3) and Q (l, 3) overlap (separating-axis
    test over ``axes``, which must hold the face normals of both and the cross products of
    their edge directions; touching counts). A non-convex polygon is tested by its hull,
    which errs on the side of reporting an overlap."""
    norm = np.linalg.norm(axes, axis=1)
    axes = axes[norm > 1e-12 * norm.max()]
    p, q = P @ axes.T, Q @ axes.T
    tol = 1e-12 * (np.abs(p).max() + np.abs(q).max())
    separated = (p.max(axis=0) < q.min(axis=0) - tol) | (q.max(axis=0) < p.min(axis=0) - tol)
    return not bool(np.any(separated))


def add_prism_volumes(occ, regions) -> list[tuple[int, int]]:
    """OCC volumes of the prism halves, in the order [n^+ half 0, n^- half 0, n^+ half 1, ...]."""
    ents = []
    for r in regions:
        e1, e2, n = r.frame
        a1, a2, d = r.half
        rect = [r.centre + s1 * a1 * e1 + s2 * a2 * e2 for s1, s2 in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        for sign in (1.0, -1.0):
            pts = [occ.addPoint(*x) for x in rect]
            loop = occ.addCurveLoop([occ.addLine(a, b) for a, b in zip(pts, pts[1:] + pts[:1])])
            out = occ.extrude([(2, occ.addPlaneSurface([loop]))], *(sign * d * n))
            ents += [(3, tag) for dim, tag in out if dim == 3]
    return ents


def set_mirror_3d(gmsh, regions, children) -> list[tuple[int, int]]:
    """Make every bounding surface of each n^- half (but the mid-plane) periodic to its mirror
    surface of the n^+ half, and return the (n^+, n^-) volume tags per region.

    ``children`` holds, per half (order of :func:`add_prism_volumes`), its pieces after the
    fragment; each half must have stayed a single volume whose faces pair up by reflection.
    """
    occ = gmsh.model.occ
    pairs = []
    for k, r in enumerate(regions):
        up = [tag for d, tag in children[2 * k] if d == 3]
        lo = [tag for d, tag in children[2 * k + 1] if d == 3]
        cut = InputError("mirror", f"the mirrored prism around the {r.label} is cut by another fracture or "
                         "interface; move them apart (or use mirror = \"none\")")
        if len(up) != 1 or len(lo) != 1:
            raise cut
        bu = sorted({abs(t) for _, t in gmsh.model.getBoundary([(3, up[0])], combined=False, oriented=False)})
        bl = sorted({abs(t) for _, t in gmsh.model.getBoundary([(3, lo[0])], combined=False, oriented=False)})
        slaves = [t for t in bl if t not in bu]  # the mid-plane pieces are shared
        masters = [t for t in bu if t not in bl]
        if len(slaves) != len(masters):
            raise cut
        cu = np.array([occ.getCenterOfMass(2, t) for t in masters])
        cl = r.reflect(np.array([occ.getCenterOfMass(2, t) for t in slaves]))
        au = np.array([occ.getMass(2, t) for t in masters])
        al = np.array([occ.getMass(2, t) for t in slaves])
        dist = np.linalg.norm(cl[:, None, :] - cu[None, :, :], axis=2)
        match = dist.argmin(axis=1)
        tol = 1e-7 * float(np.max(r.half))
        if (np.any(dist[np.arange(len(slaves)), match] > tol) or np.unique(match).size != len(slaves)
                or np.any(np.abs(al - au[match]) > 1e-7 * au[match])):
            raise cut
        for s, m in zip(slaves, match):
            gmsh.model.mesh.setPeriodic(2, [s], [masters[m]], r.affine.tolist())
        pairs.append((up[0], lo[0]))
    return pairs


def reflect_halves(gmsh, regions, pairs, tags, X, cells, etags):
    """Replace each n^- half's tetrahedra by the reflections of its n^+ half's.

    Parameters
    ----------
    gmsh : the gmsh module, with the model meshed
    regions : list of MirrorPrism
    pairs : list of (n^+ volume, n^- volume) tags, from :func:`set_mirror_3d`
    tags : (n,) int
        gmsh node tags of the rows of ``X``.
    X : (n, 3) float, m
        Node coordinates.
    cells : (c, 4) int
        Tetrahedra, as row numbers of ``X``.
    etags : (c,) int
        gmsh element tags of the tetrahedra.

    Returns
    -------
    X : (n + k, 3) float, m
        With the k reflected interior nodes appended.
    cells : (c', 4) int
        The n^- halves' tetrahedra replaced (rows of the new ``X``); the n^- halves' own
        interior nodes are left unused.

    Raises
    ------
    MeshError
        ``mesh.mirror``: the boundary meshes of the two halves are not mirror images
        (gmsh did not honour the periodicity).
    """
    mesh = gmsh.model.mesh
    tags = np.asarray(tags, np.int64)
    row = np.full(int(tags.max(initial=0)) + 1, -1, np.int64)
    row[tags] = np.arange(tags.size)

    def rows(dim, tag, boundary):
        return row[np.asarray(mesh.getNodes(dim, tag, includeBoundary=boundary)[0], np.int64)]

    keep = np.ones(len(cells), bool)
    new_X, new_cells = [X], []
    n = len(X)
    for r, (up, lo) in zip(regions, pairs):
        _, e_up = mesh.getElementsByType(4, up)
        e_lo, _ = mesh.getElementsByType(4, lo)
        keep &= ~np.isin(etags, np.asarray(e_lo, np.int64))
        T = row[np.asarray(e_up, np.int64).reshape(-1, 4)]
        # boundary nodes of a half: its nodes with its boundary minus those without
        b_up = np.setdiff1d(rows(3, up, True), rows(3, up, False))
        b_lo = np.setdiff1d(rows(3, lo, True), rows(3, lo, False))
        # gmsh copies periodic meshes by the affine map, and mid-plane nodes are their own
        # images: a true match is exact up to rounding
        tol = 1e-9 * float(np.max(r.half))
        dist, j = cKDTree(X[b_lo]).query(r.reflect(X[b_up]))
        if b_up.size != b_lo.size or np.any(dist > tol) or np.unique(j).size != j.size:
            raise MeshError("mirror", f"the boundary meshes of the two halves of the prism around the {r.label} "
                            f"are not mirror images ({b_up.size} and {b_lo.size} nodes, worst mismatch "
                            f"{dist.max(initial=0):.3g} m); gmsh did not honour the periodic surfaces")
        inner = np.setdiff1d(T, b_up)
        image = np.full(len(X), -1, np.int64)
        image[b_up] = b_lo[j]
        image[inner] = n + np.arange(inner.size)
        new_X.append(r.reflect(X[inner]))
        n += inner.size
        # a reflection reverses orientation: swap two vertices to keep positive volumes
        new_cells.append(image[T][:, [1, 0, 2, 3]])
    return np.concatenate(new_X), np.concatenate([cells[keep]] + new_cells)
