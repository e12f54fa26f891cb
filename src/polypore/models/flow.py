"""Single-phase mixed-dimensional Darcy flow with discontinuous matrix–fracture pressures.

HFV scheme of scheme.md §5 on the matrix cells and on the fracture mesh, coupled by the
exchange law F_Kσ = |σ| (Λ_f/η)(p_Kσ − p_f,σ) on each side of every fracture face.
Steady solves and implicit-Euler steps; cell pressures are eliminated cell by cell
(``polypore.assembly.flow``) and recovered after the global solve.

Conventions and units
---------------------
* Pressures in Pa, lengths in m, times in s. Fluxes F are volumetric rates in m³/s
  (per metre of thickness in 2D) and positive **outward** (out of a cell, out of a
  fracture face, out of Ω, from the matrix into the fracture for exchange fluxes).
* Values (boundary data, sources, apertures) are numbers, arrays with one entry per
  entity, or callables ``f(x, y, z, t)`` vectorised over points (z = 0 in 2D), e.g.
  :class:`polypore.core.expressions.Expression`.
* Boundary faces without a condition are no-flow. Fracture edges on ∂Ω take the matrix
  condition of their boundary part: a pressure there is also the fracture's pressure;
  otherwise the fracture end is no-flow unless ``fracture_boundary`` gives it a pressure.
  Tips are no-flow.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from ..assembly.flow import FlowAssembler, FlowSystem
from ..core.errors import InputError
from ..discretisation.hfv import CELL_POINTS
from ..parallel.layout import distribute, min_owner
from ..parallel.context import context
from ..solvers.factory import SolverChoice, SolverSource, build
from ..core.timing import SPLIT


def cubic_law(aperture: np.ndarray) -> np.ndarray:
    """Fracture conductivity C_f(d_f) = d_f³/12 in m³ (scheme.md §2 **Choice**)."""
    return aperture ** 3 / 12.0


def normal_transmissivity(aperture: np.ndarray, normal_permeability: np.ndarray) -> np.ndarray:
    """Λ_f(d_f) = 2 K_fn/d_f in m (scheme.md §2 **Choice**); exchange flux = (Λ_f/η) Δp."""
    return 2.0 * normal_permeability / aperture


@dataclass(frozen=True)
class FlowData:
    """Physical data of the flow model.

    Attributes
    ----------
    permeability : float, (d, d), (n_cells,) or (n_cells, d, d)
        Matrix permeability K_m in m², symmetric positive definite.
    viscosity : float
        Dynamic viscosity η in Pa·s (> 0).
    biot_modulus : float or (n_cells,) array
        Biot modulus M in Pa (> 0); ``inf`` (default) means no matrix storage.
    biot_coefficient : float
        Biot coefficient b (dimensionless, ≥ 0); used by the poromechanics coupling.
    aperture : float, (n_ff,) or callable
        Fracture aperture d_f in m (> 0).
    normal_permeability : float or (n_ff,)
        Fracture normal permeability K_fn in m² (> 0).
    conductivity_law : callable d_f -> C_f
        Tangential fracture conductivity in m³ (default cubic law d_f³/12).
    normal_transmissivity_law : callable (d_f, K_fn) -> Λ_f
        Normal transmissivity in m (default 2 K_fn/d_f).
    fracture_compressibility : float
        c_f in 1/Pa (≥ 0): fracture storage |σ| d_f c_f (p_f^n − p_f^{n−1})/Δt (default 0).
    """

    permeability: object = 1e-15
    viscosity: float = 1e-3
    biot_modulus: float = np.inf
    biot_coefficient: float = 1.0
    aperture: object = 1e-4
    normal_permeability: object = 1e-15
    conductivity_law: Callable = cubic_law
    normal_transmissivity_law: Callable = normal_transmissivity
    fracture_compressibility: float = 0.0


@dataclass(frozen=True)
class Pressure:
    """Dirichlet condition: pressure ``value`` in Pa (number or f(x, y, z, t))."""

    value: object = 0.0


@dataclass(frozen=True)
class Flux:
    """Neumann condition: outward flux density ``value`` in m³/s per m² (m/s); < 0 injects.

    ``Flux(0.0)`` (:data:`NO_FLOW`) is the no-flow condition.
    """

    value: object = 0.0


NO_FLOW = Flux(0.0)


@dataclass(frozen=True, eq=False)
class FlowSolution:
    """All pressures and fluxes of one solve (scheme.md §5 unknowns), SI units.

    Attributes
    ----------
    time : float, s.
    cell : (n_cells,) p_K.  face : (n_faces,) p_σ (NaN on fracture faces: see ``trace``).
    trace : (n_ff, 2) p_Kσ on the + and − sides.  fracture : (n_ff,) p_f.  edge : (n_e,) p_e.
    aperture : (n_ff,) d_f used for the storage of this state, m.
    cell_flux : (nnz(cell_faces),) F_Kσ out of each cell through each face, m³/s.
    exchange : (n_ff, 2) matrix → fracture flux on the + and − sides, m³/s.
    fracture_flux : (nnz(face_edges),) F_σe out of each fracture face through each of its
        edges (order of ``FlowModel.fracture_cells.face_edges``), m³/s.
    boundary_flux : dict name -> outflow through that boundary part (matrix + fracture ends), m³/s.
    fracture_boundary_flux : dict name -> outflow of the fractures through that part, m³/s.
    timings : dict of seconds (assembly, condensation, solve, recovery).
    """

    time: float
    cell: np.ndarray
    face: np.ndarray
    trace: np.ndarray
    fracture: np.ndarray
    edge: np.ndarray
    aperture: np.ndarray
    cell_flux: np.ndarray = field(repr=False)
    exchange: np.ndarray = field(repr=False)
    fracture_flux: np.ndarray = field(repr=False)
    boundary_flux: dict = field(default_factory=dict)
    fracture_boundary_flux: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict, repr=False)


def evaluate(value, points: np.ndarray, t: float, field_name: str, n: int | None = None) -> np.ndarray:
    """Evaluate a number, a per-entity array or f(x, y, z, t) at points (k, d) -> (k,)."""
    k = points.shape[0]
    if callable(value):
        x = points[:, 0]
        y = points[:, 1]
        z = points[:, 2] if points.shape[1] > 2 else np.zeros(k)
        try:
            out = np.asarray(value(x, y, z, t), float)
        except InputError:
            raise
        except Exception as exc:
            raise InputError(field_name, f"could not evaluate the function: {exc}") from None
        out = np.broadcast_to(out, (k,)).copy() if out.ndim == 0 or out.shape == (k,) else out
    else:
        try:
            out = np.asarray(value, float)
        except (TypeError, ValueError):
            raise InputError(field_name, f"expected a number, an array or a function f(x, y, z, t), "
                             f"got {value!r}") from None
        if out.ndim == 0:
            out = np.full(k, float(out))
    if out.shape != (k,):
        raise InputError(field_name, f"expected one value per entity ({k}), got shape {out.shape}")
    if not np.all(np.isfinite(out)):
        raise InputError(field_name, "values must be finite numbers")
    return out


def _positive(value, name: str, allow_inf=False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(name, f"must be a number, got {value!r}") from None
    if not (v > 0) or (np.isinf(v) and not allow_inf) or np.isnan(v):
        raise InputError(name, f"must be a positive number{' (inf allowed)' if allow_inf else ''}, got {value!r}")
    return v


def permeability_tensor(value, n_cells: int, dim: int, name: str = "permeability") -> np.ndarray:
    """(n_cells, d, d) SPD tensors from a scalar, (d, d), (n_cells,) or (n_cells, d, d) value."""
    K = np.asarray(value, float)
    if K.ndim == 0:
        K = np.broadcast_to(float(K) * np.eye(dim), (n_cells, dim, dim))
    elif K.shape == (dim, dim):
        K = np.broadcast_to(K, (n_cells, dim, dim))
    elif K.shape == (n_cells,):
        K = K[:, None, None] * np.eye(dim)[None]
    elif K.shape != (n_cells, dim, dim):
        raise InputError(name, f"expected a number, a ({dim}, {dim}) tensor, one value per cell ({n_cells}) "
                         f"or ({n_cells}, {dim}, {dim}) tensors; got shape {K.shape}")
    K = np.ascontiguousarray(K)
    if not np.all(np.isfinite(K)):
        raise InputError(name, "values must be finite")
    scale = np.abs(K).max(axis=(1, 2))
    asym = np.abs(K - K.transpose(0, 2, 1)).max(axis=(1, 2))
    ev = np.linalg.eigvalsh(0.5 * (K + K.transpose(0, 2, 1)))
    bad = (asym > 1e-12 * scale) | ~(ev[:, 0] > 1e-14 * np.maximum(scale, 1e-300)) | ~(scale > 0)
    if np.any(bad):
        c = int(np.flatnonzero(bad)[0])
        raise InputError(name, f"must be symmetric positive definite (m²); cell {c} has {K[c].tolist()} with "
                         f"eigenvalues {ev[c].tolist()}")
    return K


class FlowModel:
    """Mixed-dimensional HFV flow on a fractured mesh (scheme.md §5).

    Parameters
    ----------
    fmesh : FracturedMesh
    data : FlowData
    boundary : mapping boundary name -> Pressure | Flux
        Conditions on named boundary parts; faces without one are no-flow.
    fracture_boundary : mapping boundary name -> Pressure | Flux(0)
        Conditions of the fracture ends (edges on ∂Ω) on that part, to give a pressure
        where the matrix is impervious. Contradicting the matrix's pressure condition on the
        same part (no-flow, or another pressure) raises InputError.
    cell_source : number, (n_cells,) or f(x, y, z, t)
        h_m in m³/s per m³ (1/s), evaluated at cell centroids.
    fracture_source : number, (n_ff,) or f(x, y, z, t)
        h_f in m³/s per m² of fracture (m/s), at fracture face centroids.
    alpha, fracture_alpha : float, optional
        HFV stabilisation (defaults √d and √(d−1)).
    cell_point : "auto" (default) or "centroid"
        HFV cell points (`discretisation.hfv.matrix_hfv`).
    solver : a ready solver or a :class:`~polypore.solvers.factory.SolverChoice` (plain backends), optional
        Default ``SolverChoice("auto", symmetric=True)``.
    """

    def __init__(self, fmesh, data: FlowData, boundary: Mapping | None = None, *,
                 fracture_boundary: Mapping | None = None, cell_source=0.0, fracture_source=0.0,
                 alpha=None, fracture_alpha=None, solver: SolverSource = None, cell_point: str = "auto"):
        t0 = time.perf_counter()
        self.fmesh = fmesh
        self.mesh = mesh = fmesh.mesh
        self.network = net = fmesh.network
        self.data = data
        self.viscosity = _positive(data.viscosity, "viscosity")
        M = np.asarray(data.biot_modulus, float)
        self.biot_modulus: float | np.ndarray
        if M.ndim == 0:
            self.biot_modulus = _positive(data.biot_modulus, "biot_modulus", allow_inf=True)
        elif M.shape == (mesh.n_cells,) and np.all(M > 0):
            self.biot_modulus = M                               # per cell (layered storage), Pa
        else:
            raise InputError("biot_modulus", f"expected a positive number or one per cell ({mesh.n_cells}), "
                             f"got shape {M.shape}")
        b = float(data.biot_coefficient)
        if not (b >= 0 and np.isfinite(b)):
            raise InputError("biot_coefficient", f"must be a finite number ≥ 0, got {data.biot_coefficient!r}")
        cf = float(data.fracture_compressibility)
        if not (cf >= 0 and np.isfinite(cf)):
            raise InputError("fracture_compressibility", f"must be a finite number ≥ 0 (1/Pa), got {cf!r}")
        self.permeability = permeability_tensor(data.permeability, mesh.n_cells, mesh.dim)
        for a, nm in ((alpha, "alpha"), (fracture_alpha, "fracture_alpha")):
            if a is not None:
                _positive(a, nm)
        self.normal_permeability = self._positive_array(
            evaluate(data.normal_permeability, self._ff_points(), 0.0, "normal_permeability"),
            "normal_permeability", "m²")
        self.aperture0 = self.aperture(0.0)
        self.cell_source = cell_source
        self.fracture_source = fracture_source
        self.solver = build(solver, default=SolverChoice("auto", symmetric=True))
        self._resolve_boundary(dict(boundary or {}), dict(fracture_boundary or {}))
        t1 = time.perf_counter()
        if cell_point not in CELL_POINTS:
            raise InputError("cell_point", f"must be one of {', '.join(CELL_POINTS)}, got {cell_point!r}")
        self.assembler = FlowAssembler(mesh, net, self.permeability / self.viscosity, alpha, fracture_alpha,
                                       cell_point)
        self.fracture_cells = self.assembler.fcells
        self.setup_seconds = {"validation": t1 - t0, "local_operators_and_pattern": time.perf_counter() - t1}
        self._cache: tuple | None = None
        self._distributed = False

    # -- distributed runs (parallel/layout.py) ---------------------------------------------
    def dof_owner(self, part: np.ndarray) -> np.ndarray:
        """(n_dofs,) owner rank of every HFV unknown (face, trace, fracture, edge pressures) for the
        cell ranks ``part``: the lowest rank among the cells of a face; a fracture face's traces
        and pressure its + side cell's; an edge the lowest among its fracture faces'."""
        d = self.assembler.dofs
        cf = self.mesh.cell_faces
        own = min_owner(d.n, d.slot, part[cf.rows_of_entries()], fill=-1)
        fown = part[self.network.plus_cell]
        own[d.trace.ravel()] = np.repeat(fown, 2)
        own[d.frac] = fown
        fe = self.fracture_cells.face_edges
        if d.edge.size and fe.nnz:
            eo = min_owner(d.edge.size, fe.values, fown[fe.rows_of_entries()], fill=-1)
            own[d.edge] = eo
        return np.maximum(own, 0)

    def _distribute(self):
        """Under mpiexec: the layout of the free unknowns of :meth:`_system`, given to the solver
        (at the first solve: a flow model inside the coupled model never solves on its own)."""
        if self._distributed or context() is None:
            return
        self._distributed = True
        ids, _, _ = self.dirichlet(0.0)
        free = np.ones(self.assembler.dofs.n, bool)
        free[ids] = False
        distribute(self.solver, self.mesh, lambda part: self.dof_owner(part)[free])

    # -- data ---------------------------------------------------------------------------------
    def _ff_points(self) -> np.ndarray:
        return self.mesh.geometry.face_centroid[self.network.faces]

    @staticmethod
    def _positive_array(v, name, unit):
        if not np.all(v > 0):
            i = int(np.flatnonzero(~(v > 0))[0])
            raise InputError(name, f"must be positive ({unit}); fracture face {i} has {v[i]!r}")
        return v

    def aperture(self, t: float) -> np.ndarray:
        """(n_ff,) d_f from ``data.aperture`` at time t, m; InputError unless > 0."""
        return self._positive_array(evaluate(self.data.aperture, self._ff_points(), t, "aperture"),
                                    "aperture", "m")

    def _edge_points(self) -> np.ndarray:
        en = self.network.edge_nodes
        return self.mesh.nodes[en].mean(axis=1)

    def _group(self, name: str, fld: str) -> np.ndarray:
        try:
            return self.mesh.boundary_group(name)
        except InputError as exc:
            raise InputError(fld, exc.detail) from None

    def _resolve_boundary(self, boundary: dict, fracture_boundary: dict):
        mesh, net = self.mesh, self.network
        owner = np.full(mesh.n_faces, -1)
        conds: list = []
        for name, cond in boundary.items():
            faces = self._group(name, f"boundary.{name}")
            if not isinstance(cond, (Pressure, Flux)):
                raise InputError(f"boundary.{name}", f"expected Pressure(value) or Flux(value), got {cond!r}")
            taken = faces[owner[faces] >= 0]
            if taken.size:
                other = conds[owner[taken[0]]]
                if other[1] != cond:
                    raise InputError(f"boundary.{name}", f"face {int(taken[0])} also belongs to boundary "
                                     f"{other[0]!r} with a different condition ({other[1]!r} vs {cond!r}); "
                                     "overlapping boundary parts must carry the same condition")
            owner[faces] = len(conds)
            conds.append((name, cond))
        self._face_conditions = [(name, cond, np.flatnonzero(owner == i)) for i, (name, cond) in enumerate(conds)]
        # fracture ends: edges lying on each named boundary part
        ne = net.edge_nodes.shape[0]
        nn = mesh.n_nodes
        if mesh.dim == 2:
            ekeys = net.edge_nodes[:, 0].astype(np.int64)
        else:
            en = net.edge_nodes.astype(np.int64)
            ekeys = en[:, 0] * nn + en[:, 1]
        on_part = {}
        for name, faces in mesh.boundary.items():
            if faces.size == 0 or ne == 0:
                continue
            sub = mesh.face_nodes.take(faces)
            if mesh.dim == 2:
                keys = np.unique(sub.values.astype(np.int64))
            else:
                nxt = np.arange(sub.nnz) + 1
                nxt[sub.offsets[1:] - 1] = sub.offsets[:-1]
                a, b = sub.values.astype(np.int64), sub.values[nxt].astype(np.int64)
                keys = np.unique(np.minimum(a, b) * nn + np.maximum(a, b))
            hit = np.isin(ekeys, keys)
            if hit.any():
                on_part[name] = np.flatnonzero(hit)
        for name, cond in fracture_boundary.items():
            fld = f"fracture_boundary.{name}"
            self._group(name, fld)
            if not isinstance(cond, (Pressure, Flux)):
                raise InputError(fld, f"expected Pressure(value) or Flux(0) (no-flow), got {cond!r}")
            if isinstance(cond, Flux) and not (not callable(cond.value) and np.all(np.asarray(cond.value) == 0)):
                raise InputError(fld, f"fracture ends accept a pressure or no-flow (Flux(0)), got {cond!r}")
            matrix = boundary.get(name)
            if isinstance(matrix, Pressure) and cond != matrix:
                what = "no-flow" if isinstance(cond, Flux) else f"pressure {cond.value!r}"
                raise InputError(fld, f"{what} conflicts with the pressure condition {matrix.value!r} of the "
                                 f"matrix on boundary {name!r}: a fracture reaching a pressure boundary takes that "
                                 "pressure; remove this entry or change the matrix condition")
        effective = {}
        for name in on_part:
            if name in fracture_boundary:
                effective[name] = fracture_boundary[name]
            elif isinstance(boundary.get(name), Pressure):
                effective[name] = boundary[name]
            elif name in boundary:
                effective[name] = NO_FLOW
        edge_owner = np.full(ne, -1)
        econds: list = []
        for name, cond in effective.items():
            edges = on_part[name]
            taken = edges[edge_owner[edges] >= 0]
            if taken.size:
                oname, ocond = econds[edge_owner[taken[0]]]
                if ocond != cond:
                    x = self._edge_points()[taken[0]].tolist()
                    raise InputError(f"fracture_boundary.{name}",
                                     f"the fracture end at {x} lies on boundary parts {oname!r} ({ocond!r}) and "
                                     f"{name!r} ({cond!r}): it is given both conditions; make them agree")
            edge_owner[edges] = len(econds)
            econds.append((name, cond))
        self._edge_conditions = [(name, cond, np.flatnonzero(edge_owner == i)) for i, (name, cond) in enumerate(econds)]
        self.edge_parts = on_part

    def dirichlet(self, t: float):
        """Dirichlet dof ids and values at time t, and the Neumann face fluxes (n_faces,)."""
        g = self.mesh.geometry
        dofs = self.assembler.dofs
        ids, vals = [], []
        qflux = np.zeros(self.mesh.n_faces)
        for name, cond, faces in self._face_conditions:
            v = evaluate(cond.value, g.face_centroid[faces], t, f"boundary.{name}")
            if isinstance(cond, Pressure):
                ids.append(dofs.face[faces])
                vals.append(v)
            else:
                qflux[faces] = v * g.face_area[faces]
        pts = self._edge_points()
        for name, cond, edges in self._edge_conditions:
            if isinstance(cond, Pressure):
                ids.append(dofs.edge[edges])
                vals.append(evaluate(cond.value, pts[edges], t, f"boundary.{name}"))
        return (np.concatenate(ids) if ids else np.zeros(0, np.int64), np.concatenate(vals) if vals else np.zeros(0),
                qflux)

    def sources(self, t: float):
        """Cell and fracture source volumes per second: |K| h_m (n_cells,), |σ| h_f (n_ff,), m³/s."""
        g = self.mesh.geometry
        hm = evaluate(self.cell_source, g.cell_centroid, t, "cell_source") * g.cell_volume
        hf = evaluate(self.fracture_source, self._ff_points(), t, "fracture_source") \
            * g.face_area[self.network.faces]
        return hm, hf

    # -- solves -------------------------------------------------------------------------------
    def _system(self, dt: float | None, aperture: np.ndarray) -> tuple:
        key = (dt, aperture.tobytes())
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1:]
        t0 = time.perf_counter()
        g = self.mesh.geometry
        area = g.face_area[self.network.faces]
        eta = self.viscosity
        if dt is None:
            s_cell = np.zeros(self.mesh.n_cells)
            s_frac = np.zeros(self.network.n_faces)
        else:
            s_cell = g.cell_volume / (self.biot_modulus * dt)
            s_frac = area * aperture * float(self.data.fracture_compressibility) / dt
        lam = np.asarray(self.data.normal_transmissivity_law(aperture, self.normal_permeability), float)
        cond = np.asarray(self.data.conductivity_law(aperture), float)
        lam = np.broadcast_to(lam, aperture.shape)
        cond = np.broadcast_to(cond, aperture.shape)
        if not (np.all(lam > 0) and np.all(np.isfinite(lam))):
            raise InputError("normal_transmissivity_law", "must return positive finite values (m)")
        if not (np.all(cond >= 0) and np.all(np.isfinite(cond))):
            raise InputError("conductivity_law", "must return non-negative finite values (m³)")
        system = self.assembler.system(s_cell, area * lam / eta, cond / eta, s_frac)
        t1 = time.perf_counter()
        ids, _, _ = self.dirichlet(0.0)
        free = np.ones(self.assembler.dofs.n, bool)
        free[ids] = False
        A = system.A.tocsr()
        fidx = np.flatnonzero(free)
        A_ff = A[fidx][:, fidx]
        A_fd = A[fidx][:, ids]
        t2 = time.perf_counter()
        timings = {"assembly": t1 - t0, **self.assembler.last_timings, "dirichlet_split": t2 - t1}
        self._cache = (key, system, fidx, A_ff, A_fd, timings)
        return system, fidx, A_ff, A_fd, timings

    def _solve(self, t, dt, aperture, cell_rhs, frac_rhs) -> FlowSolution:
        self._distribute()
        with SPLIT.timed("assembly"):
            system, fidx, A_ff, A_fd, timings = self._system(dt, aperture)
            timings = dict(timings)
            t0 = time.perf_counter()
            ids, vals, qflux = self.dirichlet(t)
            asm = self.assembler
            b = asm.rhs(system, cell_rhs, frac_rhs, qflux)
            x = np.zeros(asm.dofs.n)
            x[ids] = vals
        t1 = time.perf_counter()
        with SPLIT.timed("linear"):
            x[fidx] = self.solver.solve(A_ff, b[fidx] - A_fd @ vals)
        t2 = time.perf_counter()
        sol = self._post(system, x, cell_rhs, t, aperture)
        timings.update(rhs=t1 - t0, solve=t2 - t1, recovery=time.perf_counter() - t2)
        object.__setattr__(sol, "timings", timings)
        return sol

    def _post(self, system: FlowSystem, x, cell_rhs, t, aperture) -> FlowSolution:
        asm, mesh, net = self.assembler, self.mesh, self.network
        d = asm.dofs
        p_cell = asm.recover_cells(system, x, cell_rhs)
        F = asm.cell_fluxes(p_cell, x)
        Ff = asm.fracture_fluxes(system, x)
        face = np.full(mesh.n_faces, np.nan)
        ok = d.face >= 0
        face[ok] = x[d.face[ok]]
        # outflow of the fractures through each edge (only ∂Ω edges carry a non-zero sum)
        fe = self.fracture_cells.face_edges
        edge_out = np.bincount(fe.values, weights=Ff, minlength=net.edge_nodes.shape[0])
        cf = mesh.cell_faces
        face_out = np.zeros(mesh.n_faces)
        np.add.at(face_out, cf.values, F)
        bflux, fbflux = {}, {}
        for name, faces in mesh.boundary.items():
            fb = float(edge_out[self.edge_parts[name]].sum()) if name in self.edge_parts else 0.0
            fbflux[name] = fb
            bflux[name] = float(face_out[faces].sum()) + fb
        return FlowSolution(float(t), p_cell, face, x[d.trace], x[d.frac], x[d.edge], np.array(aperture, float),
                            F, asm.exchange_fluxes(system, x), Ff, bflux, fbflux)

    def solve_steady(self, t: float = 0.0, aperture: np.ndarray | None = None) -> FlowSolution:
        """Steady state: Σ_σ F_Kσ = |K| h_m, exchange, fracture and edge balances (scheme.md §5).

        Raises RunError (singular system) for a problem without any pressure condition.
        """
        ap = self.aperture(t) if aperture is None else self._positive_array(
            np.asarray(aperture, float), "aperture", "m")
        hm, hf = self.sources(t)
        return self._solve(t, None, ap, hm, hf)

    def initial_state(self, pressure, t: float = 0.0) -> FlowSolution:
        """A state with all pressures from ``pressure`` (number or f(x, y, z, t)); zero fluxes."""
        g = self.mesh.geometry
        net = self.network
        p_cell = evaluate(pressure, g.cell_centroid, t, "initial_pressure")
        face = evaluate(pressure, g.face_centroid, t, "initial_pressure")
        pf = face[net.faces].copy()
        face[net.faces] = np.nan
        edge = evaluate(pressure, self._edge_points(), t, "initial_pressure")
        z = np.zeros
        return FlowSolution(float(t), p_cell, face, np.stack([pf, pf], 1), pf, edge, self.aperture(t),
                            z(self.mesh.cell_faces.nnz), z((net.n_faces, 2)), z(self.fracture_cells.face_edges.nnz))

    def step(self, old: FlowSolution, dt: float, *, aperture: np.ndarray | None = None,
             cell_rhs_extra: np.ndarray | None = None, fracture_rhs_extra: np.ndarray | None = None) -> FlowSolution:
        """One implicit-Euler step from ``old`` to t = old.time + dt (scheme.md §5–6).

        Matrix storage |K| (p_K^n − p_K^{n−1})/(M Δt); fracture storage
        |σ|(d_f^n − d_f^{n−1})/Δt + |σ| d_f c_f (p_f^n − p_f^{n−1})/Δt. Conductivities use the
        previous aperture d_f^{n−1} = ``old.aperture`` (scheme.md §6).

        Parameters
        ----------
        aperture : (n_ff,) d_f^n, m; default ``data.aperture`` at the new time.
        cell_rhs_extra : (n_cells,) added to the cell balances' right-hand side, m³/s
            (the poromechanics hook: −b |K| (div^K u^n − div^K u^{n−1})/Δt).
        fracture_rhs_extra : (n_ff,) added to the fracture balances' right-hand side, m³/s.
        """
        dt = _positive(dt, "dt")
        t = old.time + dt
        new_ap = self.aperture(t) if aperture is None else self._positive_array(
            np.asarray(aperture, float), "aperture", "m")
        prev_ap = np.asarray(old.aperture, float)
        g = self.mesh.geometry
        area = g.face_area[self.network.faces]
        hm, hf = self.sources(t)
        s_cell = g.cell_volume / (self.biot_modulus * dt)
        s_frac = area * prev_ap * float(self.data.fracture_compressibility) / dt
        cell_rhs = hm + s_cell * old.cell
        frac_rhs = hf + s_frac * old.fracture - area * (new_ap - prev_ap) / dt
        if cell_rhs_extra is not None:
            cell_rhs = cell_rhs + cell_rhs_extra
        if fracture_rhs_extra is not None:
            frac_rhs = frac_rhs + fracture_rhs_extra
        sol = self._solve(t, dt, prev_ap, cell_rhs, frac_rhs)
        object.__setattr__(sol, "aperture", new_ap)
        return sol
