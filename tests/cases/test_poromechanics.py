"""Coupled poromechanics (scheme.md §6): Terzaghi consolidation, the discrete energy identity
and estimate (with Coulomb slip, 2D and 3D, one- and two-sided bubbles), detection of a wrong
coupling sign, fracture injection with partial opening and mass conservation, and the
Newton Jacobian against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import sheared_mechanics

from polypore.core.errors import InputError
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.models.contact import OPEN, SLIP
from polypore.models.energy import check_energy
from polypore.models.flow import FlowData, Pressure
from polypore.models.mechanics import ContactSpec, DisplacementBC, MechanicsData, TractionBC
from polypore.models.poromechanics import Poromechanics

ZERO = lambda X, t: 0.0 * X  # noqa: E731


def _lame(E, nu):
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


# ---- Terzaghi -----------------------------------------------------------------------------
TZ = dict(E=1e8, nu=0.25, b=1.0, M=1e9, k=1e-13, eta=1e-3, load=1e5, H=1.0)


def _terzaghi_model(ny):
    """Column (0, 0.1) × (0, H), one cell wide: load on top (for t > 0), drained top, rollers on
    the sides, fixed impervious bottom."""
    mu, lam = _lame(TZ["E"], TZ["nu"])
    mesh = cartesian_mesh([np.linspace(0, 0.1, 2), np.linspace(0, TZ["H"], ny + 1)])
    fm = FracturedMesh.build(mesh, [])
    nc = mesh.n_cells
    load = TZ["load"]
    md = MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam),
                       displacement=[DisplacementBC("ymin", (0, 1), ZERO), DisplacementBC("xmin", (0,), ZERO),
                                     DisplacementBC("xmax", (0,), ZERO)],
                       traction=[TractionBC("ymax", lambda X, t: np.tile([0.0, -load * (t > 0)], (len(X), 1)))])
    fd = FlowData(permeability=TZ["k"], viscosity=TZ["eta"], biot_modulus=TZ["M"], biot_coefficient=TZ["b"])
    return Poromechanics(fm, md, fd, {"ymax": Pressure(0.0)})


def _terzaghi_constants():
    mu, lam = _lame(TZ["E"], TZ["nu"])
    Kd = lam + 2 * mu                                  # oedometric (drained) modulus
    b, M = TZ["b"], TZ["M"]
    cv = TZ["k"] / TZ["eta"] / (b * b / Kd + 1 / M)    # consolidation coefficient, m²/s
    p0 = b * M * TZ["load"] / (Kd + b * b * M)         # undrained pressure at t = 0⁺
    return Kd, cv, p0


def terzaghi_pressure(z, t, n_terms=400):
    """Series solution p(z, t), drained top z = H, impervious bottom z = 0."""
    _, cv, p0 = _terzaghi_constants()
    H = TZ["H"]
    m = np.arange(n_terms)[:, None]
    a = (2 * m + 1) * np.pi / (2 * H)
    return (4 * p0 / ((2 * m + 1) * np.pi) * np.sin(a * (H - z)) * np.exp(-a * a * cv * t)).sum(0)


def _run_terzaghi(ny, n_steps, sign=1.0):
    """Undrained first step (Δt = 1e-6 T_c), then n_steps to 0.5 T_c; errors at 0.05, 0.2, 0.5 T_c."""
    Kd, cv, p0 = _terzaghi_constants()
    Tc = TZ["H"] ** 2 / cv
    P = _terzaghi_model(ny)
    P._coupling_sign = sign
    st = P.initial_state(0.0)
    st, info = P.step(st, 1e-6 * Tc)
    undrained = st
    energies = [info.energy]
    z = P.fm.mesh.geometry.cell_centroid[:, 1]
    errs = {}
    dt = 0.5 * Tc / n_steps
    marks = {round(f * n_steps / 0.5): f for f in (0.05, 0.2, 0.5)}
    for n in range(1, n_steps + 1):
        st, info = P.step(st, dt)
        energies.append(info.energy)
        if n in marks:
            errs[marks[n]] = np.abs(P.cell_pressure(st) - terzaghi_pressure(z, st.time)).max() / p0
    return P, undrained, errs, energies


def test_the_predictor_extrapolates_the_last_increment_within_its_reach():
    """Solver.predictor = "linear": the first iterate of a step is the last step's increment
    extrapolated to this Δt (Δt/Δt_prev ≤ 2), which on a diffusing column leaves a much smaller
    residual than the old state; not after a step ten thousand times shorter (an undrained
    response, not a rate); the converged step is the same with either start."""
    Kd, cv, p0 = _terzaghi_constants()
    Tc = TZ["H"] ** 2 / cv
    P = _terzaghi_model(10)
    st0 = P.initial_state(0.0)
    st1, _ = P.step(st0, 1e-6 * Tc)
    dt = 0.01 * Tc
    ctx, x0 = P.step_context(st1, dt, st1.time + dt)
    assert P._predicted_start(st1, dt, ctx) is None                 # Δt/Δt_prev = 10⁴
    states = [st1]
    for _ in range(8):
        states.append(P.step(states[-1], dt)[0])
    st2, st3 = states[-2:]
    t = st3.time + dt
    ctx, x0 = P.step_context(st3, dt, t)
    xp = P._predicted_start(st3, dt, ctx)
    assert xp is not None and xp.shape == x0.shape
    up, _, pp = P._split(xp, ctx.u_dir, ctx.p_dir, ctx.pressure_scale)
    assert np.allclose(pp, 2 * st3.p - st2.p, rtol=1e-12, atol=1e-9 * p0)
    assert np.allclose(up, 2 * st3.u.ravel() - st2.u.ravel(), rtol=1e-12, atol=1e-18)
    # Newton's weighted flow norm; right after the undrained step the decaying rate makes the
    # extrapolation overshoot (1.5× the old state's residual on the second step), later it gains
    r0 = P._linearise(x0, ctx).block_norms["flow"]
    rp = P._linearise(xp, ctx).block_norms["flow"]
    assert rp < 0.3 * r0                      # measured 8.0 × 10⁻⁴ → 1.2 × 10⁻⁴
    assert P._predicted_start(st2, dt, ctx) is not None            # the earlier state keeps its own
    with_pred, _ = P.step(st3, dt)
    P.predictor = "none"
    assert P._predicted_start(st3, dt, ctx) is None
    without, _ = P.step(st3, dt)
    assert np.allclose(with_pred.p, without.p, rtol=1e-9, atol=1e-9 * p0)
    with pytest.raises(InputError, match="^predictor:"):
        Poromechanics(P.fm, None, None, predictor="quadratic")


def test_terzaghi_consolidation():
    Kd, cv, p0 = _terzaghi_constants()
    out = {}
    for ny, n_steps in ((10, 50), (20, 200)):           # Δt ∝ h²: implicit Euler and HFV both O(h²)
        P, und, errs, energies = _run_terzaghi(ny, n_steps)
        out[ny] = errs
        # undrained response: uniform p = b M σ/(K_d + b² M) and settlement σ H/(K_d + b² M)
        z = P.fm.mesh.geometry.cell_centroid[:, 1]
        rel = np.abs(P.cell_pressure(und) / p0 - 1)
        # drained in the top cell; the pressure stabilisation (δ b² h²/(λ_L+2μ) Δ∂_t p) passes a
        # geometric tail of that drop down, ≈ 1/6.3 per cell: 2.5 % of it two cells below
        # (measured 4.2e-6 and 1.7e-5 for ny = 10, 20; round-off with the stabilisation off)
        assert rel.max() < 1e-3 and rel[z < TZ["H"] - 2.0 / ny].max() < 0.03 * rel.max()
        top = np.isclose(P.fm.mesh.nodes[P.fm.sides.side_node][:, 1], TZ["H"])
        settle = TZ["load"] * TZ["H"] / (Kd + TZ["b"] ** 2 * TZ["M"])
        assert np.allclose(und.u[: P.fm.sides.n_sides][top, 1], -settle, rtol=1e-3)
        assert not check_energy(energies)
        assert max(abs(e.defect) / e.scale for e in energies) < 1e-12
    # measured: ny=10 {0.05: 3.4e-2, 0.2: 6.3e-3, 0.5: 7.2e-3}; ny=20 {9.0e-3, 1.5e-3, 1.8e-3}
    # (pressure stabilisation on; off: {3.4e-2, 6.9e-3, 6.9e-3}, {8.6e-3, 1.7e-3, 1.7e-3})
    for f in (0.05, 0.2, 0.5):
        assert out[20][f] < 1e-2
        assert out[10][f] / out[20][f] > 3.5
    assert max(out[20].values()) < 1e-2


def test_energy_check_catches_a_wrong_coupling_sign():
    """No fracture: the identity ΔE + D_visc + D_num = W closes to round-off; with the sign of the
    Biot term flipped in the equilibrium equation, the estimate is violated at every step."""
    *_, good = _run_terzaghi(10, 10)
    assert not check_energy(good)
    assert max(abs(e.defect) / e.scale for e in good) < 1e-12
    # no contact, no friction: every dissipation is viscous or the implicit-Euler ½a(δu,δu) + ½|δp|²/M
    assert all(e.friction_dissipation == 0 and e.contact_normal == 0 for e in good)
    *_, bad = _run_terzaghi(10, 10, sign=-1.0)
    violations = check_energy(bad)
    assert len(violations) == len(bad), violations
    assert min(abs(e.defect) / e.scale for e in bad) > 1e-2


# ---- fractured cases ----------------------------------------------------------------------------
def _box(dim, n):
    return cartesian_mesh([grid_coordinates(0, 1, n, [0.25, 0.5, 0.75])] * dim)


def _centre_fracture(dim):
    if dim == 2:
        return [FractureSpec("F", np.array([[0.25, 0.5], [0.75, 0.5]]))]
    return [FractureSpec("F", np.array([[0.25, 0.25, 0.5], [0.75, 0.25, 0.5], [0.75, 0.75, 0.5], [0.25, 0.75, 0.5]]))]


def shear_case(dim, n, two_sided=False, T=50.0, **kw):
    """Fracture with tips in the unit square/cube; bottom fixed, top displaced by
    min(t/T, 1)(shear, −compression) so that the fracture slips while loading, then sticks;
    p = 1e5 Pa on xmin, initial pressure 1e5 Pa, F = 0.5."""
    fm = FracturedMesh.build(_box(dim, n), _centre_fracture(dim))
    md = sheared_mechanics(fm, T, two_sided)
    fd = FlowData(permeability=1e-15, viscosity=1e-3, biot_modulus=1e10, biot_coefficient=0.5, aperture=1e-4,
                  normal_permeability=1e-15)
    return Poromechanics(fm, md, fd, {"xmin": Pressure(1e5)}, **kw)


@pytest.mark.parametrize("dim,n,two_sided", [(2, 16, False), (2, 16, True), (3, 8, False)])
def test_energy_estimate_with_coulomb_slip(dim, n, two_sided):
    P = shear_case(dim, n, two_sided)
    st = P.initial_state(1e5)
    terms, slipping = [], []
    for _ in range(8):
        st, info = P.step(st, 10.0)
        terms.append(info.energy)
        slipping.append(info.slip)
    assert max(slipping) == P.n_ff and min(slipping) == 0      # slips while loading, sticks afterwards
    assert max(e.friction_dissipation for e in terms) > 0.01 * max(e.viscous_dissipation for e in terms)
    assert all(e.viscous_dissipation > 0 for e in terms)
    assert not check_energy(terms)
    # the exact identity (with the implicit-Euler and normal-contact terms) closes to round-off;
    # |λ_τ|·|Δ[[u]]_τ| equals the friction dissipation (the slip law holds exactly)
    for e in terms:
        assert abs(e.defect) < 1e-11 * e.scale, e.as_dict()
        assert abs(e.contact_tangential_excess) < 1e-11 * e.scale
        assert e.contact_normal > -1e-12 * e.scale and e.numerical_dissipation > 0


def _finite_difference_check(P, st, eps=1e-6):
    """(ctx, x, v, linearisation at x, central difference of the residual along v, J v) for the
    step st → st.time + 10 s, at a perturbed first iterate x."""
    ctx, x0 = P.step_context(st, 10.0, st.time + 10.0)
    x = x0 * (1 + 1e-3 * np.random.default_rng(0).standard_normal(x0.size))
    lin = P._linearise(x, ctx)
    v = np.random.default_rng(1).standard_normal(x.size) * np.abs(x).mean()
    fd = (P._linearise(x + eps * v, ctx).residual - P._linearise(x - eps * v, ctx).residual) / (2 * eps)
    return ctx, x, v, lin, fd, lin.jacobian @ v


def test_jacobian_matches_finite_differences():
    """The pattern-filled Jacobian equals the derivative of the residual (away from kinks)."""
    P = shear_case(2, 8)
    st = P.initial_state(1e5)
    st, _ = P.step(st, 10.0)
    ctx, x, v, lin, fd, Jv = _finite_difference_check(P, st)
    assert np.any(lin.active_set == SLIP)
    assert np.linalg.norm(fd - Jv) < 1e-6 * np.linalg.norm(Jv)


def injection_case(dim, n, q=1e-6, **kw):
    """Fracture with tips under a confining traction growing with x, fluid injected into the
    fracture (h_f = q m/s on its faces), drained top, low-permeability matrix."""
    mu, lam = _lame(1e10, 0.2)
    fm = FracturedMesh.build(_box(dim, n), _centre_fracture(dim))
    nc = fm.mesh.n_cells
    top, bot = ("ymax", "ymin") if dim == 2 else ("zmax", "zmin")
    lateral = [b for b in fm.mesh.boundary if b not in (top, bot)]
    tr = np.zeros(dim)
    tr[-1] = -1e6
    md = MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam),
                       displacement=[DisplacementBC(bot, tuple(range(dim)), ZERO)]
                       + [DisplacementBC(b, ("xyz".index(b[0]),), ZERO) for b in lateral],
                       traction=[TractionBC(top, lambda X, t: np.outer(1 + 3 * (X[:, 0] - 0.25), tr))],
                       contact=ContactSpec("coulomb", 0.5))
    fd = FlowData(permeability=1e-18, viscosity=1e-3, biot_modulus=1e10, biot_coefficient=0.5, aperture=1e-4,
                  normal_permeability=1e-18, fracture_compressibility=1e-9)
    return Poromechanics(fm, md, fd, {top: Pressure(0.0)}, fracture_source=q, **kw)


@pytest.mark.parametrize("dim,n,q", [(2, 16, 1e-6), (3, 8, 5e-7)])
def test_injection_opens_the_fracture_and_conserves_mass(dim, n, q):
    P = injection_case(dim, n, q)
    mesh, net = P.fm.mesh, P.fm.network
    g = mesh.geometry
    vol = g.cell_volume
    area = g.face_area[net.faces]
    x = g.face_centroid[net.faces][:, 0]
    st = P.initial_state(0.0)
    assert np.all(st.state != OPEN)
    n_open, pf_max = [0], [0.0]
    terms = []
    for _ in range(6):
        old = st
        st, info = P.step(st, 0.5)
        terms.append(info.energy)
        fq = P.fracture_quantities(st)
        is_open = st.state == OPEN
        # opens where the confining stress is lowest (small x), the open zone grows, p_f rises
        assert is_open.any() and not is_open.all()
        assert x[is_open].max() <= x[~is_open].min()
        assert is_open.sum() >= n_open[-1] and fq["p_f"].max() > pf_max[-1]
        n_open.append(int(is_open.sum()))
        pf_max.append(float(fq["p_f"].max()))
        # open: λ_n = 0 (the effective normal stress vanishes) and [[u]]_n < 0; closed: [[u]]_n = 0
        assert np.all(np.abs(fq["lambda_n"][is_open]) <= 1e-12 * fq["lambda_n"].max())
        assert np.all(fq["jump_n"][is_open] < 0)
        assert np.all(fq["lambda_n"][~is_open] > 0)
        assert np.abs(fq["jump_n"][~is_open]).max() < 1e-12 * np.abs(fq["jump_n"]).max()
        assert np.allclose(st.aperture, 1e-4 - fq["jump_n"], rtol=0, atol=1e-18)
        # mass: per cell, per fracture face, and globally (aperture change included)
        dt = st.time - old.time
        du = st.u - old.u
        div = sum(P.mech.ops.D[j] @ du[:, j] for j in range(dim))
        sol = P.flow_solution(st)
        M, b = P.flow.biot_modulus, P.flow.data.biot_coefficient
        dpK = P.cell_pressure(st) - P.cell_pressure(old)
        cell_out = np.bincount(mesh.cell_faces.rows_of_entries(), weights=sol.cell_flux, minlength=mesh.n_cells)
        res_cell = vol * (b * div + dpK / M) + dt * cell_out
        scale = dt * np.abs(sol.cell_flux).max()
        assert np.abs(res_cell).max() < 1e-9 * scale
        fe = P.asm.fcells.face_edges
        frac_out = np.bincount(fe.rows_of_entries(), weights=sol.fracture_flux, minlength=net.n_faces)
        cf = P.flow.data.fracture_compressibility
        dpf = sol.fracture - old.p[P.dofs.frac]
        res_frac = (area * (st.aperture - old.aperture) + area * cf * old.aperture * dpf
                    + dt * (frac_out - sol.exchange.sum(1)) - dt * area * q)
        assert np.abs(res_frac).max() < 1e-9 * dt * area.sum() * q
        injected = dt * area.sum() * q
        stored = (np.sum(vol * (b * div + dpK / M)) + np.sum(area * (st.aperture - old.aperture))
                  + np.sum(area * cf * old.aperture * dpf))
        out = dt * sum(sol.boundary_flux.values())
        assert abs(injected - stored - out) < 1e-9 * injected
        assert np.sum(area * (st.aperture - old.aperture)) > 0.1 * injected     # most goes into opening
    assert n_open[-1] > n_open[1]
    assert not check_energy(terms)
    assert max(abs(e.defect) / e.scale for e in terms) < 1e-11


def test_jacobian_with_dilatancy_and_reference_traction():
    """Dilatant aperture (tan ψ |[[u − u⁰]]_τ| in the fracture storage) and a reference traction
    λ⁰: the Jacobian is still the derivative of the residual."""
    P = shear_case(2, 8)
    st = P.initial_state(1e5)
    P.tan_psi[:] = np.tan(np.radians(20.0))
    P.lam0 = 1e3 * P.mech.normal
    st, _ = P.step(st, 10.0)
    ctx, x, v, lin, fd, Jv = _finite_difference_check(P, st)
    assert np.any(lin.active_set == SLIP)
    assert np.linalg.norm(fd - Jv) < 1e-6 * np.linalg.norm(Jv)
    P.tan_psi[:] = 0.0
    lin0 = P._linearise(x, ctx)
    assert np.linalg.norm(lin.jacobian @ v - lin0.jacobian @ v) > 1e-6 * np.linalg.norm(Jv)   # the term is there


@pytest.mark.parametrize("case", ["shear-dilatant", "injection"])
def test_jacobian_with_implicit_conductivities(case):
    """C_f and Λ_f at the iterate's aperture (models/implicit_conductivity.py): the Jacobian, with
    their derivative through the normal opening (injection) and the dilatant slip (shear), is the
    residual's derivative, and dropping that derivative would be visible."""
    if case == "injection":
        P = injection_case(2, 16, conductivity_aperture="current")
        st = P.initial_state(0.0)
        st, _ = P.step(st, 0.5)
        assert np.any(st.state == OPEN)
    else:
        P = shear_case(2, 8, conductivity_aperture="current")
        st = P.initial_state(1e5)
        P.tan_psi[:] = np.tan(np.radians(20.0))
        st, _ = P.step(st, 10.0)
    ctx, x, v, lin, fd, Jv = _finite_difference_check(P, st)
    assert np.linalg.norm(fd - Jv) < 1e-8 * np.linalg.norm(Jv)
    imp = P._implicit
    full = imp.coupling_values
    imp.coupling_values = lambda *a: 0.0 * full(*a)
    assert np.linalg.norm(fd - P._linearise(x, ctx).jacobian @ v) > 1e-4 * np.linalg.norm(Jv)
    imp.coupling_values = full


