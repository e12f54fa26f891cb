"""From a case's ``[mesh]``, ``[[fractures]]``, ``[[regions]]`` and ``[[boundaries]]`` tables to a
:class:`~polypore.mesh.FracturedMesh`.

The tables, their keys and defaults are in :mod:`polypore.setup.schema.geometry`; an example
(all lengths in m)::

    [mesh]
    generator = "simplicial"   # cartesian | simplicial | voronoi | agglomerated | file
    lower = [-1, -1, -1]       # box domain (not for "file")
    upper = [1, 1, 1]
    size = 0.25                # target cell size (cartesian may give `cells` instead)
    fracture_size = 0.1        # simplicial/agglomerated: size on fractures (default: size)

    [[fractures]]
    name = "F1"
    vertices = [[x, y(, z)], ...]   # 2D polyline / 3D planar polygon, or in 3D a regular polygon:
    # centre = [x, y, z], radius = 0.12, sides = 6, normal = [0, 0, 1]

    [[regions]]                     # optional material regions (cells by centroid)
    name = "reservoir"
    lower = [...]
    upper = [...]

    # or a corner-point grid (docs/cornerpoint.md): generator = "grdecl" with file = "model.grdecl",
    # or generator = "cornerpoint" with cells, extent, top, dip and [[mesh.faults]]; its boundary
    # parts are west, east, south, north, top, bottom (and internal), and [[fractures]] select faults:
    # name = "F1", fault = "F1" (default: the name); unselected faults stay bonded; pillar_angle = 60.0
    # tilts the outermost pillars 60° from vertical (fanning out along x); refine = [ni, nj, nk]
    # splits every grid cell along its pillars (mesh/cornerpoint/refine.py)

    [[boundaries]]                  # optional extra boundary parts: the faces of part `on` whose
    name = "injection"              # centroid lies in the box (e.g. the reservoir's face on xmin)
    on = "xmin"
    lower = [...]
    upper = [...]

Here the mesh is built and what needs it is checked: fractures inside the domain and
conforming, regions that tile Ω, boundary parts that exist and select faces.
"""

from __future__ import annotations

import dataclasses
import difflib
import logging
import time
import weakref
from pathlib import Path

import numpy as np

from ..core import live
from ..core.errors import InputError
from ..core.memory import trim_heap
from ..mesh import FracturedMesh, FractureSpec
from ..mesh.mesh import with_boundary_parts, with_regions
from .casefile import CaseFile
from .generators import REGISTRY, resolve
from .translate import CORNERPOINT, MESH, case_keys

log = logging.getLogger("polypore")


def _fracture_specs(case) -> list[FractureSpec]:
    """The fractures of a generated mesh (the schema checked their dimension)."""
    specs = []
    for f in case.fractures:
        normal = None if f.normal is None else np.asarray(f.normal)
        if f.radius is not None:
            V = regular_polygon(np.asarray(f.centre), f.radius, normal, f.sides, f"fractures.{f.name}.normal")
        else:
            V = np.asarray(f.vertices)
        specs.append(FractureSpec(f.name, V, normal))
    return specs


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


def _regions(case, dim: int):
    out = []
    for r in case.regions:
        if len(r.lower) != dim:
            raise InputError(f"regions.{r.name}.lower", f"must have {dim} coordinates (the mesh is {dim}D), got "
                             f"{r.lower}")
        out.append((r.name, np.asarray(r.lower), np.asarray(r.upper)))
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


