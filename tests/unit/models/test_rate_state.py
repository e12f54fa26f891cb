"""The rate-and-state law of the contact patches (models/rate_state.py): its local slip-rate
solve, consistent tangent, exact state updates, steady state and initial state."""

import numpy as np
import pytest

from polypore.cases.spring_slider import friction as ref_friction, state_after, steady_friction
from polypore.models.contact import OPEN, SLIP, STICK, ContactLaw, linearise_contact
from polypore.models.friction import friction_law
from polypore.models.rate_state import RateAndState

A, B, DC, F0, V0 = 0.010, 0.015, 1e-3, 0.6, 1e-6


def law(n=1, state_law="aging", eta=0.0, a=A, b=B, vi=1e-9):
    return friction_law("rate-and-state", n, friction=F0, a=a, b=b, critical_slip=DC, reference_rate=V0,
                        initial_slip_rate=vi, damping=eta, state_law=state_law)


RATES = np.array([1e-25, 1e-15, 1e-9, 1e-6, 1e-3, 1.0])


@pytest.mark.parametrize("state_law", ["aging", "slip"])
def test_state_update_is_the_exact_solution(state_law):
    L = law(len(RATES), state_law)
    theta0 = 3.0 * DC / RATES
    dt = 0.7 * DC / RATES
    for k in range(len(RATES)):
        lt = L.log_state(np.log(RATES), theta0, float(dt[k]))[0][k]
        assert np.exp(lt) == pytest.approx(state_after(theta0[k], RATES[k], dt[k], DC, state_law), rel=1e-12)


@pytest.mark.parametrize("state_law", ["aging", "slip"])
def test_state_derivative_by_central_differences(state_law):
    L = law(len(RATES), state_law)
    x = np.log(RATES)
    theta0, dt = 0.3 * DC / RATES * np.linspace(0.5, 4, len(RATES)), 1e3
    h = 1e-6
    fd = (L.log_state(x + h, theta0, dt)[0] - L.log_state(x - h, theta0, dt)[0]) / (2 * h)
    assert np.allclose(L.log_state(x, theta0, dt)[1], fd, rtol=1e-6, atol=1e-9)


def test_coefficient_is_the_reference_and_the_classical_law():
    L = law(len(RATES))
    theta = DC / RATES * 2.0
    mu = L.friction(RATES, theta)
    assert np.allclose(mu, ref_friction(RATES, theta, A, B, F0, V0, DC), rtol=1e-13)
    big = RATES > 1e-20           # where V ≫ V₀ e^{−Ψ/a}: the classical form
    classical = F0 + A * np.log(RATES / V0) + B * np.log(V0 * theta / DC)
    assert np.allclose(mu[big], classical[big], rtol=1e-12)


@pytest.mark.parametrize("state_law", ["aging", "slip"])
def test_steady_state_at_imposed_rate(state_law):
    """At θ = D_c/V the state stays put over any step and μ = f₀ + (a − b) ln(V/V₀)."""
    V = np.array([1e-12, 1e-9, 1e-6, 1e-2])
    L = law(len(V), state_law)
    for dt in (1e-3, 1.0, 1e6):
        lt = L.log_state(np.log(V), DC / V, dt)[0]
        assert np.allclose(np.exp(lt), DC / V, rtol=1e-12)
    mu = L.friction(V, DC / V)
    assert np.allclose(mu, F0 + (A - B) * np.log(V / V0), rtol=1e-12)
    assert np.allclose(mu, steady_friction(V, A, B, F0, V0), rtol=1e-14)
    # and from another state, a long imposed slide reaches it
    lt = L.log_state(np.log(V), 50 * DC / V, float(200 * DC / V.min()))[0]
    assert np.allclose(L.friction(V, np.exp(lt)), F0 + (A - B) * np.log(V / V0), rtol=1e-12)


def _problem(n, seed=0):
    rng = np.random.default_rng(seed)
    sigma = 10e6 * rng.uniform(0.5, 2.0, n)
    theta0 = DC / 1e-9 * 10 ** rng.uniform(-3, 3, n)
    beta = 1e10 * rng.uniform(0.5, 2.0, n)
    return sigma, theta0, beta


