"""The case file as a whole: the remaining tables (``[time]``, ``[solver]``, ``[exact]``,
``[initial_state]``, ``[monitor]``, ``[parameters]``) and :class:`Case`, whose validator checks what
spans tables: the model a case asks for and the tables that model reads, dimensions, names given
twice, ``"exact"`` values without an ``[exact]`` solution, steady against transient flow.

Required-for-a-run tables (a mechanics run needs ``[material]``) are checked where the run is set
up, so that ``polypore mesh`` accepts a case with only its geometry.
"""

from __future__ import annotations

import keyword
import re
from typing import Annotated

from pydantic import Field, PlainValidator, WithJsonSchema, model_validator

from ...cases.exact import PROFILES, SOLUTIONS
from ...cases.flow_exact import NAMES as FLOW_SOLUTIONS
from ...cases.reference import REFERENCES
from ...core.expressions import CONSTANTS, FUNCTIONS, VARIABLES
from ...models.friction import LAW_KEYS
from ...solvers.linear import BACKENDS
from ...solvers.newton import FORCING, PREDICTORS
from .flow import Flow
from .geometry import CORNERPOINT, FRACTURE_DATA, BoundaryPart, Fracture, Mesh, Region
from .mechanics import Contact, Material, Mechanics, RegionMaterial
from .types import (ExprTensor, Number, NonNegative, Positive, Table, Text, choice, fail, finite, is_number, number,
                    show, vector)

MODELS = ("mechanics", "flow", "poromechanics")
EXACT = tuple(SOLUTIONS) + PROFILES + REFERENCES + FLOW_SOLUTIONS
_COMMON = {"name", "description", "model", "base_dir", "parameters", "mesh", "fractures", "regions", "boundaries",
           "solver"}
# the tables each model reads; any other is an error rather than silently ignored
READS = {"mechanics": _COMMON | {"material", "materials", "mechanics", "contact", "exact"},
         "flow": _COMMON | {"flow", "time", "exact"},
         "poromechanics": _COMMON | {"material", "materials", "mechanics", "contact", "flow", "time", "initial_state",
                                     "monitor"}}
SOLVER_KEYS = {"mechanics": {"linear", "tolerance", "increment_tolerance", "max_iterations", "forcing", "forcing_max",
                               "petsc"},
               "flow": {"linear", "linear_tolerance", "petsc"}}
SOLVER_KEYS["poromechanics"] = SOLVER_KEYS["mechanics"] | SOLVER_KEYS["flow"] | {"predictor"}
_NAME = re.compile(r"[\w.-]+")
# output times of one run: each writes a set of VTU files and a summary row, so 100,000 of them
# are hours of writing and gigabytes of files (issue 25), never a considered choice
MAX_OUTPUT_TIMES = 10_000


def physics(given: set, model: str | None) -> str:
    """The model a case with top-level keys ``given`` asks for: ``model``, else "poromechanics"
    with mechanics tables and [flow], "flow" with [flow] only, else "mechanics"."""
    if model is not None:
        return model
    mech = bool(given & {"mechanics", "material", "materials", "contact"})
    return ("poromechanics" if mech else "flow") if "flow" in given else "mechanics"


def _model_tables(given: set, model: str | None) -> None:
    """Fail on a table the case's model does not read (it would be ignored)."""
    physics_ = physics(given, model)
    how = f"model = {model!r}" if model else "model inferred from its tables"
    for table in sorted(given - READS[physics_]):
        hint = {"time": "a static case has no time loop; a transient run needs a [flow] table (poromechanics)",
                "monitor": "points are recorded by poromechanics runs only",
                "initial_state": "the in-situ state is read by poromechanics runs only",
                "exact": "no exact solution is available for poromechanics",
                "flow": "set model = \"poromechanics\" for flow with mechanics"}.get(
            table, "set model = \"poromechanics\" for mechanics with flow")
        fail(f"a {physics_} case ({how}) does not read [{table}]: {hint}; remove it", key=table)