def test_implicit_conductivities_conserve_mass_and_energy():
    """With the step's own aperture in the fluxes the energy identity still closes and each
    fracture face balances its mass with the fluxes at that aperture (flux_aperture)."""
    P = injection_case(2, 16, conductivity_aperture="current")
    net, area = P.fm.network, P.mech.face_area
    st = P.initial_state(0.0)
    terms = []
    for _ in range(4):
        old = st
        st, info = P.step(st, 0.5)
        terms.append(info.energy)
        assert np.array_equal(st.flux_aperture, np.maximum(st.aperture, P.closed_aperture))
        sol = P.flow_solution(st)
        fe = P.asm.fcells.face_edges
        out = np.bincount(fe.rows_of_entries(), weights=sol.fracture_flux, minlength=net.n_faces)
        dpf = sol.fracture - old.p[P.dofs.frac]
        res = (area * (st.aperture - old.aperture) + area * 1e-9 * old.aperture * dpf
               + 0.5 * (out - sol.exchange.sum(1)) - 0.5 * area * 1e-6)
        assert np.abs(res).max() < 1e-9 * 0.5 * area.sum() * 1e-6
    assert np.any(st.aperture > 1.01 * P.closed_aperture)
    assert not check_energy(terms)
    assert max(abs(e.defect) / e.scale for e in terms) < 1e-11
    from polypore.core.errors import InputError

    with pytest.raises(InputError, match="conductivity_aperture"):
        injection_case(2, 4, conductivity_aperture="implicit")


