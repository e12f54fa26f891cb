"""What long work is doing right now, for a live status line (issue 25: silence on long runs).

The layers that do the work (mesh generation, the solvers, Newton, the time loops) report here
and know nothing of terminals: a phase they enter (:func:`phase`), facts (:func:`update`: the
Newton iteration and its residual, the unknowns, the step), one Krylov iteration
(:func:`krylov_iteration`). The run drivers or the CLI install an observer
(:class:`polypore.io.progress.LiveStatus`) that turns these into a status line; without one every
call returns at once (one global read), so the numerics pay nothing and behave the same.

The observer protocol (every method must be cheap: it runs on the computing thread)::

    enter(name)              a phase starts ("meshing", "assembling", "factorising", ...)
    leave(name)              it ends (phases nest: the enclosing one shows again)
    update(**facts)          newton=k, residual=r, unknowns=n, label="...", step=k, steps=N,
                             step_done=seconds, krylov_solved=iterations of the finished solve
    krylov_iteration()       one more Krylov iteration of the current linear solve
"""

from __future__ import annotations

from contextlib import contextmanager

_observer = None


def install(observer):
    """Make ``observer`` receive the reports (None: nobody); returns the previous one."""
    global _observer
    previous, _observer = _observer, observer
    return previous


def current():
    """The installed observer, or None."""
    return _observer


@contextmanager
def phase(name: str):
    """The ``with`` block is phase ``name`` of the live status."""
    obs = _observer
    if obs is None:
        yield
        return
    obs.enter(name)
    try:
        yield
    finally:
        obs.leave(name)


def update(**facts) -> None:
    """Report facts (protocol in the module docstring)."""
    obs = _observer
    if obs is not None:
        obs.update(**facts)


def krylov_iteration(*_args) -> None:
    """One Krylov iteration done (usable directly as a SciPy callback's body)."""
    obs = _observer
    if obs is not None:
        obs.krylov_iteration()
