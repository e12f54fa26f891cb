"""Face-wise contact laws and their semi-smooth linearisation (scheme.md §4).

Per fracture face σ with multiplier λ_σ ∈ R^d, normal n = n⁺, mean jump q = [[u]]_σ and
tangential slip s (= [[u]]_τ in a static run, the increment Δ[[u]]_τ in a time step):

    y_n = λ_n + β q_n,      y_τ = λ_τ + β s_τ,
    λ_n = [y_n]_{R+},       λ_τ = [y_τ]_r,

with r = 0 (frictionless), r = g (Tresca) or r = F [y_n]_{R+} (Coulomb). **Choice:** the
Coulomb radius uses [y_n]_+ rather than λ_n (the two agree at a solution, since then
λ_n = [y_n]_+); it keeps r ≥ 0 at every iterate (Hüeber, Stadler, Wohlmuth 2008).
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

LAWS = ("frictionless", "tresca", "coulomb")
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
    """Contact law on the fracture faces.

    Attributes
    ----------
    kind : "frictionless", "tresca" or "coulomb"
    friction : (n_ff,) Coulomb coefficient F ≥ 0 per fracture face (dimensionless)
    threshold : (n_ff,) Tresca threshold g ≥ 0 per face, Pa
    beta : (n_ff,) β_σ > 0 in Pa/m (scheme.md §4: β = c (2μ + λ_L)/h_σ)
    """

    kind: str
    friction: np.ndarray
    threshold: np.ndarray
    beta: np.ndarray

    def __post_init__(self):
        if self.kind not in LAWS:
            raise InputError("contact.law", f"unknown contact law {self.kind!r}; allowed: {', '.join(LAWS)}")
        if np.any(~np.isfinite(self.friction)) or np.any(self.friction < 0):
            raise InputError("contact.friction", f"must be finite and ≥ 0, got {np.nanmin(self.friction)!r}")
        if np.any(~np.isfinite(self.threshold)) or np.any(self.threshold < 0):
            raise InputError("contact.threshold", f"must be finite and ≥ 0 (Pa), got {np.nanmin(self.threshold)!r}")
        if np.any(~(self.beta > 0)):
            raise InputError("contact.beta", "must be positive")


def _normal_tangential(v, n):
    vn = np.einsum("fi,fi->f", v, n)
    return vn, v - vn[:, None] * n


def contact_state(law: ContactLaw, lam, q, s, n):
    """(n_ff,) state per face (OPEN / STICK / SLIP) at the current iterate."""
    return linearise_contact(law, lam, q, s, n, np.ones(len(n)))[3]


def linearise_contact(law: ContactLaw, lam: np.ndarray, q: np.ndarray, s: np.ndarray, n: np.ndarray,
                      area: np.ndarray):
    """Residual and generalised derivatives of the projection equations, batched over faces.

    Parameters
    ----------
    lam, q, s, n : (n_ff, d) multiplier (Pa), mean jump (m), slip (m), unit normal n⁺
    area : (n_ff,) |σ| (m² in 3D, m in 2D)

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
    I = np.eye(d)
    nn = np.einsum("fi,fj->fij", n, n)
    Pt = I[None] - nn
    lam_n, lam_t = _normal_tangential(lam, n)
    q_n = np.einsum("fi,fi->f", q, n)
    _, s_t = _normal_tangential(s, n)
    y_n = lam_n + beta * q_n
    y_t = lam_t + beta[:, None] * s_t
    closed = y_n > 0
    if law.kind == "frictionless":
        r = np.zeros(nf)
    elif law.kind == "tresca":
        r = law.threshold.astype(float)
    else:
        r = law.friction * np.maximum(y_n, 0.0)
    ny = np.linalg.norm(y_t, axis=1)
    inside = (ny <= r) & (r > 0)                                  # the projection's value
    stick = (ny < (1.0 - STICK_SLIP_TIE) * r) & (r > 0)           # state and derivative (ties: slip)
    slip = ~stick
    state = np.where(~closed, OPEN, np.where(stick, STICK, SLIP)).astype(np.int8)
    if law.kind == "tresca":
        state = np.where(closed, state, OPEN).astype(np.int8)

    # P(y) and its derivative with respect to (λ, q): normal part
    Pn = np.where(closed, y_n, 0.0)
    dPn_dlam = np.where(closed[:, None], n, 0.0)                 # (nf, d)
    dPn_dq = beta[:, None] * dPn_dlam
    # tangential part: y_t if stick, r ŷ if slip (r = 0 gives 0)
    safe = np.where(ny > 0, ny, 1.0)
    yhat = y_t / safe[:, None]
    Pt_val = np.where(inside[:, None], y_t, r[:, None] * yhat)
    fac = np.where(stick, 1.0, r / safe)                         # stick: identity on the tangent plane
    M = fac[:, None, None] * np.where(stick[:, None, None], Pt, Pt - np.einsum("fi,fj->fij", yhat, yhat))
    M = np.einsum("fij,fjk->fik", M, Pt)                          # ∂P_τ/∂y_τ composed with the tangent projector
    dPt_dlam = M.copy()
    dPt_dq = beta[:, None, None] * M
    if law.kind == "coulomb":
        # slip: r = F y_n depends on λ_n and q_n where the face is closed
        g = (slip & closed)[:, None] * (law.friction[:, None] * yhat)   # (nf, d) = ∂P_τ/∂r · ∂r/∂y_n direction
        dPt_dlam += np.einsum("fi,fj->fij", g, n)
        dPt_dq += beta[:, None, None] * np.einsum("fi,fj->fij", g, n)
    P = Pn[:, None] * n + Pt_val
    dP_dlam = np.einsum("fi,fj->fij", n, dPn_dlam) + dPt_dlam
    dP_dq = np.einsum("fi,fj->fij", n, dPn_dq) + dPt_dq
    w = area / beta
    C = w[:, None] * (lam - P)
    dC_dlam = w[:, None, None] * (I[None] - dP_dlam)
    dC_dq = -w[:, None, None] * dP_dq
    return C, dC_dlam, dC_dq, state
