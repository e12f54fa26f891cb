"""From a case's ``[material]`` (or ``[[materials]]``), ``[mechanics]``, ``[contact]``, ``[exact]``
and ``[solver]`` tables to the model's plain data (:class:`~polypore.models.mechanics.MechanicsData`).

The tables, their keys, ranges and defaults are in :mod:`polypore.setup.schema.mechanics`
(``polypore schema`` prints them); an example (SI units)::

    [material]                 # uniform; or [[materials]] blocks with `region = "name"`
    E = 1e10                   # Pa  (or mu = ..., lambda = ...)
    nu = 0.2

    [mechanics]
    body_force = [0, "-2260*9.81"]     # N/m3, expressions of x, y, z, t, or "exact"
    biot = 1.0                 # b in [0, 1]; 0 decouples

    [[mechanics.boundary]]     # one block per boundary part (xmin ... zmax or mesh groups)
    name = "xmin"
    u = [0, 0]                 # all components (m), or "exact"; or ux, uy, uz (rollers)
    traction = [-1e8, 0]       # Pa, σ n on the part; 0 in the components u/ux/uy/uz hold

    [contact]                  # not needed without fractures
    law = "coulomb"            # frictionless | tresca | coulomb
    friction = 0.5             # F; expression of x, y, z and D (distance to the fracture's nearest tip)

    [exact]
    solution = "penny-shaped-crack"    # polypore/cases/penny_exact.py
    stress = [[0, 0, 0], [0, 0, 0], [0, 0, 0]]   # remote stress (Pa, tension positive)

Here the expressions are parsed and evaluated on the mesh, and what needs the mesh is checked:
boundary parts and regions that exist, vectors of the mesh's dimension, friction and threshold
≥ 0 on every fracture face, exact solutions that fit the case.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from ..cases.exact import SingleCrack, get_solution
from ..cases.penny_exact import PennyCrack, penny_crack
from ..cases.reference import REFERENCES, load_reference
from ..core.errors import InputError
from ..core.expressions import parse
from ..mesh import FracturedMesh
from ..models.fracture_geometry import tip_distance
from ..models.materials import check_elastic, lame
from ..models.friction import LAW_DEFAULTS, LAW_KEYS
from ..models.mechanics import ContactSpec, DisplacementBC, MechanicsData, TractionBC
from ..solvers import linear as _linear
from ..solvers.factory import SolverChoice
from .solver import solver_choice
from ..solvers.newton import NewtonOptions
from .casefile import CaseFile
from .schema.case import Solver
from .schema.geometry import CORNERPOINT
from .schema.mechanics import ORDER_AUTO, Contact, Mechanics
from .translate import MECHANICS, case_keys

log = logging.getLogger("polypore")


@dataclass
class MechanicsSetup:
    data: MechanicsData
    solver: SolverChoice
    newton: NewtonOptions
    exact: object | None
    E: np.ndarray
    nu: np.ndarray
    choices: dict = dataclasses.field(default_factory=dict)   # the discretisation used and why (summary.json)

    @case_keys(MECHANICS)
    def problem(self, fm: FracturedMesh):
        """The :class:`~polypore.models.mechanics.ContactMechanics` of this setup on ``fm`` (its
        InputErrors name the case-file keys)."""
        from ..models.mechanics import ContactMechanics

        return ContactMechanics(fm, self.data, self.solver, self.newton)


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
    if not (isinstance(value, list) and len(value) == dim
            and all(isinstance(r, list) and len(r) == dim for r in value)):
        raise InputError(field, f"expected a {dim}×{dim} list of lists of numbers or expressions, got {value!r}")
    rows = [vector_field(r, f"{field}[{i}]", dim, params) for i, r in enumerate(value)]

    def fn(X, t=0.0):
        return np.stack([r(X, t) for r in rows], axis=1)

    return fn


def _elastic(m, field: str, mesh=None) -> tuple:
    """(E, ν) of a [material] table (the schema checked the ranges of E, ν or μ, λ): numbers, or
    (n_cells,) arrays when E or ν come from the cell keywords of a corner-point grid."""
    if m.mu is not None:
        E, nu = m.mu * (3 * m.lam + 2 * m.mu) / (m.lam + m.mu), m.lam / (2 * (m.lam + m.mu))
    else:
        E, nu = (_cell_array(getattr(m, k), k, m.keyword, field, mesh) for k in ("E", "nu"))
    check_elastic(E, nu, field)
    return E, nu


_RANGE = {"E": (lambda v: (v > 0) & np.isfinite(v), "positive and finite (Pa)"),
          "nu": (lambda v: (v > -1) & (v < 0.5), "in (−1, 0.5)")}


def _cell_array(value, key: str, keyword, field: str, mesh):
    """E or ν as given: a number; "grdecl:KW" -> (n_cells,) values of the grid's cell keyword KW;
    a table {keyword value: number} -> (n_cells,) values by the cells' values of ``keyword``.
    InputError naming ``field.key`` (or ``field.keyword``), the keyword, value and allowed values
    and, for a bad cell value, the cell (i, j, k), 1-based as in the file."""
    if not isinstance(value, (str, dict)):
        return value
    from .flow import _grid

    grid, info = _grid(mesh, f"{field}.{key}")
    known = ", ".join(sorted(grid.properties)) or "none"
    if isinstance(value, str):
        kw = value.split(":", 1)[1].upper()
        if kw not in grid.properties:
            raise InputError(f"{field}.{key}", f"{value!r}: {grid.source} has no cell keyword {kw}; its cell "
                             f"keywords are {known}")
        out = info.cell_values(grid.properties[kw]).astype(float)
        ok, allowed = _RANGE[key]
        bad = ~ok(out)
        if bad.any():
            c = int(np.flatnonzero(bad)[0])
            raise InputError(f"{field}.{key}", f"{value!r}: {kw} is {out[c]:g} in cell {info.cell_name(c)} "
                             f"({int(bad.sum())} cell(s)); {key} must be {allowed}")
        return out
    kw = keyword.upper()
    if kw not in grid.properties:
        raise InputError(f"{field}.keyword", f"{grid.source} has no cell keyword {kw}; its cell keywords are {known}")
    tag = info.cell_values(grid.properties[kw]).astype(float)
    if not np.all(tag == np.round(tag)):
        c = int(np.flatnonzero(tag != np.round(tag))[0])
        raise InputError(f"{field}.keyword", f"{kw} must hold integers (a region number per cell), got {tag[c]:g} "
                         f"in cell {info.cell_name(c)}")
    keys = np.array(sorted(value), float)
    vals = np.array([value[int(k)] for k in keys])
    pos = np.minimum(np.searchsorted(keys, tag), keys.size - 1)
    miss = keys[pos] != tag
    if miss.any():
        absent = sorted({int(v) for v in np.unique(tag[miss])})
        c = int(np.flatnonzero(miss)[0])
        raise InputError(f"{field}.{key}", f"no value for {kw} = {', '.join(map(str, absent))} (e.g. cell "
                         f"{info.cell_name(c)}); the table gives {kw} = {', '.join(str(int(a)) for a in keys)}; the grid's active "
                         f"cells have {kw} = {', '.join(str(int(a)) for a in np.unique(tag))}")
    return vals[pos]


def _materials(spec, fm: FracturedMesh):
    mesh = fm.mesh
    nc = mesh.n_cells
    E = np.full(nc, np.nan)
    nu = np.full(nc, np.nan)
    if spec.materials:
        for i, m in enumerate(spec.materials):
            field = f"materials.{m.name or i}"
            if m.region not in mesh.region_names:
                raise InputError(f"{field}.region", f"unknown region {m.region!r}; the mesh has "
                                 f"{', '.join(mesh.region_names)}")
            sel = mesh.cell_region == mesh.region_names.index(m.region)
            e, n = _elastic(m, field, mesh)
            E[sel] = e[sel] if np.ndim(e) else e
            nu[sel] = n[sel] if np.ndim(n) else n
        if np.isnan(E).any():
            missing = sorted({mesh.region_names[r] for r in np.unique(mesh.cell_region[np.isnan(E)])})
            raise InputError("materials", f"no material for region(s) {', '.join(missing)}")
    else:
        if spec.material is None:
            raise InputError("material", "is required: give E (Pa) and nu, e.g. [material] E = 1e10, nu = 0.25")
        E[:], nu[:] = _elastic(spec.material, "material", mesh)
    return E, nu


def _exact(spec, fm: FracturedMesh, params, E, nu, mu, lam):
    """The [exact] solution (friction and pressure filled in later), or None."""
    ex = spec.exact
    if ex is None:
        return None
    if not (np.ptp(mu) == 0 and np.ptp(lam) == 0):
        raise InputError("exact.solution", "exact solutions need one uniform material")
    if ex.solution == "single-crack":
        if fm.mesh.dim != 2:
            raise InputError("exact.solution", "single-crack is a 2D solution; the mesh is 3D")
        # the friction coefficient is filled in once [contact] has been read
        return SingleCrack(ex.sigma, np.deg2rad(ex.psi_deg), ex.half_length, float(E[0]), float(nu[0]), 0.0)
    if ex.solution in REFERENCES:
        return load_reference(ex.solution, "exact.solution")
    if ex.solution == "penny-shaped-crack":
        # pressure and friction are filled in once [mechanics] and [contact] have been read
        return _penny_table(ex, fm, params, float(E[0]), float(nu[0]))
    sol = get_solution(ex.solution, mu[0], lam[0])
    if sol.dim != fm.mesh.dim:
        raise InputError("exact.solution", f"{ex.solution!r} is a {sol.dim}D solution; the mesh is {fm.mesh.dim}D")
    return sol


@case_keys(MECHANICS)
def mechanics_setup(case: CaseFile, fm: FracturedMesh) -> MechanicsSetup:
    """The mechanics tables of the case as model data for the mesh ``fm`` (InputError naming the field)."""
    spec = case.spec
    mesh = fm.mesh
    d = mesh.dim
    params = spec.parameters
    E, nu = _materials(spec, fm)
    mu, lam = lame(E, nu)
    exact = _exact(spec, fm, params, E, nu, mu, lam)
    sec = spec.mechanics or Mechanics()
    order, why = resolve_order(sec.order, fm, spec.model, (spec.solver or Solver()).linear)
    nodal, nodal_why = resolve_nodal_stabilisation(sec.nodal_stabilisation, spec.mesh.generator)
    stab, stab_why = resolve_stabilisation(sec.stabilisation, spec.mesh.generator)
    choices = discretisation_choices(spec, sec, order, why, d)
    if order == 1:                      # the quadratic space has no stabilisation
        choices |= {"nodal_stabilisation": nodal, "nodal_stabilisation_source": nodal_why,
                    "stabilisation": stab, "stabilisation_source": stab_why}
    log.info("discretisation: %s", describe_choices(choices))
    if sec.bubbles == "one-sided" and spec.mesh.mirror != "none":
        log.warning("mesh.mirror with one-sided bubbles: the bubbles sit on one side of each fracture, "
                    "which breaks the mirror symmetry; set mechanics.bubbles = \"two-sided\" to get its benefit")
    body_f = None if sec.body_force is None else vector_field(sec.body_force, "mechanics.body_force", d, params,
                                                               exact, getattr(exact, "body_force", None))
    pm_f = None if sec.matrix_pressure is None else scalar_field(sec.matrix_pressure, "mechanics.matrix_pressure",
                                                                 params)
    pf_f = None if sec.fracture_pressure is None else scalar_field(sec.fracture_pressure,
                                                                   "mechanics.fracture_pressure", params)
    s0_f = None if sec.initial_stress is None else tensor_field(sec.initial_stress, "mechanics.initial_stress", d,
                                                                params)
    disp, trac = _boundary(sec, mesh, params, exact)
    c = spec.contact or Contact()
    coeffs = _contact_values(c, fm, params, spec.fractures)
    friction, threshold = coeffs["friction"], coeffs["threshold"]
    if isinstance(exact, SingleCrack):
        if np.ptp(friction) > 0:
            raise InputError("contact.friction", "the single-crack analytic solution needs one friction coefficient")
        exact = dataclasses.replace(exact, friction=float(friction[0]) if friction.size else 0.0)
    if isinstance(exact, PennyCrack):
        exact = _penny_loads(exact, fm, friction, pf_f)
    s = spec.solver or Solver()
    newton = NewtonOptions(tol=s.tolerance, increment_tol=s.increment_tolerance, max_iterations=s.max_iterations,
                           forcing=s.forcing, forcing_max=s.forcing_max, label="contact Newton")
    data = MechanicsData(mu=mu, lam=lam, displacement=tuple(disp), traction=tuple(trac), body_force=body_f,
                         matrix_pressure=pm_f, biot=sec.biot, fracture_pressure=pf_f, initial_stress=s0_f,
                         contact=ContactSpec(c.law, friction, threshold, c.beta, c.initial, c.patch_ratio,
                                             {k: v for k, v in coeffs.items()
                                              if k not in ("friction", "threshold") and c.law in LAW_KEYS[k]},
                                             _rate_state_options(c)),
                         two_sided=sec.bubbles == "two-sided", bubble_side=sec.bubble_side, stabilisation=stab,
                         bubble_stabilisation=sec.bubble_stabilisation,
                         nodal_stabilisation=nodal,
                         **({"order": order} if order != 1 else {}))
    return MechanicsSetup(data, solver_choice(s.linear, **s.backend_options()), newton, exact, E, nu, choices)


def _rate_state_options(c: Contact) -> dict:
    """The rate-and-state law's case-wide options for ContactSpec.options (empty for other laws)."""
    if c.law != "rate-and-state":
        return {}
    return {"state_law": c.state_law, "stick_rate": float(c.stick_rate), "start_from": c.initial_state_from,
            "shear_wave_speed": float(c.shear_wave_speed) if c.radiation_damping else None}


