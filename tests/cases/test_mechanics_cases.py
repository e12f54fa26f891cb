"""Static contact cases through the command line: results, convergence rates, bad input."""

import csv
import json

import numpy as np
import pytest

from polypore.runs.convergence import fit_rate, refined
from polypore.runs.static import solve_static
from polypore.setup.casefile import load_case


def test_c1_cartesian_converges_first_order():
    """C1 on Cartesian hexahedra (4³, 8³, 12³ cells): ‖∇^D u − ∇u‖ and the λ errors decrease at rate ≥ 0.9."""
    hs, eg, el = [], [], []
    for n in (4, 8, 12):
        case = load_case("frictionless-3d", ["mesh.generator=cartesian", f"mesh.cells=[{n},{n},{n}]"])
        problem, st, _, err, _ = solve_static(case)
        hs.append(problem.fm.mesh.geometry.cell_diameter.max())
        eg.append(err["grad_u_L2"])
        el.append(err["lambda_L2"])
    assert fit_rate(hs, eg) >= 0.9
    assert fit_rate(hs, el) >= 0.9
    assert eg[-1] < eg[0] / 2.5


def test_refined_case_halves_sizes_or_doubles_cells():
    c = load_case("frictionless-3d", ["mesh.size=0.5"])
    assert refined(c, 2).data["mesh"]["size"] == 0.125
    c = load_case("frictionless-3d", ["mesh.generator=cartesian", "mesh.cells=[2,3,4]"])
    assert refined(c, 1).data["mesh"]["cells"] == [4, 6, 8]


def test_six_fractures_static_shows_all_states(tmp_path, cli):
    out = tmp_path / "six"
    code, text, err = cli("run", "six-fractures-static", "--out", str(out), "--set", "mesh.size=0.1",
                          "--set", "mesh.fracture_size=0.04")
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    step = summary["steps"][-1]
    assert step["open"] > 0 and step["stick"] > 0 and step["slip"] > 0
    assert step["residual"] < 1e-8
    rows = list(csv.DictReader((out / "fractures.csv").open()))
    assert len(rows) == summary["mesh"]["fracture_faces"]
    assert {r["state"] for r in rows} == {"open", "stick", "slip"}
    # F6 (isolated, pulled apart by the shear) is open: λ = 0 and [[u]]_n < 0 there
    f6 = [r for r in rows if r["fracture"] == "F6"]
    assert all(r["state"] == "open" and float(r["jump_n"]) < 0 and abs(float(r["lambda_n"])) < 1e-3 for r in f6)
    # Coulomb: |λ_τ| ≤ F λ_n everywhere (F ≥ 0.5), with equality on slipping faces
    for r in rows:
        assert float(r["lambda_t"]) <= 5.5 * max(float(r["lambda_n"]), 0) + 1e-3
    for name in ("bulk_0000.vtu", "fractures_0000.vtu", "solution.pvd", "profiles.png", "contact_states.png",
                 "case.toml"):
        assert (out / name).stat().st_size > 0
    assert not list(out.glob(".partial-*"))


def test_single_crack_against_analytic_profile():
    """C3 as built in (mirrored band, two-sided bubbles): λ_n exact to the finite-domain floor
    over the whole crack, slip converging; on a general mesh λ_n is off next to the tips."""
    errs = []
    for fs in (0.1, 0.05):
        case = load_case("single-crack", [f"mesh.fracture_size={fs}", "mesh.size=8"])
        _, st, _, err, _ = solve_static(case)
        errs.append(err)
    assert errs[1]["slip_L2_rel"] < errs[0]["slip_L2_rel"] < 0.12
    assert errs[1]["slip_L2_rel"] < 0.07
    assert max(e["lambda_n_L2_rel"] for e in errs) < 1e-3
    general = []
    for fs in (0.1, 0.05):
        case = load_case("single-crack", [f"mesh.fracture_size={fs}", "mesh.size=8", "mesh.mirror=none"])
        general.append(solve_static(case)[3])
    assert general[1]["lambda_n_L2_rel_away_from_tips"] < general[0]["lambda_n_L2_rel_away_from_tips"] < 0.1
    assert min(e["lambda_n_L2_rel"] for e in general) > 0.02  # the tip faces: see docs/contact.md
    # mirrored patches at the tips only: λ_n over the whole crack converges
    tips = []
    for fs in (0.1, 0.05):
        case = load_case("single-crack", [f"mesh.fracture_size={fs}", "mesh.size=8", "mesh.mirror=tips"])
        tips.append(solve_static(case)[3])
    assert tips[1]["lambda_n_L2_rel"] < 0.7 * tips[0]["lambda_n_L2_rel"]
    assert tips[1]["lambda_n_L2_rel"] < 0.5 * general[1]["lambda_n_L2_rel"]


