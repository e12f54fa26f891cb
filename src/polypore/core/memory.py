"""Giving freed heap memory back to the operating system (glibc's ``malloc_trim``), and compact
index arrays for the large sparse matrices a model keeps.

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

import numpy as np

_TRIM = None
M_MMAP_THRESHOLD = -3          # mallopt parameter (malloc.h)
# Blocks above this size are mapped on their own and unmapped when freed. glibc's default starts
# at 128 kB but raises itself up to 32 MB after the first large frees, after which the Newton
# loop's 10-100 MB temporaries (Jacobian copies, the condensed block, AMG set-ups) came from the
# heap and fragmented it: on the 30,000-cell corner-point study (block-amg) the resident memory
# of one step grew from 1.26 to 2.08 GB while the live arrays stayed at 0.5-0.7 GB. Fixed at
# 1 MiB the run peaked at 1.40 GB but the page faults of fresh mappings cost emerald-injection
# 21 % in wall time (31.6 against 26.1 s); 8 MiB keeps both: 1.48 GB, and 27.1 s.
MMAP_THRESHOLD = 8 << 20


def trim_heap() -> bool:
    """Return the free pages of the C heap to the kernel (``malloc_trim(0)``; a few ms). Does
    nothing, and returns False, where the C library has no ``malloc_trim`` (not glibc). The
    first call also fixes glibc's mmap threshold (``MMAP_THRESHOLD``) for the process."""
    global _TRIM
    if _TRIM is None:
        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            _TRIM = libc.malloc_trim
            _TRIM.argtypes = [ctypes.c_size_t]
            libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
            libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
        except (OSError, AttributeError):
            _TRIM = False
    if not _TRIM:
        return False
    _TRIM(0)
    return True


INT32_MAX = np.iinfo(np.int32).max


def int32_indices(M):
    """``M`` (a csr/csc matrix or array) with int32 ``indices`` and ``indptr`` where they fit, in place.

    SciPy keeps int64 indices when a matrix is built from int64 coordinates, as assembly does to
    avoid overflow in ``row * d + i``: on the 10⁵-cell weak-scaling grid the elastic matrix held
    411 MB of which 137 MB were the upper halves of its column indices. Returns ``M``.
    """
    if M.nnz <= INT32_MAX and max(M.shape) <= INT32_MAX:
        M.indices = M.indices.astype(np.int32, copy=False)
        M.indptr = M.indptr.astype(np.int32, copy=False)
    return M
