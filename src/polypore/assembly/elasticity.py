"""Global elasticity matrix of the bubble VEM (scheme.md §3, "Discrete elasticity").

a(u, v) = Σ_K |K| σ^K(u) : ε^K(v) + Σ_K h_K^{d-2} (2μ_K + λ_K) S_K(u, v), assembled from the
sparse operators as Σ_K |K| [μ (∇u:∇v + ∇u:∇vᵀ) + λ div u div v] + Pᵀ H P, so that no
dense local matrix is ever stored. Degrees of freedom are interleaved: slot a,
component i ↦ a·d + i.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..discretisation import Operators


def interleave(blocks, d: int) -> sp.csr_array:
    """Assemble a d×d grid of (n, n) scalar blocks into one interleaved (n·d, n·d) matrix."""
    rows, cols, vals = [], [], []
    n = None
    for i in range(d):
        for j in range(d):
            B = blocks[i][j]
            if B is None:
                continue
            B = B.tocoo()
            n = B.shape[0]
            rows.append(B.row.astype(np.int64) * d + i)
            cols.append(B.col.astype(np.int64) * d + j)
            vals.append(B.data)
    A = sp.coo_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n * d, n * d))
    return A.tocsr()


def elasticity_matrix(ops: Operators, mu: np.ndarray, lam: np.ndarray, stab_scale: float = 1.0) -> sp.csr_array:
    """Stiffness matrix (n_dofs, n_dofs) in N/m (J/m² in 2D).

    Parameters
    ----------
    mu, lam : (n_cells,) Lamé parameters μ and λ_L in Pa.
    stab_scale : factor on the stabilisation (1 in the scheme; 0 gives the unstabilised
        form, whose kernel contains the rigid motions).
    """
    mesh = ops.space.fm.mesh
    d = mesh.dim
    vol = mesh.geometry.cell_volume
    Wmu = sp.diags_array(vol * mu)
    Wlam = sp.diags_array(vol * lam)
    D = ops.D
    lap = sum(Dq.T @ Wmu @ Dq for Dq in D)
    h = mesh.geometry.cell_diameter
    cell = ops.stab_cell
    H = sp.diags_array(stab_scale * (h ** (d - 2) * (2 * mu + lam))[cell])
    S = ops.stab.T @ H @ ops.stab
    blocks = [[None] * d for _ in range(d)]
    for i in range(d):
        for j in range(d):
            B = D[j].T @ Wmu @ D[i] + D[i].T @ Wlam @ D[j]
            if i == j:
                B = B + lap + S
            blocks[i][j] = B
    return interleave(blocks, d)
