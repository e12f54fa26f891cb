"""The fault figures draw the numbers summary.json reports (issue 24): on a small corner-point
injection run, the faces coloured slip / open / stick in fault_maps.png, the percentage in its
titles, the faces with an onset colour and the curves of slip_onset.png are summary.json's
``final_fault_states`` and series, in the run and when replotted from the run's folder (with
outputs only every other step, so that the folder's output times are not the steps)."""

import json
import logging
import re

import numpy as np
import pytest

from polypore.cli import main
from polypore.io import monitor3d as m3
from polypore.io import plots3d
from polypore.runs import coupled

SMALL = ["mesh.cells=[10, 5, 4]", "mesh.faults.F1.index=5", "mesh.faults.F2.index=2", "mesh.faults.F2.stop=6",
         "flow.wells.I1.column=[4, 3]", "flow.wells.I1.layers=[2, 3]", "time.end=432000", "time.output_every=2"]
COUNTS = ("faces", "open", "stick", "slip", "ever_slipped")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The small run: its folder, what its fault figures drew (returned by the plot functions),
    the titles of fault_maps.png and the run's PlotData."""
    out = tmp_path_factory.mktemp("fps") / "run"
    drawn, titles, data = {}, [], []
    real_write, real_save = coupled.write_3d_plots, plots3d.save

    def spy_save(fig, path):
        if path.name == "fault_maps.png":
            titles.extend(a.get_title() for a in fig.axes)
        real_save(fig, path)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(coupled, "write_3d_plots", lambda folder, d: data.append(d) or real_write(folder, d, drawn))
        mp.setattr(plots3d, "save", spy_save)
        args = ["run", "cornerpoint-injection", "--out", str(out)]
        for s in SMALL:
            args += ["--set", s]
        assert main(args) == 0
    return out, drawn, titles, data[0]


def check_against_summary(summary, drawn, titles=None):
    mon = summary["monitor"]
    final = mon["final_fault_states"]
    maps, onset = drawn["fault_maps.png"], drawn["slip_onset.png"]
    assert set(maps) == set(final) == set(mon["slip_area_fraction"])
    for n, f in final.items():
        assert f["time"] == mon["time"][-1] == maps[n]["time"]
        assert {k: maps[n][k] for k in COUNTS} == {k: f[k] for k in COUNTS}, n
        # the faces coloured slip, the title and the last value of the series: one number
        assert maps[n]["slip_area_fraction"] == pytest.approx(f["slip_area_fraction"], rel=1e-12, abs=1e-15)
        assert maps[n]["title_slip_area_fraction"] == mon["slip_area_fraction"][n][-1] == f["slip_area_fraction"]
        np.testing.assert_allclose(onset[n]["slip_area_fraction"], mon["slip_area_fraction"][n], rtol=1e-12)
        np.testing.assert_allclose(onset[n]["open_area_fraction"], mon["open_area_fraction"][n], rtol=1e-12)
        assert onset[n]["first_slip"] == mon["fault_onset"][n]["first_slip"] == maps[n]["first_slip"]
        if titles is not None:
            t, = [t for t in titles if t.startswith(f"{n} (dip")]
            pct = re.search(r"state, ([0-9.e-]+)% of the area slips \((\d+) of (\d+) faces\)", t)
            assert pct, t
            assert float(pct.group(1)) == pytest.approx(100 * f["slip_area_fraction"], rel=0.06, abs=0.051)
            assert (int(pct.group(2)), int(pct.group(3))) == (f["slip"], f["faces"])


def test_fault_figures_draw_the_summary(run):
    out, drawn, titles, _ = run
    s = json.loads((out / "summary.json").read_text())
    final = s["monitor"]["final_fault_states"]["F1"]
    assert 0 < final["slip"] < final["faces"] and final["ever_slipped"] >= final["slip"]     # F1 slips here
    assert final["slip"] == s["steps"][-1]["slip"] and final["open"] == s["steps"][-1]["open"]
    check_against_summary(s, drawn, titles)
    # the per-fault report of the corner-point grid: both faults, F2 bonded; vertical, F1 on an
    # i pillar line (striking along y), F2 on a j line
    f1, f2 = s["faults"]["F1"], s["faults"]["F2"]
    assert f1["fracture"] == "F1" and f2["fracture"] is None and f1["faces"] == final["faces"]
    assert f1["dip_deg"] == pytest.approx(90.0) and f2["dip_deg"] == pytest.approx(90.0)
    assert f1["strike_deg"] % 180 == pytest.approx(0.0, abs=1e-9) and f2["strike_deg"] % 180 == pytest.approx(90.0)
    # 1000 m long, 160 m stack less the 30 m throw (F2, which crosses it, changes it a little)
    assert f1["cells"] == {"hanging_wall": 20, "footwall": 20} and 120e3 < f1["area_m2"] <= 130e3


def test_replotted_fault_figures_draw_the_summary(run, tmp_path):
    out, _, _, ran = run
    s = json.loads((out / "summary.json").read_text())
    assert len(m3.read_fractures_csv(out / "fractures.csv")["time"]) < len(s["monitor"]["time"])   # outputs: 0, 2, 4, 5
    d = m3.from_run_directory(out)
    assert not [n for n in d.notes if "not summary.json" in n], d.notes
    drawn = {}
    plots3d.write_3d_plots(tmp_path, d, drawn)
    check_against_summary(s, drawn)
    # every step's onset, not only the output times' (one face here first slips on day 3, not an output)
    np.testing.assert_array_equal(d.onset, ran.onset)
    np.testing.assert_array_equal(d.state, ran.state)


def test_a_map_that_disagrees_with_the_series_is_reported(run, tmp_path, caplog):
    out, _, _, ran = run
    d = m3.from_run_directory(out)
    d.state = np.where(d.state == m3.SLIP, m3.STICK, d.state)        # the faces say stick, the series slip
    with caplog.at_level(logging.WARNING, logger="polypore"):
        what = plots3d.fault_maps_plot(tmp_path / "f.png", d)
    assert what["F1"]["slip"] == 0 and what["F1"]["title_slip_area_fraction"] > 0
    assert "fault_maps.png: the faces of F1 coloured slip cover 0% of its area" in caplog.text
    # and a replot whose fractures.csv is not the summary's says so
    summary = json.loads((out / "summary.json").read_text())
    summary["monitor"]["final_fault_states"]["F1"]["slip"] += 1
    bad = tmp_path / "bad"
    bad.mkdir()
    for p in out.iterdir():
        (bad / p.name).write_bytes(p.read_bytes())
    (bad / "summary.json").write_text(json.dumps(summary))
    assert any("not summary.json's final_fault_states" in n for n in m3.from_run_directory(bad).notes)


def test_round_off_slip_gets_no_colour_scale_of_its_own(run, tmp_path):
    """A fault whose slip is round-off is drawn on the shared scale (blank), not with its 1e-14 mm
    stretched over the whole colour bar; a fault that slips keeps its own scale."""
    _, _, _, ran = run
    d = m3.from_run_directory(run[0])
    what = plots3d.fault_maps_plot(tmp_path / "a.png", d)
    assert what["F1"]["slip_colour_max_m"] == pytest.approx(float(d.slip.max()))
    d.slip = d.slip * 1e-14
    what = plots3d.fault_maps_plot(tmp_path / "b.png", d)
    assert what["F1"]["slip_colour_max_m"] == pytest.approx(plots3d.SLIP_FLOOR)
