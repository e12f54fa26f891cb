"""SCEC SEAS benchmark BP6-QD (-A aging law, -S slip law, -C constant friction): the independent
reference of issue 28 (docs/bp6.md).

Antiplane slip δ(z, t) on the fault x = 0, |z| < l_f, of a homogeneous elastic whole space, no
slip for |z| > l_f, quasi-dynamic shear stress and pore pressure prescribed along the fault
(Lambert and Dunham's description, 8 Nov 2021):

    τ = τ⁰ + K[δ] − η V,     σ′ = σ̄₀ − p(z, t),     η = μ/(2c_s),

    K[δ](z) = (μ/2π) p.v.∫ ∂δ/∂ξ (ξ) / (ξ − z) dξ          (a slip patch lowers the stress on it).

K is discretised by piecewise-constant slip on N cells of size h, collocated at the cell centres
(exact for piecewise-constant slip): a Toeplitz matrix, applied by FFT. Rate-and-state (QD-A,
QD-S): V from the traction balance at every evaluation, (δ, ln θ) integrated by SciPy's explicit
Runge–Kutta pairs (DOP853 or RK45). Constant friction (QD-C): the complementarity problem
V ≥ 0, F − τ ≥ 0, (F − τ) V = 0 by implicit Euler, one linear complementarity problem per step
solved exactly by active sets. The QD-C front during injection is also given semi-analytically
(:func:`constant_friction_crack`).

Units: SI throughout (Pa, m, s); the description's MPa, km, days are converted in
:class:`Bp6Parameters`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import fft as sfft
from scipy import integrate, linalg, optimize, special

from .spring_slider import state_rate

DAY = 86400.0
YEAR = 365.0 * DAY                     # t_f = 2 years = 63 072 000 s, as tandem's and QDBIM's BP6 runs
VARIANTS = ("QD-A", "QD-S", "QD-C")
# The description's nine on-fault stations (m), its section 4.1
STATIONS = (-1500.0, 0.0, 500.0, 1000.0, 1500.0, 2500.0, 3500.0, 5000.0, 7500.0)


@dataclass(frozen=True)
class Bp6Parameters:
    """BP6's Table 1 (SI units).

    mu : shear modulus, Pa;  rho : density, kg/m³;  cs : shear-wave speed, m/s;
    sigma0 : background effective normal stress σ̄₀, Pa;  tau_init : initial shear stress, Pa;
    q0 : injection rate, m/s (volume per time per unit area of the x–y plane);
    beta : pore + fluid compressibility, 1/Pa;  phi : porosity;  k : permeability, m²;
    eta_f : fluid viscosity, Pa·s;  lf : half-length of the frictional fault, m;
    dz : the suggested cell size, m;  t_off : injection stop, s;  t_final : end, s;
    a, b : rate-and-state parameters;  Dc : D_RS, m;  V0 : V*, m/s;  f0 : f*;
    V_init : initial slip rate (QD-A/S), m/s;  f_const : QD-C friction coefficient;
    stations : on-fault station positions z, m.
    """

    mu: float = 32.04e9
    rho: float = 2670.0
    cs: float = 3464.0
    sigma0: float = 50e6
    tau_init: float = 29.2e6
    q0: float = 1.25e-6
    beta: float = 1e-8
    phi: float = 0.1
    k: float = 1e-13
    eta_f: float = 1e-3
    lf: float = 20e3
    dz: float = 10.0
    t_off: float = 100 * DAY
    t_final: float = 2 * YEAR
    a: float = 0.007
    b: float = 0.005
    Dc: float = 4e-3
    V0: float = 1e-6
    f0: float = 0.6
    V_init: float = 1e-12
    f_const: float = 0.6
    stations: tuple = STATIONS

    @property
    def alpha(self) -> float:
        """Hydraulic diffusivity k/(φβη_f), m²/s (Table 1: 0.1)."""
        return self.k / (self.phi * self.beta * self.eta_f)

    @property
    def eta(self) -> float:
        """Radiation damping μ/(2c_s), Pa·s/m."""
        return self.mu / (2 * self.cs)

    @property
    def source(self) -> float:
        """q₀/(βφ), Pa·m/s: the strength of the line source in ∂p/∂t = α ∂²p/∂z² + (q₀/βφ) δ_D(z)."""
        return self.q0 / (self.beta * self.phi)

    def tau0(self, variant: str) -> float:
        """τ⁰ (Pa): τ_init + ηV_init for QD-A/S (so that V(0⁺) = V_init), τ_init for QD-C."""
        return self.tau_init if variant == "QD-C" else self.tau_init + self.eta * self.V_init

    @property
    def theta0(self) -> float:
        """Initial state θ₀ (s) of QD-A/S, the description's eq. (24): f(V_init, θ₀) = τ_init/σ̄₀."""
        a, b = self.a, self.b
        return (self.Dc / self.V0) * np.exp(a / b * np.log(2 * self.V0 / self.V_init
                                                           * np.sinh(self.tau_init / (a * self.sigma0))) - self.f0 / b)


