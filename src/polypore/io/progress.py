"""Progress of long loops (time steps, convergence levels): elapsed time and an estimate of
what is left, as a rich progress bar on a terminal and as text for the log lines.

The estimate assumes the remaining items cost what the finished ones cost on average
(``growth = 1``), or that each costs ``growth`` times the one before (mesh refinement levels).
"""

from __future__ import annotations

import logging
import sys
import time


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
        if bar is None:
            bar = sys.stderr.isatty() and logging.getLogger("polypore").isEnabledFor(logging.INFO)
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
        return self

    def __exit__(self, *exc):
        if self._bar is not None:
            self._bar.stop()
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
