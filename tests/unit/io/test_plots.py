"""Plot helpers: one time unit per run, readable value units, wrapped multi-fracture figures."""

import struct

import numpy as np
import pytest

from polypore.io.plots import (MAX_COLUMNS, fracture_profiles, format_time, time_tag, time_unit,
                               value_unit)


def _png_size(path):
    head = open(path, "rb").read(24)
    return struct.unpack(">II", head[16:24])


def test_time_unit_is_days_for_long_runs_and_seconds_otherwise():
    assert time_unit(250 * 86400.0) == (86400.0, "days")
    assert time_unit(2000.0) == (1.0, "s")
    assert format_time(100 * 86400.0, 250 * 86400.0) == "100 days"
    assert format_time(500.0, 2000.0) == "500 s"
    assert time_tag(100 * 86400.0, 250 * 86400.0) == "100d"
    assert time_tag(500.0, 2000.0) == "500"


@pytest.mark.parametrize("unit, magnitude, expected", [
    ("Pa", 6.2e7, (1e6, "MPa")), ("Pa", 2.5e3, (1e3, "kPa")), ("Pa", 12.0, (1.0, "Pa")),
    ("Pa", 3e10, (1e9, "GPa")), ("m", 1.2e-3, (1e-3, "mm")), ("m", 2.7e-4, (1e-6, "µm")),
    ("m", 15.0, (1.0, "m")), ("m", 0.0, (1.0, "m")), ("K", 300.0, (1.0, "K")),
])
def test_value_unit_picks_the_prefix_of_the_magnitude(unit, magnitude, expected):
    assert value_unit(unit, magnitude) == expected


def test_many_fractures_wrap_into_blocks(tmp_path):
    rng = np.random.default_rng(0)
    nf, per = 6, 12
    fracture = np.repeat(np.arange(nf), per)
    s = np.tile(np.linspace(0.0, 1.0, per), nf)
    fields = {"λ_n (Pa)": 2e7 + 1e6 * rng.random(nf * per), "|[[u]]_τ| (m)": 1e-3 * rng.random(nf * per)}
    states = np.array(["stick", "slip", "open"])[rng.integers(0, 3, nf * per)]
    wide = tmp_path / "profiles.png"
    fracture_profiles(wide, [f"F{j}" for j in range(nf)], fracture, s, fields, states, title="t")
    w, h = _png_size(wide)
    one = tmp_path / "one.png"
    fracture_profiles(one, ["F0"], fracture[:per], s[:per], {k: v[:per] for k, v in fields.items()}, states[:per])
    w1, _ = _png_size(one)
    # six fractures wrap into blocks of MAX_COLUMNS: no wider than MAX_COLUMNS single columns
    assert w < MAX_COLUMNS * w1 * 1.05
    assert h > w / 2


def test_monitor_panel_labels_what_it_plots(tmp_path, monkeypatch):
    """Issue 25: dfm-2d's monitor.png called the panel "overpressure (MPa)" while its fracture
    curves are the fracture pressure p_f itself (absolute: 10 MPa where the overpressure is 0)."""
    from types import SimpleNamespace

    from polypore.io import plots

    figs = []
    monkeypatch.setattr(plots, "save", lambda fig, path: figs.append(fig))
    net = SimpleNamespace(n_faces=0, names=["F1"])
    t = [0.0, 1.0, 2.0]
    monitor = {"time": t, "points": {"P": [0.0, 1e5, 2e5]}, "fault_p": {"F1": [1e7, 1.01e7, 1.02e7]},
               "fault_slip": {"F1": [0.0, 0.0, 1e-4]}}
    plots.monitor_plots(tmp_path, "c", net, None, monitor, [], None)
    a1 = figs[0].axes[0]
    labels = [h.get_label() for h in a1.get_lines()]
    assert a1.get_ylabel() == "pressure (MPa)"
    assert labels == ["overpressure p − p⁰ at P", "max fracture pressure p_f on F1"]
    figs.clear()
    plots.monitor_plots(tmp_path, "c", net, None, {**monitor, "fault_p": {}, "fault_slip": {}}, [], None)
    assert figs[0].axes[0].get_ylabel() == "overpressure p − p⁰ (MPa)"