def is_simplicial(mesh) -> bool:
    """Every cell a triangle (2D) / tetrahedron (3D): the meshes the quadratic space runs on."""
    d = mesh.dim
    return bool(np.all(mesh.cell_nodes.counts == d + 1) and np.all(mesh.cell_faces.counts == d + 1))


def resolve_order(order, fm: FracturedMesh, model: str | None = None, linear: str | None = None) -> tuple[int, str]:
    """The displacement order of ``mechanics.order`` (1, 2 or "auto") on the mesh ``fm``, and why.

    "auto" takes the quadratic space (2) on 3D meshes of tetrahedra with fractures, for every model:
    on the validation cases it is the more accurate per unknown and per second of wall time
    (cube-slip-3d, penny-pressurised, penny-inclined, C5; docs/defaults.md). Elsewhere 1: P2 does
    not exist on polytopal meshes (Voronoi, Cartesian, corner-point grids), and 2D and meshes
    without fractures were not part of that study.

    The study timed PARDISO. With SciPy's SuperLU, the only direct solver of the default
    install, a quadratic 3D system fills in so much that one Newton iteration of penny-inclined
    took 5 minutes instead of seconds (about 20 min for the case, against 50 s with order 1), and
    the block solvers were not measured with P2: "auto" keeps order 1 unless the run's linear
    solver is PARDISO (``linear``: solver.linear; None: not known, taken as the default "auto").
    """
    if order != ORDER_AUTO:
        return int(order), "given"
    mesh = fm.mesh
    if mesh.dim != 3:
        return 1, "auto: 2D mesh"
    if not is_simplicial(mesh):
        return 1, "auto: polytopal mesh (P2 needs tetrahedra)"
    if fm.network.n_faces == 0:
        return 1, "auto: no fractures"
    if not _linear.pardiso_solves(linear):
        why = (f"solver.linear = {linear!r}" if linear not in (None, "auto", "pardiso") else
               "no PARDISO: SciPy's SuperLU takes minutes per Newton iteration on quadratic 3D systems; "
               "pip install 'polypore[fast]'")
        return 1, f"auto: 3D tetrahedra with fractures, but {why} (order 2 is taken with PARDISO)"
    return 2, "auto: 3D mesh of tetrahedra with fractures"



