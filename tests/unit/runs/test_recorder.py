"""The run recorder (issue 27): OutputSeries numbers the outputs and writes solution.pvd and
fractures.csv; PoroRecorder keeps a poromechanics run's per-step series and step rows, checked
here on two recorded steps of fake data (two fractures of one and two faces, three cells)."""

import csv
import logging
from types import SimpleNamespace

import numpy as np
import pytest

from polypore.io.results import fracture_rows
from polypore.models.friction import Coulomb
from polypore.runs.march import StepRecord
from polypore.runs.recorder import CONDUCTIVITY_GROWTH_WARN, OutputSeries, PoroRecorder

NORMAL = np.array([[0.0, 1.0], [0.0, 1.0], [1.0, 0.0]])        # (n_ff, 2): faces 0, 1 on F1, 2 on F2
AREA = np.array([1.0, 3.0, 2.0])


def _block(step, t):
    n = len(AREA)
    return fracture_rows(step, t, ["F1", "F2"], np.array([0, 0, 1]), np.zeros((n, 2)), np.arange(n, dtype=float),
                         AREA, np.zeros((n, 2)), NORMAL, np.zeros((n, 2)), ["stick"] * n)


def test_output_series_numbers_the_outputs_and_writes_pvd_and_csv(tmp_path):
    series = OutputSeries(tmp_path)
    assert series.files() == (tmp_path / "bulk_0000.vtu", tmp_path / "fractures_0000.vtu")
    series.add(0.0, _block(0, 0.0))
    assert series.files() == (tmp_path / "bulk_0001.vtu", tmp_path / "fractures_0001.vtu")
    series.add(5.0, _block(3, 5.0))
    series.write()
    assert series.count == 2
    assert series.pvd == [(0.0, "bulk_0000.vtu", 0), (0.0, "fractures_0000.vtu", 1),
                          (5.0, "bulk_0001.vtu", 0), (5.0, "fractures_0001.vtu", 1)]
    pvd = (tmp_path / "solution.pvd").read_text()
    assert pvd.index('file="bulk_0000.vtu"') < pvd.index('file="fractures_0001.vtu"')
    rows = list(csv.DictReader(open(tmp_path / "fractures.csv")))
    assert [(r["step"], r["time"], r["fracture"], r["face"]) for r in rows] == [
        ("0", "0", "F1", "0"), ("0", "0", "F1", "1"), ("0", "0", "F2", "2"),
        ("3", "5", "F1", "0"), ("3", "5", "F1", "1"), ("3", "5", "F2", "2")]


class FakeModel:
    """The parts of a Poromechanics model the recorder reads: the jump is the state's u per face,
    the cell pressure its p, the aperture and p_f fixed multiples of them."""

    mech = SimpleNamespace(face_area=AREA, normal=NORMAL, n_c=3, face_values=lambda v: v,
                           law=SimpleNamespace(friction_law=Coulomb(np.array([0.6, 0.6, 0.8]))))
    n_ff = 3

    def jumps(self, u):
        return u

    def cell_pressure(self, st):
        return st.p

    def fracture_quantities(self, st):
        return {"aperture": 1e-4 * (1 + st.time) * np.ones(3), "p_f": np.array([1.0, 2.0, 3.0]) * st.time}


def _state(t, p, u, state, lam=None):
    return SimpleNamespace(time=t, p=np.asarray(p, float), u=np.asarray(u, float), state=np.asarray(state),
                           lam=np.zeros((3, 2)) if lam is None else np.asarray(lam, float))


def _info(iterations, growth, linear=None):
    return {"info": SimpleNamespace(iterations=iterations, residual=1e-12, open=0, stick=2, slip=1, history=[1.0],
                                    linear_iterations=linear, conductivity_growth=growth, energy=None), "dt": 5.0}


@pytest.fixture
def recorder():
    geometry = SimpleNamespace(cell_volume=np.ones(3), cell_centroid=np.array([[0.0, 0], [1, 0], [2, 0]]),
                               face_centroid=np.array([[0.5, 0.5], [1.5, 0.5], [2.0, 1.0], [9, 9]]))
    net = SimpleNamespace(names=("F1", "F2"), fracture=np.array([0, 0, 1]), faces=np.array([0, 1, 2]))
    fm = SimpleNamespace(mesh=SimpleNamespace(geometry=geometry), network=net)
    start = _state(0.0, [0, 0, 0], np.zeros((3, 2)), [1, 1, 1])
    return PoroRecorder(FakeModel(), fm, np.arange(3.0), {"a": 2}, {"W": np.array([0, 1])}, np.zeros(3),
                        np.zeros(3), start, growth_limit=None), start


