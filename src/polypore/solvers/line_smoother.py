"""Line (block) Gauss–Seidel smoothing around an AMG V-cycle for the mechanics block.

On flat cells (thin in z) the strongest couplings of the displacement block run along the short
vertical edges; point smoothers inside smoothed aggregation then leave those directions poorly
smoothed.  `LineSmoothedAMG` wraps any AMG preconditioner with a symmetric multicolour block
Gauss–Seidel over *lines* of nodes.  The lines are found algebraically from S and its rigid-body
near-null space only (no mesh or coordinates are passed in):

1. dofs → nodes from the near-null-space rows (translation columns give the component, rotation
   columns two coordinates; dofs are node-major with ascending components, Dirichlet components
   removed); rows of B that are zero (cell bubbles) are nodes of their own;
2. node coupling w_IJ = ‖S_IJ‖_F / sqrt(‖S_II‖_F ‖S_JJ‖_F);
3. lines = connected components of the graph of *mutual* top-2 couplings among point nodes
   (degree ≤ 2, so paths or cycles); bubbles join their strongest point neighbour's line;
4. lines coloured (Jones–Plassmann, random priorities, smallest free colour) so that lines of one
   colour are not coupled in S; each colour's block-diagonal part is factorised once, as a band
   (`LineBlocks`).
"""
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import lapack
from scipy.sparse.csgraph import connected_components, reverse_cuthill_mckee
from threadpoolctl import threadpool_limits

from ..core.csr import csr_rows, row_block_data

# Widest band (super-diagonals) factorised as a band; wider blocks go to SuperLU.
MAX_BAND = 128
# Rows of S per block when node couplings are summed (bounds the temporaries)
ROW_BLOCK = 25_000


def dof_nodes(B, tol=1e-8):
    """Node id per dof, from the near-null space B (n, 6) of a 3-D displacement field.

    Rotation columns: 3 = (−y, x, 0), 4 = (0, −z, y), 5 = (z, 0, −x).  A dof starts a new node
    when its component does not exceed the previous dof's (node-major ordering) or when a
    coordinate both dofs know differs; zero rows (bubbles) are single-dof nodes.
    """
    n = B.shape[0]
    zero = ~B.any(1)
    comp = np.argmax(B[:, :3], 1)
    X = np.full((n, 3), np.nan)
    r = B[:, 3:]
    for c, (a, ka, sa), (b, kb, sb) in ((0, (1, 0, -1), (2, 2, 1)), (1, (0, 0, 1), (2, 1, -1)),
                                       (2, (1, 1, 1), (0, 2, -1))):
        i = comp == c                   # component c knows coordinates a and b
        X[i, a] = sa * r[i, ka]
        X[i, b] = sb * r[i, kb]
    scale = max(np.nanmax(np.abs(X[~zero])), 1.0) if (~zero).any() else 1.0
    both = ~np.isnan(X[1:]) & ~np.isnan(X[:-1])
    moved = (np.where(both, np.abs(X[1:] - X[:-1]), 0.0) > tol * scale).any(1)
    new = (comp[1:] <= comp[:-1]) | moved | zero[1:] | zero[:-1]
    return np.r_[0, np.cumsum(new)]


def _top2_mutual(W):
    """Symmetric 0/1 matrix of edges I–J with J among I's two largest off-diagonal w and vice versa."""
    W = sp.coo_matrix(W)
    off = W.row != W.col
    i, j, w = W.row[off], W.col[off], W.data[off]
    o = np.lexsort((-w, i))              # by row, strongest first
    i, j = i[o], j[o]
    start = np.searchsorted(i, i)        # first position of each row
    keep = np.arange(len(i)) - start < 2
    nn = W.shape[0]
    T = sp.csr_matrix((np.ones(keep.sum()), (i[keep], j[keep])), shape=(nn, nn))
    return T.multiply(T.T).tocsr()


def color_graph(G, seed=0):
    """Colour per vertex of the symmetric pattern G (no two neighbours equal).

    Jones–Plassmann: each round colours the uncoloured vertices whose random priority beats all
    uncoloured neighbours, each with the smallest colour absent among its coloured neighbours.
    """
    G = sp.csr_matrix(G, dtype=float)
    G.setdiag(0)
    G.eliminate_zeros()
    G.data[:] = 1.0
    n = G.shape[0]
    prio = np.random.default_rng(seed).permutation(n) + 1.0
    color = -np.ones(n, int)
    rows = np.repeat(np.arange(n), np.diff(G.indptr))
    while (color < 0).any():
        unc = color < 0
        # highest uncoloured-neighbour priority per vertex
        pn = np.where(unc[G.indices], prio[G.indices], 0.0)
        best = np.zeros(n)
        np.maximum.at(best, rows, pn)
        cand = np.nonzero(unc & (prio > best))[0]
        K = max(color.max() + 2, 1)
        done = ~unc
        used = sp.csr_matrix((np.ones(done.sum()), (np.nonzero(done)[0], color[done])), shape=(n, K))
        used = (G[cand] @ used).toarray() > 0          # colours taken by coloured neighbours
        used[:, -1] = False                            # a fresh colour is always free
        color[cand] = np.argmin(used, 1)
    return color


