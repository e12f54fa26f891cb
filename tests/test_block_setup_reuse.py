"""Set-ups of the block preconditioners (solvers/block_contact.py) are reused while their matrix is
unchanged, rebuilt when it changes, and freed on release."""

import numpy as np
import pytest
import scipy.sparse as sp

from polypore.solvers.block_contact import _CondensedSolve


def _spd(n=12, shift=1e-2):
    one = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    return sp.csr_matrix(sp.kron(one, sp.identity(n)) + sp.kron(sp.identity(n), one) + shift * sp.identity(n * n))


@pytest.mark.parametrize("mechanics", ["amg", "direct"])
def test_condensed_solve_is_set_up_once_per_matrix(mechanics):
    S = _spd()
    b = np.random.default_rng(1).standard_normal(S.shape[0])
    cs = _CondensedSolve(mechanics)
    op = cs(S)
    assert cs(S.copy()) is op and cs.setups == 1          # equal matrix, another object: reused
    S2 = S.copy()
    S2.data[0] *= 1.5                                     # one value changed: built again
    op2 = cs(S2)
    assert op2 is not op and cs.setups == 2
    if mechanics == "direct":
        assert np.linalg.norm(S2 @ (op2 @ b) - b) < 1e-10 * np.linalg.norm(b)
    cs.release()
    assert cs(S2) is not op2 and cs.setups == 3


def test_condensed_solve_rejects_an_unknown_method():
    with pytest.raises(ValueError, match="mechanics must be one of"):
        _CondensedSolve("cholesky")