def test_poro_recorder_records_two_steps(recorder, caplog):
    rec, start = recorder
    rec.record(start)
    # step 1: face 2 (F2) slips 2 mm tangentially; one schedule step in two sub-steps, 3 + 2 Newton iterations
    st = _state(5.0, [1.0, 4.0, 2.0], [[0.0, 0.0], [0.0, 0.0], [0.0, 0.002]], [1, 1, 2])
    step = StepRecord(1, 5.0, 5.0, seconds=0.5, substeps=[_info(3, 2.0, [4, 5]), _info(2, 5e3, [6])],
                      failed=[{"from": 0.0, "to": 5.0, "reason": "no convergence", "newton_iterations": 7}])
    step.info = step.substeps[-1]
    with caplog.at_level(logging.WARNING, logger="polypore"):
        row = rec.step_row(step)
        rec.record(st)
    assert row == {"time": 5.0, "dt": 5.0, "newton_iterations": 5, "residual": 1e-12, "open": 0, "stick": 2,
                   "slip": 1, "seconds": 0.5, "cuts": 0, "history": [1.0],
                   "substeps": {"accepted": 2, "rejected": 0, "kept_above_limit": 0, "smallest_dt": 5.0},
                   "linear_iterations": [4, 5, 6], "failed_attempts": step.failed, "conductivity_growth": 5e3}
    assert rec.warned_at == 1 and "conductivity grew up to 5.0e+03-fold" in caplog.text
    # area-weighted fracture means (aperture, p_f): F1 of faces 0, 1 (areas 1, 3), F2 of face 2
    assert rec.series == [{"time": 0.0, "F1": (1e-4, 0.0), "F2": (1e-4, 0.0)},
                          {"time": 5.0, "F1": pytest.approx((6e-4, 8.75)), "F2": pytest.approx((6e-4, 15.0))}]
    assert rec.monitor["time"] == [0.0, 5.0]
    assert rec.monitor["points"] == {"a": [0.0, 2.0]}
    assert rec.monitor["fault_p"] == {"F1": [0.0, 10.0], "F2": [0.0, 15.0]}
    assert rec.monitor["fault_slip"] == {"F1": [0.0, 0.0], "F2": [0.0, pytest.approx(0.002)]}
    assert rec.onset == {"time": 5.0, "previous_time": 0.0, "faces": 1, "first_slipping_faces": [[2.0, 1.0]]}
    assert rec.check_energy() == []
    s = rec.summary({"faces": 0})
    assert list(s) == ["steps", "energy_check", "conductivity_growth", "fracture_means", "slip_onset",
                       "slip_bubble", "monitor"]
    assert s["steps"] == [row] and s["energy_check"] == {"violations": [], "steps_checked": 0}
    assert s["conductivity_growth"] == {"max": 5e3, "warned_at_step": 1, "warn_above": CONDUCTIVITY_GROWTH_WARN,
                                        "step_limit": None, "substeps": 2, "rejected": 0}
    mon = s["monitor"]
    assert mon["overpressure_at_points"] == {"a": [0.0, 2.0]} and mon["points"] == {"a": [2.0, 0.0]}
    assert mon["slip_area_fraction"] == {"F1": [0.0, 0.0], "F2": [0.0, 1.0]}
    assert mon["wells"] == {"W": {"cells": 2, "mean_overpressure": [0.0, 2.5], "max_overpressure": [0.0, 4.0]}}
    assert rec.totals() == {"newton_iterations": 5, "newton_iterations_failed": 7, "linear_iterations_failed": 0}


def test_fault_stress_is_measured_from_the_start(recorder):
    """ΔCFS = Δ|λ_τ| − μ Δλ_n per face against the recorder's initial state, μ the law's
    coefficient per face; the slip tendency |λ_τ|/λ_n, NaN on an open face."""
    rec, _ = recorder
    start = _state(0.0, [0, 0, 0], np.zeros((3, 2)), [1, 1, 1], lam=[[1.0, 10.0], [-2.0, 10.0], [0.0, 5.0]])
    rec2 = PoroRecorder(FakeModel(), rec.fm, np.arange(3.0), {}, {}, np.zeros(3), np.zeros(3), start)
    # faces 0, 1: normal (0, 1) (NORMAL), face 2 open at the end
    now = _state(1.0, [0, 0, 0], np.zeros((3, 2)), [1, 2, 0], lam=[[3.0, 9.0], [-1.0, 12.0], [0.0, 0.0]])
    f = rec2.fault_stress(now)
    n = NORMAL
    for i, mu in enumerate([0.6, 0.6, 0.8]):
        sn0, sn = start.lam[i] @ n[i], now.lam[i] @ n[i]
        t0 = np.linalg.norm(start.lam[i] - sn0 * n[i])
        t1 = np.linalg.norm(now.lam[i] - sn * n[i])
        assert f["delta_cfs"][i] == pytest.approx((t1 - t0) - mu * (sn - sn0), abs=1e-12)
        assert f["delta_tau"][i] == pytest.approx(t1 - t0) and f["delta_sigma_n"][i] == pytest.approx(sn - sn0)
    assert f["slip_tendency"][0] == pytest.approx(np.linalg.norm(now.lam[0] - (now.lam[0] @ n[0]) * n[0])
                                                  / (now.lam[0] @ n[0]))
    assert f["delta_cfs"][0] == pytest.approx(2.6)          # τ 1 → 3, σ_n′ 10 → 9: 2 + 0.6
    assert np.isnan(f["slip_tendency"][2])
