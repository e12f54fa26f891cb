"""Time schedules: validation, output times, step cutting."""

import numpy as np
import pytest

from polypore.core.errors import InputError, RunError
from polypore.runs.march import march
from polypore.setup.casefile import CaseFile
from polypore.setup.schedule import TimeSchedule, parse_schedule
from polypore.solvers.interface import SolverDefaults


def test_times_hit_output_times_and_end():
    s = TimeSchedule(0.0, 100.0, 30.0, output_times=(45.0, 100.0))
    t = s.times()
    assert t[0] == 0 and t[-1] == 100 and 45.0 in t and np.all(np.diff(t) > 0)
    assert s.is_output(2, 45.0) and not s.is_output(1, 30.0) and s.is_output(len(t) - 1, 100.0)


@pytest.mark.parametrize("table,field,msg", [
    ({"end": 0.0, "step": 1.0}, "time.end", "does not advance"),
    ({"end": 10.0, "step": 0.0}, "time.step", "does not advance"),
    ({"end": 10.0, "step": 1.0, "output_times": [5.0, 12.0]}, "time.output_times", "outside the run"),
    ({"end": 10.0, "step": 1.0, "typo": 1}, "time.typo", "unknown key"),
    ({"end": 10.0, "step": 1.0, "max_conductivity_growth": 1.0}, "time.max_conductivity_growth", "must be > 1, got 1.0"),
    ({"end": 10.0, "step": 1.0, "growth_cuts": 61}, "time.growth_cuts", "61"),
    # issue 25: 100,000 output times were accepted ("about 14 h left")
    ({"end": 1e5, "step": 1.0, "output_times": [float(k) for k in range(1, 100_001)]}, "time.output_times",
     "100,000 distinct output times; allowed: at most 10,000"),
])
def test_bad_schedules(table, field, msg):
    case = CaseFile("t", None, {"model": "flow", "mesh": {"generator": "cartesian", "lower": [0, 0], "upper": [1, 1],
                                                          "cells": [2, 2]}, "time": table})
    with pytest.raises(InputError) as exc:
        parse_schedule(case.spec)
    assert exc.value.field == field and msg in str(exc.value)


def test_march_cuts_failing_steps_then_gives_up():
    s = TimeSchedule(0.0, 4.0, 2.0, max_cuts=2)
    calls = []

    def step(state, t0, t1):
        calls.append((t0, t1))
        if t1 - t0 > 1.0:          # steps longer than 1 s "do not converge"
            raise RunError("Newton did not converge")
        return state + (t1 - t0), {"newton_iterations": 3}

    state, recs = march(s, 0.0, step)
    assert state == pytest.approx(4.0) and [r.cuts for r in recs] == [1, 1]
    with pytest.raises(RunError, match="failed after 1 cut"):
        march(TimeSchedule(0.0, 4.0, 4.0, max_cuts=1), 0.0, step)


def test_march_records_what_failed_attempts_cost():
    """A cut step's failed attempts keep their span, reason and the work the solver attached."""
    s = TimeSchedule(0.0, 2.0, 2.0, max_cuts=2)

    def step(state, t0, t1):
        if t1 - t0 > 1.0:
            exc = RunError("poromechanics Newton stalled: the line search cut the last 3 steps")
            exc.newton_iterations, exc.linear_iterations = 10, [7, 8]
            raise exc
        return state + (t1 - t0), {"newton_iterations": 3}

    _, (rec,) = march(s, 0.0, step)
    assert rec.failed == [{"from": 0.0, "to": 2.0, "reason": "poromechanics Newton stalled",
                           "newton_iterations": 10, "linear_iterations": [7, 8]}]
    assert len(rec.substeps) == 2


def test_newton_reports_the_iterations_of_a_failed_attempt():
    import scipy.sparse as sp

    from polypore.solvers.newton import Linearisation, NewtonOptions, semismooth_newton

    class Flip(SolverDefaults):
        backend = "test"

        def solve(self, J, b):
            return np.array([2.0])

    def lin(x):
        return Linearisation(np.array([x[0] ** 2 + 1.0]), sp.csr_matrix(np.eye(1)), {"r": float(x[0] ** 2 + 1)},
                             {}, None)

    with pytest.raises(RunError) as err:
        semismooth_newton(lin, np.array([-1.0]), Flip(), lambda dx, x: 1.0,
                          NewtonOptions(max_iterations=7, free_steps=2, min_step=1.0), verbose=False)
    assert err.value.newton_iterations == 7