class Time(Table):
    """``[time]``: the implicit-Euler schedule of a transient run (s)."""

    start: Number = Field(0.0, description="start time (s)")
    end: Number = Field(description="end time (s) > start")
    step: Number = Field(description="time step (s) > 0 (the last step is shortened to land on end)")
    output_every: number(ge=1, integer=True) = Field(1, description="write outputs every n steps (and at the end)")
    output_times: vector(None, "times (s)") | None = Field(None, description="or write outputs at these times (s); "
                                                         "steps are shortened to land on them")
    max_cuts: number(ge=0, le=30, integer=True) = Field(4, description="halvings of a step whose Newton loop "
                                                        "fails before the run stops")
    max_conductivity_growth: number(gt=1) | None = Field(
        None, description="poromechanics: redo a step at half the size while some fracture face's conductivity "
        "grows more than this factor in it (a slip onset; the conductivities lag one step); default: no limit")
    growth_cuts: number(ge=0, le=60, integer=True) = Field(8, description="with max_conductivity_growth: the "
                                                           "smallest sub-step is time.step / 2^growth_cuts "
                                                           "(rate-and-state friction: at least 2^48)")
    rate_tolerance: number(gt=0, le=1) = Field(0.05, description="rate-and-state friction: the sub-steps are sized "
                                               "so that ln V (times the state's sensitivity to it, where above 1) "
                                               "changes by about this much per sub-step on every fault face (from "
                                               "years between events to milliseconds inside one); implicit Euler's "
                                               "error is proportional to it")

    @model_validator(mode="after")
    def _advances(self):
        if not self.end > self.start:
            fail(f"must exceed time.start = {self.start!r} (s): the schedule does not advance, got {self.end!r}",
                 key="end")
        if not self.step > 0:
            fail(f"must be positive (s): the schedule does not advance, got {self.step!r}", key="step")
        if self.output_times is not None:
            if "output_every" in self.given():
                fail("give output_every or output_times, not both", key="output_times")
            n = len(set(self.output_times))
            if n > MAX_OUTPUT_TIMES:
                fail(f"{n:,} distinct output times; allowed: at most {MAX_OUTPUT_TIMES:,} (each writes the "
                     "run's VTU files and a summary row)", key="output_times")
            bad = [v for v in self.output_times if not self.start < v <= self.end]
            if bad:
                fail(f"{bad[0]!r} lies outside the run ({self.start!r}, {self.end!r}] s", key="output_times")
        return self


def _petsc_options(v):
    # the names are checked by PETSc itself when the solver is set up (solvers/petsc.py)
    if not isinstance(v, dict):
        fail(f"expected a table of PETSc options (name = value), got {show(v)}")
    for name, x in v.items():
        if isinstance(x, bool) or isinstance(x, str) or is_number(x) and finite(x):
            continue
        fail(f"expected a text, a finite number or true/false, got {show(x)}", key=name)
    return v


class Solver(Table):
    """``[solver]``: linear solver and Newton options."""

    linear: choice(*BACKENDS) = Field("auto", description="linear solver backend")
    tolerance: Positive = Field(1e-8, description="mechanics: Newton residual tolerance (relative)")
    increment_tolerance: Positive = Field(1e-8, description="mechanics: Newton increment tolerance (relative)")
    max_iterations: number(ge=1, integer=True) = Field(50, description="mechanics: Newton iterations at most")
    forcing: choice(*FORCING) = Field("eisenstat-walker", description="mechanics: tolerance of the block-amg/"
                                      "block-petsc solves per Newton iteration, Eisenstat-Walker forcing in Newton's "
                                      "weighted norm, or 'fixed' (1e-8 relative, plain 2-norm)")
    forcing_max: number(gt=0, lt=1) = Field(1e-2, description="mechanics: loosest relative tolerance of an "
                                            "Eisenstat-Walker linear solve")
    predictor: choice(*PREDICTORS) = Field("linear", description="poromechanics: first Newton iterate of a time "
                                           "step, the last step's increment extrapolated ('linear'; not over a step "
                                           "more than twice the last) or the old state ('none')")
    linear_tolerance: Positive = Field(1e-10, description="flow: relative residual of iterative backends")
    petsc: Annotated[dict, PlainValidator(_petsc_options), WithJsonSchema(
        {"type": "object", "additionalProperties": {"type": ["string", "number", "boolean"]}})] | None = Field(
        None, description="[solver.petsc]: PETSc options (name = value, without the leading '-') of the petsc "
        "and block-petsc backends")

    @model_validator(mode="after")
    def _petsc_backend(self):
        if self.petsc is not None and self.linear not in ("petsc", "block-petsc"):
            fail(f"applies to linear = \"petsc\" or \"block-petsc\" only; this case has linear = {self.linear!r}",
                 key="petsc")
        return self

    def backend_options(self) -> dict:
        """Keyword arguments of :class:`~polypore.solvers.linear.LinearSolver` beyond the backend."""
        return {} if self.petsc is None else {"petsc_options": dict(self.petsc)}


