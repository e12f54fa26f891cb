"""polypore's BP6-QD-C (benchmarks/cases/bp6-qd.toml, docs/bp6.md "polypore's run") on its coarse
mesh for 30 days: the fault's own flow gives BP6's pressure (eq. (26), `bp6.pore_pressure`), the
injected volume is exact, the fault stays closed with the effective normal stress σ̄₀ − p_f, and
the slipping crack's edge is where the reference puts it."""

from pathlib import Path

import numpy as np
import pytest

from polypore.cases import bp6
from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh
from polypore.setup.poromechanics import poro_setup

CASE = Path(__file__).resolve().parents[2] / "benchmarks" / "cases" / "bp6-qd.toml"
DAY = bp6.DAY
P = bp6.Bp6Parameters()
H = 200.0                      # the case's fault face size (m)


@pytest.fixture(scope="module")
def run30():
    """30 daily steps of the case as written (h = 200 m, R = 50 km, QD-C): per day the face
    centroids x and the fracture quantities."""
    case = load_case(str(CASE), [f"mesh.fracture_size={H}", f"parameters.h={H}"])
    fm = build_fractured_mesh(case)
    model, fs, _ = poro_setup(case, fm)
    x = fm.mesh.geometry.face_centroid[fm.network.faces][:, 0]
    area = model.mech.face_area
    st = model.initial_state(fs.initial_pressure)
    days = {}
    for day in range(1, 31):
        st, _ = model.step(st, DAY, day * DAY)
        if day % 10 == 0:
            days[day] = model.fracture_quantities(st)
    return x, area, days


def test_fault_pressure_is_bp6s(run30):
    """p_f at the face centroids against eq. (26) at the same points (|x| ≤ 7.5 km): within
    5e-3 of the peak p(0, t_off) = 6.555 MPa (measured 3.5e-3 at 10 days, 2.2e-3 at 30: implicit
    Euler with 1-day steps and 200-m faces); the injected volume Q t is in storage exactly."""
    x, area, days = run30
    peak = bp6.pore_pressure(np.array([0.0]), P.t_off)[0]
    inner = np.abs(x) <= 7500.0
    for day, q in days.items():
        t = day * DAY
        err = np.abs(q["p_f"] - bp6.pore_pressure(x, t))[inner].max() / peak
        assert err < 5e-3, (day, err)
        stored = np.sum(1e-9 * q["p_f"] * area)                 # c_f d_f p_f |σ| (m² per m)
        assert stored == pytest.approx(1.25e-6 * t, rel=1e-9)   # Q t


def test_fault_closed_with_effective_normal_stress(run30):
    """No face opens; λ_n = σ̄₀ − p_f to 1e-3 of σ̄₀ (measured 30 kPa at 30 days: the in-plane slip
    changes the normal stress only through the mesh's asymmetry about y = 0, largest at the crack
    edges; with mesh.mirror = "fractures" and two-sided bubbles it is 24 Pa, docs/bp6.md), and
    Coulomb's |λ_τ| ≤ 0.6 λ_n holds."""
    x, area, days = run30
    for q in days.values():
        assert np.all(q["jump_n"] > -1e-9)
        assert np.abs(q["lambda_n"] - (P.sigma0 - q["p_f"])).max() < 1e-3 * P.sigma0
        assert np.all(q["lambda_t"] <= 0.6 * q["lambda_n"] * (1 + 1e-9))


def test_slipping_crack_edge_at_30_days(run30):
    """At 30 days the slip (> 1 µm) reaches the crack edge of the semi-analytical solution, a =
    869.7 m (`bp6.constant_friction_crack`), to within one face (measured: last slipped face
    centroid 900 m, tip estimate 936 m), symmetric about x = 0."""
    x, area, days = run30
    slip = days[30]["jump_t"]
    slipped = x[slip > 1e-6]
    a = 869.7
    assert a - H < slipped.max() < a + H
    assert slipped.min() == pytest.approx(-slipped.max(), abs=1e-6)
