"""Rate-and-state friction with radiation damping on the contact patches (issue 28,
docs/rate_state_design.md).

On a closed patch with effective normal traction σ′ = [y_n]_+ (Pa) the friction disc has radius

    r(V) = σ′ μ(V, θ(V)) + η V,     μ = a asinh( V/(2V₀) exp(Ψ/a) ),  Ψ = f₀ + b ln(V₀ θ/D_c),

the regularised coefficient (Rice and Ben-Zion 1996; Lapusta et al. 2000), valid down to V = 0;
η = μ_s/(2 c_s) (Pa·s/m) the radiation damping of the quasi-dynamic approximation (Rice 1993).
V = |s_τ|/Δt is the step's slip rate (m/s) and θ(V) the state after the step at that constant
rate, by the exact solutions of the state laws (aging θ̇ = 1 − Vθ/D_c, slip θ̇ = −(Vθ/D_c)
ln(Vθ/D_c)), so the state update adds no time discretisation of its own.

r(0) = 0: a regularised law has no static threshold, every closed patch creeps, and ∂r/∂V at
V → 0 is of order σ′ a e^{f₀/a}/V₀ (10²⁶ σ′/V₀ for f₀/a = 60). The contact projection therefore
does not take r at the iterate's slip: it solves the sliding patch's scalar equation

    g(V) = r(V) + β Δt V − |y_τ| = 0

for V in x = ln V (one root where g increases; a safeguarded Newton with a bracket), and hands the
global Jacobian the consistent tangent of that solution, ∂r/∂|y_τ| = r′/(r′ + βΔt) ∈ [0, 1], in
place of the unbounded ∂r/∂s_τ (:meth:`RateAndState.trial_radius`). At the root λ_τ = r ŷ and
s_τ = ΔtV ŷ satisfy λ_τ = [λ_τ + β s_τ]_r: the projection's solution, so the contact conditions
are still exact per multiplier, and the dissipation λ_τ·s_τ = r |s_τ| ≥ 0.

In a static solve (Δt = 0) the law holds every closed patch (r = ∞): the run's initial
equilibrium is bonded, and :meth:`RateAndState.start` then finds each patch's state from its
traction and the initial slip rate, τ = σ′ μ(V_i, θ₀) + η V_i.

State per patch (n, 2): θ (s) and the last step's slip rate V (m/s).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError
from .friction import Radius, _check

STATE_LAWS = ("aging", "slip")
INITIAL_STATES = ("traction", "steady")
# the local Newton's stopping test on x = ln V, and its iteration cap (a bracket halves at worst)
LOCAL_TOL = 1e-13
LOCAL_ITERATIONS = 200
_BIG = 700.0          # exp() argument cap
# the time step control measures ln(V + V_f) with V_f = RATE_FLOOR × stick_rate: the changes of
# slip rates far below what is reported as slip do not steer the step
RATE_FLOOR = 0.1
# **Choice**: the radiation damping fades as a patch opens, η σ′/(σ′ + DAMPING_FADE) (Pa): an
# open patch carries no shear traction, and a damping that vanished abruptly there made the
# projection jump at y_n = 0 (r(0⁺) = η|y_τ|/(η + βΔt)), on which the semi-smooth Newton cycled
# between open and closed (the near-open end face of the rate-state-slider case); at σ′ ≥ 1 MPa
# the damping is η to 1e-3
DAMPING_FADE = 1e3


@dataclass(frozen=True)
class SlidingSolution:
    """A patch's solution of r(V) + βΔtV = |y_τ| (:meth:`RateAndState.solve_rate`).

    Attributes
    ----------
    rate : (n,) V, m/s
    radius : (n,) r(V), Pa
    d_trial : (n,) ∂r/∂|y_τ| at fixed σ′ (dimensionless, in [0, 1])
    d_normal : (n,) ∂r/∂σ′ with V following the trial (dimensionless)
    iterations : the local Newton's iterations (the largest over the patches)
    monotone : (n,) bool, g increases at the root (its only root); False where the state's
        softening over the step outweighs the direct effect (a step too long for the state,
        ΔtV/D_c ≳ a/b: the root may not be unique, and the time step control must shorten it)
    """

    rate: np.ndarray
    radius: np.ndarray
    d_trial: np.ndarray
    d_normal: np.ndarray
    iterations: int
    monotone: np.ndarray


@dataclass(frozen=True, eq=False)
class RateAndState:
    """Regularised rate-and-state friction with the aging or the slip law and radiation damping.

    Parameters (per patch, (n,), or scalars)
    ----------
    f0 : reference coefficient at V₀ (``friction``);  a, b : direct and evolution effects (–)
    critical_slip : D_c > 0, m;  reference_rate : V₀ > 0, m/s
    initial_rate : V_i > 0, m/s, the slip rate at the start (the state follows from the traction)
    damping : η = μ_s/(2 c_s) ≥ 0, Pa·s/m (0: fully quasi-static)
    state_law : "aging" or "slip"
    stick_rate : slip rate (m/s) below which a patch is reported as stick (the derivative does not
        depend on it: the law is smooth)
    start_from : "traction" (θ₀ such that the initial traction slides at V_i) or "steady"
        (θ₀ = D_c/V_i, the slip rate then what the initial traction gives)
    """

    f0: np.ndarray
    a: np.ndarray
    b: np.ndarray
    critical_slip: np.ndarray
    reference_rate: np.ndarray
    initial_rate: np.ndarray
    damping: np.ndarray
    state_law: str = "aging"
    stick_rate: float = 1e-9
    start_from: str = "traction"
    name: str = field(default="rate-and-state", init=False)
    instability_hint = ("With rate-and-state friction and a < b the fault can nucleate an earthquake; the run's time "
                        "step must follow the slip rate (the time step control of [time]) and radiation damping "
                        "(contact.shear_wave_speed) keeps the slip rate bounded")

    def __post_init__(self):
        f0 = _check("friction", self.f0, "must be finite and ≥ 0")
        n = f0.shape

        def arr(key, v, what, positive=False):
            return np.array(_check(key, np.broadcast_to(np.asarray(v, float), n), what, positive), float)

        object.__setattr__(self, "f0", np.array(f0, float))
        object.__setattr__(self, "a", arr("a", self.a, "must be finite and > 0", positive=True))
        object.__setattr__(self, "b", arr("b", self.b, "must be finite and ≥ 0"))
        object.__setattr__(self, "critical_slip", arr("critical_slip", self.critical_slip,
                                                      "must be finite and > 0 (m)", positive=True))
        object.__setattr__(self, "reference_rate", arr("reference_rate", self.reference_rate,
                                                       "must be finite and > 0 (m/s)", positive=True))
        object.__setattr__(self, "initial_rate", arr("initial_slip_rate", self.initial_rate,
                                                     "must be finite and > 0 (m/s)", positive=True))
        object.__setattr__(self, "damping", arr("shear_wave_speed", self.damping,
                                                "gives a radiation damping that must be finite and ≥ 0 (Pa·s/m)"))
        if self.state_law not in STATE_LAWS:
            raise InputError("state_law", f"unknown state law {self.state_law!r}; allowed: {', '.join(STATE_LAWS)}")
        if self.start_from not in INITIAL_STATES:
            raise InputError("start_from", f"must be one of {', '.join(INITIAL_STATES)}, got {self.start_from!r}")
        if not (np.isfinite(self.stick_rate) and self.stick_rate > 0):
            raise InputError("stick_rate", f"must be finite and > 0 (m/s), got {self.stick_rate!r}")

    # ---- the coefficient and the state ---------------------------------------------------------
    def log_state(self, x: np.ndarray, theta0: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(ln θ, ∂ln θ/∂x) after a step Δt (s) at constant V = e^x from θ₀ (s), (n,) each: the
        exact solutions of the state law (module docstring). V = 0 (x = −∞): aging θ₀ + Δt, slip θ₀."""
        Dc = self.critical_slip
        w = np.exp(np.minimum(x + np.log(dt / Dc), _BIG))            # V Δt / D_c
        e = np.exp(-w)
        if self.state_law == "aging":
            # θ = θ₀ e^{−w} + Δt φ(w), φ(w) = (1 − e^{−w})/w: no D_c/V cancellation at small V
            small = w < 1e-4
            ws = np.where(small, 1.0, w)
            phi = np.where(small, 1.0 - w / 2 + w * w / 6, -np.expm1(-ws) / ws)
            dphi = np.where(small, -0.5 + w / 3 - w * w / 8, (e * (1.0 + ws) - 1.0) / (ws * ws))
            theta = theta0 * e + dt * phi
            return np.log(theta), w * (-theta0 * e + dt * dphi) / theta
        # slip law: ln(Vθ/D_c) = ln(Vθ₀/D_c) e^{−w}; V = 0 keeps θ₀ (x = −∞ would give −∞ + ∞)
        finite = np.isfinite(x)
        xf = np.where(finite, x, 0.0)
        L0 = xf + np.log(theta0 / Dc)
        lt = np.where(finite, np.log(Dc) - xf + L0 * e, np.log(theta0))
        return lt, np.where(finite, np.expm1(-w) - L0 * w * e, 0.0)

    def coefficient(self, x: np.ndarray, log_theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(μ, ∂μ/∂ln z) at V = e^x and θ = e^{log_theta}, ln z = x − ln 2V₀ + Ψ/a; asinh evaluated
        in logs so that neither tiny nor huge z over- or underflows."""
        a = self.a
        psi = self.f0 + self.b * (np.log(self.reference_rate / self.critical_slip) + log_theta)
        lz = x - np.log(2 * self.reference_rate) + psi / a
        big = lz > 0
        lzb = np.where(big, lz, 0.0)
        asinh = np.where(big, lzb + np.log1p(np.sqrt(1.0 + np.exp(-2 * lzb))),
                         np.arcsinh(np.exp(np.minimum(lz, 0.0))))
        return a * asinh, a / np.sqrt(1.0 + np.exp(np.minimum(-2 * lz, _BIG)))

    def friction(self, V: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """μ(V, θ) (n,) at slip rate V (m/s) and state θ (s)."""
        with np.errstate(divide="ignore"):
            return self.coefficient(np.log(V), np.log(theta))[0]

    def damping_at(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(η σ′/(σ′ + DAMPING_FADE), its derivative in σ′) at σ′ (n,) Pa: the radiation damping,
        fading on opening (DAMPING_FADE)."""
        s = np.maximum(sigma, 0.0)
        return self.damping * s / (s + DAMPING_FADE), self.damping * DAMPING_FADE / (s + DAMPING_FADE) ** 2

    def _g(self, x, sigma, ny, theta0, dt, beta):
        """g(x) = σ′μ + (η + βΔt)V − |y_τ| and ∂g/∂x, and the pieces of the tangent."""
        lt, dlt = self.log_state(x, theta0, dt)
        mu, dmu = self.coefficient(x, lt)
        V = np.exp(x)
        c = self.damping_at(sigma)[0] + beta * dt
        dfric = sigma * dmu * (1.0 + self.b / self.a * dlt)           # ∂(σ′μ)/∂x
        return sigma * mu + c * V - ny, dfric + c * V, mu, dfric

    def solve_rate(self, sigma, ny, theta0, dt, beta, guess=None) -> SlidingSolution:
        """The slip rate of sliding patches: r(V) + βΔtV = |y_τ| (module docstring) by a bracketed
        Newton in x = ln V.

        Parameters
        ----------
        sigma : (n,) σ′ ≥ 0, Pa;  ny : (n,) |y_τ| ≥ 0, Pa;  theta0 : (n,) θ before the step, s
        dt : Δt > 0, s;  beta : (n,) β, Pa/m;  guess : (n,) V to start from (m/s), or None
        """
        eta, deta = self.damping_at(sigma)
        c = eta + beta * dt
        pos = ny > 0
        hi = np.log(np.where(pos, ny, 1.0) / c)                       # g(hi) ≥ 0 since σ′μ ≥ 0
        lo = hi - 80.0
        for _ in range(12):                                           # g(lo) < 0: push lo down
            glo = self._g(lo, sigma, ny, theta0, dt, beta)[0]
            if not np.any(glo >= 0):
                break
            lo = np.where(glo >= 0, lo - 80.0, lo)
        x = hi - 1.0 if guess is None else np.clip(np.log(np.maximum(guess, 1e-300)), lo, hi)
        x = np.where((x <= lo) | (x >= hi), 0.5 * (lo + hi), x)
        it = 0
        while it < LOCAL_ITERATIONS:
            it += 1
            g, dg, _, _ = self._g(x, sigma, ny, theta0, dt, beta)
            lo = np.where(g < 0, x, lo)
            hi = np.where(g >= 0, x, hi)
            with np.errstate(divide="ignore", invalid="ignore"):
                xn = x - g / dg
            bad = ~np.isfinite(xn) | (xn <= lo) | (xn >= hi) | (dg <= 0)
            xn = np.where(bad, 0.5 * (lo + hi), xn)
            step = np.abs(xn - x)
            x = xn
            if np.all((step <= LOCAL_TOL * np.maximum(1.0, np.abs(x))) | ~pos):
                break
        g, dg, mu, dfric = self._g(x, sigma, ny, theta0, dt, beta)
        V = np.where(pos, np.exp(x), 0.0)
        r = np.where(pos, ny - beta * dt * V, 0.0)                    # = σ′μ + ηV at the root
        # consistent tangent: ∂r/∂|y| = 1 − βΔtV/g′ (g′ = ∂g/∂x); where the state's softening makes
        # g′ ≤ the always-positive part (a step too long for the state: the time step control
        # rejects it), the tangent of the frozen state
        gx = np.maximum(dg, c * V + np.maximum(dfric, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            d_trial = np.where(pos, 1.0 - beta * dt * V / gx, self._rest_tangent(sigma, theta0, dt, beta))
            d_normal = np.where(pos, beta * dt * V * (mu + deta * V) / gx, 0.0)
        return SlidingSolution(V, r, np.clip(d_trial, 0.0, 1.0), d_normal, it, ~pos | (dfric >= 0))

    def _rest_tangent(self, sigma, theta0, dt, beta):
        """r′(0)/(r′(0) + βΔt) at zero trial traction: the limit of r/|y_τ| as |y_τ| → 0."""
        psi = self.f0 + self.b * np.log(self.reference_rate * theta0 / self.critical_slip)
        # r′(0) = σ′ a e^{Ψ/a}/(2V₀) + η, its exponential capped (then the tangent is 1 to round-off)
        with np.errstate(divide="ignore"):
            lr = np.log(sigma * self.a / (2 * self.reference_rate)) + psi / self.a
        rp = np.exp(np.minimum(lr, _BIG)) + self.damping_at(sigma)[0]
        with np.errstate(invalid="ignore"):
            return np.where(rp > 0, rp / (rp + beta * dt), 0.0)

    # ---- the FrictionLaw interface -------------------------------------------------------------
    def radius(self, y_n, slip, state, dt) -> Radius:
        """r at the step's slip, explicit in s_τ (the FrictionLaw form; the contact projection uses
        :meth:`trial_radius`, which agrees with it at a solution). Δt = 0: ∞ (held)."""
        n = len(y_n)
        if dt <= 0:
            return Radius(np.where(y_n > 0, np.inf, 0.0), np.zeros(n))
        V = np.linalg.norm(slip, axis=1) / dt
        with np.errstate(divide="ignore"):
            x = np.log(V)
        lt = self.log_state(x, state[:, 0], dt)[0]
        mu = self.coefficient(x, lt)[0]
        closed = y_n > 0
        eta, deta = self.damping_at(y_n)
        return Radius(np.where(closed, np.maximum(y_n, 0.0) * mu + eta * V, 0.0), (mu + deta * V) * closed)

    def trial_radius(self, y_n: np.ndarray, ny: np.ndarray, state: np.ndarray, dt: float,
                     beta: np.ndarray) -> Radius:
        """r from the trial traction (n,) |y_τ| (Pa): the sliding patch's solution with its tangent
        ``d_trial`` = ∂r/∂|y_τ|, ``d_normal`` = ∂r/∂y_n, and its slip rate ``rate`` (m/s). Open
        patches: r = 0. Δt = 0 (a static solve): r = ∞, every closed patch held."""
        n = len(y_n)
        if dt <= 0:
            return Radius(np.where(y_n > 0, np.inf, 0.0), np.zeros(n))
        closed = y_n > 0
        sigma = np.maximum(y_n, 0.0)
        sol = self.solve_rate(sigma, np.where(closed, ny, 0.0), state[:, 0], dt, beta, guess=state[:, 1])
        z = np.zeros(n)
        return Radius(np.where(closed, sol.radius, 0.0), np.where(closed, sol.d_normal, 0.0), None,
                      d_trial=np.where(closed, sol.d_trial, 0.0), rate=np.where(closed, sol.rate, z))

    def initial_state(self, n: int) -> np.ndarray:
        """(n, 2) θ = D_c/V_i (steady state at the initial rate) and V_i, before :meth:`start`."""
        return np.column_stack([self.critical_slip / self.initial_rate, self.initial_rate])

    def start(self, state: np.ndarray, lam_n: np.ndarray, lam_t: np.ndarray) -> np.ndarray:
        """(n, 2) the state in which the initial tractions λ_n, |λ_τ| (n,) Pa slide at V_i:
        θ₀ from τ = σ′ μ(V_i, θ₀) + η V_i, i.e. Ψ = a ln((2V₀/V_i) sinh(μ/a)). Patches whose traction
        cannot slide at V_i (open, |λ_τ| ≤ ηV_i, or b = 0) take the steady state θ₀ = D_c/V_i and
        the rate their traction gives with it (0 where open or without shear), so that the first
        step does not start from a rate its traction cannot hold."""
        Vi, a = self.initial_rate, self.a
        sig = np.maximum(lam_n, 0.0)
        mu = (lam_t - self.damping_at(sig)[0] * Vi) / np.where(sig > 0, sig, 1.0)
        ok = (sig > 0) & (mu > 0) & (self.b > 0) & (self.start_from == "traction")
        m = np.where(ok, mu / a, 1.0)
        log_sinh = m + np.log(-np.expm1(-2 * m)) - np.log(2.0)
        psi = a * (np.log(2 * self.reference_rate / Vi) + log_sinh)
        with np.errstate(over="ignore"):
            theta = self.critical_slip / self.reference_rate * np.exp(
                (psi - self.f0) / np.where(self.b > 0, self.b, 1.0))
        good = ok & np.isfinite(theta) & (theta > 0)
        theta = np.where(good, theta, self.critical_slip / Vi)
        V = np.array(Vi, float)
        if not np.all(good):
            # r(V) = |λ_τ| at θ₀: the scalar equation with βΔt → 0 (a step so short that βΔtV ≪ r)
            rest = self.solve_rate(sig, np.where(sig > 0, lam_t, 0.0), theta, 1e-300, np.ones(len(theta))).rate
            V = np.where(good, Vi, rest)
        return np.column_stack([theta, V])

    def advance(self, state, slip, dt) -> np.ndarray:
        """(n, 2) θ after the step at V = |s_τ|/Δt, and V. A static solve (Δt = 0) keeps the state."""
        if dt <= 0:
            return state
        return self.advance_at(state, np.linalg.norm(slip, axis=1) / dt, dt)

    def advance_at(self, state, V, dt) -> np.ndarray:
        """(n, 2) as :meth:`advance`, the step's slip rate V (n,) m/s given."""
        with np.errstate(divide="ignore"):
            lt = self.log_state(np.log(V), state[:, 0], dt)[0]
        return np.column_stack([np.exp(lt), V])

    def step_error(self, old: np.ndarray, new: np.ndarray, dt: float, sigma: np.ndarray | None = None
                   ) -> tuple[float, int]:
        """How far the step moved the fault, and the patches where it was too long for the state.

        Implicit Euler takes V constant over the step (the step's mean) and the state at its end
        from the state law's exact solution at that V (:meth:`log_state`): both are exact when V
        does not change, so the error is first order in the step's change of x = ln(V + V_f)
        (V_f = RATE_FLOOR × stick_rate: slower slip does not steer the step), in the slip
        directly and in the state through its sensitivity ∂ln θ/∂x. The measure is
        max(|Δx|, |∂ln θ/∂x| |Δx|) per patch, which the time step control bounds.

        The change of ln θ itself was the measure at first (fourteenth session; Lapusta et
        al.'s change-of-state criterion ΔtV/D_c ≲ ξ applied to ln θ): on a locked fault healing
        from a young state (θ₀ = 13 s, V = 1e-12 m/s) it held a 20-day coupled run at steps
        growing 5 % each (405 sub-steps for the first 5 days) while the exact update made the
        healing exact at any step (docs/rate_state_design.md, "Step error"). An estimate from
        the difference of consecutive steps' mean rates was tried before: it reads the O(Δt) lag
        of a mean rate as error whenever the step size changes.

        ``sigma`` (n,) the patches' effective normal tractions after the step (Pa): patches below
        10 DAMPING_FADE are open or opening, their slip (≈ |y_τ|/(βΔt)) is not a rate-and-state
        slip and does not steer the step.

        Returns (the largest measure over the patches, the number of patches where the step's
        equation for V had a softening branch at its root, :class:`SlidingSolution` ``monotone``)."""
        if dt <= 0 or not len(new):
            return 0.0, 0
        vf = RATE_FLOOR * self.stick_rate
        dx = np.abs(np.log((new[:, 1] + vf) / (old[:, 1] + vf)))
        V = new[:, 1]
        with np.errstate(divide="ignore"):
            x = np.log(V)
        dlt = self.log_state(x, old[:, 0], dt)[1]
        err = dx * np.maximum(1.0, np.abs(dlt))
        if sigma is not None:
            err = np.where(sigma > 10 * DAMPING_FADE, err, 0.0)
        soft = (V > 0) & (1.0 + self.b / self.a * dlt < 0)
        return float(np.max(err)), int(np.count_nonzero(soft))

    def state_fields(self, state) -> dict[str, np.ndarray]:
        with np.errstate(divide="ignore"):
            mu = self.friction(np.maximum(state[:, 1], 0.0), state[:, 0])
        return {"state_theta": state[:, 0], "slip_rate": state[:, 1], "friction_coefficient": mu}

    def stuck(self, rate: np.ndarray) -> np.ndarray:
        """(n,) bool: patches reported as stick (slip rate below ``stick_rate``)."""
        return rate < self.stick_rate
