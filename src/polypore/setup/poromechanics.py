"""From a poromechanics case to a :class:`~polypore.models.poromechanics.Poromechanics` model.

The case has the mechanics tables of :mod:`.mechanics` (``[material]``, ``[mechanics]``,
``[contact]``), the flow tables of :mod:`.flow` (``[flow]``), ``[time]`` (:mod:`.schedule`)
and optionally ``[initial_state]`` (:mod:`.insitu`) and ``[monitor]``; ``[mechanics] biot`` is
the Biot coefficient b of both equations.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from ..core.errors import InputError
from ..models.poromechanics import STABILISATION, Poromechanics
from .casefile import CaseFile
from .flow import flow_setup
from .insitu import reference_state
from .limits import machine_memory
from .mechanics import mechanics_setup
from .translate import POROMECHANICS, SOLVER, case_keys

log = logging.getLogger("polypore")

# solver.linear = "auto" on coupled 3D systems of order 1 (resolve_linear; docs/iterative_cornerpoint.md)
# estimated unknowns from which PARDISO on the displacement and pressure blocks (block-direct) wins
# over PARDISO on the whole system, since its block solves skip PARDISO's iterative refinement
# (2026-11-29): emerald (estimated 64,901) 0.83× the CPU time and 0.67× the memory; at about 15,000
# unknowns a tie (cornerpoint-injection 0.88×, grdecl-b 1.23×); docs/iterative_cornerpoint.md
BLOCK_DIRECT_MIN = 40_000
# With PARDISO, block-amg (AMG on the displacement block) only where block-direct's factors would not fit
# (MEMORY_SHARE): on the 10⁵-cell weak-scaling grid block-amg is 0.75× the CPU time and 0.37× the memory,
# but on b.grdecl refined 4 × 4 × 4 (786,744 unknowns) its AMG needs ~90 GMRES iterations per solve and
# more (~1.5 h by the run's own estimate) where block-direct ran in 18 min and 8.2 GB: the factors are
# the robust choice while they fit (docs/iterative_cornerpoint.md, "Eleventh session")
# peak memory of a block-direct run: bytes per unknown at 775,608 unknowns and the growth of PARDISO's
# fill with size (emerald 7.8, the 30,000-cell study 8.0, the 10⁵-cell grid 9.2 kB per unknown: n^0.11)
BLOCK_DIRECT_BYTES = 9.2e3
BLOCK_DIRECT_GROWTH = 0.11
MEMORY_SHARE = 0.5             # block-direct only where its estimate is below this share of the memory
SUPERLU_MAX = 30_000           # estimated unknowns up to which SciPy's SuperLU takes seconds in 3D


def estimated_unknowns(fm) -> int:
    """d × nodes + cells + faces: the coupled system's size before it is built (nodal
    displacements, HFV cell and face pressures; within 3 % on emerald-injection and the 30,000-cell
    generated grid)."""
    m = fm.mesh
    return int(m.dim * m.n_nodes + m.n_cells + m.n_faces)


def block_direct_bytes(n: int) -> float:
    """Estimated peak memory (bytes) of a ``block-direct`` run with about ``n`` unknowns."""
    return BLOCK_DIRECT_BYTES * n * (n / 775_608) ** BLOCK_DIRECT_GROWTH


def resolve_linear(linear: str, fm, order: int, pardiso: bool) -> tuple[str, str]:
    """The coupled model's linear solver for ``solver.linear`` and why.

    "auto" is the direct solver (PARDISO when installed, else SuperLU) except on 3D systems of
    order 1 that are large for it: with PARDISO from about BLOCK_DIRECT_MIN unknowns
    "block-direct" (PARDISO on the condensed displacement block and on the fixed-stress pressure
    block, GMRES around them), and where those factors would take more than MEMORY_SHARE of the
    machine's memory (:func:`block_direct_bytes`), "block-amg" (AMG on the displacement block); without
    PARDISO "block-amg" from about SUPERLU_MAX unknowns. The P2 systems stay direct: the block
    solvers were not measured on them.
    """
    if linear != "auto":
        return linear, "given"
    from ..parallel.context import context

    direct = "pardiso" if pardiso else "superlu"
    if context() is not None:
        return "auto", "auto: distributed run (MUMPS)"
    if fm.mesh.dim != 3 or order != 1:
        return direct, "auto: direct" + (" (2D)" if fm.mesh.dim != 3 else " (quadratic displacements)")
    n = estimated_unknowns(fm)
    if pardiso and n >= BLOCK_DIRECT_MIN:
        need, have = block_direct_bytes(n), machine_memory()
        if need > MEMORY_SHARE * have:
            return "block-amg", (f"auto: about {n:,} unknowns; the displacement block's factors would need about "
                                 f"{need / 1e9:.1f} GB of this machine's {have / 1e9:.1f} GB: AMG on it instead")
        return "block-direct", (f"auto: about {n:,} unknowns; PARDISO on the displacement and pressure blocks "
                                "with GMRES around them is faster and smaller than PARDISO on the whole system "
                                f"from about {BLOCK_DIRECT_MIN:,}")
    if not pardiso and n > SUPERLU_MAX:
        return "block-amg", (f"auto: about {n:,} unknowns and no PARDISO: SciPy's SuperLU would take minutes and "
                             "gigabytes; pip install 'polypore[fast]' for PARDISO")
    return direct, f"auto: about {n:,} unknowns, direct ({direct})"

@case_keys(POROMECHANICS)
def poro_setup(case: CaseFile, fm):
    """(Poromechanics model, flow setup, mechanics setup) for a case on the mesh ``fm``."""
    spec = case.spec
    if spec.flow is None:
        raise InputError("flow", "a poromechanics case needs flow data: a [flow] table (permeability, viscosity, "
                         "biot_modulus, aperture, normal_permeability, boundary conditions)")
    if spec.time is None:
        raise InputError("time", "a poromechanics case is transient: give [time] with end and step (s)")
    ms = mechanics_setup(case, fm)
    from ..solvers.linear import have_pardiso

    linear, why = resolve_linear((spec.solver.linear if spec.solver is not None else "auto"), fm,
                                 ms.data.order, have_pardiso())
    if linear not in ("auto", ms.solver.backend):
        with case_keys(SOLVER):
            ms = dataclasses.replace(ms, solver=dataclasses.replace(ms.solver, backend=linear))
    log.info("linear solver: %s (%s)", ms.solver.backend, why)
    ms.choices |= {"linear_solver": ms.solver.backend, "linear_solver_source": why}
    fs = flow_setup(case, fm)
    flow_data = dataclasses.replace(fs.data, biot_coefficient=ms.data.biot)
    ref = reference_state(case, fm)
    model = Poromechanics(fm, ms.data, flow_data, fs.boundary, fracture_boundary=fs.fracture_boundary,
                          cell_source=fs.cell_source, fracture_source=fs.fracture_source, alpha=fs.alpha,
                          fracture_alpha=fs.fracture_alpha, cell_point=fs.cell_point, solver=ms.solver,
                          newton=dataclasses.replace(ms.newton, label="poromechanics Newton", stall_iterations=12),
                          initial_traction=None if ref is None else ref.traction(fm),
                          dilatancy=fs.info.get("tan_psi", 0.0),
                          pressure_stabilisation=STABILISATION if fs.info.get("pressure_stabilisation") is None
                          else fs.info["pressure_stabilisation"],
                          predictor=spec.solver.predictor if spec.solver is not None else "linear")
    model.reference = ref
    return model, fs, ms


def monitor_points(case: CaseFile, mesh) -> dict:
    """``[monitor] points = {name = [x, y(, z)]}``: name -> the cell whose centroid is nearest."""
    mon = case.spec.monitor
    if mon is None:
        return {}
    out = {}
    c = mesh.geometry.cell_centroid
    lo, hi = mesh.bounding_box
    for name, x in mon.points.items():
        f = f"monitor.points.{name}"
        if len(x) != mesh.dim:
            raise InputError(f, f"must be {mesh.dim} coordinates (m), got {x}")
        x = np.asarray(x)
        if np.any(x < lo - 1e-9 * np.abs(hi - lo)) or np.any(x > hi + 1e-9 * np.abs(hi - lo)):
            raise InputError(f, f"lies outside the domain {lo.tolist()} – {hi.tolist()}")
        out[name] = int(np.argmin(np.linalg.norm(c - x, axis=1)))
    return out
