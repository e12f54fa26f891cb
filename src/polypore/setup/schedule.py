"""Time schedules of transient runs: the ``[time]`` table and the step times it gives.

``[time]`` table (s; keys and checks in :class:`polypore.setup.schema.case.Time`)::

    [time]
    start = 0.0
    end = 2000.0
    step = 20.0
    output_every = 1              # write outputs every n steps (and at the end), or
    output_times = [500, 2000]    # at these times (steps are shortened to land on them)
    max_cuts = 4                  # halvings of a step whose Newton loop fails before giving up
    max_conductivity_growth = 1e3 # poromechanics: halve a (sub-)step in which a C_f grows more
    growth_cuts = 8               # its smallest sub-step: step / 2^growth_cuts
    rate_tolerance = 0.05         # rate-and-state: change of ln V per sub-step (RateLaw.step_error)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError


@dataclass(frozen=True)
class TimeSchedule:
    """Implicit-Euler schedule t_0 = start < t_1 < ... < t_n = end (s) and its output times."""

    start: float
    end: float
    step: float
    output_every: int = 1
    output_times: tuple = ()
    max_cuts: int = 4
    max_conductivity_growth: float | None = None
    growth_cuts: int = 8
    rate_tolerance: float = 0.05

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


def parse_schedule(spec, required: bool = False) -> TimeSchedule | None:
    """The schedule of a validated case's ``[time]`` table (:class:`polypore.setup.schema.case.Time`,
    which checked it); None when absent (and not required)."""
    tt = spec.time
    if tt is None:
        if required:
            raise InputError("time", "is required for this case: give [time] with end and step (s)")
        return None
    outs = () if tt.output_times is None else tuple(sorted(set(tt.output_times)))
    return TimeSchedule(tt.start, tt.end, tt.step, tt.output_every, outs, tt.max_cuts,
                        None if tt.max_conductivity_growth is None else float(tt.max_conductivity_growth),
                        int(tt.growth_cuts), float(tt.rate_tolerance))
