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
    slot : (n_contributions,) int32 (int64 beyond 2³¹ entries), position of each contribution in ``data``.
    """

    shape: tuple
    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray

    @classmethod
    def build(cls, rows: np.ndarray, cols: np.ndarray, shape) -> "Pattern":
        rows = np.asarray(rows, np.int64).ravel()
        cols = np.asarray(cols, np.int64).ravel()
        return cls.from_keys(rows * shape[1] + cols, shape)

    @classmethod
    def from_keys(cls, key: np.ndarray, shape) -> "Pattern":
        """The pattern of contributions given as keys row · n_cols + col ((m,) int64).

        The distinct keys come from a sort and the slots from a search, chunk by chunk, into the
        int32 slot list: ``np.unique`` with ``return_inverse`` also holds an argsort and an int64
        inverse per contribution. With the coupled model dropping its (row, col) lists after the
        build, this lowers the set-up peak of large grids (docs/iterative_cornerpoint.md). The
        slots are the same (the inverse of unique).
        """
        key = np.asarray(key, np.int64).ravel()
        ks = np.sort(key)
        distinct = np.empty(ks.size, bool)
        distinct[:1] = True
        np.not_equal(ks[1:], ks[:-1], out=distinct[1:])
        uniq = ks[distinct]
        del ks, distinct
        idx_dtype = np.int32 if max(shape) < 2**31 - 1 and uniq.size < 2**31 - 1 else np.int64
        # int32 positions where they fit: the slot list is the largest array of a pattern
        slot = np.empty(key.size, idx_dtype)
        step = 1 << 22
        for a in range(0, key.size, step):
            slot[a:a + step] = np.searchsorted(uniq, key[a:a + step])
        r = uniq // shape[1]
        indptr = np.zeros(shape[0] + 1, np.int64)
        np.cumsum(np.bincount(r, minlength=shape[0]), out=indptr[1:])
        del r
        return cls(tuple(shape), indptr.astype(idx_dtype), (uniq % shape[1]).astype(idx_dtype), slot)

    @property
    def nnz(self) -> int:
        return self.indices.size

    def fill(self, values: np.ndarray) -> sp.csr_array:
        """csr array with the contributions ``values`` (n_contributions,) summed into place."""
        data = np.bincount(self.slot, weights=np.asarray(values, float).ravel(), minlength=self.nnz)
        return sp.csr_array((data, self.indices, self.indptr), shape=self.shape)


@dataclass(frozen=True, eq=False)
class BlockPattern:
    """A :class:`Pattern` over several blocks of contributions, optionally restricted to the rows
    one process owns (distributed runs: each rank assembles only its rows of a Jacobian).

    Build it from every block's (row, col) lists in the global numbering; ``fill`` then takes each
    block's values already restricted to the kept contributions (:meth:`take` restricts a block's
    full value list). Without a restriction every contribution is kept and the pattern is the one
    :meth:`Pattern.build` gives for the concatenated lists.

    Attributes
    ----------
    pattern : Pattern (n_rows, n_cols) of the kept contributions (local rows, mapped columns)
    keep : tuple, per block the (k_b,) int64 positions of its kept contributions, or None when
        every contribution of the block is kept
    starts : (n_blocks + 1,) int, where each block's kept contributions start in ``pattern.slot``

    Besides :meth:`fill` (every block at once), the data can be built block by block with
    :meth:`add`, in block order: a block whose values do not change (an elasticity matrix) is then
    summed once, not at every Newton iteration, and the sums are those of :meth:`fill` bit for bit
    as long as the blocks are added in their order.
    """

    pattern: Pattern
    keep: tuple
    starts: tuple = ()

    @classmethod
    def build(cls, blocks, shape, row_local: np.ndarray | None = None, col_map: np.ndarray | None = None,
              n_rows: int | None = None) -> "BlockPattern":
        """
        Parameters
        ----------
        blocks : sequence of (rows, cols) integer arrays (any shape; raveled), global numbering
        shape : (n_rows, n_cols) of the global matrix
        row_local : (n_rows,) int, the local row of every global row, −1 for rows not kept; None:
            every row, numbered as given
        col_map : (n_cols,) int, the new number of every column (e.g. the distributed numbering);
            None: unchanged
        n_rows : rows of the restricted pattern (with ``row_local``)
        """
        keys, keep = [], []
        for r, c in blocks:
            r = np.asarray(r, np.int64).ravel()
            c = np.asarray(c, np.int64).ravel()
            if row_local is None:
                k = None
            else:
                lr = row_local[r]
                k = np.flatnonzero(lr >= 0)
                r = lr[k]
                c = c[k]
                if k.size == lr.size:
                    k = None                    # the whole block: no index list to keep
                elif lr.size < 2**31 - 1:
                    k = k.astype(np.int32)
            if col_map is not None:
                c = col_map[c]
            # one int64 key per contribution, block by block: the (row, col) lists of a block go
            # as its keys are made (the largest transient of a model's set-up)
            keys.append(r * shape[1] + c)
            del r, c
            keep.append(k)
        if row_local is None:
            rows_out = shape[0]
        else:
            assert n_rows is not None, "row_local needs n_rows"
            rows_out = int(n_rows)
        starts = tuple(int(v) for v in np.concatenate([[0], np.cumsum([k.size for k in keys], dtype=np.int64)]))
        key = np.concatenate(keys) if keys else np.zeros(0, np.int64)
        del keys
        return cls(Pattern.from_keys(key, (rows_out, shape[1])), tuple(keep), starts)

    def take(self, block: int, values: np.ndarray) -> np.ndarray:
        """The kept entries of one block's full (raveled) value list."""
        v = np.asarray(values, float).ravel()
        k = self.keep[block]
        return v if k is None else v[k]

    def zeros(self) -> np.ndarray:
        """(nnz,) zero data of the pattern, to :meth:`add` blocks into."""
        return np.zeros(self.pattern.nnz)

    def add(self, data: np.ndarray, block: int, values: np.ndarray) -> np.ndarray:
        """Add one block's kept values (k_b,) into ``data`` (nnz,) in place, each contribution in
        its order (``np.add.at``: the running sums of :meth:`fill`'s bincount); returns ``data``."""
        v = np.asarray(values, float).ravel()
        a, b = self.starts[block], self.starts[block + 1]
        if v.size != b - a:
            raise ValueError(f"block {block}: {v.size} values for {b - a} kept contributions")
        np.add.at(data, self.pattern.slot[a:b], v)
        return data

    def put(self, data: np.ndarray, block: int, values: np.ndarray) -> np.ndarray:
        """Like :meth:`add` for a block whose contributions have distinct slots no other block
        has filled yet (e.g. an assembled csr matrix's entries into zeros): a plain scatter, ~10×
        faster than ``np.add.at`` and the same values bit for bit (0 + v = v); returns ``data``."""
        v = np.asarray(values, float).ravel()
        a, b = self.starts[block], self.starts[block + 1]
        if v.size != b - a:
            raise ValueError(f"block {block}: {v.size} values for {b - a} kept contributions")
        data[self.pattern.slot[a:b]] = v
        return data

    def distinct(self, block: int) -> bool:
        """Whether the block's contributions have distinct slots (so that :meth:`put` may fill it)."""
        sl = self.pattern.slot[self.starts[block]:self.starts[block + 1]]
        return bool(np.unique(sl).size == sl.size)

    def matrix(self, data: np.ndarray) -> sp.csr_array:
        """csr array (n_rows, n_cols) on the pattern with the given data (nnz,), not copied."""
        p = self.pattern
        return sp.csr_array((data, p.indices, p.indptr), shape=p.shape)

    def fill(self, values) -> sp.csr_array:
        """csr array (n_rows, n_cols) from every block's kept values (a sequence, block order)."""
        return self.pattern.fill(np.concatenate([np.asarray(v, float).ravel() for v in values]))


def jacobian_pattern(blocks, n: int, layout) -> BlockPattern:
    """The fixed pattern of an (n, n) Newton Jacobian from its blocks of (row, col) contributions:
    every row serially; under mpiexec (``layout`` a DofLayout) this rank's rows, numbered from 0,
    with the columns in the distributed numbering, the rows PETSc takes as they are."""
    if layout is None:
        return BlockPattern.build(blocks, (n, n))
    return BlockPattern.build(blocks, (n, n), row_local=layout.local_index, col_map=layout.inv,
                              n_rows=layout.n_local)