def resolve_nodal_stabilisation(value: str, generator: str | None) -> tuple[str, str]:
    """The nodal stabilisation weight of ``mechanics.nodal_stabilisation`` ("auto", "diameter",
    "thickness") and why.

    "auto" takes "thickness" on corner-point grids (generators grdecl, cornerpoint), whose cells
    are flat (aspect ratios 10–100): with the diameter weight the kernel modes of flat cells are
    stiffened by h_K/t_K, which on emerald-injection doubled the poroelastic change of a fault's
    shear traction on the grid and made 20 % of a fault slip on its 2×2×2 refinement where the
    thickness weight gives the same fault stresses on all three grids and no slip
    (docs/contact_patches.md, "Flat cells"). Elsewhere "diameter" (the scheme's): the tetrahedral,
    Voronoi and Cartesian validation cases were measured with it.
    """
    if value != "auto":
        return value, "given"
    if generator in CORNERPOINT:
        return "thickness", "auto: corner-point grid (flat cells)"
    return "diameter", "auto: the scheme's weight off corner-point grids"


STAB_CORNERPOINT = 0.3


def resolve_stabilisation(value, generator: str | None) -> tuple[float, str]:
    """The scale of the stabilisation of ``mechanics.stabilisation`` (a number or "auto") and why.

    "auto" takes 0.3 on corner-point grids (generators grdecl, cornerpoint) and 1 (the scheme's
    weights) elsewhere. At a fracture node the multipliers balance whatever the nodal rows carry,
    the stabilisation's reaction included: it vanishes on affine fields but not on the kinked
    fields of a poroelastic load, so it enters the fault tractions as an O(h) error proportional to
    the scale. On the closed-form displaced fault (docs/displaced_fault_scale_tables.md) the scale 0.3
    lowers the L2 error of Δτ from 53 % to 20 % at h = 25 m and from 14 % to 5.9 % at 3.1 m (Δσ'_n
    18 → 7 %, 5.1 → 2.9 %), and L∞ Δτ from 5.4 to 2.9 %; 0.1 gains little more on L2 and loses on
    L∞ (9 % at 6.25 m: stability); on cornerpoint-injection's 100 m columns the fault's shear change
    next to the well's row fell from 4 × the adjacent cells' traction to their value
    (docs/contact_patches.md, "The stabilisation's reaction"). The tetrahedral, Voronoi and
    Cartesian validation cases were measured with 1.
    """
    if value != "auto":
        return float(value), "given"
    if generator in CORNERPOINT:
        return STAB_CORNERPOINT, "auto: corner-point grid"
    return 1.0, "auto: the scheme's weights off corner-point grids"


