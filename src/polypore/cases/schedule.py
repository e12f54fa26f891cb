"""Time schedules of transient runs and the time-marching driver with step cutting.

``[time]`` table (s)::

    [time]
    start = 0.0
    end = 2000.0
    step = 20.0
    output_every = 1              # write outputs every n steps (and at the end), or
    output_times = [500, 2000]    # at these times (steps are shortened to land on them)
    max_cuts = 4                  # halvings of a step whose Newton loop fails before giving up
"""

from __future__ import annotations

import logging
import time as _time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core.errors import InputError, RunError
from .casefile import Section

log = logging.getLogger("polypore")


@dataclass(frozen=True)
class TimeSchedule:
    """Implicit-Euler schedule t_0 = start < t_1 < ... < t_n = end (s) and its output times."""

    start: float
    end: float
    step: float
    output_every: int = 1
    output_times: tuple = ()
    max_cuts: int = 4

    def times(self) -> np.ndarray:
        """(n + 1,) step end times, including every output time exactly."""
        n = max(1, int(np.ceil((self.end - self.start) / self.step - 1e-9)))
        t = self.start + self.step * np.arange(n + 1)
        t[-1] = self.end
        if self.output_times:
            t = np.union1d(t, np.asarray(self.output_times, float))
            # drop steps shorter than 1e-9 of a step next to an inserted output time
            keep = np.concatenate([[True], np.diff(t) > 1e-9 * self.step])
            t = t[keep]
            t[-1] = self.end
        return t

    def is_output(self, k: int, t: float) -> bool:
        """Whether step k (1-based) ending at t writes outputs (the last step always does)."""
        if abs(t - self.end) <= 1e-9 * self.step:
            return True
        if self.output_times:
            return bool(np.any(np.abs(np.asarray(self.output_times) - t) <= 1e-9 * self.step))
        return k % self.output_every == 0


def parse_schedule(root: Section, required: bool = False) -> TimeSchedule | None:
    """Read ``[time]``; None when absent (and not required). Errors name the field."""
    if not root.has("time"):
        if required:
            raise InputError("time", "is required for this case: give [time] with end and step (s)")
        return None
    sec = root.section("time")
    start = sec.number("start", 0.0)
    end = sec.number("end")
    step = sec.number("step")
    if not end > start:
        raise InputError(sec.field("end"), f"must exceed time.start = {start!r} (s): the schedule does not "
                         f"advance, got {end!r}")
    if not step > 0:
        raise InputError(sec.field("step"), f"must be positive (s): the schedule does not advance, got {step!r}")
    every = sec.number("output_every", 1, integer=True, positive=True)
    outs = ()
    if sec.has("output_times"):
        vals = sec.vector("output_times")
        bad = [v for v in vals if not start < v <= end]
        if bad:
            raise InputError(sec.field("output_times"), f"{bad[0]!r} lies outside the run ({start!r}, {end!r}] s")
        outs = tuple(sorted(set(vals)))
    cuts = sec.number("max_cuts", 4, integer=True, nonneg=True)
    sec.done()
    return TimeSchedule(start, end, step, every, outs, cuts)


@dataclass
class StepRecord:
    """What happened in one accepted step."""

    index: int
    time: float
    dt: float
    info: dict = field(default_factory=dict)
    cuts: int = 0
    seconds: float = 0.0


def march(schedule: TimeSchedule, state, step: Callable, on_step: Callable | None = None, label: str = "step"):
    """Advance ``state`` over the schedule with implicit-Euler steps ``step(state, t_old, t_new) ->
    (state, info)``; a step that raises RunError is retried as two half steps, recursively, at
    most ``schedule.max_cuts`` times, then the run stops with a RunError saying where and why.

    ``on_step(record, state, is_output)`` is called after every accepted schedule step.
    Returns the final state and the list of StepRecord.
    """
    times = schedule.times()
    records = []
    for k in range(1, len(times)):
        t0, t1 = float(times[k - 1]), float(times[k])
        tic = _time.perf_counter()
        state, info, cuts = _advance(state, t0, t1, step, schedule.max_cuts, 0)
        rec = StepRecord(k, t1, t1 - t0, info, cuts, _time.perf_counter() - tic)
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