# ------------------------------------------------------------------------------------------------
# Pore pressure along the fault


def _g(u):
    """e^{−u²}/√π − u erfc(u), u ≥ 0: the shape of the constant-rate line-source solution."""
    return np.exp(-u * u) / np.sqrt(np.pi) - u * special.erfc(u)


def _G(z, t, alpha):
    """The description's eq. (27): √t [e^{−z²/4αt}/√π − |z|/√(4αt) erfc(|z|/√(4αt))], 0 for t ≤ 0."""
    t = np.asarray(t, float)
    tp = np.where(t > 0, t, 1.0)
    u = np.abs(z) / np.sqrt(4 * alpha * tp)
    return np.where(t > 0, np.sqrt(tp) * _g(u), 0.0)


def pore_pressure(z, t, prm: Bp6Parameters = Bp6Parameters(), images: int = 2):
    """Pore-pressure change p(z, t), Pa, on the fault.

    The description's eq. (26), p = q₀/(βφ√α) [G(z, t) − G(z, t − t_off) H(t − t_off)]: the line
    source of strength q₀/(βφ) switched on at t = 0 and, by superposition, off at t_off, in an
    infinite fault. With ``images`` > 0 the no-flux ends z = ±l_f of eq. (21) are added by images
    at z = 2j l_f, |j| ≤ images (below 1e-15 relative for t ≤ t_f: t_f ≪ l_f²/(4α) = 31.7 yr).
    """
    z = np.asarray(z, float)
    s = prm.source / np.sqrt(prm.alpha)
    out = np.zeros(np.broadcast(z, np.asarray(t)).shape)
    spread = np.sqrt(4 * prm.alpha * max(float(np.max(t)), 0.0))
    for j in range(-images, images + 1):
        # image j is at least (2|j| − 1) l_f from the fault: skip it below erfc(6) ~ 2e-17
        if j and (2 * abs(j) - 1) * prm.lf > 6 * spread:
            continue
        zj = z - 2 * j * prm.lf
        out = out + s * (_G(zj, t, prm.alpha) - _G(zj, np.asarray(t) - prm.t_off, prm.alpha))
    return out


def darcy_velocity(z, t, prm: Bp6Parameters = Bp6Parameters()):
    """Darcy velocity q = −(k/η_f) ∂p/∂z, m/s, of the infinite-fault pressure:
    q = (q₀/2) sign(z) [erfc(|z|/√(4αt)) − erfc(|z|/√(4α(t − t_off))) H(t − t_off)]."""
    z, t = np.asarray(z, float), np.asarray(t, float)

    def one(tt):
        tp = np.where(tt > 0, tt, 1.0)
        return np.where(tt > 0, special.erfc(np.abs(z) / np.sqrt(4 * prm.alpha * tp)), 0.0)

    return 0.5 * prm.q0 * np.sign(z) * (one(t) - one(t - prm.t_off))


# ------------------------------------------------------------------------------------------------
# The elastostatic kernel


def kernel_row(n: int, h: float, mu: float) -> np.ndarray:
    """k_m (Pa/m), m = 0 … n−1: shear stress change at a cell centre from unit slip on the cell m
    cells away, μ/(2πh) · 1/(m² − 1/4) (k₀ = −2μ/(πh); the k_m sum to 0 over all m ∈ ℤ)."""
    m = np.arange(n, dtype=float)
    return mu / (2 * np.pi * h) / (m * m - 0.25)


def segment_stress(x, c, d, mu: float):
    """Stress change at x from unit slip on the segment (c, d): (μ/2π)[1/(c − x) − 1/(d − x)]."""
    return mu / (2 * np.pi) * (1.0 / (c - x) - 1.0 / (d - x))


class Kernel:
    """K on n cells of size h as a symmetric Toeplitz matrix, applied by FFT (circulant
    embedding); ``dense(idx)`` gives the block on cells ``idx``."""

    def __init__(self, n: int, h: float, mu: float):
        self.n, self.h, self.mu = n, h, mu
        self.row = kernel_row(n, h, mu)
        self.nfft = sfft.next_fast_len(2 * n - 1, real=True)
        c = np.zeros(self.nfft)
        c[:n] = self.row
        c[self.nfft - n + 1:] = self.row[1:][::-1]
        self._hat = sfft.rfft(c)

    def __call__(self, slip: np.ndarray) -> np.ndarray:
        return sfft.irfft(sfft.rfft(slip, self.nfft) * self._hat, self.nfft)[: self.n]

    def dense(self, idx=None) -> np.ndarray:
        idx = np.arange(self.n) if idx is None else np.asarray(idx)
        return self.row[np.abs(idx[:, None] - idx[None, :])]


