"""Semi-smooth Newton iteration (scheme.md §4), independent of the physics.

The caller supplies ``linearise(x) -> Linearisation`` (residual blocks, Jacobian, labels
such as open/stick/slip counts) and block norms; this module runs the loop, logs every
iteration and decides convergence or failure.

**Inexact Newton (forcing terms).** With an iterative linear solver (one whose ``takes_target``
is true, the block solvers) and row weights from the model (``Linearisation.row_scale``),
each Krylov solve is asked for a relative residual η_k in the weighted norm ‖w∘r‖₂, the norm
of Newton's own test, instead of a fixed 1e-8 in the plain 2-norm. The plain norm lets one kind
of equation dominate (on C5 the multiplier rows hold nearly the whole right-hand side), and GMRES,
asked for 1e-8 of it, stalls at the round-off floor of that system (docs/poromechanics.md,
"Measurements cited by the code").
η_k is Eisenstat–Walker's choice 2 (SIAM J. Sci. Comput. 17, 1996):

    η_k = γ (‖F_k‖/‖F_{k−1}‖)^α,  γ = 0.9, α = 2,  kept ≥ γ η_{k−1}^α when that is > 0.1,

capped at ``forcing_max`` and never below what the Newton test needs, θ tol/‖F_k‖ (no
oversolving). Two semi-smooth-specific rules keep the exact steps exact: the first iteration
(when the caller expects the active set to stay, ``first_tight``), and every iteration whose
active set equals the previous iterate's (the step is expected to be the last: for a fixed active
set the residual is affine), solve to θ tol/‖F_k‖, θ = ``forcing_margin``, so that the new
residual is below tol. A linear problem thus still converges in one Newton iteration (two when
θ tol/‖F_k‖ is below the round-off floor of the weighted norm, at which the block solvers stop:
block_contact.attainable_rtol), and only iterations that change the active set are solved
loosely. A tight solve at an iterate that already meets the test (θ tol/‖F_k‖ > ``forcing_max``:
the confirming step that a residual which is not piecewise linear, e.g. with dilatancy, needs) is
asked for θ tol/‖F_k‖ itself, up to ``forcing_confirm``. A first iteration that is not tight gets
``forcing_max``: the poromechanics time loop passes ``first_tight`` only after a step that
converged in one iteration (or left every state as it found it), because an exact first solve is
wasted when the active set then moves (docs/poromechanics.md), and not for a run's first step,
whose norm from a state at rest holds the sources alone (models/poromechanics.py).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core import live
from ..core.errors import RunError
from ..core.memory import trim_heap
from .interface import LinearSystemSolver
from ..core.timing import SPLIT

log = logging.getLogger("polypore")


@dataclass
class Linearisation:
    """What the model returns at an iterate.

    Attributes
    ----------
    residual : (n,) residual vector F(x)
    jacobian : (n, n) sparse generalised Jacobian; on N ranks this rank's rows of it
        (:class:`~polypore.parallel.layout.OwnedRows`). Newton drops it after its linear solve.
    block_norms : dict name -> scaled residual norm (dimensionless: each block's residual
        against the size of its own terms, 1 = nothing solved yet)
    counts : dict label -> int (e.g. open / stick / slip faces), logged
    active_set : (n_faces,) contact states, used for the "active set unchanged" test
    piecewise_linear : the residual is affine while the active set does not change, so that
        the Newton step that kept it was exact; False for smooth nonlinear terms (dilatancy),
        which then need the increment test
    row_scale : (n,) positive weights w (1/unit of each residual row) or None: ‖w∘residual‖₂ is the
        Newton measure, ``block_norms`` squared and summed (the flow kinds summed, not maxed);
        iterative linear solves are stopped in this norm (module docstring). None: plain 2-norm
        and the linear solver's own tolerance.
    """

    residual: np.ndarray
    jacobian: object
    block_norms: dict
    counts: dict = field(default_factory=dict)
    active_set: np.ndarray | None = None
    piecewise_linear: bool = True
    row_scale: np.ndarray | None = None


@dataclass
class KrylovTarget:
    """What one iterative linear solve must reach (set by Newton for each iteration).

    Attributes
    ----------
    weights : (n,) positive row weights w or None; the solver works on the row-scaled system
        diag(w) J x = diag(w) b (so that GMRES minimises and tests ‖w∘(b − J x)‖₂)
    rtol : relative residual ‖w∘(b − J x)‖ ≤ rtol ‖w∘b‖ (the forcing term η_k, dimensionless)
    """

    weights: np.ndarray | None
    rtol: float


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
    # spending the remaining iterations (two half steps converge quickly, docs/poromechanics.md).
    # 0 (the default, static problems) disables
    # the test; the time loops of runs/ set it.
    stall_iterations: int = 0
    # With stall_iterations set, also give up when the line search has cut each of the last
    # `crawl_iterations` steps to ≤ `crawl_step` and the residual has not halved over them: the
    # iterate sits at a kink of the contact law that neither one-sided linearisation crosses (a face
    # flipping stick ↔ slip, its Newton slip predicted backwards; docs/iterative_cornerpoint.md, "What
    # the stall is"). A smaller time step
    # converges.
    crawl_iterations: int = 3
    crawl_step: float = 1.0 / 8
    # Attainable accuracy: with the active set fixed and an increment below
    # 10⁻² increment_tol (nothing moves), a residual up to `floor_factor` × tol is the round-off
    # floor of the linear solves (cond(J) ε grows like h⁻², docs/poromechanics.md), and the iterate is
    # accepted instead of iterating to max_iterations.
    floor_factor: float = 100.0
    # Forcing terms of the iterative linear solves (module docstring): "eisenstat-walker", or
    # "fixed" for the solver's own relative tolerance in the plain 2-norm (the behaviour before).
    # Direct solvers ignore it. forcing_max caps η_k (EW propose 0.9; looser caps cost Newton iterations);
    # forcing_min is the smallest η asked of a Krylov solver (below it round-off decides).
    # 1e-2 balances Newton against GMRES iterations (a Newton iteration costs ~5 GMRES ones;
    # docs/poromechanics.md).
    forcing: str = "eisenstat-walker"
    forcing_max: float = 1e-2
    forcing_min: float = 1e-12
    forcing_margin: float = 0.1
    # loosest η of a tight solve whose need θ tol/‖F_k‖ exceeds forcing_max (a confirming step)
    forcing_confirm: float = 0.5
    forcing_gamma: float = 0.9
    forcing_alpha: float = 2.0


@dataclass
class NewtonResult:
    x: np.ndarray
    iterations: int
    residual: float
    counts: dict
    history: list
    seconds_linear: float
    seconds_assembly: float
    active_set: np.ndarray | None = None      # the contact states at x (the last linearisation's)


def _merit(lin: Linearisation) -> float:
    return float(np.sqrt(sum(v * v for v in lin.block_norms.values())))


def row_weights(*scales: np.ndarray, spread: float = 1e8) -> np.ndarray:
    """(n,) Newton row weights 1/scale from the per-row residual scales of each block.

    A scale is floored at max(scale)/``spread``: a block without any term yet (e.g. the flow
    rows of a state at rest) has its norm's scale floored at 1e-300, and weights of 1e150 would
    wreck the row-scaled Krylov system; the floor bounds the scaling's condition number.

    Parameters
    ----------
    *scales : (n_b,) arrays, the size of each residual row in the row's own unit (the model's
        block scales, N for the mechanics and the Δt-scaled flow rows); concatenated in order
    spread : largest ratio of two weights (dimensionless)

    Returns
    -------
    (n,) array, 1/unit of each row
    """
    s = np.concatenate(scales)
    top = float(s.max(initial=0.0))
    return 1.0 / np.maximum(s, max(top / spread, 1e-300))


FORCING = ("eisenstat-walker", "fixed")
# first iterate of a time step's Newton loop: the last step's increment extrapolated, or the old state
PREDICTORS = ("linear", "none")


def forcing_term(fnorm: float, prev_fnorm: float | None, prev_eta: float | None, tight: bool,
                 options: NewtonOptions) -> float:
    """η_k of one Newton iteration (module docstring).

    Parameters
    ----------
    fnorm : ‖w∘F(x_k)‖₂, the weighted residual norm at the iterate (dimensionless)
    prev_fnorm, prev_eta : the same norm and η at the previous iterate (None at the first)
    tight : solve to what the Newton test needs (first iteration if the caller asks, or the active
        set unchanged); otherwise EW's η, or ``forcing_max`` without a previous iterate
    options : NewtonOptions (tol, forcing_*)

    Returns
    -------
    float : relative tolerance in [forcing_min, forcing_max]
    """
    need = options.forcing_margin * options.tol / fnorm if fnorm > 0 else 1.0
    if tight:
        if need > options.forcing_max:
            # the iterate already (nearly) meets the test: this solve confirms it (a residual that
            # is not piecewise linear needs one more iterate), and any η ≤ need keeps the next
            # residual below θ tol; capping it at forcing_max wasted GMRES iterations on these
            # confirming solves (docs/iterative_cornerpoint.md, "block-direct")
            return float(min(need, options.forcing_confirm))
        eta = need
    elif prev_fnorm is None or not prev_fnorm > 0:
        eta = max(options.forcing_max, need)              # a loose first iteration
    else:
        g, a = options.forcing_gamma, options.forcing_alpha
        eta = g * (fnorm / prev_fnorm) ** a
        if prev_eta is not None and g * prev_eta ** a > 0.1:
            # EW's safeguard: do not let η drop sharply after one lucky reduction
            eta = max(eta, g * prev_eta ** a)
        eta = max(eta, need)
    return float(min(max(eta, options.forcing_min), options.forcing_max))


def semismooth_newton(linearise: Callable[[np.ndarray], Linearisation], x0: np.ndarray, solver: LinearSystemSolver,
                      increment_norm: Callable[[np.ndarray, np.ndarray], float],
                      options: NewtonOptions | None = None, verbose: bool = True,
                      first_tight: bool = True, x_pred: np.ndarray | None = None) -> NewtonResult:
    """Run the semi-smooth Newton loop from x0.

    Converged when every block norm is ≤ tol and either the last increment is ≤ increment_tol
    or the last full step kept the active set (then the last linear solve was exact for the
    final set; for a residual that is not piecewise linear, the previous residual must also
    have been ≤ tol).
    Raises RunError after ``max_iterations`` with the last residuals and state counts.
    The linear solves are inexact (forcing terms, module docstring) when ``options.forcing`` is
    "eisenstat-walker", the solver takes a :class:`KrylovTarget` and the model gives row weights;
    ``first_tight`` asks the first solve for what the Newton test needs (a step expected to be
    linear), otherwise it gets ``forcing_max``.
    ``x_pred`` (same shape as x0) is a predicted first iterate, e.g. the previous time step's
    increment extrapolated: Newton starts there unless its residual is not finite. Not "where its
    residual is the smaller": at x0 the residual holds only the step's new loads, which a good
    prediction trades for small residuals in every block, and that comparison threw the predictor
    away where it halved the Newton iterations (docs/iterative_cornerpoint.md, ninth session).
    """
    options = NewtonOptions() if options is None else options
    if options.forcing not in FORCING:
        raise ValueError(f"NewtonOptions.forcing must be one of {FORCING}, got {options.forcing!r}")
    live.update(newton_start=options.label, unknowns=int(np.size(x0)))
    seen = {"iterations": 0}
    try:
        return _newton(linearise, x0, solver, increment_norm, options, verbose, first_tight, x_pred, seen)
    except RunError as exc:
        # what the failed attempt cost, for the caller's report (a cut step's work is not lost
        # from the run's totals: runs/march.py)
        exc.newton_iterations = seen["iterations"]
        raise
    finally:
        live.update(newton_end=True)


def _krylov_total(solver: LinearSystemSolver) -> int:
    """Krylov iterations of all the solves of ``solver`` so far."""
    return int(sum(solver.krylov_iterations))


def _newton(linearise, x0, solver, increment_norm, options, verbose, first_tight, x_pred, seen) -> NewtonResult:
    inexact = options.forcing != "fixed" and bool(solver.takes_target)
    prev_fnorm = prev_eta = None
    x = np.array(x0, float)
    history: list[dict] = []
    t_lin = t_asm = 0.0
    prev_active = None
    inc = np.inf
    step = 1.0
    t0 = time.perf_counter()
    with SPLIT.timed("assembly"):
        lin: Linearisation | None = None
        if x_pred is not None:
            lin = linearise(np.array(x_pred, float))
            if np.all(np.isfinite(lin.residual)):
                x = np.array(x_pred, float)
            else:
                lin.jacobian = None
                lin = None
        if lin is None:
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
        seen["iterations"] = it
        live.update(newton=it, residual=rnorm)
        if verbose:
            states = " ".join(f"{k} {v}" for k, v in lin.counts.items())
            blocks = " ".join(f"{k} {v:.2e}" for k, v in lin.block_norms.items())
            log.info("%s it %2d: residual %.3e (%s) increment %.2e%s  %s", options.label, it, rnorm, blocks,
                     inc if np.isfinite(inc) else float("nan"), f" (step {step:g})" if step < 1 else "", states)
        if not np.all(np.isfinite(lin.residual)):
            raise RunError(f"{options.label}: the residual became NaN/Inf at iteration {it}")
        if rnorm <= options.tol and (inc <= options.increment_tol or exact or it == 0 and rnorm == 0.0):
            return NewtonResult(x, it, rnorm, lin.counts, history, t_lin, t_asm, lin.active_set)
        if same and inc <= 1e-2 * options.increment_tol and rnorm <= options.floor_factor * options.tol:
            log.info("%s: accepted at the round-off floor (residual %.2e, increment %.1e, active set fixed)",
                     options.label, rnorm, inc)
            return NewtonResult(x, it, rnorm, lin.counts, history, t_lin, t_asm, lin.active_set)
        if it == options.max_iterations:
            break
        k = options.stall_iterations
        if k and it >= options.free_steps + k:
            r = [h["residual"] for h in history]
            if min(r[-k:]) > 0.5 * min(r[:-k]):
                raise RunError(f"{options.label} stalled: the scaled residual did not halve in {k} iterations "
                               f"(best {min(r):.3e}, now {rnorm:.3e}; active sets cycling) — smaller load or "
                               "time steps help")
        c = options.crawl_iterations
        if k and c and len(history) > c and max(h["step"] for h in history[-c:]) <= options.crawl_step \
                and rnorm > 0.5 * history[-c - 1]["residual"]:
            raise RunError(f"{options.label} stalled: the line search cut the last {c} steps to ≤ "
                           f"{options.crawl_step:g} and the scaled residual did not halve ({rnorm:.3e}; an iterate "
                           "at a kink of the contact law) — smaller load or time steps help")
        prev_active = None if lin.active_set is None else lin.active_set.copy()
        trim_heap()                 # the assembly's temporaries, before the solver's allocations
        t0 = time.perf_counter()
        k0 = _krylov_total(solver) if live.current() is not None else None
        with SPLIT.timed("linear"):
            if inexact and lin.row_scale is not None:
                fnorm = float(np.linalg.norm(lin.row_scale * lin.residual))
                eta = forcing_term(fnorm, prev_fnorm, prev_eta, (it == 0 and first_tight) or same, options)
                row["forcing"] = eta
                dx = solver.solve(lin.jacobian, -lin.residual, target=KrylovTarget(lin.row_scale, eta))
                prev_fnorm, prev_eta = fnorm, eta
            else:
                dx = solver.solve(lin.jacobian, -lin.residual)
        t_lin += time.perf_counter() - t0
        if k0 is not None:
            live.update(krylov_solved=(_krylov_total(solver) or 0) - k0)   # not None when k0 is not
        # the Jacobian is not needed any more: its memory (on N ranks this rank's rows) and the
        # solve's temporaries go back to the system before the line search assembles the next one
        lin.jacobian = None
        trim_heap()
        merit0 = _merit(lin)
        step = 1.0
        t0 = time.perf_counter()
        while True:
            with SPLIT.timed("assembly"):
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
