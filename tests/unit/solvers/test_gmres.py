"""The restarted GMRES driver of the block solvers (solvers/block_contact.py): iteration cap and
the round-off floor of the true residual."""

from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from polypore.core.errors import RunError
from polypore.solvers.block_contact import _gmres


def _opts(**kw):
    base = dict(rtol=1e-8, maxiter=400, restart=100, accept_rtol=1e-6, iterations=[])
    base.update(kw)
    return SimpleNamespace(**base)


def _floor_system(n=40, cond=1e10, seed=0):
    """J = Q diag(d) Qᵀ with d from 1 to ``cond``: evaluating J x - b in floating point leaves a
    relative residual of about 1e-7 however accurate x is."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    d = np.logspace(0, np.log10(cond), n)
    J = Q @ np.diag(d) @ Q.T
    Jinv = Q @ np.diag(1.0 / d) @ Q.T
    return sp.csr_matrix(J), Q @ np.ones(n), (lambda r: Jinv @ r)


def test_floor_is_accepted_after_few_iterations():
    J, b, apply = _floor_system()
    opts = _opts()
    x = _gmres(J, b, apply, opts)
    res = np.linalg.norm(J @ x - b) / np.linalg.norm(b)
    assert opts.rtol < res <= opts.accept_rtol          # the floor really is above rtol
    assert opts.iterations[-1] <= 10                      # SciPy's own loop spun for thousands


def test_floor_above_accept_rtol_is_an_error():
    J, b, apply = _floor_system()
    with pytest.raises(RunError, match="GMRES did not reach"):
        _gmres(J, b, apply, _opts(accept_rtol=1e-12, maxiter=30, restart=10))


@pytest.mark.parametrize("maxiter, restart", [(7, 100), (25, 10)])
def test_maxiter_caps_inner_iterations(maxiter, restart):
    rng = np.random.default_rng(1)
    n = 300
    J = sp.diags(np.logspace(0, 6, n)) + sp.random(n, n, density=0.02, random_state=rng)
    opts = _opts(maxiter=maxiter, restart=restart)
    with pytest.raises(RunError, match=f"in {maxiter} iterations"):
        _gmres(sp.csr_matrix(J), rng.standard_normal(n), lambda r: r, opts)
    assert opts.iterations[-1] == maxiter


def test_zero_right_hand_side():
    J, _, apply = _floor_system(n=5)
    opts = _opts()
    assert np.all(_gmres(J, np.zeros(5), apply, opts) == 0) and opts.iterations[-1] == 0


def test_restart_shortened_on_large_systems_only():
    """The Krylov basis stays within its byte budget on large systems, never below the floor;
    small systems keep the restart asked for."""
    from polypore.solvers.block_contact import KRYLOV_BASIS_BYTES, MIN_RESTART, krylov_restart

    assert krylov_restart(100, 10_000) == 100 and krylov_restart(25, 10_000) == 25
    n = 4_400_000
    r = krylov_restart(100, n)
    assert MIN_RESTART <= r < 100 and (r + 1) * 8 * n <= KRYLOV_BASIS_BYTES
    assert krylov_restart(100, 50_000_000) == MIN_RESTART and krylov_restart(10, 50_000_000) == 10