def elliptical_crack_stress(x, half_length: float, stress_drop: float):
    """Stress change of the antiplane crack with slip (2Δσ/μ)√(a² − x²): −Δσ on |x| < a,
    Δσ(|x|/√(x² − a²) − 1) outside."""
    x = np.abs(np.asarray(x, float))
    out = np.full(x.shape, -stress_drop)
    o = x > half_length
    out[o] = stress_drop * (x[o] / np.sqrt(x[o] ** 2 - half_length ** 2) - 1.0)
    return out


def grid(prm: Bp6Parameters, dz: float | None = None, half_length: float | None = None):
    """Cell centres z (m) and size h: an odd number 2M + 1 of cells on (−L, L), L = l_f unless
    ``half_length``, so that z = 0 is a centre; h is the closest to ``dz`` (default prm.dz)."""
    L = prm.lf if half_length is None else half_length
    dz = prm.dz if dz is None else dz
    M = max(1, int(np.floor(L / dz)))
    if 2 * L / (2 * M + 1) < 0.5 * dz:
        M -= 1
    n = 2 * M + 1
    h = 2 * L / n
    return (np.arange(n) - M) * h, h


# ------------------------------------------------------------------------------------------------
# Results


@dataclass
class Bp6Result:
    """A run's output. Time series (n_t,) or (n_t, n_stations) at the times ``t`` (s); profiles
    (n_profiles, n_z) at ``profile_t`` on ``profile_z``. Units: m, m/s, Pa, s."""

    variant: str
    h: float
    t: np.ndarray
    stations: np.ndarray
    slip: np.ndarray
    slip_rate: np.ndarray
    shear_stress: np.ndarray
    pore_pressure: np.ndarray
    darcy_velocity: np.ndarray
    log10_state: np.ndarray
    max_slip_rate: np.ndarray
    moment_rate: np.ndarray                   # ∫ μ V dz, N/(m·s)
    front_rate: np.ndarray                    # largest z > 0 with V ≥ front_rate_threshold
    front_slip: np.ndarray                    # largest z > 0 with δ ≥ front_slip_threshold
    front_rate_threshold: float
    front_slip_threshold: float
    profile_t: np.ndarray
    profile_z: np.ndarray
    profile_slip: np.ndarray
    profile_shear_stress: np.ndarray
    stats: dict = field(default_factory=dict)
    front_tip: np.ndarray | None = None       # QD-C: edge of the slipped region (δ > 0)

    def to_dict(self, digits: int = 7) -> dict:
        """JSON-ready: arrays as nested lists rounded to ``digits`` significant digits."""

        def r(a):
            a = np.asarray(a, float)
            return np.vectorize(lambda v: float(f"{v:.{digits}g}"), otypes=[float])(a).tolist() if a.size else []

        names = ["t", "stations", "slip", "slip_rate", "shear_stress", "pore_pressure", "darcy_velocity",
                 "log10_state", "max_slip_rate", "moment_rate", "front_rate", "front_slip", "profile_t",
                 "profile_z", "profile_slip", "profile_shear_stress"]
        d = {k: r(getattr(self, k)) for k in names}
        if self.front_tip is not None:
            d["front_tip"] = r(self.front_tip)
        d.update(variant=self.variant, h=self.h, front_rate_threshold=self.front_rate_threshold,
                 front_slip_threshold=self.front_slip_threshold, stats=self.stats)
        return d


def default_output_times(prm: Bp6Parameters) -> np.ndarray:
    """Log-spaced to 1 day, daily to t_f, hourly for 2 days around t_off (s)."""
    t = np.concatenate([np.geomspace(60.0, DAY, 25), np.arange(DAY, prm.t_final + 0.5 * DAY, DAY),
                        prm.t_off + np.arange(-24, 49) * 3600.0])
    return np.unique(np.round(t[(t > 0) & (t <= prm.t_final)], 6))


def default_profile_times() -> np.ndarray:
    return np.array([10, 30, 60, 100, 150, 200, 365, 730]) * DAY


def _front(z, values, threshold, log=False):
    """Largest z > 0 where ``values`` ≥ threshold, linearly interpolated between centres (in log
    for ``log``); 0 if none."""
    pos = z >= 0
    zp, v = z[pos], values[pos]
    above = np.nonzero(v >= threshold)[0]
    if above.size == 0:
        return 0.0
    i = above[-1]
    if i == zp.size - 1:
        return float(zp[i])
    v0, v1, c = v[i], v[i + 1], threshold
    if log:
        v0, v1, c = np.log(max(v0, 1e-300)), np.log(max(v1, 1e-300)), np.log(c)
    w = (v0 - c) / (v0 - v1) if v0 != v1 else 0.0
    return float(zp[i] + w * (zp[i + 1] - zp[i]))


def _interp_rows(z, rows, zq):
    """Linear interpolation of (n_t, n_z) rows at the points zq."""
    rows = np.atleast_2d(rows)
    return np.stack([np.interp(zq, z, r) for r in rows])


# ------------------------------------------------------------------------------------------------
# Rate-and-state (QD-A, QD-S)


