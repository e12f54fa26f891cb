"""Resource guards: the cells, unknowns, time steps and memory a case will need, estimated from
the case file before any work starts, and refused when beyond the machine or sane bounds.

The estimates are rough (within a factor 2 of the built-in meshes, tests/unit/setup/test_limits.py) but
cheap: cells from the domain's measure and the mesh sizes (a graded simplicial mesh has about
c_d/h(r)^d cells per unit measure, h growing from the fracture size by ``grading`` per unit
distance r from the fracture; a corner-point grid's nx·ny·nz from its header or ``mesh.cells``,
times ``mesh.refine``), memory from measured bytes per cell of the built-in runs. They
only have to tell a run that fits from one that tries to allocate terabytes (``time.step =
1e-12`` over a year, ``convergence --levels 30``). A mesh file's cells are not estimated.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from ..core.errors import InputError
from ..mesh.generators.fronts import RING_RADIUS, SECTORS, graded_count, ring_radii
from .generators import REGISTRY, resolve

FLAG = "--no-limits"
MAX_STEPS = 1_000_000            # time steps of one run
# cells per unit area (volume) of a mesh of size h: c_d / h^d (equilateral triangles, regular tetrahedra)
CELLS_PER_SIZE = {2: 4 / math.sqrt(3), 3: 6 * math.sqrt(2)}
# peak bytes per cell of a run (measured: C5 at 127k tetrahedra 2.5 GB, C4 at 3k triangles ~200 MB
# of which most is the interpreter and libraries)
BYTES_PER_CELL = {2: 5e3, 3: 2e4}
BASE_BYTES = 3e8                 # the interpreter, numpy, scipy, gmsh
NODES_PER_CELL = {2: 0.5, 3: 0.2}
# quadratic displacements (mechanics.order = 2, or "auto" on 3D tetrahedra with fractures): vertex and
# edge slots per cell, and the peak bytes per cell relative to order 1 (measured on C5 at 5.4k
# tetrahedra: 26.7k displacement unknowns against 5.2k, 890 MB against 430 MB; docs/defaults.md)
P2_SLOTS_PER_CELL = {2: 2.0, 3: 1.6}
P2_BYTES_FACTOR = 5.0
FACES_PER_CELL = {2: 1.5, 3: 2.0}
TIP_RADIUS = 4.0                 # polypore.mesh.generators.simplicial.TIP_RADIUS (importing it loads gmsh)


def machine_memory() -> float:
    """Total physical memory of the machine (bytes); inf if the system does not say."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return math.inf


@dataclass(frozen=True)
class Estimate:
    """What a run of a case needs, roughly.

    Attributes
    ----------
    cells : float
        Cells of the mesh (inf: beyond any machine; NaN: unknown, a mesh file).
    field : str
        The case field that sets the cell count (``mesh.size``, ``mesh.fracture_size`` ...).
    unknowns : float
    steps : float
        Time steps (1 for a static or steady run).
    memory : float
        Peak memory, bytes.
    """

    cells: float
    field: str
    unknowns: float
    steps: float
    memory: float


def _band(measure: float, perimeter: float, h: float, size: float, grading: float, d: int,
          volume: float) -> float:
    """Cells in the zone around a fracture (length or area ``measure``, perimeter in 3D) where the
    size grows from h to ``size`` by ``grading`` per unit distance r, beyond the cells of size
    ``size`` it replaces: ∫ c_d dV(r) / (h + g r)^d with the shells dV of the Steiner formula
    (a slab near the fracture, a ball far from it), the zone cut where it would outgrow the domain."""
    if h >= size:
        return 0.0
    c = CELLS_PER_SIZE[d]

    def grown(r):   # measure of the set of points within r of the fracture
        return 2 * measure * r + math.pi * r * r if d == 2 else \
            2 * measure * r + math.pi / 2 * perimeter * r * r + 4 / 3 * math.pi * r ** 3

    def shell(r):
        return 2 * measure + 2 * math.pi * r if d == 2 else 2 * measure + math.pi * perimeter * r + 4 * math.pi * r * r

    R = (size - h) / grading
    if grown(R) > volume:
        lo, hi = 0.0, R
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if grown(mid) < volume else (lo, mid)
        R = hi
    # trapezoid rule on r = R x^2 (fine steps near the fracture, where the integrand peaks)
    n = 200
    rs = [R * (k / n) ** 2 for k in range(n + 1)]
    f = [c * shell(r) / (h + grading * r) ** d for r in rs]
    cells = sum(0.5 * (f[k] + f[k + 1]) * (rs[k + 1] - rs[k]) for k in range(n))
    return max(cells - c * grown(R) / size ** d, 0.0)


