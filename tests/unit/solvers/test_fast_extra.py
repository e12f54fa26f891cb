"""The optional extra ``fast`` (PARDISO through pypardiso): chosen by ``auto``, and it gives the
results of the default SciPy solver. ``make test-fast`` installs the extra in a clean venv and
runs the suite with ``POLYPORE_REQUIRE_PARDISO=1``, so that this file fails there (instead of
skipping) when the extra did not install; without the extra (``make test``) it is skipped."""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.sparse as sp

from polypore.solvers.linear import LinearSolver, have_pardiso

if not have_pardiso():
    if os.environ.get("POLYPORE_REQUIRE_PARDISO"):
        pytest.fail("POLYPORE_REQUIRE_PARDISO is set but pypardiso does not import: the extra 'fast' did not install",
                    pytrace=False)
    pytest.skip("the optional extra 'fast' (pypardiso) is not installed", allow_module_level=True)


def _laplacian_3d(n):
    """7-point Laplacian on n³ nodes plus a small shift: SPD, (n³, n³)."""
    one = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    A = sp.kron(sp.kron(one, eye), eye) + sp.kron(sp.kron(eye, one), eye) + sp.kron(sp.kron(eye, eye), one)
    return sp.csr_matrix(A + 1e-3 * sp.identity(n**3))


def test_auto_picks_pardiso():
    assert LinearSolver("auto").backend == "pardiso"


@pytest.mark.parametrize("symmetric", [True, False])
def test_pardiso_matches_superlu(symmetric):
    rng = np.random.default_rng(3)
    A = _laplacian_3d(12)
    if not symmetric:
        A = sp.csr_matrix(A + sp.diags(0.3 * rng.random(A.shape[0] - 1), 1))
    b = rng.standard_normal((A.shape[0], 2))
    x_p = LinearSolver("pardiso", symmetric=symmetric).solve(A, b)
    x_s = LinearSolver("superlu", symmetric=symmetric).solve(A, b)
    assert np.linalg.norm(A @ x_p - b) < 1e-10 * np.linalg.norm(b)
    assert np.abs(x_p - x_s).max() < 1e-10 * np.abs(x_s).max()


def test_pardiso_keeps_no_factors_after_a_solve():
    """pypardiso's module-level solver kept the last factors and a copy of the matrix: after a
    coupled model's initial equilibrium they stayed resident through the run (1.3 GB at 30,000
    corner-point cells). A solve releases them; the next one factorises again."""
    import pypardiso

    A = _laplacian_3d(10)
    b = np.ones(A.shape[0])
    s = LinearSolver("pardiso", symmetric=True)
    x1 = s.solve(A, b)
    held = pypardiso.scipy_aliases.pypardiso_solver
    assert held.factorized_A.shape == (0, 0)
    x2 = s.solve(A, 2 * b)
    assert np.linalg.norm(A @ x1 - b) < 1e-10 * np.linalg.norm(b)
    assert np.abs(x2 - 2 * x1).max() < 1e-12 * np.abs(x2).max()


def test_a_3d_contact_case_is_solver_independent():
    """cube-slip-3d on a coarse mesh: the same slip and Newton count with PARDISO and SuperLU."""
    pytest.importorskip("gmsh")
    from polypore.runs.static import solve_static
    from polypore.setup.casefile import load_case

    out = {}
    for backend in ("pardiso", "superlu"):
        # the linear space on a coarse √r mesh (the case's own P2 mesh takes SuperLU minutes and 5 GB)
        case = load_case("cube-slip-3d", [f"solver.linear={backend}", "mechanics.order=1", "mesh.front=isotropic",
                                          "mesh.grading=0.4", "mesh.tip_grading=0.5",
                                          "mesh.size=0.48", "mesh.fracture_size=0.128", "mesh.tip_size=0.024"])
        _, st, _, err, _ = solve_static(case)
        out[backend] = st, err
    (st_p, err_p), (st_s, err_s) = out["pardiso"], out["superlu"]
    assert st_p.newton_iterations == st_s.newton_iterations
    assert np.array_equal(st_p.state, st_s.state)
    assert abs(err_p["max_slip_error_rel"] - err_s["max_slip_error_rel"]) < 1e-8
    assert abs(err_p["slip_L2_rel"] - err_s["slip_L2_rel"]) < 1e-8