def solve_slip_rate(tau_qs, sigma_e, psi, prm: Bp6Parameters, eta: float | None = None):
    """V (m/s) and the friction coefficient w from τ_qs − ηV = σ′ a asinh(V/(2V₀) e^{ψ/a}).

    Written in w: σ′w + ηV(w) = τ_qs, V(w) = V₀(e^{(w−ψ)/a} − e^{−(w+ψ)/a}) — increasing and
    convex for w > 0, so Newton from the upper bound w = τ_qs/σ′ decreases monotonically to the
    root (no overflow: the exponents stay those of the physical V).
    """
    a, V0 = prm.a, prm.V0
    eta = prm.eta if eta is None else eta
    w = tau_qs / sigma_e
    for _ in range(50):
        e1, e2 = np.exp((w - psi) / a), np.exp(-(w + psi) / a)
        g = sigma_e * w + eta * V0 * (e1 - e2) - tau_qs
        dw = g / (sigma_e + eta * V0 * (e1 + e2) / a)
        w = w - dw
        if np.all(np.abs(dw) <= 1e-15 * np.abs(w)):
            break
    V = V0 * (np.exp((w - psi) / a) - np.exp(-(w + psi) / a))
    return V, w


class RateStateFault:
    """QD-A / QD-S on the cells z (m) of size h: the ODE y = (δ, ln θ) → ẏ = (V, θ̇/θ).

    Each evaluation: τ_qs = τ⁰ + K[δ], σ′ = σ̄₀ − p(z, t), V from :func:`solve_slip_rate`;
    aging d ln θ/dt = 1/θ − V/D_c, slip d ln θ/dt = −(V/D_c) ln(Vθ/D_c).
    """

    def __init__(self, prm: Bp6Parameters, law: str, z: np.ndarray, h: float, pressure: bool = True,
                 R_clamp: float | None = None):
        if law not in ("aging", "slip"):
            raise ValueError(f"law must be 'aging' or 'slip', got {law!r}")
        self.prm, self.law, self.z, self.h = prm, law, z, h
        self.n = z.size
        self.K = Kernel(self.n, h, prm.mu)
        self.Kimg = None if R_clamp is None else clamped_image_matrix(z, h, prm.mu, R_clamp)
        self.tau0 = prm.tau0("QD-A")
        self.pressure = pressure
        self.nfev = 0

    def sigma_e(self, t):
        p = pore_pressure(self.z, t, self.prm) if self.pressure else 0.0
        return self.prm.sigma0 - p

    def fields(self, t, y):
        """τ_qs, σ′, ψ, V, w at (t, y)."""
        prm, n = self.prm, self.n
        delta, lnth = y[:n], y[n:]
        tau_qs = self.tau0 + self.K(delta)
        if self.Kimg is not None:
            tau_qs = tau_qs + self.Kimg @ delta
        sig = self.sigma_e(t)
        psi = prm.f0 + prm.b * (np.log(prm.V0 / prm.Dc) + lnth)
        V, w = solve_slip_rate(tau_qs, sig, psi, prm)
        return tau_qs, sig, psi, V, w

    def rhs(self, t, y):
        self.nfev += 1
        prm, n = self.prm, self.n
        # a rejected trial stage may overflow: its non-finite error estimate makes the pair cut the step
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            _, _, _, V, _ = self.fields(t, y)
            theta = np.exp(y[n:])
            dl = state_rate(V, theta, prm.Dc, self.law) / theta      # d ln θ/dt
        return np.concatenate([V, dl])

    def initial_state(self) -> np.ndarray:
        return np.concatenate([np.zeros(self.n), np.full(self.n, np.log(self.prm.theta0))])


