"""Monitor plots of 3D poromechanics runs (io/monitor3d.py prepares the data, io/plots3d.py draws).

The data preparation is tested on small made-up inputs; the figures of a small corner-point
injection run (10 × 5 × 4 cells, a few seconds) are tested against the run's own files: the
curves, face colours and images drawn are the series of summary.json, the states and jumps of
fractures.csv and the overpressure of the VTU files.
"""

import csv
import json
import struct

import numpy as np
import pytest

from polypore.cli import main
from polypore.io import monitor3d as m3
from polypore.io import plots3d
from polypore.io.plots import format_time, time_unit
from polypore.io.vtu import write_unstructured_vtu
from polypore.runs import coupled

DAY = 86400.0
# cornerpoint-injection on 10 × 5 × 4 cells (faults and well at the case's map positions), 5 days:
# F1 starts slipping on day 1 and its slipping area grows to 20% by day 5
SMALL = ["mesh.cells=[10, 5, 4]", "mesh.faults.F1.index=5", "mesh.faults.F2.index=2", "mesh.faults.F2.stop=6",
         "flow.wells.I1.column=[4, 3]", "flow.wells.I1.layers=[2, 3]", "time.end=432000"]


def _run(out, extra=()):
    args = ["run", "cornerpoint-injection", "--out", str(out)]
    for s in SMALL + list(extra):
        args += ["--set", s]
    return main(args)


def _png_size(path):
    head = open(path, "rb").read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", head[16:24])


# --------------------------------------------------------------------------- data preparation


def test_area_fractions_and_first_time():
    fracture = np.array([0, 0, 0, 1, 1])
    area = np.array([1.0, 2.0, 3.0, 4.0, 4.0])
    state = np.array([2, 0, 1, 2, 2])                 # slip, open, stick | slip, slip
    slip, opn = m3.area_fractions(fracture, area, state, 3)
    assert slip == pytest.approx([1 / 6, 1.0, 0.0]) and opn == pytest.approx([2 / 6, 0.0, 0.0])
    assert m3.first_time([0, 1, 2, 3], [0, 0, 0.005, 0.2]) == 2
    assert m3.first_time([0, 1, 2, 3], [0, 0, 0.005, 0.2], 0.01) == 3
    assert m3.first_time([0, 1], [0, 0]) is None


def test_step_recorder_onsets_wells_and_fracture_overpressure():
    rec = m3.StepRecorder(("A", "B"), [0, 0, 1], [1.0, 1.0, 2.0], {"W": [1, 2]}, [1.0, 1.0, 3.0])
    rec.add(0.0, [1, 1, 1], [0.0, 0.0, 0.0], p_f=[5.0, 5.0, 7.0])
    rec.add(10.0, [2, 1, 1], [1.0, 2.0, 4.0], p_f=[6.0, 9.0, 7.5])
    rec.add(20.0, [2, 2, 0], [1.0, 3.0, 1.0], p_f=[6.0, 9.0, 8.0])
    assert rec.slip_fraction == {"A": [0.0, 0.5, 1.0], "B": [0.0, 0.0, 0.0]}
    assert rec.open_fraction["B"] == [0.0, 0.0, 1.0]
    np.testing.assert_array_equal(rec.onset, [10.0, 20.0, np.nan])
    assert rec.onsets() == {"A": {"first_slip": 10.0, "area_1pct": 10.0}, "B": {"first_slip": None, "area_1pct": None}}
    assert rec.well_mean["W"] == pytest.approx([0.0, (2 + 12) / 4, (3 + 3) / 4])
    assert rec.well_max["W"] == [0.0, 4.0, 3.0]
    assert rec.max_overpressure == [0.0, 4.0, 3.0] and rec.peak_cell[1:] == [2, 1]
    assert rec.max_fracture_overpressure == {"A": [0.0, 4.0, 4.0], "B": [0.0, 0.5, 1.0]}
    s = rec.summary(np.arange(9.0).reshape(3, 3))
    assert s["wells"]["W"]["cells"] == 2 and s["max_overpressure_at"] == [3.0, 4.0, 5.0]


def _square(x0, y0, z0, e1, e2):
    """A planar quad of side 1 with corner (x0, y0, z0) spanned by unit vectors e1, e2."""
    o = np.array([x0, y0, z0], float)
    e1, e2 = np.asarray(e1, float), np.asarray(e2, float)
    return np.array([o, o + e1, o + e1 + e2, o + e2])


