"""Simplicial meshes (triangles / tetrahedra) of a box conforming to fractures, by gmsh.

The box, the fractures and the region interfaces are built with the OpenCASCADE
kernel and fragmented together, so that every fracture (and interface) becomes a
union of mesh faces; crossing fractures are split along their intersections. The
mesh size is ``size`` in the bulk and ``fracture_size`` on fractures, growing
linearly with the distance to the fractures.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from ...core.errors import InputError, MeshError
from ...core.ragged import INDEX
from ..build import mesh_from_cells
from ..fractures import validate_spec
from ..mesh import Mesh
from ..msh import gmsh_last_error, gmsh_session
from .mirror import add_region_surfaces, mirror_regions, mirror_volumes, set_mirror

log = logging.getLogger("polypore")

# size growth per unit distance away from the fractures (h(d) = fracture_size + GRADING * d)
GRADING = 0.4
# radius of the graded zone around crack tips, in units of fracture_size
TIP_RADIUS = 4.0
# exponent γ of the tip law h(r) = fracture_size (r/R)^γ: 1/2 suits P1-type spaces; quadratic
# displacements want γ in [2/3, 3/4] (docs/accuracy_3d.md, "Mesh grading for P2")
TIP_GRADING = 0.5


def simplicial_mesh(lower, upper, fractures=(), size: float = 0.1, *, fracture_size: float | None = None,
                    interfaces=(), seed: int = 0, grading: float = GRADING,
                    tip_size: float | None = None, tip_grading: float = TIP_GRADING,
                    mirror: str = "none") -> Mesh:
    """Triangulate a rectangle / tetrahedralise a box, conforming to fractures and interfaces.

    Parameters
    ----------
    lower, upper : (d,) float, m
        Opposite corners of the box domain, d = 2 or 3.
    fractures : sequence of FractureSpec
        2D polylines (possibly kinked) or 3D planar polygons, inside the box; they may
        reach its boundary and cross each other.
    size : float, m
        Target cell size in the bulk.
    fracture_size : float, m, optional
        Target cell size on the fractures (default ``size``); the size grows
        linearly (slope ``grading``, default ``GRADING``) to ``size`` away from them.
    tip_size : float, m, optional
        Target size at the crack tips: the fracture ends inside the box in 2D, the fracture
        edges inside the box (tip lines) in 3D. Within R = TIP_RADIUS · fracture_size of them
        the size follows h(r) = fracture_size (r/R)^tip_grading (r the distance to the tips),
        floored at tip_size and capped by the fracture and bulk sizes. Like the fracture
        refinement, it applies only when fracture_size < size.
    tip_grading : float
        Exponent γ ∈ (0, 1] of that law. The default 1/2 (√r) is the grading for P1-type spaces
        at a √r crack front; quadratic displacements reach their best rate per unknown with
        γ ∈ [2/3, 3/4] (isotropic cells; docs/accuracy_3d.md). Ignored without ``tip_size``.
    mirror : {"none", "tips", "fractures"}
        Mesh a patch around every fracture tip ("tips", 2D only) or a band around every
        straight fracture ("fractures"; in 3D a prism around every planar fracture)
        symmetrically about the fracture line / plane (see :mod:`.mirror` and
        :mod:`.mirror3d`: no crack-tip error in the normal multipliers).
    interfaces : sequence of FractureSpec
        Further lines/polygons the mesh must conform to (region boundaries), meshed at ``size``.
    seed : int
        Gmsh's random seed (meshes are reproducible for a given seed).

    Returns
    -------
    Mesh
        Triangles (nodes (n, 2)) or tetrahedra, without unused nodes.

    Raises
    ------
    InputError / MeshError
        Bad box or sizes, bad fracture geometry, or gmsh failing to mesh the geometry.
    """
    lower = np.asarray(lower, float).ravel()
    upper = np.asarray(upper, float).ravel()
    dim = lower.size
    if dim not in (2, 3) or upper.shape != lower.shape:
        raise InputError("lower", f"lower/upper must both have 2 or 3 coordinates, got {lower.tolist()} "
                         f"and {upper.tolist()}")
    if np.any(upper <= lower):
        raise InputError("upper", f"must exceed lower {lower.tolist()} in every direction, got {upper.tolist()}")
    if not (np.isfinite(size) and size > 0):
        raise InputError("size", f"must be a positive number, got {size}")
    fsize = float(size if fracture_size is None else fracture_size)
    if not (np.isfinite(fsize) and fsize > 0):
        raise InputError("fracture_size", f"must be a positive number, got {fracture_size}")
    if tip_size is not None:
        if not (isinstance(tip_size, (int, float)) and tip_size > 0):
            raise InputError("tip_size", f"must be a positive number (m), got {tip_size}")
    if not (isinstance(tip_grading, (int, float)) and 0 < tip_grading <= 1):
        raise InputError("tip_grading", f"must be an exponent in (0, 1] (h ∝ r^γ at crack tips; 0.5 for P1, "
                         f"2/3 to 3/4 for quadratic displacements), got {tip_grading}")
    if not (isinstance(grading, (int, float)) and grading > 0):
        raise InputError("grading", f"must be a positive number (size growth per unit distance), got {grading}")
    fsize = min(fsize, float(size))
    box = np.stack([lower, upper])
    fractures, interfaces = list(fractures), list(interfaces)
    for s in fractures:
        validate_spec(s, dim, box)
    for s in interfaces:
        validate_spec(s, dim, box)
    regions = mirror_regions(mirror, fractures, lower, upper, interfaces, fsize)
    span = float(np.max(upper - lower))
    est = np.prod(upper - lower) / size ** dim
    if est > 5e7:
        raise InputError("size", f"{size} m would give about {est:.3g} cells in the bulk alone; use a larger size")

    t0 = time.perf_counter()
    opts = {
        "Mesh.RandomSeed": int(seed),
        # the size comes from the background field only
        "Mesh.MeshSizeExtendFromBoundary": 0, "Mesh.MeshSizeFromPoints": 0, "Mesh.MeshSizeFromCurvature": 0,
        "Mesh.MeshSizeMax": float(size), "Mesh.MeshSizeMin": 0.5 * min(fsize, tip_size or fsize),
        # OCC booleans need a tolerance relative to the model, not the absolute default
        "Geometry.Tolerance": 1e-9 * span, "Geometry.ToleranceBoolean": 1e-9 * span,
        "Geometry.OCCBooleanPreserveNumbering": 1,
    }
    with gmsh_session(opts) as gmsh:
        try:
            nodes, conn = _generate(gmsh, dim, lower, upper, fractures, interfaces, float(size), fsize,
                                    float(grading), tip_size, regions, float(tip_grading))
        except (InputError, MeshError):
            raise
        except Exception as exc:
            raise MeshError("gmsh", f"gmsh could not mesh the domain with its {len(fractures)} fracture(s) and "
                            f"{len(interfaces)} interface(s): {gmsh_last_error(gmsh, exc)}. Fractures that "
                            "nearly touch, overlap or meet at tiny angles are the usual cause; move them apart "
                            "or refine fracture_size") from None
    t_gmsh = time.perf_counter() - t0
    kind = "triangle" if dim == 2 else "tetra"
    if conn.shape[0] == 0:
        raise MeshError("gmsh", "gmsh produced no cells; check the domain and the sizes")
    mesh = mesh_from_cells(nodes, {kind: conn})
    log.info("gmsh: %d %s in %.2f s (%d nodes)", mesh.n_cells, "triangles" if dim == 2 else "tetrahedra",
             t_gmsh, mesh.n_nodes)
    return mesh


def _add_spec(occ, spec, dim) -> list[tuple[int, int]]:
    """OCC entities of one fracture: the curves of a polyline (2D) or one plane surface (3D)."""
    V = np.asarray(spec.vertices, float)
    if dim == 2:
        pts = [occ.addPoint(x, y, 0.0) for x, y in V]
        return [(1, occ.addLine(a, b)) for a, b in zip(pts[:-1], pts[1:])]
    pts = [occ.addPoint(*x) for x in V]
    lines = [occ.addLine(a, b) for a, b in zip(pts, pts[1:] + pts[:1])]
    loop = occ.addCurveLoop(lines)
    return [(2, occ.addPlaneSurface([loop]))]


def _tip_points(gmsh, fractures, lower, upper) -> list[int]:
    """Tags of the model points at 2D fracture ends strictly inside the box (tips, or T-junctions)."""
    ends = []
    for s in fractures:
        V = np.asarray(s.vertices, float)
        for P in (V[0], V[-1]):
            tol = 1e-9 * float(np.max(upper - lower))
            if np.all(P > lower + tol) and np.all(P < upper - tol):
                ends.append(P)
    tags = []
    for _, tag in gmsh.model.getEntities(0):
        X = np.asarray(gmsh.model.getValue(0, tag, []))[:2]
        if any(np.linalg.norm(X - P) <= 1e-9 * float(np.max(upper - lower)) for P in ends):
            tags.append(tag)
    return tags


def _tip_curves(gmsh, frac_ents, fractures, lower, upper) -> list[int]:
    """Tags of the 3D tip lines: edges of the fracture surfaces that lie neither on the box
    boundary nor on another fracture (intersection and T-junction lines). Fracture edges are
    straight, so each is classified by its midpoint."""
    from ..fractures import _inside_polygon

    tol = 1e-7 * float(np.max(upper - lower))
    geos = [validate_spec(s, 3) for s in fractures]
    curves = sorted({abs(c) for tag in frac_ents
                     for _, c in gmsh.model.getBoundary([(2, tag)], combined=False, oriented=False)})
    tips = []
    for c in curves:
        t0, t1 = gmsh.model.getParametrizationBounds(1, c)
        mid = np.asarray(gmsh.model.getValue(1, c, [0.5 * (t0[0] + t1[0])]))
        if np.any(np.isclose(mid, lower, rtol=0, atol=tol) | np.isclose(mid, upper, rtol=0, atol=tol)):
            continue
        owners = 0
        for g in geos:
            X = mid - g["centre"]
            if abs(X @ g["normal"]) <= tol:
                owners += int(_inside_polygon(np.array([[X @ g["e1"], X @ g["e2"]]]), g["poly2d"], tol)[0])
        if owners == 1:
            tips.append(c)
    return tips


def _generate(gmsh, dim, lower, upper, fractures, interfaces, size, fsize, grading=GRADING, tip_size=None,
              regions=(), tip_grading=TIP_GRADING):
    occ = gmsh.model.occ
    ext = upper - lower
    if dim == 2:
        domain = [(2, occ.addRectangle(lower[0], lower[1], 0.0, ext[0], ext[1]))]
    else:
        domain = [(3, occ.addBox(*lower, *ext))]
    tools, owner = [], []
    for i, s in enumerate(list(fractures) + list(interfaces)):
        ents = _add_spec(occ, s, dim)
        tools += ents
        owner += [i] * len(ents)
    mirrored = add_region_surfaces(occ, regions)
    frac_ents = set()
    if tools:
        _, out_map = occ.fragment(domain, tools + mirrored)
        # children of every tool; the first map entry belongs to the domain
        for i, children in zip(owner, out_map[1:]):
            if i < len(fractures):
                frac_ents.update(tag for d, tag in children if d == dim - 1)
    occ.synchronize()
    pairs = set_mirror(gmsh, regions, out_map[1 + len(tools):]) if mirrored else []

    field = gmsh.model.mesh.field
    if frac_ents and fsize < size:
        extent = max(float(np.ptp(np.asarray(s.vertices), axis=0).max()) for s in fractures)
        dist = field.add("Distance")
        field.setNumbers(dist, "CurvesList" if dim == 2 else "SurfacesList", sorted(frac_ents))
        # samples per entity (per direction in 3D): spaced at most fsize / 2
        cap = 20000 if dim == 2 else 400
        field.setNumber(dist, "Sampling", int(np.clip(np.ceil(2 * extent / fsize), 20, cap)))
        thr = field.add("Threshold")
        field.setNumber(thr, "InField", dist)
        field.setNumber(thr, "SizeMin", fsize)
        field.setNumber(thr, "SizeMax", size)
        field.setNumber(thr, "DistMin", 0.5 * fsize)
        field.setNumber(thr, "DistMax", 0.5 * fsize + (size - fsize) / grading)
        background = thr
        tips = [] if tip_size is None else (_tip_points(gmsh, fractures, lower, upper) if dim == 2
                                            else _tip_curves(gmsh, frac_ents, fractures, lower, upper))
        if tips and tip_size < fsize:
            # crack tips carry the stress singularity: grade down to tip_size there
            dtip = field.add("Distance")
            field.setNumbers(dtip, "PointsList" if dim == 2 else "CurvesList", tips)
            if dim == 3:
                field.setNumber(dtip, "Sampling", int(np.clip(np.ceil(2 * extent / tip_size), 20, 2000)))
            # h(r) = fsize (r/R)^γ, floored at tip_size. γ = 1/2: the grading that resolves the √r
            # crack-tip field with P1-type spaces (cell count ∝ R²/fsize³ per unit tip length,
            # whatever tip_size); γ ∈ [2/3, 3/4] for P2 (cell count ∝ log(1/tip_size) at 2/3, ∝
            # tip_size^(2-3γ) above)
            R = TIP_RADIUS * fsize
            root = field.add("MathEval")
            if tip_grading == 0.5:      # the expression of before: meshes unchanged bit for bit
                field.setString(root, "F", f"{fsize!r} * Sqrt(F{dtip} / {R!r})")
            else:
                field.setString(root, "F", f"{fsize!r} * (F{dtip} / {R!r})^{float(tip_grading)!r}")
            floor = field.add("MathEval")
            field.setString(floor, "F", repr(float(tip_size)))
            ttip = field.add("Max")
            field.setNumbers(ttip, "FieldsList", [root, floor])
            background = field.add("Min")
            field.setNumbers(background, "FieldsList", [thr, ttip])
        field.setAsBackgroundMesh(background)
    else:
        const = field.add("MathEval")
        field.setString(const, "F", repr(size))
        field.setAsBackgroundMesh(const)
    gmsh.model.mesh.generate(dim)

    tags, coords, _ = gmsh.model.mesh.getNodes()
    etype = 2 if dim == 2 else 4  # 3-node triangle / 4-node tetrahedron
    etags, enodes = gmsh.model.mesh.getElementsByType(etype)
    tags = np.asarray(tags, np.int64)
    X = np.asarray(coords, float).reshape(-1, 3)[:, :dim]
    conn = np.asarray(enodes, np.int64).reshape(-1, dim + 1)
    # gmsh node tags -> compact 0-based numbering of the nodes the cells use
    lookup = np.full(int(tags.max(initial=0)) + 1, -1, np.int64)
    lookup[tags] = np.arange(tags.size)
    idx = lookup[conn]
    # 3D mirror: gmsh meshed the halves' surfaces symmetrically, the volumes are mirrored here
    X, idx = mirror_volumes(gmsh, regions, pairs, tags, X, idx, np.asarray(etags, np.int64))
    used, inv = np.unique(idx, return_inverse=True)
    return X[used], inv.reshape(idx.shape).astype(INDEX)
