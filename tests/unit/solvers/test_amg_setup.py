"""solvers/amg_setup.py: the copy-free finest level gives pyamg's smoothed-aggregation hierarchy."""

from __future__ import annotations

import numpy as np
import pyamg
import pytest
import scipy.sparse as sp

from polypore.solvers import amg_setup
from polypore.solvers.amg_setup import sa_hierarchy
from polypore.solvers.linear import repeatable_random


def _problems():
    A3 = sp.csr_matrix(pyamg.gallery.poisson((28, 28, 28), format="csr"))
    E, B = pyamg.gallery.linear_elasticity((150, 150), format="csr")
    return [("poisson-3d", A3, None), ("elasticity-2d", sp.csr_matrix(E), B)]


@pytest.mark.parametrize("name,A,B", _problems())
def test_same_hierarchy_as_pyamg(monkeypatch, name, A, B):
    monkeypatch.setattr(amg_setup, "ROW_BLOCK", 3000)          # several row blocks
    with repeatable_random():
        ref = pyamg.smoothed_aggregation_solver(A, B=B, strength="symmetric", max_coarse=1000, coarse_solver="splu")
    with repeatable_random():
        ml = sa_hierarchy(A, B, max_coarse=1000, coarse_solver="splu")
    assert len(ml.levels) == len(ref.levels) >= 3
    # the finest level and the first coarse operator are pyamg's to round-off; deeper levels come
    # from pyamg's own set-up on that operator, whose pattern can differ by entries that cancel to
    # round-off (a sum over row blocks), so their aggregates may differ: compared by the cycle
    for mine, theirs in zip(ml.levels[:2], ref.levels[:2]):
        a, b = sp.csr_matrix(mine.A), sp.csr_matrix(theirs.A)
        assert a.shape == b.shape and abs(a - b).max() <= 1e-12 * abs(b).max(), name
    assert type(ml.levels[1].A).__name__ == type(ref.levels[1].A).__name__       # the block form kept
    P, Pr = sp.csr_matrix(ml.levels[0].P), sp.csr_matrix(ref.levels[0].P)
    assert abs(P - Pr).max() <= 1e-12 * abs(Pr).max()
    assert np.shares_memory(ml.levels[0].R.data, ml.levels[0].P.data)       # R a view of P
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    its = []
    for h in (ml, ref):
        res = []
        h.solve(b, tol=1e-8, accel="cg", residuals=res)
        its.append(len(res))
    assert abs(its[0] - its[1]) <= max(1, 0.1 * its[1]), its

def test_small_operator_goes_to_pyamg():
    A = sp.csr_matrix(pyamg.gallery.poisson((20, 20), format="csr"))
    ml = sa_hierarchy(A, None, max_coarse=1000)
    assert len(ml.levels) == 1
