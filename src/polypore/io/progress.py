"""Progress of long work: elapsed time and an estimate of what is left.

:class:`Progress` counts the items of a loop (time steps, convergence levels) for the per-step log
lines ("step k/N: ... (elapsed …, about … left)"). Its estimate assumes the remaining items cost
what the finished ones cost on average (``growth = 1``), or that each costs ``growth`` times the
one before (mesh refinement levels).

:class:`LiveStatus` is the live status line of issue 25 (docs/live_progress.md): what the run is
doing right now (phase, Newton iteration and residual, Krylov iterations), the elapsed time of the
step and of the run and an estimate for both, also before the first step completes, refreshed by
a background thread so that it moves while a native solve holds the main thread. On a terminal it
is one line rewritten in place; in a log (not a terminal) a plain line whenever nothing was
written for ``interval`` seconds. The work reports through :mod:`polypore.core.live`.
"""

from __future__ import annotations

import logging
import math
import shutil
import sys
import threading
import time

from ..core import live


def clock(seconds: float) -> str:
    """'42 s', '3 min 05 s', '2 h 07 min'."""
    s = max(0.0, float(seconds))
    if s < 60:
        return f"{s:.0f} s"
    if s < 3600:
        return f"{int(s // 60)} min {int(s % 60):02d} s"
    return f"{int(s // 3600)} h {int(s % 3600 // 60):02d} min"


class Progress:
    """Counts finished items of a loop of ``total`` items and estimates the time left.

    Parameters
    ----------
    total : int
        Number of items (steps, levels).
    label : str
        What an item is, for the bar ("steps", "levels").
    growth : float
        Cost ratio of consecutive items (1: equal cost; 8: 3D refinement levels).
    bar : bool or None
        Show a rich bar; by default only when stderr is a terminal and the polypore logger
        shows INFO messages (not with --quiet).
    """

    def __init__(self, total: int, label: str = "steps", growth: float = 1.0, bar: bool | None = None):
        self.total = max(int(total), 0)
        self.label = label
        self.growth = float(growth)
        self.done = 0
        self.start = time.perf_counter()
        self._last = []                      # seconds of the last two finished items
        self._booked = 0.0                   # their running total (advance without seconds)
        if bar is None:         # the live status line, when there is one, shows the progress instead
            bar = sys.stderr.isatty() and logging.getLogger("polypore").isEnabledFor(logging.INFO) \
                and live.current() is None
        self._bar = None
        if bar and self.total > 1:
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress as RichProgress, TextColumn,
                                       TimeElapsedColumn)

            self._bar = RichProgress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                                     TimeElapsedColumn(), TextColumn("{task.fields[left]}"), transient=True)
            self._task = self._bar.add_task(label, total=self.total, left="")

    def __enter__(self):
        if self._bar is not None:
            self._bar.start()
        if self.total:
            live.update(steps=self.total, unit=self.label.rstrip("s") or self.label, growth=self.growth, step=1)
        return self

    def __exit__(self, *exc):
        if self._bar is not None:
            self._bar.stop()
        live.update(steps=None)
        return False

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def remaining(self) -> float | None:
        """Estimated seconds left, or None before the first item finishes."""
        if not self._last:
            return None
        left = self.total - self.done
        if self.growth == 1.0:
            return left * self.elapsed / self.done
        r = self.growth
        if len(self._last) >= 2 and self._last[-2] > 0:
            r = max(1.0, self._last[-1] / self._last[-2])     # the measured growth, when known
        return self._last[-1] * sum(r ** i for i in range(1, left + 1))

    def advance(self, seconds: float | None = None) -> str:
        """Record a finished item (its own ``seconds``, default: time since the previous one);
        returns 'elapsed …, about … left' for a log line."""
        now = self.elapsed
        took = now - self._booked if seconds is None else float(seconds)
        self._booked += took
        self._last = (self._last + [took])[-2:]
        self.done += 1
        live.update(step_done=True, **({"step": self.done + 1} if self.done < self.total else {}))
        text = self.text()
        if self._bar is not None:
            rem = self.remaining()
            self._bar.update(self._task, completed=self.done, left="" if rem is None or self.done >= self.total else f"~{clock(rem)} left")
        return text

    def text(self) -> str:
        rem = self.remaining()
        if self.done >= self.total or rem is None:
            return f"elapsed {clock(self.elapsed)}"
        return f"elapsed {clock(self.elapsed)}, about {clock(rem)} left"


