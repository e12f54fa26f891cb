"""From a case's ``[mesh]``, ``[[fractures]]`` and ``[[regions]]`` tables to a FracturedMesh.

Schema (all lengths in m)::

    [mesh]
    generator = "simplicial"   # cartesian | simplicial | voronoi | agglomerated | file
    lower = [-1, -1, -1]       # box domain (not for "file")
    upper = [1, 1, 1]
    size = 0.25                # target cell size (cartesian may give `cells` instead)
    cells = [8, 8, 8]          # cartesian only: cells per direction
    fracture_size = 0.1        # simplicial/agglomerated: size on fractures (default: size)
    grading = 0.4              # simplicial/agglomerated: size growth per unit distance from the fractures
    tip_size = 0.001           # simplicial: size at crack tips (2D) / tip lines (3D) (default: none)
    mirror = "none"            # simplicial: "tips" (2D) | "fractures" (2D, 3D): mesh symmetric about the fracture
                               #   line around each tip / along each straight fracture (λ_n free of
                               #   crack-tip error with two-sided bubbles)
    rounds = 2                 # agglomerated: rounds of pairwise merging
    perturb = 0.0              # random node perturbation, fraction of the local edge length
    seed = 0
    file = "mesh.msh"          # file only (relative to the case file)

    [[fractures]]
    name = "F1"
    vertices = [[x, y(, z)], ...]   # 2D polyline / 3D planar polygon, or in 3D a regular polygon:
    centre = [x, y, z]              #   centre, circumradius, number of sides (default 6) and normal
    radius = 0.12
    sides = 6
    normal = [0, 0, 1]              # 3D, optional: direction of n^+
    group = "F1"                    # file meshes: the physical group (default: name)

    [[regions]]                     # optional material regions (cells by centroid)
    name = "reservoir"
    lower = [...]
    upper = [...]

    [[boundaries]]                  # optional extra boundary parts: the faces of part `on` whose
    name = "injection"              # centroid lies in the box (e.g. the reservoir's face on xmin)
    on = "xmin"
    lower = [...]
    upper = [...]
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..mesh import FracturedMesh, FractureSpec
from ..mesh.generators.mirror import MODES as MIRROR_MODES
from ..mesh.mesh import with_boundary_parts, with_regions
from .casefile import CaseFile, Section

log = logging.getLogger("polypore")

GENERATORS = ("cartesian", "simplicial", "voronoi", "agglomerated", "file")


def _fracture_specs(root: Section, dim: int, file_mesh: bool):
    specs, groups = [], {}
    for sec in root.sections("fractures"):
        name = sec.string("name")
        if file_mesh:
            groups[name] = sec.string("group", name)
            normal = sec.vector("normal", dim, None)
            specs.append((name, normal))
        elif dim == 3 and sec.has("radius"):
            normal = np.asarray(sec.vector("normal", 3))
            V = regular_polygon(np.asarray(sec.vector("centre", 3)), sec.number("radius", positive=True),
                                normal, sec.number("sides", 6, integer=True, lo=2), sec.field("normal"))
            specs.append(FractureSpec(name, V, normal))
        else:
            V = np.asarray(sec.points("vertices", dim))
            normal = sec.vector("normal", 3, None) if dim == 3 else None
            specs.append(FractureSpec(name, V, None if normal is None else np.asarray(normal)))
        sec.done()
    return specs, groups


def regular_polygon(centre, radius, normal, sides, field="normal") -> np.ndarray:
    """(sides, 3) vertices of a regular polygon; the first lies along normal × (e_z or e_x)."""
    n = np.asarray(normal, float)
    if not np.linalg.norm(n) > 0:
        raise InputError(field, "must be a non-zero vector")
    n = n / np.linalg.norm(n)
    ref = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(n, ref)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    th = 2 * np.pi * np.arange(sides) / sides
    return centre + radius * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)


def _regions(root: Section, dim: int):
    out = []
    for sec in root.sections("regions"):
        name = sec.string("name")
        lo = np.asarray(sec.vector("lower", dim))
        hi = np.asarray(sec.vector("upper", dim))
        if np.any(hi <= lo):
            raise InputError(sec.field("upper"), f"must exceed lower {lo.tolist()} in every direction, got {hi.tolist()}")
        out.append((name, lo, hi))
        sec.done()
    return out


def _interfaces(regions, lower, upper) -> list[FractureSpec]:
    """Sides of region boxes strictly inside the domain: the mesh must conform to them."""
    dim = lower.size
    out = []
    tol = 1e-12 * float(np.max(upper - lower))
    for name, lo, hi in regions:
        lo_c, hi_c = np.maximum(lo, lower), np.minimum(hi, upper)
        for k in range(dim):
            for val in (lo[k], hi[k]):
                if val <= lower[k] + tol or val >= upper[k] - tol:
                    continue
                if dim == 2:
                    j = 1 - k
                    V = np.zeros((2, 2))
                    V[:, k] = val
                    V[:, j] = [lo_c[j], hi_c[j]]
                else:
                    j, m = [a for a in range(3) if a != k]
                    V = np.zeros((4, 3))
                    V[:, k] = val
                    V[:, j] = [lo_c[j], hi_c[j], hi_c[j], lo_c[j]]
                    V[:, m] = [lo_c[m], lo_c[m], hi_c[m], hi_c[m]]
                out.append(FractureSpec(f"{name}:{'xyz'[k]}={val:g}", V))
    # the same plane from two adjacent regions: keep one
    uniq = {}
    for s in out:
        uniq.setdefault((tuple(np.round(s.vertices, 12).ravel())), s)
    return list(uniq.values())


def _boundary_parts(root: Section, fm: FracturedMesh) -> FracturedMesh:
    mesh = fm.mesh
    parts = {}
    for sec in root.sections("boundaries"):
        name = sec.string("name")
        if name in mesh.boundary or name in parts:
            raise InputError(sec.field("name"), f"boundary part {name!r} exists already; choose another name")
        on = sec.string("on")
        if on not in mesh.boundary:
            raise InputError(sec.field("on"), f"unknown boundary part {on!r}; this mesh has {sorted(mesh.boundary)}")
        lo = np.asarray(sec.vector("lower", mesh.dim))
        hi = np.asarray(sec.vector("upper", mesh.dim))
        faces = mesh.boundary[on]
        c = mesh.geometry.face_centroid[faces]
        sel = faces[np.all((c >= lo) & (c <= hi), axis=1)]
        if sel.size == 0:
            raise InputError(sec.field("lower"), f"no face of {on!r} has its centroid in the box {lo.tolist()} – "
                             f"{hi.tolist()}")
        parts[name] = sel
        sec.done()
    if not parts:
        return fm
    return FracturedMesh(with_boundary_parts(mesh, parts), fm.network, fm.sides)


def _assign_regions(fm: FracturedMesh, regions, field="regions") -> FracturedMesh:
    mesh = fm.mesh
    c = mesh.geometry.cell_centroid
    tag = np.full(mesh.n_cells, -1)
    count = np.zeros(mesh.n_cells, int)
    for i, (name, lo, hi) in enumerate(regions):
        inside = np.all((c >= lo) & (c <= hi), axis=1)
        tag[inside] = i
        count += inside
    if np.any(count == 0):
        k = int(np.flatnonzero(count == 0)[0])
        raise InputError(field, f"the regions do not cover the domain: {int(np.sum(count == 0))} cell(s) lie in no "
                         f"region, e.g. the cell at {np.round(c[k], 6).tolist()}; regions must tile Ω")
    if np.any(count > 1):
        k = int(np.flatnonzero(count > 1)[0])
        raise InputError(field, f"regions overlap at {np.round(c[k], 6).tolist()}; each cell must be in one region")
    mesh = with_regions(mesh, tag, [r[0] for r in regions])
    return FracturedMesh(mesh, fm.network, fm.sides)


def build_fractured_mesh(case: CaseFile) -> FracturedMesh:
    """Generate (or read) the case's mesh, map its fractures and compute node sides.

    Logs each stage with its wall time. Raises InputError for any bad field.
    """
    root = case.root()
    sec = root.section("mesh")
    gen = sec.string("generator", "simplicial", GENERATORS)
    seed = sec.number("seed", 0, integer=True, nonneg=True)
    amp = sec.number("perturb", 0.0, nonneg=True)
    if amp > 0.4:
        raise InputError(sec.field("perturb"), f"must be at most 0.4 (fraction of the local edge length), got {amp}")
    t0 = time.perf_counter()
    if gen == "file":
        from ..mesh.msh import read_msh

        fname = sec.string("file")
        path = Path(fname)
        if not path.is_absolute():
            path = Path(case.data.get("base_dir", ".")) / path
        mesh, groups_found = read_msh(str(path))
        dim = mesh.dim
        specs, groups = _fracture_specs(root, dim, True)
        named, normals = {}, {}
        for name, normal in specs:
            grp = groups[name]
            if grp not in groups_found:
                raise InputError(f"fractures.{name}.group", f"the mesh file {str(path)!r} has no interior physical "
                                 f"group {grp!r}; its fracture groups are {sorted(groups_found)}")
            named[name] = groups_found[grp]
            normals[name] = normal
        sec.done(ignore=("lower", "upper"))
        log.info("read %s (%d cells) in %.2f s", path, mesh.n_cells, time.perf_counter() - t0)
        fm = FracturedMesh.from_faces(mesh, named, normals)
        regions = _regions(root, dim)
        if regions:
            fm = _assign_regions(fm, regions)
        return _boundary_parts(root, fm)

    lower = np.asarray(sec.vector("lower"))
    dim = lower.size
    if dim not in (2, 3):
        raise InputError(sec.field("lower"), f"must have 2 or 3 coordinates, got {lower.tolist()}")
    upper = np.asarray(sec.vector("upper", dim))
    if np.any(upper <= lower):
        raise InputError(sec.field("upper"), f"must exceed lower {lower.tolist()} in every direction, got {upper.tolist()}")
    specs, _ = _fracture_specs(root, dim, False)
    regions = _regions(root, dim)
    interfaces = _interfaces(regions, lower, upper)
    if gen == "cartesian":
        from ..mesh.generators.cartesian import cartesian_mesh, grid_coordinates

        if sec.has("cells"):
            cells = sec.vector("cells", dim)
            sec.raw("size", None)  # `cells` takes precedence over a size inherited from the case
            if any(c < 1 or int(c) != c for c in cells):
                raise InputError(sec.field("cells"), f"must be positive integers, got {cells}")
        else:
            size = sec.number("size", positive=True)
            cells = [max(1, int(np.ceil((upper[k] - lower[k]) / size))) for k in range(dim)]
        include = [set() for _ in range(dim)]
        for s in list(specs) + interfaces:
            for k in range(dim):
                include[k].update(np.asarray(s.vertices)[:, k].tolist())
        axes = [grid_coordinates(lower[k], upper[k], int(cells[k]), sorted(include[k])) for k in range(dim)]
        mesh = cartesian_mesh(axes)
    elif gen == "simplicial":
        from ..mesh.generators.simplicial import simplicial_mesh

        size = sec.number("size", positive=True)
        fsize = sec.number("fracture_size", size, positive=True)
        grading = sec.number("grading", 0.4, positive=True)
        tip = sec.number("tip_size", None, positive=True)
        mirror = sec.string("mirror", "none", MIRROR_MODES)
        mesh = simplicial_mesh(lower, upper, specs, size, fracture_size=fsize, interfaces=interfaces, seed=seed,
                               grading=grading, tip_size=tip, mirror=mirror)
    elif gen == "voronoi":
        from ..mesh.generators.voronoi import voronoi_mesh

        size = sec.number("size", positive=True)
        mesh = voronoi_mesh(lower, upper, size, list(specs) + interfaces, seed=seed)
    else:  # agglomerated
        from ..mesh import build_network
        from ..mesh.generators.agglomerate import agglomerate
        from ..mesh.generators.simplicial import simplicial_mesh

        size = sec.number("size", positive=True)
        fsize = sec.number("fracture_size", size, positive=True)
        rounds = sec.number("rounds", 2, integer=True, nonneg=True)
        grading = sec.number("grading", 0.4, positive=True)
        base = simplicial_mesh(lower, upper, specs, size / 2, fracture_size=fsize / 2, interfaces=interfaces, seed=seed,
                               grading=grading)
        keep = build_network(base, list(specs) + interfaces).faces
        mesh = agglomerate(base, keep, rounds=rounds, seed=seed)
    log.info("%s mesh generator: %d cells in %.2f s", gen, mesh.n_cells, time.perf_counter() - t0)
    if amp > 0:
        from ..mesh.generators.perturb import perturb

        mesh = perturb(mesh, amp, list(specs) + interfaces, seed=seed)
    sec.done()
    t1 = time.perf_counter()
    fm = FracturedMesh.build(mesh, specs)
    log.info("mapped %d fracture(s) (%d faces) and %d node sides in %.2f s", len(specs), fm.network.n_faces,
             fm.sides.n_sides, time.perf_counter() - t1)
    if regions:
        fm = _assign_regions(fm, regions)
    return _boundary_parts(root, fm)