def test_fault_frame_of_vertical_and_gently_dipping_faults():
    # vertical fault x = 3 with normals of both signs: strike along +y, drawn against z
    fr = m3.fault_frame([[1, 0, 0], [-1, 0, 0]], [1.0, 3.0], [[3, 0, -10], [3, 2, -12]])
    assert abs(fr.normal[0]) == pytest.approx(1.0) and fr.strike == pytest.approx([0, 1, 0])
    assert fr.dip == pytest.approx(90.0) and fr.vertical == "z"
    assert fr.origin == pytest.approx([3, 1.5, -11.5])
    assert fr.coords(np.array([[3.0, 4.0, -7.0]]))[0] == pytest.approx([2.5, -7.0])
    # a plane dipping 16° towards −x: drawn in its own plane (up dip), areas preserved
    dip = np.radians(16.0)
    n = np.array([np.sin(dip), 0.0, np.cos(dip)])
    down_dip = np.array([np.cos(dip), 0.0, -np.sin(dip)])         # in the plane: n · down_dip = 0
    quad = _square(0, 0, 0, [0, 1, 0], down_dip)
    fr = m3.fault_frame([n], [1.0], [quad.mean(axis=0)])
    assert fr.dip == pytest.approx(16.0) and fr.vertical == "updip" and fr.updip == pytest.approx(-down_dip)
    polys = m3.project_faces(fr, quad, np.arange(4), np.array([4]), [0])
    assert m3.polygon_area(polys[0]) == pytest.approx(1.0)


def test_vertical_exaggeration():
    assert m3.vertical_exaggeration(100.0, 80.0) == 1.0
    assert m3.vertical_exaggeration(900.0, 50.0) == 10.0          # needs 6: the next round factor
    assert m3.vertical_exaggeration(1000.0, 190.0) == 2.0


def test_raster_map_and_section_pick_the_right_cells():
    # two columns of two stacked unit cubes: cells 0, 1 at x in (0, 1), cells 2, 3 at x in (1, 2)
    lo = np.array([[0, 0, 0], [0, 0, 1], [1, 0, 0], [1, 0, 1]], float)
    hi = lo + 1.0
    c = lo + 0.5
    v = np.array([1.0, 5.0, 7.0, 2.0])
    img, g = m3.column_max_map(lo, hi, v, max_pixels=20)
    xs, ys = g.centres()
    left = xs < 1.0
    assert np.all(img[:, left] == 5.0) and np.all(img[:, ~left] == 7.0)      # the largest over depth
    sec, sg, h = m3.vertical_section(lo, hi, c, v, axis=1, at=0.5, max_pixels=20)
    assert h == 0
    xs, zs = sg.centres()
    expect = np.where(zs[:, None] < 1.0, np.where(xs[None, :] < 1.0, 1.0, 7.0), np.where(xs[None, :] < 1.0, 5.0, 2.0))
    np.testing.assert_array_equal(sec, expect)
    # a section outside every cell is empty; a window limits the horizontal extent
    assert np.isnan(m3.vertical_section(lo, hi, c, v, axis=1, at=5.0)[0]).all()
    sec, sg, _ = m3.vertical_section(lo, hi, c, v, axis=1, at=0.5, max_pixels=20, window=(1.0, 2.0))
    assert sg.extent[0] == pytest.approx(1.0) and set(np.unique(sec)) == {2.0, 7.0}
    b_lo, b_hi = m3.interest_box(lo, hi, [0, 0, 1.0, 0], points=np.zeros((0, 3)), pad=0.0)
    assert b_lo == pytest.approx([1, 0]) and b_hi == pytest.approx([2, 1])


def test_section_traces_and_outlines():
    # two triangles forming the vertical unit square x = 0.5, y in (0, 1), z in (0, 1)
    pts = np.array([[0.5, 0, 0], [0.5, 1, 0], [0.5, 1, 1], [0.5, 0, 1]], float)
    conn, off = np.array([0, 1, 2, 0, 2, 3]), np.array([3, 6])
    seg = m3.section_traces(pts, conn, off, axis=1, at=0.25)    # the plane y = 0.25 cuts both triangles
    assert seg.shape == (2, 2, 2)
    assert np.allclose(seg[..., 0], 0.5) and sorted(np.round(seg[..., 1].ravel(), 12)) == [0.0, 0.25, 0.25, 1.0]
    out = m3.outline_segments(pts, conn, off, np.array([0, 0]))
    assert out.shape == (4, 2, 3)                                 # the diagonal is shared: not an outline
    assert m3.outline_segments(pts, conn, off, np.array([0, 1])).shape == (6, 2, 3)


