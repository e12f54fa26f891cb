"""Poromechanics through the command line (C4 at a coarse mesh): files, energy audit, bad input."""

import csv
import json

import pytest


COARSE = ["--set", "mesh.size=0.2", "--set", "mesh.fracture_size=0.1", "--set", "time.step=250",
          "--set", "time.output_times=[500.0, 2000.0]"]


def test_c4_coarse_run_writes_everything_and_passes_the_energy_check(tmp_path, cli):
    out = tmp_path / "c4"
    code, text, err = cli("run", "dfm-2d", "--out", str(out), *COARSE)
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    assert s["model"] == "poromechanics" and len(s["steps"]) == 8
    assert s["energy_check"]["violations"] == [] and s["energy_check"]["steps_checked"] == 8
    for st in s["steps"]:
        assert st["residual"] < 1e-8
        assert set(st["energy"]) == {"elastic", "storage", "friction_dissipation", "viscous_dissipation",
                                     "source_work"}
    # loading phase (t ≤ T/4): the compression raises the matrix pressure; afterwards it drains
    means = s["fracture_means"]
    assert max(r["F2"][1] for r in means) > 1.2e5 and means[-1]["F2"][1] < max(r["F2"][1] for r in means)
    rows = list(csv.DictReader((out / "fractures.csv").open()))
    assert {r["time"] for r in rows} == {"0", "500", "2000"}
    assert all(r["aperture"] and r["p_f"] for r in rows)
    for name in ("solution.pvd", "bulk_0002.vtu", "fractures_0002.vtu", "overpressure.png", "fracture_means.png",
                 "contact_t500.png", "contact_t2000.png"):
        assert (out / name).stat().st_size > 0


BAD = [
    (["time.end=-5"], "time.end", "does not advance"),
    (["time.output_times=[100.0, 5000.0]"], "time.output_times", "outside the run"),
    (["flow.biot_modulus=-1e10"], "flow.biot_modulus", ""),
    (["model=poromechanics", "flow=0"], "flow", ""),
]


@pytest.mark.parametrize("overrides,field,msg", BAD)
def test_bad_poromechanics_input(tmp_path, cli, overrides, field, msg):
    argv = ["run", "dfm-2d", "--out", str(tmp_path / "o"), *COARSE]
    for o in overrides:
        argv += ["--set", o]
    code, _, err = cli(*argv)
    assert code == 2, err
    assert f"error: {field}" in err and msg in err and "Traceback" not in err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_poromechanics_case_without_flow_table(tmp_path, cli):
    case = tmp_path / "noflow.toml"
    case.write_text("""
name = "noflow"
model = "poromechanics"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [4, 4]
[material]
E = 1e9
nu = 0.25
[[mechanics.boundary]]
name = "ymin"
u = [0, 0]
[time]
end = 10.0
step = 1.0
""")
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "o"))
    assert code == 2 and "error: flow" in err and "flow data" in err