def _boundary_parts(case, fm: FracturedMesh) -> FracturedMesh:
    mesh = fm.mesh
    parts = {}
    for b in case.boundaries:
        field = f"boundaries.{b.name}"
        if b.name in mesh.boundary:
            raise InputError(f"{field}.name", f"boundary part {b.name!r} exists already; choose another name")
        if b.on not in mesh.boundary:
            raise InputError(f"{field}.on", f"unknown boundary part {b.on!r}; this mesh has {sorted(mesh.boundary)}")
        if len(b.lower) != mesh.dim:
            raise InputError(f"{field}.lower", f"must have {mesh.dim} coordinates (the mesh is {mesh.dim}D), got "
                             f"{b.lower}")
        lo, hi = np.asarray(b.lower), np.asarray(b.upper)
        faces = mesh.boundary[b.on]
        c = mesh.geometry.face_centroid[faces]
        sel = faces[np.all((c >= lo) & (c <= hi), axis=1)]
        if sel.size == 0:
            raise InputError(f"{field}.lower", f"no face of {b.on!r} has its centroid in the box {lo.tolist()} – "
                             f"{hi.tolist()}")
        parts[b.name] = sel
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

    Logs each stage with its wall time. Raises InputError for any bad field. In a distributed run
    (mpiexec) rank 0 builds it and broadcasts it to the other ranks (docs/parallel.md: the mesh
    stays serial).
    """
    from ..parallel.context import context

    ctx = context()
    with live.phase("meshing"):
        if ctx is not None and ctx.size > 1:
            # the corner-point grid a mesh came from is held beside it (keyed by the mesh object),
            # so it travels with the mesh: without it the other ranks refused "grdecl" values and
            # waited for rank 0 forever
            fm, cp, refine = ctx.bcast_call(_with_side_tables, case)
            if cp is not None:
                _CORNERPOINT[fm.mesh] = cp
            if refine is not None:
                _REFINED[fm.mesh] = refine
        else:
            fm = _build_fractured_mesh(case)
    trim_heap()                 # the mesh generator's and the broadcast's temporaries (core/memory.py)
    return fm


def _with_side_tables(case: CaseFile):
    """(fm, cornerpoint_of(fm.mesh), its refinement or None): what rank 0 broadcasts."""
    fm = _build_fractured_mesh(case)
    return fm, _CORNERPOINT.get(fm.mesh), _REFINED.get(fm.mesh)


@case_keys(MESH)          # the mesh layer's parameter names -> mesh.*, fractures.* keys
def _build_fractured_mesh(case: CaseFile) -> FracturedMesh:
    spec = case.spec
    m = spec.mesh
    t0 = time.perf_counter()
    gen = REGISTRY[m.generator]
    if not gen.box:
        return resolve(gen.build)(case, spec, t0)
    lower, upper = np.asarray(m.lower), np.asarray(m.upper)
    dim = lower.size
    specs = _fracture_specs(spec)
    regions = _regions(spec, dim)
    interfaces = _interfaces(regions, lower, upper)
    mesh = resolve(gen.build)(m, lower, upper, specs, interfaces)
    log.info("%s mesh generator: %d cells in %.2f s", m.generator, mesh.n_cells, time.perf_counter() - t0)
    if m.perturb > 0:
        from ..mesh.generators.perturb import perturb

        mesh = perturb(mesh, m.perturb, list(specs) + interfaces, seed=m.seed)
    t1 = time.perf_counter()
    fm = FracturedMesh.build(mesh, specs)
    log.info("mapped %d fracture(s) (%d faces) and %d node sides in %.2f s", len(specs), fm.network.n_faces,
             fm.sides.n_sides, time.perf_counter() - t1)
    if regions:
        fm = _assign_regions(fm, regions)
    return _boundary_parts(spec, fm)


# ---- the box generators' builders (setup/generators.py): (mesh table, lower, upper, fracture
# specs, region interfaces) -> Mesh -------------------------------------------------------------
def build_cartesian(m, lower, upper, specs, interfaces):
    from ..mesh.generators.cartesian import cartesian_mesh, grid_coordinates

    dim = lower.size
    if m.cells is not None:   # `cells` takes precedence over a size inherited from the case
        cells = [int(c) for c in m.cells]
    else:
        cells = [max(1, int(np.ceil((upper[k] - lower[k]) / m.size))) for k in range(dim)]
    include = [set() for _ in range(dim)]
    for s in list(specs) + interfaces:
        for k in range(dim):
            include[k].update(np.asarray(s.vertices)[:, k].tolist())
    axes = [grid_coordinates(lower[k], upper[k], cells[k], sorted(include[k])) for k in range(dim)]
    return cartesian_mesh(axes)


def build_simplicial(m, lower, upper, specs, interfaces):
    if m.front == "anisotropic":
        from ..mesh.generators.fronts import front_mesh

        return front_mesh(lower, upper, specs, m.size, fracture_size=m.fracture_size or m.size,
                          interfaces=interfaces, tip_size=m.tip_size, tip_grading=m.tip_grading, grading=m.grading,
                          seed=m.seed)
    from ..mesh.generators.simplicial import simplicial_mesh

    return simplicial_mesh(lower, upper, specs, m.size, fracture_size=m.fracture_size or m.size,
                           interfaces=interfaces, seed=m.seed, grading=m.grading, tip_size=m.tip_size,
                           tip_grading=m.tip_grading, mirror=m.mirror)


def build_voronoi(m, lower, upper, specs, interfaces):
    from ..mesh.generators.voronoi import voronoi_mesh

    return voronoi_mesh(lower, upper, m.size, list(specs) + interfaces, seed=m.seed)


def build_agglomerated(m, lower, upper, specs, interfaces):
    from ..mesh import build_network
    from ..mesh.generators.agglomerate import agglomerate
    from ..mesh.generators.simplicial import simplicial_mesh

    fsize = m.fracture_size or m.size
    base = simplicial_mesh(lower, upper, specs, m.size / 2, fracture_size=fsize / 2, interfaces=interfaces,
                           seed=m.seed, grading=m.grading)
    keep = build_network(base, list(specs) + interfaces).faces
    return agglomerate(base, keep, rounds=m.rounds, seed=m.seed)


# ---- the generators that bring their own geometry: (case, spec, t0) -> FracturedMesh ------------
def build_file(case: CaseFile, spec, t0: float) -> FracturedMesh:
    """A Gmsh file's mesh; its fractures are interior physical groups."""
    from ..mesh.msh import read_msh

    path = Path(spec.mesh.file)
    if not path.is_absolute():
        path = Path(spec.base_dir or ".") / path
    from ..parallel.context import context

    mesh, groups_found = read_msh(str(path), isolate=context() is None)   # no fork under MPI
    dim = mesh.dim
    named, normals = {}, {}
    for f in spec.fractures:
        grp = f.group or f.name
        if grp not in groups_found:
            raise InputError(f"fractures.{f.name}.group", f"the mesh file {str(path)!r} has no interior physical "
                             f"group {grp!r}; its fracture groups are {sorted(groups_found)}")
        if f.normal is not None and len(f.normal) != dim:
            raise InputError(f"fractures.{f.name}.normal", f"must have {dim} components (the mesh is {dim}D), got "
                             f"{f.normal}")
        named[f.name] = groups_found[grp]
        normals[f.name] = f.normal
    log.info("read %s (%d cells) in %.2f s", path, mesh.n_cells, time.perf_counter() - t0)
    fm = FracturedMesh.from_faces(mesh, named, normals)
    regions = _regions(spec, dim)
    if regions:
        fm = _assign_regions(fm, regions)
    return _boundary_parts(spec, fm)