def test_energy_identity_with_dilatancy():
    """With shear dilation the identity still closes (the dilatant storage work is counted)."""
    P = shear_case(2, 16)
    st = P.initial_state(1e5)
    P.tan_psi[:] = np.tan(np.radians(20.0))
    terms = []
    for _ in range(6):
        st, info = P.step(st, 10.0)
        terms.append(info.energy)
    assert any(abs(e.dilatancy_work) > 1e-6 * e.scale for e in terms)
    for e in terms:
        assert abs(e.defect) < 1e-11 * e.scale, e.as_dict()
    q, r = P.jumps(st.u), P.jumps(st.u) - P.jumps(P.u_ref)          # u⁰ = the initial state
    qn = np.einsum("fi,fi->f", q, P.mech.normal)
    slip = np.linalg.norm(r - np.einsum("fi,fi->f", r, P.mech.normal)[:, None] * P.mech.normal, axis=1)
    assert slip.max() > 1e-6
    eps = 1e-3 * P.closed_aperture.max() * P.tan_psi.max()         # the regularised norm |·|_ε
    assert np.allclose(st.aperture, P.closed_aperture - qn + P.tan_psi * slip, rtol=0, atol=eps)


def test_reference_state_is_at_rest_without_loads():
    """λ⁰ from an in-situ stress that satisfies the friction law and no load increment: the
    step leaves u, slip and pressures unchanged (round-off); a stress violating it is refused."""
    from polypore.core.errors import RunError

    mu, lam = _lame(1e10, 0.2)
    fm = FracturedMesh.build(_box(2, 8), _centre_fracture(2))
    nc = fm.mesh.n_cells
    md = MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam), displacement=[DisplacementBC("ymin", (0, 1), ZERO)],
                       contact=ContactSpec("coulomb", 0.5))
    fd = FlowData(permeability=1e-15, viscosity=1e-3, biot_modulus=1e10, biot_coefficient=1.0, aperture=1e-4,
                  normal_permeability=1e-15)
    sigma0 = -np.array([[7e6, 2e6], [2e6, 1e7]])                    # total in-situ stress, Pa: |τ| < 0.5 σ_n
    P = Poromechanics(fm, md, fd, {"xmin": Pressure(0.0)})
    n = P.mech.normal
    P.lam0 = -(n @ sigma0.T)                                        # λ⁰ = −σ⁰ n⁺ (reference p_f = 0)
    st0 = P.reference_state(0.0)
    st, info = P.step(st0, 10.0)
    assert np.abs(st.u).max() < 1e-16 and info.slip == 0 and info.open == 0
    assert np.abs(st.lam - P.lam0).max() < 1e-9 * 1e7
    assert np.abs(st.p).max() < 1e-6
    P.lam0 = -(n @ (-np.array([[7e6, 6e6], [6e6, 1e7]])).T)        # |τ| > 0.5 σ_n
    with pytest.raises(RunError, match="not an equilibrium"):
        P.reference_state(0.0)


