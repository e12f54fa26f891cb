"""Distributed runs under ``mpiexec`` (docs/parallel.md, "Distributed runs"): the dof layouts that
the PETSc solvers use and the row-block operators (the communicator context is
:mod:`polypore.parallel.context`). No physics here.

Design:

* Every rank holds the whole mesh (built on rank 0 and broadcast). The Newton iterate, the residual
  and the active sets are replicated, so every rank takes the same Newton decisions without a
  reduction and the history on N ranks is the 1-rank history up to the linear solves.
* The mesh cells are partitioned with METIS (:func:`polypore.parallel.partition.partition_cells`).
  Every unknown of a linear system gets an owner rank from its cells (a model's ``dof_owner``):
  the lowest rank among the cells of a node, face or edge unknown; a fracture face's multipliers,
  bubbles and pressures the rank of its + side cell.
* A :class:`DofLayout` renumbers the unknowns so that each rank's are one contiguous block in rank
  order (stable: the serial order inside a rank), the layout PETSc's MPIAIJ matrices and
  vectors have. Each rank assembles only its rows of the Jacobian (:class:`OwnedRows`, columns in
  the distributed numbering), which go to PETSc as they are; the solution is gathered on every
  rank after the solve (vectors are small next to matrices).
* The model's operators on the replicated vectors (elasticity, coupling, flow matrices) are
  :class:`RowBlock` s: each rank keeps the rows it owns, and a product is those rows' part
  followed by an Allgatherv. Each entry is computed by one rank exactly as serially (the same row
  in the same order), so residuals, norms and Newton's decisions are the serial ones, bit for bit,
  and do not depend on MPI's reduction order.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..core.csr import join_free, split_free
from .context import context

log = logging.getLogger("polypore")

class DofLayout:
    """A permutation of the unknowns of one linear system that makes each rank's a contiguous block.

    Parameters
    ----------
    owner : (n,) int, owner rank of every unknown (serial numbering)
    comm : mpi4py communicator

    Attributes
    ----------
    perm : (n,) int32 (int64 beyond 2³¹), serial index of every distributed index (new → old)
    inv : (n,) int32 (int64 beyond 2³¹), distributed index of every serial index (old → new)
    counts : (size,) int64, unknowns per rank; start, end : this rank's rows [start, end)
    owned : (end − start,) serial indices of this rank's rows, in distributed order
    """

    def __init__(self, owner: np.ndarray, comm):
        owner = np.asarray(owner, np.int64)
        size, rank = comm.Get_size(), comm.Get_rank()
        if owner.size and (owner.min() < 0 or owner.max() >= size):
            raise ValueError(f"owner ranks must lie in [0, {size}), got [{owner.min()}, {owner.max()}]")
        self.comm = comm
        self.n = owner.size
        # int32 where it fits: a model keeps a layout per system (Newton unknowns, displacement
        # dofs, flow unknowns), replicated on every rank
        it = np.int32 if self.n < 2**31 - 1 else np.int64
        self.perm = np.argsort(owner, kind="stable").astype(it)
        self.inv = np.empty(self.n, it)
        self.inv[self.perm] = np.arange(self.n, dtype=it)
        self.counts = np.bincount(owner, minlength=size).astype(np.int64)
        starts = np.concatenate([[0], np.cumsum(self.counts)])
        self.start, self.end = int(starts[rank]), int(starts[rank + 1])
        self.displs = starts[:-1]
        self.owned = self.perm[self.start:self.end]

    @classmethod
    def contiguous(cls, n: int, comm) -> "DofLayout":
        """No renumbering: PETSc's default split of n rows (for systems without a model layout)."""
        size = comm.Get_size()
        counts = [n // size + (r < n % size) for r in range(size)]
        return cls(np.repeat(np.arange(size), counts), comm)

    @property
    def n_local(self) -> int:
        return self.end - self.start

    def rows(self, A) -> sp.csr_matrix:
        """(n_local, n) this rank's rows of the permuted matrix P A Pᵀ, columns distributed-numbered,
        from the serial (n, n) matrix A."""
        A = sp.csr_matrix(A)
        R = A[self.owned]
        R = sp.csr_matrix((R.data, self.inv[R.indices], R.indptr), shape=(self.n_local, A.shape[1]))
        R.sort_indices()
        return R

    def local(self, b: np.ndarray) -> np.ndarray:
        """This rank's entries of a serial-numbered vector (n,) or (n, k), distributed order."""
        return np.ascontiguousarray(np.asarray(b)[self.owned])

    def gather(self, x_local: np.ndarray) -> np.ndarray:
        """The whole serial-numbered vector from every rank's part (n_local,) or (n_local, k):
        an Allgatherv, so every rank gets it."""
        x_local = np.ascontiguousarray(x_local, float)
        k = 1 if x_local.ndim == 1 else x_local.shape[1]
        MPI = _mpi()
        # rank r's rows are rows displs[r] … of the (n, k) result in row-major order: one message
        buf = np.empty((self.n, k) if x_local.ndim == 2 else self.n, float)
        self.comm.Allgatherv([x_local, MPI.DOUBLE], [buf, (self.counts * k, self.displs * k), MPI.DOUBLE])
        out = np.empty_like(buf)
        out[self.perm] = buf
        return out

    @property
    def local_index(self) -> np.ndarray:
        """(n,) local row (0 … n_local − 1) of every serial unknown this rank owns, −1 for the
        others (the dtype of ``perm``)."""
        li = getattr(self, "_local_index", None)
        if li is None:
            li = np.full(self.n, -1, self.perm.dtype)
            li[self.owned] = np.arange(self.n_local)
            self._local_index = li
        return li

    def field(self, serial: np.ndarray) -> np.ndarray:
        """Sorted distributed indices of the unknowns ``serial`` (serial numbering) that this rank
        owns: the rows of one field (an index set of PCFIELDSPLIT)."""
        g = self.inv[np.asarray(serial, np.int64)]
        return np.sort(g[(g >= self.start) & (g < self.end)])     # type: ignore[operator]  # numpy stubs: generic dtype

    def field_rows(self, serial: np.ndarray) -> np.ndarray:
        """Serial indices of :meth:`field` (same order): to pick this rank's rows of per-unknown
        data, such as near-null vectors, of that field."""
        return self.perm[self.field(serial)]


@dataclass(eq=False)
class OwnedRows:
    """This rank's rows of the matrix of a distributed linear system (Newton's Jacobian on N ranks).

    Attributes
    ----------
    rows : csr (n_local, n), rows ``layout.start`` … ``layout.end − 1`` of P A Pᵀ (P the layout's
        permutation): the rows of the unknowns ``layout.owned``, columns in the distributed numbering;
        None once a solver has taken them (:meth:`take`)
    layout : DofLayout of the system
    """

    rows: sp.csr_matrix | None
    layout: "DofLayout"

    @property
    def shape(self) -> tuple[int, int]:
        return (self.layout.n, self.layout.n)

    def take(self) -> sp.csr_matrix:
        """The rows, handed over: this object lets go of them, so that a solver that has copied
        them into PETSc frees them before its Krylov iterations (Newton holds the Jacobian
        until its solve returns). A second take is an error."""
        if self.rows is None:
            raise ValueError("the rows of this OwnedRows were taken by a solve already")
        rows, self.rows = self.rows, None
        return rows


class RowBlock:
    """A sparse operator (m, k) of which this rank holds the rows it owns; rows and columns keep the
    serial numbering. ``op @ x`` for a replicated x (k,) or (k, j) is the whole replicated product
    (m,) or (m, j): this rank's rows, then an Allgatherv. Every entry is one rank's row sum in the
    serial order of the row, so the product is the serial one bit for bit.

    Parameters
    ----------
    local : csr (n_local, k), the rows ``layout.owned`` of the operator
    layout : DofLayout of the m rows
    """

    def __init__(self, local, layout: "DofLayout"):
        self.local = sp.csr_matrix(local)
        self.layout = layout
        self.shape = (layout.n, self.local.shape[1])

    @classmethod
    def of(cls, A, layout: "DofLayout | None"):
        """The owned rows of the serial matrix A (m, k) as a RowBlock; A itself when ``layout`` is None
        (a serial run)."""
        if layout is None:
            return A
        return cls(sp.csr_matrix(A)[layout.owned], layout)

    def __matmul__(self, x):
        return self.layout.gather(self.local @ np.asarray(x, float))

    def diagonal(self) -> np.ndarray:
        """(m,) the diagonal (m = k), replicated."""
        L = self.local
        own = self.layout.owned
        d = np.zeros(len(own))
        rows = np.repeat(np.arange(L.shape[0]), np.diff(L.indptr))
        hit = L.indices == own[rows]
        np.add.at(d, rows[hit], L.data[hit])
        return self.layout.gather(d)

    def __abs__(self) -> "RowBlock":
        """|op| entry by entry; shares this operator's index arrays (only the values are new)."""
        L = self.local
        return RowBlock(sp.csr_matrix((np.abs(L.data), L.indices, L.indptr), shape=L.shape), self.layout)

    @property
    def nnz(self) -> int:
        return self.local.nnz


class SplitRowBlock(RowBlock):
    """A RowBlock of a square matrix whose product follows the serial
    :class:`~.block_jacobian.FreeSplit`'s order: each owned row sums its entries in free columns
    (free rows only) and adds the sum of the others, so that distributed residuals stay the serial
    ones bit for bit. ``local`` is assembled when asked for (set-up only).

    Parameters
    ----------
    A : (n, n) csr, sorted indices, the serial matrix;  layout : DofLayout;  free : (m,) increasing
    """

    def __init__(self, A, layout: "DofLayout", free: np.ndarray):
        L = sp.csr_matrix(A)[layout.owned]
        L.sort_indices()
        self.layout, self.shape = layout, (layout.n, L.shape[1])
        self.free = np.asarray(free)
        self._ff, self._rest = split_free(L, layout.owned, self.free, all_rows=True)

    @property
    def local(self) -> sp.csr_matrix:
        L = join_free(self._ff, self._rest, self.free, np.arange(self._rest.shape[0])).tocsr()
        L.sort_indices()
        return L

    @property
    def nnz(self) -> int:
        return self._ff.nnz + self._rest.nnz

    def __matmul__(self, x):
        x = np.asarray(x, float)
        y = self._rest @ x
        y += self._ff @ x[self.free]
        return self.layout.gather(y)


def local_rows(A):
    """The rows this rank holds of an operator: ``A.local`` of a :class:`RowBlock`, else A (serial)."""
    return A.local if isinstance(A, RowBlock) else A


def _mpi():
    from mpi4py import MPI

    return MPI


def min_owner(n: int, index: np.ndarray, rank: np.ndarray, fill: int = 0) -> np.ndarray:
    """(n,) the lowest ``rank`` over the entries of each index (``fill`` where none).

    Parameters
    ----------
    index : (m,) int, unknown of every (cell, unknown) incidence
    rank : (m,) int, rank of that cell
    """
    out = np.full(n, np.iinfo(np.int64).max, np.int64)
    np.minimum.at(out, np.asarray(index, np.int64), np.asarray(rank, np.int64))
    out[out == np.iinfo(np.int64).max] = fill
    return out


def register_layout(solver, layout: DofLayout) -> None:
    """Give ``solver`` the layout of its systems of size ``layout.n`` (a solver may serve several
    systems, e.g. the mechanics and the coupled ones; any layout is correct, the model's keeps the
    mesh partition)."""
    if solver is None:
        return
    layouts = getattr(solver, "layouts", None)
    if layouts is None:
        try:
            solver.layouts = layouts = {}
        except AttributeError:
            return
    layouts[layout.n] = layout


def owned_layout(mesh, owner_of) -> DofLayout | None:
    """Under mpiexec: the layout of unknowns whose owner ranks are ``owner_of(part)`` (n,), from the
    cell ranks ``part`` (n_cells,) of ``mesh``'s partition; None when serial."""
    from .ownership import cell_ownership

    ctx = context()
    if ctx is None:
        return None
    return DofLayout(owner_of(cell_ownership(mesh).owner), ctx.comm)


def distribute(solver, mesh, owner_of) -> DofLayout | None:
    """Under mpiexec: the layout of a model's unknowns (:func:`owned_layout`), registered on
    ``solver``; None when serial."""
    layout = owned_layout(mesh, owner_of)
    if layout is not None:
        register_layout(solver, layout)
    return layout


def layout_for(solver, n: int) -> DofLayout | None:
    """The layout registered on ``solver`` for size n; in a distributed run without one, PETSc's
    contiguous split (correct, but not aligned with the mesh partition); None when serial."""
    ctx = context()
    if ctx is None:
        return None
    layouts = getattr(solver, "layouts", None)
    if layouts is None:
        layouts = {}
        try:
            solver.layouts = layouts
        except AttributeError:
            pass
    lay = layouts.get(n)
    if lay is None:
        lay = layouts[n] = DofLayout.contiguous(n, ctx.comm)
    return lay
