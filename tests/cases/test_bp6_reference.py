"""The BP6 reference (src/polypore/cases/bp6.py, docs/bp6.md): its pressure against a numerical
solution of the diffusion equation, its kernel against the elliptical crack, its QD-C solver
against the crack with bounded stress, its rate-and-state solver at steady sliding."""

import numpy as np
import pytest
from scipy import optimize, sparse
from scipy.sparse.linalg import splu

from polypore.cases import bp6

DAY = bp6.DAY
P = bp6.Bp6Parameters()


def test_parameters_of_the_description():
    assert P.alpha == pytest.approx(0.1, rel=1e-12)
    assert P.eta == pytest.approx(32.04e9 / (2 * 3464.0), rel=1e-15)
    assert P.mu == pytest.approx(P.rho * P.cs ** 2, rel=2e-4)          # Table 1 rounds ρc_s² = 32.038 GPa
    # eq. (24): the initial state makes f(V_init, θ₀) = τ_init/σ̄₀
    psi = P.f0 + P.b * np.log(P.V0 * P.theta0 / P.Dc)
    f_init = P.a * np.arcsinh(P.V_init / (2 * P.V0) * np.exp(psi / P.a))
    assert f_init == pytest.approx(P.tau_init / P.sigma0, rel=1e-13)


