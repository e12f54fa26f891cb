"""Static contact mechanics with P0 multipliers (scheme.md §3 "Discrete elasticity", §4).

Unknowns: the free nodal + bubble displacement dofs (Dirichlet dofs eliminated) and one
multiplier λ_σ ∈ R^d per fracture face. The system

    A u + Σ_σ |σ| λ_σ·[[v]]_σ = ℓ(v)            (equilibrium, scheme.md §3)
    (|σ|/β)(λ_σ − P(λ_σ + β [[u]]_σ)) = 0       (projections, scheme.md §4)

is solved by the semi-smooth Newton loop of :mod:`polypore.solvers.newton`. The
Jacobian's sparsity is built once; each iteration refills its values.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import Callable, Protocol, Sequence

import numpy as np
import scipy.sparse as sp

from ..assembly.elasticity import elasticity_matrix
from ..assembly.blocks import Block
from ..assembly.pattern import Pattern, jacobian_pattern
from ..core.csr import with_entries
from ..core.errors import InputError
from ..core.memory import trim_heap
from ..discretisation import DisplacementSpace, Operators, QuadraticOperators, QuadraticSpace
from ..discretisation.contact_patches import contact_patches
from ..discretisation.faces import face_entries, face_mean_operator
from ..mesh import FracturedMesh
from ..solvers.block_jacobian import BlockJacobian, FreeSplit, block_diag_csr
from ..parallel.layout import OwnedRows, SplitRowBlock, local_rows, min_owner, owned_layout, register_layout
from ..solvers.factory import BlockProblem, SolverSource, build
from ..solvers.interface import LinearSystemSolver
from ..solvers.linear import release_solver
from ..solvers.newton import Linearisation, NewtonOptions, row_weights, semismooth_newton
from .contact import OPEN, PATCH_RATIO, SLIP, STICK, ContactLaw, linearise_contact
from .friction import RateLaw, friction_law

log = logging.getLogger("polypore")

VectorField = Callable[[np.ndarray, float], np.ndarray]   # (X (n, d) m, t s) -> (n, d)
ScalarField = Callable[[np.ndarray, float], np.ndarray]   # (X (n, d) m, t s) -> (n,)
TensorField = Callable[[np.ndarray, float], np.ndarray]   # (X (n, d) m, t s) -> (n, d, d)


@dataclass(frozen=True)
class DisplacementBC:
    """Dirichlet condition u_i = value_i on the named boundary part for i in ``components`` (m)."""

    boundary: str
    components: tuple
    value: VectorField


@dataclass(frozen=True)
class TractionBC:
    """Neumann condition σ n = value on the named boundary part (Pa)."""

    boundary: str
    value: VectorField


@dataclass(frozen=True)
class ContactSpec:
    """Contact data per fracture face: law, F (–; the static F_s of slip-weakening), Tresca g (Pa),
    β scale c (–, scheme.md §4), and the other coefficients of the friction law by their case-file
    keys (``friction.LAW_KEYS``; slip-weakening: ``dynamic_friction`` (–), ``critical_slip`` (m)),
    (n_ff,) arrays or scalars."""

    law: str = "coulomb"
    friction: np.ndarray | float = 0.0
    threshold: np.ndarray | float = 0.0
    beta_scale: float = 1.0
    initial: str = "closed"   # first Newton iterate: "closed" (bonded, always solvable) or "open" (λ = 0)
    # smallest |P| / A_K of a multiplier patch (discretisation/contact_patches.py); 0: one per face
    patch_ratio: float = PATCH_RATIO
    coefficients: dict = field(default_factory=dict)
    # rate-and-state: state_law ("aging"/"slip"), stick_rate (m/s), shear_wave_speed (m/s, or None:
    # no radiation damping)
    options: dict = field(default_factory=dict)


@dataclass(frozen=True)
class MechanicsData:
    """Everything the static contact-mechanics model needs besides the mesh.

    Attributes
    ----------
    mu, lam : (n_cells,) Lamé parameters in Pa
    displacement : Dirichlet conditions; traction : Neumann conditions
    body_force : f(X, t) in N/m³ at cell centroids, or None
    matrix_pressure : p_m(X, t) in Pa at cell centroids (Biot term −b p_m I), or None
    biot : (n_cells,) Biot coefficient b (–)
    fracture_pressure : p_f(X, t) in Pa at fracture face centroids, or None
    initial_stress : σ⁰(X, t) in Pa at cell centroids (total stress = σ⁰ + σ(u)), or None
    contact : ContactSpec
    two_sided : bubbles on both sides of fracture faces (default: one-sided; order 2: the 3D face
        bubbles, 2D has none)
    bubble_side : side of one-sided bubbles (order 1): "regular" (default: the cell of which the
        face is the more regular face) or "plus" (the scheme's), :func:`~polypore.discretisation.space.bubble_sides`
    stabilisation : scale of the stabilisation S (1 in the scheme; unused by order 2)
    bubble_stabilisation : "face" ((2μ + λ_L) |σ|²/|K| per bubble, default) or "cell" (the
        scheme's h_K^{d−2} (2μ + λ_L)), :func:`~polypore.assembly.elasticity.elasticity_matrix`
    nodal_stabilisation : "diameter" (the scheme's h_K^{d−2}) or "thickness" (reduced on flat
        cells), :func:`~polypore.assembly.elasticity.nodal_weight`
    order : 1 (nodal + bubble space, scheme.md §3) or 2 (quadratic displacements on simplicial
        meshes, :mod:`polypore.discretisation.quadratic`; P0 multipliers on the face-mean jumps)
    """

    mu: np.ndarray
    lam: np.ndarray
    displacement: Sequence[DisplacementBC] = ()
    traction: Sequence[TractionBC] = ()
    body_force: VectorField | None = None
    matrix_pressure: ScalarField | None = None
    biot: np.ndarray | float = 1.0
    fracture_pressure: ScalarField | None = None
    initial_stress: TensorField | None = None
    contact: ContactSpec = field(default_factory=ContactSpec)
    two_sided: bool = False
    bubble_side: str = "regular"
    stabilisation: float = 1.0
    order: int = 1
    bubble_stabilisation: str = "face"
    nodal_stabilisation: str = "diameter"

    def __post_init__(self):
        # checked where the API builds the data: deep in the assembly a bad μ would only surface
        # as a non-positive contact β or a singular matrix
        mu, lam = np.broadcast_arrays(np.asarray(self.mu, float), np.asarray(self.lam, float))
        _require("mu", mu, (mu > 0) & np.isfinite(mu), "the shear modulus must be positive and finite (Pa)")
        _require("lam", lam, np.isfinite(lam) & (3 * lam + 2 * mu > 0),
                 "Lamé's λ must be finite and exceed −2μ/3 (Pa; Poisson's ratio > −1)")
        b = np.asarray(self.biot, float)
        _require("biot", b, (b >= 0) & (b <= 1), "the Biot coefficient must lie in [0, 1]")
        if self.bubble_stabilisation not in ("face", "cell"):
            raise InputError("bubble_stabilisation", f"must be 'face' or 'cell', got "
                             f"{self.bubble_stabilisation!r}")
        if self.bubble_side not in ("plus", "regular"):
            raise InputError("bubble_side", f"must be 'plus' or 'regular', got {self.bubble_side!r}")
        if self.nodal_stabilisation not in ("diameter", "thickness"):
            raise InputError("nodal_stabilisation", f"must be 'diameter' or 'thickness', got "
                             f"{self.nodal_stabilisation!r}")
        if isinstance(self.order, bool) or self.order not in (1, 2):
            raise InputError("order", f"the displacement order must be 1 (nodal + bubble space) or 2 "
                             f"(quadratic, simplicial meshes), got {self.order!r}")


def _require(field_: str, values: np.ndarray, ok: np.ndarray, what: str) -> None:
    """InputError naming ``field_`` and the first value where ``ok`` fails."""
    if not np.all(ok):
        raise InputError(field_, f"{what}, got {float(values[~ok].ravel()[0])!r}")


@dataclass
class MechanicsState:
    """A solution: slot displacements u (n_slots, d) in m, multipliers λ (n_ff, d) in Pa, face states."""

    u: np.ndarray
    lam: np.ndarray
    state: np.ndarray
    time: float = 0.0
    newton_iterations: int = 0
    residual: float = 0.0
    history: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    friction: np.ndarray | None = None      # (n_c, k) the friction law's state after this solve


class HasDisplacement(Protocol):
    """A state with displacements ``u`` (n_slots, d), m: MechanicsState, the coupled model's PoroState."""

    u: np.ndarray


def _with_contact_couplings(A, jump, d: int):
    """A with explicit zeros wherever the condensed contact term couples two dofs: every pair of
    dofs (both components) of the slots in one patch's jump (``jump`` coo (n_c, n_slots)).

    The block preconditioners' condensed matrix S = A − Bᵀ Ĉ⁻¹ Ĉ_u (solvers/block_contact.py)
    then has A's pattern and is built by changing those entries of A's restriction in place,
    without a sparse sum (whose temporaries were the Newton iteration's memory peak,
    docs/iterative_cornerpoint.md). Values, and every product with A, are unchanged.
    """
    if jump.nnz == 0:
        return A
    E = sp.csr_array((np.ones(jump.nnz), (jump.row, jump.col)), shape=jump.shape)
    Z = (E.T @ E).tocoo()                                # slot pairs sharing a patch
    comp = np.arange(d)
    rows = (Z.row.astype(np.int64)[:, None, None] * d + comp[None, :, None]) + 0 * comp[None, None, :]
    cols = (Z.col.astype(np.int64)[:, None, None] * d + comp[None, None, :]) + 0 * comp[None, :, None]
    A.sort_indices()
    return with_entries(A, rows.ravel(), cols.ravel())


def _side_points(space: DisplacementSpace) -> np.ndarray:
    """Evaluation point of every side: its node, or for a node with several sides (on Γ) the
    node nudged 1e-12 of the way towards one of the side's cells.

    Piecewise-defined data (exact solutions discontinuous across Γ) are then evaluated on the
    side's own piece; continuous data change by O(1e-12 h |∇f|) at fracture nodes only.
    """
    mesh = space.fm.mesh
    sides = space.fm.sides
    cell = mesh.cell_nodes.rows_of_entries()
    first = np.full(sides.n_sides, -1, np.int64)
    first[sides.cell_node_side[::-1]] = np.arange(cell.size)[::-1]
    X = mesh.nodes[sides.side_node]
    multi = np.bincount(sides.side_node, minlength=mesh.n_nodes)[sides.side_node] > 1
    X[multi] += 1e-12 * (mesh.geometry.cell_centroid[cell[first[multi]]] - X[multi])
    return X


def _face_average(mesh, faces: np.ndarray, cells: np.ndarray, fn: VectorField, t: float) -> np.ndarray:
    """(k, d) (1/|σ|)∫_σ fn for the given faces, evaluated from the side of ``cells``."""
    d = mesh.dim
    g = mesh.geometry
    out = np.zeros((len(faces), d))
    fn_ = mesh.face_nodes
    xK = g.cell_centroid[cells]
    sub = fn_.take(faces)
    for m, rows, conn in sub.groups():
        X = mesh.nodes[conn]                                     # (k, m, d)
        if d == 2:
            a, b = X[:, 0], X[:, 1]
            gp = np.array([0.5 - np.sqrt(0.15), 0.5, 0.5 + np.sqrt(0.15)])
            gw = np.array([5.0, 8.0, 5.0]) / 18.0
            P = a[:, None] + gp[None, :, None] * (b - a)[:, None]   # (k, 3, d)
            W = np.broadcast_to(gw, (len(rows), 3))
        else:
            xc = X.mean(axis=1)
            Xn = np.roll(X, -1, axis=1)
            area = 0.5 * np.linalg.norm(np.cross(X - xc[:, None], Xn - xc[:, None]), axis=2)   # (k, m)
            # edge-midpoint rule on each sub-triangle (x_c, s_i, s_{i+1}): exact for quadratics
            mids = np.stack([(xc[:, None] + X) / 2, (X + Xn) / 2, (Xn + xc[:, None]) / 2], axis=2)  # (k, m, 3, d)
            P = mids.reshape(len(rows), 3 * m, d)
            W = np.repeat(area / 3.0, 3, axis=1)
            W = W / W.sum(axis=1, keepdims=True)
        k, q = P.shape[:2]
        Pn = P + 1e-12 * (xK[rows][:, None, :] - P)
        vals = np.asarray(fn(Pn.reshape(-1, d), t), float).reshape(k, q, d)
        out[rows] = np.einsum("kq,kqd->kd", W, vals)
    return out


class ContactMechanics:
    """The discrete static contact-mechanics problem on a fractured mesh.

    Parameters
    ----------
    fm : FracturedMesh
    data : MechanicsData
    solver : a ready solver, or a :class:`~polypore.solvers.factory.SolverChoice` the model builds
        (:func:`~polypore.solvers.factory.build`, with :meth:`block_problem` for the block backends);
        default sparse direct
    """

    def __init__(self, fm: FracturedMesh, data: MechanicsData, solver: SolverSource = None,
                 newton: NewtonOptions | None = None):
        t0 = time.perf_counter()
        self.fm, self.data = fm, data
        mesh, net = fm.mesh, fm.network
        self.dim = d = mesh.dim
        self.order = int(data.order)
        self.space: DisplacementSpace | QuadraticSpace
        self.ops: Operators | QuadraticOperators
        if self.order == 2:
            self.space = QuadraticSpace.build(fm, data.two_sided)
            self.ops = QuadraticOperators.build(self.space)
        else:
            self.space = DisplacementSpace.build(fm, data.two_sided, data.bubble_side)
            self.ops = Operators.build(self.space)
        mu, lam = np.broadcast_to(data.mu, (mesh.n_cells,)), np.broadcast_to(data.lam, (mesh.n_cells,))
        self.mu, self.lam = mu, lam
        self.A = elasticity_matrix(self.ops, mu, lam, data.stabilisation, data.bubble_stabilisation,
                                   data.nodal_stabilisation)
        if self.ops.stab is not None:
            # the stabilisation rows serve A only (the largest operator: one row per cell node),
            # so they are not kept for the rest of the run
            self.ops = replace(self.ops, stab=None, stab_cell=None)   # type: ignore[arg-type]  # both classes have them
        self.n_dofs = self.space.n_dofs
        g = mesh.geometry
        self.face_area = g.face_area[net.faces]
        self.n_ff = net.n_faces
        # the multipliers live on patches of faces (one per face unless faces are slivers,
        # discretisation/contact_patches.py): the contact rows use the patch-mean jumps
        if not data.contact.patch_ratio >= 0:
            raise InputError("patch_ratio", f"must be ≥ 0, got {data.contact.patch_ratio!r}")
        self.patches = P = contact_patches(fm, data.contact.patch_ratio)
        self.n_c = P.n
        self.c_area, self.c_normal = P.area, P.normal
        self.c_jump = self.ops.jump if P.identity else sp.csr_array(P.mean @ self.ops.jump)
        # per face, the jump and normal of its patch: within a patch only the mean jump is
        # controlled (by the patch's multiplier), so the aperture, the fracture-pressure coupling
        # and the outputs take that one; then Σ_σ |σ| λ_σ·[[v]]_σ = Σ_P |P| λ_P·[[v]]_P with
        # λ_σ = λ_P(σ), and the coupling's adjointness (energy identity, models/energy.py) holds
        if P.identity:
            self.jump_scalar, self.normal = self.ops.jump, net.normal
        else:
            self.jump_scalar, self.normal = self.c_jump[P.face_patch], P.expand(P.normal)
        # the patch jump as a vector operator (n_c*d, n_dofs) and the equilibrium coupling
        # B_c = |P| [[·]]_P (= Σ_σ |σ| [[·]]_σ with each face's patch jump: B_cᵀ λ_P = Bᵀ λ_face)
        self.Jcv, self.Bcv = _vector_jump(self.c_jump, P.area, self.n_dofs, d)
        J = self.c_jump.tocoo()
        self.A = _with_contact_couplings(self.A, J, d)
        self._face_means: dict = {}    # traction boundaries: face-mean operators (order 2: face quadratures)
        self._setup_dirichlet()
        self._setup_contact()
        # under mpiexec (parallel/layout.py; None serially): the layout of the Newton unknowns,
        # whose rows this rank assembles, and of all displacement dofs, whose rows of A it keeps
        self.layout = owned_layout(mesh, self.dof_owner)
        self.dof_layout = owned_layout(mesh, lambda part: np.repeat(self.slot_owner(part), d))
        # serially A is kept as its free block and the rest (FreeSplit): the block solvers take the
        # free block as it is; under mpiexec each rank keeps its rows
        self.A = FreeSplit(self.A, self.free) if self.dof_layout is None else \
            SplitRowBlock(self.A, self.dof_layout, self.free)
        self._use_solver(build(solver, self.block_problem))
        self.newton = newton or NewtonOptions(label="contact Newton")
        trim_heap()                 # the set-up's temporaries (core/memory.py)
        self.seconds_setup = time.perf_counter() - t0
        log.info("mechanics: order %d, %d displacement dofs (%d free), %d multipliers (%d faces in %s), %s bubbles; "
                 "set up in %.2f s", self.order, self.n_dofs, self.free.size, self.n_c * d, self.n_ff,
                 "their own patches" if P.identity else f"{self.n_c} patches",
                 "two-sided" if data.two_sided else "one-sided", self.seconds_setup)

    def _use_solver(self, solver: LinearSystemSolver) -> None:
        """Take the model's solver, once: the Jacobian's patterns for it and its layout."""
        self.solver = solver
        self.pattern = self._fixed_vals = self._blocks = None
        # the Jacobian goes to the solver by blocks (a block solver, one process): no assembled
        # matrix, A's free block used in place (solvers/block_jacobian.py); fixed for the model
        self.blockwise = bool(solver.takes_blocks) and self.layout is None
        if self.blockwise:
            self._setup_blocks(self.c_jump.tocoo())
        else:
            self._setup_pattern(self.c_jump.tocoo())
        if self.layout is not None:
            register_layout(solver, self.layout)

    def block_problem(self) -> BlockProblem:
        """The contact system as the block solvers see it (:mod:`polypore.solvers.factory`): the free
        displacements, the multipliers, the contact rows' condensation and the rigid-body modes."""
        return BlockProblem(self.free.size, self.dim, self.n_c * self.dim, self.condensation(), self.rigid_modes())

    def condensation(self, rho: float = 0.1):
        """Contact-row data for the block preconditioners: c_σ = |σ| β_σ (the scaled rows), n⁺."""
        from ..solvers.block_contact import ContactCondensation

        return ContactCondensation(self.c_area * self.law.beta, self.c_normal, rho)

    def rigid_modes(self) -> np.ndarray:
        """(n_free, 3 or 6) rigid motions of the free displacement dofs (bubbles zero); made once
        and shared read-only by the solvers that take them (48 bytes per dof each)."""
        from ..solvers.linear import rigid_body_modes

        if getattr(self, "_rigid", None) is None:
            R = np.zeros((self.n_dofs, 3 if self.dim == 2 else 6))
            R[: self.space.n_point_slots * self.dim] = rigid_body_modes(self.slot_points)
            self._rigid = R[self.free]
            self._rigid.flags.writeable = False
        return self._rigid

    # ---- distributed runs (parallel/layout.py) --------------------------------------------
    def slot_owner(self, part: np.ndarray) -> np.ndarray:
        """(n_slots,) owner rank of every displacement slot for the cell ranks ``part`` (n_cells,):
        the lowest rank among the cells holding it (a bubble: its cell)."""
        sp_ = self.space
        cs = sp_.cell_slots
        if isinstance(cs, np.ndarray):             # order 2: (n_cells, n_loc), bubbles apart
            idx, cells = cs.ravel(), np.repeat(np.arange(cs.shape[0]), cs.shape[1])
        else:
            idx, cells = cs.values, cs.rows_of_entries()
        own = min_owner(sp_.n_slots, idx, part[cells], fill=-1)
        nb = sp_.n_bubbles
        if nb:
            b = sp_.n_point_slots + np.arange(nb)
            own[b] = np.where(own[b] < 0, part[sp_.bubble_cell], own[b])
        return np.maximum(own, 0)

    def dof_owner(self, part: np.ndarray) -> np.ndarray:
        """(n_free + n_c d,) owner rank of every Newton unknown [free u, λ̃]: a slot's for its
        components, the + side cell's of its largest face for a patch's multipliers."""
        u = np.repeat(self.slot_owner(part), self.dim)[self.free]
        lam = np.repeat(part[self.patches.plus_cell], self.dim)
        return np.concatenate([u, lam])

    # ---- set-up -------------------------------------------------------------------------
    def _boundary_faces(self, name: str, field_: str) -> np.ndarray:
        mesh = self.fm.mesh
        if name not in mesh.boundary:
            raise InputError(field_, f"unknown boundary {name!r}; this mesh has {', '.join(sorted(mesh.boundary))}")
        return np.asarray(mesh.boundary[name], np.int64)

    def _setup_dirichlet(self):
        d = self.dim
        comp_mask = np.zeros((self.space.n_point_slots, d), bool)
        self._dir_groups = []
        for bc in self.data.displacement:
            faces = self._boundary_faces(bc.boundary, f"displacement.{bc.boundary}")
            comps = tuple(int(c) for c in bc.components)
            if not comps or any(c < 0 or c >= d for c in comps):
                raise InputError(f"displacement.{bc.boundary}", f"components must be in 0..{d - 1}, got {comps}")
            slot = np.unique(self._face_slots(faces))
            comp_mask[np.ix_(slot, comps)] = True
            self._dir_groups.append((slot, comps, bc.value))
        constrained = comp_mask.any(axis=0)
        if not constrained.all() or comp_mask.sum() < d * (d + 1) // 2:
            missing = [("xyz"[i]) for i in range(d) if not constrained[i]]
            raise InputError("displacement", "the displacement is not held: rigid motions are free "
                             + (f"(no Dirichlet condition on the {', '.join(missing)} component)" if missing else
                                "(too few Dirichlet nodes)")
                             + "; give a displacement (u, ux, uy, uz) on some boundary part")
        dofs = np.zeros(self.n_dofs, bool)
        dofs[: self.space.n_point_slots * d] = comp_mask.ravel()
        self.is_dirichlet = dofs
        self.free = np.flatnonzero(~dofs)
        self.fixed = np.flatnonzero(dofs)
        self.free_index = np.full(self.n_dofs, -1, np.int64)
        self.free_index[self.free] = np.arange(self.free.size)
        # evaluation point of every point slot (vertex, or edge midpoint for order 2), m
        self.slot_points = _side_points(self.space) if self.order == 1 else self.space.slot_points()

    def _face_slots(self, faces: np.ndarray) -> np.ndarray:
        """Point slots on the given boundary faces (their vertices, and edges for order 2)."""
        if isinstance(self.space, DisplacementSpace):
            return face_entries(self.space, faces)[2]
        vs, es = self.space.face_slots(faces)
        return np.concatenate([vs.ravel(), es.ravel()])

    def _face_mean(self, faces: np.ndarray, cells: np.ndarray | None = None) -> sp.csr_array:
        """(len(faces), n_slots) face mean of the trace from ``cells`` without bubbles."""
        if isinstance(self.space, DisplacementSpace):
            return face_mean_operator(self.space, faces, cells)
        return self.space.face_mean_operator(faces, cells)

    def _setup_contact(self):
        c = self.data.contact
        P = self.patches
        kp = P.plus_cell
        if not c.beta_scale > 0:
            raise InputError("beta_scale", f"must be positive, got {c.beta_scale!r}")
        beta = c.beta_scale * (2 * self.mu[kp] + self.lam[kp]) / P.diameter
        # per patch: the area-weighted means of the faces' coefficients (equal on a fracture's
        # faces unless given as fields)
        def per_patch(v):
            if v is None:
                return None
            v = np.broadcast_to(np.asarray(v, float), (self.n_ff,))
            return np.array(v if P.identity else P.mean @ v, float)

        opts = dict(c.options)
        cs = opts.pop("shear_wave_speed", None)
        if cs is not None:
            # radiation damping η = μ_s/(2c_s) with the shear modulus of the patch's cell (Rice 1993)
            opts["damping"] = self.mu[kp] / (2.0 * float(cs))
        law = friction_law(c.law, self.n_c, friction=per_patch(c.friction), threshold=per_patch(c.threshold),
                           **{k: per_patch(v) for k, v in c.coefficients.items()}, **opts)
        self.law = ContactLaw(law, beta)

    def _free_block(self):
        """A as coo (this rank's rows on N ranks), the free numbers of its rows and columns, and
        the mask of its entries in free rows and columns."""
        if isinstance(self.A, FreeSplit):
            A = self.A.ff.tocoo()                 # the free block's entries, in A's order
            return A, A.row, A.col, np.ones(A.nnz, bool)
        A = local_rows(self.A).tocoo()
        arow = A.row if self.dof_layout is None else self.dof_layout.owned[A.row]
        fr, fc = self.free_index[arow], self.free_index[A.col]
        return A, fr, fc, (fr >= 0) & (fc >= 0)

    def _bt_values(self, Bt) -> np.ndarray:
        # Newton works on λ̃ = λ/β (a length, like u) with the contact rows multiplied by β: the
        # Jacobian then has blocks of one scale (~ μ h^{d-2}) instead of μ, |σ| and |σ|/β, which
        # would cost the direct solver ~8 digits
        return Bt.data * self.law.beta[Bt.col // self.dim]

    def elastic_block_values(self) -> np.ndarray:
        """The values of the Jacobian's block A (N/m), in the order of :meth:`jacobian_blocks`
        (recomputed from A: a caller need not keep a copy between steps)."""
        A, _, _, ka = self._free_block()
        return A.data[ka]

    def jacobian_blocks(self, J) -> tuple[list, list]:
        """The (row, col) lists of the Newton Jacobian's mechanical blocks in the numbering of the
        unknowns [free u, λ̃, …], and their values where they are fixed.

        Blocks, in order: A (free rows and columns; on N ranks only this rank's rows, from the rows
        of A it keeps), Bᵀ (u rows, λ̃ columns), C_u (contact rows, u columns: one d × d entry
        per jump entry whose slot is free, selected by ``self.contact_jump_entries``'s mask), C_λ (d × d per patch).

        Parameters
        ----------
        J : coo (n_c, n_slots), the scalar patch-mean jump operator ``c_jump``

        Returns
        -------
        blocks : list of (rows, cols) int64 arrays
        values : list, the fixed values of A (N/m) and Bᵀ β (N/m), then None, None (C_u and C_λ
            change at every iterate)
        """
        d, nf, nfree = self.dim, self.n_c, self.free.size
        A, fr, fc, ka = self._free_block()
        Bt = self.Bcv[:, self.free].T.tocoo()
        bt_vals = self._bt_values(Bt)
        rows, fcol, keep = self._cu_entries(J)            # C_u: row (σ, i), col (slot a, j)
        lr = (np.arange(nf)[:, None, None] * d + np.arange(d)[None, :, None]) + 0 * np.arange(d)[None, None, :]
        lc = (np.arange(nf)[:, None, None] * d + np.arange(d)[None, None, :]) + 0 * np.arange(d)[None, :, None]
        blocks = [(fr[ka], fc[ka]), (Bt.row, nfree + Bt.col), (nfree + rows[keep], fcol[keep]),
                  (nfree + lr, nfree + lc)]
        return blocks, [A.data[ka], bt_vals, None, None]

    def release_solver(self) -> None:
        """Free the linear solver's matrices and set-ups once no solve follows
        (:func:`~polypore.solvers.linear.release_solver`)."""
        release_solver(self.solver)

    def release_assembly(self) -> None:
        """Free the Jacobian's pattern and fixed values (the coupled model needs them for its
        initial equilibrium only); the next :meth:`linearise` builds them again."""
        self.pattern = self._fixed_vals = self._blocks = None

    def free_block(self) -> sp.csr_matrix:
        """A restricted to the free dofs (csr, free numbering; serial runs), not a copy."""
        return self.A.ff

    def _cu_entries(self, J):
        """(rows, cols, keep): the C_u contributions, row (patch σ, i), col (free number of slot a,
        component j), for every entry (σ, a) of the patch jump ``J`` (coo) and i, j < d; keep: the
        column is free. Sets ``self.contact_jump_entries`` (the jump entries and the mask, for the values)."""
        d = self.dim
        rows = J.row.astype(np.int64)[:, None, None] * d + np.arange(d)[None, :, None]
        colsd = J.col.astype(np.int64)[:, None, None] * d + np.arange(d)[None, None, :]
        rows, colsd = np.broadcast_arrays(rows, colsd)
        fcol = self.free_index[colsd]
        keep = fcol >= 0
        self.contact_jump_entries = (J.row, J.data, keep)
        return rows, fcol, keep

    def _setup_blocks(self, J):
        """The fixed blocks (Bᵀ β) and the pattern of C_u for :meth:`linearise` by blocks."""
        d, nc, nfree = self.dim, self.n_c, self.free.size
        Bt = self.Bcv[:, self.free].T.tocoo()
        rows, fcol, keep = self._cu_entries(J)
        self._blocks = (sp.csr_array((self._bt_values(Bt), (Bt.row, Bt.col)), shape=(nfree, nc * d)),
                        Pattern.build(rows[keep], fcol[keep], (nc * d, nfree)))

    def jacobian_by_blocks(self, cu: np.ndarray, cl: np.ndarray) -> BlockJacobian:
        """The contact Jacobian [[A, Bᵀβ], [C_u, C_λ]] by blocks from the values of C_u (kept
        contributions, :meth:`_cu_entries` order) and C_λ ((n_c, d, d), β² included)."""
        if self._blocks is None:
            self._setup_blocks(self.c_jump.tocoo())
        assert self._blocks is not None
        bt, cu_pattern = self._blocks
        return BlockJacobian(self.free_block(), bt, cu_pattern.fill(cu), block_diag_csr(cl))

    def _setup_pattern(self, J):
        """All (row, col) contributions of the Newton Jacobian, restricted to free dofs, built once
        (on N ranks: this rank's rows, distributed numbering)."""
        n = self.free.size + self.n_c * self.dim
        blocks, values = self.jacobian_blocks(J)
        self.pattern = jacobian_pattern(blocks, n, self.layout)
        self._fixed_vals = np.concatenate([self.pattern.take(k, values[k]) for k in (Block.ELASTIC, Block.MULTIPLIER)])

    # ---- loads ----------------------------------------------------------------------------
    def dirichlet_vector(self, t: float = 0.0) -> np.ndarray:
        """(n_dofs,) prescribed values on Dirichlet dofs, 0 elsewhere (m)."""
        d = self.dim
        u = np.zeros((self.space.n_slots, d))
        for slot, comps, fn in self._dir_groups:
            val = np.asarray(fn(self.slot_points[slot], t), float).reshape(len(slot), d)
            u[np.ix_(slot, comps)] = val[:, comps]
        return u.ravel()

    def load_vector(self, t: float = 0.0) -> np.ndarray:
        """(n_dofs,) right-hand side ℓ(v): body force, tractions, Biot, fracture pressure, σ⁰ (N)."""
        mesh, d = self.fm.mesh, self.dim
        g = mesh.geometry
        data = self.data
        F = np.zeros((self.space.n_slots, d))
        # cell integrals by the operators' quadrature: one point per cell (x̄_K, |K|) for order 1
        ops = self.ops
        xq, wq, cq = ops.qp_point, ops.qp_weight, ops.qp_cell
        if data.body_force is not None:
            f = np.asarray(data.body_force(xq, t), float).reshape(-1, d)
            F += ops.value.T @ (wq[:, None] * f)
        for bc in data.traction:
            faces = self._boundary_faces(bc.boundary, f"traction.{bc.boundary}")
            if isinstance(self.space, DisplacementSpace):
                gv = np.asarray(bc.value(g.face_centroid[faces], t), float).reshape(-1, d)
                if bc.boundary not in self._face_means:
                    self._face_means[bc.boundary] = face_mean_operator(self.space, faces)
                F += self._face_means[bc.boundary].T @ (g.face_area[faces][:, None] * gv)
                continue
            # order 2: ∫_σ g·v with the P2 trace, by a face rule exact for quadratic g
            if bc.boundary not in self._face_means:
                self._face_means[bc.boundary] = self.space.trace_quadrature(faces)
            P, W, V = self._face_means[bc.boundary]
            gv = np.asarray(bc.value(P, t), float).reshape(-1, d)
            F += V.T @ (W[:, None] * gv)
        if data.matrix_pressure is not None:
            p = np.asarray(data.matrix_pressure(xq, t), float) * np.broadcast_to(data.biot, (mesh.n_cells,))[cq]
            for j in range(d):
                F[:, j] += ops.D[j].T @ (wq * p)
        if data.initial_stress is not None:
            S0 = np.asarray(data.initial_stress(xq, t), float).reshape(-1, d, d)
            for i in range(d):
                for j in range(d):
                    F[:, i] -= ops.D[j].T @ (wq * S0[:, i, j])
        if data.fracture_pressure is not None and self.n_ff:
            pf = np.asarray(data.fracture_pressure(g.face_centroid[self.fm.network.faces], t), float)
            F -= self.jump_scalar.T @ ((self.face_area * pf)[:, None] * self.normal)
        return F.ravel()

    # ---- Newton ----------------------------------------------------------------------------
    def split(self, x, udir):
        """(u (n_dofs,), λ (n_c, d) per patch, Pa) of a Newton vector."""
        nfree = self.free.size
        u = udir.copy()
        u[self.free] = x[:nfree]
        lam = x[nfree:].reshape(self.n_c, self.dim) * self.law.beta[:, None]
        return u, lam

    def friction_state(self, state: np.ndarray | None) -> np.ndarray:
        """(n_c, k) the friction law's state ``state``, or its initial state for None."""
        return self.law.friction_law.initial_state(self.n_c) if state is None else state

    def start_friction(self, lam: np.ndarray) -> np.ndarray:
        """(n_c, k) the friction law's state at the start of a run whose initial tractions are the
        face multipliers ``lam`` (n_ff, d), Pa (a rate law's initial state follows from them)."""
        lp = self.patch_values(lam)
        ln = np.einsum("fi,fi->f", lp, self.c_normal)
        lt = np.linalg.norm(lp - ln[:, None] * self.c_normal, axis=1)
        return self.law.friction_law.start(self.friction_state(None), ln, lt)

    def advance_friction(self, state: np.ndarray | None, u: np.ndarray, q_old: np.ndarray | None,
                         dt: float, lam: np.ndarray | None = None) -> np.ndarray:
        """(n_c, k) the friction law's state after a step that took the patch jumps from ``q_old``
        (n_c, d; None: zero) to those of the displacements ``u`` (n_slots·d,), m; ``lam`` (n_c, d)
        the step's multipliers (Pa), which a rate law takes its slip rate from."""
        q = (self.Jcv @ np.ravel(u)).reshape(self.n_c, self.dim)
        s = q if q_old is None else q - q_old
        n = self.c_normal
        s = s - np.einsum("fi,fi->f", s, n)[:, None] * n
        fl, st = self.law.friction_law, self.friction_state(state)
        if isinstance(fl, RateLaw) and lam is not None and dt > 0:
            # V from the trial traction y = λ + βs, not from |s|/Δt: at V Δt far below the jumps'
            # round-off (1e-12 m/s over 1e-9 s is 1e-21 m of a 1e-3 m jump) the slip is noise,
            # while the traction fixes V to the local solve's accuracy
            b = self.law.beta
            ln = np.einsum("fi,fi->f", lam, n)
            yn = ln + b * np.einsum("fi,fi->f", q, n)
            yt = lam - ln[:, None] * n + b[:, None] * s
            rate = fl.trial_radius(yn, np.linalg.norm(yt, axis=1), st, dt, b).rate
            assert rate is not None             # a rate law's trial radius carries its rate
            return fl.advance_at(st, rate, dt)
        return fl.advance(st, s, dt)

    def patch_values(self, face_values: np.ndarray) -> np.ndarray:
        """(n_c, ...) patch means of face values (n_ff, ...) (the values themselves on faces
        that are their own patch)."""
        return face_values if self.patches.identity else self.patches.mean @ face_values

    def state_counts(self, state: np.ndarray) -> dict:
        """{"open", "stick", "slip"}: fracture faces in each state, from the patch states (n_c,)."""
        c = np.bincount(self.face_values(np.asarray(state, np.int64)), minlength=3)
        return {"open": int(c[OPEN]), "stick": int(c[STICK]), "slip": int(c[SLIP])}

    def face_values(self, patch_values: np.ndarray) -> np.ndarray:
        """(n_ff, ...) the value of each face's patch."""
        return patch_values if self.patches.identity else self.patches.expand(patch_values)

    def linearise(self, x, F, udir, q_old=None, friction=None) -> Linearisation:
        """Residual and Jacobian at x; ``q_old`` (n_c, d) the patch jumps of the previous step,
        ``friction`` (n_c, k) the friction law's state before it (None: its initial state)."""
        d, nf = self.dim, self.n_c
        u, lam = self.split(x, udir)
        q = (self.Jcv @ u).reshape(nf, d)
        s = q if q_old is None else q - q_old
        C, dC_dlam, dC_dq, state = linearise_contact(self.law, lam, q, s, self.c_normal, self.c_area, friction)
        Au, Bl = self.A @ u, self.Bcv.T @ lam.ravel()          # A: a RowBlock on N ranks (gathered)
        Ru = Au + Bl - F
        Ru_f = Ru[self.free]
        b = self.law.beta
        Jac: BlockJacobian | OwnedRows | sp.csr_array
        if self.blockwise:
            jrow, jval, keep = self.contact_jump_entries
            Jac = self.jacobian_by_blocks((dC_dq[jrow] * (jval * b[jrow])[:, None, None])[keep],
                                          dC_dlam * (b * b)[:, None, None])
        else:
            if self.pattern is None:
                self._setup_pattern(self.c_jump.tocoo())
            jrow, jval, keep = self.contact_jump_entries
            pat = self.pattern
            assert pat is not None
            cu = (dC_dq[jrow] * (jval * b[jrow])[:, None, None])[keep]
            Jac = pat.fill([self._fixed_vals, pat.take(Block.CONTACT_JUMP, cu),
                            pat.take(Block.CONTACT_MULTIPLIER, dC_dlam * (b * b)[:, None, None])])
            if self.layout is not None:
                Jac = OwnedRows(Jac, self.layout)
        # scales: the work-conjugate size of each block (energy-norm scaling)
        # (A u over all dofs includes the Dirichlet reactions, the load of a purely kinematic case)
        su = max(float(np.linalg.norm(F)), float(np.linalg.norm(Au)), float(np.linalg.norm(Bl)), 1e-300)
        sc = max(float(np.linalg.norm(self.c_area[:, None] * q)),
                 float(np.linalg.norm((self.c_area / self.law.beta)[:, None] * lam)), 1e-300)
        norms = {"equilibrium": float(np.linalg.norm(Ru_f) / su)}
        if nf:
            norms["contact"] = float(np.linalg.norm(C) / sc)
        counts = self.state_counts(state) if nf else {}
        # the residual rows are N: equilibrium, and contact C_σ β_σ; dividing by the block scales
        # gives the weights whose 2-norm is Newton's measure (iterative solves stop in it)
        w = row_weights(np.full(Ru_f.size, su), np.repeat(b * sc, d))
        return Linearisation(np.concatenate([Ru_f, (C * b[:, None]).ravel()]), Jac, norms, counts, state,
                             row_scale=w)

    def solve(self, t: float = 0.0, initial: MechanicsState | None = None, q_old: np.ndarray | None = None,
              verbose: bool = True, friction: np.ndarray | None = None) -> MechanicsState:
        """Solve the static problem at time t (loads evaluated at t).

        A load step of a quasi-static sequence passes the previous step's patch jumps ``q_old``
        (n_c, d) and the friction law's state after it ``friction`` (n_c, k): the slip is then the
        step's increment. The returned state carries the law's state after this step.

        Starts from ``initial`` or, by default, from u = Dirichlet values and every fracture face
        closed and stuck (λ = tiny compression), whose linearisation is the bonded problem; with
        ``contact.initial = "open"`` from λ = 0 (every face open: fewer iterations when most of
        Γ opens, but singular if some block is held by contact alone).
        """
        t0 = time.perf_counter()
        F = self.load_vector(t)
        udir = self.dirichlet_vector(t)
        nfree = self.free.size
        x0 = np.zeros(nfree + self.n_c * self.dim)
        if initial is not None:
            x0[:nfree] = initial.u.ravel()[self.free]
            x0[nfree:] = (self.patch_values(initial.lam) / self.law.beta[:, None]).ravel()
        else:
            x0[nfree:] = self.closed_start(F)
        t1 = time.perf_counter()

        def incr(dx, x):
            du = np.linalg.norm(dx[:nfree]) / max(np.linalg.norm(x[:nfree] + dx[:nfree]), 1e-300)
            dl = np.linalg.norm(dx[nfree:]) / max(np.linalg.norm(x[nfree:] + dx[nfree:]), 1e-300) if self.n_ff else 0
            return float(max(du, dl))

        res = semismooth_newton(lambda x: self.linearise(x, F, udir, q_old, friction), x0, self.solver, incr,
                                self.newton, verbose)
        u, lam = self.split(res.x, udir)
        assert res.active_set is not None          # a contact Newton reports its states
        law_state = self.advance_friction(friction, u, q_old, 0.0)
        return MechanicsState(u.reshape(-1, self.dim), self.face_values(lam), self.face_values(res.active_set), t,
                              res.iterations, res.residual, res.history,
                              {"loads": t1 - t0, "assembly": res.seconds_assembly, "linear": res.seconds_linear,
                               "total": time.perf_counter() - t0}, law_state)

    def closed_start(self, F: np.ndarray) -> np.ndarray:
        """(n_c d,) the first iterate's λ̃ = λ/β: every patch closed and stuck under a tiny
        compression (10⁻¹² of the largest load), whose linearisation is the bonded problem;
        zero (every patch open) with ``contact.initial = "open"``."""
        if self.data.contact.initial != "closed":
            return np.zeros(self.n_c * self.dim)
        scale = max(np.abs(F).max(initial=0.0), 1e-300)
        return (1e-12 * scale * self.c_normal / self.law.beta[:, None]).ravel()

    # ---- interpolation -------------------------------------------------------------------------
    def interpolate(self, fn: VectorField, t: float = 0.0) -> np.ndarray:
        """(n_slots, d) interpolate I_D u of a field (scheme.md §3, "Interpolator").

        Nodal slots: u|_K(x_s) (evaluated on the side's own piece for data discontinuous across
        Γ); bubbles: (1/|σ|)∫_σ γ^{Kσ}u − the nodal face mean from K, the face integral by a
        quadrature exact for quadratics on the face's sub-triangles (3D) or 3-point Gauss (2D).
        Order 2: point slots take u at vertices and edge midpoints, the face bubbles (mean 1)
        the face mean of u minus that of the P2 trace; quadratic fields are reproduced.
        """
        d = self.dim
        u = np.zeros((self.space.n_slots, d))
        npt = self.space.n_point_slots
        u[:npt] = np.asarray(fn(self.slot_points, t), float).reshape(-1, d)
        if self.space.n_bubbles:
            mesh = self.fm.mesh
            faces = self.fm.network.faces[self.space.bubble_face]
            cells = self.space.bubble_cell
            mean = _face_average(mesh, faces, cells, fn, t)
            u[npt:] = mean - self._face_mean(faces, cells) @ u
        return u

    # ---- post-processing ---------------------------------------------------------------------
    def jumps(self, st: MechanicsState) -> np.ndarray:
        """(n_ff, d) mean jump [[u]]_σ in m."""
        return self.jump_scalar @ st.u

    def jump_parts(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n_ff, d) each: the parts of the mean jump [[u]]_σ (``jump_scalar @ u``, u (n_slots, d))
        from the point slots (nodes; with order 2 also edge points) and from the face bubbles, m.
        A jump carried by a bubble alone is a cell-local mode, not a displacement of the fault's
        sides (docs/fault_bounds.md, the sliver that runs away)."""
        J = sp.csc_array(self.jump_scalar)
        npt = self.space.n_point_slots                   # bubble slots come after the point slots
        u = np.asarray(u, float).reshape(J.shape[1], -1)
        return J[:, :npt] @ u[:npt], J[:, npt:] @ u[npt:]

    def gradients(self, st: HasDisplacement) -> np.ndarray:
        """(n_cells, d, d) ∇^K u (order 2: the cell mean of ∇u)."""
        return self.ops.gradient(st.u)

    def stress(self, st: HasDisplacement) -> np.ndarray:
        """(n_cells, d, d) σ^K = 2μ ε^K + λ_L div^K I in Pa (without σ⁰ and the Biot term)."""
        G = self.gradients(st)
        eps = 0.5 * (G + G.transpose(0, 2, 1))
        tr = np.trace(eps, axis1=1, axis2=2)
        return 2 * self.mu[:, None, None] * eps + (self.lam * tr)[:, None, None] * np.eye(self.dim)

    def cell_displacement(self, st: HasDisplacement) -> np.ndarray:
        """(n_cells, d) Π^K u at the cell centroid (= ū_K; order 2: the cell mean of u), m."""
        return self.ops.mean @ st.u

    def node_displacement(self, st: HasDisplacement) -> np.ndarray:
        """(n_nodes, d) nodal displacement (average over the node's sides), m."""
        sides = self.fm.sides
        n = self.fm.mesh.n_nodes
        cnt = np.bincount(sides.side_node, minlength=n)
        out = np.stack([np.bincount(sides.side_node, weights=st.u[: sides.n_sides, k], minlength=n)
                        for k in range(self.dim)], 1)
        return out / np.maximum(cnt, 1)[:, None]


def _vector_jump(J: sp.sparray, area: np.ndarray, n_dofs: int, d: int) -> tuple[sp.csr_array, sp.csr_array]:
    """The vector forms (n d, n_dofs) of a scalar jump operator J (n, n_slots): J ⊗ I_d and
    |σ| J ⊗ I_d (the equilibrium coupling B), for n faces or patches of measure ``area``."""
    J = J.tocoo()
    rows = (J.row[:, None].astype(np.int64) * d + np.arange(d)).ravel()
    cols = (J.col[:, None].astype(np.int64) * d + np.arange(d)).ravel()
    vals = np.repeat(J.data, d)
    shape = (J.shape[0] * d, n_dofs)
    return (sp.csr_array((vals, (rows, cols)), shape=shape),
            sp.csr_array((vals * np.repeat(area[J.row], d), (rows, cols)), shape=shape))
