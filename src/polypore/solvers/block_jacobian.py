"""A Newton Jacobian held by its blocks, for the block solvers (no assembled copy).

The coupled Jacobian (docs/choices.md, block solvers) is

    [ A    Bt   Gup ]      u: free displacement dofs
    [ Cu   Cl   0   ]      l: scaled multipliers (d per contact patch)
    [ Gpu  0    F   ]      p: free pressure unknowns (absent in contact mechanics)

Assembled into one CSR matrix it repeats A, the largest block, and GMRES, the condensation and
the fixed-stress pressure operator only ever use the blocks. Held by blocks, A is the model's own
elastic matrix's free block (`FreeSplit`: the elastic matrix is stored that way), and the assembled pattern of the
whole Jacobian (its slot list and indices, int32 each per entry), its fixed part and its data
(float64 each per entry) are never made (a fifth of a Newton iteration's memory on large grids,
docs/iterative_cornerpoint.md, sixth session).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..core.csr import csr_rows, join_free, row_block_data, split_free

_ABS_CHUNK = 2_000_000          # nonzeros per chunk of |M| |x| (no copy of M's values)


def abs_matvec(M, ax: np.ndarray) -> np.ndarray:
    """|M| ax for a csr M (ax ≥ 0), chunk by chunk of rows: no nnz-sized copy of |M.data|."""
    if hasattr(M, "abs_matvec"):
        return M.abs_matvec(ax)
    M = sp.csr_matrix(M)
    out = np.empty(M.shape[0])
    ip = M.indptr
    edges = np.searchsorted(ip, np.arange(0, ip[-1] + _ABS_CHUNK, _ABS_CHUNK), side="right") - 1
    edges = np.unique(np.r_[0, np.clip(edges, 0, M.shape[0]), M.shape[0]])
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        out[a:b] = csr_rows(M, a, b, np.abs(row_block_data(M, a, b))) @ ax
    return out


def block_diag_csr(blocks: np.ndarray) -> sp.csr_matrix:
    """(n d, n d) csr of the dense diagonal blocks (n, d, d) (every entry stored, zeros too)."""
    n, d, _ = blocks.shape
    indptr = np.arange(n * d + 1, dtype=np.int64) * d
    indices = (np.arange(n)[:, None, None] * d + np.arange(d)[None, None, :] + 0 * np.arange(d)[None, :, None])
    return sp.csr_matrix((np.asarray(blocks, float).ravel(), indices.ravel(), indptr), shape=(n * d, n * d))


class FreeSplit:
    """A square csr matrix A (n, n) stored as its free–free block and the rest.

    ``ff`` is A[free][:, free] (csr, in the free numbering: the block solvers' A, and the base the
    condensed S shares its indices with); ``rest`` holds A's entries in a fixed row or column (csr,
    full numbering: the Dirichlet couplings and the reactions). ``A @ u`` and ``diagonal()`` are
    A's; held this way the elastic matrix needs no separate restricted copy or index map for the
    block solvers (docs/iterative_cornerpoint.md, "Measurements cited by the code").

    Parameters
    ----------
    A : (n, n) csr, sorted indices;  free : (m,) int, increasing
    """

    def __init__(self, A, free: np.ndarray):
        A = sp.csr_matrix(A)
        A.sort_indices()
        self.free = np.asarray(free)
        self.shape, self.dtype = A.shape, A.dtype
        self.ff, self.rest = split_free(A, np.arange(A.shape[0]), self.free)
        # the condensed S shares these index arrays: read-only, so that an in-place change of S's
        # structure (eliminate_zeros, an unsorted sort) raises instead of corrupting A
        self.ff.indices.flags.writeable = self.ff.indptr.flags.writeable = False

    @property
    def nnz(self) -> int:
        return self.ff.nnz + self.rest.nnz

    def __matmul__(self, x):
        x = np.asarray(x, float)
        y = self.rest @ x
        y[self.free] += self.ff @ x[self.free]
        return y

    def diagonal(self) -> np.ndarray:
        d = self.rest.diagonal()
        d[self.free] = self.ff.diagonal()
        return d

    def tocoo(self) -> sp.coo_matrix:
        """A (n, n) as coo (free–free entries first)."""
        return join_free(self.ff, self.rest, self.free, self.free)

    def tocsr(self) -> sp.csr_matrix:
        return self.tocoo().tocsr()

    def tocsc(self) -> sp.csc_matrix:
        return self.tocoo().tocsc()


class BorrowedValues:
    """A csr matrix A whose value array another matrix borrows, and A itself as an operator.

    The condensed S = A − ½(P + Pᵀ) differs from the elastic block A only on the contact
    couplings, and A is stored with those entries (zeros where A has none), so S can be A's own
    arrays with ``values`` written at ``pos`` (:meth:`.block_contact.ContactCondensation.condense`
    with ``borrow``): a second value array of A's size is not needed
    (docs/iterative_cornerpoint.md, seventh session). While borrowed, this object is A for the Krylov solve: ``@``,
    :meth:`diagonal` and :meth:`abs_matvec` add E = A − S, held on ``pos`` only; :meth:`restore`
    writes A's saved values back (exactly: assigned, not re-added).

    Parameters
    ----------
    A : (n, n) csr, sorted indices (its ``data`` is changed until :meth:`restore`)
    pos : (k,) distinct positions in A.data;  values : (k,) S's values there
    """

    def __init__(self, A: sp.csr_matrix, pos: np.ndarray, values: np.ndarray):
        self.A, self.pos = A, np.asarray(pos)
        self.shape, self.dtype = A.shape, A.dtype
        self.saved = A.data[self.pos].copy()
        rows = np.searchsorted(A.indptr, self.pos, side="right") - 1
        cols = A.indices[self.pos]
        self._diag = rows[rows == cols], self.saved[rows == cols]
        A.data[self.pos] = values
        self.E = sp.csr_matrix((self.saved - values, (rows, cols)), shape=A.shape)
        self._absE = sp.csr_matrix((np.abs(self.saved) - np.abs(values), (rows, cols)), shape=A.shape)

    def __matmul__(self, x):
        return self.A @ x + self.E @ x

    def diagonal(self) -> np.ndarray:
        d = self.A.diagonal()
        d[self._diag[0]] = self._diag[1]
        return d

    def abs_matvec(self, ax: np.ndarray) -> np.ndarray:
        """|A| ax (ax ≥ 0)."""
        return abs_matvec(self.A, ax) + self._absE @ ax

    def restore(self) -> None:
        """A's own values back (idempotent)."""
        self.A.data[self.pos] = self.saved