@pytest.mark.parametrize("state_law", ["aging", "slip"])
@pytest.mark.parametrize("eta", [0.0, 5e6])
def test_local_solve_root_and_consistency_with_the_radius(state_law, eta):
    n = 40
    sigma, theta0, beta = _problem(n)
    dt = 1e-2
    L = law(n, state_law, eta)
    # trial tractions from far below to far above the friction at θ₀
    ny = sigma * np.linspace(0.3, 0.9, n)
    sol = L.solve_rate(sigma, ny, theta0, dt, beta)
    V = sol.rate
    assert np.all(V > 0)
    # r + βΔtV = |y| and r is the law's radius at the slip s = ΔtV (the energy audit's)
    assert np.allclose(sol.radius + beta * dt * V, ny, rtol=1e-13)
    slip = np.zeros((n, 3))
    slip[:, 0] = V * dt
    state = np.column_stack([theta0, np.full(n, 1e-9)])
    r = L.radius(sigma, slip, state, dt).value
    assert np.allclose(r, sol.radius, rtol=1e-9, atol=1e-6)


@pytest.mark.parametrize("state_law", ["aging", "slip"])
@pytest.mark.parametrize("eta", [0.0, 5e6])
def test_consistent_tangent_by_central_differences(state_law, eta):
    n = 40
    sigma, theta0, beta = _problem(n, 1)
    dt = 1e-3
    L = law(n, state_law, eta)
    ny = sigma * np.linspace(0.4, 0.8, n)
    sol = L.solve_rate(sigma, ny, theta0, dt, beta)
    h = 1e-7
    d_ny = (L.solve_rate(sigma, ny * (1 + h), theta0, dt, beta).radius
            - L.solve_rate(sigma, ny * (1 - h), theta0, dt, beta).radius) / (2 * h * ny)
    d_s = (L.solve_rate(sigma * (1 + h), ny, theta0, dt, beta).radius
           - L.solve_rate(sigma * (1 - h), ny, theta0, dt, beta).radius) / (2 * h * sigma)
    ok = sol.monotone
    assert np.allclose(sol.d_trial[ok], d_ny[ok], rtol=1e-5, atol=1e-7)
    assert np.allclose(sol.d_normal[ok], d_s[ok], rtol=1e-5, atol=1e-7)
    assert np.all((sol.d_trial >= 0) & (sol.d_trial <= 1))
    # where the state softens faster than the direct effect stiffens, the step is too long
    w = sol.rate * dt / DC
    assert np.all(w[~ok] > 0.1 * A / B)
    assert ok.sum() >= n - 3


def test_start_recovers_the_initial_traction():
    n = 5
    eta = 2e6
    L = law(n, eta=eta, vi=1e-12)
    sig = np.full(n, 50e6)
    tau = np.array([0.3, 0.45, 0.5, 0.55, 0.6]) * 50e6
    st = L.start(L.initial_state(n), sig, tau)
    eta_eff = L.damping_at(sig)[0]
    assert np.allclose(eta_eff, eta, rtol=1e-4)
    assert np.allclose(sig * L.friction(np.full(n, 1e-12), st[:, 0]) + eta_eff * 1e-12, tau, rtol=1e-12)
    assert np.all(st[:, 1] == 1e-12)
    # an open patch takes the steady state
    st = L.start(L.initial_state(n), np.zeros(n), tau)
    assert np.allclose(st[:, 0], DC / 1e-12)


def test_bad_coefficients_name_their_key():
    from polypore.core.errors import InputError
    with pytest.raises(InputError, match="critical_slip"):
        friction_law("rate-and-state", 2, friction=0.6, a=0.01, b=0.01, critical_slip=0.0, initial_slip_rate=1e-9)
    with pytest.raises(InputError, match="state_law"):
        RateAndState(np.full(1, 0.6), 0.01, 0.01, 1e-3, 1e-6, 1e-9, 0.0, state_law="ageing")
    with pytest.raises(InputError, match="initial_slip_rate"):
        friction_law("rate-and-state", 1, friction=0.6, a=0.01, b=0.01, critical_slip=1e-3)


def _contact(n, dt, eta=0.0, seed=3):
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    L = law(n, eta=eta)
    beta = 1e10 * rng.uniform(0.5, 2, n)
    sig = 20e6 * rng.uniform(0.2, 1, n)
    t = rng.normal(size=(n, 3))
    t -= np.einsum("fi,fi->f", t, normal)[:, None] * normal
    t /= np.linalg.norm(t, axis=1)[:, None]
    # shear ratios from well below to above the friction: patches held, creeping and sliding fast
    lam = sig[:, None] * normal + (sig * np.linspace(0.3, 0.75, n))[:, None] * t
    q = 1e-6 * rng.normal(size=(n, 3))
    state = np.column_stack([DC / 1e-9 * 10 ** rng.uniform(-2, 2, n), np.full(n, 1e-9)])
    return ContactLaw(L, beta), lam, q, normal, np.ones(n), state


