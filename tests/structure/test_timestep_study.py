"""benchmarks/timestep_study.py's measures on a hand-made fractures.csv (two faces, three times)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _module(name: str = "timestep_study"):
    """A benchmarks/ script imported as a module."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_slipped_and_slip_state_areas_max_slip_and_pressures(tmp_path):
    rows = ["step,time,fracture,face,area,jump_t,state,p_f,lambda_n,lambda_t"]
    # face 0: 30 m², slips 2 mm by day 5 then sticks; face 1: 10 m², 0.05 mm (below 0.1 mm) but sliding
    for k, (t, s0, s1, st0, st1, p0, p1) in enumerate([(0, 0, 0, "stick", "stick", 0, 0),
                                                       (5, 2e-3, 0, "slip", "stick", 1e6, 2e6),
                                                       (10, 2e-3, 5e-5, "stick", "slip", 3e6, 1e6)]):
        rows += [f"{k},{t * 86400.0},F,0,30,{s0},{st0},{p0},1,0", f"{k},{t * 86400.0},F,1,10,{s1},{st1},{p1},1,0"]
    (tmp_path / "fractures.csv").write_text("\n".join(rows) + "\n")
    m = _module().measures(tmp_path, np.array([0.0, 5.0, 10.0]) * 86400.0, slipped_mm=0.1)["F"]
    assert m["max_slip"] == [0.0, 2e-3, 2e-3]
    assert m["slipped_area"] == [0.0, 0.75, 0.75]
    assert m["slip_state_area"] == [0.0, 0.75, 0.25]
    assert m["max_p_f"] == [0.0, 2e6, 3e6]
    assert m["mean_p_f"] == pytest.approx([0.0, 1.25e6, 2.5e6])
    with pytest.raises(SystemExit, match="no output at t = 345600 s"):
        _module().measures(tmp_path, np.array([5.0]) * 86400.0 - 86400.0, slipped_mm=0.1)


def test_refinement_averages_the_fine_slip_onto_the_coarse_faces(tmp_path):
    """fault_bounds.py --refinement: each fine face goes to the nearest coarse face of its fault;
    the fine slip averaged by area there is compared with the coarse slip, and potencies."""
    head = "step,time,fracture,face,x,y,z,area,jump_t,state,p_f,lambda_n,lambda_t"

    def write(folder, faces):                      # faces: (x, area, slip at t = 1 day)
        folder.mkdir()
        rows = [head]
        for k, t in enumerate((0.0, 86400.0)):
            rows += [f"{k},{t},F,{i},{x},0,0,{a},{s * k},stick,0,1,0" for i, (x, a, s) in enumerate(faces)]
        (folder / "fractures.csv").write_text("\n".join(rows) + "\n")

    write(tmp_path / "c", [(0.0, 2.0, 1e-3), (1.0, 2.0, 3e-3)])
    write(tmp_path / "f", [(-0.25, 1.0, 0.0), (0.25, 1.0, 2e-3), (0.75, 0.5, 6e-3), (1.25, 1.5, 2e-3)])
    r = _module("fault_bounds").refinement(tmp_path / "c", tmp_path / "f")["F"]
    assert r["time_s"] == [0.0, 86400.0]
    assert r["max_slip_coarse"][1] == 3e-3 and r["max_slip_fine"][1] == 6e-3
    # coarse face 0 gets (0 + 2e-3)/2 = 1e-3, face 1 (0.5·6e-3 + 1.5·2e-3)/2 = 3e-3
    assert r["max_slip_fine_on_coarse"][1] == pytest.approx(3e-3)
    assert r["potency_coarse"][1] == pytest.approx(8e-3) and r["potency_fine"][1] == pytest.approx(8e-3)
