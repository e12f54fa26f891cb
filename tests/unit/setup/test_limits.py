"""Resource guards (issue 14): cells, unknowns, time steps and memory estimated before any work,
refused with the field and the override flag named, and nothing written."""

import math

import pytest

from polypore.core.errors import InputError
from polypore.setup import limits
from polypore.setup.casefile import load_case
from polypore.setup.limits import check_limits, estimate

from conftest import STATIC_2D

FLOW = """
name = "f"
model = "flow"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [2, 2]
[flow]
permeability = 1e-12
biot_modulus = 1e9
initial_pressure = 0.0
[[flow.boundary]]
name = "xmin"
pressure = 1e5
[time]
end = 10.0
step = 1.0
"""


def test_a_tiny_time_step_over_a_year_is_refused_before_any_work(tmp_path, cli):
    out = tmp_path / "o"
    code, _, err = cli("run", "fault-injection", "--set", "time.end=31557600", "--set", "time.step=1e-12",
                       "--set", "time.output_times=[31557600]", "--out", str(out))
    assert code == 2 and err.startswith("polypore: error: time.step: 1e-12 s from 0 to 3.15576e+07 s is 3.16e+19 "
                                        "time steps; allowed: at most 1,000,000"), err
    assert "--no-limits" in err and "Traceback" not in err and not out.exists()


def test_convergence_levels_beyond_the_machine_are_refused(tmp_path, cli):
    out = tmp_path / "o"
    code, _, err = cli("convergence", "coulomb-2d", "--levels", "30", "--out", str(out))
    assert code == 2 and err.startswith("polypore: error: --levels: the run would need about ") and "cells" in err
    assert "this machine has" in err and "--no-limits" in err and not out.exists()
    # the same study with 3 levels fits
    assert check_limits(load_case("coulomb-2d").spec, levels=3).cells < 1e5


def test_a_mesh_beyond_the_machine_is_refused_by_mesh_and_run(tmp_path, cli):
    for command in ("mesh", "run"):
        code, _, err = cli(command, "cube-slip-3d", "--set", "mesh.size=1e-4", "--out", str(tmp_path / command))
        assert code == 2 and err.startswith("polypore: error: mesh.size: the run would need about ") and \
            "--no-limits" in err, err
        assert not (tmp_path / command).exists()


def test_no_limits_runs_anyway(tmp_path, cli, monkeypatch):
    case = tmp_path / "f.toml"
    case.write_text(FLOW)
    monkeypatch.setattr(limits, "MAX_STEPS", 5)
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "a"))
    assert code == 2 and "time.step: 1 s from 0 to 10 s is 10 time steps; allowed: at most 5" in err, err
    code, text, err = cli("run", str(case), "--out", str(tmp_path / "b"), "--no-limits")
    assert code == 0 and "10 time steps" in text, err
    # the mesh command has no time loop: the step count does not limit it
    code, _, err = cli("mesh", str(case), "--out", str(tmp_path / "c"))
    assert code == 0, err


def test_estimates_follow_the_meshes(tmp_path):
    """The cell estimates of the built-in meshes lie within a factor 2 of the meshes' cells (the
    guard only has to tell a run that fits from one that tries to allocate terabytes)."""
    from polypore.setup.meshing import build_fractured_mesh

    for name, overrides in (("darcy-dfm-2d", []), ("fault-injection", []), ("coulomb-3d", []),
                            ("frictionless-3d", ["mesh.generator=cartesian", "mesh.cells=[5, 6, 7]"]),
                            ("darcy-manufactured-2d", ["mesh.size=0.05"]),
                            ("single-crack", ["mesh.fracture_size=0.1"]),          # graded about a 2D crack
                            ("penny-pressurised", ["fractures.crack.sides=8", "mesh.fracture_size=0.8"]),
                            # r^(2/3) towards the tip lines (for P2): 2x the cells of the sqrt law
                            ("cube-slip-3d", ["mesh.front=isotropic", "mesh.grading=0.4", "mesh.size=0.48",
                                              "mesh.fracture_size=0.128", "mesh.tip_size=0.012",
                                              "mesh.tip_grading=0.7"]),
                            # anisotropic crack-front tubes (the case's default) and a finer one
                            ("cube-slip-3d", []),
                            ("cube-slip-3d", ["mesh.fracture_size=0.175", "mesh.tip_size=0.0025"])):
        case = load_case(name, overrides)
        est = estimate(case.spec)
        cells = build_fractured_mesh(case).mesh.n_cells
        assert cells / 2 < est.cells < 2 * cells, (name, est.cells, cells)
        assert est.unknowns > 0.5 * est.cells and est.steps >= 1 and est.memory > limits.BASE_BYTES
    path = tmp_path / "t.toml"
    path.write_text(STATIC_2D)
    spec = load_case(str(path)).spec
    assert estimate(spec).cells == 16 and estimate(spec, levels=3).cells == 16 * 4 ** 2
    assert estimate(load_case("dfm-2d").spec).steps == 100 + 4          # the steps and the output times


def test_guard_limits_are_parameters():
    spec = load_case("dfm-2d").spec
    with pytest.raises(InputError, match=r"^mesh.size: the mesh would have about .* cells; allowed here: at most "
                       "100; --no-limits runs it anyway"):
        check_limits(spec, max_cells=100)
    with pytest.raises(InputError, match=r"^mesh.size: the run would need about .*; this machine has 1 KB"):
        check_limits(spec, memory=1024)
    assert check_limits(spec, memory=math.inf).steps == 104


def test_a_tiny_tip_size_of_anisotropic_fronts_is_refused_up_front(tmp_path, cli):
    """Issue 25: cube-slip-3d with mesh.tip_size = 1e-7 gave no output for 300 s. The generator
    sweeps 257 rings over ~1500 layers per edge there (graded_positions floors the layers at
    tip_size near the corners); the estimate counted 2 layers per edge (length / fracture_size)."""
    est = estimate(load_case("cube-slip-3d", ["mesh.tip_size=1e-7"]).spec)
    assert est.field == "mesh.tip_size" and est.cells > 1e7, est
    out = tmp_path / "o"
    code, _, err = cli("mesh", "cube-slip-3d", "--set", "mesh.tip_size=1e-7", "--out", str(out))
    assert code == 2 and err.startswith("polypore: error: mesh.tip_size: the run would need about "), err
    assert "e+08 cells" in err and "--no-limits" in err and not out.exists()


def test_a_tilted_cornerpoint_grid_is_estimated_by_its_cells():
    spec = load_case("cornerpoint-injection", ["mesh.pillar_angle=60", "mesh.pinchout=[2]"]).spec
    est = check_limits(spec)
    assert est.cells == 20 * 10 * 8 and est.field == "mesh.cells" and est.unknowns > est.cells


def test_a_fracture_reaching_far_outside_is_estimated_without_allocating_its_front():
    # a fuzzed vertex at x = 1e9 m: the front-tube estimate counted the generator's layers by making
    # them (1e10 positions, the fuzz run was killed for memory); counted now, and refused
    from polypore.mesh.generators.fronts import graded_count, graded_positions

    assert graded_count(1.0, 0.5, 0.15, 0.6, 0.04) == len(graded_positions(1.0, 0.5, 0.15, 0.6, 0.04)) - 1
    assert graded_count(1e9, 0.5, 0.15, 0.6, 0.04) > 1e8          # counted in microseconds, nothing made
