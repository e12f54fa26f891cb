"""Friction laws as objects: the radius of the tangential projection and the law's own state.

The contact conditions (scheme.md §4, `contact.py`) project the trial tangential traction y_τ on
the disc of radius r: λ_τ = [y_τ]_r. A friction law says what r is, per contact patch:

    r = r(y_n, s_τ, state, Δt)

from the trial normal traction y_n (Pa), the step's slip s_τ (m; the tangential jump increment
in a time step, the jump itself in a static solve), the law's state per patch carried across
steps (none for Coulomb; the slip path for slip-weakening) and the time step Δt (s; for rate
laws). The semi-smooth Newton linearisation and the energy audit both read r from here, and the
model advances the state once a step is accepted (:meth:`FrictionLaw.advance`). A new law is a
class here with the four methods of :class:`FrictionLaw` and its case-file keys.

State codes (``contact.OPEN``/``STICK``/``SLIP``) stay in `contact.py`: they are the projection's,
not a law's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from ..core.errors import InputError


@dataclass(frozen=True)
class Radius:
    """The radius of the friction disc and its derivatives, per patch.

    Attributes
    ----------
    value : (n,) r, Pa
    d_normal : (n,) ∂r/∂y_n (dimensionless)
    d_slip : (n, d) ∂r/∂s_τ, Pa/m, or None where r does not depend on the slip
    d_trial : (n,) ∂r/∂|y_τ| (dimensionless), or None: a law whose radius follows from the trial
        traction (a rate law, :meth:`RateLaw.trial_radius`); every closed patch then slides
    rate : (n,) the slip rate that radius belongs to, m/s (rate laws)
    """

    value: np.ndarray
    d_normal: np.ndarray
    d_slip: np.ndarray | None = None
    d_trial: np.ndarray | None = None
    rate: np.ndarray | None = None


@runtime_checkable
class FrictionLaw(Protocol):
    """What the contact linearisation and the energy audit need of a friction law."""

    @property
    def name(self) -> str:
        """The law's case-file name (``contact.law``)."""
        ...

    @property
    def instability_hint(self) -> str | None:
        """What a run that lost its equilibrium should be told, for a law that can soften (None: cannot)."""
        ...

    def radius(self, y_n: np.ndarray, slip: np.ndarray, state: np.ndarray, dt: float) -> Radius:
        """r at trial normal traction y_n (n,) Pa and step slip ``slip`` (n, d) m, tangential."""
        ...

    def initial_state(self, n: int) -> np.ndarray:
        """(n, k) the state of n patches before the first step (k = 0: no state)."""
        ...

    def start(self, state: np.ndarray, lam_n: np.ndarray, lam_t: np.ndarray) -> np.ndarray:
        """(n, k) the state at the start of a run, in equilibrium with the initial tractions λ_n,
        |λ_τ| (n,) Pa (a rate law's initial state follows from them; the others keep ``state``)."""
        ...

    def advance(self, state: np.ndarray, slip: np.ndarray, dt: float) -> np.ndarray:
        """(n, k) the state after an accepted step whose slip was ``slip`` (n, d)."""
        ...

    def state_fields(self, state: np.ndarray) -> dict[str, np.ndarray]:
        """The state as named (n,) arrays for the outputs (empty without state)."""
        ...


@runtime_checkable
class RateLaw(Protocol):
    """A friction law whose radius the contact projection takes from the trial traction: r solves
    r(V) + βΔtV = |y_τ| with V = |s_τ|/Δt (`rate_state.py`)."""

    def trial_radius(self, y_n: np.ndarray, ny: np.ndarray, state: np.ndarray, dt: float,
                     beta: np.ndarray) -> Radius:
        """r, ∂r/∂y_n, ∂r/∂|y_τ| and V at trial tractions y_n, |y_τ| (n,) Pa."""
        ...

    def stuck(self, rate: np.ndarray) -> np.ndarray:
        """(n,) bool: the patches reported as stick at slip rates ``rate`` (n,) m/s."""
        ...

    def advance_at(self, state: np.ndarray, rate: np.ndarray, dt: float) -> np.ndarray:
        """(n, k) the state after a step at slip rates ``rate`` (n,) m/s."""
        ...

    def step_error(self, old: np.ndarray, new: np.ndarray, dt: float, sigma: np.ndarray | None = None
                   ) -> tuple[float, int]:
        """(local error estimate of the step, patches where the step was too long for the state)."""
        ...


