"""The time loop of transient runs: implicit-Euler steps over a :class:`TimeSchedule`, a failed
step retried as two half steps (step cutting); with an ``accept`` test, sub-steps of an adapted
size that halves on a rejected or failed sub-step and doubles after an accepted one."""

from __future__ import annotations

import logging
import time as _time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core.errors import RunError
from ..io.progress import Progress
from ..setup.schedule import TimeSchedule

log = logging.getLogger("polypore")


@dataclass
class StepRecord:
    """What happened in one schedule step (several sub-steps when it was cut or rejected)."""

    index: int
    time: float
    dt: float
    info: dict = field(default_factory=dict)        # the last accepted sub-step's
    cuts: int = 0                                    # deepest halving (failures and rejections)
    seconds: float = 0.0
    progress: str = ""      # 'elapsed …, about … left' after this step
    substeps: list = field(default_factory=list)    # info of every accepted sub-step, in order
    rejected: int = 0                                # sub-steps solved and then rejected by ``accept``
    forced: int = 0                                  # sub-steps ``accept`` rejected at the smallest size (kept)
    failed: list = field(default_factory=list)       # attempts that raised: their span, cost and reason


def _failure(exc: RunError, t0: float, t1: float) -> dict:
    """A failed attempt as the run reports it: its work counts in the run's totals."""
    out = {"from": t0, "to": t1, "reason": str(exc).split(":")[0]}
    for key in ("newton_iterations", "linear_iterations"):
        if getattr(exc, key, None) is not None:
            out[key] = getattr(exc, key)
    return out


def march(schedule: TimeSchedule, state, step: Callable, on_step: Callable | None = None, label: str = "step",
          accept: Callable | None = None, max_rejections: int = 0):
    """Advance ``state`` over the schedule with implicit-Euler steps ``step(state, t_old, t_new) ->
    (state, info)``; a step that raises RunError is retried as two half steps, recursively, at
    most ``schedule.max_cuts`` times, then the run stops with a RunError saying where and why.

    ``accept(info) -> None | str`` may reject a converged step (the string says why). With it, each
    schedule step is covered by sub-steps of an adapted size h: a rejected or failed sub-step is
    redone at h/2, an accepted one lets the next try 2h (never beyond the schedule step); a step
    whose info carries ``size_factor`` (an error controller's) is redone at ≤ h/2 by that factor
    and followed by a step of that factor × h, and h
    carries over to the next schedule step, so that a slip front moving for days is not found
    again by a cascade of rejections every day. h stays ≥ Δt/2^``max_rejections`` (a sub-step
    rejected at that size is kept with a warning); a failure at h is retried at most
    ``schedule.max_cuts`` times in a row. ``on_step(record, state, is_output)`` is called after
    every schedule step. Returns the final state and the list of StepRecord.
    """
    times = schedule.times()
    records = []
    h = [float(schedule.step)]                      # the adapted sub-step (with ``accept``)
    with Progress(len(times) - 1, f"{label}s") as bar:
        for k in range(1, len(times)):
            t0, t1 = float(times[k - 1]), float(times[k])
            tic = _time.perf_counter()
            rec = StepRecord(k, t1, t1 - t0)
            if accept is None:
                state = _advance(state, t0, t1, step, schedule.max_cuts, 0, rec)
            else:
                state = _adapted(state, t0, t1, step, schedule.max_cuts, accept, rec, h, float(schedule.step),
                                 max_rejections)
            rec.info = rec.substeps[-1]
            rec.seconds = _time.perf_counter() - tic
            rec.progress = bar.advance()
            records.append(rec)
            if on_step is not None:
                on_step(rec, state, schedule.is_output(k, t1))
    return state, records


def _advance(state, t0, t1, step, max_cuts, depth, rec):
    """State at t1 from t0, a failed step retried as two half steps; accepted infos go to ``rec``."""
    rec.cuts = max(rec.cuts, depth)
    try:
        new, info = step(state, t0, t1)
    except RunError as exc:
        if depth >= max_cuts:
            raise RunError(f"the step from t = {t0:g} s to {t1:g} s failed after {depth} cut(s) of the time step "
                           f"(smallest Δt {t1 - t0:g} s): {exc}") from None
        rec.failed.append(_failure(exc, t0, t1))
        log.warning("step %g → %g s failed (%s); retrying as two half steps", t0, t1, rec.failed[-1]["reason"])
        tm = 0.5 * (t0 + t1)
        mid = _advance(state, t0, tm, step, max_cuts, depth + 1, rec)
        return _advance(mid, tm, t1, step, max_cuts, depth + 1, rec)
    rec.substeps.append(info)
    return new


def _adapted(state, t0, t1, step, max_cuts, accept, rec, h, dt, max_rejections):
    """State at t1 from t0 by sub-steps of the adapted size h[0] ≤ dt (see :func:`march`)."""
    h_min = dt / 2.0 ** max_rejections
    t, fails = t0, 0
    while t < t1 - 1e-9 * (t1 - t0):
        size = min(h[0], t1 - t)
        if t1 - (t + size) < 1e-6 * size:          # land on t1 (no sliver sub-step)
            size = t1 - t
        try:
            new, info = step(state, t, t + size)
        except RunError as exc:
            if fails >= max_cuts:
                raise RunError(f"the step from t = {t:g} s to {t + size:g} s failed after {fails} cut(s) of the "
                               f"time step (smallest Δt {size:g} s): {exc}") from None
            rec.failed.append(_failure(exc, t, t + size))
            log.warning("step %g → %g s failed (%s); retrying with half the step", t, t + size,
                        rec.failed[-1]["reason"])
            fails += 1
            rec.cuts = max(rec.cuts, fails)
            h[0] = 0.5 * size
            continue
        why = accept(info)
        # an error-controlled step proposes the next size's factor itself (info["size_factor"])
        factor = info.get("size_factor") if isinstance(info, dict) else None
        if why and size > h_min * (1 + 1e-9):
            rec.rejected += 1
            shrink = 0.5 if factor is None else min(factor, 0.5)
            log.info("step %g → %g s rejected (%s); redoing it with %.2g of the step", t, t + size, why, shrink)
            h[0] = max(shrink * size, h_min)
            continue
        if why:
            rec.forced += 1
            log.warning("step %g → %g s kept at the smallest sub-step (%g s) although %s", t, t + size, size, why)
        rec.substeps.append(info)
        rec.cuts = max(rec.cuts, int(round(np.log2(dt / size))) if size < dt else 0)
        if factor is not None and factor < 1.0:
            h[0] = max(factor * size, h_min)
        elif size >= h[0] * (1 - 1e-9):               # not a step shortened to land on t1
            h[0] = min((2.0 if factor is None else factor) * size, dt)
        state, t, fails = new, t + size, 0
    return state