def find_lines(S, B, attach_bubbles=True):
    """(node per dof (n,), line per node (n_nodes,), node coupling pattern ‖S_IJ‖_F (csr)).

    Bubble nodes (zero rows of B) are kept out of the mutual top-2 search: they couple to every
    node of their cell and otherwise take line slots of point nodes (on em2: 3608 lines and 32
    colours instead of 2771 and 16, same PCG count).  With attach_bubbles they then join the
    line of their strongest point neighbour.
    """
    n = S.shape[0]
    node = dof_nodes(B)
    nn = node[-1] + 1
    bub = np.zeros(nn, bool)
    bub[node[~B.any(1)]] = True
    P = sp.csr_matrix((np.ones(n), (np.arange(n), node)), shape=(n, nn))
    # ‖S_IJ‖_F² for all node pairs, summed over blocks of rows of S (S∘S of all rows at once was
    # the set-up's memory peak, docs/iterative_cornerpoint.md); the normalisation makes w scale-free per node
    S = sp.csr_matrix(S)
    F = None
    for a in range(0, n, ROW_BLOCK):
        b = min(a + ROW_BLOCK, n)
        Sr = csr_rows(S, a, b, row_block_data(S, a, b) ** 2)
        term = (P[a:b].T @ Sr @ P).tocsr()
        F = term if F is None else F + term
        del Sr, term
    F = sp.csr_matrix(F)
    F.data = np.sqrt(F.data)
    d = np.sqrt(F.diagonal())
    Fc = F.tocoo()
    w = Fc.data / (d[Fc.row] * d[Fc.col])
    pt = ~bub[Fc.row] & ~bub[Fc.col]
    W = sp.coo_matrix((w[pt], (Fc.row[pt], Fc.col[pt])), shape=F.shape)
    _, line = connected_components(_top2_mutual(W), directed=False)
    if attach_bubbles and bub.any() and (~bub).any():
        # strongest point neighbour of each bubble node (rows sorted by w, last one wins)
        e = bub[Fc.row] & ~bub[Fc.col]
        r, c, we = Fc.row[e], Fc.col[e], w[e]
        o = np.lexsort((we, r))
        best = np.full(nn, -1)
        best[r[o]] = c[o]
        has = bub & (best >= 0)
        line[has] = line[best[has]]
        _, line = np.unique(line, return_inverse=True)
    return node, line, F


class LineBlocks:
    """Factors of one colour's within-line block D (symmetric), solved in a band ordering.

    Lines are paths of nodes (with their cells' bubbles), so reverse Cuthill–McKee puts D in a band
    of 10–50 super-diagonals and LAPACK's banded Cholesky (``dpbtrf``) factorises it in
    n·(band + 1) numbers. SuperLU allocates far more than the factors take (its first guess is 20 × nnz), which glibc's
    heap recycles into resident memory Newton iteration after Newton iteration
    (docs/iterative_cornerpoint.md, fifth session). A block whose band is wider than
    ``MAX_BAND`` or that is not positive definite is factorised by SuperLU.

    Parameters
    ----------
    idx : (m,) int, the colour's dofs;  D : (m, m) csr, their within-line block
    ordered : D is already in a band ordering (no RCM: ``order`` is ``idx``)

    Attributes
    ----------
    order : (m,) int, the colour's dofs (indices into S) in band order
    """

    def __init__(self, idx: np.ndarray, D: sp.csr_matrix, ordered: bool = False):
        p = np.arange(D.shape[0]) if ordered else reverse_cuthill_mckee(sp.csr_matrix(D), symmetric_mode=True)
        Dp = sp.coo_matrix(D if ordered else D[p][:, p])
        band = int(np.abs(Dp.row - Dp.col).max(initial=0))
        self.order = idx[p]
        self._chol: np.ndarray | None = None
        self._lu: Any = None           # SuperLU
        if band <= MAX_BAND:
            up = Dp.row <= Dp.col
            ab = np.zeros((band + 1, D.shape[0]))
            ab[band + Dp.row[up] - Dp.col[up], Dp.col[up]] = Dp.data[up]
            # one BLAS thread: the banded Cholesky's blocks are small, and OpenBLAS's threads
            # spin against each other when the machine is busy (several times slower beside one other
            # process, docs/iterative_cornerpoint.md, seventh session)
            with threadpool_limits(1, user_api="blas"):
                c, info = lapack.dpbtrf(ab, overwrite_ab=1)
            if info == 0:
                self._chol = c
                return
        self._lu = spla.splu(sp.csc_matrix(Dp))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """D⁻¹ b for b (m,) in ``order``."""
        if self._chol is not None:
            x, info = lapack.dpbtrs(self._chol, b)
            return x
        return self._lu.solve(b)