def test_read_vtu_round_trip(tmp_path):
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.5]])
    write_unstructured_vtu(tmp_path / "t.vtu", pts, [0, 1, 2, 3], [4], [10],
                           cell_data={"p": np.array([2.5]), "n": np.array([[0.0, 0.0, 1.0]])})
    a = m3.read_vtu(tmp_path / "t.vtu")
    np.testing.assert_array_equal(a["Points"], pts)
    assert a["connectivity"].tolist() == [0, 1, 2, 3] and a["offsets"].tolist() == [4]
    assert a["p"].tolist() == [2.5] and a["n"].shape == (1, 3)
    with pytest.raises(KeyError):
        m3.read_vtu(tmp_path / "t.vtu", ["missing"])


def test_time_unit_is_days_from_one_day():
    assert time_unit(8 * DAY) == (DAY, "days") and time_unit(0.5 * DAY) == (1.0, "s")
    assert format_time(DAY, 8 * DAY) == "1 day" and format_time(2 * DAY, 8 * DAY) == "2 days"


# --------------------------------------------------------------------------- a small 3D run


def _artists(fig):
    """What a figure draws: per axes its title, lines (label, x, y), polygon collections
    (array, polygons) and images."""
    from matplotlib.collections import PolyCollection

    out = []
    for ax in fig.axes:
        out.append({"title": ax.get_title(), "ylabel": ax.get_ylabel(),
                    "lines": [(ln.get_label(), np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float))
                              for ln in ax.get_lines()],
                    "polys": [(None if pc.get_array() is None else np.ma.filled(np.ma.asarray(pc.get_array(), float),
                                                                                 np.nan),
                               [p.vertices[:-1] if np.allclose(p.vertices[0], p.vertices[-1]) else p.vertices
                                for p in pc.get_paths()])
                              for pc in ax.collections if isinstance(pc, PolyCollection)],
                    "images": [np.ma.filled(np.ma.asarray(im.get_array(), float), np.nan) for im in ax.get_images()]})
    return out


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """The small run, with what every figure drew and which files existed when it was saved."""
    out = tmp_path_factory.mktemp("p3d") / "run"
    drawn, present = {}, {}
    real_save = plots3d.save

    def spy(fig, path):
        drawn[path.name] = _artists(fig)
        present[path.name] = sorted(p.name for p in path.parent.iterdir())
        real_save(fig, path)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plots3d, "save", spy)
        assert _run(out) == 0
    return out, drawn, present


def _csv(out):
    return m3.read_fractures_csv(out / "fractures.csv")


def test_the_figures_exist_after_the_data(small_run):
    out, drawn, present = small_run
    for name in plots3d.FIGURES:
        w, h = _png_size(out / name)
        assert (out / name).stat().st_size > 20_000 and w > 600 and h > 300, name
        # written after the VTU series, the PVD and fractures.csv, before summary.json (the run's end mark)
        assert {"fractures.csv", "solution.pvd", "bulk_0005.vtu", "fractures_0005.vtu"} <= set(present[name])
        assert "summary.json" not in present[name]
    assert not list(out.glob(".*.tmp"))


def test_slip_onset_curves_are_the_runs_series(small_run):
    out, drawn, _ = small_run
    s = json.loads((out / "summary.json").read_text())
    mon = s["monitor"]
    fr = _csv(out)
    # every step is an output here: the per-step series equal the per-face data of fractures.csv
    assert fr["time"].tolist() == mon["time"]
    frac = np.array([m3.area_fractions(np.zeros(fr["area"].size, int), fr["area"], st, 1)[0][0] for st in fr["state"]])
    np.testing.assert_allclose(mon["slip_area_fraction"]["F1"], frac, rtol=1e-12)
    assert 0 < frac[-1] < 1 and frac[0] == 0                      # the test means something: F1 starts slipping
    first = float(fr["time"][np.argmax((fr["state"] == m3.SLIP).any(axis=1))])
    assert mon["fault_onset"]["F1"]["first_slip"] == first
    panels = drawn["slip_onset.png"]
    (label, x, y), = [ln for ln in panels[0]["lines"] if not ln[0].startswith("_")]
    assert label.startswith(f"F1: first slip at {format_time(first, 5 * DAY)}")
    np.testing.assert_allclose(x, np.asarray(mon["time"]) / DAY)
    np.testing.assert_allclose(y, 100 * frac, rtol=1e-12)
    open_line = [ln for ln in panels[1]["lines"] if ln[1].size > 2][0]
    np.testing.assert_allclose(open_line[2], 100 * np.asarray(mon["open_area_fraction"]["F1"]))
    # the largest slip: summary's max_slip, in the axis' unit, = the largest tangential jump change in
    # fractures.csv
    fv = m3.read_vtu(out / "fractures_0005.vtu", ["normal"])
    slip = m3.tangential(fr["jump"] - fr["jump"][0], fv["normal"])
    slip_line = [ln for ln in panels[2]["lines"] if ln[1].size > 2][0]
    unit = panels[2]["ylabel"].rsplit("(", 1)[1].rstrip(")")
    scale = {"µm": 1e6, "mm": 1e3, "m": 1.0}[unit]
    np.testing.assert_allclose(slip_line[2], slip.max(axis=1) * scale, rtol=1e-6, atol=1e-9)