def _check(key: str, values: np.ndarray, what: str, positive: bool = False) -> np.ndarray:
    v = np.asarray(values, float)
    bad = ~np.isfinite(v) | ((v <= 0) if positive else (v < 0))
    if np.any(bad):
        raise InputError(key, f"{what}, got {v[bad].ravel()[0]!r}")
    return v


class _Stateless:
    """The state methods of a law without state (which cannot soften either)."""

    instability_hint = None

    def initial_state(self, n: int) -> np.ndarray:
        return np.zeros((n, 0))

    def start(self, state, lam_n, lam_t) -> np.ndarray:
        return state

    def advance(self, state, slip, dt) -> np.ndarray:
        return state

    def state_fields(self, state) -> dict[str, np.ndarray]:
        return {}


@dataclass(frozen=True, eq=False)
class Frictionless(_Stateless):
    """r = 0: closed faces slide freely."""

    name: str = field(default="frictionless", init=False)

    def radius(self, y_n, slip, state, dt) -> Radius:
        z = np.zeros(len(y_n))
        return Radius(z, z)


@dataclass(frozen=True, eq=False)
class Tresca(_Stateless):
    """r = g, a given threshold (Pa) per patch (n,), whatever the normal traction."""

    threshold: np.ndarray
    name: str = field(default="tresca", init=False)

    def __post_init__(self):
        object.__setattr__(self, "threshold", _check("threshold", self.threshold,
                                                     "must be finite and ≥ 0 (Pa)"))

    def radius(self, y_n, slip, state, dt) -> Radius:
        return Radius(self.threshold.astype(float), np.zeros(len(y_n)))


@dataclass(frozen=True, eq=False)
class Coulomb(_Stateless):
    """r = F [y_n]_+ with a friction coefficient F (n,) per patch (dimensionless).

    **Choice** (scheme.md §4): [y_n]_+ rather than λ_n; the two agree at a solution and the radius
    stays ≥ 0 at every iterate (Hüeber, Stadler, Wohlmuth 2008).
    """

    friction: np.ndarray
    name: str = field(default="coulomb", init=False)

    def __post_init__(self):
        object.__setattr__(self, "friction", _check("friction", self.friction, "must be finite and ≥ 0"))

    def radius(self, y_n, slip, state, dt) -> Radius:
        closed = y_n > 0
        return Radius(self.friction * np.maximum(y_n, 0.0), self.friction * closed)


