"""Mixed-dimensional poromechanics with frictional contact, monolithic semi-smooth Newton
(scheme.md §6).

One implicit-Euler step from (u^{n−1}, λ^{n−1}, p^{n−1}) solves, for the free displacement
dofs, the multipliers λ_σ and every flow unknown except Dirichlet pressures,

    A u + Σ_σ |σ| λ_σ·[[v]]_σ − G p = ℓ^n(v)                                 (equilibrium, §3)
    (|σ|/β)(λ_σ − P(λ_σ + β ([[u]]_n n, Δ[[u]]_τ))) = 0                      (contact, §4)
    Δt A_f(d_f^{n−1}) p − Δt r^n + G^T (u^n − u^{n−1}) + S_δ(p^n − p^{n−1}) = 0   (flow, §5–6)

with the coupling G (n_dofs, n_flow): G[:, K] = |K| b div^K(·) on cell pressures and
G[:, σ] = −|σ| [[·]]_σ·n⁺ on fracture pressures, so that −G p is the Biot term
−Σ_K |K| b p_K div^K v + Σ_σ |σ| p_f,σ [[v]]_σ·n⁺ and G^T δu the storage change
|K| b div^K δu of the cells and −|σ| [[δu]]_n = |σ| (d_f^n − d_f^{n−1}) of the fracture faces.
A_f is :meth:`FlowAssembler.full_matrix` (cells included, rows "storage + outflow" in m³/s)
with the conductivities C_f, Λ_f at d_f^{n−1}; r^n holds sources, Neumann fluxes and
the old storage. S_δ is the pressure stabilisation below.

**Pressure stabilisation (choice).** On simplices, away from fractures, the displacement
space is P1 and the matrix pressure P0: the pair is not inf-sup stable, and a sudden load
with a first step Δt ≪ h²/c_v (undrained response, drainage through one layer of cells)
gives a checkerboard pressure overshoot along the drained boundary (10 % of the undrained
pressure on triangles, 11 % on tetrahedra; none on the Cartesian column, which is 1D).
Following Rodrigo, Gaspar, Hu, Zikatanov (CMAME 298, 2016), the mass balance gets the
consistent perturbation −div(δ b² h²/(λ_L + 2μ) ∇∂_t p), discretised as a two-point
pressure-jump form S_δ on the cell pressures (:meth:`Poromechanics.stabilisation_matrix`):
the local jump stabilisation of the P1–P0 pair, with the Biot scaling b²/(λ_L + 2μ) that
the elimination of a displacement bubble would produce. It is symmetric positive
semi-definite and acts on the increment, so the energy estimate keeps holding with the extra
stored energy ½ S_δ(p, p) (models/energy.py); it is O(h²) on smooth solutions. Fracture faces
and ∂Ω are excluded: pressures may jump across Γ, and the drained boundary must not see an
extra outflow (the undrained response stays exact in the interior). Its flux does not depend
on the permeability, so each face weight is multiplied by the ratio of the harmonic to the
arithmetic mean of the two cells' normal permeabilities: it cannot carry fluid through a
barrier (C6's caprocks). δ = 1/4, the value of Rodrigo et al. in 1D (there h is the cell
size; here h_σ is the cells' width across σ, which is that size on Cartesian grids):
overshoot ≤ 0.12 % on triangles and tetrahedra, against 10–11 % without
(docs/poromechanics.md, "Small time steps: pressure stabilisation").

**Friction (choice, from the slides):** λ = −T⁺ with T⁺ = σ^T(u, p_m)⁺ n⁺ + p_f n⁺ is the
contact (effective) traction: λ_n = −σ^T_nn − p_f is the effective normal stress, and the
Coulomb law |λ_τ| ≤ F λ_n acts on it, on the slip increment Δ[[u]]_τ = [[u^n]]_τ − [[u^{n−1}]]_τ.

**Scaling.** Newton works on x = [u_free (m), λ̃ = λ/β (m), p̃ = p/s (m)] with each flow row
multiplied by −s (s per flow unknown in Pa/m, see :meth:`Poromechanics.pressure_scale`):
every diagonal entry of the Jacobian then has the size of the elastic block's
(~ (2μ + λ_L) h^{d−2}) and the Jacobian is symmetric whenever no fracture face slips (saddle
point: −S Δt A_f S in the flow block, S = diag(s)). The flow residual is measured per kind of
equation against the magnitudes of its own terms (docs/poromechanics.md, "Residual scaling").
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
import scipy.sparse as sp

from ..assembly.poro_system import (CELL, FACE, FRACTURE, FRACTURE_EDGE, N_KINDS, TRACE, CoupledJacobian,
                                    DilatancyEntries, FlowUnknowns, PressureStabilisation, biot_coupling)
from ..core.errors import InputError, RunError
from ..core.memory import int32_indices, trim_heap
from ..mesh import FracturedMesh
from ..solvers.block_jacobian import BlockJacobian
from ..parallel.layout import RowBlock, local_rows, owned_layout, register_layout
from ..solvers.factory import BlockProblem, SolverSource, build, coupled_solvers
from ..solvers.linear import release_solver
from ..solvers.newton import PREDICTORS, Linearisation, NewtonOptions, row_weights, semismooth_newton
from .contact import OPEN, SLIP, linearise_contact
from .fault_stress import normal_and_shear
from .energy import step_energy
from .friction import RateLaw
from .flow import FlowData, FlowModel, FlowSolution, _positive
from .implicit_conductivity import H as LAW_STEP, ImplicitConductivity
from .mechanics import ContactMechanics, MechanicsData

log = logging.getLogger("polypore")

# the smallest scale of a kind of flow equation, per row, as a fraction of the cell balances'
# (all flow rows are volumes, m³): floored_kind_scales
KIND_FLOOR = 1e-4


def floored_kind_scales(den: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Each flow kind's Σ T_i² (the "Residual scaling" denominators), floored at
    ``KIND_FLOOR``² × the cell balances' mean T_i² per row × the kind's row count.

    A kind without terms (the face, trace and fracture rows of a state at rest, whose unknowns are
    changes from the in-situ state, before anything flows) had its scale floored only at 1e-8 of
    the largest row scale of the whole system (``row_weights``): in the first Newton system of an
    injection its rows then weighed 1e8 times the cells' and the row-weighted GMRES stalled at a
    relative residual of 1 for the first 10–15 iterations, a stall that grew with the grid. Once
    anything flows the kinds' scales per row are 0.4 (faces), 10³–10⁴ (traces, fracture cells)
    and 2·10⁻⁴ … 10³ (fracture edges) of the cells' (weak-scaling grids), all above the floor:
    it only speaks where a kind has no terms of its own.

    Parameters
    ----------
    den : (5,) Σ T_i² per kind (cells first);  count : (5,) rows per kind

    Returns
    -------
    (5,) array
    """
    if count[0] == 0:
        return den
    return np.maximum(den, KIND_FLOOR ** 2 * den[0] / count[0] * count)

APERTURES = ("previous", "current")   # flow.conductivity_aperture: d_f^{n−1} (scheme.md §6) or d_f^n
# largest Δt/Δt_prev the predictor extrapolates over (the time loops double a sub-step at most)
PREDICTOR_REACH = 2.0
STABILISATION = 0.25   # default δ of the pressure-jump stabilisation (docs/poromechanics.md, docs/choices.md)


