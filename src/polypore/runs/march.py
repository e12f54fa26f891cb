"""The time loop of transient runs: implicit-Euler steps over a :class:`TimeSchedule`, a failed
step retried as two half steps (step cutting)."""

from __future__ import annotations

import logging
import time as _time
from dataclasses import dataclass, field
from typing import Callable

from ..core.errors import RunError
from ..io.progress import Progress
from ..setup.schedule import TimeSchedule

log = logging.getLogger("polypore")


@dataclass
class StepRecord:
    """What happened in one accepted step."""

    index: int
    time: float
    dt: float
    info: dict = field(default_factory=dict)
    cuts: int = 0
    seconds: float = 0.0
    progress: str = ""      # 'elapsed …, about … left' after this step


def march(schedule: TimeSchedule, state, step: Callable, on_step: Callable | None = None, label: str = "step"):
    """Advance ``state`` over the schedule with implicit-Euler steps ``step(state, t_old, t_new) ->
    (state, info)``; a step that raises RunError is retried as two half steps, recursively, at
    most ``schedule.max_cuts`` times, then the run stops with a RunError saying where and why.

    ``on_step(record, state, is_output)`` is called after every accepted schedule step.
    Returns the final state and the list of StepRecord.
    """
    times = schedule.times()
    records = []
    with Progress(len(times) - 1, f"{label}s") as bar:
        for k in range(1, len(times)):
            t0, t1 = float(times[k - 1]), float(times[k])
            tic = _time.perf_counter()
            state, info, cuts = _advance(state, t0, t1, step, schedule.max_cuts, 0)
            rec = StepRecord(k, t1, t1 - t0, info, cuts, _time.perf_counter() - tic)
            rec.progress = bar.advance()
            records.append(rec)
            if on_step is not None:
                on_step(rec, state, schedule.is_output(k, t1))
    return state, records


def _advance(state, t0, t1, step, max_cuts, depth):
    try:
        new, info = step(state, t0, t1)
        return new, info, depth
    except RunError as exc:
        if depth >= max_cuts:
            raise RunError(f"the step from t = {t0:g} s to {t1:g} s failed after {depth} cut(s) of the time step "
                           f"(smallest Δt {t1 - t0:g} s): {exc}") from None
        log.warning("step %g → %g s failed (%s); retrying as two half steps", t0, t1, str(exc).split(":")[0])
        tm = 0.5 * (t0 + t1)
        mid, _, d1 = _advance(state, t0, tm, step, max_cuts, depth + 1)
        new, info, d2 = _advance(mid, tm, t1, step, max_cuts, depth + 1)
        return new, info, max(d1, d2)