@dataclass(frozen=True, eq=False)
class SlipWeakening:
    """Linear slip-weakening: r = F(δ) [y_n]_+ with δ the slip path (m) and

        F(δ) = F_d + (F_s − F_d) max(1 − δ/D_c, 0),

    from the static coefficient F_s down to the dynamic F_d over the critical slip D_c (Ida 1972;
    Palmer and Rice 1973). δ = δ⁰ + |s_τ|: the path accumulated in the accepted steps (the state,
    (n, 1)) plus this step's slip, so the weakening is implicit in the step and its derivative
    ∂r/∂s_τ = F'(δ) [y_n]_+ ŝ_τ enters Newton's Jacobian (ŝ_τ = 0 at zero slip, the subgradient
    taken there).

    Parameters
    ----------
    friction : (n,) F_s;  dynamic : (n,) F_d ≤ F_s;  critical_slip : (n,) D_c > 0, m
    """

    friction: np.ndarray
    dynamic: np.ndarray
    critical_slip: np.ndarray
    name: str = field(default="slip-weakening", init=False)
    # a weakening fault can lose every quasi-static equilibrium near the last one: the slipping
    # patch runs away (an earthquake), which no smaller step resolves
    instability_hint = ("With slip-weakening friction this is typically a frictional instability: the slipping "
                        "patch outgrew its nucleation length (2a_c = 1.158 μ/((1 − ν) W), W = (friction − "
                        "dynamic_friction) σ_n′ / critical_slip) and the fault has no quasi-static equilibrium "
                        "near the last state (docs/contact.md, \"Slip-weakening\")")

    def __post_init__(self):
        fs = _check("friction", self.friction, "must be finite and ≥ 0")
        fd = _check("dynamic_friction", np.broadcast_to(self.dynamic, fs.shape), "must be finite and ≥ 0")
        dc = _check("critical_slip", np.broadcast_to(self.critical_slip, fs.shape),
                    "must be finite and > 0 (m)", positive=True)
        if np.any(fd > fs):
            i = int(np.argmax(fd > fs))
            raise InputError("dynamic_friction", f"must not exceed the static friction: {fd[i]!r} > {fs[i]!r}")
        object.__setattr__(self, "friction", fs)
        object.__setattr__(self, "dynamic", np.array(fd, float))
        object.__setattr__(self, "critical_slip", np.array(dc, float))

    def coefficient(self, path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(F(δ), F'(δ)) at slip path δ (n,) m."""
        drop = self.friction - self.dynamic
        weakening = path < self.critical_slip
        F = self.dynamic + drop * np.maximum(1.0 - path / self.critical_slip, 0.0)
        return F, np.where(weakening, -drop / self.critical_slip, 0.0)

    def radius(self, y_n, slip, state, dt) -> Radius:
        ns = np.linalg.norm(slip, axis=1)
        F, dF = self.coefficient(state[:, 0] + ns)
        yp = np.maximum(y_n, 0.0)
        shat = slip / np.where(ns > 0, ns, 1.0)[:, None]
        return Radius(F * yp, F * (y_n > 0), (dF * yp)[:, None] * shat)

    def initial_state(self, n: int) -> np.ndarray:
        return np.zeros((n, 1))

    def start(self, state, lam_n, lam_t) -> np.ndarray:
        return state

    def advance(self, state, slip, dt) -> np.ndarray:
        return state + np.linalg.norm(slip, axis=1)[:, None]

    def state_fields(self, state) -> dict[str, np.ndarray]:
        return {"slip_path": state[:, 0], "friction_coefficient": self.coefficient(state[:, 0])[0]}


LAWS = ("frictionless", "tresca", "coulomb", "slip-weakening", "rate-and-state")
# the case-file coefficients per face (contact.KEY, or a fracture's own) and the laws that read them
LAW_KEYS = {"friction": ("coulomb", "slip-weakening", "rate-and-state"), "threshold": ("tresca",),
            "dynamic_friction": ("slip-weakening",), "critical_slip": ("slip-weakening", "rate-and-state"),
            "a": ("rate-and-state",), "b": ("rate-and-state",), "reference_rate": ("rate-and-state",),
            "initial_slip_rate": ("rate-and-state",)}
# coefficients a law reads that have a default (the others are required)
LAW_DEFAULTS = {"reference_rate": 1e-6}


def friction_law(name: str, n: int, friction=None, threshold=None, dynamic_friction=None,
                 critical_slip=None, a=None, b=None, reference_rate=None, initial_slip_rate=None,
                 damping=None, state_law: str = "aging", stick_rate: float = 1e-9,
                 start_from: str = "traction") -> FrictionLaw:
    """The law ``name`` for n patches from its coefficients ((n,) arrays or scalars; ``damping``
    η = μ_s/(2c_s) in Pa·s/m, rate-and-state's radiation damping, 0 if None).

    Raises
    ------
    InputError naming the contact key when the law is unknown or a coefficient is missing or out of range
    """
    if name not in LAWS:
        raise InputError("law", f"unknown contact law {name!r}; allowed: {', '.join(LAWS)}")

    def need(key, v):
        if v is None:
            raise InputError(key, f"is needed by contact.law = {name!r}")
        return np.array(np.broadcast_to(np.asarray(v, float), (n,)), float)

    if name == "frictionless":
        return Frictionless()
    if name == "tresca":
        return Tresca(need("threshold", threshold))
    if name == "coulomb":
        return Coulomb(need("friction", friction))
    if name == "rate-and-state":
        from .rate_state import RateAndState     # the module imports Radius from here

        return RateAndState(need("friction", friction), need("a", a), need("b", b),
                            need("critical_slip", critical_slip),
                            need("reference_rate", LAW_DEFAULTS["reference_rate"] if reference_rate is None
                                 else reference_rate),
                            need("initial_slip_rate", initial_slip_rate), need("damping", 0.0 if damping is None
                                                                               else damping),
                            state_law, stick_rate, start_from)
    return SlipWeakening(need("friction", friction), need("dynamic_friction", dynamic_friction),
                         need("critical_slip", critical_slip))


def failure_coefficient(law: FrictionLaw, n: int) -> np.ndarray:
    """(n,) the friction coefficient μ of the Coulomb failure stress CFS = |λ_τ| − μ λ_n per patch
    (:mod:`polypore.models.fault_stress`).

    **Choice**: the law's static coefficient, the one a failure assessment compares with: Coulomb's
    F, slip-weakening's F_s, rate-and-state's f₀ (its steady-state coefficient at V₀); 0 for the
    frictionless and the Tresca laws, whose threshold does not depend on the normal traction.
    """
    mu = getattr(law, "f0", getattr(law, "friction", None))
    return np.zeros(n) if mu is None else np.array(np.broadcast_to(mu, (n,)), float)