def discretisation_choices(spec, sec: Mechanics, order: int, why: str, dim: int) -> dict:
    """The discretisation choices of the run (order, bubbles; simplicial meshes: mirrored mesh, in 3D
    crack-front cells), each with its source: "given" (the case file), "default", or the reason of
    order "auto". summary.json's "choices"."""
    mech_given = sec.given() if spec.mechanics is not None else set()
    mesh, mesh_given = spec.mesh, spec.mesh.given()
    out = {"order": order, "order_source": why,
           "bubbles": sec.bubbles, "bubbles_source": "given" if "bubbles" in mech_given else "default"}
    if order == 1 and sec.bubbles == "one-sided":
        out |= {"bubble_side": sec.bubble_side,
                "bubble_side_source": "given" if "bubble_side" in mech_given else "default"}
    if getattr(mesh, "generator", None) == "simplicial":
        out |= {"mirror": mesh.mirror, "mirror_source": "given" if "mirror" in mesh_given else "default"}
        if dim == 3:
            out |= {"front": mesh.front, "front_source": "given" if "front" in mesh_given else "default"}
    return out


def describe_choices(c: dict) -> str:
    """One line: "order 2 (auto: 3D mesh of tetrahedra with fractures), one-sided bubbles (default), ..."."""
    parts = [f"order {c['order']} ({c['order_source']})", f"{c['bubbles']} bubbles ({c['bubbles_source']})"]
    if "bubble_side" in c:
        parts.append(f"bubbles on the {c['bubble_side']} side ({c['bubble_side_source']})")
    if "nodal_stabilisation" in c:
        parts.append(f"{c['nodal_stabilisation']}-weighted nodal stabilisation ({c['nodal_stabilisation_source']})")
    if "stabilisation" in c:
        parts.append(f"stabilisation × {c['stabilisation']:g} ({c['stabilisation_source']})")
    if "front" in c:
        parts.append(f"{c['front']} crack-front cells ({c['front_source']})")
    if "mirror" in c:
        parts.append(f"mirror {c['mirror']} ({c['mirror_source']})")
    return ", ".join(parts)