def test_march_adapts_the_sub_steps_to_the_callers_test():
    """``accept`` rejecting a converged step (time.max_conductivity_growth): the sub-step halves on a
    rejection, doubles after an acceptance (up to the schedule step) and carries over to the next
    schedule step; at the smallest size a rejected sub-step is kept with a count; failures halve it
    too, at most max_cuts times in a row."""
    s = TimeSchedule(0.0, 8.0, 4.0, max_cuts=1)
    calls = []

    def step(state, t0, t1):
        calls.append((t0, t1))
        return state + (t1 - t0), {"dt": t1 - t0, "t": t1}

    def accept(info):                       # sub-steps starting before t = 3 s must be ≤ 1 s
        return "too long" if info["dt"] > 1.0 and info["t"] - info["dt"] < 3.0 else None

    state, (r1, r2) = march(s, 0.0, step, accept=accept, max_rejections=5)
    assert state == pytest.approx(8.0)
    # (3, 4) lands on the schedule step's end: h stays 2 s for the next one, then grows to 4 s
    assert calls == [(0, 4), (0, 2), (0, 1), (1, 3), (1, 2), (2, 4), (2, 3), (3, 4), (4, 6), (6, 8)]
    assert [i["dt"] for i in r1.substeps] == [1.0] * 4 and r1.rejected == 4 and r1.cuts == 2
    assert [i["dt"] for i in r2.substeps] == [2.0, 2.0] and r2.rejected == 0 and r1.info is r1.substeps[-1]
    state, (r1, _) = march(s, 0.0, step, accept=accept, max_rejections=1)     # smallest sub-step 2 s
    assert [i["dt"] for i in r1.substeps] == [2.0, 2.0] and r1.rejected == 1 and r1.forced == 2

    def fragile(state, t0, t1):
        if t1 - t0 > 2.0:
            raise RunError("Newton did not converge")
        return step(state, t0, t1)

    state, (r1, r2) = march(s, 0.0, fragile, accept=accept, max_rejections=3)
    assert state == pytest.approx(8.0) and [i["dt"] for i in r1.substeps] == [1.0, 1.0, 1.0, 1.0]
    assert state == pytest.approx(8.0) and [i["dt"] for i in r2.substeps] == [2.0, 2.0]

    def broken(state, t0, t1):
        if t1 - t0 > 0.5:
            raise RunError("Newton did not converge")
        return step(state, t0, t1)

    with pytest.raises(RunError, match="failed after 1 cut"):        # max_cuts = 1 failure in a row
        march(s, 0.0, broken, accept=accept, max_rejections=3)
    state, (rec, _) = march(s, 0.0, step)                       # without accept: one step each
    assert len(rec.substeps) == 1 and rec.rejected == 0


def test_newton_gives_up_early_when_the_residual_stalls():
    """A cycling iteration (residual never halves) stops after free_steps + stall_iterations."""
    import numpy as np
    import scipy.sparse as sp

    from polypore.core.errors import RunError
    from polypore.solvers.newton import Linearisation, NewtonOptions, semismooth_newton

    class Flip(SolverDefaults):
        backend = "test"

        def solve(self, J, b):
            return np.array([2.0])                      # always overshoots: x alternates ±1

    def lin(x):
        return Linearisation(np.array([x[0] ** 2 + 1.0]), sp.csr_matrix(np.eye(1)), {"r": float(x[0] ** 2 + 1)},
                             {}, None)

    opts = NewtonOptions(max_iterations=50, stall_iterations=5, free_steps=2, min_step=1.0)
    with pytest.raises(RunError, match="stalled"):
        semismooth_newton(lin, np.array([-1.0]), Flip(), lambda dx, x: 1.0, opts, verbose=False)
    with pytest.raises(RunError, match="did not converge in 50"):
        semismooth_newton(lin, np.array([-1.0]), Flip(), lambda dx, x: 1.0,
                          NewtonOptions(max_iterations=50, stall_iterations=0, free_steps=2, min_step=1.0), verbose=False)


def test_newton_gives_up_when_the_line_search_crawls():
    """Every step cut to min_step without the residual halving (an iterate at a kink that neither
    linearisation crosses): a stall after crawl_iterations, not after free_steps + stall_iterations;
    without stall_iterations (static problems) the loop runs on to max_iterations."""
    import numpy as np
    import scipy.sparse as sp

    from polypore.core.errors import RunError
    from polypore.solvers.newton import Linearisation, NewtonOptions, semismooth_newton

    class Overshoot(SolverDefaults):
        backend = "test"

        def solve(self, J, b):
            return np.array([-1000.0 * np.sign(self.x)])

    solver = Overshoot()

    def lin(x):
        solver.x = x[0]
        r = abs(x[0]) + 1.0                      # never zero, kink at 0
        return Linearisation(np.array([r]), sp.csr_matrix(np.eye(1)), {"r": r}, {}, None)

    opts = NewtonOptions(max_iterations=40, stall_iterations=20, free_steps=0, min_step=1.0 / 64)
    with pytest.raises(RunError, match="line search cut the last 3 steps") as err:
        semismooth_newton(lin, np.array([1.0]), solver, lambda dx, x: 1.0, opts, verbose=False)
    assert "stalled" in str(err.value)
    with pytest.raises(RunError, match="did not converge in 40"):
        semismooth_newton(lin, np.array([1.0]), solver, lambda dx, x: 1.0,
                          NewtonOptions(max_iterations=40, free_steps=0, min_step=1.0 / 64), verbose=False)


def test_newton_accepts_the_round_off_floor_only_when_nothing_moves():
    """Residual stuck slightly above tol with zero increments and a fixed active set: accepted;
    with increments that still move the iterate: not."""
    import numpy as np
    import scipy.sparse as sp

    from polypore.core.errors import RunError
    from polypore.solvers.newton import Linearisation, NewtonOptions, semismooth_newton

    class Tiny(SolverDefaults):
        backend = "test"

        def __init__(self, step):
            self.step = step

        def solve(self, J, b):
            return np.array([self.step])

    def lin(x):
        return Linearisation(np.array([2e-8]), sp.csr_matrix(np.eye(1)), {"r": 2e-8}, {}, np.zeros(1, np.int8))

    opts = NewtonOptions(max_iterations=10)
    res = semismooth_newton(lin, np.array([1.0]), Tiny(1e-13), lambda dx, x: float(abs(dx[0])), opts, verbose=False)
    assert res.iterations == 1 and res.residual == 2e-8
    with pytest.raises(RunError):
        semismooth_newton(lin, np.array([1.0]), Tiny(1e-6), lambda dx, x: float(abs(dx[0])), opts, verbose=False)