def test_fault_maps_colour_the_faces_by_the_runs_data(small_run):
    out, drawn, _ = small_run
    fr = _csv(out)
    fv = m3.read_vtu(out / "fractures_0005.vtu", ["normal", "offsets"])
    axes = [a for a in drawn["fault_maps.png"] if a["polys"]]
    assert len(axes) == 3                                          # one fault: state, slip, onset
    (state, polys), = axes[0]["polys"]
    (slip, _), = axes[1]["polys"]
    (onset, _), = axes[2]["polys"]
    np.testing.assert_array_equal(state, fr["state"][-1])
    final = m3.tangential(fr["jump"][-1] - fr["jump"][0], fv["normal"])
    # in the colour bar's unit, µm or mm as the slip's size asks
    scale = min((1e6, 1e3), key=lambda c: abs(np.log(c * final.max() / max(slip.max(), 1e-300))))
    np.testing.assert_allclose(slip, final * scale, rtol=1e-6, atol=1e-9)
    slipping = fr["state"] == m3.SLIP
    expect = np.where(slipping.any(axis=0), fr["time"][np.argmax(slipping, axis=0)] / DAY, np.nan)
    np.testing.assert_array_equal(onset, expect)
    # F1 is vertical: drawn against z, its faces keep their areas
    areas = [m3.polygon_area(p) for p in polys]
    np.testing.assert_allclose(areas, fr["area"], rtol=1e-6)
    assert len(polys) == fv["offsets"].size


def test_pressure_curves_and_map_are_the_runs_overpressure(small_run):
    out, drawn, _ = small_run
    s = json.loads((out / "summary.json").read_text())
    mon = s["monitor"]
    ops = [m3.read_vtu(out / f"bulk_{k:04d}.vtu", ["overpressure"])["overpressure"] for k in range(6)]
    lines = {ln[0]: ln for ln in drawn["pressure.png"][0]["lines"]}
    np.testing.assert_allclose(lines["largest in the domain"][2], [o.max() / 1e6 for o in ops], rtol=1e-9)
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh

    case = load_case(str(out / "case.toml"))
    mesh = build_fractured_mesh(case).mesh
    cells = coupled.case_wells(case, mesh)["I1"]
    vol = mesh.geometry.cell_volume[cells]
    np.testing.assert_allclose(lines["well I1: largest of its cells"][2], [o[cells].max() / 1e6 for o in ops],
                               rtol=1e-9)
    np.testing.assert_allclose(lines["well I1: mean over its cells"][2],
                               [(o[cells] * vol).sum() / vol.sum() / 1e6 for o in ops], rtol=1e-9)
    np.testing.assert_allclose(lines["matrix at monitor point well"][2],
                               np.asarray(mon["overpressure_at_points"]["well"]) / 1e6)
    assert mon["wells"]["I1"]["cells"] == cells.size
    # the map: the largest over depth, so its largest pixel is the largest cell; the section
    # through the well shows the well's cells' values
    (img,), (sec,) = [a["images"] for a in drawn["pressure_map.png"] if a["images"]]
    final = ops[-1]
    assert np.nanmax(img) == pytest.approx(final.max() / 1e6)
    assert np.nanmin(img) >= final.min() / 1e6 - 1e-12
    for c in cells:
        assert np.any(np.isclose(sec, final[c] / 1e6, rtol=1e-12))


def test_replot_from_the_run_folder_gives_the_same_data(small_run, tmp_path):
    out, drawn, _ = small_run
    d = m3.from_run_directory(out, lambda c, lo, hi: coupled.run_folder_wells(out, c, lo, hi))
    mon = json.loads((out / "summary.json").read_text())["monitor"]
    np.testing.assert_allclose(d.slip_fraction["F1"], mon["slip_area_fraction"]["F1"])
    np.testing.assert_allclose(d.max_overpressure, mon["max_overpressure"])
    assert list(d.well_cells_xyz) == ["I1"] and d.t_final == 5 * DAY
    slip_drawn, = [a["polys"][0][0] for a in drawn["fault_maps.png"] if "slip since" in a["title"]]
    # in the colour bar's unit, µm or mm as the slip's size asks
    scale = min((1e6, 1e3), key=lambda c: abs(np.log(c * d.slip.max() / max(slip_drawn.max(), 1e-300))))
    np.testing.assert_allclose(d.slip * scale, slip_drawn, rtol=1e-6, atol=1e-9)
    assert main(["plot", str(out), "--out", str(tmp_path / "again")]) == 0
    assert sorted(p.name for p in (tmp_path / "again").glob("*.png")) == sorted(plots3d.FIGURES)


