"""Long native calls that a signal can still stop.

Python runs a signal handler only when the main thread is back in bytecode. A sparse
factorisation (SuperLU, PARDISO) can keep the main thread in C for minutes, so SIGINT and
SIGTERM would be honoured only when it returns. :func:`interruptible` runs such a call on a
worker thread while the main thread waits in short, interruptible joins: the handler's
exception (KeyboardInterrupt, ``Terminated``) is raised in the main thread within a fraction of
a second, the run cleans up (failed.json, no staging folder), and the abandoned worker dies
with the process.
"""

from __future__ import annotations

import atexit
import queue
import signal
import threading

__all__ = ["interruptible", "abandoned"]

_POLL = 0.1  # s between checks of the main thread for a pending signal


def _handled_by_python() -> bool:
    """True when SIGINT or SIGTERM has a Python handler that a waiting main thread can run."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            if callable(signal.getsignal(sig)):
                return True
        except (ValueError, OSError):  # pragma: no cover - platform without the signal
            continue
    return False


class _Worker:
    """One long-lived daemon thread that runs the calls: a thread per call would make OpenMP
    and MKL start a new thread team for every factorisation. A worker whose call was
    abandoned (the caller was interrupted) is replaced by a fresh one."""

    def __init__(self):
        self.jobs: queue.SimpleQueue = queue.SimpleQueue()
        self.busy = False
        self.thread = threading.Thread(target=self._loop, name="polypore-native-calls", daemon=True)
        self.thread.start()

    def stop(self):
        """End the thread if it is idle (a busy, abandoned one is left to os._exit)."""
        if not self.busy and self.thread.is_alive():
            self.jobs.put(None)
            self.thread.join(timeout=1.0)

    def _loop(self):
        while True:
            job = self.jobs.get()
            if job is None:
                return
            fn, args, kwargs, box, done = job
            try:
                box["value"] = fn(*args, **kwargs)
            except BaseException as exc:  # re-raised in the caller, with its traceback
                box["error"] = exc
            finally:
                done.set()


_WORKER: _Worker | None = None


def stop_worker() -> None:
    """End the idle worker thread; the next call starts a new one. Called at exit and before a
    fork: a live thread that had run SciPy's SuperLU left the interpreter with an error set
    where it tore the thread's state down (the final flush of stdout failed: exit status 120
    after a successful run; a forked child printed "SystemError: ... returned a result with an
    exception set")."""
    global _WORKER
    if _WORKER is not None and not _WORKER.busy:
        _WORKER.stop()
        _WORKER = None


atexit.register(stop_worker)


def abandoned() -> bool:
    """True when a call was left running by an interrupted caller. The process must then end
    with :func:`os._exit`: a normal interpreter shutdown frees the objects the abandoned native
    code still uses and crashes it (SIGSEGV instead of the signal's exit status)."""
    return _WORKER is not None and _WORKER.busy


def interruptible(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, run so that a signal stops the caller at once.

    Only worth it for calls that release the GIL (ctypes calls, SciPy's SuperLU); a call that
    holds it blocks the main thread's handler as before, and nothing is lost. Outside the main
    thread, or when no Python handler is installed, ``fn`` runs directly. The call must not be
    collective (MPI) and must not touch state the main thread's clean-up uses: an interrupted
    call keeps running, unobserved, until the process exits.

    Returns
    -------
    The value of ``fn``; its exception is re-raised in the caller.
    """
    global _WORKER
    if threading.current_thread() is not threading.main_thread() or not _handled_by_python():
        return fn(*args, **kwargs)
    if _WORKER is None or _WORKER.busy:
        _WORKER = _Worker()
    worker = _WORKER
    box: dict = {}
    done = threading.Event()
    worker.busy = True
    worker.jobs.put((fn, args, kwargs, box, done))
    while not done.wait(_POLL):     # a signal's handler runs here and raises past the worker,
        pass                        # which stays busy: the next call gets a new one
    worker.busy = False
    if "error" in box:
        raise box.pop("error")
    return box["value"]
