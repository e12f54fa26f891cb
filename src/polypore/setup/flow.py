"""From a case's ``[flow]``, ``[time]``, ``[exact]`` and ``[solver]`` tables to a :class:`FlowModel`.

The tables, their keys, ranges and defaults are in :mod:`polypore.setup.schema.flow`
(``polypore schema`` prints them); an example (SI units)::

    [flow]
    permeability = 1e-15             # K_m (m²): number/expression, d×d matrix or a table by region
    viscosity = 1e-3                 # η (Pa·s)
    biot_modulus = 1e10              # M (Pa), "inf" (no matrix storage; the default) or by region
    aperture = 1e-4                  # d_f (m) > 0: expression of x, y, z, t, D, L
    initial_pressure = 1e5           # p⁰ (Pa) of a transient run

    [[flow.boundary]]                # one block per boundary part; parts without one are no-flow
    name = "xmin"
    pressure = 1e5                   # or flux, rate, mass_rate

    [time]                           # transient runs (implicit Euler, setup/schedule.py)
    end = 2000.0
    step = 20.0

Here expressions are parsed and evaluated on the mesh, and what needs the mesh is checked:
regions and boundary parts that exist, positive apertures and permeabilities on every face,
a pressure condition where the pressure would otherwise be defined up to a constant.

Variables in fracture expressions: ``D`` the distance (m) from the face centroid to the
nearest tip of the same fracture (1e30 on a fracture without tips), ``L`` the fracture's
length in 2D, the square root of its area in 3D (m).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..cases.flow_exact import DarcyManufactured, gamma1_mask
from ..core.errors import InputError
from ..core.expressions import parse
from ..mesh import FracturedMesh
from ..models.flow import FlowData, FlowModel, Flux, NO_FLOW, Pressure, evaluate, permeability_tensor
from ..models.fracture_geometry import tip_distance
from ..solvers.factory import SolverChoice
from .solver import solver_choice
from .casefile import CaseFile
from .schedule import TimeSchedule, parse_schedule
from .schema.case import Solver
from .schema.flow import GRDECL
from .translate import FLOW, case_keys

FRACTURE_VARS = ("D", "L")
log = logging.getLogger("polypore")


@dataclass
class FlowSetup:
    """Everything a flow run needs, validated against the mesh."""

    fm: FracturedMesh
    data: FlowData
    boundary: dict
    fracture_boundary: dict
    cell_source: object
    fracture_source: object
    solver: SolverChoice
    schedule: TimeSchedule | None = None
    initial_pressure: object = None
    alpha: float | None = None
    fracture_alpha: float | None = None
    exact: DarcyManufactured | None = None
    on_gamma1: np.ndarray | None = None
    info: dict = field(default_factory=dict)
    cell_point: str = "auto"

    @property
    def steady(self) -> bool:
        return self.schedule is None

    @case_keys(FLOW)
    def model(self) -> FlowModel:
        return FlowModel(self.fm, self.data, self.boundary, fracture_boundary=self.fracture_boundary,
                         cell_source=self.cell_source, fracture_source=self.fracture_source, alpha=self.alpha,
                         fracture_alpha=self.fracture_alpha, solver=self.solver, cell_point=self.cell_point)


# -- helpers -------------------------------------------------------------------------------------
def _point_fn(expr, extra: dict | None = None):
    """f(x, y, z, t) from an Expression, with fixed per-entity extra variables (D, L)."""
    extra = extra or {}

    def fn(x, y, z, t=0.0):
        return expr(x, y, z, t, **extra)

    fn.text = expr.text
    return fn


def _cell_values(value, field: str, params, centroids) -> np.ndarray:
    e = parse(value, field, params)
    if "t" in e.names:
        raise InputError(field, f"expression {e.text!r} may not depend on t here")
    c = centroids
    z = c[:, 2] if c.shape[1] > 2 else np.zeros(c.shape[0])
    with np.errstate(all="ignore"):
        out = np.broadcast_to(e(c[:, 0], c[:, 1], z, 0.0), (c.shape[0],)).astype(float)
    if not np.all(np.isfinite(out)):
        raise InputError(field, f"expression {e.text!r} is not finite at every cell centroid")
    return out


def _tensor(value, field: str, params, centroids, dim: int) -> np.ndarray:
    """Permeability value -> (n, d, d): number/expression (isotropic) or a d×d matrix."""
    n = centroids.shape[0]
    if isinstance(value, list):
        if not (len(value) == dim and all(isinstance(r, list) and len(r) == dim for r in value)):
            raise InputError(field, f"expected a number, an expression or a {dim}×{dim} matrix (list of {dim} rows "
                             f"of {dim} numbers), got {value!r}")
        K = np.empty((n, dim, dim))
        for i in range(dim):
            for j in range(dim):
                K[:, i, j] = _cell_values(value[i][j], f"{field}[{i}][{j}]", params, centroids)
        return permeability_tensor(K, n, dim, field)
    return permeability_tensor(_cell_values(value, field, params, centroids), n, dim, field)


def _permeability(flow, mesh, params) -> np.ndarray:
    d, nc = mesh.dim, mesh.n_cells
    c = mesh.geometry.cell_centroid
    K = np.full((nc, d, d), np.nan)
    value = flow.permeability
    if value == GRDECL:
        from ..mesh.cornerpoint import cell_permeability

        grid, info = _grid(mesh, "flow.permeability")
        K[:] = cell_permeability(grid, info)
        bad = ~(np.linalg.eigvalsh(K)[:, 0] > 0)
        if bad.any():
            raise InputError("flow.permeability", f"\"grdecl\": PERMX/PERMY/PERMZ (× NTG) of {grid.source} give a "
                             f"zero permeability in {int(bad.sum())} active cell(s), e.g. cell "
                             f"{info.cell_name(np.flatnonzero(bad)[0])}; "
                             "flow needs K > 0 (make those cells inactive or give a number)")
        value = None
    elif isinstance(value, dict):
        for name, v in value.items():
            f = f"flow.permeability.{name}"
            sel = _region(mesh, name, f)
            K[sel] = _tensor(v, f, params, c[sel], d)
    elif value is not None:
        K[:] = _tensor(value, "flow.permeability", params, c, d)
    for r in flow.regions:
        sel = _region(mesh, r.name, f"flow.regions.{r.name}.name")
        K[sel] = _tensor(r.permeability, f"flow.regions.{r.name}.permeability", params, c[sel], d)
    if np.isnan(K).any():
        if flow.permeability is None and not flow.regions:
            raise InputError("flow.permeability", "is required: the matrix permeability K_m in m² (a number, a "
                             f"{d}×{d} matrix or a table by region)")
        missing = sorted({mesh.region_names[i] for i in np.unique(mesh.cell_region[np.isnan(K).any(axis=(1, 2))])})
        raise InputError("flow.permeability", f"no permeability for region(s) {', '.join(missing)}")
    return K


def _region(mesh, name: str, field: str) -> np.ndarray:
    """Cells of region ``name`` (a boolean mask); InputError naming ``field`` if the mesh has none."""
    if name not in mesh.region_names:
        raise InputError(field, f"unknown region {name!r}; the mesh has {', '.join(mesh.region_names)}")
    return mesh.cell_region == mesh.region_names.index(name)


def _by_region(value, field: str, mesh) -> np.ndarray | None:
    """(n_cells,) values of a key given as a number or a table by region (checked by the schema),
    None if absent."""
    if value is None:
        return None
    if not isinstance(value, dict):
        return np.full(mesh.n_cells, float(value))
    out = np.full(mesh.n_cells, np.nan)
    for name, v in value.items():
        if v == GRDECL:
            raise InputError(f"{field}.{name}", "\"grdecl\" applies to the whole grid, not to one region")
        out[_region(mesh, name, f"{field}.{name}")] = v
    if np.isnan(out).any():
        missing = sorted({mesh.region_names[i] for i in np.unique(mesh.cell_region[np.isnan(out)])})
        raise InputError(field, f"no value for region(s) {', '.join(missing)}")
    return out


def _grid(mesh, field: str):
    """(grid, info) of a corner-point mesh, for a value given as "grdecl"."""
    from .meshing import cornerpoint_of

    cp = cornerpoint_of(mesh)
    if cp is None:
        raise InputError(field, "\"grdecl\" takes the values from a corner-point grid's keywords, but this mesh is "
                         "not one (mesh.generator = \"grdecl\" or \"cornerpoint\")")
    return cp


def grid_porosity(mesh, field: str = "flow.porosity") -> np.ndarray:
    """(n_cells,) pore-volume fraction PORO × NTG × MULTPV of a corner-point mesh (NTG, MULTPV
    default 1)."""
    grid, info = _grid(mesh, field)
    if "PORO" not in grid.properties:
        raise InputError(field, f"\"grdecl\": {grid.source} has no PORO keyword; give the porosity as a number")
    phi = info.cell_values(grid.properties["PORO"]).astype(float)
    for kw in ("NTG", "MULTPV"):
        if kw in grid.properties:
            phi = phi * info.cell_values(grid.properties[kw])
    bad = ~((phi > 0) & (phi <= 1))
    if bad.any():
        c = np.flatnonzero(bad)[0]
        raise InputError(field, f"\"grdecl\": PORO × NTG × MULTPV of {grid.source} is {phi[c]:g} in cell "
                         f"{info.cell_name(c)} ({int(bad.sum())} cell(s) outside (0, 1])")
    return phi


def _storage(flow, mesh):
    """M (Pa): a number, inf, a table by region, or from porosity φ and fluid compressibility
    c_w as 1/M = φ c_w (incompressible grains, b = 1: the Choice of C6); φ = "grdecl" takes
    PORO × NTG × MULTPV of a corner-point grid."""
    if flow.porosity == GRDECL:
        return 1.0 / (grid_porosity(mesh) * flow.fluid_compressibility)
    if flow.porosity is not None:
        return 1.0 / (_by_region(flow.porosity, "flow.porosity", mesh) * flow.fluid_compressibility)
    M = _by_region(flow.biot_modulus, "flow.biot_modulus", mesh)
    if M is None:
        return np.inf
    return float(M[0]) if np.all(M == M[0]) else M


def fracture_variables(fm: FracturedMesh) -> dict:
    """Per-fracture-face D (distance to the nearest tip, 1e30 without tips) and L (m)."""
    net = fm.network
    D = tip_distance(fm)
    D = np.where(np.isfinite(D), D, 1e30)
    area = fm.mesh.geometry.face_area[net.faces]
    meas = np.bincount(net.fracture, weights=area, minlength=len(net.names))
    if fm.mesh.dim == 3:
        meas = np.sqrt(meas)
    return {"D": D, "L": meas[net.fracture]}


# -- main entry ----------------------------------------------------------------------------------
@case_keys(FLOW)
def flow_setup(case: CaseFile, fm: FracturedMesh) -> FlowSetup:
    """The flow tables of ``case`` as a flow model's data for the mesh ``fm`` (InputError naming the field)."""
    spec = case.spec
    mesh, net = fm.mesh, fm.network
    d = mesh.dim
    params = spec.parameters
    sec = spec.flow
    if sec is None:
        raise InputError("flow", "is required for a flow case: give at least permeability, viscosity and a "
                         "[[flow.boundary]] pressure condition")
    K = _permeability(sec, mesh, params)
    M = _storage(sec, mesh)
    fvars = fracture_variables(fm)
    xf = mesh.geometry.face_centroid[net.faces]

    def fracture_expr(key, with_t=True, extra=()):
        v = getattr(sec, key)
        # a fracture's own conductivity without a [flow] one: the cubic law elsewhere
        e = parse("d**3/12" if v is None else v, f"flow.{key}", params, extra=FRACTURE_VARS + tuple(extra))
        if not with_t and "t" in e.names:
            raise InputError(f"flow.{key}", f"expression {e.text!r} may not depend on t")
        return _per_fracture(e, key, spec.fractures, net, params, with_t, FRACTURE_VARS + tuple(extra))

    ap = fracture_expr("aperture")
    kfn = fracture_expr("normal_permeability", with_t=False)
    # the schema checked steady against [time]; the aperture is checked at the start time
    schedule = parse_schedule(spec)
    steady = schedule is None
    t0 = 0.0 if steady else schedule.start
    cols = (xf[:, 0], xf[:, 1], xf[:, 2] if d == 3 else np.zeros(net.n_faces))
    for e, key, unit in ((ap, "aperture", "m"), (kfn, "normal_permeability", "m²")):
        vals = np.broadcast_to(e(*cols, t0, **fvars), (net.n_faces,))
        bad = ~(vals > 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(e.field_of(i), f"must be positive ({unit}) on every fracture face; "
                             f"{e.text_of(i)!r} gives {vals[i]:g} on fracture {net.names[net.fracture[i]]} at "
                             f"{np.round(xf[i], 6).tolist()} (t = {t0:g} s)")
    cond_law = None
    if sec.fracture_conductivity is not None or any(f.fracture_conductivity is not None for f in spec.fractures):
        ce = fracture_expr("fracture_conductivity", with_t=False, extra=("d",))

        def cond_law(a, _e=ce):
            return np.broadcast_to(_e(*cols, 0.0, d=a, **fvars), a.shape)

        probe = cond_law(np.asarray(np.broadcast_to(ap(*cols, t0, **fvars), (net.n_faces,)), float))
        if not np.all(probe >= 0):
            i = int(np.argmin(probe))
            raise InputError(ce.field_of(i), f"must give values ≥ 0 (m³); {ce.text_of(i)!r} gives "
                             f"{float(probe[i]):g}")
    exact_name = None if spec.exact is None else spec.exact.solution
    if exact_name is not None and int(exact_name[-2]) != d:
        raise InputError("exact.solution", f"{exact_name!r} is a {exact_name[-2]}D solution but the mesh is {d}D")

    def source(key, extra):
        v = getattr(sec, key)
        if v == "exact":
            return "exact"   # the schema checked that the case has an [exact] solution
        return _point_fn(parse(v, f"flow.{key}", params, extra=extra), None if not extra else fvars)

    cell_source = _with_wells(source("source", ()), sec, mesh, params)
    fracture_source = source("fracture_source", FRACTURE_VARS)
    initial = None
    if not steady:
        if sec.initial_pressure is None:
            raise InputError("flow.initial_pressure", "is required for a transient run (Pa, expression of x, y, z)")
        initial = _point_fn(parse(sec.initial_pressure, "flow.initial_pressure", params))
    boundary = _boundary(sec, mesh, params)
    fracture_boundary = _fracture_boundary(sec, mesh, params)
    has_pressure = any(v == "exact" or isinstance(v, Pressure) for v in boundary.values()) or any(
        isinstance(v, Pressure) for v in fracture_boundary.values())
    c_f = _fracture_compressibility(spec, sec)
    no_storage = not np.any(np.isfinite(M)) and c_f == 0
    if not has_pressure and (steady or no_storage):
        raise InputError("flow.boundary", "no boundary part has a pressure condition, so the pressure is only "
                         "defined up to a constant" + (" (a steady problem)" if steady else " (no storage: "
                                                      "biot_modulus is inf)") + "; give `pressure` on at least "
                         "one [[flow.boundary]] part (parts without a block are no-flow)")
    s = spec.solver or Solver()
    data = FlowData(permeability=K, viscosity=sec.viscosity, biot_modulus=M,
                    aperture=_point_fn(ap, fvars), normal_permeability=np.broadcast_to(
                        kfn(*cols, 0.0, **fvars), (net.n_faces,)).astype(float),
                    fracture_compressibility=c_f,
                    **({"conductivity_law": cond_law} if cond_law is not None else {}))
    exact = on1 = None
    if exact_name is not None:
        exact, on1 = _exact(exact_name, fm, data, K, ap, cols, fvars)
        pexact = Pressure(exact.p)
        boundary = {k: (pexact if v == "exact" else v) for k, v in boundary.items()}
        if cell_source == "exact":
            cell_source = exact.h_m
        if fracture_source == "exact":
            fracture_source = exact.h_f(xf, on1)
    return FlowSetup(fm, data, boundary, fracture_boundary, cell_source, fracture_source,
                     solver_choice(s.linear, symmetric=True, rtol=s.linear_tolerance, **s.backend_options()), schedule,
                     initial, sec.alpha,
                     sec.fracture_alpha, exact, on1,
                     {"fracture_variables": fvars, "tan_psi": float(np.tan(np.radians(sec.dilatancy_angle))),
                      "pressure_stabilisation": sec.pressure_stabilisation}, sec.cell_point)


def _fracture_compressibility(spec, sec) -> float:
    """c_f of the fracture storage (1/Pa): flow.fracture_compressibility, or with rate-and-state
    friction, when not given, the fluid's compressibility. Without fracture storage the fault
    pressure of a step much shorter than the fault's drainage time is fixed only by the round-off
    of the normal jumps (1e-18 m moved it by 5·10⁴ Pa in a 1e-6 s step of fault-injection), which
    a Coulomb threshold absorbs but a rate-and-state slip rate, exponential in σ′/(aσ′), does not."""
    c_f = float(sec.fracture_compressibility)
    law = spec.contact.law if spec.contact is not None else None
    if law == "rate-and-state" and "fracture_compressibility" not in sec.given() and c_f == 0:
        c_f = float(sec.fluid_compressibility or 0.0)
        if c_f > 0:
            log.info("flow.fracture_compressibility = %g 1/Pa (the fluid's, for rate-and-state friction; give it to "
                     "change)", c_f)
    return c_f


class _PerFracture:
    """A fracture expression with per-fracture replacements: called like an Expression on all the
    fracture faces (arrays of n_ff values), it gives the ``[flow]`` value except on the faces of
    fractures whose ``[[fractures]]`` block has its own (``aperture``, ``normal_permeability``,
    ``fracture_conductivity``)."""

    def __init__(self, base, key: str, parts: list, fracture: np.ndarray):
        self.base, self.key, self.parts, self.fracture = base, key, parts, fracture
        self.names = set(base.names).union(*(e.names for _, _, e in parts))
        self.text = base.text if not parts else base.text + "; " + "; ".join(
            f"{name}: {e.text}" for name, _, e in parts)
        self.is_constant = False

    def __call__(self, *args, **kw):
        n = self.fracture.size
        out = np.array(np.broadcast_to(np.asarray(self.base(*args, **kw), float), (n,)))
        for _, sel, e in self.parts:
            out[sel] = np.broadcast_to(np.asarray(e(*args, **kw), float), (n,))[sel]
        return out

    def field_of(self, i: int) -> str:
        """The case-file field giving the value on fracture face i."""
        for name, sel, _ in self.parts:
            if sel[i]:
                return f"fractures.{name}.{self.key}"
        return f"flow.{self.key}"

    def text_of(self, i: int) -> str:
        for _, sel, e in self.parts:
            if sel[i]:
                return e.text
        return self.base.text


def _per_fracture(base, key: str, fractures, net, params, with_t: bool, extra) -> _PerFracture:
    """``base`` (the [flow] expression of ``key``) with the [[fractures]] blocks' own values."""
    parts = []
    for f in fractures:
        v = getattr(f, key, None)
        if v is None or f.name not in net.names:
            continue
        field = f"fractures.{f.name}.{key}"
        e = parse(v, field, params, extra=extra)
        if not with_t and "t" in e.names:
            raise InputError(field, f"expression {e.text!r} may not depend on t")
        parts.append((f.name, net.fracture == net.names.index(f.name), e))
    return _PerFracture(base, key, parts, net.fracture)


def _boundary_part(mesh, name: str, field: str) -> None:
    if name not in mesh.boundary:
        raise InputError(field, f"unknown boundary {name!r}; this mesh has {', '.join(sorted(mesh.boundary))}")


def _boundary(sec, mesh, params) -> dict:
    """Boundary part -> Pressure, Flux or "exact" from the [[flow.boundary]] blocks (one condition
    each, one block per part: checked by the schema)."""
    boundary = {}
    for b in sec.boundary:
        field = f"flow.boundary.{b.name}"
        _boundary_part(mesh, b.name, f"{field}.name")
        if b.rate is not None or b.mass_rate is not None:
            # a total injection rate, spread uniformly over the part: flux density −rate/|part|;
            # a mass rate is divided by the fluid density
            key = "rate" if b.rate is not None else "mass_rate"
            e = parse(getattr(b, key), f"{field}.{key}", params)
            if e.names - {"t"}:
                raise InputError(f"{field}.{key}", f"a rate may depend on t only (a schedule), got {e.text!r}")
            part = float(mesh.geometry.face_area[mesh.boundary[b.name]].sum())
            if key == "mass_rate":
                part *= sec.fluid_density

            def rate_flux(x, y, z, t=0.0, e=e, part=part):
                return np.broadcast_to(-np.asarray(e(t=t), float) / part, np.shape(x)).astype(float)

            rate_flux.text = f"-({e.text})/{part:g}"
            boundary[b.name] = Flux(float(-e() / part) if e.is_constant else rate_flux)
            continue
        key = "pressure" if b.pressure is not None else "flux"
        v = getattr(b, key)
        if v == "exact":
            boundary[b.name] = "exact"
            continue
        fn = parse(v, f"{field}.{key}", params)
        val = float(fn()) if fn.is_constant else _point_fn(fn)
        boundary[b.name] = Pressure(val) if key == "pressure" else Flux(val)
    return boundary


def _fracture_boundary(sec, mesh, params) -> dict:
    """Boundary part -> Pressure or NO_FLOW for the fracture ends ([[flow.fracture_boundary]])."""
    out = {}
    for b in sec.fracture_boundary:
        field = f"flow.fracture_boundary.{b.name}"
        _boundary_part(mesh, b.name, f"{field}.name")
        if b.no_flow:
            out[b.name] = NO_FLOW
        else:
            fn = parse(b.pressure, f"{field}.pressure", params)
            out[b.name] = Pressure(float(fn()) if fn.is_constant else _point_fn(fn))
    return out


def _exact(name, fm, data: FlowData, K, ap, cols, fvars):
    """The manufactured solution with κ, Λ and C taken from the case's (uniform) data."""
    field = "exact.solution"
    on1 = gamma1_mask(fm, field)
    d = fm.mesh.dim
    k0 = K[0, 0, 0]
    if not (np.allclose(K, k0 * np.eye(d)[None], rtol=1e-12, atol=0)):
        raise InputError(field, "the manufactured Darcy solution needs a uniform isotropic permeability")
    a = np.asarray(np.broadcast_to(ap(*cols, 0.0, **fvars), (fm.network.n_faces,)), float)
    if ap.names - {"t"} and np.ptp(a) > 0 or "t" in ap.names:
        raise InputError(field, "the manufactured Darcy solution needs a uniform constant aperture")
    kfn = np.asarray(data.normal_permeability, float)
    if np.ptp(kfn) > 1e-12 * abs(kfn[0]):
        raise InputError(field, "the manufactured Darcy solution needs a uniform normal permeability")
    eta = data.viscosity
    lam = np.asarray(data.normal_transmissivity_law(a, kfn), float)
    cond = np.asarray(data.conductivity_law(a), float)
    if np.ptp(cond) > 1e-12 * abs(cond[0]):
        raise InputError(field, "the manufactured Darcy solution needs a uniform fracture conductivity")
    return DarcyManufactured(d, kappa=k0 / eta, lam=float(lam[0]) / eta, cond=float(cond[0]) / eta), on1


def well_cells(mesh, well, field: str) -> np.ndarray:
    """Mesh cells of a ``[[flow.wells]]`` block: its column (i, j) and layers k1...k2 (1-based, of
    the grid as given: with ``mesh.refine`` the well is the middle child column, or for an even
    factor the 2 (or 2 × 2) middle columns, around the old column's centre line, through all the
    children of its layers, so that the well stays where it was)."""
    from ..mesh.cornerpoint.refine import centre_children, child_range
    from .meshing import cornerpoint_refinement

    grid, info = _grid(mesh, f"{field}.column")
    ri, rj, rk = cornerpoint_refinement(mesh)
    nx, ny, nz = grid.dims[0] // ri, grid.dims[1] // rj, grid.dims[2] // rk
    i, j = (int(a) for a in well.column)
    if not (1 <= i <= nx and 1 <= j <= ny):
        raise InputError(f"{field}.column", f"[{i}, {j}] lies outside the grid: i in 1 ... {nx}, j in 1 ... {ny}")
    k1, k2 = (1, nz) if well.layers is None else (int(a) for a in well.layers)
    if k2 > nz:
        raise InputError(f"{field}.layers", f"[{k1}, {k2}] goes below the grid's {nz} layers")
    K1, K2 = child_range(k1, k2, rk)
    cells = info.cells_in(centre_children(i - 1, ri), centre_children(j - 1, rj), (K1 - 1, K2 - 1))
    if cells.size == 0:
        raise InputError(f"{field}.column", f"column [{i}, {j}], layers {k1} ... {k2}, has no active cell")
    return cells


def _with_wells(base, sec, mesh, params):
    """The cell source h_m (1/s) plus the wells' rates, each spread over its cells by volume."""
    if not sec.wells:
        return base
    if base == "exact":
        raise InputError("flow.wells", "wells cannot be combined with source = \"exact\"")
    vol = mesh.geometry.cell_volume
    wells = []
    for w in sec.wells:
        field = f"flow.wells.{w.name}"
        cells = well_cells(mesh, w, field)
        key = "rate" if w.rate is not None else "mass_rate"
        e = parse(getattr(w, key), f"{field}.{key}", params)
        if e.names - {"t"}:
            raise InputError(f"{field}.{key}", f"a rate may depend on t only (a schedule), got {e.text!r}")
        scale = 1.0 / (float(vol[cells].sum()) * (sec.fluid_density if key == "mass_rate" else 1.0))
        wells.append((cells, e, scale))
        log.info("well %s: %d cells, %.4g m³", w.name, cells.size, float(vol[cells].sum()))
    n = mesh.n_cells

    def source(x, y, z, t=0.0):
        h = np.array(np.broadcast_to(evaluate(base, np.stack([x, y, z], 1), t, "flow.source"), (n,)), float)
        for cells, e, scale in wells:
            h[cells] += float(e(t=t)) * scale
        return h

    source.text = f"source + {len(wells)} well(s)"
    return source