@dataclass
class PoroState:
    """A state of the coupled model at one time (all SI).

    Attributes
    ----------
    time : float, s
    u : (n_slots, d) nodal-side and bubble displacements, m
    lam : (n_ff, d) contact multipliers λ = −T⁺, Pa
    p : (n_flow,) every flow unknown in :class:`FlowDofs` order followed by the cell
        pressures (index ``dofs.n + K``), Pa
    aperture : (n_ff,) d_f = d_f^c − [[u]]_n, m
    state : (n_ff,) int8 contact state (OPEN / STICK / SLIP)
    friction : (n_c, k) the friction law's state per contact patch (`friction.py`; k = 0 for
        Coulomb and Tresca, the slip path for slip-weakening); None: the law's initial state
    flux_aperture : (n_ff,) aperture at which the step that produced this state evaluated
        C_f and Λ_f (d_f^{n−1}; the state's own aperture for an initial state), m: the fluxes
        built with it are the conservative ones
    stabilisation_flux : (n_pairs,) δ w_σ (δp_K − δp_L)/Δt of that step from K to L across the
        faces of the pressure stabilisation (:meth:`Poromechanics.stabilisation_matrix`),
        m³/s; None (zero) for an initial state
    """

    time: float
    u: np.ndarray
    lam: np.ndarray
    p: np.ndarray
    aperture: np.ndarray
    state: np.ndarray
    flux_aperture: np.ndarray | None = None
    stabilisation_flux: np.ndarray | None = None
    friction: np.ndarray | None = None

    def __post_init__(self):
        if self.flux_aperture is None:
            self.flux_aperture = self.aperture


@dataclass(eq=False)
class StepContext:
    """What is fixed during the Newton loop of one step t^{n−1} → t^n (scaled Newton unknowns).

    Attributes
    ----------
    loads : (n_dofs,) mechanical load vector at t^n, N
    u_dir, p_dir : (n_dofs,), (n_flow,) Dirichlet values at t^n (zero elsewhere), m and Pa
    flow_matrix, flow_rhs : the step's flow system Δt-scaled (:meth:`Poromechanics.flow_step_system`)
    u_old : (n_dofs,) displacements at t^{n−1}, m;  q_old : (n_c, d) patch jumps at t^{n−1}, m
    pressure_scale : (n_flow,) s, pressures in Newton's unknowns are p / s
    jacobian_step : the step's fixed Jacobian data (a pattern's data array, or blocks (G_up, G_pu
        data, F) with block solvers)
    abs_flow : |flow_matrix|;  terms_old : (n_flow,) magnitudes of the t^{n−1} terms per flow row
    slip_old : (n_ff,) regularised |[[u^{n−1} − u⁰]]_τ| with dilatancy, else None
    implicit_old : the implicit conductivities' reference (coefficients and Δt), else None
    friction_state : (n_c, k) the friction law's state at t^{n−1} (`friction.py`)
    dt : Δt, s
    """

    loads: np.ndarray
    u_dir: np.ndarray
    flow_matrix: object
    flow_rhs: np.ndarray
    p_dir: np.ndarray
    u_old: np.ndarray
    q_old: np.ndarray
    pressure_scale: np.ndarray
    jacobian_step: object
    abs_flow: object
    terms_old: np.ndarray
    slip_old: np.ndarray | None
    implicit_old: tuple | None
    friction_state: np.ndarray
    dt: float


@dataclass
class StepInfo:
    """Newton report of one step: iterations, final scaled residual, open/stick/slip counts,
    per-iteration history, seconds, the energy terms (:class:`EnergyTerms`) if computed and,
    with an iterative solver, the Krylov iterations of each Newton iteration."""

    iterations: int
    residual: float
    open: int
    stick: int
    slip: int
    history: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    energy: object = None
    linear_iterations: list = field(default_factory=list)
    conductivity_growth: float = 1.0    # :meth:`Poromechanics.conductivity_growth` of the step
    # a rate law's (local error estimate, patches where the step was too long for the state)
    # (friction.RateLaw.step_error); None for the other laws
    rate_error: tuple | None = None