def _tips(measure: float, h: float, d: int, tip_size: float, gamma: float) -> float:
    """Cells of the graded zone around tip points (2D, ``measure`` their number) or tip lines
    (3D, their length): h(r) = max(tip_size, h (r/R)^gamma) for r < R = TIP_RADIUS h, so
    ∫ c 2π r / h(r)^d dr = 2π c [r0²/(2 tip_size^d) + R^(dγ)/h^d ∫_r0^R r^(1-dγ) dr] with r0 where
    the floor starts; halved in 3D (the cap at the fracture size cuts the zone). For γ = 1/2 and
    a fine floor this is 2π c R²/h² per tip (2D), 2π c R²/h³ per unit tip length (3D)."""
    R = TIP_RADIUS * h
    r0 = R * (min(tip_size, h) / h) ** (1.0 / gamma)
    p = 2.0 - d * gamma
    outer = math.log(R / r0) if abs(p) < 1e-12 else (R ** p - r0 ** p) / p
    per_tip = r0 ** 2 / (2 * tip_size ** d) + R ** (d * gamma) / h ** d * outer
    return CELLS_PER_SIZE[d] * 2 * math.pi * measure * per_tip * (0.5 if d == 3 else 1.0)


def _front_tubes(edges, h: float, tip_size: float, gamma: float) -> float:
    """Cells of the anisotropic crack-front tubes (``mesh.front = "anisotropic"``,
    mesh/generators/fronts.py) along the fracture edges of lengths ``edges``: a ring of K squares
    of SECTORS points (2 SECTORS K triangles) swept in the layers the generator places along each
    edge (:func:`~polypore.mesh.generators.fronts.graded_count`, graded towards the corners
    and floored at tip_size: at tip_size = 1e-7 m over 1500 layers per edge, where a spacing of
    ``h`` would say 2), each prism split into 3 tetrahedra. The slab's core and the fill's first
    cells next to the tubes add 80 % (calibrated on cube-slip-3d's meshes: the whole estimate
    within 1.1–1.5× of the cells made, tests/unit/setup/test_limits.py)."""
    rho = RING_RADIUS * h
    tip = min(tip_size, rho)
    K = len(ring_radii(rho, tip, gamma))
    # counted, not made: a fracture edge of 1e9 m would otherwise allocate its 1e10 layers here
    layers = sum(graded_count(e, h, rho, gamma, tip) for e in edges if e > 0)
    return 1.8 * 3 * 2 * SECTORS * K * layers


def _length(points) -> float:
    return sum(math.dist(a, b) for a, b in zip(points, points[1:]))


def _area(points) -> float:
    """Area of a planar polygon in 3D."""
    c = [sum(p[i] for p in points) / len(points) for i in range(3)]
    area = [0.0, 0.0, 0.0]
    for a, b in zip(points, points[1:] + points[:1]):
        u = [a[i] - c[i] for i in range(3)]
        v = [b[i] - c[i] for i in range(3)]
        area = [area[0] + (u[1] * v[2] - u[2] * v[1]) / 2, area[1] + (u[2] * v[0] - u[0] * v[2]) / 2,
                area[2] + (u[0] * v[1] - u[1] * v[0]) / 2]
    return math.sqrt(sum(a * a for a in area))


def _fractures(spec, d: int):
    """(measure, tip measure, shortest edge, edge lengths) of each fracture: 2D lengths and 2 tip
    points, 3D areas and perimeters; the mesh resolves every edge, so no cell on a fracture is
    larger than its shortest edge."""
    out = []
    for f in spec.fractures:
        if f.radius is not None:
            n = f.sides
            edge = 2 * f.radius * math.sin(math.pi / n)
            out.append((0.5 * n * f.radius ** 2 * math.sin(2 * math.pi / n), n * edge, edge, (edge,) * n))
        elif f.vertices is not None:
            V = [list(p) for p in f.vertices]
            ring = V if d == 2 else V + V[:1]
            edges = tuple(math.dist(a, b) for a, b in zip(ring, ring[1:]))
            edge = min(edges, default=math.inf)
            out.append((_length(V), 2.0, edge, edges) if d == 2 else (_area(V), _length(ring), edge, edges))
    return out