def test_pressure_against_numerical_diffusion():
    """Crank–Nicolson finite volumes (h = 10 m, Δt = 600 s) of ∂p/∂t = α∂²p/∂z² + (q₀/βφ)δ(z) on
    a fault shortened to l_f = 3 km with no-flux ends, through shut-in: eq. (26) with its images
    agrees to 1e-4 of the peak; without the images it does not (the ends matter by 150 days)."""
    prm = bp6.with_(P, lf=3000.0)
    n = 2 * int(prm.lf / 10.0 - 0.5) + 1
    h = 2 * prm.lf / n
    z = (np.arange(n) - n // 2) * h
    main = np.full(n, -2.0)
    main[[0, -1]] = -1.0                                       # no flux through z = ±l_f
    lap = sparse.diags([np.ones(n - 1), main, np.ones(n - 1)], [-1, 0, 1]) * (prm.alpha / h ** 2)
    src = np.zeros(n)
    src[n // 2] = prm.source / h
    dt = 600.0
    eye = sparse.identity(n)
    lhs, rhs = splu((eye - 0.5 * dt * lap).tocsc()), (eye + 0.5 * dt * lap).tocsr()
    p, t = np.zeros(n), 0.0
    for T in (10 * DAY, prm.t_off, 150 * DAY, 300 * DAY):
        while t < T - 1e-6:
            p = lhs.solve(rhs @ p + dt * (src if t + 0.5 * dt < prm.t_off else 0.0))
            t += dt
        exact = bp6.pore_pressure(z, t, prm)
        assert np.abs(p - exact).max() < 1e-4 * exact.max()
        if T == 300 * DAY:
            assert np.abs(p - bp6.pore_pressure(z, t, prm, images=0)).max() > 0.1 * exact.max()
    # the Darcy velocity is −(k/η_f)∂p/∂z of eq. (26): q₀/2 each way at the source
    zz = np.array([-800.0, 300.0, 1500.0])
    dp = (bp6.pore_pressure(zz + 0.01, 50 * DAY, P) - bp6.pore_pressure(zz - 0.01, 50 * DAY, P)) / 0.02
    assert bp6.darcy_velocity(zz, 50 * DAY, P) == pytest.approx(-P.k / P.eta_f * dp, rel=1e-6)
    assert bp6.darcy_velocity(1e-9, 50 * DAY, P) == pytest.approx(P.q0 / 2, rel=1e-9)


def test_kernel_against_elliptical_crack():
    """The cell means of the slip (2Δσ/μ)√(a² − z²) on n cells of (−1.5a, 1.5a) (tips at cell
    edges): −Δσ inside to 1e-6 of Δσ (|z| < a/2), Δσ(|z|/√(z² − a²) − 1) outside at more than a/5
    from the tips to 2e-4, that error falling as h² (×4 per halving, the tips' cells); the FFT
    product is the dense one; Σ_{|m|<n} k_m = −μ/(πh(n − ½)) (→ 0: uniform slip is stress-free)."""
    a, ds = 1000.0, 1e6

    def primitive(x):
        x = np.clip(x, -a, a)
        return 0.5 * (x * np.sqrt(a * a - x * x) + a * a * np.arcsin(x / a))

    far_err = []
    for n in (400, 800):
        h = 3 * a / n
        z = -1.5 * a + h * (np.arange(n) + 0.5)
        K = bp6.Kernel(n, h, P.mu)
        slip = 2 * ds / P.mu * (primitive(z + h / 2) - primitive(z - h / 2)) / h
        tau = K(slip)
        assert np.abs(tau - K.dense() @ slip).max() < 1e-9 * ds
        err = np.abs(tau - bp6.elliptical_crack_stress(z, a, ds))
        assert err[np.abs(z) < 0.5 * a].max() < 1e-6 * ds
        far_err.append(err[np.abs(np.abs(z) - a) > 0.2 * a].max())
        assert far_err[-1] < 2e-4 * ds
        assert 2 * K.row[1:].sum() + K.row[0] == pytest.approx(-P.mu / (np.pi * h * (n - 0.5)), rel=1e-9)
    assert far_err[0] / far_err[1] > 3.5


def test_crack_solution():
    """The crack Green function gives (2Δσ/μ)√(a² − x²) under uniform Δσ; QD-C's crack has a
    zero stress-intensity factor and starts at t_c = πα((fσ̄₀ − τ⁰)/(f q₀/βφ))² (4.1 days)."""
    x = np.array([0.0, 300.0, -700.0, 990.0])
    assert bp6.crack_slip(x, 1000.0, lambda s: 1e6 + 0 * s, P.mu) == pytest.approx(
        2e6 / P.mu * np.sqrt(1000.0 ** 2 - x ** 2), rel=1e-9)
    prm = P
    t = 30 * DAY
    a = bp6.constant_friction_crack(t, prm)
    # bounded stress: ∫₀^a Δσ/√(a² − z²) dz = 0, checked by quadrature on a fine grid
    ph = np.linspace(0, np.pi / 2, 20001)
    p = bp6.pore_pressure(a * np.sin(ph), t, prm, images=0)
    dsig = prm.tau0("QD-C") - prm.f_const * prm.sigma0 + prm.f_const * p
    assert abs(np.trapezoid(dsig, ph)) < 1e-6 * prm.f_const * prm.sigma0
    # onset: f p(0, t) = fσ̄₀ − τ⁰ at t_c, no slip before
    tc = np.pi * ((prm.f_const * prm.sigma0 - prm.tau_init) / (prm.f_const * prm.source)) ** 2 * prm.alpha
    assert bp6.constant_friction_crack(0.99 * tc, prm) == 0.0
    assert bp6.constant_friction_crack(1.05 * tc, prm) > 0.0


def test_qdc_against_crack_with_bounded_stress():
    """QD-C by the LCP (h = 10 m) at 10, 30 and 100 days of injection against the semi-analytical
    crack (η → 0): front to h/2, slip at z = 0, 0.5 km to 4e-3 of the
    slip at the centre (3e-3 at 10 days, the crack 22 cells long; 7e-5 at 100 days)."""
    times = np.array([10, 30, 100]) * DAY
    r = bp6.run_constant_friction(P, dz=10.0, half_length=4e3, t_out=times, profile_t=[], t_final=P.t_off,
                                  dt_first=5 * DAY, dt_max=50 * DAY)
    for i, t in enumerate(times, start=1):
        a = bp6.constant_friction_crack(t, P)
        assert abs(r.front_tip[i] - a) < 0.5 * r.h
        ref = bp6.constant_friction_slip([0.0, 500.0], t, P)
        assert np.abs(r.slip[i, [1, 2]] - ref).max() < 4e-3 * ref[0]
    # the slipped region only grows while injecting; strength is never exceeded
    assert np.all(np.diff(r.front_tip) >= 0)


def test_clamped_circle_correction_decays_as_inverse_square():
    """A crack of half-length 1 km under uniform stress drop, in a clamped circle of radius R
    (images, antiplane): the slip lost to the boundary falls 4× per doubling of R."""
    z, h = bp6.grid(P, 50.0, 4000.0)
    m = np.abs(z) < 1000.0
    K = bp6.Kernel(z.size, h, P.mu).dense()[np.ix_(m, m)]
    free = np.linalg.solve(K, -np.ones(m.sum())).max()
    loss = []
    for R in (2e4, 4e4, 8e4):
        Ki = bp6.clamped_image_matrix(z, h, P.mu, R)[np.ix_(m, m)]
        loss.append(1 - np.linalg.solve(K + Ki, -np.ones(m.sum())).max() / free)
    assert 0 < loss[-1] < loss[0]
    assert loss[0] / loss[1] == pytest.approx(4.0, rel=0.05)
    assert loss[1] / loss[2] == pytest.approx(4.0, rel=0.05)


@pytest.mark.parametrize("law", ["aging", "slip"])
def test_rate_state_reaches_steady_friction(law):
    """From an off-steady state (f(V₀, θ₀) = f₀ + 0.001, θ₀ = 1.22 D_c/V₀) at constant stress and
    no injection, the solver's fault relaxes to steady sliding: τ/σ̄₀ = f₀ + (a − b) ln(V/V₀) to
    1e-8 and V the root of τ⁰ − ηV = σ̄₀(f₀ + (a − b) ln(V/V₀)) to 1e-5 (D_c = 1 µm so that the
    relaxation is over in seconds; a fault 2000 km long so that its locked ends are felt below 1e-6)."""
    prm = bp6.with_(P, Dc=1e-6, V_init=P.V0, tau_init=P.sigma0 * (P.f0 + 0.001))
    assert prm.theta0 == pytest.approx(np.exp(0.2) * prm.Dc / prm.V0, rel=1e-9)
    t_end = 60.0
    r = bp6.run_rate_state(prm, law=law, dz=2e4, half_length=1e6, t_out=[1.0, t_end], profile_t=[],
                           t_final=t_end, pressure=False, rtol=1e-10, atol_slip=1e-14)
    V, tau = r.slip_rate[-1, 1], r.shear_stress[-1, 1]
    assert tau / prm.sigma0 == pytest.approx(prm.f0 + (prm.a - prm.b) * np.log(V / prm.V0), abs=1e-8)
    tau0 = prm.tau0("QD-A")
    Vss = optimize.brentq(lambda v: tau0 - prm.eta * v - prm.sigma0 * (prm.f0 + (prm.a - prm.b) * np.log(v / prm.V0)),
                          1e-7, 1e-5, xtol=1e-20)
    assert V == pytest.approx(Vss, rel=1e-5)
    assert r.slip_rate[1, 1] != pytest.approx(Vss, rel=1e-3)       # it did relax


def test_rate_state_coarse_run_is_symmetric_and_uses_the_pressure():
    """QD-A on 80-m cells to 30 days: the stations ±1.5 km agree, the pressure is eq. (26)."""
    r = bp6.run_rate_state(P, law="aging", dz=80.0, t_out=np.array([10, 30]) * DAY, profile_t=[], t_final=30 * DAY)
    i, j = P.stations.index(-1500.0), P.stations.index(1500.0)
    assert np.abs(r.slip[:, i] - r.slip[:, j]).max() < 1e-9 * r.slip[:, 1].max()
    assert r.pore_pressure[-1, 1] == pytest.approx(float(bp6.pore_pressure(0.0, 30 * DAY, P)), rel=1e-12)
    assert r.slip[-1, 1] > r.slip[-1, 2] > 0
