"""Signal handlers that native libraries silently disarm.

Some libraries reset signal dispositions at C level when they start: ``gmsh.initialize``
sets SIGTERM and SIGPIPE (and SIGSEGV, SIGFPE, SIGILL, SIGBUS) back to their defaults.
Python does not notice: :func:`signal.getsignal` still reports its own handler, but SIGTERM
now kills the process outright (no message, no failed.json, the staging folder left
behind) and writing to a closed pipe kills it instead of raising BrokenPipeError.
"""

from __future__ import annotations

import signal
import threading

__all__ = ["rearm_signal_handlers"]


def rearm_signal_handlers() -> list[int]:
    """Install again, at C level, every handler that Python believes is installed.

    Call after any native call that may reset signal dispositions (``gmsh.initialize``,
    ``gmsh.finalize``). Python functions (SIGINT, SIGTERM under the command line) and
    ignored signals (SIGPIPE) are re-installed: :func:`signal.signal` with the same handler
    re-arms the C handler. Defaults are left alone: a C-level handler Python does not know
    of (faulthandler's) is not Python's to reset. Off the main thread nothing can be done.

    Returns
    -------
    list of int
        The signals re-installed.
    """
    if threading.current_thread() is not threading.main_thread():
        return []
    done = []
    for sig in signal.valid_signals():
        try:
            handler = signal.getsignal(sig)
        except (ValueError, OSError):
            continue
        if callable(handler) or handler == signal.SIG_IGN:
            try:
                signal.signal(sig, handler)
            except (ValueError, OSError):  # SIGKILL, SIGSTOP and signals the platform refuses
                continue
            done.append(int(sig))
    return done
