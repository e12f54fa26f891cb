"""PETSc backends (solvers/petsc.py, solvers/petsc_fieldsplit.py): same solutions as SciPy on
polypore's own systems, PETSc options passed through and checked, near-null spaces, set-up reuse,
and the fieldsplit preconditioners against block_contact's. Needs petsc4py (``make test-mpi``);
skipped elsewhere, except the SciPy-only check of the condensation blocks."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from polypore.core.errors import InputError
from polypore.mesh import FracturedMesh
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.models.mechanics import ContactMechanics, DisplacementBC, MechanicsData
from polypore.solvers.block_contact import BlockContactSolver, BlockPoroSolver


@functools.lru_cache(maxsize=None)
def elasticity(n: int = 6):
    """(A, b, rigid-body modes) of 3D VEM elasticity on an n³ grid, clamped at z = 0, loaded downwards."""
    mesh = cartesian_mesh([grid_coordinates(0, 1, n, []) for _ in range(3)])
    fm = FracturedMesh.build(mesh, [])
    nc = mesh.n_cells
    P = ContactMechanics(fm, MechanicsData(mu=np.full(nc, 4.0e9), lam=np.full(nc, 3.0e9),
                                           displacement=[DisplacementBC("zmin", (0, 1, 2), lambda X, t: 0 * X)]))
    A = sp.csr_matrix(P.A.tocsr()[P.free][:, P.free])
    b = np.zeros(A.shape[0])
    b[2::3] = -1.0
    b += 0.1 * np.sin(np.arange(A.shape[0]))          # not only a smooth load
    return A, b, P.rigid_modes()


@functools.lru_cache(maxsize=None)
def poro_system():
    """A coupled step Jacobian [u, l, p] of a 3D sheared fracture after two loading steps (slip)
    and what the block solvers are built from."""
    from test_poromechanics import shear_case

    P = shear_case(3, 8)
    st = P.initial_state(1e5)
    for _ in range(2):
        st, _info = P.step(st, 10.0)
    ctx, x0 = P.step_context(st, 10.0, st.time + 10.0)
    lin = P._linearise(x0, ctx)
    s = ctx.pressure_scale
    return (sp.csr_matrix(lin.jacobian.tocsr()), -lin.residual, P.mech.free.size, P.dim, P.n_ff * P.dim,
            P.mech.condensation(), P.mech.rigid_modes(), 1.0 / s[P.flow_free], lin.counts)


def test_condensation_blocks_match_block_contact():
    """Cl̂⁻¹ and Cû of the PETSc preconditioner matrix are block_contact's (SciPy only)."""
    from polypore.solvers.petsc_fieldsplit import modified_contact_blocks

    J, _, nu, d, nl, cond, *_ = poro_system()
    po = nu + nl
    A, Bt, Cu, Cl = J[:nu, :nu], J[:nu, nu:po], J[nu:po, :nu], J[nu:po, nu:po]
    Cinv, Cu_s, _S = cond.condense(A, Bt, Cu, Cl)
    Clhat, Cu_s2 = modified_contact_blocks(cond, Cu, Cl)
    from polypore.solvers.block_contact import _diag_blocks

    assert np.allclose(np.linalg.inv(Clhat), _diag_blocks(Cinv, nl // d, d), rtol=1e-12, atol=0)
    assert abs(Cu_s - Cu_s2).max() <= 1e-12 * abs(Cu_s).max()


# ---- everything below needs petsc4py ------------------------------------------------------------
def _petsc():
    return pytest.importorskip("petsc4py.PETSc")


@pytest.mark.parametrize("amg", ["gamg", "hypre"])
def test_solution_equals_scipy(amg):
    _petsc()
    from polypore.solvers.petsc import PetscLinearSolver

    A, b, B = elasticity()
    s = PetscLinearSolver(symmetric=True, rtol=1e-12, near_nullspace=B, amg=amg)
    x = s.solve(A, b)
    ref = spla.spsolve(A.tocsc(), b)
    assert np.linalg.norm(x - ref) <= 1e-8 * np.linalg.norm(ref)
    assert s.driver.ksp.getType() == "cg" and s.driver.ksp.getPC().getType() == ("gamg" if amg == "gamg" else "hypre")
    assert 0 < s.iterations[-1] < 60
    # several right-hand sides at once, as LinearSolver.solve allows
    X = s.solve(A, np.column_stack([b, 2 * b]))
    assert np.allclose(X[:, 1], 2 * X[:, 0], rtol=1e-8, atol=1e-8 * np.abs(X).max())


def test_linear_solver_backend_petsc():
    _petsc()
    from polypore.solvers.linear import LinearSolver

    A, b, B = elasticity()
    s = LinearSolver("petsc", symmetric=True, rtol=1e-12, near_nullspace=B)
    x = s.solve(A, b)
    assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b)
    assert s.stats.calls == 1 and s.stats.iterations


def test_near_nullspace_and_block_size():
    _petsc()
    from polypore.solvers.petsc import PetscLinearSolver

    A, b, B = elasticity()
    s = PetscLinearSolver(symmetric=True, rtol=1e-10, near_nullspace=B)
    s.solve(A, b)
    assert s.block_size == 3 and s._mat.getBlockSize() == 3
    nsp = s._mat.getNearNullSpace()
    assert nsp is not None and len(nsp.getVecs()) == 6
    V = np.column_stack([v.getArray() for v in nsp.getVecs()])
    assert np.allclose(V.T @ V, np.eye(6), atol=1e-10)                 # orthonormalised
    assert np.linalg.matrix_rank(np.column_stack([V, B]), tol=1e-8 * np.abs(B).max()) == 6  # spans B
    # without the rigid-body modes GAMG needs more iterations: the near-null space is used
    plain = PetscLinearSolver(symmetric=True, rtol=1e-10)
    plain.solve(A, b)
    assert s.iterations[-1] < plain.iterations[-1]


def test_options_pass_through_and_scope():
    PETSc = _petsc()
    from polypore.solvers.petsc import PetscLinearSolver

    A, b, B = elasticity()
    s = PetscLinearSolver(symmetric=True, rtol=1e-10, near_nullspace=B, prefix="t1_",
                          options={"-ksp_type": "minres", "pc_gamg_threshold": 0.02, "mg_levels_ksp_max_it": 3})
    s.solve(A, b)
    ksp = s.driver.ksp
    assert ksp.getType() == "minres" and ksp.getOptionsPrefix() == "t1_"
    assert np.linalg.norm(A @ s.solve(A, b) - b) <= 1e-9 * np.linalg.norm(b)
    db = PETSc.Options()
    assert not db.hasName("t1_ksp_type") and not db.hasName("t1_pc_gamg_threshold")   # removed after the solve
    # an entry already in PETSc's database (command line, PETSC_OPTIONS) wins over the table
    db.setValue("t2_ksp_type", "cg")
    try:
        s2 = PetscLinearSolver(symmetric=True, prefix="t2_", options={"ksp_type": "minres"})
        s2.solve(A, b)
        assert s2.driver.ksp.getType() == "cg"
    finally:
        db.delValue("t2_ksp_type")


@pytest.mark.parametrize("options, field, text", [
    ({"ksp_type": "cgg"}, "petsc_options.ksp_type", "allowed: "),
    ({"pc_gamg_type": "smooth"}, "petsc_options.pc_gamg_type", "agg, geo, classical"),
    ({"ksp_rtoll": 1e-3}, "petsc_options.ksp_rtoll", "did not use"),
    ({"pc_hypre_boomeramg_strong_threshold": 0.5}, "petsc_options.pc_hypre_boomeramg_strong_threshold",
     "did not use"),                                     # an option of a preconditioner not selected
    ({"pc_gamg_threshold": [0.1]}, "petsc_options.pc_gamg_threshold", "string, number or boolean"),
    ({"ksp type": "cg"}, "petsc_options.ksp type", "letters, digits and '_'"),
])
def test_bad_options_name_the_option(options, field, text):
    _petsc()
    from polypore.solvers.petsc import PetscLinearSolver

    A, b, B = elasticity()
    with pytest.raises(InputError, match=text) as err:
        PetscLinearSolver(symmetric=True, options=options).solve(A, b)
    assert err.value.field == field


def test_setup_reuse_is_counted():
    _petsc()
    from polypore.solvers.petsc import PetscLinearSolver, ReusePolicy

    A, b, B = elasticity()
    s = PetscLinearSolver(symmetric=True, rtol=1e-10, near_nullspace=B, reuse=ReusePolicy(max_age=3, growth=10.0))
    for k in range(7):                                   # Newton-like: the operator changes a little
        Ak = (A + sp.diags(1e-3 * (k + 1) * A.diagonal())).tocsr()
        x = s.solve(Ak, b)
        assert np.linalg.norm(Ak @ x - b) <= 1e-9 * np.linalg.norm(b)
    assert s.stats.setups == 3                           # solves 1, 4, 7
    # growth: a reused set-up that needs many more iterations is rebuilt for the next solve
    g = PetscLinearSolver(symmetric=True, rtol=1e-10, near_nullspace=B, reuse=ReusePolicy(max_age=100, growth=1.2))
    g.solve(A, b)
    g.solve((A + sp.diags(3.0 * A.diagonal())).tocsr(), b)   # the old hierarchy is poor for this one
    g.solve(A, b)
    assert g.iterations[1] > 1.2 * g.iterations[0] and g.stats.setups == 2
    # a stale set-up that fails is rebuilt and the solve repeated
    f = PetscLinearSolver(symmetric=True, rtol=1e-10, maxiter=60, near_nullspace=B, reuse=ReusePolicy(max_age=100))
    f.solve(A, b)
    # stiffer on every 7th dof: the stale hierarchy needs ~160 CG iterations, a fresh one ~20
    C = (A + sp.diags(50.0 * A.diagonal() * (np.arange(A.shape[0]) % 7 == 0))).tocsr()
    x = f.solve(C, b)
    assert f.stats.retries == 1 and f.stats.setups == 2
    assert np.linalg.norm(C @ x - b) <= 1e-9 * np.linalg.norm(b)


@pytest.mark.parametrize("structure", ["condensed", "fieldsplit"])
def test_block_contact_solver_matches_block_contact(structure):
    _petsc()
    from polypore.solvers.petsc_fieldsplit import PetscBlockContactSolver

    J, r, nu, d, nl, cond, B, _pns, counts = poro_system()
    assert counts["slip"] > 0                             # slipping faces: the g nᵀ coupling is dropped
    po = nu + nl
    K = sp.csr_matrix(J[:po, :po])
    rhs = np.asarray(r[:po])
    ref = spla.spsolve(K.tocsc(), rhs)
    options = {"pc_type": "fieldsplit"} if structure == "fieldsplit" else None
    s = PetscBlockContactSolver(nu, d, cond, near_nullspace=B, rtol=1e-10, options=options)
    assert s.structure == structure
    x = s.solve(K, rhs)
    assert np.linalg.norm(K @ x - rhs) <= 1e-9 * np.linalg.norm(rhs)
    assert np.linalg.norm(x - ref) <= 1e-6 * np.linalg.norm(ref)
    pc = s.driver.ksp.getPC()
    if structure == "fieldsplit":
        assert pc.getType() == "fieldsplit"
        ksp_l, ksp_s = pc.getFieldSplitSubKSP()
        assert ksp_l.getPC().getType() == "pbjacobi" and ksp_s.getPC().getType() == "hypre"
        assert ksp_s.getOperators()[1].getNearNullSpace() is not None
    else:
        assert pc.getType() == "python"
        ku = s._cpc.ku
        assert ku.getPC().getType() == "hypre" and ku.getOptionsPrefix() == "contact_fieldsplit_u_"
        assert ku.getOperators()[1].getNearNullSpace() is not None
        assert s._cpc.kp is None
    # the same preconditioner as BlockContactSolver's up to the AMG: similar GMRES counts
    ref_solver = BlockContactSolver(nu, d, cond, near_nullspace=B, rtol=1e-10)
    ref_solver.solve(K, rhs)
    assert s.iterations[-1] <= 2 * ref_solver.iterations[-1] + 5


def test_condensed_preconditioner_applies_the_fieldsplit_one():
    """The condensed PC (polypore's Schur blocks, two AMG sub-solves) is PCFIELDSPLIT's full Schur +
    selfp + multiplicative recipe: with exact sub-solves (LU on S_uu and S_pp) both apply the same
    operator, so GMRES takes the same iterations to the same solution; with the AMGs, nearly the same."""
    _petsc()
    from polypore.solvers.petsc_fieldsplit import PetscBlockContactSolver, PetscBlockPoroSolver

    J, r, nu, d, nl, cond, B, pns, _ = poro_system()
    po = nu + nl
    lu = {"fieldsplit_m_fieldsplit_u_pc_type": "lu", "fieldsplit_m_fieldsplit_p_pc_type": "lu"}
    runs = {}
    for structure in ("condensed", "fieldsplit"):
        extra = {"pc_type": "fieldsplit"} if structure == "fieldsplit" else {}
        for sub, opts in (("lu", lu), ("amg", {})):
            s = PetscBlockPoroSolver(nu, d, nl, cond, near_nullspace=B, rtol=1e-10, options={**opts, **extra})
            s.pressure_nullspace = pns
            runs[structure, sub] = (s.solve(J, r), s.iterations[-1])
        c = PetscBlockContactSolver(nu, d, cond, near_nullspace=B, rtol=1e-10,
                                    options={"fieldsplit_u_pc_type": "lu", **extra})
        runs[structure, "contact"] = (c.solve(sp.csr_matrix(J[:po, :po]), r[:po]), c.iterations[-1])
    for sub in ("lu", "contact"):
        (xc, ic), (xf, if_) = runs["condensed", sub], runs["fieldsplit", sub]
        assert ic == if_, (sub, ic, if_)
        assert np.linalg.norm(xc - xf) <= 1e-8 * np.linalg.norm(xf)
    assert abs(runs["condensed", "amg"][1] - runs["fieldsplit", "amg"][1]) <= 2


@pytest.mark.parametrize("structure", ["condensed", "fieldsplit"])
def test_time_split_counts_each_second_once(structure):
    """The preconditioner set-up and the Krylov iterations of a solve, as the time split records
    them, fit in the solve's wall time (a set-up timed inside another was counted twice)."""
    _petsc()
    import time

    from polypore.solvers.petsc_fieldsplit import PetscBlockPoroSolver
    from polypore.core.timing import SPLIT

    J, r, nu, d, nl, cond, B, pns, _ = poro_system()
    s = PetscBlockPoroSolver(nu, d, nl, cond, near_nullspace=B, pressure_nullspace=pns,
                             options={"pc_type": "fieldsplit"} if structure == "fieldsplit" else None)
    s.solve(J, r)                                   # first solve: the structures are built
    SPLIT.reset()
    t0 = time.perf_counter()
    s.solve(J, 0.5 * r)
    wall = time.perf_counter() - t0
    assert SPLIT.wall["preconditioner"] > 0 and SPLIT.wall["krylov"] > 0
    assert SPLIT.wall["preconditioner"] + SPLIT.wall["krylov"] <= wall


@pytest.mark.parametrize("amg", ["gamg", "hypre"])
@pytest.mark.parametrize("structure", ["condensed", "fieldsplit"])
def test_block_poro_solver_matches_block_poro(amg, structure):
    _petsc()
    from polypore.solvers.petsc_fieldsplit import PetscBlockPoroSolver

    J, r, nu, d, nl, cond, B, pns, _counts = poro_system()
    ref = spla.spsolve(J.tocsc(), r)
    options = {"ksp_gmres_restart": 60, **({"pc_type": "fieldsplit"} if structure == "fieldsplit" else {})}
    s = PetscBlockPoroSolver(nu, d, nl, cond, near_nullspace=B, rtol=1e-10, amg=amg, options=options)
    s.pressure_nullspace = pns
    x = s.solve(J, r)
    assert np.linalg.norm(J @ x - r) <= 1e-9 * np.linalg.norm(r)
    assert np.linalg.norm(x - ref) <= 1e-6 * np.linalg.norm(ref)
    ref_solver = BlockPoroSolver(nu, d, nl, cond, near_nullspace=B, pressure_nullspace=pns, pressure="amg",
                                 rtol=1e-10)
    ref_solver.solve(J, r)
    assert s.iterations[-1] <= 2 * ref_solver.iterations[-1] + 5
    # the Newton iterations of one step: the pressure set-up is kept, the rest rebuilt
    s.solve(J, 0.5 * r)
    assert s.pressure_builds == 1 and s.stats.setups == 2
    J2 = J.copy()
    J2.data = J2.data.copy()
    po = nu + nl
    F = J2[po:, po:]
    J2 = (J2 + sp.block_diag([sp.csr_matrix((po, po)), 1e-3 * sp.diags(F.diagonal())])).tocsr()  # a new step
    s.solve(J2, r)
    assert s.pressure_builds == 2


def test_block_solvers_keep_iterations_list_semantics():
    """The models read ``solver.iterations`` after a step, like BlockPoroSolver's."""
    _petsc()
    from polypore.solvers.petsc_fieldsplit import PetscBlockPoroSolver

    J, r, nu, d, nl, cond, B, pns, _ = poro_system()
    s = PetscBlockPoroSolver(nu, d, nl, cond, near_nullspace=B, pressure_nullspace=pns)
    k0 = len(s.iterations)
    s.solve(J, r)
    s.solve(J, np.zeros_like(r))
    assert len(s.iterations) == k0 + 2 and s.iterations[-1] == 0 and s.seconds > 0


def _garbage_entries(PETSc, capfd) -> int:
    """Objects waiting in COMM_WORLD's garbage (petsc4py defers their destroy, petsc.collect_garbage)."""
    capfd.readouterr()
    PETSc.garbage_view()
    out = capfd.readouterr().out
    return sum(int(ln.split("Total entries:")[1]) for ln in out.splitlines() if "Total entries:" in ln)


def test_repeated_solves_do_not_pile_up_petsc_objects(capfd):
    """Every Newton iteration's work vectors and null spaces are destroyed: before the fix each solve
    left a full-size vector (and the pressure null space) in petsc4py's deferred garbage, 0.4 GB per
    rank over C5 at 127k cells."""
    PETSc = _petsc()
    from polypore.solvers.petsc import PetscLinearSolver
    from polypore.solvers.petsc_fieldsplit import PetscBlockContactSolver, PetscBlockPoroSolver

    J, r, nu, d, nl, cond, B, pns, _ = poro_system()
    po = nu + nl
    A, b, modes = elasticity(4)
    cases = [(PetscBlockPoroSolver(nu, d, nl, cond, near_nullspace=B, pressure_nullspace=pns), J, r),
             (PetscBlockContactSolver(nu, d, cond, near_nullspace=B), sp.csr_matrix(J[:po, :po]), r[:po]),
             (PetscLinearSolver(symmetric=True, near_nullspace=modes), A, b)]
    for s, K, rhs in cases:
        counts = []
        for k in range(6):
            s.solve(K, (1.0 + k) * rhs)
            counts.append(_garbage_entries(PETSc, capfd))
        assert counts[-1] <= counts[1], (type(s).__name__, counts)


def test_block_petsc_runs_a_coupled_case_with_the_newton_history_of_block_amg(tmp_path):
    """solver.linear = "block-petsc" through the case file: with the fixed linear tolerance
    (solver.forcing = "fixed"), the same Newton iterations and contact states per step as block-amg
    on a small 3D poromechanics case; with Eisenstat–Walker forcing (the default; PETSc tests it in
    the plain 2-norm, block-amg in Newton's weighted norm) the same contact states, Newton counts
    within one per step. A misspelt PETSc option is an input error naming it."""
    pytest.importorskip("petsc4py.PETSc")
    import json
    import subprocess
    import sys

    def run(linear, *extra):
        out = tmp_path / f"{linear}{len(list(tmp_path.iterdir()))}"
        cmd = [sys.executable, "-m", "polypore", "-q", "run", "dfm-3d", "--out", str(out), "--set", "mesh.size=0.2",
               "--set", "time.end=4", "--set", "time.output_times=[4.0]", "--set", f"solver.linear={linear}", *extra]
        return subprocess.run(cmd, capture_output=True, text=True, timeout=600), out

    hist = {}
    for forcing in ("fixed", "eisenstat-walker"):
        for linear in ("block-amg", "block-petsc"):
            proc, out = run(linear, "--set", f"solver.forcing={forcing}")
            assert proc.returncode == 0, proc.stderr
            steps = json.loads((out / "summary.json").read_text())["steps"]
            hist[linear, forcing] = [(s["newton_iterations"], s["open"], s["stick"], s["slip"]) for s in steps]
    assert hist["block-petsc", "fixed"] == hist["block-amg", "fixed"]
    ew_amg, ew_petsc = hist["block-amg", "eisenstat-walker"], hist["block-petsc", "eisenstat-walker"]
    assert [h[1:] for h in ew_petsc] == [h[1:] for h in ew_amg]
    assert all(abs(a[0] - b[0]) <= 1 for a, b in zip(ew_amg, ew_petsc)), (ew_amg, ew_petsc)
    proc, _ = run("block-petsc", "--set", "solver.petsc.ksp_typo=1")
    assert proc.returncode == 2 and "ksp_typo" in proc.stderr and "Traceback" not in proc.stderr
    # an option of the coupled fieldsplit only (its inner pressure split) is valid: the table also
    # reaches the initial-state contact solve and the flow solve, which do not read it (SharedOptions)
    proc, _ = run("block-petsc", "--set", "solver.petsc.fieldsplit_m_fieldsplit_p_pc_gamg_threshold=0.02")
    assert proc.returncode == 0, proc.stderr
    proc, _ = run("block-petsc", "--set", "solver.petsc.fieldsplit_m_fieldsplit_p_pc_gamg_threshhold=0.02")
    assert proc.returncode == 2 and "threshhold" in proc.stderr and "Traceback" not in proc.stderr


def test_a_case_names_the_option_as_the_case_file_does(tmp_path, capsys):
    """The solver raises in its own terms (``petsc_options.ksp_rtoll``); the run translates what
    its solve raises to the case-file key (setup/translate.py, RUN_MECHANICS)."""
    _petsc()
    from polypore.cli import main

    code = main(["run", "single-crack", "--out", str(tmp_path / "r"), "--set", "solver.linear=petsc",
                 "--set", "solver.petsc.ksp_rtoll=1e-3"])
    err = capsys.readouterr().err
    assert code == 2 and "solver.petsc.ksp_rtoll" in err and "did not use" in err, err