class Exact(Table):
    """``[exact]``: an exact, analytic or reference solution to compare with (errors in summary.json)."""

    solution: choice(*EXACT) = Field(description="the solution")
    sigma: Positive | None = Field(None, description="single-crack: remote compression (Pa)")
    psi_deg: number(gt=0, lt=90) | None = Field(None, description="single-crack: crack angle to the compression "
                                                "(degrees)")
    half_length: Positive | None = Field(None, description="single-crack: half length of the crack (m)")
    fracture: Text | None = Field(None, description="penny-shaped-crack: the crack (default: the only fracture)")
    stress: ExprTensor | None = Field(None, description="penny-shaped-crack: remote stress (Pa, 3×3, tension "
                                      "positive)")
    pressure: Number | None = Field(None, description="penny-shaped-crack: pressure on the faces (Pa; default "
                                    "mechanics.fracture_pressure)")
    radius: Positive | None = Field(None, description="penny-shaped-crack: radius (m; default: the polygon's "
                                    "circumradius)")

    @model_validator(mode="after")
    def _solution_keys(self):
        own = {"single-crack": ("sigma", "psi_deg", "half_length"),
               "penny-shaped-crack": ("fracture", "stress", "pressure", "radius")}
        for key in sorted(self.given() - {"solution"} - set(own.get(self.solution, ()))):
            users = [s for s, keys in own.items() if key in keys]
            fail(f"applies to solution = {users[0]!r} only; this case has solution = {self.solution!r}", key=key)
        if self.solution == "single-crack":
            for key in own["single-crack"]:
                if getattr(self, key) is None:
                    fail("is required for the single-crack solution", key=key)
        return self


class InitialState(Table):
    """``[initial_state]``: a gravitational in-situ equilibrium the run starts from (C6)."""

    gravity: NonNegative = Field(9.81, description="g (m/s²), along −x_d (the last coordinate is up)")
    rock_density: Positive = Field(description="ρ_r (kg/m³): σ_v = ρ_r g z")
    fluid_density: NonNegative = Field(1000.0, description="ρ_w (kg/m³): p_h = p_s + ρ_w g z")
    stress_ratio: Positive = Field(description="k = σ_h/σ_v")
    surface: Number = Field(0.0, description="elevation of the ground surface (m)")
    surface_pressure: Number = Field(0.0, description="p_s (Pa)")
    stress_ratio_max: Positive | None = Field(None, description="3D: k_H = σ_H/σ_v of the largest horizontal "
                                              "stress (default stress_ratio: isotropic horizontal stress)")
    azimuth: number(ge=-180, le=180) = Field(0.0, description="3D: direction of σ_H, degrees from +x towards +y")


def _points(v):
    if not isinstance(v, dict):
        fail(f"expected a table name = [x, y(, z)] (m), got {show(v)}")
    for name, x in v.items():
        if not (isinstance(x, list) and len(x) in (2, 3) and all(is_number(a) and finite(a) for a in x)):
            fail(f"must be 2 or 3 finite coordinates (m), got {show(x)}", key=name)
    return {k: [float(a) for a in x] for k, x in v.items()}


class Monitor(Table):
    """``[monitor]``: points whose overpressure a poromechanics run records against time."""

    points: Annotated[dict, PlainValidator(_points), WithJsonSchema(
        {"type": "object", "additionalProperties": {"type": "array", "items": {"type": "number"},
                                                    "minItems": 2, "maxItems": 3}})] = Field(
        default_factory=dict, description="name = [x, y(, z)] (m): the cell whose centroid is nearest")


def _parameters(v):
    if not isinstance(v, dict):
        fail(f"expected a table of named numbers, got {show(v)}")
    for name, x in v.items():
        taken = ("a coordinate/time variable" if name in VARIABLES else "a function" if name in FUNCTIONS
                 else "a constant" if name in CONSTANTS else None)
        if taken:
            fail(f"the name {name!r} is {taken} in expressions; rename the parameter", key=name)
        if not name.isidentifier() or keyword.iskeyword(name):
            fail(f"{name!r} cannot be used in an expression; allowed: names of letters, digits and _ that do not "
                 "start with a digit", key=name)
        if not is_number(x) or not finite(x):
            fail(f"expected a finite number, got {show(x)}", key=name)
    return {k: float(x) for k, x in v.items()}


def _case_name(v):
    if isinstance(v, str) and _NAME.fullmatch(v) and v != "." and ".." not in v:
        return v
    fail("the case name names its results folder (results/<name>), so it may hold only letters, digits, '-', "
         f"'_' and '.', with no path separator and no '..'; got {show(v)}")


def _description(v):
    if not isinstance(v, str):
        fail(f"expected a text, got {show(v)}")
    return v