class LiveStatus:
    """The live status line of a run (module docstring); an observer of :mod:`polypore.core.live`.

    Parameters
    ----------
    stream : text stream written to (default: sys.stderr)
    clock : callable returning seconds (default: time.perf_counter); tests pass a fake one
    terminal : one line rewritten in place (True) or plain lines (False); default: stream.isatty()
    tick : seconds between redraws of the terminal line (and of the background thread's polls)
    interval : plain form: a line after this many seconds without any output (log line or status)
    width : the terminal line is cut to this many characters (default: the terminal's width - 1)
    prefix : the plain lines' prefix (that of the log lines)
    iterations_per_step : Newton iterations per step assumed before a step has finished
    seconds_per_unknown : seconds of one Newton iteration per unknown assumed before an iteration
        has finished (a first guess between block-amg on C5 at 46k cells, 2.9 s for 175k unknowns,
        and SuperLU on dfm-3d's default mesh, ~9 s for 22.5k unknowns on 2 loaded cores)

    Use ``with LiveStatus() as status:`` (installs it, starts the thread, clears the line at the end);
    :meth:`guard` a logging handler so that its records first clear the line. :meth:`poll` does one
    refresh (the thread calls it every ``tick`` seconds; tests call it with a fake clock).
    """

    def __init__(self, stream=None, *, clock=time.perf_counter, terminal: bool | None = None, tick: float = 1.0,
                 interval: float = 30.0, width: int | None = None, prefix: str = "[polypore] ",
                 iterations_per_step: float = 6.0, seconds_per_unknown: float = 1e-4):
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        if terminal is None:
            try:
                terminal = self.stream.isatty()
            except (AttributeError, ValueError):
                terminal = False
        self.terminal = bool(terminal)
        self.tick, self.interval, self.width, self.prefix = float(tick), float(interval), width, prefix
        self.iterations_per_step = float(iterations_per_step)
        self.seconds_per_unknown = float(seconds_per_unknown)
        self._state = threading.Lock()        # the facts (short holds, on the computing thread too)
        self._out = threading.RLock()         # writing to the stream (the thread and the log records)
        self.start = self.clock()
        self._phases: list[tuple[str, float]] = []
        self._newton = None                   # {"label", "it", "residual", "unknowns", "since"}
        self._samples: dict[str, list] = {}   # Newton label -> [(seconds of an iteration, unknowns)]
        self._steps = None                    # number of steps (None: no step loop running)
        self._unit, self._growth = "step", 1.0
        self._step, self._step_start, self._step_its = 0, self.start, 0
        self._finished: list[tuple[float, int]] = []     # (seconds, Newton iterations) of finished steps
        self._krylov_done = self._krylov_live = 0
        self._shown = False
        self._last_draw = -math.inf
        self._last_out = self.start
        self._thread = None
        self._stop = threading.Event()
        self._guarded = []
        self._previous = None

    # -- the observer protocol (polypore.core.live) -------------------------------------------------

    def enter(self, name: str) -> None:
        with self._state:
            self._phases.append((name, self.clock()))

    def leave(self, name: str) -> None:
        with self._state:
            for k in range(len(self._phases) - 1, -1, -1):
                if self._phases[k][0] == name:
                    del self._phases[k]
                    break

    def krylov_iteration(self) -> None:
        self._krylov_live += 1

    def update(self, **facts) -> None:
        now = self.clock()
        with self._state:
            if "steps" in facts:
                self._steps = facts["steps"]
                if self._steps is None:
                    self._step = 0
            if "unit" in facts:
                self._unit = facts["unit"]
            if "growth" in facts:
                self._growth = float(facts["growth"])
            if facts.get("step_done"):
                self._finished.append((now - self._step_start, self._step_its))
            if "step" in facts:
                self._step, self._step_start, self._step_its = int(facts["step"]), now, 0
                self._krylov_done = self._krylov_live = 0
            if "newton_start" in facts:
                self._newton = {"label": facts["newton_start"], "it": None, "residual": None,
                                "unknowns": facts.get("unknowns"), "since": now}
                if not self._steps:
                    self._krylov_done = self._krylov_live = 0
            nw = self._newton
            if "newton" in facts and nw is not None:
                if facts["newton"] and nw["it"] is not None:     # an iteration (solve, line search) finished
                    self._samples.setdefault(nw["label"], []).append((now - nw["since"], nw["unknowns"]))
                    self._step_its += 1
                nw["it"], nw["residual"], nw["since"] = facts["newton"], facts.get("residual"), now
            if "krylov_solved" in facts:
                self._krylov_done += int(facts["krylov_solved"])
                self._krylov_live = 0
            if facts.get("newton_end"):
                self._newton = None

    # -- estimates ----------------------------------------------------------------------------------

    def _iteration_seconds(self, nw, now, samples) -> tuple[float | None, bool]:
        """(seconds of one iteration of the running Newton solve, rough?): the mean of its label's
        last iterations; else, scaled by the unknowns, of the other Newton solves' iterations (the
        initial equilibrium before the first step) or ``seconds_per_unknown`` (rough); never less
        than the current iteration has taken so far."""
        own = samples.get(nw["label"], [])[-5:]
        if own:
            return sum(s for s, _ in own) / len(own), False
        n = nw["unknowns"]
        other = [(s, m) for v in samples.values() for s, m in v[-5:] if m]
        if n and other:
            t = n * sum(s / m for s, m in other) / len(other)
        elif n:
            t = n * self.seconds_per_unknown
        else:
            return None, True
        if nw["it"] is not None:
            t = max(t, now - nw["since"])
        return t, True

    def estimate(self, now: float | None = None) -> tuple[float | None, float | None, bool]:
        """(seconds left in the current step or solve, seconds left in the run, rough?); None where
        nothing can be said yet. The step: the Newton iterations it still needs (the mean of the
        finished steps, else ``iterations_per_step``) times the seconds of one iteration, or with no
        Newton solve running the mean finished step minus the time spent; the run: that plus the
        steps after it at the mean finished step (× ``growth`` per level), else at the step's estimate."""
        now = self.clock() if now is None else now
        with self._state:
            nw = dict(self._newton) if self._newton else None
            samples = {k: v[-5:] for k, v in self._samples.items()}
            done = list(self._finished)
            steps, k, growth = self._steps, self._step, self._growth
            step_elapsed, step_its = now - self._step_start, self._step_its
        rough = False
        step_left = per_step = None
        its_per_step = self.iterations_per_step
        if done and steps:
            its_per_step = sum(i for _, i in done) / len(done)
        elif nw is not None:
            rough = True
        if nw is not None:
            t_it, r = self._iteration_seconds(nw, now, samples)
            if t_it is not None:
                rough = rough or r
                left = max(its_per_step - step_its, 1.0)            # iterations, the current one included
                into = now - nw["since"] if nw["it"] is not None else 0.0
                step_left = (left - 1.0) * t_it + max(t_it - into, 0.0)
                per_step = its_per_step * t_it
        if done and steps:
            last = done[-1][0]
            per_step = sum(s for s, _ in done) / len(done) if growth == 1.0 else last * growth
            if step_left is None and k >= 1:
                step_left = max(per_step - step_elapsed, 0.0)
        run_left = None
        if steps:
            after = steps - k if k >= 1 else steps          # k = 0: the solve before the first step
            if per_step is not None and (step_left is not None or k == 0 and not nw):
                if growth == 1.0 or not done:
                    future = after * per_step
                else:
                    future = sum(per_step * growth ** (i + 1) for i in range(after))   # per_step: this level
                run_left = (step_left or 0.0) + future
        else:
            run_left = step_left
        return step_left, run_left, rough

    # -- the line -----------------------------------------------------------------------------------

    def status(self, now: float | None = None) -> str:
        """The status as text, parts joined by ' · ': the step, the Newton iteration and its
        residual, the phase and how long it has run, the Krylov iterations of the step, the elapsed
        time of the step and of the run each with its estimate ("~… left"), and "(rough estimate)"
        while the estimate rests on assumed figures (before an iteration or a step has finished)."""
        now = self.clock() if now is None else now
        step_left, run_left, rough = self.estimate(now)
        with self._state:
            parts = []
            if self._steps:
                parts.append(f"{self._unit} {self._step}/{self._steps}" if self._step >= 1
                             else f"before {self._unit} 1/{self._steps}")
            nw = self._newton
            if nw is not None:
                text = nw["label"] + (f" it {nw['it']}" if nw["it"] is not None else "")
                if nw["residual"] is not None:
                    text += f", residual {nw['residual']:.1e}"
                parts.append(text)
            if self._phases:
                name, since = self._phases[-1]
                parts.append(f"{name} {clock(now - since)}")
            elif nw is None:
                parts.append("working")
            kry = self._krylov_done + self._krylov_live
            if kry:
                parts.append(f"{kry} Krylov its")
            if self._steps and self._step >= 1:
                parts.append(f"{self._unit} {clock(now - self._step_start)}"
                             + (f", ~{clock(step_left)} left" if step_left is not None else ""))
            parts.append(f"run {clock(now - self.start)}" + (f", ~{clock(run_left)} left" if run_left is not None
                                                             else ""))
        text = " · ".join(parts)
        return text + " (rough estimate)" if rough and (step_left is not None or run_left is not None) else text

    def poll(self) -> None:
        """One refresh: redraw the terminal line (at most every ``tick`` s), or in plain form write
        a line when nothing was written for ``interval`` s."""
        now = self.clock()
        with self._out:
            if self.terminal:
                if now - self._last_draw < 0.999 * self.tick:
                    return
                line = self.status(now)
                width = self.width or shutil.get_terminal_size((100, 24)).columns - 1
                if len(line) > width:
                    line = line[:max(width - 1, 0)] + "…"
                self._write("\r\x1b[K" + line)
                self._shown = True
                self._last_draw = now
            elif now - self._last_out >= self.interval:
                self._write(f"{self.prefix}still running: {self.status(now)}\n")
                self._last_out = now

    def erase(self) -> None:
        """Clear the terminal line (before other output); it is redrawn at the next poll."""
        with self._out:
            if self._shown:
                self._write("\r\x1b[K")
                self._shown = False
            self._last_out = self.clock()
            self._last_draw = -math.inf

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            pass

    def guard(self, handler: logging.Handler) -> None:
        """Let the log records of ``handler`` first clear the line (and count as output)."""
        emit = handler.emit

        def guarded(record):
            with self._out:
                self.erase()
                emit(record)

        handler.emit = guarded
        self._guarded.append(handler)

    # -- lifetime -----------------------------------------------------------------------------------

    def _run(self) -> None:
        while not self._stop.wait(self.tick):
            try:
                self.poll()
            except Exception:        # the status line must never stop a run
                pass

    def __enter__(self):
        self._previous = live.install(self)
        self._thread = threading.Thread(target=self._run, name="polypore-status", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        live.install(self._previous)
        self.erase()
        for h in self._guarded:
            h.__dict__.pop("emit", None)
        self._guarded.clear()
        return False


def erase_live_line() -> None:
    """Clear the live status line, if one is shown (before writing to stderr outside logging)."""
    obs = live.current()
    if isinstance(obs, LiveStatus):
        obs.erase()
