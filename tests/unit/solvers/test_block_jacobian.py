"""The Newton Jacobian by blocks (solvers/block_jacobian.py): the block solvers get the blocks the
models used to assemble into one matrix, equal entry for entry, and S is built on A's pattern."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import sheared_mechanics

from polypore.core.csr import csr_positions, csr_positions_in_rows, with_entries
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.models.contact import SLIP
from polypore.models.flow import FlowData, Pressure
from polypore.models.mechanics import ContactMechanics
from polypore.models.poromechanics import Poromechanics
from polypore.solvers.block_jacobian import BlockJacobian, FreeSplit, abs_matvec, block_diag_csr
from polypore.solvers.factory import SolverChoice
from polypore.solvers.linear import LinearSolver


def _random_spd(n, seed):
    R = sp.random(n, n, density=0.08, random_state=seed, format="csr")
    return sp.csr_matrix(R + R.T + sp.eye(n) * n)


def test_free_split_is_the_matrix_by_blocks():
    A = _random_spd(60, 1)
    A.sort_indices()
    free = np.sort(np.random.default_rng(0).choice(60, 45, replace=False))
    F = FreeSplit(A, free)
    assert abs(F.ff - A[free][:, free]).max() == 0 and F.ff.has_sorted_indices
    assert F.nnz == A.nnz and abs(F.tocsr() - A).max() == 0 and abs(F.tocsc() - A).max() == 0
    x = np.random.default_rng(1).standard_normal(60)
    assert np.allclose(F @ x, A @ x, rtol=1e-14, atol=1e-14 * np.abs(A @ x).max())
    assert np.array_equal(F.diagonal(), A.diagonal())
    fixed = np.setdiff1d(np.arange(60), free)
    R = sp.csr_matrix(F.rest)
    assert np.all(np.isin(R.tocoo().row, fixed) | np.isin(R.tocoo().col, fixed))   # the rest: fixed rows/cols only


def test_block_jacobian_products_and_assembly():
    rng = np.random.default_rng(2)
    nu, nl, n_p = 30, 9, 20
    J = sp.random(nu + nl + n_p, nu + nl + n_p, density=0.1, random_state=3, format="csr")
    J = sp.lil_matrix(J + sp.eye(J.shape[0]))
    J[nu:nu + nl, nu + nl:] = 0.0                   # no λ–p blocks
    J[nu + nl:, nu:nu + nl] = 0.0
    J = sp.csr_matrix(J)
    J.eliminate_zeros()
    B = BlockJacobian.from_csr(J, nu, nl)
    x = rng.standard_normal(J.shape[0])
    assert B.shape == J.shape
    assert np.allclose(B @ x, J @ x, rtol=1e-13, atol=1e-13)
    assert np.allclose(B.abs_matvec(np.abs(x)), abs(J) @ np.abs(x), rtol=1e-13)
    assert abs(B.tocsr() - J).max() == 0
    assert np.allclose(abs_matvec(J, np.abs(x)), abs(J) @ np.abs(x), rtol=1e-13)
    blocks = rng.standard_normal((4, 3, 3))
    assert abs(block_diag_csr(blocks) - sp.block_diag(list(blocks))).max() == 0


def test_with_entries_adds_explicit_zeros_only():
    rng = np.random.default_rng(5)
    for seed in range(20):
        M = sp.csr_array(sp.random(25, 20, density=0.2, random_state=seed, format="csr"))
        M.sort_indices()
        r, c = rng.integers(0, 25, 30), rng.integers(0, 20, 30)
        N = with_entries(M, r, c)
        assert abs(N - M).max() == 0 and N.has_sorted_indices
        assert csr_positions(N, r, c)[1].all()
        assert N.nnz == len(set(zip(*M.nonzero())) | set(zip(r.tolist(), c.tolist())))
        pos, found = csr_positions_in_rows(N, r, c)
        assert found.all() and np.array_equal(pos, csr_positions(N, r, c)[0])


def _box(n):
    return cartesian_mesh([grid_coordinates(0, 1, n, [0.25, 0.5, 0.75])] * 3)


def _fracture():
    return [FractureSpec("F", np.array([[0.25, 0.25, 0.5], [0.75, 0.25, 0.5], [0.75, 0.75, 0.5], [0.25, 0.75, 0.5]]))]


def _poro(solver, **kw):
    fm = FracturedMesh.build(_box(6), _fracture())
    fd = FlowData(permeability=1e-15, viscosity=1e-3, biot_modulus=1e10, biot_coefficient=0.5, aperture=1e-4,
                  normal_permeability=1e-15)
    return Poromechanics(fm, sheared_mechanics(fm, 50.0, False), fd, {"xmin": Pressure(1e5)}, solver=solver, **kw)


@pytest.fixture(scope="module")
def poro_pair():
    return _poro(SolverChoice("block-amg")), _poro(LinearSolver("superlu"))


def _dilatant_linearisations(Pb, Pa):
    """Both models with ψ = 20° after one step of Pa; (state, x0 of Pa's and Pb's next step, x a
    perturbed iterate, Pa's and Pb's linearisations at x)."""
    st = Pa.initial_state(1e5)
    for P in (Pa, Pb):
        P.tan_psi[:] = np.tan(np.radians(20.0))
        P.u_ref = st.u.copy()
    st, _ = Pa.step(st, 10.0)
    ca, x0 = Pa.step_context(st, 10.0, st.time + 10.0)
    cb, xb = Pb.step_context(st, 10.0, st.time + 10.0)
    x = x0 * (1 + 1e-3 * np.random.default_rng(0).standard_normal(x0.size))
    return st, x0, xb, x, Pa._linearise(x, ca), Pb._linearise(x, cb)


def test_coupled_blocks_equal_the_assembled_jacobian(poro_pair):
    """With dilatancy (the p × u block gets a second contribution) and slipping faces: the blocks
    the block solver receives are the assembled Jacobian's, entry for entry."""
    Pb, Pa = poro_pair
    assert Pb.blockwise and not Pa.blockwise and Pb.jacobian.pattern is None
    _, x0, xb, x, la, lb = _dilatant_linearisations(Pb, Pa)
    assert np.array_equal(x0, xb)
    assert np.any(la.active_set == SLIP)
    assert np.array_equal(la.residual, lb.residual)
    assert isinstance(lb.jacobian, BlockJacobian)
    Ja, Jb = sp.csr_matrix(la.jacobian), lb.jacobian.tocsr()
    assert abs(Ja - Jb).max() == 0
    v = np.random.default_rng(1).standard_normal(x.size)
    assert np.allclose(Jb @ v, lb.jacobian @ v, rtol=1e-12, atol=1e-12 * np.abs(Jb @ v).max())
    for P in (Pa, Pb):
        P.tan_psi[:] = 0.0