def test_plot_command_refuses_what_is_not_a_3d_poromechanics_run(small_run, tmp_path, capsys):
    """`polypore plot` names RUN_DIR and why, exit 2, no traceback: no folder, a 2D run, a run
    folder missing its fractures.csv."""
    out = small_run[0]
    assert main(["plot", str(tmp_path / "nothing")]) == 2
    assert "RUN_DIR" in capsys.readouterr().err
    two_d = tmp_path / "two_d"
    two_d.mkdir()
    summary = json.loads((out / "summary.json").read_text())
    (two_d / "summary.json").write_text(json.dumps({**summary, "mesh": {**summary["mesh"], "dim": 2}}))
    assert main(["plot", str(two_d)]) == 2
    assert "2D poromechanics" in capsys.readouterr().err
    partial = tmp_path / "partial"
    partial.mkdir()
    (partial / "summary.json").write_text((out / "summary.json").read_text())
    assert main(["plot", str(partial)]) == 2
    err = capsys.readouterr().err
    assert "fractures.csv" in err and "Traceback" not in err


def test_a_failing_plot_is_a_warning_not_a_failed_run(tmp_path, monkeypatch, capfd):
    def broken(path, d):
        raise RuntimeError("boom")

    monkeypatch.setattr(plots3d, "fault_maps_plot", broken)
    assert _run(tmp_path / "o", ["time.end=86400"]) == 0
    out = tmp_path / "o"
    assert (out / "summary.json").is_file() and not (out / "fault_maps.png").exists()
    assert all((out / n).stat().st_size > 0 for n in plots3d.FIGURES if n != "fault_maps.png")
    assert "plot fault_maps.png not written: RuntimeError: boom" in capfd.readouterr().err
    # and a failure in collecting the data: no figure, still a finished run
    monkeypatch.setattr("polypore.runs.coupled.collect", lambda *a, **k: 1 / 0)
    assert _run(tmp_path / "o2", ["time.end=86400"]) == 0
    assert not list((tmp_path / "o2").glob("*.png")) and (tmp_path / "o2" / "summary.json").is_file()
    assert "3D monitor plots not written: ZeroDivisionError" in capfd.readouterr().err


def test_fractures_csv_reader_matches_the_file(small_run):
    out, _, _ = small_run
    fr = _csv(out)
    rows = list(csv.DictReader(open(out / "fractures.csv")))
    last = [r for r in rows if int(r["step"]) == fr["step"][-1]]
    assert [m3.STATE_CODES[r["state"]] for r in last] == fr["state"][-1].tolist()
    assert [float(r["jump_y"]) for r in last] == fr["jump"][-1, :, 1].tolist()


def test_fault_stress_map_draws_the_runs_final_delta_cfs(small_run):
    """fault_stress.png colours each fault's faces by the final output's ΔCFS (the VTU array,
    in the colour bar's unit) and slip tendency (NaN where open)."""
    out, drawn, _ = small_run
    last = sorted(out.glob("fractures_*.vtu"))[-1]
    v = m3.read_vtu(last, ["delta_cfs", "slip_tendency", "fracture"])
    axes = drawn["fault_stress.png"]
    cfs_axes = [a for a in axes if "ΔCFS" in a["title"]]
    ts_axes = [a for a in axes if "slip tendency" in a["title"]]
    assert cfs_axes and len(cfs_axes) == len(ts_axes)
    drawn_cfs = np.concatenate([a["polys"][0][0] for a in cfs_axes])
    drawn_ts = np.concatenate([a["polys"][0][0] for a in ts_axes])
    faces = np.concatenate([np.flatnonzero(v["fracture"] == i) for i in range(len(cfs_axes))])
    ref = v["delta_cfs"][faces]
    scale = min((1.0, 1e-3, 1e-6), key=lambda c: abs(np.log(max(abs(ref).max() * c, 1e-300) /
                                                                 max(np.abs(drawn_cfs).max(), 1e-300))))
    np.testing.assert_allclose(drawn_cfs, ref * scale, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(drawn_ts, v["slip_tendency"][faces], rtol=1e-12)
