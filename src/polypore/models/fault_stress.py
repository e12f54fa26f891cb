"""Coulomb failure stress change and slip tendency of fault faces (issue 28's maps).

With λ_n = λ·n⁺ the normal contact traction (Pa, positive in compression: the effective normal
stress σ_n′, since the fluid pressure acts on the faces apart from λ, scheme.md §1–2) and
τ = |λ_τ| the shear traction, between a reference state ⁰ (the start of a run) and now:

    ΔCFS = Δτ − μ Δσ_n′ = (|λ_τ| − |λ_τ⁰|) − μ (λ_n − λ_n⁰),       slip tendency T_s = τ/σ_n′,

μ the failure coefficient of the friction law (:func:`polypore.models.friction.failure_coefficient`).
ΔCFS > 0 moves a face towards failure; T_s reaches μ on a Coulomb face that slips. Δτ is the
change of the shear traction's length, not of a component along a fixed rake: a fault whose
shear traction rotates is not brought closer to failure by the rotation alone. T_s is NaN where
the face is open (σ_n′ ≤ OPEN_ROUNDOFF × the largest traction: no traction to compare with).
"""

from __future__ import annotations

import numpy as np

OPEN_ROUNDOFF = 1e-9        # σ_n′ at or below this fraction of the largest traction: open


def normal_and_shear(lam: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(λ_n, |λ_τ|), each (n,), of tractions ``lam`` (n, d) on faces of unit normals (n, d), Pa."""
    ln = np.einsum("fi,fi->f", lam, normal)
    return ln, np.linalg.norm(lam - ln[:, None] * normal, axis=1)


def coulomb_fields(lam: np.ndarray, lam_ref: np.ndarray, normal: np.ndarray, mu: np.ndarray) -> dict:
    """The fault-stress outputs of tractions ``lam`` against ``lam_ref`` (both (n, d), Pa).

    Returns
    -------
    dict of (n,) arrays: ``delta_cfs`` ΔCFS (Pa), ``slip_tendency`` τ/σ_n′ (–, NaN where open),
    ``delta_tau`` Δ|λ_τ| (Pa), ``delta_sigma_n`` Δλ_n (Pa, positive: more compression)
    """
    sn, tau = normal_and_shear(lam, normal)
    sn0, tau0 = normal_and_shear(lam_ref, normal)
    d_tau, d_sn = tau - tau0, sn - sn0
    # an open face's λ is zero up to the solve's round-off (1e-12 of the tractions): τ/σ_n′ of
    # round-off is noise, and differed between a serial and a 2-rank run
    closed = sn > OPEN_ROUNDOFF * (float(np.max(np.abs(lam))) if lam.size else 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tendency = np.where(closed, tau / np.where(closed, sn, 1.0), np.nan)
    return {"delta_cfs": d_tau - mu * d_sn, "slip_tendency": tendency, "delta_tau": d_tau, "delta_sigma_n": d_sn}