def estimate_cells(spec) -> tuple[float, str]:
    """(cells, the field that sets them) of a case's mesh; NaN cells for a mesh file, inf when
    the count overflows."""
    try:
        return _cells(spec)
    except (OverflowError, ZeroDivisionError):   # sizes so small that h^d underflows
        return math.inf, "mesh.size"


def grdecl_header_dims(path, max_lines: int = 1_000_000):
    """(nx, ny, nz) of the SPECGRID (or DIMENS) record of a GRDECL file, read from its first
    ``max_lines`` lines (not from INCLUDE files); None when not found there."""
    kw = None
    words: list = []
    try:
        with open(path, errors="replace") as fh:
            for n, line in enumerate(fh):
                if n >= max_lines:
                    return None
                line = line.split("--", 1)[0]
                if kw is None:
                    w = line.strip().upper()
                    if w in ("SPECGRID", "DIMENS"):
                        kw = w
                    continue
                words += line.replace("/", " / ").split()
                if "/" in words or len(words) >= 3:
                    break
    except OSError:
        return None
    try:
        dims = tuple(int(w) for w in words[:3])
    except ValueError:
        return None
    return dims if len(dims) == 3 and min(dims) >= 1 else None


def _cells(spec) -> tuple[float, str]:
    return resolve(REGISTRY[spec.mesh.generator].estimate)(spec)


# ---- each generator's estimate (setup/generators.py): spec -> (cells, the field that sets them) --
def _refine_factor(m) -> tuple[int, str | None]:
    refine = math.prod(getattr(m, "refine", None) or (1, 1, 1))
    return refine, ("mesh.refine" if refine > 1 else None)


def cells_grdecl(spec) -> tuple[float, str]:
    """nx·ny·nz of the file's header (unknown in an INCLUDE file: NaN), times the refinement."""
    from .meshing import grdecl_path

    m = spec.mesh
    refine, rfield = _refine_factor(m)
    try:
        dims = grdecl_header_dims(grdecl_path(m.file, spec.base_dir))
    except InputError:
        dims = None
    return (math.nan if dims is None else float(math.prod(dims)) * refine), rfield or "mesh.file"


def cells_file(spec) -> tuple[float, str]:
    """A mesh file's count is known once it is read: NaN."""
    return math.nan, "mesh.file"


def cells_cornerpoint(spec) -> tuple[float, str]:
    """At most nx·ny·nz (inactive and pinched-out cells are left out), times the refinement."""
    m = spec.mesh
    refine, rfield = _refine_factor(m)
    return float(math.prod(m.cells)) * refine, rfield or "mesh.cells"


def cells_cartesian(spec) -> tuple[float, str]:
    m = spec.mesh
    if m.cells is not None:
        return float(math.prod(m.cells)), "mesh.cells"
    extent = [hi - lo for lo, hi in zip(m.lower, m.upper)]
    return float(math.prod(max(1, math.ceil(e / m.size)) for e in extent)), "mesh.size"


def cells_voronoi(spec) -> tuple[float, str]:
    m = spec.mesh
    return math.prod(hi - lo for lo, hi in zip(m.lower, m.upper)) / m.size ** len(m.lower), "mesh.size"


def cells_simplicial(spec) -> tuple[float, str]:
    """The bulk at ``size`` plus the bands graded from the fractures and, with ``tip_size``, the
    tips' or fronts' refinement."""
    m = spec.mesh
    d = len(m.lower)
    volume = math.prod(hi - lo for lo, hi in zip(m.lower, m.upper))
    size = m.size
    h = m.fracture_size or size
    parts = {"mesh.size": CELLS_PER_SIZE[d] * volume / size ** d, "mesh.fracture_size": 0.0, "mesh.tip_size": 0.0}
    for measure, tips, edge, edges in _fractures(spec, d):
        hf = max(min(h, edge), 1e-300)
        parts["mesh.fracture_size"] += _band(measure, tips, hf, size, m.grading, d, volume)
        if m.generator == "simplicial" and getattr(m, "front", "isotropic") == "anisotropic" and m.tip_size:
            parts["mesh.tip_size"] += _front_tubes(edges, hf, m.tip_size, m.tip_grading)
        elif m.generator == "simplicial" and getattr(m, "tip_size", None) is not None and m.tip_size < hf < size:
            parts["mesh.tip_size"] += _tips(tips, hf, d, m.tip_size, m.tip_grading)
    return sum(parts.values()), max(parts, key=parts.get)


