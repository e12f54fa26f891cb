"""ΔCFS and slip tendency of fault faces (models/fault_stress.py) and the failure coefficient of
each friction law (issue 28's maps)."""

import numpy as np
import pytest

from polypore.models.fault_stress import coulomb_fields, normal_and_shear
from polypore.models.friction import failure_coefficient, friction_law


def _frame(rng, n):
    """n random unit normals in 3D and a unit tangent of each."""
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    t = np.cross(nrm, rng.normal(size=(n, 3)))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return nrm, t


def test_coulomb_fields_on_tilted_faces():
    """Tractions built from (σ_n′, τ) in each face's own frame give back Δτ, Δσ_n′, ΔCFS and τ/σ_n′."""
    rng = np.random.default_rng(3)
    n = 50
    nrm, t = _frame(rng, n)
    s0, tau0 = rng.uniform(1e6, 3e7, n), rng.uniform(1e6, 1e7, n)
    s1, tau1 = s0 + rng.uniform(-5e5, 5e5, n), tau0 + rng.uniform(-1e5, 1e5, n)
    s1[:5] = 0.0                                    # open at the end
    tau1[:5] = 0.0
    _, t2 = _frame(rng, n)                           # the shear rotates within the plane
    t2 -= np.einsum("fi,fi->f", t2, nrm)[:, None] * nrm
    t2 /= np.linalg.norm(t2, axis=1, keepdims=True)
    lam0 = s0[:, None] * nrm + tau0[:, None] * t
    lam1 = s1[:, None] * nrm + tau1[:, None] * t2
    mu = rng.uniform(0.3, 0.8, n)
    f = coulomb_fields(lam1, lam0, nrm, mu)
    assert np.allclose(f["delta_tau"], tau1 - tau0, atol=1e-6)
    assert np.allclose(f["delta_sigma_n"], s1 - s0, atol=1e-6)
    assert np.allclose(f["delta_cfs"], (tau1 - tau0) - mu * (s1 - s0), atol=1e-6)
    assert np.all(np.isnan(f["slip_tendency"][:5]))
    assert np.allclose(f["slip_tendency"][5:], tau1[5:] / s1[5:], rtol=1e-12)
    ln, lt = normal_and_shear(lam1, nrm)
    assert np.allclose(ln, s1, atol=1e-6) and np.allclose(lt, tau1, atol=1e-6)


def test_pressure_rise_on_a_critically_stressed_face_raises_cfs_by_mu_dp():
    """A fluid pressure rise Δp lowers σ_n′ by Δp at fixed total stress: ΔCFS = μ Δp."""
    nrm = np.array([[0.0, 1.0]])
    lam0 = np.array([[6e6, 1e7]])
    lam1 = lam0 - 2e6 * nrm
    f = coulomb_fields(lam1, lam0, nrm, np.array([0.6]))
    assert f["delta_cfs"][0] == pytest.approx(0.6 * 2e6)
    assert f["slip_tendency"][0] == pytest.approx(6e6 / 8e6)


@pytest.mark.parametrize("law, kw, expected", [
    ("coulomb", {"friction": 0.6}, 0.6),
    ("slip-weakening", {"friction": 0.7, "dynamic_friction": 0.4, "critical_slip": 1e-3}, 0.7),
    ("rate-and-state", {"friction": 0.55, "a": 0.01, "b": 0.015, "critical_slip": 1e-4, "initial_slip_rate": 1e-9},
     0.55),
    ("tresca", {"threshold": 1e6}, 0.0),
    ("frictionless", {}, 0.0),
])
def test_failure_coefficient_is_the_static_one(law, kw, expected):
    fl = friction_law(law, 4, **kw)
    assert np.array_equal(failure_coefficient(fl, 4), np.full(4, expected))