class Unchanged:
    """A matrix lent unchanged (no contact rows): :class:`BorrowedValues`' interface, nothing to
    restore."""

    def __init__(self, A):
        self.A, self.shape, self.dtype = A, A.shape, A.dtype

    def __matmul__(self, x):
        return self.A @ x

    def diagonal(self) -> np.ndarray:
        return self.A.diagonal()

    def abs_matvec(self, ax: np.ndarray) -> np.ndarray:
        return abs_matvec(self.A, ax)

    def restore(self) -> None:
        pass


@dataclass
class BlockJacobian:
    """The Newton Jacobian [[A, Bt, Gup], [Cu, Cl, 0], [Gpu, 0, F]] by blocks (module docstring).

    Blocks are csr matrices (``uu`` the ``ff`` of a :class:`FreeSplit`); the pressure blocks are None in
    contact mechanics. Supports ``J @ x`` (x (n,)), :meth:`abs_matvec` and :meth:`tocsr`.
    """

    uu: object
    ul: object
    lu: object
    ll: object
    up: object = None
    pu: object = None
    pp: object = None

    def __post_init__(self):
        self.n_u, self.n_l = self.uu.shape[0], self.ll.shape[0]
        self.n_p = 0 if self.pp is None else self.pp.shape[0]
        n = self.n_u + self.n_l + self.n_p
        self.shape = (n, n)
        self.dtype = np.dtype(float)
        self.ndim = 2

    @classmethod
    def from_csr(cls, J, n_u: int, n_l: int) -> "BlockJacobian":
        """The blocks of an assembled Jacobian (copies of its slices)."""
        J = sp.csr_matrix(J)
        po = n_u + n_l
        if po == J.shape[0]:
            return cls(J[:n_u, :n_u], J[:n_u, n_u:], J[n_u:, :n_u], J[n_u:, n_u:])
        return cls(J[:n_u, :n_u], J[:n_u, n_u:po], J[n_u:po, :n_u], J[n_u:po, n_u:po],
                   J[:n_u, po:], J[po:, :n_u], J[po:, po:])

    def _split(self, x):
        nu, po = self.n_u, self.n_u + self.n_l
        return x[:nu], x[nu:po], x[po:]

    def _apply(self, x, f):
        xu, xl, xp = self._split(np.asarray(x, float).ravel())
        yu = f(self.uu, xu) + f(self.ul, xl)
        yl = f(self.lu, xu) + f(self.ll, xl)
        if self.pp is None:
            return np.concatenate([yu, yl])
        yu += f(self.up, xp)
        yp = f(self.pu, xu) + f(self.pp, xp)
        return np.concatenate([yu, yl, yp])

    def __matmul__(self, x):
        return self._apply(x, lambda M, v: M @ v)

    def dot(self, x):
        return self @ x

    matvec = dot

    def abs_matvec(self, ax: np.ndarray) -> np.ndarray:
        """|J| ax (ax ≥ 0), block by block."""
        return self._apply(ax, abs_matvec)

    def tocsr(self) -> sp.csr_matrix:
        """The assembled Jacobian (tests, dumps, direct fall-backs)."""
        rows = [[self.uu, self.ul], [self.lu, self.ll]]
        if self.pp is not None:
            rows[0].append(self.up)
            rows[1].append(None)
            rows.append([self.pu, None, self.pp])
        return sp.csr_matrix(sp.bmat(rows, format="csr"))