# -- corner-point grids --------------------------------------------------------------------------
_CORNERPOINT: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_REFINED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def cornerpoint_of(mesh):
    """(CornerPointGrid, CornerPointInfo) the mesh was processed from, or None (not a corner-point mesh).

    The info's cells are the mesh's cells; its ``faults`` are every fault of the grid.
    """
    return _CORNERPOINT.get(mesh)


def grdecl_path(file: str, base_dir: str | None) -> Path:
    """The GRDECL file of ``mesh.file``: absolute, or relative to the case file's folder
    ``base_dir``; a built-in case (no folder) takes it from the package's case data, where
    its grids are shipped, and so does a copy of a built-in case (its ``case.toml`` in a results
    folder) when the folder has no such file. InputError naming ``mesh.file`` if it does not exist."""
    from importlib import resources

    from .casefile import CASES, DATA

    path = Path(file)
    if path.is_absolute():
        candidates = [path]
    else:
        shipped = Path(str(resources.files(CASES) / DATA)) / path
        candidates = [shipped] if base_dir is None else [Path(base_dir) / path, shipped]
    for c in candidates:
        if c.is_file():
            return c
    from ..core.paths import not_a_file

    why = not_a_file(candidates[0]) or "does not exist"
    raise InputError("mesh.file", f"GRDECL file {str(candidates[0])!r} {why} (a relative path is taken from the case "
                     "file's folder)")