def test_bubble_slip_is_told_apart_from_a_slip_of_the_faults_sides():
    """ContactMechanics.jump_parts splits each face's mean jump into its point-slot and bubble
    parts (summing to the jump); runs/coupled.bubble_slip flags a face whose slip is its bubble's
    (a cell-local soft mode, the runaway sliver of docs/fault_bounds.md) and not one whose sides moved."""
    from polypore.runs.coupled import bubble_slip

    P = shear_case(3, 4)
    st = P.initial_state(1e5)
    mech, net = P.mech, P.fm.network
    rng = np.random.default_rng(0)
    u = rng.standard_normal(st.u.shape) * 1e-3
    pts, bub = mech.jump_parts(u)
    assert np.allclose(pts + bub, P.jumps(u), rtol=0, atol=1e-15)
    npt = mech.space.n_point_slots
    assert np.any(np.abs(bub) > 0) and np.all(mech.jump_parts(np.r_[u[:npt], 0 * u[npt:]])[1] == 0)
    n = mech.normal
    t = np.cross(n[0], [1.0, 0.0, 0.0]) if abs(n[0, 0]) < 0.9 else np.cross(n[0], [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    moved = st.u.copy()
    j = np.flatnonzero(mech.space.bubble_face == 0)[0] + npt          # the bubble slot of fracture face 0
    moved[j] += 5e-3 * t
    r = bubble_slip(P, type(st)(st.time, moved, st.lam, st.p, st.aperture, st.state), net)
    assert r["faces"] == 1 and r["largest"]["face"] == 0 and r["largest"]["bubble_m"] > 4e-3
    assert r["largest"]["nodal_m"] < 1e-12
    # jumps of the nodes alone (bubbles at rest), above the slipped threshold: none is flagged
    nodal = st.u + 10 * np.r_[u[:npt], 0 * u[npt:]]
    assert np.linalg.norm(mech.jump_parts(nodal - st.u)[0], axis=1).min() > 1e-3
    assert bubble_slip(P, type(st)(st.time, nodal, st.lam, st.p, st.aperture, st.state), net)["faces"] == 0


def _slip_weakening_shear(dim, n, dc=2e-5):
    """shear_case with linear slip-weakening from F_s = 0.5 to F_d = 0.3 over D_c."""
    import dataclasses

    fm = FracturedMesh.build(_box(dim, n), _centre_fracture(dim))
    md = sheared_mechanics(fm, 50.0)
    md = dataclasses.replace(md, contact=ContactSpec("slip-weakening", 0.5,
                                                      coefficients={"dynamic_friction": 0.3, "critical_slip": dc}))
    fd = FlowData(permeability=1e-15, viscosity=1e-3, biot_modulus=1e10, biot_coefficient=0.5, aperture=1e-4,
                  normal_permeability=1e-15)
    return Poromechanics(fm, md, fd, {"xmin": Pressure(1e5)})


def test_slip_weakening_jacobian_state_and_energy():
    """Slip-weakening in the coupled model: the Jacobian (with ∂r/∂s) matches central differences
    of the residual, the slip path accumulates |Δ[[u]]_τ| per patch, the friction weakens to F_d
    and no further, the energy identity closes to round-off with the law's radius, and the fault
    slips more than under Coulomb with F = F_s."""
    P = _slip_weakening_shear(2, 16)
    st = P.initial_state(1e5)
    st, _ = P.step(st, 10.0)
    path = P.friction_state(st)[:, 0]
    assert path.max() > 0 and np.all(path >= 0)
    ctx, x, v, lin, fd, Jv = _finite_difference_check(P, st)
    assert np.any(lin.active_set == SLIP)
    law = P.mech.law.friction_law
    assert np.any((lin.active_set == SLIP) & (path < law.critical_slip))      # weakening faces in the check
    assert np.linalg.norm(fd - Jv) < 1e-6 * np.linalg.norm(Jv)
    terms = []
    for _ in range(6):
        prev = P.friction_state(st)[:, 0]
        q0 = P.mech.Jcv @ st.u.ravel()
        st, info = P.step(st, 10.0)
        terms.append(info.energy)
        dq = (P.mech.Jcv @ st.u.ravel() - q0).reshape(P.mech.n_c, -1)
        dq -= np.einsum("fi,fi->f", dq, P.mech.c_normal)[:, None] * P.mech.c_normal
        assert np.allclose(P.friction_state(st)[:, 0], prev + np.linalg.norm(dq, axis=1), rtol=0, atol=1e-18)
    for e in terms:
        assert abs(e.defect) < 1e-11 * e.scale, e.as_dict()
        # |λ_τ| = r(δ) to Newton's tolerance, where r now moves with the slip itself (2.4e-11 measured)
        assert abs(e.contact_tangential_excess) < 1e-10 * e.scale
    fields = P.friction_fields(st)
    assert fields["friction_coefficient"].min() >= 0.3 - 1e-15 and fields["friction_coefficient"].max() <= 0.5
    assert np.any(fields["friction_coefficient"] == 0.3)                         # fully weakened faces
    C = shear_case(2, 16)
    sc = C.initial_state(1e5)
    for _ in range(7):
        sc, _ = C.step(sc, 10.0)
    slip = np.abs(P.jumps(st.u)[:, 0]).max()
    assert slip > 1.1 * np.abs(C.jumps(sc.u)[:, 0]).max()