def test_implicit_conductivity_blocks_equal_the_assembled_jacobian():
    """Conductivities at the iterate's aperture (a third p × u contribution and a flow block that
    changes per iterate): the blocks equal the assembled Jacobian's, to round-off."""
    Pb, Pa = (_poro(SolverChoice(k), conductivity_aperture="current") for k in ("block-amg", "superlu"))
    st, _, _, x, la, lb = _dilatant_linearisations(Pb, Pa)
    assert np.any(la.active_set == SLIP)
    assert np.array_equal(la.residual, lb.residual)
    Ja, Jb = sp.csr_matrix(la.jacobian), lb.jacobian.tocsr()
    assert abs(Ja - Jb).max() <= 1e-12 * abs(Ja).max()
    lag = _poro(LinearSolver("superlu"))
    lag.tan_psi[:] = Pa.tan_psi
    lag.u_ref = Pa.u_ref
    cl, _ = lag.step_context(st, 10.0, st.time + 10.0)
    assert abs(Ja - sp.csr_matrix(lag._linearise(x, cl).jacobian)).max() > 1e-6 * abs(Ja).max()   # the terms are there


def test_contact_blocks_equal_the_assembled_jacobian():
    fm = FracturedMesh.build(_box(6), _fracture())
    md = sheared_mechanics(fm, 50.0, False)
    Mb, Ma = ContactMechanics(fm, md, SolverChoice("block-amg")), ContactMechanics(fm, md, LinearSolver("superlu"))
    assert Mb.blockwise and Mb.pattern is None and not Ma.blockwise
    F, udir = Ma.load_vector(30.0), Ma.dirichlet_vector(30.0)
    st = Ma.solve(30.0, verbose=False)
    x = np.concatenate([st.u.ravel()[Ma.free], (Ma.patch_values(st.lam) / Ma.law.beta[:, None]).ravel()])
    la, lb = Ma.linearise(x, F, udir), Mb.linearise(x, F, udir)
    assert abs(sp.csr_matrix(la.jacobian) - lb.jacobian.tocsr()).max() == 0
    # the elastic matrix holds the contact couplings as explicit zeros; its values are unchanged
    assert Mb.A.nnz > np.count_nonzero(Mb.A.tocsr().data) and isinstance(Mb.A, FreeSplit)


