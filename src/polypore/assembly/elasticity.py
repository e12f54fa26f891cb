"""Global elasticity matrix of the bubble VEM (scheme.md §3, "Discrete elasticity").

a(u, v) = Σ_K |K| σ^K(u) : ε^K(v) + Σ_K h_K^{d-2} (2μ_K + λ_K) S_K(u, v), assembled from the
sparse operators as Σ_K |K| [μ (∇u:∇v + ∇u:∇vᵀ) + λ div u div v] + Pᵀ H P, so that no
dense local matrix is ever stored. The quadratic space (mechanics.order = 2) uses the same
form with a sum over quadrature points in place of the sum over cells, and no stabilisation.
Degrees of freedom are interleaved: slot a, component i ↦ a·d + i.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..core.csr import csr_keys
from ..core.memory import int32_indices
from ..mesh.geometry import cell_thickness


def interleave(blocks, d: int) -> sp.csr_array:
    """Assemble a d×d grid of (n, n) scalar blocks into one interleaved (n·d, n·d) matrix.

    Built as a block-sparse (d × d blocks) matrix on the union of the blocks' patterns, then
    converted: an entry absent from its block is an explicit zero there and is dropped, so the
    result is the coordinate assembly's, entry for entry. The coordinate assembly (three nnz-long
    arrays per block, concatenated, then converted) peaked at several times the result
    (docs/iterative_cornerpoint.md, fifth session).
    """
    mats = {}
    n = None
    for i in range(d):
        for j in range(d):
            if blocks[i][j] is not None:
                B = sp.csr_array(blocks[i][j])
                B.sum_duplicates()
                mats[i, j] = B
                n = B.shape[0]
    U = None
    for B in mats.values():
        one = sp.csr_array((np.ones(B.nnz), B.indices, B.indptr), shape=B.shape)
        U = one if U is None else U + one
    assert U is not None and n is not None          # d ≥ 1: mats has d² blocks
    U.sort_indices()

    ku = csr_keys(U)
    data = np.zeros((U.nnz, d, d))
    for (i, j), B in mats.items():
        data[np.searchsorted(ku, csr_keys(B)), i, j] = B.data      # every entry of B is in U
    del ku, mats
    A = sp.bsr_array((data, U.indices, U.indptr), shape=(n * d, n * d)).tocsr()
    A.eliminate_zeros()
    return int32_indices(A)


FLAT = 4.0   # "thickness" weight: h_K^{d−2} min(1, FLAT t_K/h_K); 1 on every shape-regular cell


def nodal_weight(mesh, scaling: str = "diameter") -> np.ndarray:
    """(n_cells,) length factor of the nodal stabilisation rows (× (2μ + λ_L)).

    "diameter": the scheme's h_K^{d−2}. "thickness": h_K^{d−2} min(1, 4 t_K/h_K) with the cell's
    thickness t_K = |K| / (its largest face measure). The factor is 1 on shape-regular cells
    (t_K/h_K = 0.27 on a regular tetrahedron, 0.58 on a cube, 0.43 on an equilateral triangle)
    and ≈ 4 t_K on flat ones: the kernel modes of Π^K on a flat cell (in-plane twist and bending
    of a layer) carry an energy ∝ (2μ + λ) t_K, not ∝ h_K, and the diameter weight stiffens them
    by h_K/t_K (20 on Emerald's cells): on a reservoir grid it doubled the poroelastic shear change
    on a fault (docs/contact_patches.md, "Flat cells").
    """
    g = mesh.geometry
    d = mesh.dim
    h = g.cell_diameter
    if scaling == "diameter":
        return h ** (d - 2)
    if scaling != "thickness":
        raise ValueError(f"nodal scaling must be 'diameter' or 'thickness', got {scaling!r}")
    return h ** (d - 2) * np.minimum(1.0, FLAT * cell_thickness(mesh) / h)


def elasticity_matrix(ops, mu: np.ndarray, lam: np.ndarray, stab_scale: float = 1.0,
                      bubble_scaling: str = "face", nodal_scaling: str = "diameter") -> sp.csr_array:
    """Stiffness matrix (n_dofs, n_dofs) in N/m (J/m² in 2D).

    Σ_q w_q [μ (∇u:∇v + ∇u:∇vᵀ) + λ div u div v] over the rows q of ``ops.D`` (quadrature points
    ``ops.qp_cell``, weights ``ops.qp_weight``: one per cell with weight |K| for
    :class:`~polypore.discretisation.Operators`), plus the stabilisation when ``ops.stab`` is set.

    Parameters
    ----------
    ops : Operators or QuadraticOperators
    mu, lam : (n_cells,) Lamé parameters μ and λ_L in Pa.
    stab_scale : factor on the stabilisation (1 in the scheme; 0 gives the unstabilised
        form, whose kernel contains the rigid motions).
    bubble_scaling : weight of a bubble's stabilisation row |v_Kσ|²: "cell", the scheme's
        h_K^{d−2} (2μ + λ_L)_K, or "face" (default), (2μ + λ_L)_K |σ|²/|K|.
    nodal_scaling : length factor of the nodal rows, :func:`nodal_weight` ("diameter": the
        scheme's h_K^{d−2}; "thickness": reduced on flat cells).

    Notes
    -----
    **Choice** ("face"): |σ|²/|K| is the weight the consistency term itself gives the bubble
    (its gradient is |σ| v_Kσ ⊗ n_Kσ / |K| over |K|), the diagonal recipe of the VEM literature.
    On shape-regular cells it equals h_K^{d−2} up to a bounded factor (3/2 on a regular
    tetrahedron, 1 on a cube); on the flat cells of reservoir grids and on the slivers and thin
    strips of corner-point faults h_K^{d−2} makes the bubble stiffer than the cell by up to
    |K| h_K^{d−2}/|σ|² (10³–10¹² there), so that the face's multiplier cannot be controlled:
    the discrete inf-sup constant falls like √(|σ|/A_K) with "cell" and stays at its
    regular-face value with "face" (tests/unit/discretisation/test_contact_patches.py, docs/contact_patches.md).
    """
    mesh = ops.space.fm.mesh
    d = mesh.dim
    w, cell = ops.qp_weight, ops.qp_cell
    Wmu = sp.diags_array(w * mu[cell])
    Wlam = sp.diags_array(w * lam[cell])
    D = ops.D
    lap = sum(Dq.T @ Wmu @ Dq for Dq in D)
    S = None
    if ops.stab is not None:
        g = mesh.geometry
        wts = stab_scale * (nodal_weight(mesh, nodal_scaling) * (2 * mu + lam))[ops.stab_cell]
        nb = ops.space.n_bubbles
        if bubble_scaling == "face" and nb:
            # bubble rows come last (discretisation/operators.py, _stabilisation)
            sp_ = ops.space
            K = sp_.bubble_cell
            area = g.face_area[sp_.fm.network.faces[sp_.bubble_face]]
            wts[-nb:] = stab_scale * (2 * mu + lam)[K] * area ** 2 / g.cell_volume[K]
        elif bubble_scaling not in ("face", "cell"):
            raise ValueError(f"bubble_scaling must be 'face' or 'cell', got {bubble_scaling!r}")
        H = sp.diags_array(wts)
        S = ops.stab.T @ H @ ops.stab
    blocks = [[None] * d for _ in range(d)]
    for i in range(d):
        for j in range(d):
            B = D[j].T @ Wmu @ D[i] + D[i].T @ Wlam @ D[j]
            if i == j:
                B = B + lap if S is None else B + lap + S
            blocks[i][j] = B
    return interleave(blocks, d)