class LineSmoothedAMG:
    """Symmetric line-block-Gauss–Seidel / AMG composite preconditioner for an SPD block S.

    One application ``M @ r``: forward multicolour line block-GS sweep from x = 0, one AMG cycle on
    the residual, backward sweep (colours reversed), so M is symmetric when S and the AMG are.
    Each colour keeps a copy of its rows of S (in its band order) for its residual.

    The AMG works on S in its own numbering. Renumbered colour by colour (so that a colour's rows
    would be a slice of it, no copies), its level-0 Gauss–Seidel sweeps in that order, which costs
    coupled GMRES iterations on Emerald and gains nothing elsewhere (docs/iterative_cornerpoint.md,
    sixth session). Lines, colours and band orders are kept by
    :meth:`refit`, which
    takes a new S of the same pattern (between Newton iterations only contact rows change).

    Parameters
    ----------
    S : (n, n) sparse, symmetric positive definite (the condensed mechanics block)
    near_nullspace : (n, 6) rigid-body modes (cols 0..2 translations, 3..5 rotations); zero rows
        allowed (bubble dofs)
    amg_factory : callable ``(S, B) -> op`` with ``op @ r`` one AMG cycle, e.g.
        ``polypore.solvers.block_contact._amg``

    Attributes
    ----------
    node : (n,) node id per dof;  line : (n_nodes,) line id per node;  colors : (n_lines,)
    n_lines, n_colors : ints;  line_length : (n_lines,) nodes per line
    """

    def __init__(self, S, near_nullspace, amg_factory, seed=0, attach_bubbles=True):
        S = sp.csr_matrix(S)
        B = np.asarray(near_nullspace)
        self.shape, self.dtype = S.shape, S.dtype
        self.node, self.line, F = find_lines(S, B, attach_bubbles)
        node, nn = self.node, self.node[-1] + 1
        self.n_lines = int(self.line.max()) + 1
        self.line_length = np.bincount(self.line, minlength=self.n_lines)
        # lines of one colour must not be coupled: colour the line graph of S's pattern
        R = sp.csr_matrix((np.ones(nn), (np.arange(nn), self.line)), shape=(nn, self.n_lines))
        Gl = R.T @ (F != 0).astype(float) @ R
        del F, R
        self.colors = color_graph(Gl, seed)
        self.n_colors = int(self.colors.max()) + 1
        self._dline = self.line[node]
        dcol = self.colors[self._dline]
        self._orders = [np.nonzero(dcol == k)[0] for k in range(self.n_colors)]
        self._fit(S, ordered=False)
        self.amg = amg_factory(S, B)

    def _fit(self, S, ordered=True):
        """The colours' row copies and line factors for the values of S (band orders found on the
        first call, kept after)."""
        self.S = self.sets = None
        sets = []
        for k, idx in enumerate(self._orders):
            Sk = S[idx][:, idx].tocoo()
            same = self._dline[idx[Sk.row]] == self._dline[idx[Sk.col]]   # within-line part only
            Dk = sp.csr_matrix((Sk.data[same], (Sk.row[same], Sk.col[same])), shape=(len(idx),) * 2)
            del Sk
            blocks = LineBlocks(idx, Dk, ordered=ordered)
            self._orders[k] = blocks.order
            sets.append((blocks.order, S[blocks.order], blocks))
        self.S, self.sets = S, sets

    def refit(self, S, amg_refit):
        """This smoother for a new S of the same pattern: lines, colours and band orders kept, the
        row copies and line factors made again; ``amg_refit(S) -> op`` the AMG cycle on it."""
        S = sp.csr_matrix(S)
        if S.shape != self.shape:
            raise ValueError(f"S is {S.shape}, the line smoother's {self.shape}")
        self.amg = None
        self._fit(S)
        self.amg = amg_refit(S)
        return self

    def _sweep(self, x, b, order):
        for k in order:
            idx, Sr, lu = self.sets[k]
            x[idx] += lu.solve(b[idx] - Sr @ x)
        return x

    def __matmul__(self, r):
        r = np.asarray(r).ravel()
        x = self._sweep(np.zeros_like(r, dtype=float), r, range(self.n_colors))
        x += self.amg @ (r - self.S @ x)
        return self._sweep(x, r, range(self.n_colors - 1, -1, -1))
