"""Sparsity patterns built once and refilled with new values (no re-sorting per Newton step)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True, eq=False)
class Pattern:
    """A CSR structure and the map from a fixed list of (row, col) contributions to it.

    Build once from the coordinate lists of every contribution (duplicates allowed); then
    :meth:`fill` turns a value per contribution into a csr array by a single bincount.

    Attributes
    ----------
    shape : (n_rows, n_cols)
    indptr, indices : CSR structure (int32/int64)
    slot : (n_contributions,) int64, position of each contribution in ``data``.
    """

    shape: tuple
    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray

    @classmethod
    def build(cls, rows: np.ndarray, cols: np.ndarray, shape) -> "Pattern":
        rows = np.asarray(rows, np.int64).ravel()
        cols = np.asarray(cols, np.int64).ravel()
        key = rows * shape[1] + cols
        uniq, slot = np.unique(key, return_inverse=True)
        r = uniq // shape[1]
        indptr = np.zeros(shape[0] + 1, np.int64)
        np.cumsum(np.bincount(r, minlength=shape[0]), out=indptr[1:])
        idx_dtype = np.int32 if max(shape) < 2**31 - 1 and uniq.size < 2**31 - 1 else np.int64
        return cls(tuple(shape), indptr.astype(idx_dtype), (uniq % shape[1]).astype(idx_dtype), slot.ravel())

    @property
    def nnz(self) -> int:
        return self.indices.size

    def fill(self, values: np.ndarray) -> sp.csr_array:
        """csr array with the contributions ``values`` (n_contributions,) summed into place."""
        data = np.bincount(self.slot, weights=np.asarray(values, float).ravel(), minlength=self.nnz)
        return sp.csr_array((data, self.indices, self.indptr), shape=self.shape)
