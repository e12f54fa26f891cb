"""The quasi-dynamic spring-slider with rate-and-state friction: the reference of issue 28's checks
(docs/rate_state_design.md).

A block on a frictional interface under normal stress σ′ (Pa), pulled through a spring of
stiffness k (Pa/m, per unit area) whose far end moves at V_L (m/s), with radiation damping η V:

    k (V_L t − δ) + τ₀ = σ′ μ(V, θ) + η V,      δ̇ = V,

μ the regularised rate-and-state coefficient and θ the state of the aging or the slip law (module
functions below). Differentiating the balance in time gives an ODE for (δ, ln V, ln θ), which
:meth:`SpringSlider.integrate` solves with SciPy's implicit Radau method to a tight tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STATE_LAWS = ("aging", "slip")


def friction(V, theta, a, b, f0, V0, Dc):
    """μ(V, θ) = a asinh(V/(2V₀) exp(Ψ/a)), Ψ = f₀ + b ln(V₀θ/D_c): the regularised coefficient
    (V in m/s, θ in s, D_c in m); the classical f₀ + a ln(V/V₀) + b ln(V₀θ/D_c) for V ≫ V₀ e^{−Ψ/a}."""
    psi = f0 + b * np.log(V0 * theta / Dc)
    return a * np.arcsinh(V / (2 * V0) * np.exp(psi / a))


def state_rate(V, theta, Dc, law: str = "aging"):
    """θ̇ (dimensionless): aging 1 − Vθ/D_c, slip −(Vθ/D_c) ln(Vθ/D_c)."""
    x = V * theta / Dc
    return 1.0 - x if law == "aging" else -x * np.log(x)


def state_after(theta0, V, dt, Dc, law: str = "aging"):
    """θ after a time dt at constant slip rate V > 0: the exact solutions of both state laws,
    aging θ = D_c/V + (θ₀ − D_c/V) e^{−V dt/D_c}, slip ln(Vθ/D_c) = ln(Vθ₀/D_c) e^{−V dt/D_c}."""
    decay = np.exp(-V * dt / Dc)
    if law == "aging":
        return Dc / V + (theta0 - Dc / V) * decay
    return Dc / V * np.exp(np.log(V * theta0 / Dc) * decay)


def steady_friction(V, a, b, f0, V0):
    """μ at steady state (θ = D_c/V, both laws): a asinh(V/(2V₀) e^{(f₀ + b ln(V₀/V))/a}),
    f₀ + (a − b) ln(V/V₀) in the classical range."""
    return a * np.arcsinh(V / (2 * V0) * np.exp((f0 + b * np.log(V0 / V)) / a))


@dataclass(frozen=True)
class SpringSlider:
    """The spring-slider's data (SI units): k (Pa/m), σ′ (Pa), a, b, f₀ (dimensionless), V₀, V_L
    (m/s), D_c (m), η (Pa·s/m), the state law ("aging" or "slip")."""

    k: float
    sigma: float
    a: float
    b: float
    Dc: float
    f0: float = 0.6
    V0: float = 1e-6
    VL: float = 1e-9
    eta: float = 0.0
    law: str = "aging"

    def __post_init__(self):
        if self.law not in STATE_LAWS:
            raise ValueError(f"law must be one of {STATE_LAWS}, got {self.law!r}")

    @property
    def critical_stiffness(self) -> float:
        """k_c = (b − a) σ′/D_c, Pa/m: steady sliding is unstable for k < k_c (Ruina 1983)."""
        return (self.b - self.a) * self.sigma / self.Dc

    def rhs(self, t, y):
        """d/dt (δ, ln V, ln θ) from the time derivative of the balance."""
        V, theta = np.exp(y[1]), np.exp(y[2])
        a, b = self.a, self.b
        z = V / (2 * self.V0) * np.exp((self.f0 + b * np.log(self.V0 * theta / self.Dc)) / a)
        root = np.sqrt(1.0 + z * z)
        dmu_dlnV = a * z / root                     # V ∂μ/∂V
        dmu_dlntheta = b * z / root                 # θ ∂μ/∂θ
        dlntheta = state_rate(V, theta, self.Dc, self.law) / theta
        # k (V_L − V) = σ′ (μ_V V̇ + μ_θ θ̇) + η V̇, with V̇ = V d(ln V)/dt, θ̇ = θ d(ln θ)/dt
        dlnV = (self.k * (self.VL - V) - self.sigma * dmu_dlntheta * dlntheta) / (self.sigma * dmu_dlnV + self.eta * V)
        return np.array([V, dlnV, dlntheta])

    def jacobian(self, y, h: float = 1e-6) -> np.ndarray:
        """(3, 3) ∂rhs/∂y by central differences (the linear stability of a state)."""
        J = np.zeros((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            J[:, j] = (self.rhs(0.0, y + e) - self.rhs(0.0, y - e)) / (2 * h)
        return J

    def steady_state(self) -> np.ndarray:
        """(δ = 0, ln V_L, ln(D_c/V_L)): steady sliding at the load-point velocity."""
        return np.array([0.0, np.log(self.VL), np.log(self.Dc / self.VL)])

    def integrate(self, t_end: float, y0=None, rtol: float = 1e-11, atol: float = 1e-13, t_eval=None):
        """SciPy's ``solve_ivp`` (Radau) from ``y0`` (default: steady state) to ``t_end`` (s);
        returns its solution object (t, y = (δ, ln V, ln θ))."""
        from scipy.integrate import solve_ivp

        y0 = self.steady_state() if y0 is None else np.asarray(y0, float)
        return solve_ivp(self.rhs, (0.0, t_end), y0, method="Radau", rtol=rtol, atol=atol, t_eval=t_eval,
                         jac=lambda t, y: self.jacobian(y))



class PatchSlider:
    """The spring-slider as one contact patch of the model (models/rate_state.py): the balance
    k(V_L t_n − δ_n) + τ₀ = σ′μ(V, θ(V)) + ηV with V = (δ_n − δ_{n−1})/Δt and θ(V) the exact
    state update is r(V) + kΔtV = τ₀ + k(V_L t_n − δ_{n−1}), the patch's scalar equation with β = k,
    solved by :meth:`RateAndState.solve_rate`; the state (θ, V) is the law's.

    Parameters
    ----------
    slider : SpringSlider;  y0 : (δ, ln V, ln θ) at t = 0 (τ₀ follows from the balance there)
    """

    def __init__(self, slider: SpringSlider, y0):
        from ..models.rate_state import RateAndState

        self.slider = slider
        one = self.one = np.ones(1)
        V, theta = float(np.exp(y0[1])), float(np.exp(y0[2]))
        self.law = RateAndState(one * slider.f0, slider.a, slider.b, slider.Dc, slider.V0, V, slider.eta, slider.law)
        self.delta0 = float(y0[0])
        self.state0 = np.array([[theta, V]])               # the law's (n = 1, 2) state
        sigma = one * slider.sigma
        self.tau0 = float(sigma[0] * self.law.friction(one * V, one * theta)[0]
                          + self.law.damping_at(sigma)[0][0] * V) + slider.k * self.delta0

    def step(self, t: float, h: float, delta: float, state: np.ndarray) -> np.ndarray:
        """The law's state (1, 2) after the step t − h → t (s) from slip ``delta`` (m) and ``state``."""
        s, one = self.slider, self.one
        y = self.tau0 + s.k * (s.VL * t - delta)
        V = self.law.solve_rate(one * s.sigma, one * y, state[:, 0], h, one * s.k, guess=state[:, 1]).rate
        return self.law.advance_at(state, V, h)

    def shear(self, t: float, delta: float) -> float:
        """τ = τ₀ + k(V_L t − δ), Pa."""
        return self.tau0 + self.slider.k * (self.slider.VL * t - delta)


def polypore_steps(slider: SpringSlider, y0, dt: float, n_steps: int):
    """The spring-slider stepped by polypore's own scheme for a contact patch (:class:`PatchSlider`)
    with n_steps fixed steps dt (s) from y0 = (δ, ln V, ln θ).

    Returns
    -------
    t, δ (m), V (m/s), θ (s), τ (Pa): (n_steps + 1,) each
    """
    p = PatchSlider(slider, y0)
    delta, state = p.delta0, p.state0
    out = np.zeros((n_steps + 1, 5))
    out[0] = 0.0, delta, state[0, 1], state[0, 0], p.shear(0.0, delta)
    for n in range(1, n_steps + 1):
        t = n * dt
        state = p.step(t, dt, delta, state)
        delta += state[0, 1] * dt
        out[n] = t, delta, state[0, 1], state[0, 0], p.shear(t, delta)
    return out.T
