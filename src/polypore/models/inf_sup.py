"""The discrete inf-sup constant of the contact multipliers (docs/contact_patches.md).

    β = min_λ sup_v  Σ_P |P| λ_P·[[v]]_P / (‖v‖_A ‖λ‖_M),

with ‖v‖_A² = a(v, v) + S(v, v) on the free displacement dofs (scheme.md §3, "Discrete
elasticity" and "Stabilisation") and the mesh-dependent H^{-1/2} norm of the multipliers
‖λ‖_M² = Σ_σ h_K |σ| |λ_{P(σ)}|² / (2μ + λ_L)_K (K = K_σ⁺, h_K its diameter), the same weights
for face-wise and patch multipliers, so that the two constants compare on one scale. β² is the
smallest eigenvalue of M^{-1/2} B A^{-1} Bᵀ M^{-1/2}; a β that tends to zero as faces shrink or
thin means multipliers whose size the displacement cannot control (spurious tractions).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as la
import scipy.sparse.linalg as spla

from ..parallel.layout import local_rows

__all__ = ["inf_sup_constant"]


def inf_sup_constant(mech) -> float:
    """β of a :class:`~polypore.models.mechanics.ContactMechanics` (dimensionless); dense in the
    multipliers, for meshes of up to a few thousand multipliers (tests, studies)."""
    d = mech.dim
    if mech.n_c == 0:
        return float("inf")
    free = mech.free
    A = local_rows(mech.A).tocsc()[free][:, free]
    B = mech.Bcv[:, free].toarray()                                   # (n_c d, n_free)
    net, g = mech.fm.network, mech.fm.mesh.geometry
    kp = net.plus_cell
    w_face = g.cell_diameter[kp] * mech.face_area / (2 * mech.mu[kp] + mech.lam[kp])
    w = np.bincount(mech.patches.face_patch, w_face, mech.n_c)        # ‖λ‖_M² = Σ_P w_P |λ_P|²
    S = B @ spla.splu(A).solve(B.T)                                   # B A⁻¹ Bᵀ
    m = np.repeat(1.0 / np.sqrt(w), d)
    S = (S + S.T) / 2 * m[:, None] * m[None, :]
    return float(np.sqrt(max(la.eigvalsh(S, subset_by_index=[0, 0])[0], 0.0)))
