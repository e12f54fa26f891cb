"""Small measures every run driver reports: peak memory, the time split and the unknowns of a contact
problem."""

from __future__ import annotations

import logging
import resource
import time

from ..mesh.cornerpoint import fault_report, fault_table
from ..setup.meshing import cornerpoint_of
from ..parallel.context import context
from ..core.timing import SPLIT, summary_split

log = logging.getLogger("polypore")


def peak_memory_mb() -> float:
    """Peak resident memory of this process (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def unknowns(problem) -> int:
    """Unknowns of a contact-mechanics problem: free displacement unknowns and the multipliers."""
    return int(problem.free.size + problem.n_c * problem.dim)


def corner_point_faults(case, fm) -> dict | None:
    """summary.json's ``faults`` of a run on a corner-point grid (None on other meshes): every
    fault of the grid (:func:`polypore.mesh.cornerpoint.fault_report`) with the name of the
    ``[[fractures]]`` entry using it as a contact surface (``fracture``, None: bonded); logs
    them as a table."""
    cp = cornerpoint_of(fm.mesh)
    if cp is None:
        return None
    _, info = cp
    used = {f.fault or f.name: f.name for f in getattr(case.spec, "fractures", None) or ()}
    report = fault_report(fm.mesh, info)
    log.info("faults of the grid (cells on the hanging wall / footwall; dip from horizontal; azimuths "
             "clockwise from north = +y):")
    for line in fault_table(report, used):
        log.info("  %s", line)
    return {name: {"fracture": used.get(name), **r} for name, r in report.items()}


class RunClock:
    """The wall and CPU clocks of one run, started with the run; :meth:`totals` is summary.json's
    ``totals`` time split (docs/parallel.md, "Time split")."""

    def __init__(self):
        SPLIT.reset()
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def totals(self, solver=None) -> dict:
        """seconds, seconds_{assembly, linear, preconditioner, krylov, other}, their CPU seconds
        under ``cpu`` and peak_memory_mb of this process; with the run's ``solver`` (a LinearSolver)
        also ``linear_solver`` and ``labels``, what the categories measured with it (a direct
        solver's factorisation and solves, not a preconditioner and Krylov iterations); in a
        distributed run also ``ranks``, the same for every rank (a collective call: every rank
        makes it at the same point)."""
        out = summary_split(time.perf_counter() - self.wall, time.process_time() - self.cpu,
                            backend=None if solver is None else solver.backend)
        out["peak_memory_mb"] = peak_memory_mb()
        ctx = context()
        if ctx is not None and ctx.size > 1:
            out["ranks"] = ctx.comm.allgather({k: v for k, v in out.items() if k != "ranks"})
        return out