def run_rate_state(prm: Bp6Parameters = Bp6Parameters(), law: str = "aging", dz: float | None = None,
                   half_length: float | None = None, t_out=None, profile_t=None, rtol: float = 1e-8,
                   atol_slip: float = 1e-10, atol_state: float = 1e-8, method: str = "DOP853",
                   t_final: float | None = None, front_rate_threshold: float = 1e-9,
                   front_slip_threshold: float = 1e-3, profile_z=None, pressure: bool = True,
                   max_step: float = DAY, R_clamp: float | None = None) -> Bp6Result:
    """QD-A (``law="aging"``) or QD-S (``"slip"``) on a grid of size ≈ dz over |z| < l_f (or
    ``half_length``), integrated by SciPy's ``method`` (an explicit Runge–Kutta pair) with
    relative tolerance ``rtol`` and absolute tolerances ``atol_slip`` (m), ``atol_state`` (ln s),
    steps at most ``max_step`` (s), restarted at t_off. Outputs at ``t_out`` (default
    :func:`default_output_times`) by the pair's dense output. ``R_clamp``: the fault in a clamped
    circle of radius R (antiplane images, :func:`clamped_image_matrix`), for the domain study.
    """
    import time

    z, h = grid(prm, dz, half_length)
    fault = RateStateFault(prm, law, z, h, pressure=pressure, R_clamp=R_clamp)
    n = z.size
    t_final = prm.t_final if t_final is None else t_final
    t_out = default_output_times(prm) if t_out is None else np.asarray(t_out, float)
    t_out = t_out[t_out <= t_final]
    profile_t = default_profile_times() if profile_t is None else np.asarray(profile_t, float)
    profile_t = profile_t[profile_t <= t_final]
    profile_z = np.arange(-10e3, 10e3 + 1, 100.0) if profile_z is None else np.asarray(profile_z, float)
    t_all = np.unique(np.concatenate([[0.0], t_out, profile_t]))
    atol = np.concatenate([np.full(n, atol_slip), np.full(n, atol_state)])
    solver_cls = {"RK45": integrate.RK45, "DOP853": integrate.DOP853}[method]
    y0 = fault.initial_state()

    st = np.asarray(prm.stations, float)
    rec: dict[str, list] = {k: [] for k in ("slip", "V", "tau", "lnth", "vmax", "mrate", "frate", "fslip")}
    prof_slip: list = []
    prof_tau: list = []

    def record(t, y):
        tau_qs, sig, psi, V, w = fault.fields(t, y)
        tau = tau_qs - prm.eta * V
        rec["slip"].append(np.interp(st, z, y[:n]))
        rec["V"].append(np.exp(np.interp(st, z, np.log(V))))
        rec["tau"].append(np.interp(st, z, tau))
        rec["lnth"].append(np.interp(st, z, y[n:]))
        rec["vmax"].append(V.max())
        rec["mrate"].append(prm.mu * V.sum() * h)
        rec["frate"].append(_front(z, V, front_rate_threshold, log=True))
        rec["fslip"].append(_front(z, y[:n], front_slip_threshold))
        if np.any(np.isclose(t, profile_t, rtol=0, atol=1e-6)):
            prof_slip.append(np.interp(profile_z, z, y[:n]))
            prof_tau.append(np.interp(profile_z, z, tau))

    t0 = time.perf_counter()
    record(0.0, y0)
    i_next, steps, hmin, hmax = 1, 0, np.inf, 0.0
    y = y0
    # the source stops at t_off (a kink of p in time): the pair restarts there rather than step across
    for t_start, t_end in ((0.0, min(prm.t_off, t_final)), (prm.t_off, t_final)):
        if t_end <= t_start:
            continue
        solver = solver_cls(fault.rhs, t_start, y, t_end, rtol=rtol, atol=atol, first_step=1.0, max_step=max_step)
        while solver.status == "running":
            msg = solver.step()
            if solver.status == "failed":
                raise RuntimeError(f"BP6 {law}: {msg} at t = {solver.t:.6g} s")
            steps += 1
            hmin, hmax = min(hmin, solver.step_size), max(hmax, solver.step_size)
            if i_next < t_all.size and t_all[i_next] <= solver.t:
                dense = solver.dense_output()
                while i_next < t_all.size and t_all[i_next] <= solver.t:
                    record(t_all[i_next], dense(t_all[i_next]))
                    i_next += 1
        y = solver.y
    wall = time.perf_counter() - t0
    t_rec = t_all
    keep = np.isin(t_rec, np.concatenate([[0.0], t_out]))
    sl = lambda k: np.asarray(rec[k])[keep]  # noqa: E731
    stats = dict(n_cells=int(n), steps=steps, nfev=fault.nfev, min_step=float(hmin), max_step=float(hmax),
                 wall_s=wall, method=method, rtol=rtol, half_length=float(-z[0] + h / 2), R_clamp=R_clamp)
    return Bp6Result(
        variant="QD-A" if law == "aging" else "QD-S", h=h, t=t_rec[keep], stations=st,
        slip=sl("slip"), slip_rate=sl("V"), shear_stress=sl("tau"),
        pore_pressure=pore_pressure(st[None, :], t_rec[keep][:, None], prm) if pressure
        else np.zeros((keep.sum(), st.size)),
        darcy_velocity=darcy_velocity(st[None, :], t_rec[keep][:, None], prm),
        log10_state=sl("lnth") / np.log(10), max_slip_rate=sl("vmax"), moment_rate=sl("mrate"),
        front_rate=sl("frate"), front_slip=sl("fslip"), front_rate_threshold=front_rate_threshold,
        front_slip_threshold=front_slip_threshold, profile_t=profile_t, profile_z=profile_z,
        profile_slip=np.asarray(prof_slip), profile_shear_stress=np.asarray(prof_tau), stats=stats)


# ------------------------------------------------------------------------------------------------
# Constant friction (QD-C)