def test_condensed_matrix_on_the_elastic_pattern(poro_pair):
    """S = A − ½(P + Pᵀ) is built in place on A's restriction (A holds the couplings) and equals
    the sparse sum of the earlier construction."""
    Pb, _ = poro_pair
    st = Pb.initial_state(1e5)
    st, _ = Pb.step(st, 10.0)
    ctx, x0 = Pb.step_context(st, 10.0, st.time + 10.0)
    J = Pb._linearise(x0, ctx).jacobian
    cond = Pb.mech.condensation()
    Cinv, Cu_s, S = cond.condense(J.uu, J.ul, J.lu, J.ll)
    with pytest.raises(ValueError):
        sp.csr_matrix(J.uu).eliminate_zeros()               # A's shared structure is read-only
    A = sp.csr_matrix(J.uu, copy=True)
    A.eliminate_zeros()                                      # the general path: a sparse sum
    Cinv2, Cu_s2, S2 = cond.condense(A, J.ul, J.lu, J.ll)
    P = (J.ul @ Cinv @ Cu_s).tocsr()
    ref = J.uu - 0.5 * (P + P.T)
    assert abs(S - ref).max() <= 1e-15 * abs(ref).max()
    assert abs(S - S2).max() <= 1e-15 * abs(ref).max()
    assert S.nnz == J.uu.nnz and np.shares_memory(S.indices, J.uu.indices)   # A's pattern, its indices
    assert not np.shares_memory(S.data, J.uu.data)


def test_condensed_matrix_borrows_the_elastic_values(poro_pair):
    """condense(borrow=True): S is A's own arrays with the contact entries changed; the lent
    object is A for products, diagonal and |A| x; restore() gives back A's values bit for bit, and
    a whole block solve (set-up, GMRES) leaves them so."""
    Pb, _ = poro_pair
    st = Pb.initial_state(1e5)
    st, _ = Pb.step(st, 10.0)
    ctx, x0 = Pb.step_context(st, 10.0, st.time + 10.0)
    J = Pb._linearise(x0, ctx).jacobian
    A = J.uu
    before = A.data.copy()
    cond = Pb.mech.condensation()
    Cinv, Cu_s, S_own = cond.condense(A, J.ul, J.lu, J.ll)
    _, _, S, lent = cond.condense(A, J.ul, J.lu, J.ll, borrow=True)
    try:
        assert S.data.ctypes.data == A.data.ctypes.data                # the same values
        assert np.array_equal(S.toarray(), S_own.toarray())
        ref = sp.csr_matrix((before, A.indices, A.indptr), shape=A.shape)
        v = np.random.default_rng(2).standard_normal(A.shape[0])
        assert np.allclose(lent @ v, ref @ v, rtol=0, atol=1e-13 * np.abs(ref @ v).max())
        assert np.array_equal(lent.diagonal(), ref.diagonal())
        assert np.allclose(lent.abs_matvec(np.abs(v)), abs(ref) @ np.abs(v), rtol=1e-13)
        assert not np.array_equal(A.data, before)           # borrowed: the contact entries are S's
    finally:
        lent.restore()
    assert np.array_equal(A.data, before)
    rhs = np.random.default_rng(3).standard_normal(J.shape[0])
    x = Pb.solver.solve(J, rhs)
    assert np.array_equal(J.uu.data, before)                 # the solve gave them back
    assert np.linalg.norm(J @ x - rhs) <= 1e-6 * np.linalg.norm(rhs)
