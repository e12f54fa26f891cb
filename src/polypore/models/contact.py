"""Face-wise contact laws and their semi-smooth linearisation (scheme.md §4).

Per fracture face σ with multiplier λ_σ ∈ R^d, normal n = n⁺, mean jump q = [[u]]_σ and
tangential slip s (= [[u]]_τ in a static run, the increment Δ[[u]]_τ in a time step):

    y_n = λ_n + β q_n,      y_τ = λ_τ + β s_τ,
    λ_n = [y_n]_{R+},       λ_τ = [y_τ]_r,

with the radius r from the friction law (`friction.py`): 0 (frictionless), g (Tresca),
F [y_n]_{R+} (Coulomb) or F(δ) [y_n]_{R+} (slip-weakening, δ the slip path). **Choice:** the
radius uses [y_n]_+ rather than λ_n (the two agree at a solution, since then λ_n = [y_n]_+);
it keeps r ≥ 0 at every iterate (Hüeber, Stadler, Wohlmuth 2008).
The residual returned is C = (|σ|/β)(λ − P(y)) so that the rows of closed/stuck faces
read −|σ| q, the transpose of the equilibrium coupling |σ| λ·[[v]]: the Jacobian is
symmetric when every face sticks.

States and the branch taken exactly at the kinks: y_n ≤ 0 → **open** (λ_n = 0); otherwise
|y_τ| ≤ r → **stick** (λ_τ = y_τ); |y_τ| > r → **slip**. A closed frictionless face, whose
tangential traction is zero and which may slide freely, counts as slip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from .friction import FrictionLaw, Radius, RateLaw

# the projection's states, the codes every module reads (outputs, plots, exact solutions)
OPEN, STICK, SLIP = 0, 1, 2
# Stick/slip decision: a face whose trial tangential traction |y_τ| lies within this relative band
# below the friction bound r (on the cone, to round-off) is classified SLIP. At the start of a step
# every face that slipped in the previous one sits there (s = 0, |λ_τ| = F λ_n), and without a band
# its state, hence its generalised derivative, was decided by round-off: runs with different
# linear solvers or MPI rank counts took different Newton paths (docs/parallel.md). The projection
# itself is unchanged (continuous across the cone); only the derivative chosen inside the band is.
STICK_SLIP_TIE = 1e-8
STATE_NAMES = ("open", "stick", "slip")
# default smallest |P| / A_K of a multiplier patch (discretisation/contact_patches.py; chosen by
# measurement on corner-point faults, docs/contact_patches.md)
PATCH_RATIO = 0.2


@dataclass(frozen=True, eq=False)
class ContactLaw:
    """Contact law on the contact patches: a friction law and the augmentation β.

    Attributes
    ----------
    friction_law : the radius of the friction disc and its state (`friction.py`)
    beta : (n,) β_σ > 0 in Pa/m (scheme.md §4: β = c (2μ + λ_L)/h_σ)
    """

    friction_law: FrictionLaw
    beta: np.ndarray

    def __post_init__(self):
        if not isinstance(self.friction_law, FrictionLaw):
            raise TypeError(f"friction_law must be a FrictionLaw, got {type(self.friction_law).__name__}")
        if np.any(~(self.beta > 0)):
            raise InputError("beta", "must be positive")


def _normal_tangential(v, n):
    vn = np.einsum("fi,fi->f", v, n)
    return vn, v - vn[:, None] * n


def linearise_contact(law: ContactLaw, lam: np.ndarray, q: np.ndarray, s: np.ndarray, n: np.ndarray,
                      area: np.ndarray, state: np.ndarray | None = None, dt: float = 0.0):
    """Residual and generalised derivatives of the projection equations, batched over faces.

    Parameters
    ----------
    lam, q, s, n : (n_ff, d) multiplier (Pa), mean jump (m), slip (m), unit normal n⁺
    area : (n_ff,) |σ| (m² in 3D, m in 2D)
    state : (n_ff, k) the friction law's state before the step (None: its initial state)
    dt : the time step, s (rate laws; 0 in a static solve)

    Returns
    -------
    C : (n_ff, d) residual (|σ|/β)(λ − P(y))
    dC_dlam : (n_ff, d, d)
    dC_dq : (n_ff, d, d) derivative with respect to the jump (slip and normal jump both
        depend linearly on [[u]] with unit derivative)
    state : (n_ff,) int8
    """
    nf, d = lam.shape
    beta = law.beta
    eye = np.eye(d)
    nn = np.einsum("fi,fj->fij", n, n)
    Pt = eye[None] - nn
    lam_n, lam_t = _normal_tangential(lam, n)
    q_n = np.einsum("fi,fi->f", q, n)
    _, s_t = _normal_tangential(s, n)
    y_n = lam_n + beta * q_n
    y_t = lam_t + beta[:, None] * s_t
    closed = y_n > 0
    fl = law.friction_law
    fstate = fl.initial_state(nf) if state is None else state
    ny = np.linalg.norm(y_t, axis=1)
    rad: Radius
    if isinstance(fl, RateLaw):
        # a rate law: r solved from the trial traction (rate_state.py), every closed patch slides
        # (static solves: r = ∞, held); the reported state follows the slip rate
        rad = fl.trial_radius(y_n, ny, fstate, dt, beta)
    else:
        rad = fl.radius(y_n, s_t, fstate, dt)
    r = rad.value
    inside = (ny <= r) & (r > 0)                                  # the projection's value
    stick = (ny < (1.0 - STICK_SLIP_TIE) * r) & (r > 0)           # state and derivative (ties: slip)
    slip = ~stick
    # a rate law reports as stick the patches creeping below its stick_rate
    shown = ~(fl.stuck(rad.rate) | stick) if isinstance(fl, RateLaw) and rad.rate is not None else slip
    codes = np.where(~closed, OPEN, np.where(shown, SLIP, STICK)).astype(np.int8)

    # P(y) and its derivative with respect to (λ, q): normal part
    Pn = np.where(closed, y_n, 0.0)
    dPn_dlam = np.where(closed[:, None], n, 0.0)                 # (nf, d)
    dPn_dq = beta[:, None] * dPn_dlam
    # tangential part: y_t if stick, r ŷ if slip (r = 0 gives 0)
    safe = np.where(ny > 0, ny, 1.0)
    yhat = y_t / safe[:, None]
    held = np.isinf(r)                   # a rate law in a static solve: every closed patch held
    r_fin = np.where(held, 0.0, r)
    Pt_val = np.where(inside[:, None], y_t, r_fin[:, None] * yhat)
    fac = np.where(stick, 1.0, r_fin / safe)                     # stick: identity on the tangent plane
    if rad.d_trial is not None:
        # r/|y_τ| → ∂r/∂|y_τ| as |y_τ| → 0 (a rate law's r(0) = 0)
        fac = np.where(stick | (ny > 0), fac, rad.d_trial)
    yy = np.einsum("fi,fj->fij", yhat, yhat)
    M = fac[:, None, None] * np.where(stick[:, None, None], Pt, Pt - yy)
    if rad.d_trial is not None:
        # the radius follows |y_τ|: ∂(r ŷ)/∂y_τ = (r/|y|)(P_τ − ŷŷᵀ) + (∂r/∂|y|) ŷŷᵀ
        M = M + (slip * rad.d_trial)[:, None, None] * yy
    M = np.einsum("fij,fjk->fik", M, Pt)                          # ∂P_τ/∂y_τ composed with the tangent projector
    dPt_dlam = M.copy()
    dPt_dq = beta[:, None, None] * M
    if np.any(rad.d_normal):
        # slip: r depends on y_n = λ_n + β q_n (Coulomb: r = F [y_n]_+, ∂r/∂y_n = F where closed)
        g = slip[:, None] * (rad.d_normal[:, None] * yhat)   # (nf, d) = ∂P_τ/∂r · ∂r/∂y_n
        dPt_dlam += np.einsum("fi,fj->fij", g, n)
        dPt_dq += beta[:, None, None] * np.einsum("fi,fj->fij", g, n)
    if rad.d_slip is not None:
        # slip: r depends on the step's slip s_τ = P_τ s (slip-weakening), and ∂s/∂q = I; d_slip
        # lies in the tangent plane, so composing with P_τ changes nothing
        dPt_dq += slip[:, None, None] * np.einsum("fi,fj->fij", yhat, rad.d_slip)
    P = Pn[:, None] * n + Pt_val
    dP_dlam = np.einsum("fi,fj->fij", n, dPn_dlam) + dPt_dlam
    dP_dq = np.einsum("fi,fj->fij", n, dPn_dq) + dPt_dq
    w = area / beta
    C = w[:, None] * (lam - P)
    dC_dlam = w[:, None, None] * (eye[None] - dP_dlam)
    dC_dq = -w[:, None, None] * dP_dq
    return C, dC_dlam, dC_dq, codes
