"""The 3D cube-slip case (issue 13): its fine-mesh reference, the error measures, and the
accuracy per unknown of tip-graded meshes against uniform ones."""

import numpy as np
import pytest

from polypore.cases.reference import load_reference
from polypore.runs.static import solve_static, unknowns
from polypore.setup.casefile import load_case

pytest.importorskip("gmsh")


def test_reference_file():
    ref = load_reference("cube-slip-3d")
    # quadratic displacements on three r^(2/3)-graded levels, extrapolated: 5.718e-5 m; three other
    # P2 mesh families extrapolate to 5.715-5.719e-5 m (docs/accuracy_3d.md, "The P2 reference")
    assert 5.69e-5 < ref.max_slip < 5.75e-5
    mag = np.linalg.norm(ref.slip, axis=2)
    assert np.all(mag[[0, -1], :] == 0) and np.all(mag[:, [0, -1]] == 0)      # tip lines
    assert abs(mag.max() - ref.max_slip) < 0.01 * ref.max_slip
    # the slip is tangential to the plane y = z
    n = np.array([0.0, 1.0, -1.0]) / np.sqrt(2.0)
    assert np.abs(ref.slip @ n).max() < 1e-3 * ref.max_slip


def test_error_measures_vanish_on_the_reference_itself():
    ref = load_reference("cube-slip-3d")
    A, B = np.meshgrid(0.5 * (ref.a[1:] + ref.a[:-1]), 0.5 * (ref.b[1:] + ref.b[:-1]), indexing="ij")
    X = ref.origin + A.ravel()[:, None] * ref.e1 + B.ravel()[:, None] * ref.e2
    s, ln = ref.at(X)
    area = np.full(len(X), 1.0)
    e = ref.errors_of(X, area, s, ln, np.zeros(len(X), bool))
    assert e["slip_L2_rel"] < 1e-12 and e["lambda_n_L2_rel_inner"] < 1e-12
    e = ref.errors_of(X, area, 0.9 * s, ln, np.zeros(len(X), bool))
    assert abs(e["slip_L2_rel_inner"] - 0.1) < 1e-9


def _errors(*overrides):
    # the linear space on isotropic √r-graded or uniform meshes (the case itself runs P2 on
    # anisotropic crack-front cells); grading 0.4 as the measured series
    case = load_case("cube-slip-3d", ["solver.linear=auto", "mechanics.order=1", "mesh.front=isotropic",
                                      "mesh.grading=0.4", "mesh.tip_grading=0.5", *overrides])
    problem, st, setup, err, _ = solve_static(case)
    return unknowns(problem), err


def test_tip_graded_mesh_beats_uniform_per_unknown():
    n_g, graded = _errors("mesh.size=0.48", "mesh.fracture_size=0.128", "mesh.tip_size=0.024")
    n_u, uni = _errors("mesh.size=0.07", "mesh.fracture_size=0.07", "mesh.tip_size=1e9")
    assert n_g < 1.4 * n_u
    # docs/cube_slip.md (P2 reference): uniform h = 0.07 (9k unknowns) 30 % off in the slip profile
    # (rim out), 21 % in the maximum; the graded mesh (11k) 18 % and 16 %
    assert uni["slip_L2_rel_inner"] > 0.25
    assert graded["slip_L2_rel_inner"] < 0.65 * uni["slip_L2_rel_inner"]
    assert graded["max_slip_error_rel"] < 0.85 * uni["max_slip_error_rel"]


@pytest.mark.slow
def test_quadratic_runs_are_measured_as_fields():
    """With mechanics.order = 2 the case's errors use the P2 slip at the points of a face rule (not
    the face means, which would cost O(h²) by themselves); open_faces still counts faces."""
    case = load_case("cube-slip-3d", ["solver.linear=auto", "mechanics.order=2", "mesh.front=isotropic",
                                      "mesh.grading=0.4", "mesh.size=1.0", "mesh.fracture_size=0.3",
                                      "mesh.tip_size=0.05", "mesh.tip_grading=0.6"])
    problem, st, _, err, _ = solve_static(case)
    X, W, J = problem.space.jump_quadrature()
    nq = W.size // problem.n_ff
    q = J @ st.u
    n = np.repeat(problem.normal, nq, axis=0)
    qt = q - np.einsum("fi,fi->f", q, n)[:, None] * n
    assert err["max_slip"] == pytest.approx(np.linalg.norm(qt, axis=1).max(), rel=1e-12)
    means = problem.jumps(st)
    assert err["max_slip"] > np.linalg.norm(means, axis=1).max()      # point values beat face means
    assert 0 <= err["open_faces"] <= problem.n_ff


@pytest.mark.slow
def test_the_case_default_meets_3_percent_on_max_slip_and_slip_profile():
    """The built-in case (P2 on anisotropic crack-front cells, 17.7k unknowns): issue 13's target,
    ≤ 3 % on the maximum slip and on the slip profile (relative L2) with ≤ 20,000 unknowns;
    docs/cube_slip_anisotropic.md measured 1.1 / 2.0 / 1.7 % (rim out). Isotropic r^0.6 grading
    (22.5k unknowns) was 2.7 / 7.0 / 4.6 %; P1 on the √r mesh of the same cost 10.6 / 15.4 / 13.2 %."""
    case = load_case("cube-slip-3d", ["solver.linear=auto"])
    problem, st, _, err, _ = solve_static(case)
    assert 15_000 < unknowns(problem) <= 20_000
    assert err["max_slip_error_rel"] < 0.02 and err["slip_L2_rel"] < 0.03 and err["slip_L2_rel_inner"] < 0.025
    assert err["open_faces"] == 0