def test_block_amg_coupled_solver_matches_the_direct_solver():
    """GMRES with AMG blocks (condensed mechanics, fixed-stress-type pressure Schur) gives the
    direct solver's Newton iterates on a small C5 (3D, four fractures) with the fixed linear
    tolerance; with Eisenstat–Walker forcing (the default) the steps are inexact Newton steps, and
    the states agree to the Newton tolerance with at most one more iteration per step."""
    import numpy as np

    pytest.importorskip("pyamg")
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh
    from polypore.setup.poromechanics import poro_setup

    states, counts, gmres = {}, {}, {}
    for lin, forcing in (("superlu", "fixed"), ("block-amg", "fixed"), ("block-amg", "eisenstat-walker"),
                         ("block-direct", "eisenstat-walker")):
        # order 1: the tolerances below are the nodal space's (with the default "auto", order 2 on
        # these tetrahedra, block-amg gives the direct solver's states and displacements to 1e-7 and
        # its pressures to 1.6e-7 of their maximum)
        case = load_case("dfm-3d", ["mesh.size=0.25", "mechanics.order=1", f"solver.linear={lin}",
                                    f"solver.forcing={forcing}"])
        fm = build_fractured_mesh(case)
        model, fs, _ = poro_setup(case, fm)
        st = model.initial_state(fs.initial_pressure)
        its, lits = [], []
        for k in range(2):
            st, info = model.step(st, 2.0, 2.0 * (k + 1))
            its.append(info.iterations)
            lits += info.linear_iterations
            if lin.startswith("block"):
                assert st.state.tolist().count(2) > 0          # slipping faces are present
                assert max(info.linear_iterations) <= 40, info.linear_iterations
        states[lin, forcing], counts[lin, forcing], gmres[lin, forcing] = st, its, sum(lits)
    ref = states["superlu", "fixed"]
    assert counts["block-amg", "fixed"] == counts["superlu", "fixed"]
    assert all(0 <= b - a <= 1 for a, b in zip(counts["superlu", "fixed"], counts["block-amg", "eisenstat-walker"]))
    assert all(0 <= b - a <= 1 for a, b in zip(counts["superlu", "fixed"], counts["block-direct", "eisenstat-walker"]))
    # the factorised displacement block leaves only the fixed-stress split to iterate on
    assert gmres["block-direct", "eisenstat-walker"] <= gmres["block-amg", "eisenstat-walker"]
    assert gmres["block-amg", "eisenstat-walker"] < 0.7 * gmres["block-amg", "fixed"]
    for key in (("block-amg", "fixed"), ("block-amg", "eisenstat-walker"), ("block-direct", "eisenstat-walker")):
        st = states[key]
        assert np.array_equal(st.state, ref.state)
        assert np.abs(st.u - ref.u).max() <= 1e-7 * np.abs(ref.u).max()
        assert np.abs(st.p - ref.p).max() <= 1e-7 * np.abs(ref.p).max()


def test_contact_condensation_is_symmetric_positive_definite_with_slipping_faces():
    """The preconditioner's condensed block S (solvers/block_contact.py) stays SPD when faces
    slip (the friction–normal coupling is dropped), and eliminates open faces exactly."""
    import numpy as np
    import scipy.sparse as sp

    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh
    from polypore.setup.poromechanics import poro_setup

    case = load_case("dfm-3d", ["mesh.size=0.25"])
    model, fs, _ = poro_setup(case, build_fractured_mesh(case))
    st = model.initial_state(fs.initial_pressure)
    st, _ = model.step(st, 2.0, 2.0)
    ctx, _ = model.step_context(st, 2.0, 4.0)
    x = np.concatenate([st.u.ravel()[model.mech.free], (st.lam / model.mech.law.beta[:, None]).ravel(),
                        st.p[model.flow_free] / ctx.pressure_scale[model.flow_free]])
    lin = model._linearise(x, ctx)
    assert lin.counts["slip"] > 0 and lin.counts["open"] > 0
    J = sp.csr_matrix(lin.jacobian.tocsr())
    nu, nl = model.mech.free.size, model.n_ff * 3
    A, Bt = J[:nu, :nu], J[:nu, nu:nu + nl]
    Cu, Cl = J[nu:nu + nl, :nu], J[nu:nu + nl, nu:nu + nl]
    Cinv, Cu_s, S = model.mech.condensation().condense(A, Bt, Cu, Cl)
    Sd = S.toarray()
    assert np.abs(Sd - Sd.T).max() <= 1e-12 * np.abs(Sd).max()
    assert np.linalg.eigvalsh(Sd).min() > 0
    # open faces: Cl̂⁻¹ is the exact inverse of their block
    op = np.flatnonzero(lin.active_set == 0)
    rows = (op[:, None] * 3 + np.arange(3)).ravel()
    blk = (Cinv[rows][:, rows] @ Cl[rows][:, rows]).toarray()
    assert np.abs(blk - np.eye(len(rows))).max() <= 1e-12
