"""From a case's ``[material]``, ``[mechanics]``, ``[contact]``, ``[exact]`` and ``[solver]``
tables to the model's plain data (:class:`~polypore.models.mechanics.MechanicsData`).

Schema (SI units)::

    [parameters]               # named constants usable in every expression
    sigma = 1e8

    [material]                 # uniform; or [[materials]] blocks with `region = "name"`
    E = 1e10                   # Pa  (or mu = ..., lambda = ...)
    nu = 0.2

    [mechanics]
    bubbles = "one-sided"      # or "two-sided"
    stabilisation = 1.0
    body_force = [0, "-2260*9.81"]     # N/m3, expressions of x, y, z, t, or "exact"
    matrix_pressure = "1e5"            # p_m (Pa), Biot term -b p_m I
    biot = 1.0                 # b in [0, 1]; 0 decouples
    fracture_pressure = 0              # p_f (Pa) on the fracture faces
    initial_stress = [["sxx", "sxy"], ["sxy", "syy"]]   # Pa, total stress = σ0 + σ(u)

    [[mechanics.boundary]]     # one block per boundary part (xmin ... zmax or mesh groups)
    name = "xmin"
    u = [0, 0]                 # all components (m), or "exact"
    ux = 0                     # some components (rollers): ux, uy, uz
    traction = [-1e8, 0]       # Pa, σ n on the part; 0 in the components u/ux/uy/uz hold

    [contact]                  # not needed without fractures
    law = "coulomb"            # frictionless | tresca | coulomb
    friction = 0.5             # F; expression of x, y, z and D (distance to the fracture's nearest tip)
    threshold = 0              # Tresca g (Pa), same variables
    beta = 1.0                 # c in β = c (2μ + λ_L)/h_σ
    initial = "closed"         # first Newton iterate: closed (bonded) or open (λ = 0)

    [exact]
    solution = "frictionless-3d"
    # or solution = "penny-shaped-crack" (cases/penny_exact.py) with:
    fracture = "crack"         # the circular crack (a regular polygon); default: the only fracture
    stress = [[0, 0, 0], [0, 0, 0], [0, 0, 0]]   # remote stress (Pa, tension positive; expressions
                               # of [parameters]), realised by the boundary conditions
    pressure = 1e7             # p on the faces (Pa); default: mechanics.fracture_pressure
    radius = 1.0               # a (m); default: the polygon's circumradius

    [solver]
    linear = "auto"            # auto | superlu | pardiso | amg
    tolerance = 1e-8
    max_iterations = 50
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from ..core.expressions import parse
from ..mesh import FracturedMesh
from ..models.contact import LAWS
from ..models.fracture_geometry import tip_distance
from ..models.materials import check_elastic, lame
from ..models.mechanics import ContactSpec, DisplacementBC, MechanicsData, TractionBC
from ..solvers.linear import BACKENDS, LinearSolver
from ..solvers.newton import NewtonOptions
from .casefile import CaseFile, Section
from .exact import SingleCrack, get_solution
from .penny_exact import PennyCrack, penny_crack
from .reference import REFERENCES, load_reference

log = logging.getLogger("polypore")


@dataclass
class MechanicsSetup:
    data: MechanicsData
    solver: LinearSolver
    newton: NewtonOptions
    exact: object | None
    E: np.ndarray
    nu: np.ndarray


def parameters(root: Section) -> dict:
    sec = root.section("parameters")
    out = {}
    for key in list(sec.data):
        out[key] = sec.number(key)
    sec.done()
    return out


def vector_field(value, field: str, dim: int, params, exact=None, exact_fn=None):
    """A vector field (X (n, d), t) -> (n, d) from a list of d numbers/expressions or "exact"."""
    if isinstance(value, str) and value == "exact":
        if exact is None:
            raise InputError(field, '"exact" needs an [exact] solution in the case')
        return exact_fn
    if not isinstance(value, list) or len(value) != dim:
        raise InputError(field, f"expected a list of {dim} numbers or expressions of x, y, z, t, got {value!r}")
    exprs = [parse(v, f"{field}[{i}]", params) for i, v in enumerate(value)]

    def fn(X, t=0.0):
        X = np.atleast_2d(X)
        cols = {k: X[:, i] for i, k in enumerate("xyz"[:X.shape[1]])}
        return np.stack([np.broadcast_to(e(t=t, **cols), (X.shape[0],)) for e in exprs], axis=1)

    return fn


def scalar_field(value, field: str, params):
    e = parse(value, field, params)

    def fn(X, t=0.0):
        X = np.atleast_2d(X)
        cols = {k: X[:, i] for i, k in enumerate("xyz"[:X.shape[1]])}
        return np.broadcast_to(e(t=t, **cols), (X.shape[0],)).astype(float)

    return fn


def tensor_field(value, field: str, dim: int, params):
    if not (isinstance(value, list) and len(value) == dim and all(isinstance(r, list) and len(r) == dim for r in value)):
        raise InputError(field, f"expected a {dim}×{dim} list of lists of numbers or expressions, got {value!r}")
    rows = [vector_field(r, f"{field}[{i}]", dim, params) for i, r in enumerate(value)]

    def fn(X, t=0.0):
        return np.stack([r(X, t) for r in rows], axis=1)

    return fn


def _materials(root: Section, fm: FracturedMesh):
    mesh = fm.mesh
    nc = mesh.n_cells
    E = np.full(nc, np.nan)
    nu = np.full(nc, np.nan)

    def read(sec: Section):
        if sec.has("mu") or sec.has("lambda"):
            mu = sec.number("mu")
            lam = sec.number("lambda")
            if not mu > 0:
                raise InputError(sec.field("mu"), f"the shear modulus must be positive (Pa), got {mu!r}")
            e = mu * (3 * lam + 2 * mu) / (lam + mu)
            n = lam / (2 * (lam + mu))
        else:
            e, n = sec.number("E"), sec.number("nu")
        check_elastic(e, n, sec.path)
        return e, n

    if root.has("materials"):
        for sec in root.sections("materials"):
            region = sec.string("region")
            if region not in mesh.region_names:
                raise InputError(sec.field("region"), f"unknown region {region!r}; the mesh has "
                                 f"{', '.join(mesh.region_names)}")
            sel = mesh.cell_region == mesh.region_names.index(region)
            E[sel], nu[sel] = read(sec)
            sec.done(ignore=("name",))
        if np.isnan(E).any():
            missing = sorted({mesh.region_names[r] for r in np.unique(mesh.cell_region[np.isnan(E)])})
            raise InputError("materials", f"no material for region(s) {', '.join(missing)}")
    else:
        sec = root.section("material", None)
        if not sec.data:
            raise InputError("material", "is required: give E (Pa) and nu, e.g. [material] E = 1e10, nu = 0.25")
        E[:], nu[:] = read(sec)
        sec.done()
    return E, nu


def mechanics_setup(case: CaseFile, fm: FracturedMesh) -> MechanicsSetup:
    """Read and validate every mechanics-related table of the case for the mesh ``fm``."""
    root = case.root()
    mesh = fm.mesh
    d = mesh.dim
    params = parameters(root)
    E, nu = _materials(root, fm)
    mu, lam = lame(E, nu)
    ex = root.section("exact", None)
    exact = None
    if ex.data:
        name = ex.string("solution")
        if not (np.ptp(mu) == 0 and np.ptp(lam) == 0):
            raise InputError("exact.solution", "exact solutions need one uniform material")
        if name == "single-crack":
            # the friction coefficient is filled in once [contact] has been read
            exact = SingleCrack(ex.number("sigma", positive=True), np.deg2rad(ex.number("psi_deg", lo=0, hi=90)),
                                ex.number("half_length", positive=True), float(E[0]), float(nu[0]), 0.0)
        elif name in REFERENCES:
            exact = load_reference(name, ex.field("solution"))
        elif name == "penny-shaped-crack":
            # pressure and friction are filled in once [mechanics] and [contact] have been read
            exact = _penny_table(ex, fm, params, float(E[0]), float(nu[0]))
        else:
            exact = get_solution(name, mu[0], lam[0])
        ex.done()
    sec = root.section("mechanics", None)
    bubbles = sec.string("bubbles", "one-sided", ("one-sided", "two-sided"))
    if bubbles == "one-sided" and root.data.get("mesh", {}).get("mirror", "none") != "none":
        log.warning("mesh.mirror with one-sided bubbles: the bubbles sit on one side of each fracture, "
                    "which breaks the mirror symmetry; set mechanics.bubbles = \"two-sided\" to get its benefit")
    stab = sec.number("stabilisation", 1.0, positive=True)
    body = sec.raw("body_force", None)
    body_f = None if body is None else vector_field(body, sec.field("body_force"), d, params, exact,
                                                     getattr(exact, "body_force", None))
    pm = sec.raw("matrix_pressure", None)
    pm_f = None if pm is None else scalar_field(pm, sec.field("matrix_pressure"), params)
    biot = sec.number("biot", 1.0)
    if not 0 <= biot <= 1:
        raise InputError(sec.field("biot"), f"the Biot coefficient must lie in [0, 1] (0: no coupling), got {biot!r}")
    pf = sec.raw("fracture_pressure", None)
    pf_f = None if pf is None else scalar_field(pf, sec.field("fracture_pressure"), params)
    s0 = sec.raw("initial_stress", None)
    s0_f = None if s0 is None else tensor_field(s0, sec.field("initial_stress"), d, params)
    disp, trac, seen = [], [], set()
    for b in sec.sections("boundary"):
        name = b.string("name")
        if name not in mesh.boundary:
            raise InputError(b.field("name"), f"unknown boundary {name!r}; this mesh has "
                             f"{', '.join(sorted(mesh.boundary))}")
        if name in seen:
            # the model would apply both: later displacements overwrite earlier ones, tractions add up
            raise InputError(b.field("name"), f"boundary {name!r} is given twice; one [[mechanics.boundary]] "
                             "block per part (put its u/ux/uy/uz and traction together)")
        seen.add(name)
        _check_traction(b, d)
        if b.has("u"):
            disp.append(DisplacementBC(name, tuple(range(d)), vector_field(b.raw("u"), b.field("u"), d, params, exact,
                                                                           getattr(exact, "u", None))))
        for i, key in enumerate(("ux", "uy", "uz")[:d]):
            if b.has(key):
                if b.has("u"):
                    raise InputError(b.field(key), "conflicts with `u` on the same boundary part")
                vals = [0.0] * d
                vals[i] = b.raw(key)
                disp.append(DisplacementBC(name, (i,), vector_field(vals, b.field(key), d, params)))
        if b.has("traction"):
            trac.append(TractionBC(name, vector_field(b.raw("traction"), b.field("traction"), d, params, exact,
                                                      None)))
        b.done()
    sec.done()
    # contact
    c = root.section("contact", None)
    law = c.string("law", "coulomb", LAWS)
    D = tip_distance(fm)
    Dfin = np.where(np.isfinite(D), D, 1e30)
    xf = mesh.geometry.face_centroid[fm.network.faces]
    cols = {k: xf[:, i] for i, k in enumerate("xyz"[:d])}

    def face_values(key, default):
        v = c.raw(key, default)
        e = parse(v, c.field(key), params, extra=("D",))
        out = np.broadcast_to(e(**cols, D=Dfin), (fm.network.n_faces,)).astype(float)
        if np.any(~np.isfinite(out)) or np.any(out < 0):
            raise InputError(c.field(key), f"must be finite and ≥ 0 on every fracture face, got {v!r} "
                             f"(min {np.nanmin(out) if out.size else 0:g})")
        return out

    # without fracture faces there is no contact: the case needs no [contact] table
    if law == "coulomb" and fm.network.n_faces and not c.has("friction"):
        raise InputError(c.field("friction"), "is required for the Coulomb law (a number ≥ 0 or an expression of "
                         "x, y, z and D, the distance to the fracture's nearest tip)")
    friction = face_values("friction", 0.0)
    threshold = face_values("threshold", 0.0)
    beta = c.number("beta", 1.0, positive=True)
    initial = c.string("initial", "closed", ("closed", "open"))
    c.done()
    if isinstance(exact, SingleCrack):
        if np.ptp(friction) > 0:
            raise InputError("contact.friction", "the single-crack analytic solution needs one friction coefficient")
        exact = dataclasses.replace(exact, friction=float(friction[0]) if friction.size else 0.0)
    if isinstance(exact, PennyCrack):
        exact = _penny_loads(exact, fm, friction, pf_f)
    s = root.section("solver", None)
    backend = s.string("linear", "auto", BACKENDS)
    newton = NewtonOptions(tol=s.number("tolerance", 1e-8, positive=True),
                           increment_tol=s.number("increment_tolerance", 1e-8, positive=True),
                           max_iterations=s.number("max_iterations", 50, integer=True, positive=True),
                           label="contact Newton")
    s.done()
    data = MechanicsData(mu=mu, lam=lam, displacement=tuple(disp), traction=tuple(trac), body_force=body_f,
                         matrix_pressure=pm_f, biot=biot, fracture_pressure=pf_f, initial_stress=s0_f,
                         contact=ContactSpec(law, friction, threshold, beta, initial), two_sided=bubbles == "two-sided",
                         stabilisation=stab)
    return MechanicsSetup(data, LinearSolver(backend), newton, exact, E, nu)


def _check_traction(b: Section, d: int) -> None:
    """A traction on a part must be 0 in every component its displacement condition holds: the
    model drops the traction there, so a non-zero value would be silently ignored."""
    if not b.has("traction"):
        return
    keys = ("ux", "uy", "uz")[:d]
    held = [i for i, k in enumerate(keys) if b.has("u") or b.has(k)]
    if not held:
        return
    t = b.data["traction"]

    def zero(v):
        try:
            return not isinstance(v, bool) and float(v) == 0
        except (TypeError, ValueError):
            return False

    bad = [i for i in held if not (isinstance(t, list) and len(t) == d and zero(t[i]))]
    if bad:
        given = "u" if b.has("u") else ", ".join(keys[i] for i in held)
        raise InputError(b.field("traction"), f"{t!r} conflicts with the displacement condition {given} on the "
                         f"same part: its {'xyz'[bad[0]]} component would be ignored; give the traction only in "
                         f"the free components (0 in {', '.join('xyz'[i] for i in held)}) or drop {given}")


def _penny_table(ex: Section, fm: FracturedMesh, params, E: float, nu: float) -> PennyCrack:
    """[exact] of a penny-shaped crack: its fracture, remote stress and optional radius and pressure."""
    net = fm.network
    if fm.mesh.dim != 3:
        raise InputError("exact.solution", "penny-shaped-crack is a 3D solution; the mesh is 2D")
    default = net.names[0] if len(net.names) == 1 else None
    name = ex.string("fracture", default)
    if name not in net.names:
        raise InputError(ex.field("fracture"), f"unknown fracture {name!r}; known: {', '.join(net.names)}")
    spec = net.specs[net.names.index(name)]
    S = np.zeros((3, 3))
    if ex.has("stress"):
        centre = np.asarray(spec.vertices, float).mean(axis=0)[None]
        S = tensor_field(ex.raw("stress"), ex.field("stress"), 3, params)(centre)[0]
    p = ex.number("pressure", None)
    radius = ex.number("radius", None, positive=True)
    try:
        # NaN pressure: not given, taken from mechanics.fracture_pressure later
        return penny_crack(spec, S, np.nan if p is None else p, E, nu, radius=radius)
    except ValueError as exc:
        raise InputError(ex.field("fracture"), str(exc)) from None


def _penny_loads(exact: PennyCrack, fm: FracturedMesh, friction: np.ndarray, pf_f) -> PennyCrack:
    """Fill in the penny crack's friction (and pressure, unless [exact] gave it) from the case."""
    sel = fm.network.faces_of(exact.fracture)
    F = friction[sel]
    if F.size and np.ptp(F) > 0:
        raise InputError("contact.friction", "the penny-shaped-crack solution needs one friction coefficient "
                         "on the crack")
    p = exact.pressure
    if np.isnan(p):
        p = 0.0
        if pf_f is not None and sel.size:
            vals = pf_f(fm.mesh.geometry.face_centroid[fm.network.faces[sel]])
            if np.ptp(vals) > 1e-12 * max(np.abs(vals).max(), 1e-300):
                raise InputError("mechanics.fracture_pressure", "the penny-shaped-crack solution needs a uniform "
                                 "pressure on the crack")
            p = float(vals[0])
    return dataclasses.replace(exact, friction=float(F[0]) if F.size else 0.0, pressure=p)