class Poromechanics:
    """Coupled contact mechanics + mixed-dimensional HFV Darcy flow (scheme.md §6).

    Parameters
    ----------
    fm : FracturedMesh
    mech_data : MechanicsData
        Elasticity, Dirichlet/traction conditions (functions of t), contact law. Its
        ``matrix_pressure`` and ``fracture_pressure`` must be None: the pressures are unknowns.
    flow_data : FlowData
        Flow data; ``aperture`` is the closed aperture d_f^c (evaluated at t = 0) and
        ``biot_coefficient`` the b of both equations.
    flow_boundary, fracture_boundary, cell_source, fracture_source, alpha, fracture_alpha, cell_point :
        as in :class:`FlowModel` (time-dependent values are evaluated at t^n).
    solver : a ready solver or a :class:`~polypore.solvers.factory.SolverChoice`, optional
        Default sparse direct (pardiso if installed, else SuperLU); the auxiliary solvers follow
        from it (:func:`~polypore.solvers.factory.coupled_solvers`).
    newton : NewtonOptions, optional
    initial_traction : (n_ff, d) array, optional
        λ⁰ = −T⁺ of a reference (in-situ) state in equilibrium with loads that the run does not
        apply again, Pa: the run then computes increments (u, p) from that state, the
        contact law acts on the total λ and the equilibrium on λ − λ⁰.
    dilatancy : float or (n_ff,) array
        tan ψ of the dilatant aperture d_f = d_f^c − [[u]]_n + tan ψ |[[u − u⁰]]_τ| (C6),
        in the fracture storage (linearised in Newton) and, lagged, in the conductivities.
    pressure_stabilisation : float
        δ ≥ 0 (dimensionless) of the pressure-jump stabilisation of the mass balance
        (:meth:`stabilisation_matrix`); default 0.25, 0 switches it off.
    conductivity_aperture : "previous" or "current"
        the aperture of C_f and Λ_f in a step: d_f^{n−1} (scheme.md §6, the default) or the
        step's own d_f^n, linearised in Newton (:mod:`.implicit_conductivity`; one process only;
        not a case-file key yet: at a dilatant slip onset its Newton cycles, docs/fault_bounds.md).
    predictor : "linear" or "none"
        first Newton iterate of a step: the previous step's increment (u, λ, p) extrapolated to this
        Δt (:meth:`_predicted_start`), or the old state itself.
    """

    def __init__(self, fm: FracturedMesh, mech_data: MechanicsData, flow_data: FlowData,
                 flow_boundary: Mapping | None = None, *, fracture_boundary: Mapping | None = None,
                 cell_source=0.0, fracture_source=0.0, alpha=None, fracture_alpha=None,
                 solver: SolverSource = None, newton: NewtonOptions | None = None,
                 initial_traction=None, dilatancy=0.0, pressure_stabilisation: float = STABILISATION,
                 conductivity_aperture: str = "previous", predictor: str = "linear", cell_point: str = "auto"):
        t0 = time.perf_counter()
        if predictor not in PREDICTORS:
            raise InputError("predictor", f"must be one of {', '.join(PREDICTORS)}, got {predictor!r}")
        self.predictor = predictor
        if conductivity_aperture not in APERTURES:
            raise InputError("conductivity_aperture", f"must be one of {', '.join(APERTURES)}, got "
                             f"{conductivity_aperture!r}")
        self.conductivity_aperture = conductivity_aperture
        for key in ("matrix_pressure", "fracture_pressure"):
            if getattr(mech_data, key) is not None:
                raise InputError(key, "the coupled model computes p_m and p_f: leave matrix_pressure and "
                                 "fracture_pressure unset (the flow's sources and boundaries set the pressures)")
        self.fm = fm
        self.newton = newton or NewtonOptions(label="poromechanics Newton")
        # the initial equilibrium's and the flow model's solvers, and the coupled one (built once
        # the pattern's sizes are known: _setup_solver), all decided by solvers/factory.py
        solvers = coupled_solvers(solver)
        self._solver_source = solvers.coupled
        self.mech = ContactMechanics(fm, mech_data, solvers.mechanics, self.newton)
        self.flow = FlowModel(fm, flow_data, flow_boundary, fracture_boundary=fracture_boundary,
                              cell_source=cell_source, fracture_source=fracture_source, alpha=alpha,
                              fracture_alpha=fracture_alpha, cell_point=cell_point, solver=solvers.flow)
        self.dim = fm.mesh.dim
        self.n_ff = fm.network.n_faces
        self.biot = float(flow_data.biot_coefficient)
        self.closed_aperture = self.flow.aperture0              # d_f^c (n_ff,), m
        nf, d = fm.network.n_faces, fm.mesh.dim
        lam0 = np.zeros((nf, d)) if initial_traction is None else np.asarray(initial_traction, float)
        if lam0.shape != (nf, d) or not np.all(np.isfinite(lam0)):
            raise InputError("initial_traction", f"expected finite values of shape ({nf}, {d}) (Pa), got {lam0.shape}")
        self.lam0 = lam0                                        # λ⁰ = −T⁺ of the reference state, Pa
        tpsi = np.broadcast_to(np.asarray(dilatancy, float), (nf,)).copy()
        if not np.all((tpsi >= 0) & np.isfinite(tpsi)):
            raise InputError("dilatancy", "tan ψ must be finite and ≥ 0")
        self.tan_psi = tpsi                                     # tan ψ (n_ff,), dimensionless
        self.u_ref: np.ndarray | None = None                    # u⁰ of the dilatancy law, set by initial_state
        self.asm = self.flow.assembler
        self.dofs = self.asm.dofs
        self.n_flow = self.dofs.n + fm.mesh.n_cells
        self._coupling_sign = 1.0   # −1 only in tests: a deliberately wrong Biot sign the energy check must catch
        self._last_newton: int | None = None    # Newton iterations of the last step (the first solve's forcing)
        self._last_settled = False              # the last step left every face state as it found it
        # (end state, Δu, Δλ per patch, Δp, Δt) of the last two converged steps: the predictor's
        # increments, found by the identity of the state a step starts from (a step redone from an
        # earlier state, after a rejection, finds its own)
        self._increments: list[tuple] = []
        self._setup_coupling()
        self._setup_stabilisation(pressure_stabilisation)
        self._setup_flow_dofs()
        self._setup_pattern()
        trim_heap()                 # the set-up's temporaries (core/memory.py)
        self.seconds_setup = time.perf_counter() - t0
        log.info("poromechanics: %d free displacement dofs, %d multipliers, %d free pressures; set up in %.2f s",
                 self.mech.free.size, self.mech.n_c * self.dim, self.flow_free.size, self.seconds_setup)

    # ---- set-up -------------------------------------------------------------------------
    def _setup_coupling(self):
        """G (n_dofs, n_flow) (:func:`~polypore.assembly.poro_system.biot_coupling`), b ∫_K div v on
        cells and −|σ| [[·]]·n⁺ on fracture pressures; its rows under mpiexec."""
        mech = self.mech
        G = biot_coupling(mech.ops.D, mech.ops.qp_cell, mech.ops.qp_weight, self.biot, mech.jump_scalar,
                          mech.face_area, mech.normal, self.dofs.frac, self.dofs.n, mech.n_dofs, self.n_flow)
        # the constant parts of pressure_scale, from the whole G (before it is cut to rows)
        a = mech.A.diagonal()[mech.free]
        self._elastic_diag = float(np.mean(a))                     # (2μ + λ_L) h^{d−2}, N/m (Pa in 2D)
        Gf = G[mech.free]
        self._biot_diag = Gf.multiply(Gf).T @ (1.0 / a)             # diag(Gᵀ diag(A)⁻¹ G), m³/Pa (m²/Pa in 2D)
        # under mpiexec each rank keeps its rows of G (displacement dofs) and Gᵀ (flow unknowns)
        self.flow_layout = owned_layout(self.fm.mesh, lambda part: np.concatenate([self.flow.dof_owner(part), part]))
        self.G = RowBlock.of(G, mech.dof_layout)
        # on one process Gᵀ is G's transposed view (csc), not a copy
        self.GT = G.T if self.flow_layout is None else RowBlock.of(int32_indices(G.T.tocsr()), self.flow_layout)

    def _setup_stabilisation(self, delta):
        """Face pairs and weights of the pressure-jump stabilisation (:meth:`stabilisation_matrix`)."""
        try:
            delta = float(delta)
        except (TypeError, ValueError):
            raise InputError("pressure_stabilisation", f"must be a number ≥ 0, got {delta!r}") from None
        if not (np.isfinite(delta) and delta >= 0):
            raise InputError("pressure_stabilisation", f"must be a finite number ≥ 0, got {delta}")
        self.stabilisation = delta
        g = self.fm.mesh.geometry
        self.stab = PressureStabilisation.build(delta, self.asm.cell_pairs(), g.face_area, g.face_normal,
                                                2 * self.mech.mu + self.mech.lam, self.biot, self.flow.permeability,
                                                self.dofs.n, self.n_flow)

    def stabilisation_matrix(self) -> sp.csr_array:
        """S_δ (n_flow, n_flow), m³/Pa: the pressure-jump stabilisation of the mass balance.

        S_δ(p, q) = Σ_σ w_σ (p_K − p_L)(q_K − q_L) over the interior faces σ = K|L that are not
        fracture faces, on cell pressures only, with the two-point transmissibility of
        −div(κ ∇·), κ = δ b² h_σ²/(λ_L + 2μ) taken per side, times a permeability factor:

            w_σ = δ b² |σ| h_σ² / (d_Kσ (λ_L + 2μ)_K + d_Lσ (λ_L + 2μ)_L) × 4 k_K k_L/(k_K + k_L)²,

        d_Kσ the distance from x_K to σ's plane, h_σ = (h_Kσ + h_Lσ)/2 the mean width of the
        two cells across σ (:meth:`FlowAssembler.cell_pairs`; on a uniform Cartesian grid
        w_σ = δ b² |σ| h/(λ_L + 2μ), Rodrigo et al.'s h²/(4(λ_L + 2μ)) Δ∂_t p for δ = 1/4) and
        k_K = n_σ·K_K n_σ. The step adds S_δ(p^n − p^{n−1}, q) to the Δt-scaled mass balances
        (m³ per step).
        """
        return self.stab.matrix()

    @property
    def stabilisation_pairs(self) -> np.ndarray:
        """(n_pairs, 2) cells (K, L) of the faces of S_δ."""
        return self.stab.pairs

    @property
    def stabilisation_weights(self) -> np.ndarray:
        """(n_pairs,) δ w_σ of S_δ, m^d/Pa."""
        return self.stab.weights

    def stabilisation_jumps(self, p: np.ndarray) -> np.ndarray:
        """(n_pairs,) p_K − p_L across the faces of S_δ (``stabilisation_pairs``) for a (n_flow,)
        pressure vector, Pa; S_δ(p, q) = Σ ``stabilisation_weights`` × jumps(p) × jumps(q)."""
        return self.stab.jumps(p)

    def _setup_flow_dofs(self):
        """The flow unknowns (every flow dof but the Dirichlet pressures, whose set does not depend
        on t) and the one structure of the step matrix Δt A_f + S_δ (:class:`FlowUnknowns`)."""
        ids, _, _ = self.flow.dirichlet(0.0)
        nf = self.n_ff
        Af = self.asm.full_matrix(np.ones(self.fm.mesh.n_cells), np.ones(nf), np.ones(nf), np.zeros(nf))
        self.unknowns = FlowUnknowns.build(ids, Af, self.stab.rc(), self.dofs, self.n_flow, self.flow_layout)
        self.flow_fixed, self.flow_free = self.unknowns.fixed, self.unknowns.free
        self.flow_free_index = self.unknowns.free_index

    def _setup_pattern(self):
        """The step Jacobian's structure, built once (:class:`~polypore.assembly.poro_system.CoupledJacobian`):
        every block's (row, col) contributions restricted to unknowns (on N ranks this rank's rows,
        distributed numbering), or with a block solver on one process the pressure blocks' own
        patterns (the (u, λ) blocks are the mechanics model's)."""
        mech, d, nf = self.mech, self.dim, self.n_ff
        nfree = mech.free.size
        nl = mech.n_c * d
        self.layout = owned_layout(self.fm.mesh, self.dof_owner)    # None serially
        self.n_unknowns = nfree + nl + self.flow_free.size
        self._setup_scaling()
        self._setup_solver()
        # the Jacobian goes to the solver by blocks (a block solver on one process; no assembled
        # matrix: solvers/block_jacobian.py); decided here, for the model's lifetime (a solver
        # wrapped later, e.g. by benchmarks/dump_jacobians.py, gets what this one got)
        self.blockwise = bool(self.solver.takes_blocks) and self.layout is None
        self._implicit = None
        if self.conductivity_aperture == "current" and self.n_ff:
            if self.layout is not None or self.flow_layout is not None:
                raise InputError("conductivity_aperture", "\"current\" runs on one process only; use "
                                 "\"previous\" (the default) under mpiexec")
            afp = self.unknowns.pattern
            self._implicit = ImplicitConductivity(self.asm.fracture_contributions(),
                                                  afp.pattern.slot[afp.starts[0]:afp.starts[1]],
                                                  self.flow_free_index, mech.jump_scalar, mech.free_index, d)
        imp_rc = self._implicit.rc if self._implicit is not None else (np.zeros(0, np.int64),) * 2
        # G: u rows × p columns (the rows of G this rank keeps), and p rows × u columns from the
        # rows of Gᵀ it keeps: the same values, so that each rank has its rows of both blocks
        G = local_rows(self.G).tocoo()
        grow = G.row if mech.dof_layout is None else mech.dof_layout.owned[G.row]
        gr, gc = mech.free_index[grow], self.flow_free_index[G.col]
        kg = (gr >= 0) & (gc >= 0)
        T = local_rows(self.GT).tocoo()
        trow = T.row if self.flow_layout is None else self.flow_layout.owned[T.row]
        tr, tc = self.flow_free_index[trow], mech.free_index[T.col]
        kt = (tr >= 0) & (tc >= 0)
        frac_free = self.flow_free_index[self.dofs.frac] if nf else np.zeros(0, np.int64)
        self._dil = DilatancyEntries.build(mech.jump_scalar, mech.free_index, frac_free, d)
        # the mechanics' (u, λ) blocks are built inside the call: the jacobian drops its (row,
        # col) lists (int64 per contribution) once the pattern is built
        self.jacobian = CoupledJacobian(None if self.blockwise else mech.jacobian_blocks(mech.c_jump.tocoo()),
                                        mech.contact_jump_entries, (gr[kg], gc[kg], G.data[kg]),
                                        (tr[kt], tc[kt], T.data[kt]), self._dil, imp_rc, self.unknowns, nfree, nl,
                                        self.layout, self.blockwise)
        del G, T                           # coo copies of the coupling blocks
        if self.layout is not None:
            register_layout(self.solver, self.layout)

    def _setup_solver(self):
        """The coupled solver, once: the one given, or built from the choice
        (:func:`~polypore.solvers.factory.build`; a block backend from :meth:`block_problem`)."""
        self.solver = build(self._solver_source, self.block_problem)
        self._solver_source = None

    def block_problem(self) -> BlockProblem:
        """The step system as the block solvers see it (:mod:`polypore.solvers.factory`): the
        mechanics' blocks, and the two-level pressure preconditioner's coarse unknowns (cell and
        fracture-cell pressures) and the fracture subsystem its smoother solves exactly (fracture
        cells, fracture edges, traces); kinds as in block_counts."""
        mech, k = self.mech, self.unknowns.kind
        return BlockProblem(mech.free.size, self.dim, mech.n_c * self.dim, mech.condensation(), mech.rigid_modes(),
                            pressure_groups=(np.isin(k, (CELL, FRACTURE)),
                                             np.isin(k, (TRACE, FRACTURE, FRACTURE_EDGE))), coupled=True)

    def release_solver(self) -> None:
        """Free the linear solver's matrices and preconditioner set-ups (PETSc's, where it has any)
        and return the freed heap: after the last step, before the outputs. A later step sets the
        solver up again (:func:`~polypore.solvers.linear.release_solver`)."""
        release_solver(self.solver)

    def dof_owner(self, part: np.ndarray) -> np.ndarray:
        """(n_unknowns,) owner rank of every step unknown [free u, λ̃, free pressures] for the cell
        ranks ``part``: the mechanics' and the flow's rules, a cell pressure its cell's."""
        flow = np.concatenate([self.flow.dof_owner(part), part])[self.flow_free]
        return np.concatenate([self.mech.dof_owner(part), flow])

    # ---- scaling and step coefficients ----------------------------------------------------
    def _setup_scaling(self):
        """The flow residual norm's parts (:meth:`_setup_coupling` has those of :meth:`pressure_scale`;
        the equation kinds are the flow unknowns', :class:`FlowUnknowns`)."""
        GT = self.GT
        # |Gᵀ| shares Gᵀ's index arrays (a RowBlock's __abs__ does so too)
        self._abs_GT = abs(GT) if isinstance(GT, RowBlock) else \
            type(GT)((np.abs(GT.data), GT.indices, GT.indptr), shape=GT.shape)

    def block_counts(self) -> dict:
        """Unknowns per block (summary.json ``mesh.blocks``): free displacement dofs at points
        (nodes; with order 2 also edge points) and on face bubbles, multipliers (patches × d),
        and the free pressures by equation kind (cells, faces, matrix–fracture traces, fracture
        faces, fracture edges), plus the total per cell."""
        mech, d = self.mech, self.dim
        npt = mech.space.n_point_slots * d
        k = self.unknowns.kind_count
        out: dict[str, float] = {"displacement_points": int(np.count_nonzero(mech.free < npt)),
               "displacement_bubbles": int(np.count_nonzero(mech.free >= npt)),
               "multipliers": int(mech.n_c * d),
               "pressure_cells": int(k[CELL]), "pressure_faces": int(k[FACE]), "pressure_traces": int(k[TRACE]),
               "pressure_fractures": int(k[FRACTURE]), "pressure_fracture_edges": int(k[FRACTURE_EDGE])}
        out["per_cell"] = round(sum(out.values()) / max(self.fm.mesh.n_cells, 1), 3)
        return out

    def pressure_scale(self, A_dt) -> np.ndarray:
        """(n_flow,) s in Pa/m with p = s p̃ per flow unknown: a symmetric diagonal scaling.

        s_i = √(ā / D_i) with ā the mean diagonal entry of the elastic matrix (over free dofs)
        and D_i = (Δt A_f)_ii + (Gᵀ diag(A)⁻¹ G)_ii, m³/Pa (m²/Pa in 2D): the flow diagonal
        (storage, fluxes, exchange, stabilisation) plus the diagonal of the Biot Schur complement
        of the displacement. Every diagonal entry of the scaled pressure block, the displacement
        eliminated, is then ā. One s per unknown, not per kind of unknown: a fracture edge with
        conductivity C_f/η ~ 1e-10 m³/(Pa·s) next to a matrix with k/η ~ 1e-19 m²/(Pa·s) gave
        the per-kind scaling a Jacobian condition number of 1e16–1e17 (3e10–3e11 with this
        one). D_i > 0 whenever k > 0, for any b ≥ 0 and 1/M ≥ 0; it is bounded below by
        1e-30 max D only to keep s finite for an unknown without any coefficient.

        Parameters
        ----------
        A_dt : sparse (n_flow, n_flow) the step's flow matrix (:meth:`flow_step_system`; a RowBlock
            on N ranks), m³/Pa
        """
        D = A_dt.diagonal() + self._biot_diag
        D = np.maximum(D, 1e-30 * max(float(D.max(initial=0.0)), 1e-300))
        return np.sqrt(self._elastic_diag / D)

    def conductivities(self, aperture: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(|σ| Λ_f/η, C_f/η) at the given aperture (n_ff,) each, m³/(Pa·s)."""
        data = self.flow.data
        area = self.mech.face_area
        lam = np.broadcast_to(np.asarray(data.normal_transmissivity_law(aperture, self.flow.normal_permeability),
                                         float), aperture.shape)
        cond = np.broadcast_to(np.asarray(data.conductivity_law(aperture), float), aperture.shape)
        if not (np.all(lam > 0) and np.all(np.isfinite(lam))):
            raise InputError("normal_transmissivity_law", "must return positive finite values (m)")
        if not (np.all(cond >= 0) and np.all(np.isfinite(cond))):
            raise InputError("conductivity_law", "must return non-negative finite values (m³)")
        return area * lam / self.flow.viscosity, cond / self.flow.viscosity

    def conductivity_growth(self, before: np.ndarray, after: np.ndarray) -> float:
        """Largest C_f(after)/C_f(before) over the fracture faces that carry flow after (C_f at
        least 1e-3 of the largest), 1.0 without fractures; apertures (n_ff,) in m.

        The step's fluxes use C_f(d_f^{n−1}) (scheme.md §6), a first-order time error whose
        constant is this growth: where dilatancy or opening raises C_f by orders of magnitude in
        one step (a slip onset: 10 µm → 6 mm, ×2e8), the fault conducts one step late and the
        slip depends on the step (docs/fault_bounds.md, "The time step")."""
        if not self.n_ff:
            return 1.0
        c0 = self.conductivities(np.asarray(before, float))[1]
        c1 = self.conductivities(np.asarray(after, float))[1]
        big = c1 >= 1e-3 * c1.max(initial=0.0)
        if not np.any(big & (c1 > 0)):
            return 1.0
        return float(np.max(c1[big] / np.maximum(c0[big], 1e-300 * c1.max())))

    def flow_step_system(self, old: PoroState, dt: float, t: float):
        """Δt-scaled flow matrix and right-hand side of the step (scheme.md §5–6).

        Returns
        -------
        A_dt : csr (n_flow, n_flow), Δt A_f(d_f^{n−1}) + S_δ with storage |K|/M and |σ| d_f^{n−1} c_f
            and the pressure-jump stabilisation S_δ (:meth:`stabilisation_matrix`), m³/Pa; on N
            ranks a :class:`~polypore.parallel.layout.RowBlock` of this rank's rows
        r_dt : (n_flow,) Δt × (sources + old storage − Neumann outflow) + S_δ p^{n−1}, m³ (coupling
            excluded)
        p_dir : (n_flow,) Dirichlet pressures at t on fixed dofs, 0 elsewhere, Pa
        """
        g = self.fm.mesh.geometry
        area = self.mech.face_area
        s_cell = g.cell_volume / (self.flow.biot_modulus * dt)
        s_frac = area * old.aperture * float(self.flow.data.fracture_compressibility) / dt
        ex, fc = self.conductivities(old.aperture)
        Af = self.asm.full_matrix(s_cell, ex, fc, s_frac)
        # the stabilisation acts on the increment: S_δ p^n in the matrix, S_δ p^{n−1} on the right
        A_dt = self.unknowns.step_matrix(Af.data * dt, self.stab.values())
        if self.flow_layout is not None:
            A_dt = RowBlock(A_dt, self.flow_layout)
        ids, vals, qflux = self.flow.dirichlet(t)
        hm, hf = self.flow.sources(t)
        d = self.dofs
        r = np.zeros(self.n_flow)
        r[d.n:] = hm + s_cell * old.p[d.n:]
        r[d.frac] = hf + s_frac * old.p[d.frac]
        ok = d.face >= 0
        r[d.face[ok]] -= qflux[ok]
        r_dt = r * dt
        r_dt += self.stab.apply(old.p)                                         # S_δ p^{n−1}
        p_dir = np.zeros(self.n_flow)
        p_dir[ids] = vals
        return A_dt, r_dt, p_dir

    def injection_rate(self, t: float) -> float:
        """The fluid volume injected per second at t, m³/s (m²/s per metre in 2D): the cell and
        fracture sources (wells included) plus the inflow through rate and flux boundaries, as
        the step ending at t takes them (:meth:`flow_step_system`); < 0 where production wins.
        Pressure boundaries are not injection and are left out."""
        _, _, qflux = self.flow.dirichlet(t)
        hm, hf = self.flow.sources(t)
        ok = self.dofs.face >= 0
        return float(hm.sum() + hf.sum() - qflux[ok].sum())

    def load_vector(self, t: float) -> np.ndarray:
        """(n_dofs,) ℓ(t) + Σ_σ |σ| λ⁰·[[v]]_σ: the loads of the increment problem, N (N/m in 2D).

        With λ⁰ the reference traction, the equilibrium reads A u + Bᵀ(λ − λ⁰) − G p = ℓ."""
        F = self.mech.load_vector(t)
        if self.n_ff and np.any(self.lam0):
            # λ⁰ as the multiplier space holds it (its patch means): the reference state, u = 0 and
            # λ = λ⁰, is then an equilibrium of the discrete problem
            mech = self.mech
            F = F + mech.Bcv.T @ mech.patch_values(self.lam0).ravel()
        return F

    def tangential_slip(self, q: np.ndarray):
        """(|[[u − u⁰]]_ε,τ| (n_ff,), its derivative direction (n_ff, d)) from the jumps q (n_ff, d), m.

        |x|_ε = √(|x|² + ε²) − ε with ε = 10⁻³ d_f^c: the plain norm's derivative x/|x| is a
        unit vector of arbitrary direction on a face that has not slipped (x at round-off),
        and Newton then cycles between stick and slip where dilatancy hardening holds a face at
        the Coulomb limit (C6, at slip onset). The aperture differs by at most ε tan ψ."""
        n = self.mech.normal
        q_ref = self.jumps(self.u_ref) if self.u_ref is not None else 0.0
        r = q - q_ref
        rt = r - np.einsum("fi,fi->f", r, n)[:, None] * n
        eps = 1e-3 * self.closed_aperture
        root = np.sqrt(np.einsum("fi,fi->f", rt, rt) + eps * eps)
        return root - eps, rt / root[:, None]

    # ---- states ----------------------------------------------------------------------------
    def jumps(self, u: np.ndarray) -> np.ndarray:
        """(n_ff, d) mean jumps [[u]]_σ, m."""
        return self.mech.jump_scalar @ u

    def aperture_of(self, u: np.ndarray) -> np.ndarray:
        """(n_ff,) d_f = d_f^c − [[u]]_n + tan ψ |[[u − u⁰]]_τ| (scheme.md §1, C6), m."""
        return self._aperture_and_gradient(u)[0]

    def _aperture_and_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(d_f (n_ff,) in m, ∂d_f/∂[[u]]_σ (n_ff, d) = −n + tan ψ ∂|[[u − u⁰]]_τ|_ε/∂[[u]])."""
        n = self.mech.normal
        if not self.n_ff:
            return np.zeros(0), np.zeros((0, self.dim))
        q = self.jumps(u)
        d_f = self.closed_aperture - np.einsum("fi,fi->f", q, n)
        grad = -n.copy()
        if np.any(self.tan_psi > 0):
            rel, e = self.tangential_slip(q)
            d_f = d_f + self.tan_psi * rel
            grad += self.tan_psi[:, None] * e
        return d_f, grad

    def initial_state(self, p0, u0=None, t0: float = 0.0, verbose: bool = False) -> PoroState:
        """State at t0 with every pressure from ``p0`` (number or f(x, y, z, t)).

        ``u0=None`` computes (u, λ) in equilibrium with p0 and the loads at t0 (static
        contact problem, friction on [[u]]_τ); otherwise ``u0`` (n_slots, d) or a field
        f(X, t) (interpolated, scheme.md §3) is used with λ = 0.
        """
        sol = self.flow.initial_state(p0, t0)
        p = self.pressure_vector(sol)
        mech = self.mech
        d = self.dim
        if u0 is None:
            F = self.load_vector(t0) + self.G @ p
            udir = mech.dirichlet_vector(t0)
            nfree = mech.free.size
            x0 = np.zeros(nfree + mech.n_c * d)
            x0[nfree:] = mech.closed_start(F)
            res = semismooth_newton(lambda x: mech.linearise(x, F, udir, None), x0, mech.solver,
                                    lambda dx, x: float(np.linalg.norm(dx)
                                                        / max(float(np.linalg.norm(x + dx)), 1e-300)),
                                    NewtonOptions(**{**self.newton.__dict__, "label": "initial equilibrium"}), verbose)
            u, lam = mech.split(res.x, udir)
            assert res.active_set is not None          # a contact Newton reports its states
            lam, state = mech.face_values(lam), mech.face_values(res.active_set)
            u = u.reshape(-1, d)
            # the contact Jacobian's pattern, and the contact solver's PETSc matrices and AMG, are
            # not needed by the steps
            mech.release_assembly()
            if mech.solver is not self.solver:
                mech.release_solver()
        else:
            u = np.asarray(mech.interpolate(u0, t0) if callable(u0) else u0, float).reshape(-1, d)
            lam = np.zeros((self.n_ff, d))
            state = np.full(self.n_ff, OPEN, np.int8)
        self.u_ref = u.copy()
        return PoroState(float(t0), u, lam, p, self.aperture_of(u), np.asarray(state, np.int8),
                         friction=mech.start_friction(lam))

    def reference_state(self, p0, t0: float = 0.0) -> PoroState:
        """The reference (in-situ) state itself: u = Dirichlet values, λ = λ⁰, pressures from p0
        (Pa, relative to the reference pressure). Raises RunError if λ⁰ violates the contact
        law (the reference state would not be an equilibrium)."""
        sol = self.flow.initial_state(p0, t0)
        p = self.pressure_vector(sol)
        mech, d = self.mech, self.dim
        u = mech.dirichlet_vector(t0).reshape(-1, d)
        self.u_ref = u.copy()
        mech.release_assembly()                 # no contact solve: the steps do not need it
        zero = np.zeros((mech.n_c, d))
        lam0 = mech.patch_values(self.lam0)
        state = linearise_contact(mech.law, lam0, zero, zero, mech.c_normal, mech.c_area)[3]
        if self.n_ff:
            ln = np.einsum("fi,fi->f", lam0, mech.c_normal)
            lt = np.linalg.norm(lam0 - ln[:, None] * mech.c_normal, axis=1)
            bad = (state == SLIP) | ((state == OPEN) & (np.abs(lam0).max(axis=1) > 0))
            if np.any(bad):
                raise RunError(f"the reference stress is not an equilibrium of the contact law on {int(bad.sum())} "
                               f"fracture face(s): tension or |λ_τ| > F λ_n (largest |λ_τ| / λ_n = "
                               f"{float(np.max(lt[bad] / np.maximum(ln[bad], 1e-300))):.3g}); lower the stress "
                               "ratio's deviation or raise the friction")
        lam = mech.face_values(lam0).copy()
        return PoroState(float(t0), u, lam, p, self.aperture_of(u), np.asarray(mech.face_values(state), np.int8),
                         friction=mech.start_friction(lam))

    def pressure_vector(self, sol: FlowSolution) -> np.ndarray:
        """(n_flow,) the unknown vector of a FlowSolution (FlowDofs order, then cells)."""
        d = self.dofs
        p = np.zeros(self.n_flow)
        ok = d.face >= 0
        p[d.face[ok]] = sol.face[ok]
        p[d.trace] = sol.trace
        p[d.frac] = sol.fracture
        p[d.edge] = sol.edge
        p[d.n:] = sol.cell
        return p

    # ---- Newton --------------------------------------------------------------------------------
    def _split(self, x, udir, p_dir, s):
        mech, d = self.mech, self.dim
        nfree = mech.free.size
        nl = mech.n_c * d
        u = udir.copy()
        u[mech.free] = x[:nfree]
        lam = x[nfree:nfree + nl].reshape(mech.n_c, d) * mech.law.beta[:, None]     # per patch
        p = p_dir.copy()
        p[self.flow_free] = s[self.flow_free] * x[nfree + nl:]
        return u, lam, p

    def _linearise(self, x, ctx) -> Linearisation:
        mech, d, nf = self.mech, self.dim, self.n_ff
        F, udir, A_dt, r_dt, p_dir = ctx.loads, ctx.u_dir, ctx.flow_matrix, ctx.flow_rhs, ctx.p_dir
        u_old, q_old, s, j_step = ctx.u_old, ctx.q_old, ctx.pressure_scale, ctx.jacobian_step
        abs_A, terms_old, rel_old, imp_old = ctx.abs_flow, ctx.terms_old, ctx.slip_old, ctx.implicit_old
        u, lam, p = self._split(x, udir, p_dir, s)
        qc = (mech.Jcv @ u).reshape(mech.n_c, d)                     # patch-mean jumps (contact rows)
        C, dC_dlam, dC_dq, state = linearise_contact(mech.law, lam, qc, qc - q_old, mech.c_normal, mech.c_area,
                                                     ctx.friction_state, ctx.dt)
        imp_vals = imp_dpp = None
        if imp_old is not None:
            A_dt, abs_A, imp_vals, imp_dpp = self._implicit_terms(u, p, s, A_dt, imp_old)
        cs = self._coupling_sign
        # on N ranks A, G, Gᵀ, A_dt and the |·| are RowBlocks: each product is this rank's rows and
        # an Allgatherv, the serial values bit for bit (parallel/layout.py)
        Gp = self.G @ p
        Au, Bl = mech.A @ u, mech.Bcv.T @ lam.ravel()
        Ru = Au + Bl - cs * Gp - F
        Gdu = self.GT @ (u - u_old)
        Ap = A_dt @ p
        Rf = Ap - r_dt + Gdu
        terms = abs_A @ np.abs(p) + self._abs_GT @ np.abs(u) + terms_old        # Σ |terms| of each flow row
        dil_vals = np.zeros(0)
        if nf and np.any(self.tan_psi > 0):
            # dilatancy acts per face, on the faces' (patch) jumps; the old slip is the step's
            rel, that = self.tangential_slip(self.jumps(u.reshape(-1, d)))
            w = mech.face_area * self.tan_psi
            Rf[self.dofs.frac] += w * (rel - rel_old)
            terms[self.dofs.frac] += w * rel
            dil_vals = self._dil.values(s[self.dofs.frac] * w, that)
        elif nf:
            dil_vals = self._dil.zeros()
        b = mech.law.beta
        jrow, jval, keep = self.jacobian.contact_entries
        cu = (dC_dq[jrow] * (jval * b[jrow])[:, None, None])[keep]
        cl = dC_dlam * (b * b)[:, None, None]
        implicit = None if imp_vals is None else (imp_vals, imp_dpp)
        if self.blockwise:
            Jm = mech.jacobian_by_blocks(cu, cl)
            Jac = BlockJacobian(Jm.uu, Jm.ul, Jm.lu, Jm.ll, *self.jacobian.iterate(j_step, cu, cl, dil_vals, implicit))
        else:
            Jac = self.jacobian.iterate(j_step, cu, cl, dil_vals, implicit)
        free, ff = mech.free, self.flow_free
        su = max(float(np.linalg.norm(F)), float(np.linalg.norm(Au)), float(np.linalg.norm(Bl)),
                 float(np.linalg.norm(Gp)), 1e-300)
        # flow: each kind of equation against the sum of the magnitudes of its own terms (docs/
        # poromechanics.md, "Residual scaling"); net sums such as ‖A_f p‖ cancel (b = 0, or the
        # exchange of a fracture at the matrix's pressure) and left Newton stuck at ratios 1e-7 … 1
        kind = self.unknowns.kind
        num = np.bincount(kind, Rf[ff] ** 2, minlength=N_KINDS)
        den = np.bincount(kind, terms[ff] ** 2, minlength=N_KINDS)
        den = floored_kind_scales(den, self.unknowns.kind_count)
        flow = float(np.sqrt(np.max(num / np.maximum(den, 1e-300)))) if ff.size else 0.0
        norms = {"equilibrium": float(np.linalg.norm(Ru[free]) / su), "flow": flow}
        if nf:
            sc = max(float(np.linalg.norm(mech.c_area[:, None] * qc)),
                     float(np.linalg.norm((mech.c_area / b)[:, None] * lam)), 1e-300)
            norms["contact"] = float(np.linalg.norm(C) / sc)
        counts = mech.state_counts(state) if nf else {}
        res = np.concatenate([Ru[free], (C * b[:, None]).ravel(), -s[ff] * Rf[ff]])
        # row weights of Newton's measure (solvers/newton.py): a flow row −s_i Rf_i of kind k
        # counts as Rf_i/√den_k, the kind's norm above (kinds summed in the 2-norm, not maxed)
        w = row_weights(np.full(free.size, su), np.repeat(b * sc, d) if nf else np.zeros(0),
                        s[ff] * np.sqrt(np.maximum(den, 1e-300))[kind])
        # the dilatant aperture is smooth, not piecewise linear: a step that keeps the contact
        # states is not exact, and convergence needs a small increment as well
        return Linearisation(res, Jac, norms, counts, state, row_scale=w,
                             piecewise_linear=not (nf and (np.any(self.tan_psi > 0) or imp_old is not None)))

    def _implicit_terms(self, u, p, s, A_dt, old):
        """The step matrix at the iterate's conductivities and the implicit terms' Jacobian parts
        (:mod:`.implicit_conductivity`): C_f and Λ_f at max(d_f(u), d_f^c) (a converged state has
        d_f ≥ d_f^c; an iterate below it gets the closed conductivities and no derivative).

        Returns
        -------
        A : csr (n_flow, n_flow) Δt A_f(d_f) + S_δ on A_dt's structure, m³/Pa
        abs_A : |A| (the flow rows' term magnitudes)
        pu : values of the p × u entries (the pattern's block of ``ImplicitConductivity.rc``)
        dpp : change of the free–free flow entries of the scaled Jacobian (−dpp is added)
        """
        ex0, fc0, dt = old
        d_raw, grad = self._aperture_and_gradient(u.reshape(-1, self.dim))
        ap = np.maximum(d_raw, self.closed_aperture)
        ex, fc = self.conductivities(ap)
        # central differences of the (possibly user-given) laws, relative step LAW_STEP
        hi, lo = self.conductivities(ap * (1 + LAW_STEP)), self.conductivities(ap * (1 - LAW_STEP))
        h2 = 2 * LAW_STEP * ap
        grad[d_raw < self.closed_aperture] = 0.0
        imp = self._implicit
        dA = imp.matrix_change(ex0, fc0, ex, fc, dt, A_dt.data.size)
        A = sp.csr_array((A_dt.data + dA, A_dt.indices, A_dt.indptr), shape=A_dt.shape)
        abs_A = sp.csr_array((np.abs(A.data), A_dt.indices, A_dt.indptr), shape=A_dt.shape)
        pu = imp.coupling_values(p, (hi[0] - lo[0]) / h2, (hi[1] - lo[1]) / h2, grad, s, dt)
        ar, ac = self.unknowns.rc
        sf = s[self.flow_free]
        return A, abs_A, pu, dA[self.unknowns.keep] * sf[ar] * sf[ac]

    def friction_state(self, st: PoroState) -> np.ndarray:
        """(n_c, k) the friction law's state of ``st`` (the law's initial state if it has none)."""
        return self.mech.friction_state(st.friction)

    def friction_fields(self, st: PoroState) -> dict[str, np.ndarray]:
        """The friction law's state of ``st`` as named (n_ff,) face values (outputs; empty for a law
        without state)."""
        fl = self.mech.law.friction_law
        return {k: self.mech.face_values(v) for k, v in fl.state_fields(self.friction_state(st)).items()}

    def step_context(self, old: PoroState, dt: float, t: float) -> tuple[StepContext, np.ndarray]:
        """Everything fixed during the Newton loop of the step old → t (:class:`StepContext`), and
        the first iterate x0 (the old state with the new Dirichlet data). ``self._linearise(x,
        ctx)`` is the residual and Jacobian at x."""
        mech, d = self.mech, self.dim
        F = self.load_vector(t)
        udir = mech.dirichlet_vector(t)
        A_dt, r_dt, p_dir = self.flow_step_system(old, dt, t)
        s = self.pressure_scale(A_dt)
        u_old = old.u.ravel()
        q_old = (mech.Jcv @ u_old).reshape(mech.n_c, d)             # patch jumps of the old state
        sf = s[self.flow_free]
        # the AMG of the pressure Schur block needs the scaled image of a constant pressure
        self.solver.set_pressure_nullspace(1.0 / sf)
        af_vals = self.unknowns.scaled_free_values(local_rows(A_dt).data, sf)   # rows and columns scaled by s
        # magnitudes of the flow terms at t^{n−1} (the old storage, the old displacement's part of
        # the Biot term, Δt A_f p^{n−1}): the round-off of a Newton step from the old state is
        # ε |J| |x − x^{n−1}|, so they belong to the size of each row
        abs_A = abs(A_dt)
        terms_old = abs_A @ np.abs(old.p) + np.abs(r_dt) + self._abs_GT @ np.abs(u_old)
        rel_old = None                          # |[[u^{n−1} − u⁰]]_τ|_ε per face, with dilatancy only
        if self.n_ff and np.any(self.tan_psi > 0):
            rel_old = self.tangential_slip(self.jumps(old.u))[0]
            terms_old[self.dofs.frac] += mech.face_area * self.tan_psi * rel_old
        # the Jacobian's data without the contact, dilatancy and implicit blocks (per iterate)
        j_step = self.jacobian.step_data(None if self.blockwise else mech.elastic_block_values(), sf,
                                         self._coupling_sign, af_vals)
        del af_vals
        # the implicit conductivities' reference: the coefficients A_dt was built with, and Δt
        imp_old = (*self.conductivities(old.aperture), dt) if self._implicit is not None else None
        ctx = StepContext(F, udir, A_dt, r_dt, p_dir, u_old, q_old, s, j_step, abs_A, terms_old, rel_old, imp_old,
                          self.friction_state(old), dt)
        x0 = np.concatenate([u_old[mech.free], (mech.patch_values(old.lam) / mech.law.beta[:, None]).ravel(),
                             old.p[self.flow_free] / sf])
        return ctx, x0

    def _predicted_start(self, old: PoroState, dt: float, ctx) -> np.ndarray | None:
        """The first iterate x of a step from ``old`` extrapolated from the step that ended there:
        (u, λ, p) + Δt/Δt_prev · (Δu, Δλ, Δp), or None (no such step, or ``predictor = "none"``).

        Why: a step's loads (injection, pressure diffusion) change smoothly in time, and the faces
        that slipped in the last step slip on; from the old state itself every such face starts at
        zero slip on its friction cone, where the semi-smooth Newton flips it between stick and
        slip (docs/iterative_cornerpoint.md, ninth session). Newton falls back to x0 only where
        this iterate's residual is not finite (:func:`~polypore.solvers.newton.semismooth_newton`).
        """
        hit = [inc for inc in self._increments if inc[0] is old]
        if self.predictor == "none" or not hit:
            return None
        _, du, dlam, dp, dt_prev = hit[-1]
        r = dt / dt_prev
        if r > PREDICTOR_REACH:
            # a short step followed by a long one: the short one's increment is typically a load's
            # instant (undrained) response, not a rate (Terzaghi: Δt = 1e-6 T_c, then 1e-2 T_c)
            return None
        mech, s = self.mech, ctx.pressure_scale
        u = old.u.ravel() + r * du
        lam = mech.patch_values(old.lam) + r * dlam
        p = old.p + r * dp
        return np.concatenate([u[mech.free], (lam / mech.law.beta[:, None]).ravel(),
                               p[self.flow_free] / s[self.flow_free]])

    def step(self, old: PoroState, dt: float, t_new: float | None = None, *, energy: bool = True,
             verbose: bool = False) -> tuple[PoroState, StepInfo]:
        """One implicit-Euler step from ``old`` to t_new (default old.time + dt), scheme.md §6.

        Loads and Dirichlet data at t_new; C_f, Λ_f and the fracture storage coefficient at
        d_f^{n−1} = ``old.aperture``. Returns the new state and the Newton report (with the
        energy terms of the step when ``energy``). Raises RunError if Newton fails.
        """
        t0 = time.perf_counter()
        dt = _positive(dt, "dt")
        t = old.time + dt if t_new is None else float(t_new)
        mech, d = self.mech, self.dim
        ctx, x0 = self.step_context(old, dt, t)
        udir, p_dir, s = ctx.u_dir, ctx.p_dir, ctx.pressure_scale
        nfree, nl = mech.free.size, mech.n_c * d
        t1 = time.perf_counter()
        # the step reports the Krylov iterations of the solvers Newton drives (the block solvers)
        counted = self.solver.takes_target
        k0 = len(self.solver.krylov_iterations) if counted else 0

        def krylov_since():
            return [int(k) for k in self.solver.krylov_iterations[k0:]] if counted else []

        def incr(dx, x):
            out = 0.0
            for a, b in ((0, nfree), (nfree, nfree + nl), (nfree + nl, len(x))):
                if b > a:
                    out = max(out, np.linalg.norm(dx[a:b]) / max(np.linalg.norm(x[a:b] + dx[a:b]), 1e-300))
            return float(out)

        # an exact first solve only when this step is expected to be linear (solvers/newton.py,
        # forcing terms): after a step that converged in one iteration, or that left every face's
        # state as it found it (a direct solve needs two iterations there, the second confirming;
        # without this rule block-direct needs more Newton iterations than PARDISO). After a step
        # whose active set moved it is loose, and so is the run's first step: nothing says its
        # active set stays, and from a state at rest its weighted norm holds the source terms alone
        # (the fluxes are not terms yet), so "exact" there asks far more than the next iterate's
        # norm needs (docs/iterative_cornerpoint.md, "Measurements cited by the code")
        first_tight = self._last_newton is not None and (self._last_newton <= 1 or self._last_settled)
        try:
            res = semismooth_newton(lambda x: self._linearise(x, ctx), x0, self.solver, incr, self.newton, verbose,
                                    first_tight=first_tight, x_pred=self._predicted_start(old, dt, ctx))
        except RunError as exc:
            # the failed attempt's Krylov work, for the run's report (runs/march.py)
            exc.linear_iterations = krylov_since()
            raise
        self._last_newton = res.iterations
        u, lam, p = self._split(res.x, udir, p_dir, s)
        u = u.reshape(-1, d)
        sflux = self.stabilisation_weights * self.stabilisation_jumps(p - old.p) / dt
        ap = self.aperture_of(u)
        flux_ap = np.maximum(ap, self.closed_aperture) if self._implicit is not None else old.aperture
        friction = mech.advance_friction(ctx.friction_state, u, ctx.q_old, dt, lam)
        assert res.active_set is not None
        new = PoroState(t, u, mech.face_values(lam), p, ap, np.asarray(mech.face_values(res.active_set), np.int8),
                        flux_ap, sflux, friction)
        self._last_settled = old.state is not None and np.array_equal(new.state, old.state)
        if self.predictor != "none":
            self._increments = [*self._increments[-1:], (new, (u - old.u).ravel(), lam - mech.patch_values(old.lam),
                                                         p - old.p, dt)]
        c = res.counts
        info = StepInfo(res.iterations, res.residual, c.get("open", 0), c.get("stick", 0), c.get("slip", 0),
                        res.history, {"setup": t1 - t0, "assembly": res.seconds_assembly, "linear": res.seconds_linear})
        info.linear_iterations = krylov_since()
        info.conductivity_growth = self.conductivity_growth(old.aperture, new.aperture)
        fl = mech.law.friction_law
        if isinstance(fl, RateLaw):
            info.rate_error = fl.step_error(ctx.friction_state, friction, dt, np.einsum("fi,fi->f", lam, mech.c_normal))
        if energy:
            info.energy = step_energy(self, old, new)
        info.seconds["total"] = time.perf_counter() - t0
        return new, info

    # ---- post-processing -------------------------------------------------------------------------
    def flow_solution(self, st: PoroState) -> FlowSolution:
        """The pressures and fluxes of a state as a :class:`FlowSolution` (for outputs).

        Conductivities at ``st.flux_aperture`` (those of the step that computed the state), so
        that the fluxes balance the step's storage changes; the matrix cell fluxes include the
        step's pressure-stabilisation flux ``st.stabilisation_flux`` (interior faces only, so
        the boundary fluxes are the Darcy ones).
        """
        asm, mesh, net, d = self.asm, self.fm.mesh, self.fm.network, self.dofs
        p = st.p
        flux_ap = st.aperture if st.flux_aperture is None else st.flux_aperture      # set in __post_init__
        ex, fc = self.conductivities(flux_ap) if self.n_ff else (np.zeros(0), np.zeros(0))
        F = asm.cell_fluxes(p[d.n:], p)
        if st.stabilisation_flux is not None:
            F[self.stab.positions[:, 0]] += st.stabilisation_flux
            F[self.stab.positions[:, 1]] -= st.stabilisation_flux
        Ff = asm.fhfv_unit.scaled(fc).fluxes(p[d.frac], p[d.edge][asm.fcells.face_edges.values])
        face = np.full(mesh.n_faces, np.nan)
        ok = d.face >= 0
        face[ok] = p[d.face[ok]]
        face_out = np.zeros(mesh.n_faces)
        np.add.at(face_out, mesh.cell_faces.values, F)
        edge_out = np.bincount(asm.fcells.face_edges.values, weights=Ff, minlength=net.edge_nodes.shape[0])
        bflux, fbflux = {}, {}
        for name, faces in mesh.boundary.items():
            parts = self.flow.edge_parts
            fb = float(edge_out[parts[name]].sum()) if name in parts else 0.0
            fbflux[name] = fb
            bflux[name] = float(face_out[faces].sum()) + fb
        return FlowSolution(st.time, p[d.n:].copy(), face, p[d.trace].copy(), p[d.frac].copy(), p[d.edge].copy(),
                            st.aperture.copy(), F, ex[:, None] * (p[d.trace] - p[d.frac][:, None]), Ff, bflux, fbflux)

    def fracture_quantities(self, st: PoroState) -> dict:
        """Per fracture face (scheme.md §7): jump (n_ff, d), jump_n, jump_t = |[[u]]_τ|, lambda_n,
        lambda_t = |λ_τ|, state, aperture (m), p_f (Pa)."""
        n = self.mech.normal
        q = self.jumps(st.u)
        qn, qt = normal_and_shear(q, n)
        ln, lt = normal_and_shear(st.lam, n)
        return {"jump": q, "jump_n": qn, "jump_t": qt, "lambda_n": ln, "lambda_t": lt,
                "state": st.state, "aperture": st.aperture, "p_f": st.p[self.dofs.frac]}

    def cell_pressure(self, st: PoroState) -> np.ndarray:
        """(n_cells,) p_K, Pa."""
        return st.p[self.dofs.n:]

    def stresses(self, st: PoroState) -> tuple[np.ndarray, np.ndarray]:
        """(effective σ^K(u), total σ^K(u) − b p_K I), each (n_cells, d, d) in Pa (σ⁰ excluded)."""
        eff = self.mech.stress(st)
        return eff, eff - (self.biot * self.cell_pressure(st))[:, None, None] * np.eye(self.dim)
