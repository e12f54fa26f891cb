"""The line smoother's per-colour block factors (solvers/line_smoother.py::LineBlocks)."""
import numpy as np
import scipy.sparse as sp
import pytest

from polypore.solvers import line_smoother
from polypore.solvers.line_smoother import LineBlocks


def _paths(n_lines, length, rng, spd=True):
    """Block-diagonal matrix of ``n_lines`` SPD 3-dof-per-node chains, rows shuffled."""
    blocks = []
    for _ in range(n_lines):
        m = 3 * length
        T = sp.diags([rng.uniform(-1, 1, m - k) for k in (1, 2, 3)], [1, 2, 3])
        D = T + T.T + sp.diags(np.full(m, 8.0 if spd else 0.5))
        blocks.append(D)
    D = sp.block_diag(blocks).tocsr()
    p = rng.permutation(D.shape[0])
    return D[p][:, p].tocsr()


@pytest.mark.parametrize("spd, band", [(True, None), (False, None), (True, 1)])
def test_line_blocks_solve_exactly_in_their_own_order(spd, band, monkeypatch):
    """Banded Cholesky (SPD, narrow band) and the SuperLU fallbacks (indefinite, band too wide)
    solve D x = b to round-off, with b and x in ``order``."""
    if band is not None:
        monkeypatch.setattr(line_smoother, "MAX_BAND", band)
    rng = np.random.default_rng(3)
    D = _paths(5, 7, rng, spd)
    idx = np.arange(100, 100 + D.shape[0])           # the colour's dofs in the full system
    lb = LineBlocks(idx, D)
    loc = lb.order - 100
    assert sorted(loc) == list(range(D.shape[0]))
    b = rng.standard_normal(D.shape[0])
    x = lb.solve(b[loc])
    r = D[loc][:, loc] @ x - b[loc]
    assert np.linalg.norm(r) < 1e-12 * np.linalg.norm(b)
    assert (lb._chol is not None) == (spd and band is None)

