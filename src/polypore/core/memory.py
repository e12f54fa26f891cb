"""Giving freed heap memory back to the operating system (glibc's ``malloc_trim``).

The set-up of a model, a mesh generation and each Newton iteration allocate and free many
temporaries. glibc keeps the freed pages of its heap for later allocations instead of returning
them, and fragmentation leaves much of it unusable for the large blocks that follow: on C5 at 23k
cells the poromechanics set-up left 240 MB resident of which 150 MB were free heap pages
(``malloc_trim`` brought it to 90 MB), and the peak resident memory of a 2-rank run, what limits
the mesh size per node (docs/parallel.md), was 10 % higher than with the pages returned.
"""

from __future__ import annotations

import ctypes
import ctypes.util

_TRIM = None


def trim_heap() -> bool:
    """Return the free pages of the C heap to the kernel (``malloc_trim(0)``; a few ms). Does
    nothing, and returns False, where the C library has no ``malloc_trim`` (not glibc)."""
    global _TRIM
    if _TRIM is None:
        try:
            _TRIM = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
            _TRIM.argtypes = [ctypes.c_size_t]
        except (OSError, AttributeError):
            _TRIM = False
    if not _TRIM:
        return False
    _TRIM(0)
    return True
