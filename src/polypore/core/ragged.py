"""Ragged (CSR-like) integer arrays: ``values[offsets[i]:offsets[i+1]]`` is row i."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

INDEX = np.int32  # connectivity dtype throughout


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Ragged:
    """Immutable ragged array of int32 rows.

    Attributes
    ----------
    offsets : (n + 1,) int32
        Row starts; ``offsets[0] == 0`` and ``offsets[-1] == len(values)``.
    values : (nnz,) int32
        Concatenated rows.
    """

    offsets: np.ndarray
    values: np.ndarray

    def __post_init__(self):
        off = np.ascontiguousarray(self.offsets, dtype=INDEX)
        val = np.ascontiguousarray(self.values, dtype=INDEX)
        if off.ndim != 1 or off.size == 0 or off[0] != 0 or off[-1] != val.size:
            raise ValueError("Ragged: offsets must start at 0 and end at len(values)")
        if np.any(np.diff(off) < 0):
            raise ValueError("Ragged: offsets must be non-decreasing")
        object.__setattr__(self, "offsets", _frozen(off))
        object.__setattr__(self, "values", _frozen(val))

    @classmethod
    def from_counts(cls, counts: np.ndarray, values: np.ndarray) -> "Ragged":
        off = np.zeros(len(counts) + 1, dtype=np.int64)
        np.cumsum(counts, out=off[1:])
        return cls(off, values)

    @classmethod
    def from_rows(cls, rows) -> "Ragged":
        """Build from a Python sequence of rows (small inputs and tests only)."""
        counts = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
        vals = np.concatenate([np.asarray(r, dtype=INDEX) for r in rows]) if len(rows) else np.zeros(0, INDEX)
        return cls.from_counts(counts, vals)

    @classmethod
    def from_dense(cls, a: np.ndarray) -> "Ragged":
        a = np.asarray(a)
        n, m = a.shape
        return cls(np.arange(0, n * m + 1, m, dtype=np.int64), a.ravel())

    def __len__(self) -> int:
        return self.offsets.size - 1

    @property
    def nnz(self) -> int:
        return int(self.values.size)

    @property
    def counts(self) -> np.ndarray:
        """(n,) int32 row lengths."""
        return np.diff(self.offsets)

    def row(self, i: int) -> np.ndarray:
        return self.values[self.offsets[i]:self.offsets[i + 1]]

    def rows_of_entries(self) -> np.ndarray:
        """(nnz,) int32: the row index of every entry."""
        return np.repeat(np.arange(len(self), dtype=INDEX), self.counts)

    def local_index(self) -> np.ndarray:
        """(nnz,) int32: the position of every entry inside its row."""
        return (np.arange(self.nnz, dtype=INDEX) - np.repeat(self.offsets[:-1], self.counts)).astype(INDEX)

    def groups(self):
        """Yield ``(length, rows, block)`` for each distinct row length.

        ``rows`` (k,) are row indices and ``block`` (k, length) their values, so that
        kernels can run batched over rows of one shape.
        """
        counts = self.counts
        for m in np.unique(counts):
            rows = np.flatnonzero(counts == m).astype(INDEX)
            idx = self.offsets[rows][:, None] + np.arange(m, dtype=INDEX)[None, :]
            yield int(m), rows, self.values[idx]

    def positions(self, rows: np.ndarray, m: int) -> np.ndarray:
        """(k, m) indices into ``values`` of rows that all have length m."""
        return self.offsets[rows][:, None] + np.arange(m, dtype=INDEX)[None, :]

    def take(self, rows: np.ndarray) -> "Ragged":
        """The sub-ragged array of the given rows, in that order."""
        rows = np.asarray(rows, dtype=np.int64)
        counts = self.counts[rows]
        starts = self.offsets[rows]
        idx = np.repeat(starts - np.concatenate(([0], np.cumsum(counts)[:-1])), counts) + np.arange(counts.sum())
        return Ragged.from_counts(counts, self.values[idx])

    def nbytes(self) -> int:
        return self.offsets.nbytes + self.values.nbytes


def frozen(a: np.ndarray) -> np.ndarray:
    """Return ``a`` made read-only (in place) — mesh arrays are immutable."""
    return _frozen(np.ascontiguousarray(a))
