"""The coupled poromechanics system (scheme.md §6) as data: the Biot coupling G, the pressure
stabilisation S_δ, the flow unknowns with their equation kinds, and the step Jacobian's pattern
with its named blocks, built once and refilled per step and per Newton iterate.

The coupled model (:mod:`polypore.models.poromechanics`) composes this object with the contact
mechanics and flow models: they hand it plain arrays (operators, dof maps, layouts), it hands back
matrices and Jacobian data. Nothing here knows about contact laws or time stepping.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..core.memory import int32_indices
from ..parallel.layout import OwnedRows
from .blocks import Block, PressureRowBlock
from .pattern import BlockPattern, Pattern, jacobian_pattern

# equation kind of each flow row (FlowKind order): block_counts, the residual's per-kind norms and
# the two-level pressure preconditioner's groups read it
CELL, FACE, TRACE, FRACTURE, FRACTURE_EDGE = range(5)
N_KINDS = 5


def biot_coupling(D, qp_cell, qp_weight, biot: float, jump, face_area, normal, frac_dofs, n_face_dofs: int,
                  n_dofs: int, n_flow: int) -> sp.csr_array:
    """G (n_dofs, n_flow), m^d: b ∫_K div v on cell pressures, −|σ| [[v]]_σ·n⁺ on fracture pressures.

    Parameters
    ----------
    D : sequence of d sparse (n_qp, n_slots) derivative operators ∂_j at the quadrature points
    qp_cell, qp_weight : (n_qp,) cell of each quadrature point and its weight, m^d (order 1: one
        point per cell, weight |K|)
    biot : b, dimensionless
    jump : sparse (n_ff, n_slots) mean jump [[·]]_σ per slot (scalar)
    face_area, normal : (n_ff,) |σ| (m^{d−1}) and (n_ff, d) n⁺
    frac_dofs : (n_ff,) the fracture-pressure unknown of each fracture face
    n_face_dofs : number of face/trace/fracture/edge pressures (the cell pressures follow them)
    """
    d = len(D)
    rows, cols, vals = [], [], []
    for j in range(d):
        Dj = D[j].tocoo()
        rows.append(Dj.col.astype(np.int64) * d + j)          # div v = Σ_j ∂_j v_j
        cols.append(n_face_dofs + qp_cell[Dj.row].astype(np.int64))
        vals.append(Dj.data * (biot * qp_weight)[Dj.row])
    if face_area.size:
        J = jump.tocoo()
        rows.append((J.col.astype(np.int64)[:, None] * d + np.arange(d)).ravel())
        cols.append(np.repeat(frac_dofs[J.row], d))
        vals.append((-(J.data * face_area[J.row])[:, None] * normal[J.row]).ravel())
    return int32_indices(sp.csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                      shape=(n_dofs, n_flow)))


@dataclass(frozen=True, eq=False)
class PressureStabilisation:
    """The pressure-jump stabilisation S_δ of the mass balance (models/poromechanics.py, "Pressure
    stabilisation"): S_δ(p, q) = Σ_σ w_σ (p_K − p_L)(q_K − q_L) over its face pairs.

    Attributes
    ----------
    delta : δ ≥ 0, dimensionless
    pairs : (n_pairs, 2) cells (K, L) of the stabilised faces
    weights : (n_pairs,) δ w_σ, m^d/Pa
    positions : (n_pairs, 2) their (cell, face) entries in ``mesh.cell_faces.values``
    offset : the unknown of cell 0 (cell pressures follow the face pressures)
    n_flow : number of flow unknowns
    """

    delta: float
    pairs: np.ndarray
    weights: np.ndarray
    positions: np.ndarray
    offset: int
    n_flow: int

    @classmethod
    def build(cls, delta: float, cell_pairs, face_area, face_normal, stiffness, biot: float, permeability,
              offset: int, n_flow: int) -> "PressureStabilisation":
        """The face weights w_σ = δ b² |σ| h_σ² / (d_Kσ M_K + d_Lσ M_L) × 4 k_K k_L/(k_K + k_L)².

        Parameters
        ----------
        cell_pairs : :meth:`~polypore.assembly.flow.FlowAssembler.cell_pairs` (faces, pairs, dist, width, pos)
        face_area, face_normal : (n_faces,) and (n_faces, d) of the mesh
        stiffness : (n_cells,) M = λ_L + 2μ per cell, Pa
        permeability : (n_cells, d, d) K, m²
        """
        faces, pairs, dist, width, pos = cell_pairs
        h = width.mean(axis=1)                                                # h_σ, m
        K, L = pairs.T
        w = delta * biot ** 2 * face_area[faces] * h * h / (dist[:, 0] * stiffness[K] + dist[:, 1] * stiffness[L])
        # the stabilisation flux does not depend on the permeability: across a barrier (C6's
        # caprocks, 10⁶ below the reservoir) it would carry fluid through the seal. Factor
        # harmonic/arithmetic mean of the two normal permeabilities: 1 in a homogeneous
        # region, 4 k_L/k_K across a contrast k_L ≪ k_K.
        n = face_normal[faces]
        kn = np.einsum("fi,fcij,fj->fc", n, permeability[pairs], n)           # n·K n per side, m²
        w *= 4 * kn[:, 0] * kn[:, 1] / (kn[:, 0] + kn[:, 1]) ** 2
        keep = w > 0                                                          # none when δ = 0 or b = 0
        return cls(float(delta), pairs[keep], w[keep], pos[keep], int(offset), int(n_flow))

    def rc(self) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) (4 n_pairs,) of S_δ's entries: (K, K), (L, L), (K, L), (L, K) per pair."""
        K, L = self.offset + self.pairs.T
        return np.concatenate([K, L, K, L]), np.concatenate([K, L, L, K])

    def values(self) -> np.ndarray:
        """(4 n_pairs,) S_δ's entries in the order of :meth:`rc`, m³/Pa."""
        w = self.weights
        return np.concatenate([w, w, -w, -w])

    def matrix(self) -> sp.csr_array:
        """S_δ (n_flow, n_flow), m³/Pa."""
        r, c = self.rc()
        return sp.csr_array((self.values(), (r, c)), shape=(self.n_flow, self.n_flow))

    def jumps(self, p: np.ndarray) -> np.ndarray:
        """(n_pairs,) p_K − p_L across the stabilised faces of a (n_flow,) pressure vector, Pa."""
        K, L = (self.offset + self.pairs).T
        return p[K] - p[L]

    def apply(self, p: np.ndarray) -> np.ndarray:
        """(n_flow,) S_δ p, m³ (the old pressure's part of a step's right-hand side)."""
        sj = self.weights * self.jumps(p)
        K, L = (self.offset + self.pairs).T
        return np.bincount(K, sj, self.n_flow) - np.bincount(L, sj, self.n_flow)


def flow_kinds(dofs, n_flow: int) -> np.ndarray:
    """(n_flow,) equation kind of every flow row: CELL mass balance, FACE flux continuity, TRACE
    matrix–fracture exchange, FRACTURE mass balance, FRACTURE_EDGE flux continuity."""
    kind = np.full(n_flow, CELL, np.int64)
    kind[dofs.face[dofs.face >= 0]] = FACE
    kind[dofs.trace.ravel()] = TRACE
    kind[dofs.frac] = FRACTURE
    kind[dofs.edge] = FRACTURE_EDGE
    return kind


@dataclass(frozen=True, eq=False)
class FlowUnknowns:
    """The flow unknowns of the coupled step: every flow dof but the Dirichlet pressures, and the
    fixed structure of the step's flow matrix Δt A_f + S_δ (one structure for both terms).

    Attributes
    ----------
    fixed, free : (n,) flow dofs with a Dirichlet pressure, and the others (ascending)
    free_index : (n_flow,) position of each dof among ``free``, −1 when fixed
    pattern : BlockPattern of A_f (block 0) and S_δ (block 1), this rank's rows under mpiexec
    keep : (nnz,) the pattern's entries whose row and column are free
    rc : (free rows, free cols) of those entries, in the free numbering (int32 where it fits)
    kind : (n_free,) equation kind of each free row (:func:`flow_kinds`)
    kind_count : (N_KINDS,) rows per kind
    """

    fixed: np.ndarray
    free: np.ndarray
    free_index: np.ndarray
    pattern: BlockPattern
    keep: np.ndarray
    rc: tuple
    kind: np.ndarray
    kind_count: np.ndarray

    @classmethod
    def build(cls, fixed_ids, unit_matrix, stabilisation_rc, dofs, n_flow: int, layout=None) -> "FlowUnknowns":
        """From the Dirichlet dofs (the set does not depend on t), A_f with unit coefficients (its
        structure) and S_δ's entries; ``layout`` the flow unknowns' DofLayout under mpiexec."""
        fixed = np.zeros(n_flow, bool)
        fixed[fixed_ids] = True
        free = np.flatnonzero(~fixed)
        free_index = np.full(n_flow, -1, np.int64)
        free_index[free] = np.arange(free.size)
        Af = unit_matrix
        r = np.repeat(np.arange(n_flow), np.diff(Af.indptr))
        pattern = BlockPattern.build([(r, Af.indices), stabilisation_rc], Af.shape,
                                     row_local=None if layout is None else layout.local_index,
                                     n_rows=None if layout is None else layout.n_local)
        pat = pattern.pattern
        r = np.repeat(np.arange(pat.shape[0]), np.diff(pat.indptr))
        if layout is not None:
            r = layout.owned[r]                                   # local rows → flow unknowns
        c = pat.indices.astype(np.int64)
        keep = (free_index[r] >= 0) & (free_index[c] >= 0)
        it = np.int32 if n_flow < 2**31 - 1 else np.int64
        rc = (free_index[r[keep]].astype(it), free_index[c[keep]].astype(it))
        kind = flow_kinds(dofs, n_flow)[free]
        return cls(np.flatnonzero(fixed), free, free_index, pattern, keep, rc, kind,
                   np.bincount(kind, minlength=N_KINDS))

    def step_matrix(self, flow_values_dt: np.ndarray, stabilisation_values: np.ndarray) -> sp.csr_array:
        """Δt A_f + S_δ on the fixed structure, from A_f's data × Δt and S_δ's entries."""
        pat = self.pattern
        return pat.fill([pat.take(0, flow_values_dt), pat.take(1, stabilisation_values)])

    def scaled_free_values(self, local_data: np.ndarray, scale_free: np.ndarray) -> np.ndarray:
        """The free–free entries of the step flow matrix (its local data) with rows and columns
        scaled by s (``scale_free`` (n_free,), Pa/m)."""
        ar, ac = self.rc
        return local_data[self.keep] * scale_free[ar] * scale_free[ac]


@dataclass(frozen=True)
class DilatancyEntries:
    """The dilatancy's Jacobian entries ∂(|σ| tan ψ |[[u − u⁰]]_τ|)/∂u in the fracture-pressure rows:
    one per (jump nonzero, component) whose row and column are unknowns.

    Attributes
    ----------
    face, weight : (nnz,) fracture face and jump weight of each nonzero of the scalar jump
    keep : (nnz, d) bool, the entries that are unknowns
    rows, cols : their Jacobian rows (free pressures) and columns (free displacements)
    """

    face: np.ndarray
    weight: np.ndarray
    keep: np.ndarray
    rows: np.ndarray
    cols: np.ndarray

    @classmethod
    def build(cls, jump, u_free_index, frac_free_index, d: int) -> "DilatancyEntries":
        """From the scalar jump (n_ff, n_slots), the displacement dofs' and the fracture pressures'
        free indices ((n_dofs,), (n_ff,))."""
        J = jump.tocoo()
        fcol = u_free_index[J.col.astype(np.int64)[:, None] * d + np.arange(d)]       # (nnz, d)
        frow = frac_free_index[J.row] if frac_free_index.size else np.zeros(0, np.int64)
        keep = (fcol >= 0) & (frow[:, None] >= 0)
        return cls(J.row, J.data, keep, np.broadcast_to(frow[:, None], keep.shape)[keep], fcol[keep])

    def values(self, factor: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """The entries' values −(factor_σ × jump weight) × direction_σ from a per-face factor (n_ff,)
        (s |σ| tan ψ) and the slip norm's derivative direction (n_ff, d)."""
        return -((factor[self.face] * self.weight)[:, None] * direction[self.face])[self.keep]

    def zeros(self) -> np.ndarray:
        """Zero values of every entry (no dilatancy in this step)."""
        return np.zeros(self.rows.size)


class CoupledJacobian:
    """The step Jacobian's fixed structure: the pattern of every block (serially or this rank's
    rows under mpiexec), or, for a block solver on one process, the pressure blocks' own patterns
    (the (u, λ) blocks are the mechanics model's).

    Unknowns x = [u_free, λ̃, p̃_free]; blocks by name (:class:`~polypore.assembly.blocks.Block`).

    Parameters
    ----------
    mechanics_blocks : (blocks, values) of the (u, λ) part (A, Bᵀ, C_u, C_λ) from the mechanics
        model; None with ``blockwise``
    contact_entries : (jump rows, jump values, keep) of the contact rows' displacement columns
    coupling, biot : (rows, cols, values) of G (free u × free p) and Gᵀ (free p × free u), m^d
    dilatancy : DilatancyEntries
    implicit_rc : (rows, cols) of the implicit conductivities' p × u entries (empty without)
    flow : FlowUnknowns
    n_u, n_lambda : free displacement dofs and multipliers
    layout : DofLayout of the step unknowns under mpiexec, else None
    blockwise : the block solver's pressure blocks instead of one pattern
    """

    def __init__(self, mechanics_blocks, contact_entries, coupling, biot, dilatancy: DilatancyEntries,
                 implicit_rc, flow: FlowUnknowns, n_u: int, n_lambda: int, layout=None, blockwise: bool = False):
        self.layout = layout
        self.contact_entries = contact_entries
        npf = flow.free.size
        po = n_u + n_lambda                                              # offset of the pressures
        n = po + npf
        it = np.int32 if n < 2**31 - 1 else np.int64
        gr, gc, gv = coupling
        tr, tc, tv = biot
        self.pattern: BlockPattern | None = None
        self.blocks: dict[str, Any] | None = None
        if blockwise:
            up = Pattern.build(gr, gc, (n_u, npf))
            pu = BlockPattern.build([(tr, tc), (dilatancy.rows, dilatancy.cols), implicit_rc], (npf, n_u))
            # F's entries, from the flow pattern's free part: rows ascending and columns ascending
            # in each row (the free numbering keeps the order), so its CSR structure is (ar, ac)
            ar, ac = flow.rc
            f_ptr = np.zeros(npf + 1, it)
            np.cumsum(np.bincount(ar, minlength=npf), out=f_ptr[1:])
            self.blocks = {"up": (up, gv, gc.astype(it)),
                           "pu": (pu, pu.take(PressureRowBlock.BIOT, tv), tr.astype(it)),
                           "pp": (f_ptr, ac)}
            return
        blocks, values = mechanics_blocks
        ar, ac = flow.rc
        blocks += [(gr, po + gc), (po + tr, tc), (po + ar, po + ac), (po + dilatancy.rows, dilatancy.cols),
                   (po + implicit_rc[0], implicit_rc[1])]
        self.pattern = pat = jacobian_pattern(blocks, n, layout)
        # the elasticity and multiplier blocks never change; A's values are put into each step's
        # data from A itself rather than kept as a data array of the whole pattern (nnz × 8 bytes);
        # A's entries have distinct slots
        self.elastic_distinct = pat.distinct(Block.ELASTIC)
        self.multiplier_values = pat.take(Block.MULTIPLIER, values[Block.MULTIPLIER])
        del values, blocks, mechanics_blocks      # the (row, col) lists: int64 per contribution
        self.coupling = (pat.take(Block.COUPLING, gv), gc.astype(it))      # values (m^d), p column
        self.biot = (pat.take(Block.BIOT, tv), tr.astype(it))              # values (m^d), p row

    @property
    def blockwise(self) -> bool:
        """The block solver's pressure blocks rather than one pattern."""
        return self.blocks is not None

    def step_data(self, elastic_values, scale_free, coupling_sign: float, flow_values):
        """The Jacobian's data without the contact, dilatancy and implicit blocks (added per
        iterate, :meth:`iterate`): the fixed blocks and the step's coupling and flow blocks.

        Parameters
        ----------
        elastic_values : A's values in the mechanics model's order (unused with ``blockwise``)
        scale_free : (n_free,) s of the free pressures, Pa/m
        coupling_sign : +1 (−1 only in tests: a wrong Biot sign the energy check must catch)
        flow_values : the free–free flow entries scaled by s (:meth:`FlowUnknowns.scaled_free_values`)

        Returns
        -------
        pattern data (n_contributions,), or with ``blockwise`` (G block, pu data, F block)
        """
        sf, cs = scale_free, coupling_sign
        if self.blocks is not None:
            up, up_vals, up_col = self.blocks["up"]
            pu, pu_vals, pu_row = self.blocks["pu"]
            f_ptr, f_col = self.blocks["pp"]
            npf = f_ptr.size - 1
            return (up.fill(-cs * (up_vals * sf[up_col])), pu.add(pu.zeros(), 0, -(pu_vals * sf[pu_row])),
                    sp.csr_array((-flow_values, f_col, f_ptr), shape=(npf, npf)))
        # no block of the contact rows shares an entry with the coupling, Biot and flow blocks
        # (contact rows against displacement and pressure rows), so adding these first gives
        # pat.fill's sums bit for bit
        pat = self.pattern
        assert pat is not None
        fill = pat.put if self.elastic_distinct else pat.add
        data = fill(pat.zeros(), Block.ELASTIC, pat.take(Block.ELASTIC, elastic_values))
        pat.add(data, Block.MULTIPLIER, self.multiplier_values)
        pat.add(data, Block.COUPLING, -cs * (self.coupling[0] * sf[self.coupling[1]]))
        pat.add(data, Block.BIOT, -(self.biot[0] * sf[self.biot[1]]))
        return pat.add(data, Block.FLOW, -flow_values)

    def iterate(self, step, contact_jump, contact_multiplier, dilatancy, implicit=None):
        """The Jacobian at an iterate from the step's data.

        Parameters
        ----------
        step : :meth:`step_data`'s result
        contact_jump, contact_multiplier : the contact rows' values (C_u per jump entry, C_λ per patch)
        dilatancy : values of the dilatancy entries (:meth:`DilatancyEntries.values`)
        implicit : (p × u values, change of the free–free flow entries) of the implicit
            conductivities, or None

        Returns
        -------
        csr (OwnedRows under mpiexec), or with ``blockwise`` (G block, Gᵀ-row block, F block) for the
        block Jacobian (the (u, λ) blocks come from the mechanics model)
        """
        if self.blocks is not None:
            Gup, pu_data, Fp = step
            pu = self.blocks["pu"][0]
            if np.any(dilatancy) or implicit is not None:
                pu_data = pu_data.copy()
                if np.any(dilatancy):
                    pu.add(pu_data, PressureRowBlock.DILATANCY, dilatancy)
                if implicit is not None:
                    pu.add(pu_data, PressureRowBlock.IMPLICIT_CONDUCTIVITY, implicit[0])
                    Fp = sp.csr_array((Fp.data - implicit[1], Fp.indices, Fp.indptr), shape=Fp.shape)
            return Gup, pu.matrix(pu_data), Fp
        pat = self.pattern
        assert pat is not None
        # blocks in pattern order (contact jump, contact multiplier, then dilatancy) after the
        # step's coupling, Biot and flow blocks: the sums of pat.fill bit for bit
        data = pat.add(step.copy(), Block.CONTACT_JUMP, pat.take(Block.CONTACT_JUMP, contact_jump))
        pat.add(data, Block.CONTACT_MULTIPLIER, pat.take(Block.CONTACT_MULTIPLIER, contact_multiplier))
        pat.add(data, Block.DILATANCY, pat.take(Block.DILATANCY, dilatancy))
        if implicit is not None:
            pat.add(pat.add(data, Block.IMPLICIT_CONDUCTIVITY, pat.take(Block.IMPLICIT_CONDUCTIVITY, implicit[0])),
                    Block.FLOW, pat.take(Block.FLOW, -implicit[1]))
        Jac = pat.matrix(data)
        del data
        return Jac if self.layout is None else OwnedRows(Jac, self.layout)