def _boundary(sec: Mechanics, mesh, params, exact):
    """Displacement and traction conditions of the [[mechanics.boundary]] blocks."""
    d = mesh.dim
    disp, trac = [], []
    for b in sec.boundary:
        field = f"mechanics.boundary.{b.name}"
        if b.name not in mesh.boundary:
            raise InputError(f"{field}.name", f"unknown boundary {b.name!r}; this mesh has "
                             f"{', '.join(sorted(mesh.boundary))}")
        if b.u is not None:
            disp.append(DisplacementBC(b.name, tuple(range(d)), vector_field(b.u, f"{field}.u", d, params, exact,
                                                                             getattr(exact, "u", None))))
        for i, key in enumerate(("ux", "uy", "uz")):
            v = getattr(b, key)
            if v is None:
                continue
            if i >= d:
                raise InputError(f"{field}.{key}", f"the mesh is {d}D: it has no {'xyz'[i]} component")
            vals = [0.0] * d
            vals[i] = v
            disp.append(DisplacementBC(b.name, (i,), vector_field(vals, f"{field}.{key}", d, params)))
        if b.traction is not None:
            trac.append(TractionBC(b.name, vector_field(b.traction, f"{field}.traction", d, params)))
    return disp, trac


def _contact_values(c: Contact, fm: FracturedMesh, params, fractures=()):
    """{key: (n_ff,) values per fracture face} of the contact law's coefficients (``LAW_KEYS``),
    checked finite and ≥ 0; those of another law zero.

    ``fractures`` are the case's ``[[fractures]]`` tables: a fracture's own value (``friction``,
    ``threshold``, ...) replaces the ``[contact]`` one on its faces.
    """
    mesh, net = fm.mesh, fm.network
    D = tip_distance(fm)
    Dfin = np.where(np.isfinite(D), D, 1e30)
    xf = mesh.geometry.face_centroid[net.faces]
    cols = {k: xf[:, i] for i, k in enumerate("xyz"[:mesh.dim])}
    own = {f.name: f for f in fractures}

    def face_values(key, value, field, sel=slice(None)):
        e = parse(value, field, params, extra=("D",))
        out = np.broadcast_to(e(**cols, D=Dfin), (net.n_faces,)).astype(float)[sel]
        if not np.all(np.isfinite(out)) or np.any(out < 0):
            raise InputError(field, f"must be finite and ≥ 0 on every fracture face, got {value!r} "
                             f"(min {np.nanmin(out) if out.size else 0:g})")
        return out

    def values(key, what):
        out = np.zeros(net.n_faces)
        given = getattr(c, key)
        missing = np.ones(net.n_faces, bool)
        for j, name in enumerate(net.names):
            v = getattr(own.get(name), key, None)
            if v is not None:
                sel = net.fracture == j
                out[sel] = face_values(key, v, f"fractures.{name}.{key}", sel)
                missing &= ~sel
        if given is not None:
            out[missing] = face_values(key, given, f"contact.{key}", missing)
        elif c.law in LAW_KEYS[key] and key in LAW_DEFAULTS:
            out[missing] = LAW_DEFAULTS[key]
        elif c.law in LAW_KEYS[key] and missing.any():
            # without fracture faces there is no contact: the case needs no [contact] table
            rest = sorted({net.names[j] for j in np.unique(net.fracture[missing])})
            raise InputError(f"contact.{key}", f"is required for the {c.law} law {what}, or give "
                             f"`{key}` in the [[fractures]] block of {', '.join(rest)}")
        return out

    expr = "a number ≥ 0 or an expression of x, y, z and D, the distance to the fracture's nearest tip"
    return {key: values(key, f"({expr})") for key in LAW_KEYS}


def _penny_table(ex, fm: FracturedMesh, params, E: float, nu: float) -> PennyCrack:
    """[exact] of a penny-shaped crack: its fracture, remote stress and optional radius and pressure."""
    net = fm.network
    if fm.mesh.dim != 3:
        raise InputError("exact.solution", "penny-shaped-crack is a 3D solution; the mesh is 2D")
    name = ex.fracture or (net.names[0] if len(net.names) == 1 else None)
    if name not in net.names:
        raise InputError("exact.fracture", f"unknown fracture {name!r}; known: {', '.join(net.names)}"
                         + ("" if ex.fracture else " (name it: the case has more than one)"))
    spec = net.specs[net.names.index(name)]
    S = np.zeros((3, 3))
    if ex.stress is not None:
        centre = np.asarray(spec.vertices, float).mean(axis=0)[None]
        S = tensor_field(ex.stress, "exact.stress", 3, params)(centre)[0]
    try:
        # NaN pressure: not given, taken from mechanics.fracture_pressure later
        return penny_crack(spec, S, np.nan if ex.pressure is None else ex.pressure, E, nu, radius=ex.radius)
    except ValueError as exc:
        raise InputError("exact.fracture", str(exc)) from None


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
