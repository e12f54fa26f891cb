"""The built-in rate-state-slider case (issue 28): a rate-and-state fault dragged at V_L relaxes to
steady sliding, every face at V_L with friction f₀ + (a − b) ln(V_L/V₀) (docs/rate_state_design.md),
for both state laws; the run's outputs carry the law's state."""

import glob

import meshio
import numpy as np
import pytest

from polypore.runs.dispatch import run_case
from polypore.setup.casefile import load_case

F0, A, B, V0, VL = 0.6, 0.015, 0.010, 1e-5, 1e-6
MU_S = 2.0e10 / (2 * 1.25)            # E/(2(1 + ν)), Pa
ETA = MU_S / (2 * 3000.0)             # radiation damping, Pa·s/m


def _final_faces(out):
    last = sorted(glob.glob(str(out / "fractures_*.vtu")))[-1]
    return {k: v[0] for k, v in meshio.read(last).cell_data.items()}


@pytest.mark.parametrize("state_law", ["aging", pytest.param("slip", marks=pytest.mark.slow)])
def test_steady_sliding_friction(tmp_path, state_law):
    case = load_case("rate-state-slider", overrides=["mesh.size=20", "mesh.fracture_size=20",
                                                     "time.rate_tolerance=0.2", f"contact.state_law={state_law}"])
    summary = run_case(case, tmp_path)
    f = _final_faces(tmp_path)
    V, ln, lt = f["slip_rate"], f["lambda_n"], f["lambda_t"]
    assert np.allclose(V, VL, rtol=1e-8)
    mu_ss = F0 + (A - B) * np.log(VL / V0)
    # the face balance with the faded damping (σ′ ≫ 1 kPa here: the fade is below 1e-4)
    assert np.allclose((lt - ETA * V) / ln, mu_ss, rtol=1e-6)
    assert np.allclose(f["friction_coefficient"], mu_ss, rtol=1e-10)
    assert np.all(f["state_theta"] == pytest.approx(1e-4 / VL, rel=1e-8))      # θ_ss = D_c/V_L
    assert summary["energy_check"]["violations"] == []
    steps = summary["steps"]
    assert steps[-1]["slip"] == len(V) and steps[0]["slip"] == 0
    # velocity strengthening (a > b): no event, all the slip aseismic, in the catalogue's moment
    seis = summary["seismicity"]
    assert seis["events"] == 0 and (tmp_path / "events.csv").read_text().startswith("fault,onset_s")
    assert seis["aseismic_moment"]["fault"] > 0
    # the seismicity series and figure; nothing injected here
    rows = (tmp_path / "seismicity.csv").read_text().splitlines()
    assert rows[0].startswith("time_s,injected_volume,seismic_moment,aseismic_moment,peak_slip_rate_fault")
    last = [float(v) for v in rows[-1].split(",")]
    assert last[0] == pytest.approx(1e5) and last[1] == 0.0 and last[2] == 0.0
    assert last[3] == pytest.approx(seis["aseismic_moment"]["fault"], rel=1e-8)
    assert last[4] == pytest.approx(VL, rel=1e-8)
    assert (tmp_path / "seismicity.png").stat().st_size > 0
    # ΔCFS since the start with μ = f₀: the fault loaded in shear at constant σ′
    first = {k: v[0] for k, v in meshio.read(sorted(glob.glob(str(tmp_path / "fractures_*.vtu")))[0]).cell_data.items()}
    expected = (lt - first["lambda_t"]) - F0 * (ln - first["lambda_n"])
    assert np.allclose(f["delta_cfs"], expected, rtol=1e-9, atol=1e-3)
    assert np.all(f["delta_cfs"] > 0) and np.allclose(f["slip_tendency"], lt / ln, rtol=1e-12)
