"""Where the time of a run goes: assembly, preconditioner set-up (or factorisation), Krylov
iterations (or triangular solves) (docs/parallel.md, "Time split").

One accumulator per process (per rank in a distributed run), fed where the work is done: Newton
times the model's residual and Jacobian (``assembly``) and its linear solves (``linear``); inside
those, the solvers time the set-up of their preconditioner (``preconditioner``: AMG set-ups, the
block preconditioner's matrix P and PETSc's PCSetUp, or a direct solver's factorisation) and the
iterations (``krylov``: GMRES/CG with their preconditioner applications, or a direct solver's
triangular solves). ``linear`` contains the two others; what is left of it is the conversion of the
matrices for the solver. The run drivers read :data:`SPLIT` at the end (``summary.json``'s
``totals``). Wall seconds (``time.perf_counter``) and CPU seconds of this process
(``time.process_time``): on a machine shared with other jobs the CPU seconds are the robust figure.
"""

from __future__ import annotations

import time
from contextlib import contextmanager

from . import live

CATEGORIES = ("assembly", "linear", "preconditioner", "krylov")
# The categories keep their names in summary.json (seconds_preconditioner, seconds_krylov), but a
# direct solver has no preconditioner and no Krylov iterations: printed, the parts are named by
# what ran with the run's backend (issue 25: "preconditioner set-up" on a SuperLU run misled).
DIRECT = ("superlu", "pardiso")


def split_labels(backend: str | None) -> dict:
    """{category: what it measured} for a run whose linear solves used ``backend`` (the resolved
    ``solver.linear``; None: unknown, the iterative names). A category that stays empty with the
    backend (Krylov with PARDISO, which factorises and solves in one call) is left out."""
    if backend == "pardiso":
        return {"assembly": "assembly", "preconditioner": "factorisation and solve", "other": "other"}
    if backend == "superlu":
        return {"assembly": "assembly", "preconditioner": "factorisation", "krylov": "triangular solves",
                "other": "other"}
    return {"assembly": "assembly", "preconditioner": "preconditioner set-up", "krylov": "Krylov iterations",
            "other": "other"}

PHASES = {"assembly": "assembling", "linear": "linear solve", "preconditioner": "preconditioner set-up",
          "krylov": "Krylov iterations"}
"""The live status's name of each category (:mod:`polypore.core.live`), unless a block names its own."""


class TimeSplit:
    """Wall and CPU seconds per category (:data:`CATEGORIES`), summed over the calls."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self.wall = dict.fromkeys(CATEGORIES, 0.0)
        self.cpu = dict.fromkeys(CATEGORIES, 0.0)

    def add(self, category: str, wall: float, cpu: float) -> None:
        self.wall[category] += wall
        self.cpu[category] += cpu

    @contextmanager
    def timed(self, category: str, phase: str | None = None):
        """Adds the wall and CPU seconds of the ``with`` block to ``category``; the block is also
        the live status's phase ``phase`` (default: :data:`PHASES` of the category)."""
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            with live.phase(phase or PHASES[category]):
                yield
        finally:
            self.add(category, time.perf_counter() - t0, time.process_time() - c0)

    def snapshot(self) -> dict:
        """{"wall": {category: s}, "cpu": {category: s}} (copies)."""
        return {"wall": dict(self.wall), "cpu": dict(self.cpu)}


SPLIT = TimeSplit()
"""The process's accumulator (reset by the run drivers at the start of a run)."""


def summary_split(total_wall: float, total_cpu: float, start: dict | None = None,
                  backend: str | None = None) -> dict:
    """The time split of a run for summary.json: seconds_{assembly, linear, preconditioner, krylov,
    other} (wall) and the same under ``cpu``; ``other`` is the total minus assembly, preconditioner
    and Krylov (so it holds the matrix conversions, the outputs and the set-up). With ``backend``
    also ``linear_solver`` and ``labels``, what each category measured (:func:`split_labels`).

    Parameters
    ----------
    total_wall, total_cpu : the run's wall and CPU seconds
    start : a :meth:`TimeSplit.snapshot` taken at the start of the run (None: zeros)
    backend : the run's resolved linear solver backend, or None
    """
    now = SPLIT.snapshot()
    out, cpu = {}, {}
    for kind, total, dest in (("wall", total_wall, out), ("cpu", total_cpu, cpu)):
        s = {k: now[kind][k] - (start[kind][k] if start else 0.0) for k in CATEGORIES}
        for k in CATEGORIES:
            dest[f"seconds_{k}"] = s[k]
        dest["seconds_other"] = total - s["assembly"] - s["preconditioner"] - s["krylov"]
        dest["seconds"] = total
    out["cpu"] = cpu
    if backend is not None:
        out["linear_solver"] = backend
        out["labels"] = split_labels(backend)
    return out