def cells_agglomerated(spec) -> tuple[float, str]:
    """A simplicial mesh of half the sizes, merged pairwise per round."""
    cells, field = cells_simplicial(spec)
    d = len(spec.mesh.lower)
    return cells * 2 ** d / 2 ** spec.mesh.rounds, field


def estimate(spec, levels: int = 1) -> Estimate:
    """Cells, unknowns, steps and memory of a run of ``spec`` (validated case); with ``levels`` > 1,
    of the finest mesh of a convergence study (each level halves the mesh sizes)."""
    cells, field = estimate_cells(spec)
    d = spec.mesh.dim or 2
    if levels > 1:
        cells *= 2.0 ** (d * (levels - 1)) if levels - 1 < 1000 else math.inf
        field = "--levels"
    model = spec.physics
    quadratic = model != "flow" and _quadratic(spec, d)
    mech = d * (P2_SLOTS_PER_CELL if quadratic else NODES_PER_CELL)[d] * cells if model != "flow" else 0.0
    flow = (1 + FACES_PER_CELL[d]) * cells if model != "mechanics" else 0.0
    steps = 1.0
    t = spec.time
    if t is not None and model != "mechanics":
        steps = math.ceil((t.end - t.start) / t.step) if (t.end - t.start) / t.step < 1e300 else math.inf
        steps += len(t.output_times or ())
    memory = (BASE_BYTES + BYTES_PER_CELL[d] * cells * (P2_BYTES_FACTOR if quadratic else 1.0)
              + 2e3 * steps)   # a summary row per step
    return Estimate(cells, field, mech + flow, steps, memory)


def _quadratic(spec, d: int) -> bool:
    """Whether the run will use quadratic displacements: order 2 given, or "auto" on a 3D simplicial
    mesh with fractures (setup/mechanics.py, resolve_order; decided on the mesh, foreseen here)."""
    order = spec.mechanics.order if spec.mechanics is not None else "auto"
    if order != "auto":
        return order == 2
    from ..solvers.linear import pardiso_solves      # "auto" takes order 2 with PARDISO only

    return (d == 3 and getattr(spec.mesh, "generator", None) == "simplicial" and bool(spec.fractures)
            and pardiso_solves(spec.solver.linear if spec.solver is not None else None))


def check_limits(spec, levels: int = 1, *, memory: float | None = None, max_steps: float | None = None,
                 max_cells: float = math.inf) -> Estimate:
    """The estimate of :func:`estimate`; InputError naming the field (and the override flag) when
    the run needs more memory than ``memory`` (default: the machine's), more than ``max_steps``
    (default :data:`MAX_STEPS`) time steps or more than ``max_cells`` cells."""
    est = estimate(spec, levels)
    memory = machine_memory() if memory is None else memory
    max_steps = MAX_STEPS if max_steps is None else max_steps
    override = f"; {FLAG} runs it anyway"
    if est.steps > max_steps:
        t = spec.time
        raise InputError("time.step", f"{t.step:g} s from {t.start:g} to {t.end:g} s is {est.steps:.3g} time steps; "
                         f"allowed: at most {max_steps:,.0f} (a larger time.step){override}")
    if est.cells > max_cells:
        raise InputError(est.field, f"the mesh would have about {est.cells:.3g} cells; allowed here: at most "
                         f"{max_cells:,.0f}{override}")
    if est.memory > memory:
        raise InputError(est.field, f"the run would need about {_bytes(est.memory)} (about {est.cells:.3g} cells, "
                         f"{est.unknowns:.3g} unknowns); "
                         f"this machine has {_bytes(memory)}; allowed: coarser meshes{override}")
    return est


def _bytes(b: float) -> str:
    if not math.isfinite(b):
        return "an unbounded amount of memory"
    for unit in ("B", "KB", "MB", "GB", "TB", "PB"):
        if b < 1024:
            return f"{b:.3g} {unit}"
        b /= 1024
    return f"{b:.3g} EB"
