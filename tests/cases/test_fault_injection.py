"""Case C6 (fault reactivation by injection): the in-situ reference state is an equilibrium,
injection reactivates the fault where it crosses the reservoir, and bad input exits 2."""

import numpy as np
import pytest

from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh
from polypore.setup.poromechanics import poro_setup

COARSE = ["mesh.size=200", "mesh.fracture_size=80"]


def _model(*overrides):
    case = load_case("fault-injection", [*COARSE, *overrides])
    fm = build_fractured_mesh(case)
    model, fs, _ = poro_setup(case, fm)
    return model, fs


def test_reference_state_is_an_equilibrium_without_injection():
    """No injection: every step leaves displacement increments, slip and overpressure at
    round-off; the fault carries the in-situ effective traction and sticks."""
    model, fs = _model("parameters.mass_rate=0.0")
    st0 = model.reference_state(fs.initial_pressure)
    ln = np.einsum("fi,fi->f", st0.lam, model.mech.normal)
    assert np.all(ln > 1e6)                                    # effectively compressed (Pa)
    st = st0
    for _ in range(3):
        st, info = model.step(st, 432000.0)
        assert info.slip == 0 and info.open == 0
    assert np.abs(st.u).max() < 1e-14                          # m (displacements of the injection run: ~1e-2)
    assert np.abs(st.p).max() < 1e-6                           # Pa
    assert np.abs(st.lam - st0.lam).max() < 1e-9 * np.abs(st0.lam).max()


def test_injection_run_reactivates_the_fault_in_the_reservoir(tmp_path, cli):
    """Coarse `polypore run fault-injection`: slip starts on faces at reservoir depth after the
    pressure has risen, spreads, and every C6 output is written; no energy violation."""
    import json

    out = tmp_path / "c6"
    code, _, err = cli("run", "fault-injection", "--out", str(out), *[a for o in COARSE for a in ("--set", o)])
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    on = s["slip_onset"]
    assert on is not None and 50 * 86400 < on["time"] < 250 * 86400
    depth = -np.array(on["first_slipping_faces"])[:, 1]
    assert np.all((depth > 1350) & (depth < 1650)), depth
    m = s["monitor"]
    assert m["overpressure_at_points"]["injection"][-1] > 5e6
    slip = np.array(m["max_slip"]["fault"])
    assert slip[-1] > 10 * slip[np.searchsorted(m["time"], on["time"])] > 0      # grows after onset
    assert s["steps"][-1]["slip"] > on["faces"]                                   # spreads
    assert s["energy_check"]["violations"] == []
    for name in ("monitor.png", "slip_profiles.png", "overpressure.png", "solution.pvd", "fractures.csv"):
        assert (out / name).stat().st_size > 0


@pytest.mark.parametrize("overrides,field,msg", [
    (["initial_state.stress_ratio=0"], "initial_state.stress_ratio", "must be positive, got 0"),
    (["initial_state.stress_ratio=-0.7"], "initial_state.stress_ratio", "must be positive, got -0.7"),
    (["regions.upper_aquifer.lower=[0.0, -1200.0]"], "regions", "do not cover the domain"),
    (["flow.boundary.injection.name=nowhere"], "flow.boundary.nowhere.name", "unknown boundary"),
    (["boundaries.injection.on=west"], "boundaries.injection.on", "unknown boundary part"),
    (["flow.porosity.reservoir=1.5"], "flow.porosity.reservoir", "(0, 1]"),
    (["initial_state.surface=-1000"], "initial_state.surface", "depth must be ≥ 0"),
    (["initial_state.stress_ratio=0.3"], "initial_state", "not an equilibrium"),
])
def test_bad_fault_injection_input(tmp_path, cli, overrides, field, msg):
    args = [a for o in [*COARSE, *overrides] for a in ("--set", o)]
    code, _, err = cli("run", "fault-injection", "--out", str(tmp_path / "x"), *args)
    assert code == 2, err
    assert f"error: {field}" in err and msg in err, err
    assert not (tmp_path / "x" / "summary.json").exists()


