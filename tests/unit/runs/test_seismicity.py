"""The event catalogue of rate-and-state runs (runs/seismicity.py)."""

import csv

import numpy as np
import pytest

from polypore.runs.seismicity import EventCatalogue, moment_magnitude


def _catalogue(dim=3):
    # two faults: faces 0-2 on "A" (areas 1, 2, 3 m²), 3-4 on "B"
    return EventCatalogue(np.array([0, 0, 0, 1, 1]), ("A", "B"), np.array([1.0, 2.0, 3.0, 4.0, 5.0]),
                          np.full(5, 3e10), np.arange(15.0).reshape(5, 3)[:, :dim], dim, threshold=1e-3)


def test_an_event_its_size_and_the_aseismic_slip_apart(tmp_path):
    c = _catalogue()
    z = np.zeros(5)
    c.add(0.0, 1.0, np.array([1e-9, 1e-9, 0, 1e-6, 0]), np.array([1e-9, 1e-9, 0, 1e-6, 0]))   # creep
    c.add(1.0, 1.5, np.array([1e-4, 2e-3, 5e-3, 0, 0]), np.array([1e-4, 1e-3, 2e-3, 0, 0]))     # onset: face 2
    c.add(1.5, 2.0, np.array([2e-3, 1e-2, 1e-4, 0, 0]), np.array([1e-3, 5e-3, 1e-4, 0, 0]))
    c.add(2.0, 3.0, np.array([1e-5, 1e-5, 1e-5, 0, 0]), np.array([1e-5, 1e-5, 1e-5, 0, 0]))     # ends here
    c.add(3.0, 4.0, z, z)
    assert len(c.events) == 1
    e = c.events[0]
    assert (e["fault"], e["onset_s"], e["end_s"], e["hypocentre_face"]) == ("A", 1.0, 3.0, 2)
    assert e["hypocentre_x"] == 6.0                         # face 2's centroid
    slip = np.array([1e-4 + 1e-3 + 1e-5, 1e-3 + 5e-3 + 1e-5, 2e-3 + 1e-4 + 1e-5])
    m0 = 3e10 * float(np.sum(np.array([1.0, 2.0, 3.0]) * slip))
    assert e["moment"] == pytest.approx(m0, rel=1e-12)
    assert e["magnitude_mw"] == pytest.approx(2 / 3 * (np.log10(m0) - 9.1), rel=1e-12)
    assert e["ruptured_area"] == 6.0 and e["peak_slip_rate_m_s"] == 1e-2      # faces 0-2 all crossed 1 mm/s
    assert e["mean_slip_m"] == pytest.approx(float(np.sum(np.array([1, 2, 3]) * slip) / 6), rel=1e-12)
    s = c.summary()
    assert s["events"] == 1 and s["largest"]["fault"] == "A"
    assert s["aseismic_moment"]["A"] == pytest.approx(3e10 * (1e-9 + 2e-9), rel=1e-12)
    assert s["aseismic_moment"]["B"] == pytest.approx(3e10 * 4e-6, rel=1e-12)
    c.write(tmp_path / "events.csv")
    rows = list(csv.DictReader(open(tmp_path / "events.csv")))
    assert len(rows) == 1 and float(rows[0]["moment"]) == pytest.approx(m0, rel=1e-8)


def test_an_event_running_at_the_end_is_closed_and_2d_has_no_magnitude():
    c = _catalogue(dim=2)
    c.add(0.0, 1.0, np.array([0, 0, 0, 0, 2e-3]), np.array([0, 0, 0, 0, 1e-3]))
    c.finish(1.0)
    (e,) = c.events
    assert e["fault"] == "B" and e["magnitude_mw"] is None and e["hypocentre_z"] is None
    assert e["moment"] == pytest.approx(3e10 * 5.0 * 1e-3)
    assert "per metre" in c.summary()["moment_units"]


def test_moment_magnitude():
    assert moment_magnitude(10 ** (1.5 * 6 + 9.1)) == pytest.approx(6.0)


def test_the_series_counts_injected_volume_and_both_moments(tmp_path):
    """Each sub-step adds a row: cumulative ΔV, seismic moment (events, running ones included) and
    aseismic moment, and each fault's peak rate; events carry ΔV at their end."""
    c = _catalogue()
    c.add(0.0, 1.0, np.array([1e-9, 0, 0, 1e-6, 0]), np.array([1e-9, 0, 0, 1e-6, 0]), injected=2.0)
    c.add(1.0, 2.0, np.array([2e-3, 0, 0, 0, 0]), np.array([1e-3, 0, 0, 0, 0]), injected=3.0)
    c.add(2.0, 3.0, np.zeros(5), np.zeros(5), injected=1.0)
    s = c.series()
    assert np.array_equal(s["time"], [1.0, 2.0, 3.0]) and np.array_equal(s["injected_volume"], [2.0, 5.0, 6.0])
    assert np.allclose(s["seismic_moment"], [0.0, 3e10 * 1e-3, 3e10 * 1e-3])
    assert np.allclose(s["aseismic_moment"], 3e10 * (1e-9 + 4e-6))
    assert np.array_equal(s["peak_slip_rate"]["A"], [1e-9, 2e-3, 0.0])
    assert np.array_equal(s["peak_slip_rate"]["B"], [1e-6, 0.0, 0.0])
    (e,) = c.events
    assert e["injected_volume"] == 6.0 and e["moment"] == pytest.approx(s["seismic_moment"][-1])
    assert c.summary()["injected_volume"] == 6.0
    c.write_series(tmp_path / "seismicity.csv")
    rows = list(csv.DictReader(open(tmp_path / "seismicity.csv")))
    assert [float(r["injected_volume"]) for r in rows] == [2.0, 5.0, 6.0]
    assert float(rows[1]["peak_slip_rate_A"]) == 2e-3


@pytest.mark.parametrize("dim", [2, 3])
def test_seismicity_plot_draws_the_catalogue_and_mcgarr(tmp_path, dim):
    from polypore.io.seismicity_plots import seismicity_plot

    c = _catalogue(dim)
    c.add(0.0, 1.0, np.array([1e-9, 0, 0, 1e-6, 0]), np.array([1e-9, 0, 0, 1e-6, 0]), injected=2.0)
    c.add(1.0, 2.0, np.array([2e-3, 0, 0, 0, 0]), np.array([1e-3, 0, 0, 0, 0]), injected=3.0)
    c.add(2.0, 3.0, np.zeros(5), np.zeros(5), injected=1.0)
    out = seismicity_plot(tmp_path / "s.png", "t", c.series(), c.events, dim, 1e-3, 3e10, 3.0)
    assert (tmp_path / "s.png").stat().st_size > 0
    assert out == {"events": 1, "largest_moment": pytest.approx(3e7), "injected_volume": 6.0,
                   "mcgarr_bound": pytest.approx(1.8e11)}
    # no injection, no event: the panels say so instead of failing
    c0 = _catalogue(dim)
    c0.add(0.0, 1.0, np.zeros(5), np.zeros(5))
    out0 = seismicity_plot(tmp_path / "s0.png", "t", c0.series(), c0.events, dim, 1e-3, 3e10, 1.0)
    assert out0["mcgarr_bound"] is None and out0["events"] == 0