def solve_lcp(A_of, q: np.ndarray, active0: np.ndarray, apply_A, tol: float, max_iter: int = 200):
    """x ≥ 0, w = q + A x ≥ −tol, x·w = 0 for symmetric positive definite A, by active sets.

    ``A_of(idx)`` is the dense block on ``idx``, ``apply_A(x)`` the full product. Start from the
    set ``active0``; solve A_SS x_S = −q_S; drop the cells with x < 0, add the cells with w < −tol;
    repeat. Returns x and the number of iterations.
    """
    n = q.size
    S = np.zeros(n, bool)
    S[active0] = True
    S |= q < -tol
    x = np.zeros(n)
    for it in range(1, max_iter + 1):
        idx = np.nonzero(S)[0]
        x[:] = 0.0
        if idx.size:
            x[idx] = linalg.cho_solve(linalg.cho_factor(A_of(idx), lower=True), -q[idx])
            neg = idx[x[idx] < 0]
            if neg.size:
                S[neg] = False
                continue
        w = q + apply_A(x)
        add = (~S) & (w < -tol)
        if not add.any():
            return x, it
        S |= add
    raise RuntimeError("BP6 QD-C: the active-set LCP solver did not converge")


def run_constant_friction(prm: Bp6Parameters = Bp6Parameters(), dz: float | None = None,
                          half_length: float = 12e3, t_out=None, profile_t=None, dt_max: float = 0.25 * DAY,
                          dt_first: float = 600.0, t_final: float | None = None, front_rate_threshold: float = 1e-9,
                          front_slip_threshold: float = 1e-3, profile_z=None,
                          R_clamp: float | None = None) -> Bp6Result:
    """QD-C by implicit Euler: at each t_n the complementarity problem

        Δδ ≥ 0,  w = F_n − τ⁰ − K[δ_{n−1} + Δδ] + (η/Δt) Δδ ≥ 0,  w·Δδ = 0,   F_n = f(σ̄₀ − p(·, t_n)),

    an LCP with the SPD matrix (η/Δt) I − K, solved exactly (:func:`solve_lcp`). Steps grow
    geometrically from ``dt_first`` to ``dt_max`` (s), restart at t_off. The slip never reaches
    ``half_length`` (checked), where the no-slip condition of |z| > l_f starts; a computational
    half-length below l_f is then exact. V is the step's mean rate, reported at the step's end.
    ``R_clamp``: add the image of the slip in a clamped circle of radius R (antiplane, docs/bp6.md),
    for the finite-domain study.
    """
    import time

    z, h = grid(prm, dz, half_length)
    n = z.size
    K = Kernel(n, h, prm.mu)
    t_final = prm.t_final if t_final is None else t_final
    t_out = default_output_times(prm) if t_out is None else np.asarray(t_out, float)
    t_out = t_out[t_out <= t_final]
    profile_t = default_profile_times() if profile_t is None else np.asarray(profile_t, float)
    profile_t = profile_t[profile_t <= t_final]
    profile_z = np.arange(-10e3, 10e3 + 1, 100.0) if profile_z is None else np.asarray(profile_z, float)
    Kimg = None
    if R_clamp is not None:
        Kimg = clamped_image_matrix(z, h, prm.mu, R_clamp)

    # time levels: geometric growth from dt_first to dt_max, restarted at t_off, hitting the outputs
    levels = [0.0]
    for t_start, t_end in ((0.0, min(prm.t_off, t_final)), (prm.t_off, t_final)):
        t, dt = t_start, dt_first
        while t < t_end - 1e-6:
            dt = min(dt * 1.2, dt_max)
            t = min(t + dt, t_end)
            levels.append(t)
    # an output's step is short (V is the step's mean rate): a level 1 h before each output
    t_rec = np.concatenate([t_out, profile_t])
    tl = np.unique(np.concatenate([levels, t_rec, t_rec - np.minimum(3600.0, 0.5 * t_rec)]))
    tl = tl[(tl >= 0) & (tl <= t_final)]

    f, eta = prm.f_const, prm.eta
    tau0 = prm.tau0("QD-C")
    # the problem is even in z: unknowns on the M + 1 centres z ≥ 0, the LCP in the basis
    # P = (e_0, e_i + e_−i) whose matrix PᵀAP is symmetric positive definite (docs/bp6.md)
    M = n // 2
    ih = np.arange(M + 1)

    def unfold(xh):
        return np.concatenate([xh[:0:-1], xh])

    def fold(v):
        out = v[M:].copy()
        out[1:] += v[M - 1::-1]
        return out

    sumidx = ih[:, None] + ih[None, :]
    difidx = np.abs(ih[:, None] - ih[None, :])
    Kimg_h = None
    if Kimg is not None:   # PᵀKimgP on the half grid
        cols = Kimg[:, M:].copy()
        cols[:, 1:] += Kimg[:, M - 1::-1]
        Kimg_h = cols[M:].copy()
        Kimg_h[1:] += cols[M - 1::-1]
    delta = np.zeros(n)
    Kd = np.zeros(n)
    active = np.zeros(0, int)
    tol = 1e-9 * prm.sigma0
    st = np.asarray(prm.stations, float)
    out_t: list = []
    rec: dict[str, list] = {k: [] for k in ("slip", "V", "tau", "vmax", "mrate", "frate", "fslip", "ftip")}
    prof_slip: list = []
    prof_tau: list = []
    lcp_iters, max_active = 0, 0

    def K_apply(x):
        r = K(x)
        return r if Kimg is None else r + Kimg @ x

    def record(t, V):
        tau = tau0 + Kd - eta * V
        out_t.append(t)
        rec["slip"].append(np.interp(st, z, delta))
        rec["V"].append(np.interp(st, z, V))
        rec["tau"].append(np.interp(st, z, tau))
        rec["vmax"].append(V.max())
        rec["mrate"].append(prm.mu * V.sum() * h)
        rec["frate"].append(_front(z, V, front_rate_threshold, log=False))
        rec["fslip"].append(_front(z, delta, front_slip_threshold))
        rec["ftip"].append(crack_tip(z, delta))
        if np.any(np.isclose(t, profile_t, rtol=0, atol=1e-6)):
            prof_slip.append(np.interp(profile_z, z, delta))
            prof_tau.append(np.interp(profile_z, z, tau))

    t0w = time.perf_counter()
    record(0.0, np.zeros(n))
    for t_prev, t in zip(tl[:-1], tl[1:], strict=True):
        dt = t - t_prev
        F = f * (prm.sigma0 - pore_pressure(z, t, prm))
        q = fold(F - (tau0 + Kd))
        c = eta / dt

        def A_of(idx, c=c):
            B = -2.0 * (K.row[difidx[np.ix_(idx, idx)]] + K.row[sumidx[np.ix_(idx, idx)]])
            B[np.diag_indices_from(B)] += 2.0 * c
            B[idx == 0, :] *= 0.5
            B[:, idx == 0] *= 0.5
            if Kimg_h is not None:
                B -= Kimg_h[np.ix_(idx, idx)]
            return B

        x, it = solve_lcp(A_of, q, active, lambda v, c=c: fold(c * unfold(v) - K_apply(unfold(v))), tol)
        lcp_iters += it
        active = np.nonzero(x > 0)[0]
        max_active = max(max_active, active.size)
        x = unfold(x)
        delta = delta + x
        Kd = K_apply(delta)
        if np.any(delta[[0, -1]] > 0):
            raise RuntimeError("BP6 QD-C: slip reached the end of the computational fault; enlarge half_length")
        if np.any(np.isclose(t, t_out, rtol=0, atol=1e-6)) or np.any(np.isclose(t, profile_t, rtol=0, atol=1e-6)):
            record(t, x / dt)
    wall = time.perf_counter() - t0w
    t_done = np.asarray(out_t)
    keep = np.isin(t_done, np.concatenate([[0.0], t_out]))
    sl = lambda k: np.asarray(rec[k])[keep]  # noqa: E731
    stats = dict(n_cells=int(n), steps=int(tl.size - 1), lcp_iterations=int(lcp_iters), max_active=int(max_active),
                 wall_s=wall, dt_max=dt_max, dt_first=dt_first, half_length=float(-z[0] + h / 2),
                 R_clamp=R_clamp)
    tt = t_done[keep]
    return Bp6Result(
        variant="QD-C", h=h, t=tt, stations=st, slip=sl("slip"), slip_rate=sl("V"), shear_stress=sl("tau"),
        pore_pressure=pore_pressure(st[None, :], tt[:, None], prm),
        darcy_velocity=darcy_velocity(st[None, :], tt[:, None], prm),
        log10_state=np.zeros((tt.size, st.size)), max_slip_rate=sl("vmax"), moment_rate=sl("mrate"),
        front_rate=sl("frate"), front_slip=sl("fslip"), front_rate_threshold=front_rate_threshold,
        front_slip_threshold=front_slip_threshold, profile_t=profile_t, profile_z=profile_z,
        profile_slip=np.asarray(prof_slip), profile_shear_stress=np.asarray(prof_tau), stats=stats,
        front_tip=sl("ftip"))


