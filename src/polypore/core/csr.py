"""Where entries (row, col) sit in a CSR matrix's arrays, by a search of its sorted keys."""

from __future__ import annotations

import numpy as np


def csr_keys(M) -> np.ndarray:
    """(nnz,) int64 keys row · n_cols + col of a CSR matrix or array, in storage order (sorted when
    M has sorted indices)."""
    rows = np.repeat(np.arange(M.shape[0], dtype=np.int64), np.diff(M.indptr))
    return rows * M.shape[1] + M.indices


def csr_positions(M, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions of entries (rows, cols) (same shapes) in M.data, and whether M stores them.

    M must have sorted indices. Where ``found`` is False the position is arbitrary (in range).
    """
    keys = csr_keys(M)
    want = np.asarray(rows, np.int64) * M.shape[1] + cols
    pos = np.minimum(np.searchsorted(keys, want), max(keys.size - 1, 0))
    return pos, keys[pos] == want if keys.size else np.zeros(want.shape, bool)
