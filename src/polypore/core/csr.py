"""CSR matrices' arrays: where entries (row, col) sit (a search of sorted keys), entries added as
stored zeros, and blocks of rows as views."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


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


def _row_keys(M, rows: np.ndarray):
    """(unique rows, their entries' storage positions, keys) for the given rows of M, row-major."""
    ur = np.unique(rows)
    ip = np.asarray(M.indptr, np.int64)
    start, count = ip[ur], ip[ur + 1] - ip[ur]
    seg = np.repeat(start - np.r_[0, np.cumsum(count)[:-1]], count) + np.arange(count.sum())
    return ur, seg, np.repeat(ur, count) * M.shape[1] + M.indices[seg]


def csr_positions_in_rows(M, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`csr_positions`, with keys made only for the rows asked about (few rows of a
    large matrix: no nnz-long key array)."""
    rows = np.asarray(rows, np.int64)
    want = rows * M.shape[1] + np.asarray(cols, np.int64)
    _, seg, keys = _row_keys(M, rows)
    if keys.size == 0:
        return np.zeros(want.shape, np.int64), np.zeros(want.shape, bool)
    k = np.minimum(np.searchsorted(keys, want), keys.size - 1)
    return seg[k], keys[k] == want


def with_entries(M, rows: np.ndarray, cols: np.ndarray):
    """M (csr, sorted indices) with explicit zeros stored at the (rows, cols) it does not hold:
    the same values and sorted indices, its index type kept."""
    n = M.shape[1]
    want = np.unique(np.asarray(rows, np.int64) * n + np.asarray(cols, np.int64))
    ur, seg, keys = _row_keys(M, want // n)
    k = np.searchsorted(keys, want)
    found = np.zeros(want.size, bool)
    inside = k < keys.size
    found[inside] = keys[k[inside]] == want[inside]
    new, k = want[~found], k[~found]
    if new.size == 0:
        return M
    r = new // n
    ip = np.asarray(M.indptr, np.int64)
    # the new entry goes before the stored entries of its row with larger columns: at ip[r] plus
    # the number of its row's keys below it (k minus where the row's keys start among the asked rows)
    first = np.searchsorted(keys, r * n)
    at = ip[r] + (k - first)
    data = np.insert(M.data, at, 0.0)
    indices = np.insert(M.indices, at, (new % n).astype(M.indices.dtype))
    indptr = (ip + np.r_[0, np.cumsum(np.bincount(r, minlength=M.shape[0]))]).astype(M.indptr.dtype)
    out = type(M)((data, indices, indptr), shape=M.shape)
    out.has_sorted_indices = True
    return out


def csr_rows(M, a: int, b: int, data=None):
    """Rows a:b of a csr matrix as a csr matrix on views of its index arrays; ``data`` (the
    block's values, e.g. a function of ``M.data[indptr[a]:indptr[b]]``) replaces the viewed values."""
    s, e = int(M.indptr[a]), int(M.indptr[b])
    return sp.csr_matrix((M.data[s:e] if data is None else data, M.indices[s:e], M.indptr[a:b + 1] - s),
                         shape=(b - a, M.shape[1]))


def row_block_data(M, a: int, b: int) -> np.ndarray:
    """The stored values of rows a:b of a csr matrix (a view)."""
    return M.data[int(M.indptr[a]):int(M.indptr[b])]


def kept_indptr(keep: np.ndarray, indptr: np.ndarray, rows: np.ndarray, dtype) -> np.ndarray:
    """CSR row pointer of the entries ``keep`` (nnz,) bool of the given rows, in their order."""
    c = np.zeros(keep.size + 1, np.int64)
    np.cumsum(keep, out=c[1:])
    out = np.zeros(rows.size + 1, dtype)
    np.cumsum(c[indptr[rows + 1]] - c[indptr[rows]], out=out[1:])
    return out


def split_free(L, row_global: np.ndarray, free: np.ndarray, all_rows: bool = False):
    """(ff, rest) of rows of a square matrix: ff the entries in free rows and free columns (columns
    in the free numbering), rest the others (full numbering, every row of L).

    Parameters
    ----------
    L : (r, n) csr, sorted indices, rows of an (n, n) matrix;  row_global : (r,) their numbers
    free : (m,) increasing;  all_rows : ff keeps every row of L (those not free empty), else only
        the free rows, in order (L the whole matrix: ff is its free block)
    """
    it = L.indices.dtype
    index = np.full(L.shape[1], -1, it)
    index[free] = np.arange(free.size, dtype=it)
    row_free = index[row_global] >= 0
    keep = np.repeat(row_free, np.diff(L.indptr)) & (index[L.indices] >= 0)
    ff_rows = np.arange(L.shape[0]) if all_rows else np.flatnonzero(row_free)
    ff = sp.csr_matrix((L.data[keep], index[L.indices[keep]], kept_indptr(keep, L.indptr, ff_rows, it)),
                       shape=(ff_rows.size, free.size))
    drop = ~keep
    del keep
    rest = sp.csr_matrix((L.data[drop], L.indices[drop], kept_indptr(drop, L.indptr, np.arange(L.shape[0]), it)),
                         shape=L.shape)
    return ff, rest


def join_free(ff, rest, free: np.ndarray, ff_rows: np.ndarray) -> sp.coo_matrix:
    """The rows :func:`split_free` split, as coo in the full numbering: ff's entries (its row i
    is row ``ff_rows[i]``, its columns free numbers) and then rest's. Coordinates, not a sum: the
    stored zeros (contact couplings) stay in the pattern."""
    f, r = ff.tocoo(), rest.tocoo()
    return sp.coo_matrix((np.concatenate([f.data, r.data]), (np.concatenate([ff_rows[f.row], r.row]),
                                                            np.concatenate([free[f.col], r.col]))),
                         shape=rest.shape)
