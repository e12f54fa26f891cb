"""Schema of the geometry tables: ``[mesh]``, ``[[fractures]]``, ``[[regions]]``, ``[[boundaries]]``.

All lengths in m. Each generator reads its own keys of ``[mesh]`` (:data:`GENERATOR_KEYS`);
a key of another generator is an error rather than silently ignored.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from ..generators import REGISTRY
from .types import Expr, Positive, Table, Text, choice, fail, number, points, vector

# polypore.mesh.generators.mirror.MODES (importing it would load gmsh; tests/unit/setup/test_schema.py compares)
MIRROR_MODES = ("none", "tips", "fractures")
FRONTS = ("isotropic", "anisotropic")     # crack-front cells of the simplicial generator (3D)
CORNERPOINT = ("grdecl", "cornerpoint")   # corner-point grids (docs/cornerpoint.md): 3D, faults from the grid
NONPLANAR = ("centre", "diagonal", "keep")   # polypore.mesh.cornerpoint.process_grid(nonplanar=)
# each generator's keys: the registry (setup/generators.py), which set-up and limits read too
GENERATORS = tuple(REGISTRY)
GENERATOR_KEYS = {name: set(g.keys) for name, g in REGISTRY.items()}
Coordinates = vector((2, 3), "coordinates (m)")


def check_box(lower, upper, key="upper", strict=True):
    """Fail unless ``upper`` exceeds ``lower`` (or equals it, unless ``strict``) in every direction."""
    if lower is None or upper is None:
        return
    if len(upper) != len(lower):
        fail(f"must have {len(lower)} coordinates like lower, got {upper}", key=key)
    if any(h < lo or strict and h == lo for lo, h in zip(lower, upper)):
        fail(f"must {'exceed' if strict else 'be at least'} lower {lower} in every direction, got {upper}", key=key)


class CornerPointFault(Table):
    """``[[mesh.faults]]``: a vertical fault of a generated corner-point grid (on a line of pillars)."""

    name: Text = Field(description="fault name ([[fractures]] fault = name selects it as a contact surface)")
    axis: choice("i", "j") = Field(description="i: on the pillar line i = index (strikes along y); j: j = index")
    index: number(ge=1, integer=True) = Field(description="pillar line, 1 ≤ index ≤ n − 1 (n cells along axis)")
    throw: number() = Field(description="depth offset of the high-index side (m; > 0: it goes down)")
    start: number(ge=0, integer=True) | None = Field(None, description="first pillar along the line (default 0)")
    stop: number(ge=1, integer=True) | None = Field(None, description="last pillar along the line (default "
                                                    "the end); the throw tapers to zero where it ends inside")


class Mesh(Table):
    """``[mesh]``: a generated box mesh, a Gmsh file or a corner-point grid (GRDECL file or generated)."""

    generator: choice(*GENERATORS) = Field("simplicial", description="mesh generator")
    lower: Coordinates | None = Field(None, description="lower corner of the box domain (m); not with a file")
    upper: Coordinates | None = Field(None, description="upper corner of the box domain (m)")
    size: Positive | None = Field(None, description="target cell size (m); cartesian may give `cells` instead")
    cells: vector((2, 3), "positive integers") | None = Field(
        None, description="cartesian: cells per direction (takes precedence over `size`)")
    fracture_size: Positive | None = Field(None, description="simplicial, agglomerated: cell size on the "
                                           "fractures (m; default: size)")
    grading: Positive = Field(0.4, description="simplicial, agglomerated: growth of the cell size per unit "
                              "distance from the fractures")
    tip_size: Positive | None = Field(None, description="simplicial: cell size at crack tips / tip lines (m)")
    tip_grading: number(gt=0, le=1) = Field(0.5, description="simplicial, with tip_size: exponent g of the size "
                                            "h(r) ~ r^g near tips; 0.5 suits the P1 space, 2/3-3/4 the "
                                            "quadratic one (mechanics.order = 2)")
    mirror: choice(*MIRROR_MODES) = Field("none", description="simplicial: mesh symmetric about the fractures "
                                          "around tips (2D) or along straight fractures")
    front: choice(*FRONTS) = Field("isotropic", description="simplicial, 3D: crack-front cells; isotropic (graded "
                                   "by tip_size, tip_grading) or anisotropic (thin across the fronts, "
                                   "fracture_size long along them; convex planar fractures apart from each "
                                   "other and from the box; needs tip_size; docs/accuracy_3d.md)")
    rounds: number(ge=0, integer=True) = Field(2, description="agglomerated: rounds of pairwise merging")
    perturb: number(ge=0, le=0.4) = Field(0.0, description="random node perturbation, fraction of the local "
                                          "edge length")
    seed: number(ge=0, integer=True) = Field(0, description="seed of the random generators")
    file: Text | None = Field(None, description="file: the Gmsh .msh file; grdecl: the GRDECL file (relative to "
                              "the case file)")
    nonplanar: choice(*NONPLANAR) = Field("centre", description="grdecl, cornerpoint: warped faces split "
                                          "around a centre node, along a diagonal, or kept")
    snap: number(ge=0, le=0.5) = Field(0.2, description="grdecl, cornerpoint: corners of neighbouring columns "
                                       "closer on a pillar than snap × the thinnest touching cell's thickness are "
                                       "merged at their mean depth, so that fault faces are not slivers (0: the "
                                       "grid's corners exactly; docs/cornerpoint.md, 'Sliver fault faces')")
    refine: vector(3, "positive integers") = Field([1, 1, 1], description="grdecl, cornerpoint: [ni, nj, nk], "
                                                   "every cell split into ni × nj × nk cells along its pillars "
                                                   "(faults, cell keywords and wells follow; docs/cornerpoint.md, "
                                                   "'Refinement')")
    region_keyword: Text | None = Field(None, description="grdecl, cornerpoint: integer cell keyword (e.g. "
                                        "FACIES) whose values v make the regions KEYWORD_v")
    extent: vector(3, "lengths (m)") | None = Field(None, description="cornerpoint: (Lx, Ly, H), horizontal "
                                                    "size and layer-stack thickness (m)")
    top: number() = Field(1000.0, description="cornerpoint: depth of the top of the stack at x = 0 (m)")
    dip: number(gt=-80, lt=80) = Field(0.0, description="cornerpoint: dip of the layers along +x (degrees)")
    faults: list[CornerPointFault] = Field(default_factory=list, description="cornerpoint: the faults")
    pinchout: vector(None, "layer numbers") | None = Field(None, description="cornerpoint: layers (1-based) "
                                                           "thinning to zero towards x = 0")
    pillar_angle: number(ge=0, le=80) = Field(0.0, description="cornerpoint: angle from vertical (degrees) of "
                                              "the outermost pillars (x = 0 and x = Lx); the pillars fan out "
                                              "downwards along x, symmetrically about x = Lx/2 (vertical there), "
                                              "the tangent of their angle linear in x (0: vertical pillars; "
                                              "docs/cornerpoint.md)")
    inactive: number(ge=0, lt=1) = Field(0.0, description="cornerpoint: fraction of randomly inactive cells")
    layer_permeability: vector(None, "permeabilities (mD)") | None = Field(
        None, description="cornerpoint: PERMX = PERMY of the layers from the top (mD), repeated down the stack when "
                          "there are more layers; PERMZ a tenth of it (default 100 mD everywhere)")

    @model_validator(mode="after")
    def _generator_keys(self):
        allowed = GENERATOR_KEYS[self.generator] | {"generator"}
        for key in sorted(self.given() - allowed):
            users = [g for g, keys in GENERATOR_KEYS.items() if key in keys]
            fail(f"does not apply to generator = {self.generator!r} (only to {', '.join(users)})", key=key)
        if self.generator == "file":
            if self.file is None:
                fail("is required with generator = \"file\" (the path of a Gmsh .msh file)", key="file")
            return self
        if self.generator in CORNERPOINT and any(r < 1 or int(r) != r for r in self.refine):
            fail(f"must be 3 positive integers [ni, nj, nk] (children per cell along i, j, k), got {self.refine}",
                 key="refine")
        if self.generator == "grdecl":
            if self.file is None:
                fail("is required with generator = \"grdecl\" (the path of a GRDECL file)", key="file")
            return self
        if self.generator == "cornerpoint":
            return self._cornerpoint()
        for key in ("lower", "upper"):
            if getattr(self, key) is None:
                fail(f"is required with generator = {self.generator!r}: the box corner (m), e.g. [0, 0] or "
                     "[0, 0, 0]", key=key)
        check_box(self.lower, self.upper)
        if self.cells is not None:
            if len(self.cells) != len(self.lower):
                fail(f"must give {len(self.lower)} numbers like lower, got {self.cells}", key="cells")
            if any(c < 1 or int(c) != c for c in self.cells):
                fail(f"must be positive integers, got {self.cells}", key="cells")
        elif self.size is None:
            fail(f"is required with generator = {self.generator!r}: the target cell size (m)"
                 + (" (or give cells)" if self.generator == "cartesian" else ""), key="size")
        if self.front == "anisotropic":
            if len(self.lower) != 3:
                fail("\"anisotropic\" applies to 3D boxes (in 2D a crack front is a point: use the isotropic "
                     "tip grading)", key="front")
            if self.tip_size is None:
                fail("is required with front = \"anisotropic\": the cell size across the crack fronts (m)",
                     key="tip_size")
            if self.mirror != "none":
                fail(f"{self.mirror!r} does not combine with front = \"anisotropic\" (its front cells are "
                     "already symmetric about the fracture plane); use mirror = \"none\"", key="mirror")
        if "tip_grading" in self.given() and self.tip_size is None:
            fail("grades the cells towards tips down to tip_size, which is not given (set mesh.tip_size)",
                 key="tip_grading")
        return self

    def _cornerpoint(self):
        for key, what in (("cells", "[nx, ny, nz], the cells along x, y and the layers"),
                          ("extent", "[Lx, Ly, H] (m), the horizontal size and the thickness of the stack")):
            if getattr(self, key) is None:
                fail(f"is required with generator = \"cornerpoint\": {what}", key=key)
        if len(self.cells) != 3 or any(c < 1 or int(c) != c for c in self.cells):
            fail(f"must be 3 positive integers [nx, ny, nz], got {self.cells}", key="cells")
        if any(not 0 < v <= 1e6 for v in self.extent):
            fail(f"must be 3 positive lengths of at most 1000 km (m), got {self.extent}", key="extent")
        if not abs(self.top) <= 1e5:
            # depths beyond 100 km leave too few digits for the corner-point intersections
            fail(f"must be a depth within ±100 km (m), got {self.top}", key="top")
        nz = int(self.cells[2])
        for v in self.pinchout or []:
            if int(v) != v or not 1 <= v <= nz:
                fail(f"must be layer numbers 1 ... {nz} (1-based), got {self.pinchout}", key="pinchout")
        for v in self.layer_permeability or []:
            if not 0 < v <= 1e9:
                fail(f"must be permeabilities in mD, each > 0 and ≤ 1e9, got {self.layer_permeability}",
                     key="layer_permeability")
        if self.layer_permeability is not None and len(self.layer_permeability) == 0:
            fail("must list at least one permeability (mD)", key="layer_permeability")
        seen = set()
        for i, f in enumerate(self.faults):
            n = int(self.cells[0 if f.axis == "i" else 1])
            if not 1 <= f.index <= n - 1:
                fail(f"must lie in 1 ... {n - 1} (a pillar line strictly inside the grid: {n} cells along "
                     f"{f.axis}), got {f.index}", key=("faults", i, "index"))
            thick = float(self.extent[2])
            if not abs(f.throw) <= 10 * thick:
                # a larger throw moves the block past the whole stack: no overlap is left to split,
                # and ~1e8 m throws leave too few digits for the fault intersections
                fail(f"must be at most 10 × the stack thickness extent[2] = {thick:g} m in size, got {f.throw:g}",
                     key=("faults", i, "throw"))
            if f.name in seen:
                fail(f"{f.name!r} is given twice; names must differ", key=("faults", i, "name"))
            seen.add(f.name)
        return self

    @property
    def dim(self) -> int | None:
        """2 or 3 for a generated mesh, 3 for a corner-point grid, None for a Gmsh file (known once read)."""
        if self.generator in CORNERPOINT:
            return 3
        return None if self.lower is None else len(self.lower)


# keys of [[fractures]] that give the fracture's own contact and flow data (every kind of fracture)
FRACTURE_DATA = {"friction": "contact", "threshold": "contact", "dynamic_friction": "contact",
                 "critical_slip": "contact", "a": "contact", "b": "contact", "reference_rate": "contact",
                 "initial_slip_rate": "contact", "aperture": "flow", "normal_permeability": "flow",
                 "fracture_conductivity": "flow"}


class Fracture(Table):
    """``[[fractures]]``: a 2D polyline or 3D planar polygon, or in 3D a regular polygon, a physical
    group of a mesh file or a fault of a corner-point grid; optionally with its own contact and
    flow data (``friction``, ``threshold``, ``dynamic_friction``, ``critical_slip``,
    ``aperture``, ``normal_permeability``,
    ``fracture_conductivity``), which replace the ``[contact]`` / ``[flow]`` values on its faces."""

    name: Text = Field(description="name of the fracture (results and --set address it by name)")
    vertices: points("points [x, y] or [x, y, z]", 2) | None = Field(
        None, description="2D polyline / 3D planar polygon (m)")
    centre: vector(3, "coordinates (m)") | None = Field(None, description="3D regular polygon: centre (m)")
    radius: Positive | None = Field(None, description="3D regular polygon: circumradius (m)")
    sides: number(ge=3, integer=True) = Field(6, description="3D regular polygon: number of sides")
    normal: vector((2, 3), "components") | None = Field(None, description="3D: direction of n⁺ (required for a "
                                                        "regular polygon); file meshes: d components")
    group: Text | None = Field(None, description="file meshes: the physical group (default: name)")
    fault: Text | None = Field(None, description="corner-point grids: the fault selected as this contact "
                               "surface (default: name); unselected faults stay bonded")
    # per-fracture data: on this fracture's faces they replace the [contact] / [flow] value
    friction: Expr | None = Field(None, description="coulomb: friction coefficient F ≥ 0 on this fracture "
                                  "(expression of x, y, z, D), instead of contact.friction")
    threshold: Expr | None = Field(None, description="tresca: threshold g ≥ 0 (Pa) on this fracture, instead of "
                                   "contact.threshold")
    dynamic_friction: Expr | None = Field(None, description="slip-weakening: dynamic friction F_d on this fracture, "
                                          "instead of contact.dynamic_friction")
    critical_slip: Expr | None = Field(None, description="slip-weakening, rate-and-state: critical slip D_c (m) on "
                                       "this fracture, instead of contact.critical_slip")
    a: Expr | None = Field(None, description="rate-and-state: direct effect a on this fracture, instead of contact.a")
    b: Expr | None = Field(None, description="rate-and-state: evolution effect b on this fracture, instead of "
                           "contact.b")
    reference_rate: Expr | None = Field(None, description="rate-and-state: V₀ (m/s) on this fracture, instead of "
                                        "contact.reference_rate")
    initial_slip_rate: Expr | None = Field(None, description="rate-and-state: V_i (m/s) on this fracture, instead "
                                           "of contact.initial_slip_rate")
    aperture: Expr | None = Field(None, description="flow: d_f (m) > 0 on this fracture (expression of x, y, z, t, "
                                  "D, L), instead of flow.aperture")
    normal_permeability: Expr | None = Field(None, description="flow: K_fn (m²) > 0 on this fracture (x, y, z, "
                                             "D, L), instead of flow.normal_permeability")
    fracture_conductivity: Expr | None = Field(None, description="flow: C_f (m³) of the aperture d on this "
                                               "fracture, instead of flow.fracture_conductivity (default d³/12)")

    @model_validator(mode="after")
    def _shape(self):
        given = self.given()
        polygon = {"centre", "radius", "sides"} & given
        if self.vertices is not None and polygon:
            fail(f"give either vertices or a regular polygon (centre, radius, sides), not both; got "
                 f"{', '.join(sorted(polygon))} with vertices", key=sorted(polygon)[0])
        if polygon:
            for key in ("centre", "radius", "normal"):
                if key not in given:
                    fail(f"is required for a regular polygon (with {', '.join(sorted(polygon))})", key=key)
        if self.vertices is not None:
            self._simple()
        return self

    def _simple(self):
        # a fracture crossing itself was found only inside Newton (issue 25): refuse it here
        from ...mesh.fractures import self_intersection

        closed = len(self.vertices[0]) == 3
        pair = self_intersection(self.vertices, closed)
        if pair is None:
            return
        k = len(self.vertices)
        i, j = pair
        what = "polygon" if closed else "polyline"

        def edge(e):
            return f"the edge from vertex {e + 1} to vertex {(e + 1) % k + 1}"
        fail(f"the {what} intersects itself: {edge(i)} and {edge(j)} (vertices numbered from 1) "
             f"{'fold back onto each other' if j == i + 1 or (closed and i == 0 and j == k - 1) else 'cross or touch'}"
             f"; a fracture must be a simple {what} (split it into fractures that meet, or reorder its "
             "vertices)", key="vertices")


class Region(Table):
    """``[[regions]]``: a material region, the cells whose centroid lies in a box."""

    name: Text = Field(description="region name (used by [[materials]] and flow tables by region)")
    lower: Coordinates = Field(description="lower corner of the box (m)")
    upper: Coordinates = Field(description="upper corner of the box (m)")

    @model_validator(mode="after")
    def _box(self):
        check_box(self.lower, self.upper)
        return self


class BoundaryPart(Table):
    """``[[boundaries]]``: an extra boundary part, the faces of part ``on`` with centroid in a box."""

    name: Text = Field(description="name of the new boundary part")
    on: Text = Field(description="the boundary part it is cut from (xmin ... zmax or a mesh group)")
    lower: Coordinates = Field(description="lower corner of the box (m)")
    upper: Coordinates = Field(description="upper corner of the box (m)")

    @model_validator(mode="after")
    def _box(self):
        check_box(self.lower, self.upper, strict=False)   # a flat box selects the faces in a plane
        return self
