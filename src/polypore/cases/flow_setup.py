"""From a case's ``[flow]``, ``[time]``, ``[exact]`` and ``[solver]`` tables to a :class:`FlowModel`.

Schema (SI units; every value may be a number or an expression, see below)::

    [flow]
    permeability = 1e-15             # K_m (m²): a number or expression of x, y, z (isotropic),
                                     # a d×d matrix [[kxx, kxy], [kxy, kyy]] (numbers/expressions),
                                     # or a table by region: {reservoir = 1e-13, caprock = 1e-19}
    viscosity = 1e-3                 # η (Pa·s) > 0
    biot_modulus = 1e10              # M (Pa) > 0, or "inf" (no matrix storage; the default),
                                     # or a table by region
    # porosity = {reservoir = 0.1, caprock = 0.01}   # instead of biot_modulus: 1/M = φ c_w
    # fluid_compressibility = 4.4e-10                # c_w (1/Pa), with porosity
    fracture_compressibility = 0.0   # c_f (1/Pa) ≥ 0
    dilatancy_angle = 0.0            # ψ (degrees) of d_f = d_f^c − [[u]]_n + tan ψ |[[u − u⁰]]_τ|
                                     # (poromechanics)
    aperture = 1e-4                  # d_f (m) > 0: expression of x, y, z, t, D, L
    normal_permeability = 1e-15      # K_fn (m²) > 0: expression of x, y, z, D, L
    fracture_conductivity = "d**3/12"  # C_f (m³): expression of the aperture d (and x, y, z, D, L)
    source = 0.0                     # h_m (m³/s per m³ = 1/s): expression of x, y, z, t, or "exact"
    fracture_source = 0.0            # h_f (m/s): expression of x, y, z, t, D, L, or "exact"
    initial_pressure = 1e5           # p⁰ (Pa) of a transient run: expression of x, y, z
    steady = true                    # default: true unless the case has a [time] table
    alpha = 1.414                    # HFV stabilisation α (default √d); fracture_alpha (√(d−1))
    pressure_stabilisation = 0.25    # δ ≥ 0 of the poromechanics pressure-jump stabilisation
                                     # (Poromechanics.stabilisation_matrix); 0 switches it off

    [[flow.regions]]                 # per-region permeability (overrides `permeability` there)
    name = "reservoir"
    permeability = 1e-13

    [[flow.boundary]]                # one block per boundary part; parts without one are no-flow
    name = "xmin"                    # xmin ... zmax or a mesh physical group
    pressure = 1e5                   # Pa: expression of x, y, z, t, or "exact"
    # flux = -1e-9                   # outward flux density (m/s); < 0 injects
    # mass_rate = 0.02               # or an injected mass rate (kg/s; kg/s per metre in 2D), divided
                                     # by [flow] fluid_density (default 1000 kg/m³)
    # rate = 1e-6                    # injected volume rate through the part (m³/s; m²/s per metre
                                     # in 2D), spread uniformly; an expression of t (a schedule)

    [[flow.fracture_boundary]]       # fracture ends on a boundary part where the matrix has no
    name = "xmax"                    # pressure: give them one (or no_flow = true)
    pressure = 2e5

    [time]                           # transient runs (implicit Euler)
    start = 0.0
    end = 2000.0
    step = 20.0
    output_every = 1                 # write VTU files every n steps (and at the end)

    [exact]
    solution = "darcy-manufactured-2d"   # or darcy-manufactured-3d

    [solver]
    linear = "auto"                  # auto | superlu | pardiso | amg
    linear_tolerance = 1e-10         # relative residual of iterative backends

Variables in fracture expressions: ``D`` the distance (m) from the face centroid to the
nearest tip of the same fracture (1e30 on a fracture without tips), ``L`` the fracture's
length in 2D, the square root of its area in 3D (m).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError
from ..core.expressions import parse
from ..mesh import FracturedMesh
from ..models.flow import FlowData, FlowModel, Flux, NO_FLOW, Pressure, permeability_tensor
from ..models.fracture_geometry import tip_distance
from ..solvers.linear import BACKENDS, LinearSolver
from .schedule import TimeSchedule, parse_schedule  # noqa: F401 (re-exported)
from .casefile import CaseFile, Section
from .flow_exact import NAMES as EXACT_NAMES, DarcyManufactured, gamma1_mask
from .mechanics_setup import parameters

FRACTURE_VARS = ("D", "L")


@dataclass
class FlowSetup:
    """Everything a flow run needs, validated against the mesh."""

    fm: FracturedMesh
    data: FlowData
    boundary: dict
    fracture_boundary: dict
    cell_source: object
    fracture_source: object
    solver: LinearSolver
    schedule: TimeSchedule | None = None
    initial_pressure: object = None
    alpha: float | None = None
    fracture_alpha: float | None = None
    exact: DarcyManufactured | None = None
    on_gamma1: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    @property
    def steady(self) -> bool:
        return self.schedule is None

    def model(self) -> FlowModel:
        return FlowModel(self.fm, self.data, self.boundary, fracture_boundary=self.fracture_boundary,
                         cell_source=self.cell_source, fracture_source=self.fracture_source, alpha=self.alpha,
                         fracture_alpha=self.fracture_alpha, solver=self.solver)


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


def _permeability(sec: Section, mesh, params) -> np.ndarray:
    d, nc = mesh.dim, mesh.n_cells
    c = mesh.geometry.cell_centroid
    K = np.full((nc, d, d), np.nan)
    value = sec.raw("permeability", None)
    if isinstance(value, dict):
        for name, v in value.items():
            f = sec.field(f"permeability.{name}")
            if name not in mesh.region_names:
                raise InputError(f, f"unknown region {name!r}; the mesh has {', '.join(mesh.region_names)}")
            sel = mesh.cell_region == mesh.region_names.index(name)
            K[sel] = _tensor(v, f, params, c[sel], d)
    elif value is not None:
        K[:] = _tensor(value, sec.field("permeability"), params, c, d)
    for r in sec.sections("regions"):
        name = r.string("name")
        if name not in mesh.region_names:
            raise InputError(r.field("name"), f"unknown region {name!r}; the mesh has {', '.join(mesh.region_names)}")
        sel = mesh.cell_region == mesh.region_names.index(name)
        K[sel] = _tensor(r.raw("permeability"), r.field("permeability"), params, c[sel], d)
        r.done()
    if np.isnan(K).any():
        if value is None and not sec.data.get("regions"):
            raise InputError(sec.field("permeability"), "is required: the matrix permeability K_m in m² (a number, a "
                             f"{d}×{d} matrix or a table by region)")
        missing = sorted({mesh.region_names[i] for i in np.unique(mesh.cell_region[np.isnan(K).any(axis=(1, 2))])})
        raise InputError(sec.field("permeability"), f"no permeability for region(s) {', '.join(missing)}")
    return K


def _by_region(sec: Section, key: str, mesh, check) -> np.ndarray | None:
    """(n_cells,) values of a key given as a number or a table by region, None if absent."""
    value = sec.raw(key, None)
    if value is None:
        return None
    if not isinstance(value, dict):
        return np.full(mesh.n_cells, check(value, sec.field(key)))
    out = np.full(mesh.n_cells, np.nan)
    for name, v in value.items():
        f = sec.field(f"{key}.{name}")
        if name not in mesh.region_names:
            raise InputError(f, f"unknown region {name!r}; the mesh has {', '.join(mesh.region_names)}")
        out[mesh.cell_region == mesh.region_names.index(name)] = check(v, f)
    if np.isnan(out).any():
        missing = sorted({mesh.region_names[i] for i in np.unique(mesh.cell_region[np.isnan(out)])})
        raise InputError(sec.field(key), f"no value for region(s) {', '.join(missing)}")
    return out


def _storage(sec: Section, mesh):
    """M (Pa): a number, "inf", a table by region, or from porosity φ and fluid compressibility
    c_w as 1/M = φ c_w (incompressible grains, b = 1: the Choice of C6)."""

    def modulus(v, f):
        if isinstance(v, str) and v.strip().lower() in ("inf", "infinity"):
            return np.inf
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
            raise InputError(f, f"must be a positive number (Pa) or \"inf\" (no storage), got {v!r}")
        return float(v)

    def porosity(v, f):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v <= 1:
            raise InputError(f, f"must be a number in (0, 1], got {v!r}")
        return float(v)

    if sec.has("porosity"):
        if sec.has("biot_modulus"):
            raise InputError(sec.field("porosity"), "give either biot_modulus or porosity (with "
                             "fluid_compressibility), not both")
        cw = sec.number("fluid_compressibility", None, positive=True)
        if cw is None:
            raise InputError(sec.field("fluid_compressibility"), "is required with porosity (1/Pa)")
        return 1.0 / (_by_region(sec, "porosity", mesh, porosity) * cw)
    M = _by_region(sec, "biot_modulus", mesh, modulus)
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
def flow_setup(case: CaseFile, fm: FracturedMesh) -> FlowSetup:
    """Read and validate every flow-related table of ``case`` for the mesh ``fm``."""
    root = case.root()
    mesh, net = fm.mesh, fm.network
    d = mesh.dim
    params = parameters(root)
    sec = root.section("flow", None)
    if not sec.data:
        raise InputError("flow", "is required for a flow case: give at least permeability, viscosity and a "
                         "[[flow.boundary]] pressure condition")
    K = _permeability(sec, mesh, params)
    eta = sec.raw("viscosity", 1e-3)
    if isinstance(eta, bool) or not isinstance(eta, (int, float)) or not (0 < eta < np.inf):
        raise InputError(sec.field("viscosity"), f"must be a positive number (Pa·s), got {eta!r}")
    M = _storage(sec, mesh)
    cf = sec.number("fracture_compressibility", 0.0, nonneg=True)
    psi = sec.number("dilatancy_angle", 0.0, nonneg=True)
    delta = sec.number("pressure_stabilisation", None, nonneg=True)     # None: the model's default
    if not psi < 90:
        raise InputError(sec.field("dilatancy_angle"), f"must be an angle in [0, 90) degrees, got {psi!r}")
    fvars = fracture_variables(fm)
    xf = mesh.geometry.face_centroid[net.faces]

    def fracture_expr(key, default, with_t=True, extra=()):
        v = sec.raw(key, default)
        e = parse(v, sec.field(key), params, extra=FRACTURE_VARS + tuple(extra))
        if not with_t and "t" in e.names:
            raise InputError(sec.field(key), f"expression {e.text!r} may not depend on t")
        return e

    ap = fracture_expr("aperture", 1e-4)
    kfn = fracture_expr("normal_permeability", 1e-15, with_t=False)
    t0 = 0.0
    # time schedule first: the aperture is checked at the start time
    steady_default = not root.has("time")
    steady = sec.boolean("steady", steady_default)
    schedule = None
    if root.has("time"):
        if steady:
            raise InputError(sec.field("steady"), "is true but the case has a [time] table; remove one of them "
                             "(steady = false for a transient run)")
        schedule = parse_schedule(root)
        t0 = schedule.start
    elif not steady:
        raise InputError(sec.field("steady"), "is false but the case has no [time] table (end, step in s)")
    cols = (xf[:, 0], xf[:, 1], xf[:, 2] if d == 3 else np.zeros(net.n_faces))
    for e, key, unit in ((ap, "aperture", "m"), (kfn, "normal_permeability", "m²")):
        with np.errstate(all="ignore"):
            vals = np.broadcast_to(e(*cols, t0, **fvars), (net.n_faces,))
        bad = ~(vals > 0) | ~np.isfinite(vals)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(sec.field(key), f"must be positive and finite ({unit}) on every fracture face; "
                             f"{e.text!r} gives {vals[i]:g} on fracture {net.names[net.fracture[i]]} at "
                             f"{np.round(xf[i], 6).tolist()} (t = {t0:g} s)")
    cond_law = None
    if sec.has("fracture_conductivity"):
        ce = fracture_expr("fracture_conductivity", None, with_t=False, extra=("d",))

        def cond_law(a, _e=ce):
            with np.errstate(all="ignore"):
                return np.broadcast_to(_e(*cols, 0.0, d=a, **fvars), a.shape)

        probe = cond_law(np.asarray(np.broadcast_to(ap(*cols, t0, **fvars), (net.n_faces,)), float))
        if not (np.all(probe >= 0) and np.all(np.isfinite(probe))):
            raise InputError(sec.field("fracture_conductivity"), f"must give finite values ≥ 0 (m³); {ce.text!r} "
                             f"gives {float(np.nanmin(probe)):g}")
    ex_sec = root.section("exact", None)
    exact_name = None
    if ex_sec.data:
        exact_name = ex_sec.string("solution", choices=EXACT_NAMES)
        if int(exact_name[-2]) != d:
            raise InputError(ex_sec.field("solution"), f"{exact_name!r} is a {exact_name[-2]}D solution but the "
                             f"mesh is {d}D")
        ex_sec.done()

    def source(key, extra):
        v = sec.raw(key, 0.0)
        if isinstance(v, str) and v.strip() == "exact":
            if exact_name is None:
                raise InputError(sec.field(key), '"exact" needs an [exact] solution in the case')
            return "exact"
        return _point_fn(parse(v, sec.field(key), params, extra=extra), None if not extra else fvars)

    cell_source = source("source", ())
    fracture_source = source("fracture_source", FRACTURE_VARS)
    init = sec.raw("initial_pressure", None)
    initial = None
    if schedule is not None:
        if init is None:
            raise InputError(sec.field("initial_pressure"), "is required for a transient run (Pa, expression of "
                             "x, y, z)")
        initial = _point_fn(parse(init, sec.field("initial_pressure"), params))
    elif init is not None:
        raise InputError(sec.field("initial_pressure"), "only applies to a transient run (a [time] table)")
    alpha = sec.number("alpha", None, positive=True)
    falpha = sec.number("fracture_alpha", None, positive=True)
    # boundary conditions
    rho_w = sec.number("fluid_density", 1000.0, positive=True)     # kg/m³, for mass rates
    boundary, seen = {}, {}
    for b in sec.sections("boundary"):
        name = b.string("name")
        if name not in mesh.boundary:
            raise InputError(b.field("name"), f"unknown boundary {name!r}; this mesh has "
                             f"{', '.join(sorted(mesh.boundary))}")
        if name in seen:
            raise InputError(b.field("name"), f"boundary {name!r} is given twice; one [[flow.boundary]] per part")
        seen[name] = b
        has_p, has_q, has_r, has_m = b.has("pressure"), b.has("flux"), b.has("rate"), b.has("mass_rate")
        if has_p + has_q + has_r + has_m != 1:
            raise InputError(b.field("pressure" if not has_p else "flux"),
                             "give exactly one of pressure (Pa), flux (outward, m/s), rate (injected, m³/s; "
                             "m²/s per metre in 2D) or mass_rate (injected, kg/s; kg/s per metre in 2D) for "
                             "this boundary part")
        if has_r or has_m:
            # a total injection rate, spread uniformly over the part: flux density −rate/|part|;
            # a mass rate is divided by the fluid density
            key = "rate" if has_r else "mass_rate"
            e = parse(b.raw(key), b.field(key), params)
            if e.names - {"t"}:
                raise InputError(b.field(key), f"a rate may depend on t only (a schedule), got {e.text!r}")
            part = float(mesh.geometry.face_area[mesh.boundary[name]].sum())
            if has_m:
                part *= rho_w

            def rate_flux(x, y, z, t=0.0, e=e, part=part):
                return np.broadcast_to(-np.asarray(e(t=t), float) / part, np.shape(x)).astype(float)

            rate_flux.text = f"-({e.text})/{part:g}"
            boundary[name] = Flux(float(-e() / part) if e.is_constant else rate_flux)
            b.done()
            continue
        key = "pressure" if has_p else "flux"
        v = b.raw(key)
        if isinstance(v, str) and v.strip() == "exact":
            if exact_name is None:
                raise InputError(b.field(key), '"exact" needs an [exact] solution in the case')
            if key == "flux":
                raise InputError(b.field(key), '"exact" is only available for pressure conditions')
            boundary[name] = "exact"
        else:
            fn = parse(v, b.field(key), params)
            val = float(fn()) if fn.is_constant else _point_fn(fn)
            boundary[name] = Pressure(val) if has_p else Flux(val)
        b.done()
    fracture_boundary = {}
    for b in sec.sections("fracture_boundary"):
        name = b.string("name")
        if name not in mesh.boundary:
            raise InputError(b.field("name"), f"unknown boundary {name!r}; this mesh has "
                             f"{', '.join(sorted(mesh.boundary))}")
        if b.has("pressure") == b.has("no_flow"):
            raise InputError(b.field("pressure"), "give exactly one of pressure (Pa) or no_flow = true")
        if b.has("no_flow"):
            if not b.boolean("no_flow"):
                raise InputError(b.field("no_flow"), "only no_flow = true is meaningful (omit the block otherwise)")
            fracture_boundary[name] = NO_FLOW
        else:
            fn = parse(b.raw("pressure"), b.field("pressure"), params)
            fracture_boundary[name] = Pressure(float(fn()) if fn.is_constant else _point_fn(fn))
        b.done()
    sec.done()
    has_pressure = any(v == "exact" or isinstance(v, Pressure) for v in boundary.values()) or any(
        isinstance(v, Pressure) for v in fracture_boundary.values())
    no_storage = not np.any(np.isfinite(M)) and cf == 0
    if not has_pressure and (steady or no_storage):
        raise InputError("flow.boundary", "no boundary part has a pressure condition, so the pressure is only "
                         "defined up to a constant" + (" (a steady problem)" if steady else " (no storage: "
                                                      "biot_modulus is inf)") + "; give `pressure` on at least "
                         "one [[flow.boundary]] part (parts without a block are no-flow)")
    s = root.section("solver", None)
    backend = s.string("linear", "auto", BACKENDS)
    rtol = s.number("linear_tolerance", 1e-10, positive=True)
    s.done()
    data = FlowData(permeability=K, viscosity=float(eta), biot_modulus=M,
                    aperture=_point_fn(ap, fvars), normal_permeability=np.broadcast_to(
                        kfn(*cols, 0.0, **fvars), (net.n_faces,)).astype(float),
                    fracture_compressibility=cf,
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
                     LinearSolver(backend, symmetric=True, rtol=rtol), schedule, initial, alpha, falpha, exact, on1,
                     {"fracture_variables": fvars, "tan_psi": float(np.tan(np.radians(psi))),
                      "pressure_stabilisation": delta})


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