def crack_tip(z, delta) -> float:
    """Edge (m, z > 0) of the slipped region δ > 0: past the last slipped centre by the tip
    asymptote of a crack with bounded stress, δ ∝ (a − z)^{3/2} (δ^{2/3} linear through the two
    last slipped centres); 0 if nothing slipped."""
    pos = z >= 0
    zp, d = z[pos], delta[pos]
    idx = np.nonzero(d > 0)[0]
    if idx.size == 0:
        return 0.0
    i = idx[-1]
    if i == 0 or d[i - 1] <= d[i]:
        return float(zp[i] + 0.5 * (zp[1] - zp[0]))
    s0, s1 = d[i - 1] ** (2 / 3), d[i] ** (2 / 3)
    return float(zp[i] + s1 * (zp[i] - zp[i - 1]) / (s0 - s1))


def clamped_image_matrix(z, h: float, mu: float, R: float) -> np.ndarray:
    """(n, n) stress at the centres z from unit slip on each cell's image in the clamped circle of
    radius R centred at z = 0 (antiplane, u = 0 on the circle; docs/bp6.md): w = u − u∘inv,
    inv(r) = R²r/|r|², is the field of the slip plus the image slip −δ(R²/x) on the fault's line,
    so cell (c, d) maps to (R²/d, R²/c) with slip −1 (the centre cell, c < 0 < d, to
    (−∞, R²/c) ∪ (R²/d, ∞))."""
    if np.max(np.abs(z)) + h / 2 >= R:
        raise ValueError("the fault must lie inside the clamped circle")
    c, d = (z - h / 2)[None, :], (z + h / 2)[None, :]
    x = z[:, None]
    side = (c > 0) | (d < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, hi = R * R / d, R * R / c          # the image interval (R²/d, R²/c); both ends ±∞-ward at the centre
        out = np.where(side, -segment_stress(x, lo, hi, mu), mu / (2 * np.pi) * (1.0 / (hi - x) - 1.0 / (lo - x)))
    return out


# ------------------------------------------------------------------------------------------------
# QD-C during injection: the crack with bounded stress at its tips


def _F(lam: float) -> float:
    """∫₀^{π/2} g(λ sin φ) dφ (g of :func:`_g`), decreasing from √π/2 at λ = 0 like 1/(4λ)."""
    return integrate.quad(lambda ph: _g(lam * np.sin(ph)), 0.0, np.pi / 2, epsabs=1e-14, epsrel=1e-13)[0]


def constant_friction_crack(t, prm: Bp6Parameters = Bp6Parameters()):
    """Half-length a(t) (m) of QD-C's slipping region for 0 < t ≤ t_off, in the limit η → 0.

    While the pressure rises everywhere (t ≤ t_off), the slipping region (−a, a) only grows and
    the traction on it is f(σ̄₀ − p): a static crack under the stress drop Δσ = τ⁰ − fσ̄₀ + f p(z, t),
    whose half-length makes the stress intensity factor vanish (bounded stress at the tips):
    ∫₀^a Δσ(z)/√(a² − z²) dz = 0. With p = (q₀/βφ)√(t/α) g(|z|/√(4αt)) and a = λ√(4αt) this is

        F(λ) = (π/2) (fσ̄₀ − τ⁰) √α / (f (q₀/βφ) √t),

    one equation for λ(t) (not a similarity solution: the right side falls as 1/√t). Returns 0
    before the onset F(0) = √π/2.
    """
    t = float(t)
    if t <= 0:
        return 0.0
    f, tau0 = prm.f_const, prm.tau0("QD-C")
    rhs = 0.5 * np.pi * (f * prm.sigma0 - tau0) * np.sqrt(prm.alpha) / (f * prm.source * np.sqrt(t))
    if rhs >= 0.5 * np.sqrt(np.pi):
        return 0.0
    hi = 1.0
    while _F(hi) > rhs:
        hi *= 2
    lam = optimize.brentq(lambda L: _F(L) - rhs, 0.0, hi, xtol=1e-14, rtol=1e-13)
    return lam * np.sqrt(4 * prm.alpha * t)


def crack_slip(x, a: float, stress_drop, mu: float):
    """Slip (m) at the points x of the antiplane crack (−a, a) with bounded stress at both tips
    under the stress drop ``stress_drop(s)`` (Pa, a vectorised function):

        δ(x) = (2/(πμ)) ∫_{−a}^{a} Δσ(s) ln| (a² − xs + √((a² − x²)(a² − s²))) / (a |x − s|) | ds,

    the crack's Green function ((2Δσ/μ)√(a² − x²) for uniform Δσ); quadrature split at x and 0."""
    x = np.atleast_1d(np.asarray(x, float))
    out = np.zeros(x.shape)
    for i, xi in enumerate(x):
        if abs(xi) >= a:
            continue
        rx = np.sqrt(a * a - xi * xi)

        def integrand(s, xi=xi, rx=rx):
            num = a * a - xi * s + rx * np.sqrt(max(a * a - s * s, 0.0))
            return stress_drop(s) * np.log(abs(num / (a * (xi - s))))

        bounds = [-a, *sorted({xi, 0.0}), a]
        tot = 0.0
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
            if hi > lo:
                tot += integrate.quad(integrand, lo, hi, limit=200, epsabs=1e-12 * a, epsrel=1e-11)[0]
        out[i] = 2 / (np.pi * mu) * tot
    return out


def constant_friction_slip(x, t, prm: Bp6Parameters = Bp6Parameters()):
    """Slip (m) at the points x of QD-C's crack (:func:`constant_friction_crack`) at t ≤ t_off:
    :func:`crack_slip` under Δσ = τ⁰ − fσ̄₀ + f p(z, t)."""
    a = constant_friction_crack(t, prm)
    if a == 0:
        return np.zeros(np.atleast_1d(x).shape)
    f, tau0 = prm.f_const, prm.tau0("QD-C")
    return crack_slip(x, a, lambda s: tau0 - f * prm.sigma0 + f * pore_pressure(s, t, prm, images=0), prm.mu)


def with_(prm: Bp6Parameters, **kw) -> Bp6Parameters:
    """A copy of ``prm`` with the fields ``kw`` changed."""
    return replace(prm, **kw)
