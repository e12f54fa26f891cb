"""Small measures every run driver reports: peak memory and the unknowns of a contact problem."""

from __future__ import annotations

import resource


def peak_memory_mb() -> float:
    """Peak resident memory of this process (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def unknowns(problem) -> int:
    """Unknowns of a contact-mechanics problem: free displacement unknowns and the multipliers."""
    return int(problem.free.size + problem.n_ff * problem.dim)
