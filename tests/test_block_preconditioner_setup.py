"""Set-ups of the block preconditioners (solvers/block_contact.py): the condensed block, reused while
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


def test_condensed_block_is_the_symmetric_part_of_the_schur_complement():
    """S = A − ½(P + Pᵀ), P = Bt Cl̂⁻¹ Cû, equals ½(S₀ + S₀ᵀ) with S₀ = A − P for a symmetric A
    (the condensation symmetrises only its contact term since the set-up memory was cut)."""
    from polypore.solvers.block_contact import ContactCondensation

    rng = np.random.default_rng(5)
    nf, d, nu = 6, 3, 40
    A = _spd(7)[:nu, :nu]
    n = rng.standard_normal((nf, d))
    n /= np.linalg.norm(n, axis=1)[:, None]
    c = 1.0 + rng.random(nf)
    Bt = sp.random(nu, nf * d, density=0.2, random_state=1, format="csr")
    Cu = sp.random(nf * d, nu, density=0.2, random_state=2, format="csr")
    blocks = [c[f] * 0.3 * rng.standard_normal((d, d)) for f in range(nf)]
    Cl = sp.block_diag(blocks, format="csr")
    cond = ContactCondensation(c, n, 0.1)
    Cinv, Cu_s, S = cond.condense(A, Bt, Cu, Cl)
    S0 = (A - Bt @ Cinv @ Cu_s).toarray()
    assert np.abs(S.toarray() - 0.5 * (S0 + S0.T)).max() < 1e-13 * np.abs(S0).max()
    assert np.abs(S.toarray() - S.toarray().T).max() == 0.0
