"""Semi-smooth Newton iteration (scheme.md §4), independent of the physics.

The caller supplies ``linearise(x) -> Linearisation`` (residual blocks, Jacobian, labels
such as open/stick/slip counts) and block norms; this module runs the loop, logs every
iteration and decides convergence or failure.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core.errors import RunError
from .linear import LinearSolver

log = logging.getLogger("polypore")


@dataclass
class Linearisation:
    """What the model returns at an iterate.

    Attributes
    ----------
    residual : (n,) residual vector F(x)
    jacobian : (n, n) sparse generalised Jacobian
    block_norms : dict name -> scaled residual norm (dimensionless: each block's residual
        against the size of its own terms, 1 = nothing solved yet)
    counts : dict label -> int (e.g. open / stick / slip faces), logged
    active_set : (n_faces,) contact states, used for the "active set unchanged" test
    piecewise_linear : the residual is affine while the active set does not change, so that
        the Newton step that kept it was exact; False for smooth nonlinear terms (dilatancy),
        which then need the increment test
    """

    residual: np.ndarray
    jacobian: object
    block_norms: dict
    counts: dict = field(default_factory=dict)
    active_set: np.ndarray | None = None
    piecewise_linear: bool = True


@dataclass
class NewtonOptions:
    """Stopping rule: all scaled block residuals ≤ ``tol`` and the scaled increment ≤ ``increment_tol``."""

    tol: float = 1e-8
    increment_tol: float = 1e-8
    max_iterations: int = 50
    label: str = "Newton"
    # Full steps for the first `free_steps` iterations (the active set settles), then
    # backtracking on the scaled residual norm: semi-smooth Newton on friction laws can cycle
    # between active sets, a damped step breaks the cycle.
    free_steps: int = 6
    min_step: float = 1.0 / 64
    # Give up early when the residual has not halved over the last `stall_iterations`
    # iterations (active sets cycling): the caller cuts the time step at once instead of
    # spending the remaining iterations (C5: 50 iterations ≈ 5 min at 46k cells, after which
    # two half steps converge in ~9 iterations each). 0 (the default, static problems) disables
    # the test; the time loops of runs/ set it.
    stall_iterations: int = 0
    # Attainable accuracy: with the active set fixed and an increment below
    # 10⁻² increment_tol (nothing moves), a residual up to `floor_factor` × tol is the round-off
    # floor of the linear solves (cond(J) ε grows like h⁻²: 1.1e-8 on C5 at 23k cells after T/2,
    # with increments of 1e-11), and the iterate is accepted instead of iterating to max_iterations.
    floor_factor: float = 100.0


@dataclass
class NewtonResult:
    x: np.ndarray
    iterations: int
    residual: float
    counts: dict
    history: list
    seconds_linear: float
    seconds_assembly: float


def _merit(lin: Linearisation) -> float:
    return float(np.sqrt(sum(v * v for v in lin.block_norms.values())))


def semismooth_newton(linearise: Callable[[np.ndarray], Linearisation], x0: np.ndarray, solver: LinearSolver,
                      increment_norm: Callable[[np.ndarray, np.ndarray], float],
                      options: NewtonOptions = NewtonOptions(), verbose: bool = True) -> NewtonResult:
    """Run the semi-smooth Newton loop from x0.

    Converged when every block norm is ≤ tol and either the last increment is ≤ increment_tol
    or the last full step kept the active set (then the last linear solve was exact for the
    final set; for a residual that is not piecewise linear, the previous residual must also
    have been ≤ tol).
    Raises RunError after ``max_iterations`` with the last residuals and state counts.
    """
    x = np.array(x0, float)
    history = []
    t_lin = t_asm = 0.0
    prev_active = None
    inc = np.inf
    step = 1.0
    t0 = time.perf_counter()
    lin = linearise(x)
    t_asm += time.perf_counter() - t0
    for it in range(options.max_iterations + 1):
        rnorm = max(lin.block_norms.values()) if lin.block_norms else 0.0
        same = prev_active is not None and lin.active_set is not None and np.array_equal(prev_active, lin.active_set)
        # a full step that kept the active set solved the last linear system exactly when the
        # residual is affine for a fixed set; with smooth nonlinear terms (dilatancy) the step
        # after the one that met the tolerance is at round-off (quadratic convergence), which
        # also covers iterates at rest, where a relative increment test cannot be met
        exact = same and step == 1.0 and (lin.piecewise_linear
                                          or bool(history) and history[-1]["residual"] <= options.tol)
        row = {"iteration": it, "residual": rnorm, "increment": inc, "step": step, **lin.block_norms, **lin.counts}
        history.append(row)
        if verbose:
            states = " ".join(f"{k} {v}" for k, v in lin.counts.items())
            blocks = " ".join(f"{k} {v:.2e}" for k, v in lin.block_norms.items())
            log.info("%s it %2d: residual %.3e (%s) increment %.2e%s  %s", options.label, it, rnorm, blocks,
                     inc if np.isfinite(inc) else float("nan"), f" (step {step:g})" if step < 1 else "", states)
        if not np.all(np.isfinite(lin.residual)):
            raise RunError(f"{options.label}: the residual became NaN/Inf at iteration {it}")
        if rnorm <= options.tol and (inc <= options.increment_tol or exact or it == 0 and rnorm == 0.0):
            return NewtonResult(x, it, rnorm, lin.counts, history, t_lin, t_asm)
        if same and inc <= 1e-2 * options.increment_tol and rnorm <= options.floor_factor * options.tol:
            log.info("%s: accepted at the round-off floor (residual %.2e, increment %.1e, active set fixed)",
                     options.label, rnorm, inc)
            return NewtonResult(x, it, rnorm, lin.counts, history, t_lin, t_asm)
        if it == options.max_iterations:
            break
        k = options.stall_iterations
        if k and it >= options.free_steps + k:
            r = [h["residual"] for h in history]
            if min(r[-k:]) > 0.5 * min(r[:-k]):
                raise RunError(f"{options.label} stalled: the scaled residual did not halve in {k} iterations "
                               f"(best {min(r):.3e}, now {rnorm:.3e}; active sets cycling) — smaller load or "
                               "time steps help")
        prev_active = None if lin.active_set is None else lin.active_set.copy()
        t0 = time.perf_counter()
        dx = solver.solve(lin.jacobian, -lin.residual)
        t_lin += time.perf_counter() - t0
        merit0 = _merit(lin)
        step = 1.0
        t0 = time.perf_counter()
        while True:
            trial = linearise(x + step * dx)
            if it < options.free_steps or step <= options.min_step or \
                    _merit(trial) <= (1 - 1e-4 * step) * merit0 or not np.isfinite(merit0):
                break
            step *= 0.5
        t_asm += time.perf_counter() - t0
        inc = increment_norm(step * dx, x)
        x = x + step * dx
        lin = trial
    states = ", ".join(f"{v} {k}" for k, v in lin.counts.items())
    raise RunError(f"{options.label} did not converge in {options.max_iterations} iterations: scaled residual "
                   f"{rnorm:.3e} > tol {options.tol:g} (" + ", ".join(f"{k} {v:.2e}" for k, v in
                                                                     lin.block_norms.items())
                   + f"); last contact states: {states or 'n/a'}. Try more iterations (solver.max_iterations), "
                   "a different contact.beta, or smaller load steps.")
