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


def test_amg_hierarchy_kept_for_a_few_changed_rows_and_rebuilt_for_many():
    """A new S that differs on few rows (the condensed contact rows) keeps the AMG hierarchy,
    refitted to S (finest operator and smoother), and preconditions S as well as a new one; a
    new S that differs on many rows gets a new hierarchy."""
    import scipy.sparse.linalg as spla

    pytest.importorskip("pyamg")
    S = _spd(30)
    n = S.shape[0]
    b = np.random.default_rng(2).standard_normal(n)
    cs = _CondensedSolve("amg")
    cs(S)
    assert cs.hierarchies == 1

    def pcg(S, op):
        its = [0]
        x, info = spla.cg(S, b, rtol=1e-10, maxiter=200, M=spla.LinearOperator(S.shape, matvec=op.__matmul__),
                          callback=lambda _: its.__setitem__(0, its[0] + 1))
        assert info == 0
        return its[0]

    S2 = sp.csr_matrix(S + sp.diags(np.where(np.arange(n) % 97 == 0, 1e4, 0.0)))   # stiff springs on 1 % of rows
    op2 = cs(S2)
    assert cs.setups == 2 and cs.hierarchies == 1
    assert np.array_equal(cs._ml.levels[0].A.diagonal(), S2.diagonal())            # refitted to S2
    fresh = _CondensedSolve("amg")
    assert pcg(S2, op2) <= pcg(S2, fresh(S2)) + 2
    S3 = sp.csr_matrix(S * 2.0)                                                       # every row
    cs(S3)
    assert cs.setups == 3 and cs.hierarchies == 2


def test_factorised_solve_by_substitution_phases_is_exact():
    """With PARDISO, S⁻¹ is applied by its forward, diagonal and backward phases (no iterative
    refinement); without it by SuperLU: either way an exact solve, also column by column."""
    from polypore.solvers.block_contact import _Factorised

    rng = np.random.default_rng(3)
    S = _spd(20, shift=1e-3)
    R = sp.random(S.shape[0], S.shape[0], density=5e-3, random_state=4)
    S = sp.csr_matrix(S + 0.1 * (R @ R.T))             # SPD, irregular pattern
    f = _Factorised(S)
    b = rng.standard_normal(S.shape[0])
    assert np.linalg.norm(S @ (f @ b) - b) < 1e-10 * np.linalg.norm(b)
    B = rng.standard_normal((S.shape[0], 3))
    assert np.linalg.norm(S @ (f @ B) - B) < 1e-10 * np.linalg.norm(B)