class Case(Table):
    """A polypore case file (TOML). Tables a model does not read are errors (see ``model``)."""

    name: Annotated[str, PlainValidator(_case_name), WithJsonSchema(
        {"type": "string", "pattern": r"^[\w.-]+$"})] | None = Field(
        None, description="case name, the results folder results/<name> (default: the file name)")
    description: Annotated[str, PlainValidator(_description), WithJsonSchema({"type": "string"})] | None = Field(
        None, description="one line on what the case is")
    model: choice(*MODELS) | None = Field(None, description="the physics; default: poromechanics with both "
                                          "mechanics and [flow] tables, flow with [flow] only, else mechanics")
    base_dir: Text | None = Field(None, description="not a case-file key: set by polypore (load_case) or an API "
                                  "caller to the folder of the case file, where relative mesh files are found")
    parameters: Annotated[dict, PlainValidator(_parameters), WithJsonSchema(
        {"type": "object", "additionalProperties": {"type": "number"}})] = Field(
        default_factory=dict, description="named numbers usable in every expression")
    mesh: Mesh = Field(description="the mesh")
    fractures: list[Fracture] = Field(default_factory=list, description="the fractures")
    regions: list[Region] = Field(default_factory=list, description="material regions (boxes that tile Ω)")
    boundaries: list[BoundaryPart] = Field(default_factory=list, description="extra boundary parts")
    material: Material | None = Field(None, description="uniform elastic material")
    materials: list[RegionMaterial] = Field(default_factory=list, description="or one material per region")
    mechanics: Mechanics | None = Field(None, description="mechanics options, loads and boundary conditions")
    contact: Contact | None = Field(None, description="the contact law on the fractures")
    exact: Exact | None = Field(None, description="a solution to compare with")
    flow: Flow | None = Field(None, description="Darcy flow in the matrix and the fractures")
    time: Time | None = Field(None, description="time schedule (transient runs)")
    solver: Solver | None = Field(None, description="solver options")
    initial_state: InitialState | None = Field(None, description="in-situ equilibrium (poromechanics)")
    monitor: Monitor | None = Field(None, description="points recorded against time (poromechanics)")

    @classmethod
    def _unknown_what(cls, value) -> str:
        return f"unknown top-level {'table' if isinstance(value, (dict, list)) else 'key'}"

    @property
    def physics(self) -> str:
        """The model the case asks for: ``model``, else inferred from its tables."""
        return physics(self.given(), self.model)

    @classmethod
    def _check_keys(cls, data) -> None:
        # the tables a model reads are checked before their values: a [time] table in a static case
        # is reported as such, not as a [time] table with a missing key
        super()._check_keys(data)
        model = data.get("model")
        if model is None or model in MODELS:
            _model_tables(set(data), model)

    @model_validator(mode="after")
    def _across_tables(self):
        self._model_solver()
        self._geometry()
        if self.material is not None and self.materials:
            fail("give [material] (uniform) or [[materials]] (per region), not both", key="materials")
        self._cell_materials()
        self._exact_values()
        if self.flow is not None:
            self._steady_or_transient()
        return self

    def _model_solver(self):
        model = self.physics
        if self.exact is not None and (self.exact.solution in FLOW_SOLUTIONS) != (model == "flow"):
            allowed = FLOW_SOLUTIONS if model == "flow" else [s for s in EXACT if s not in FLOW_SOLUTIONS]
            fail(f"{self.exact.solution!r} is not a solution of a {model} case; allowed: {', '.join(allowed)}",
                 key=("exact", "solution"))
        if self.solver is not None:
            for key in sorted(self.solver.given() - SOLVER_KEYS[model]):
                users = [m for m in ("mechanics", "flow") if key in SOLVER_KEYS[m]] or ["poromechanics"]
                fail(f"applies to {' and '.join(users)} only; "
                     f"this is a {model} case", key=("solver", key))

    def _geometry(self):
        dim, file_mesh = self.mesh.dim, self.mesh.generator == "file"
        for key in ("fractures", "regions", "boundaries"):
            seen = set()
            for i, item in enumerate(getattr(self, key)):
                if item.name in seen:
                    fail(f"{item.name!r} is given twice; names must differ", key=(key, i, "name"))
                seen.add(item.name)
        cornerpoint = self.mesh.generator in CORNERPOINT
        self._fracture_data()
        for i, f in enumerate(self.fractures):
            if cornerpoint:
                for k in sorted(f.given() - {"name", "fault"} - set(FRACTURE_DATA)):
                    fail("does not apply to a fault of a corner-point grid (its faces come from the grid; select "
                         "it by `fault`)", key=("fractures", i, k))
                continue
            if "fault" in f.given():
                fail("applies to corner-point grids only (generator = \"grdecl\" or \"cornerpoint\")",
                     key=("fractures", i, "fault"))
            if file_mesh:
                for k in sorted(f.given() - {"name", "group", "normal"} - set(FRACTURE_DATA)):
                    fail("does not apply to a fracture of a mesh file (its faces are the physical group `group`)",
                         key=("fractures", i, k))
                continue
            if "group" in f.given():
                fail("applies to mesh files only (generator = \"file\")", key=("fractures", i, "group"))
            polygon = f.radius is not None
            if not polygon and f.vertices is None:
                fail("is required: the fracture's vertices [[x, y(, z)], ...] (m)" + (
                    ", or in 3D a regular polygon (centre, radius, sides, normal)" if dim == 3 else ""),
                    key=("fractures", i, "vertices"))
            if dim == 2 and (polygon or f.normal is not None):
                key = "normal" if f.normal is not None else "radius"
                fail("applies to 3D meshes only (this mesh is 2D: lower has 2 coordinates)", key=("fractures", i, key))
            if dim == 3 and f.normal is not None and len(f.normal) != 3:
                fail(f"must have 3 components, got {f.normal}", key=("fractures", i, "normal"))
            if f.vertices is not None and len(f.vertices[0]) != dim:
                fail(f"must be {dim}D points like mesh.lower, got {show(f.vertices)}", key=("fractures", i, "vertices"))
        if dim is None:
            return
        for key in ("regions", "boundaries"):
            for i, item in enumerate(getattr(self, key)):
                if len(item.lower) != dim:
                    fail(f"must have {dim} coordinates like mesh.lower, got {item.lower}", key=(key, i, "lower"))
        if self.monitor is not None:
            for name, x in self.monitor.points.items():
                if len(x) != dim:
                    fail(f"must have {dim} coordinates (m), got {x}", key=("monitor", "points", name))

    def _cell_materials(self):
        """E and ν from the grid's cell keywords ("grdecl:KW", tables by keyword value) need a
        corner-point grid."""
        if self.mesh.generator in CORNERPOINT:
            return
        blocks = ([("material",)] if self.material is not None else []) + [
            ("materials", i) for i in range(len(self.materials))]
        for where in blocks:
            m = self.material if where == ("material",) else self.materials[where[1]]
            for key in ("E", "nu"):
                if isinstance(getattr(m, key), (str, dict)):
                    fail("takes cell values from a corner-point grid's keywords, but the mesh is not one (mesh."
                         "generator = \"grdecl\" or \"cornerpoint\"); give a number", key=where + (key,))

    def _fracture_data(self):
        """Per-fracture friction/threshold need the matching contact law, flow data a model with flow."""
        physics_ = self.physics
        law = (self.contact.law if self.contact is not None else "coulomb")
        for i, f in enumerate(self.fractures):
            for key in sorted(f.given() & set(FRACTURE_DATA)):
                if FRACTURE_DATA[key] == "flow" and physics_ == "mechanics":
                    fail("is flow data; this is a mechanics case (no [flow] table): remove it",
                         key=("fractures", i, key))
                if FRACTURE_DATA[key] == "contact":
                    if physics_ == "flow":
                        fail("is contact data; this is a flow case (no mechanics): remove it",
                             key=("fractures", i, key))
                    need = LAW_KEYS[key]
                    if law not in need:
                        fail(f"applies to contact.law = {' or '.join(map(repr, need))} only; this case has "
                             f"law = {law!r}", key=("fractures", i, key))

    def _exact_values(self):
        if self.exact is not None:
            return
        where = []
        if self.mechanics is not None:
            if self.mechanics.body_force == "exact":
                where.append(("mechanics", "body_force"))
            where += [("mechanics", "boundary", i, "u") for i, b in enumerate(self.mechanics.boundary)
                      if b.u == "exact"]
        if self.flow is not None:
            where += [("flow", k) for k in ("source", "fracture_source") if getattr(self.flow, k) == "exact"]
            where += [("flow", "boundary", i, "pressure") for i, b in enumerate(self.flow.boundary)
                      if b.pressure == "exact"]
        if where:
            fail('"exact" needs an [exact] solution in the case', key=where[0])

    def _steady_or_transient(self):
        timed = self.time is not None
        if self.flow.steady is True and timed:
            fail("is true but the case has a [time] table; remove one of them (steady = false for a transient "
                 "run)", key=("flow", "steady"))
        if self.flow.steady is False and not timed:
            fail("is false but the case has no [time] table (end, step in s)", key=("flow", "steady"))
        if self.flow.initial_pressure is not None and not timed:
            fail("only applies to a transient run (a [time] table)", key=("flow", "initial_pressure"))
