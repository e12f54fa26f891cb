"""Fracture conductivities at the step's own aperture, linearised in Newton (scheme.md §6, "a
fully implicit option"; ``flow.conductivity_aperture = "current"``).

The default evaluates C_f and Λ_f at d_f^{n−1}. Where a slip onset raises the dilatant aperture
10 µm → 10 mm in one step, C_f grows 10⁸–10¹⁰-fold and that step still sees a closed fault: the
slip then depends on Δt far beyond the usual first-order lag (docs/fault_bounds.md, "The time
step"). Here the step's fluxes use C_f(d_f^n), Λ_f(d_f^n) of the current iterate, and the
Jacobian gets their derivative with respect to the displacement,

    ∂(A_f(d) p)_r/∂u = Σ_σ (∂A_f/∂c_σ p)_r c_σ'(d_σ) ∂d_σ/∂u,   c ∈ {C_f/η, |σ| Λ_f/η},
    ∂d_σ/∂u = J_σ ⊗ (−n_σ + tan ψ ∂|[[u − u⁰]]_τ|_ε/∂[[u]]),

in the flow rows of the fracture cells, fracture edges and matrix traces: one entry per (row of
a face's contributions, displacement dof of the face's mean jump). The flow block A_f(d) itself
changes at every iterate; its changing entries are the exchange and fracture-HFV contributions
only (:meth:`~polypore.assembly.flow.FlowAssembler.fracture_contributions`).

The discrete energy identity still holds (the flow equation tested with p^n gives the viscous
dissipation with C_f(d_f^n), whatever aperture the coefficients use); the energy audit takes the
step's ``flux_aperture``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

# central differences of the (possibly user-given) laws C_f(d), Λ_f(d) at relative step H: the
# cubic law's derivative to ~1e-10, far below Newton's tolerance
H = 1e-5


class ImplicitConductivity:
    """Index maps (built once) and per-iterate values of the implicit-conductivity terms.

    Parameters
    ----------
    contributions : the tuple of :meth:`FlowAssembler.fracture_contributions` (slot, rows, cols,
        face, conductive, unit)
    step_slot : (nnz_full,) int, position in the step matrix A_dt's data of every entry of the
        full flow matrix's data (the step pattern's first block)
    flow_free_index : (n_flow,) int, the free-pressure number of every flow unknown, −1 if fixed
    jump : csr (n_ff, n_slots) the mean-jump operator J ([[u]]_σ = Σ J_σs u_s), dimensionless
    free_index : (n_slots · d,) int, the free number of every displacement dof, −1 if fixed
    dim : d
    """

    def __init__(self, contributions, step_slot, flow_free_index, jump, free_index, dim):
        slot, rows, cols, face, conductive, unit = contributions
        self.pos = np.asarray(step_slot)[slot]            # (m,) into A_dt.data
        self.cols, self.face, self.conductive, self.unit = cols, face, conductive, unit
        nf = jump.shape[0]
        key = rows * nf + face
        uniq, self.pair = np.unique(key, return_inverse=True)     # (row, face) pairs of the contributions
        pair_row, pair_face = uniq // nf, uniq % nf
        self.n_pairs = uniq.size
        kp = np.flatnonzero(flow_free_index[pair_row] >= 0)        # pairs in rows that are unknowns
        J = sp.csr_array(jump)
        cnt = np.diff(J.indptr)[pair_face[kp]].astype(np.int64)
        start = np.zeros(kp.size, np.int64)
        np.cumsum(cnt[:-1], out=start[1:])
        e_pair = np.repeat(kp, cnt)
        e_j = np.repeat(J.indptr[pair_face[kp]].astype(np.int64) - start, cnt) + np.arange(cnt.sum())
        e_pair, e_j = np.repeat(e_pair, dim), np.repeat(e_j, dim)
        comp = np.tile(np.arange(dim), e_j.size // dim if dim else 0)
        col = free_index[J.indices[e_j].astype(np.int64) * dim + comp]
        keep = col >= 0
        self.e_pair, self.e_comp = e_pair[keep], comp[keep]
        self.e_face = pair_face[self.e_pair]
        self.e_jval = J.data[e_j[keep]]
        self.e_row = pair_row[self.e_pair]                          # flow numbering (for the scaling)
        it = np.int32 if max(free_index.size, flow_free_index.size) < 2**31 - 1 else np.int64
        # (rows, cols) of the p × u entries in the free numbering
        self.rc = (flow_free_index[self.e_row].astype(it), col[keep].astype(it))

    def coefficient(self, ex: np.ndarray, fc: np.ndarray) -> np.ndarray:
        """(m,) the coefficient multiplying each contribution: C_f/η or |σ| Λ_f/η of its face."""
        return np.where(self.conductive, fc[self.face], ex[self.face])

    def matrix_change(self, ex0, fc0, ex, fc, dt: float, nnz: int) -> np.ndarray:
        """(nnz,) Δt (A_f(d) − A_f(d^{n−1})) on A_dt's data: coefficients (n_ff,) each, m³/(Pa·s)."""
        dc = self.coefficient(ex, fc) - self.coefficient(ex0, fc0)
        return np.bincount(self.pos, self.unit * dc * dt, minlength=nnz)

    def coupling_values(self, p, dex, dfc, grad, s, dt: float) -> np.ndarray:
        """Values of the p × u entries (``rc``) of the scaled Jacobian row −s_r ∂(Δt A_f(d) p)_r/∂u.

        Parameters
        ----------
        p : (n_flow,) pressures, Pa
        dex, dfc : (n_ff,) d(|σ| Λ_f/η)/dd and d(C_f/η)/dd at the iterate, m²/(Pa·s)
        grad : (n_ff, d) ∂d_σ/∂[[u]]_σ (−n + tan ψ ∂|·|_ε), dimensionless
        s : (n_flow,) pressure scaling, Pa/m
        """
        v = self.unit * p[self.cols] * self.coefficient(dex, dfc) * dt
        pair = np.bincount(self.pair, v, minlength=self.n_pairs)   # ∂(Δt A_f p)_r/∂d_σ per (r, σ)
        return -s[self.e_row] * pair[self.e_pair] * self.e_jval * grad[self.e_face, self.e_comp]