def cornerpoint_refinement(mesh) -> tuple[int, int, int]:
    """(r_i, r_j, r_k) of ``mesh.refine`` the corner-point mesh was built with ((1, 1, 1) if none):
    the grid of :func:`cornerpoint_of` is the refined one, the case's cell indices (wells) are
    the file's."""
    return _REFINED.get(mesh, (1, 1, 1))


def _cornerpoint_grid(spec):
    """The case's corner-point grid: read from the GRDECL file or generated, then refined by
    ``mesh.refine``."""
    from ..mesh.cornerpoint import FaultSpec, generate_grid, read_grdecl
    from ..mesh.cornerpoint.refine import refine_grid

    m = spec.mesh
    if m.generator == "grdecl":
        grid = read_grdecl(grdecl_path(m.file, spec.base_dir))
    else:
        nx, ny, nz = (int(c) for c in m.cells)
        faults = [FaultSpec(f.axis, int(f.index), float(f.throw), start=None if f.start is None else int(f.start),
                            stop=None if f.stop is None else int(f.stop), name=f.name) for f in m.faults]
        grid = generate_grid(nx, ny, nz, extent=tuple(m.extent), top=m.top, dip=m.dip, faults=faults,
                             pinchout=[int(k) - 1 for k in (m.pinchout or [])], inactive=m.inactive, seed=m.seed,
                             pillar_angle=float(m.pillar_angle),
                             layer_permeability=None if m.layer_permeability is None else list(m.layer_permeability))
    return refine_grid(grid, m.refine)


def _selected_faults(spec, info) -> dict:
    """[[fractures]] name -> fault faces, the faults they select (InputError naming the field)."""
    known = sorted(info.faults)
    out, taken = {}, {}
    for f in spec.fractures:
        fault = f.fault or f.name
        field = f"fractures.{f.name}.{'fault' if f.fault else 'name'}"
        if fault not in info.faults:
            lower = {k.lower(): k for k in known}
            close = [lower[c] for c in difflib.get_close_matches(fault.lower(), list(lower), n=1)]
            raise InputError(field, f"unknown fault {fault!r}" + (f" (did you mean {close[0]!r}?)" if close else "")
                             + f"; the grid's faults are {', '.join(known) or 'none'}")
        if fault in taken:
            raise InputError(field, f"fault {fault!r} is selected twice (by {taken[fault]!r} and {f.name!r})")
        taken[fault] = f.name
        out[f.name] = info.faults[fault]
    return out


def build_cornerpoint(case: CaseFile, spec, t0: float) -> FracturedMesh:
    """A corner-point grid's mesh; the faults named by [[fractures]] become contact surfaces."""
    from ..mesh.cornerpoint import fractured_mesh, process_grid

    m = spec.mesh
    grid = _cornerpoint_grid(spec)
    with case_keys(CORNERPOINT):
        mesh, info = process_grid(grid, nonplanar=m.nonplanar, regions=m.region_keyword, snap=m.snap)
    log.info("%s grid %s: %d active cells -> %d cells, %d faces; faults %s (%.2f s)", m.generator,
             "×".join(map(str, grid.dims)), info.n_active, mesh.n_cells, mesh.n_faces,
             {k: int(v.size) for k, v in info.faults.items()}, time.perf_counter() - t0)
    selected = _selected_faults(spec, info)
    fm = fractured_mesh(mesh, dataclasses.replace(info, faults=selected), list(selected))
    bonded = sorted(set(info.faults) - {f.fault or f.name for f in spec.fractures})
    if bonded:
        log.info("faults left bonded (not in [[fractures]]): %s", ", ".join(bonded))
    regions = _regions(spec, 3)
    if regions:
        fm = _assign_regions(fm, regions)
    fm = _boundary_parts(spec, fm)
    _CORNERPOINT[fm.mesh] = (grid, info)
    refine = tuple(int(r) for r in m.refine)
    if refine != (1, 1, 1):
        _REFINED[fm.mesh] = refine
    return fm
