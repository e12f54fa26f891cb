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
