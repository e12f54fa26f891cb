"""The spring-slider reference of issue 28 (cases/spring_slider.py, docs/rate_state_design.md):
the exact state updates, the steady state and the critical stiffness k_c = (b − a) σ′/D_c."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from polypore.cases.spring_slider import SpringSlider, friction, state_after, steady_friction, state_rate

A, B, DC, F0, V0, SIGMA = 0.010, 0.015, 1e-4, 0.6, 1e-6, 50e6


@pytest.mark.parametrize("law", ["aging", "slip"])
@pytest.mark.parametrize("V", [1e-12, 1e-9, 1e-3])
def test_state_after_a_step_at_constant_rate_is_the_ode_solution(law, V):
    theta0, dt = 3.0 * DC / V, 5.0 * DC / V
    ode = solve_ivp(lambda t, y: [state_rate(V, y[0], DC, law)], (0.0, dt), [theta0], method="Radau",
                    rtol=1e-12, atol=1e-14 * theta0)
    assert state_after(theta0, V, dt, DC, law) == pytest.approx(ode.y[0, -1], rel=1e-9)


@pytest.mark.parametrize("V", [1e-12, 1e-9, 1e-6, 1e-2])
def test_steady_state_friction(V):
    """At steady state θ = D_c/V: μ = f₀ + (a − b) ln(V/V₀) (the regularisation is below round-off here)."""
    mu = friction(V, DC / V, A, B, F0, V0, DC)
    assert mu == pytest.approx(steady_friction(V, A, B, F0, V0), rel=1e-14)
    assert mu == pytest.approx(F0 + (A - B) * np.log(V / V0), rel=1e-12)
    # and the state laws are at rest there
    assert state_rate(V, DC / V, DC, "aging") == pytest.approx(0.0, abs=1e-15)
    assert state_rate(V, DC / V, DC, "slip") == pytest.approx(0.0, abs=1e-15)


def _growth(k, law):
    s = SpringSlider(k=k, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, law=law)
    ev = np.linalg.eigvals(s.jacobian(s.steady_state()))
    return float(np.max(ev.real[np.abs(ev) > 1e-14 * np.abs(ev).max()]))      # δ is a neutral direction


@pytest.mark.parametrize("law", ["aging", "slip"])
def test_critical_stiffness(law):
    """Steady sliding turns unstable below k_c for both state laws; the neutral stiffness found by
    bisection on the linearised system is k_c to 1e-6."""
    kc = SpringSlider(k=1.0, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, law=law).critical_stiffness
    assert kc == pytest.approx((B - A) * SIGMA / DC)
    assert _growth(0.9 * kc, law) > 0 > _growth(1.1 * kc, law)
    lo, hi = 0.9 * kc, 1.1 * kc
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _growth(mid, law) > 0 else (lo, mid)
    assert 0.5 * (lo + hi) == pytest.approx(kc, rel=1e-6)


def test_stable_slider_returns_to_steady_sliding_and_unstable_one_slips_fast():
    """A velocity step of 10 % relaxes back to V_L when k > k_c; below k_c (η > 0) the same step grows
    into stick-slip with slip rates orders of magnitude above V_L, bounded by radiation damping."""
    kc = (B - A) * SIGMA / DC
    y0 = np.array([0.0, np.log(1.1e-9), np.log(DC / 1e-9)])
    stable = SpringSlider(k=2 * kc, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0).integrate(2e6, y0)
    assert stable.success and np.exp(stable.y[1, -1]) == pytest.approx(1e-9, rel=1e-6)
    eta = 30e9 / (2 * 3464.0)                                  # μ_s/(2 c_s), Pa·s/m
    unstable = SpringSlider(k=0.2 * kc, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, eta=eta).integrate(3e7, y0)
    assert unstable.success
    vmax = float(np.exp(unstable.y[1].max()))
    assert 1e-3 < vmax < SIGMA / eta                            # seismic rates, below the damping's bound σ′/η


@pytest.mark.parametrize("law,stiffness,eta", [("aging", 2.0, 0.0), ("slip", 0.8, 30e9 / (2 * 3464.0))])
def test_polypore_step_converges_at_first_order_to_the_ode(law, stiffness, eta):
    """polypore's step for one patch (models/rate_state.py: the patch's scalar equation with β = k,
    the exact state update) on the spring-slider after a 10 % velocity step, stable (k = 2k_c) and
    growing (k = 0.8k_c): slip, ln V and ln θ converge to the Radau solution at first order (the
    step's rate is its mean, docs/rate_state_design.md)."""
    from polypore.cases.spring_slider import polypore_steps

    kc = (B - A) * SIGMA / DC
    s = SpringSlider(k=stiffness * kc, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, law=law, eta=eta)
    y0 = np.array([0.0, np.log(1.1e-9), np.log(DC / 1e-9)])
    T = 4e5 if stiffness > 1 else 2e6
    errors = []
    for n in (500, 1000, 2000):
        t, d, V, th, _ = polypore_steps(s, y0, T / n, n)
        ref = s.integrate(T, y0, t_eval=t)
        errors.append([np.max(np.abs(d - ref.y[0])) / np.max(np.abs(ref.y[0])),
                       np.max(np.abs(np.log(V[1:]) - ref.y[1][1:])), np.max(np.abs(np.log(th) - ref.y[2]))])
    errors = np.array(errors)
    order = np.log2(errors[:-1] / errors[1:])
    assert np.all((order > 0.9) & (order < 1.15)), order
    assert np.all(errors[-1] < (2e-4 if stiffness > 1 else 2e-2))
