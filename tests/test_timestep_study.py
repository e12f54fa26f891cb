"""benchmarks/timestep_study.py's measures on a hand-made fractures.csv (two faces, three times)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("timestep_study", ROOT / "benchmarks" / "timestep_study.py")
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
