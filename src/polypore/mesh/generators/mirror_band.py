"""2D meshes mirror-symmetric about straight fractures, in a band around each (``mesh.mirror``).

Why: next to a crack tip the shear (mode II) part of the displacement is singular. On a
mesh that is not symmetric about the crack line, its discretisation error leaks into the
normal multiplier λ_n of the last faces before each tip, by O(K_II / sqrt(h)) on faces of
length h, so the L2 error of λ_n over the whole crack stays O(1) under refinement
(docs/contact.md, C3). On a mesh symmetric about the crack line with two-sided bubbles the
discrete problem splits exactly into a symmetric part (the closed-crack compression, which
the scheme reproduces) and an antisymmetric part (the slip), which exerts no normal
traction on the crack; λ_n then carries no tip error.

The band of a fracture of length L is the rectangle aligned with it that extends
``rel * L`` beyond each tip and ``rel * L`` to each side. Its half on the n^- side is meshed
as the reflected copy of the half on the n^+ side (gmsh periodic meshing with a reflection).
"""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError

# band margin beyond the tips and to each side, as a fraction of the fracture's length
BAND = 0.25


def band_halves(fractures, lower, upper, interfaces=(), rel: float = BAND) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """Corner points of the two half-bands of every fracture, and its reflection.

    Parameters
    ----------
    fractures : sequence of FractureSpec
        2D fractures; each must be one straight segment with both ends inside the box.
    lower, upper : (2,) float, m
        The box domain.
    interfaces : sequence of FractureSpec
        Region interfaces, which must stay out of the bands.
    rel : float
        Band margin as a fraction of each fracture's length.

    Returns
    -------
    list of (name, upper_half (4, 2), lower_half (4, 2), affine (16,))
        Per fracture, its name, the half-band corners on the n^+ and n^- sides (counter-clockwise) and
        the 4x4 row-major affine map of the reflection about the fracture line (gmsh's format).

    Raises
    ------
    InputError
        ``mesh.mirror`` naming the fracture: a kinked fracture, a band leaving the box, two
        bands overlapping, an interface crossing a band.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if lower.size != 2:
        raise InputError("mesh.mirror", "mirror-symmetric bands are available for 2D meshes only")
    if not fractures:
        raise InputError("mesh.mirror", "needs at least one fracture to mirror the mesh about")
    out, quads = [], []
    for s in fractures:
        V = np.asarray(s.vertices, float)
        if V.shape[0] != 2:
            raise InputError("mesh.mirror", f"fracture {s.name!r} has {V.shape[0] - 1} segments; the mesh can be "
                             "mirrored about straight fractures (two vertices) only")
        c = V.mean(axis=0)
        t = V[1] - V[0]
        length = float(np.linalg.norm(t))
        t /= length
        n = np.array([t[1], -t[0]])
        a, w = 0.5 * length + rel * length, rel * length
        up = np.array([c - a * t, c + a * t, c + a * t + w * n, c - a * t + w * n])
        lo = np.array([c - a * t - w * n, c + a * t - w * n, c + a * t, c - a * t])
        box = np.vstack([up, lo])
        if np.any(box < lower) or np.any(box > upper):
            raise InputError("mesh.mirror", f"the mirror band around fracture {s.name!r} ({rel:g} of its length "
                             f"beyond its tips and to each side) leaves the domain {lower.tolist()}–"
                             f"{upper.tolist()}; mirroring needs fractures whose ends lie well inside it")
        M = np.eye(2) - 2.0 * np.outer(n, n)
        shift = c - M @ c
        affine = np.array([M[0, 0], M[0, 1], 0.0, shift[0], M[1, 0], M[1, 1], 0.0, shift[1],
                           0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        out.append((s.name, up, lo, affine))
        quads.append((s.name, np.vstack([lo[:2], up[2:]])))
    for i in range(len(quads)):
        for j in range(i):
            if _convex_overlap(quads[i][1], quads[j][1]):
                raise InputError("mesh.mirror", f"the mirror bands around fractures {quads[j][0]!r} and "
                                 f"{quads[i][0]!r} overlap; mirroring needs fractures further apart")
    for s in interfaces:
        V = np.asarray(s.vertices, float)
        for name, quad in quads:
            if any(_convex_overlap(seg, quad) for seg in zip(V[:-1], V[1:])):
                raise InputError("mesh.mirror", f"the mirror band around fracture {name!r} is crossed by the "
                                 f"interface {s.name!r}; mirroring needs isolated fractures")
    return out


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


def add_band_surfaces(occ, halves) -> list[tuple[int, int]]:
    """OCC plane surfaces of the half-bands, in the order [up_0, lo_0, up_1, lo_1, ...]."""
    ents = []
    for _, up, lo, _ in halves:
        for quad in (up, lo):
            pts = [occ.addPoint(x, y, 0.0) for x, y in quad]
            loop = occ.addCurveLoop([occ.addLine(a, b) for a, b in zip(pts, pts[1:] + pts[:1])])
            ents.append((2, occ.addPlaneSurface([loop])))
    return ents


def set_mirror(gmsh, halves, children) -> None:
    """Make each n^- half-band's mesh the reflection of its n^+ half's.

    ``children`` holds, per half-band surface (same order as :func:`add_band_surfaces`), its
    pieces after the fragment; each half must have stayed a single surface.
    """
    for k, (name, _, _, affine) in enumerate(halves):
        up = [tag for d, tag in children[2 * k] if d == 2]
        lo = [tag for d, tag in children[2 * k + 1] if d == 2]
        if len(up) != 1 or len(lo) != 1:
            raise InputError("mesh.mirror", f"the mirror band around fracture {name!r} is crossed by "
                             "another fracture or interface; mirroring needs isolated fractures")
        gmsh.model.mesh.setPeriodic(2, lo, up, affine.tolist())