def test_convergence_command_writes_table(tmp_path, cli):
    out = tmp_path / "conv"
    code, text, err = cli("convergence", "frictionless-3d", "--levels", "2", "--out", str(out),
                          "--set", "mesh.generator=cartesian", "--set", "mesh.cells=[2,2,2]")
    assert code == 0, err
    res = json.loads((out / "convergence.json").read_text())
    assert res["case"] == "frictionless-3d" and len(res["levels"]) == 2
    assert {"grad_u_L2", "lambda_L2", "lambda_h12"} <= set(res["rates"])
    assert (out / "convergence.csv").exists() and (out / "convergence.png").exists()
    assert "fitted rates" in text


C3_BAD = [
    (["contact.law=sticky"], "contact.law", "allowed: frictionless, tresca, coulomb"),
    (["contact.friction=-0.2"], "contact.friction", "≥ 0"),
    (["material.E=-1e9"], "material.E", "positive"),
    (["material.nu=0.5"], "material.nu", "(−1, 0.5)"),
    (["mechanics.boundary.xmin.name=west"], "mechanics.boundary", "unknown boundary 'west'"),
    (["mechanics.boundary.xmax.traction=['-sigma * (1 + ', 0]"], "mechanics.boundary.xmax.traction", "does not parse"),
    (["mechanics.boundary.xmax.traction=['-sigma * w', 0]"], "mechanics.boundary.xmax.traction", "unknown name 'w'"),
    (["contact.friction=tan(30"], "contact.friction", "does not parse"),
]


@pytest.mark.parametrize("overrides,field,msg", C3_BAD)
def test_bad_mechanics_input_exit_2(tmp_path, cli, overrides, field, msg):
    argv = ["run", "single-crack", "--out", str(tmp_path / "o"), "--set", "mesh.size=20", "--set",
            "mesh.fracture_size=0.5"]
    for o in overrides:
        argv += ["--set", o]
    code, _, err = cli(*argv)
    assert code == 2, err
    assert field in err and msg in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_no_dirichlet_part_is_rejected(tmp_path, cli):
    case = tmp_path / "free.toml"
    case.write_text("""
name = "free"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [4, 4]
[material]
E = 1e9
nu = 0.25
[[mechanics.boundary]]
name = "xmax"
traction = [-1e6, 0]
[contact]
law = "frictionless"
""")
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "o"))
    assert code == 2 and "mechanics.boundary" in err and "rigid motions are free" in err


@pytest.mark.parametrize("case_name,bubbles", [("coulomb-2d", "one-sided"), ("tresca-2d", "two-sided")])
def test_c2_manufactured_2d_converges_with_all_states(case_name, bubbles):
    """C2 in 2D (sizes 0.2, 0.1, 0.05): all three states, fitted rates ≥ 0.9 for ∇u and λ."""
    hs, eg, el, states = [], [], [], set()
    for size in (0.2, 0.1, 0.05):
        case = load_case(case_name, [f"mesh.size={size}", f"mechanics.bubbles={bubbles}"])
        problem, st, _, err, _ = solve_static(case)
        hs.append(problem.fm.mesh.geometry.cell_diameter.max())
        eg.append(err["grad_u_L2"])
        el.append(err["lambda_L2"])
        states |= set(np.unique(st.state).tolist())
    assert states == {0, 1, 2}
    assert fit_rate(hs, eg) >= 0.9
    assert fit_rate(hs, el) >= 0.9


def test_convergence_table_flags_a_rising_error_and_reports_last_pair_rates():
    """Issue 25: `polypore convergence coulomb-2d --levels 4` printed fitted rates 1.19 / 1.67
    while the finest level's error rose (pair rate −0.45), and nothing said so."""
    from polypore.runs.convergence import format_table, rate_summary

    hs = [0.4, 0.2, 0.1, 0.05]
    errors = {"lambda_n_h12": [1.0, 0.3, 0.11, 0.15], "grad_u_L2": [1.0, 0.5, 0.25, 0.125]}
    info = rate_summary(hs, errors)
    assert info["rising"] == {"lambda_n_h12": [3]}
    assert info["last_pair_rates"]["lambda_n_h12"] == pytest.approx(-0.4475, abs=1e-3)
    assert info["last_pair_rates"]["grad_u_L2"] == pytest.approx(1.0)
    levels = [{"level": k, "h": h, "unknowns": 10 * 4 ** k, "errors": {n: e[k] for n, e in errors.items()}}
              for k, h in enumerate(hs)]
    text = format_table({"levels": levels, **info})
    assert "(-0.45)!" in text and "( 1.00) " in text
    assert "last-pair rates: lambda_n_h12 -0.45, grad_u_L2 1.00 (levels 2-3)" in text
    assert "warning: lambda_n_h12 is not monotone: it rises at levels 2->3" in text
    assert "warning: grad_u_L2" not in text