def test_mass_rate_equals_the_volume_rate_times_density_and_takes_a_schedule():
    from polypore.setup.flow import flow_setup

    case = load_case("fault-injection", [*COARSE])
    fm = build_fractured_mesh(case)
    data = {k: v for k, v in case.data.items() if k not in ("mechanics", "material", "contact", "initial_state",
                                                            "monitor", "model")}
    from polypore.setup.casefile import CaseFile

    def flux(b):
        d = dict(data, flow=dict(data["flow"], boundary=[b, {"name": "ymax", "pressure": 0.0}]))
        return flow_setup(CaseFile("x", None, d), fm).boundary["injection"].value

    q_mass = flux({"name": "injection", "mass_rate": 0.02})
    q_vol = flux({"name": "injection", "rate": 2e-5})
    assert q_mass == pytest.approx(q_vol, rel=1e-12) and q_vol == pytest.approx(-2e-5 / 100.0, rel=1e-9)
    shut = flux({"name": "injection", "mass_rate": "0.02 * (t < 100 * day)"})
    x = np.zeros(3)
    assert shut(x, x, x, 50 * 86400.0)[0] == pytest.approx(q_mass) and shut(x, x, x, 150 * 86400.0)[0] == 0.0


def test_conductivity_growth_flags_the_step_of_a_dilatant_onset(tmp_path, cli):
    """The fluxes lag one step (scheme.md §6): a step in which dilatancy raises a face's C_f by
    orders of magnitude is reported (StepInfo.conductivity_growth, summary.json) and warned of
    once; before the onset C_f does not change (growth 1); without dilatancy it never grows."""
    import json

    model, fs = _model()
    st = model.reference_state(fs.initial_pressure)
    growth, slip = [], []
    for _ in range(8):
        st, info = model.step(st, 30 * 86400.0)
        growth.append(info.conductivity_growth)
        slip.append(info.slip)
    first = next(k for k, n in enumerate(slip) if n > 0)
    assert np.allclose(growth[:first], 1.0, rtol=1e-9, atol=0)
    assert growth[first] > 10                          # 10 µm → 0.1-1 mm: ×10³-10⁶
    model, fs = _model("flow.dilatancy_angle=0")
    st = model.reference_state(fs.initial_pressure)
    for _ in range(8):
        st, info = model.step(st, 30 * 86400.0)
        assert abs(info.conductivity_growth - 1.0) < 1e-9       # closed faces: [[u]]_n at round-off
    out = tmp_path / "c6"
    args = [a for o in [*COARSE, "time.step=2592000"] for a in ("--set", o)]
    code, _, err = cli("run", "fault-injection", "--out", str(out), *args)
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    k = s["conductivity_growth"]["warned_at_step"]
    assert k is not None and s["steps"][k - 1]["conductivity_growth"] > 1e3     # ×2e4 at 30-day steps
    assert all(r["conductivity_growth"] <= 1e3 for r in s["steps"][:k - 1])
    assert err.count("may depend on time.step") == 1, err


def test_conductivity_growth_limit_cuts_the_onset_steps(tmp_path, cli):
    """time.max_conductivity_growth: the onset steps are redone in halves until no face's C_f grows
    more than the limit in a sub-step; summary.json counts them and the lag warning stays silent."""
    import json

    out = tmp_path / "c6"
    args = [a for o in [*COARSE, "time.step=2592000", "time.max_conductivity_growth=100"] for a in ("--set", o)]
    code, _, err = cli("run", "fault-injection", "--out", str(out), *args)
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    g = s["conductivity_growth"]
    assert g["step_limit"] == 100 and g["rejected"] > 0 and g["substeps"] > len(s["steps"])
    assert all(r["conductivity_growth"] <= 100 for r in s["steps"])
    cut = [r for r in s["steps"] if "substeps" in r]
    assert cut and all(r["substeps"]["accepted"] >= 2 and r["substeps"]["kept_above_limit"] == 0 for r in cut)
    assert all(r["substeps"]["smallest_dt"] < r["dt"] for r in cut)
    assert s["energy_check"]["steps_checked"] == g["substeps"] and not s["energy_check"]["violations"]
    assert "may depend on time.step" not in err and "rejected" in err