@pytest.mark.parametrize("eta", [0.0, 3e6])
def test_contact_jacobian_by_central_differences(eta):
    n, dt = 12, 1e-2
    cl, lam, q, normal, area, state = _contact(n, dt, eta)
    C, dC_dlam, dC_dq, codes = linearise_contact(cl, lam, q, q, normal, area, state, dt)
    assert set(codes) == {STICK, SLIP}
    for j in range(3):
        e = np.zeros((n, 3))
        hl, hq = 1e2, 1e-9
        e[:, j] = hl
        fd_l = (linearise_contact(cl, lam + e, q, q, normal, area, state, dt)[0]
                - linearise_contact(cl, lam - e, q, q, normal, area, state, dt)[0]) / (2 * hl)
        e[:, j] = hq
        fd_q = (linearise_contact(cl, lam, q + e, q + e, normal, area, state, dt)[0]
                - linearise_contact(cl, lam, q - e, q - e, normal, area, state, dt)[0]) / (2 * hq)
        scale_l = float(np.max(area / cl.beta))       # the identity's scale in dC/dλ
        scale_q = float(np.max(area))
        assert np.allclose(dC_dlam[:, :, j], fd_l, atol=1e-6 * scale_l)
        assert np.allclose(dC_dq[:, :, j], fd_q, atol=1e-6 * scale_q)


def test_static_solve_holds_every_closed_patch():
    n = 6
    cl, lam, q, normal, area, state = _contact(n, 0.0)
    C, dC_dlam, dC_dq, codes = linearise_contact(cl, lam, q, q, normal, area, state, 0.0)
    closed = np.einsum("fi,fi->f", lam, normal) + cl.beta * np.einsum("fi,fi->f", q, normal) > 0
    assert np.all(codes[closed] == STICK) and np.all(codes[~closed] == OPEN)
    # held: λ − P(y) = −β q on closed patches
    assert np.allclose(C[closed], -(area / cl.beta)[closed, None] * cl.beta[closed, None] * q[closed], rtol=1e-9)


def test_radius_fades_continuously_on_opening():
    """With radiation damping the radius → 0 as σ′ → 0⁺, as on an open patch (no jump at y_n = 0)."""
    L = law(5, eta=5e6)
    yn = np.array([1e-3, 1.0, 1e2, 0.0, -1.0])
    st = L.initial_state(5)
    rad = L.trial_radius(yn, np.full(5, 1e5), st, 1e-3, np.full(5, 1e10))
    assert rad.value[3] == 0.0 and rad.value[4] == 0.0
    assert rad.value[0] < 1e-2 * 1e5 * 1e-3 and rad.value[0] < rad.value[1] < rad.value[2]


@pytest.mark.parametrize("state_law", ["aging", "slip"])
def test_step_error_is_the_rate_change_the_state_update_depends_on(state_law):
    """A step at constant V has no error however much θ changes (the update is exact: a locked
    fault heals in one step); otherwise the measure is |Δ ln(V + V_f)| max(1, |∂ln θ/∂ln V|)."""
    L = law(3, state_law)
    theta0 = np.array([13.0, DC / 1e-6, 1e4])
    V = np.array([1e-12, 1e-6, 1e-3])
    dt = 4.32e5
    old = np.column_stack([theta0, V])
    healed = np.column_stack([np.exp(L.log_state(np.log(V), theta0, dt)[0]), V])
    assert np.max(np.abs(np.log(healed[:, 0] / theta0))) > 5         # θ changed by e^5 and more
    # (the two sliding patches are flagged as stepped too long for the state, ΔtV/D_c ≫ a/b: apart)
    assert L.step_error(old, healed, dt)[0] == 0.0
    V2 = V * np.array([1.0, 2.0, 1.0])
    new = np.column_stack([np.exp(L.log_state(np.log(V2), theta0, dt)[0]), V2])
    vf = 0.1 * L.stick_rate
    dlt = L.log_state(np.log(V2), theta0, dt)[1][1]
    err, _ = L.step_error(old, new, dt)
    assert err == pytest.approx(np.log((2e-6 + vf) / (1e-6 + vf)) * max(1.0, abs(dlt)), rel=1e-12)
