"""Pressure stabilisation of the coupled scheme (models/poromechanics.py, "Pressure
stabilisation"): the small-step overshoot on triangles and tetrahedra, no flow through a
permeability barrier, the energy identity with its stored term on a fractured triangle
mesh, local mass conservation with the stabilisation flux, and the case-file switch."""

from __future__ import annotations

import numpy as np
import pytest

from polypore.mesh import FracturedMesh
from polypore.mesh.generators.simplicial import simplicial_mesh
from polypore.models.energy import check_energy
from polypore.models.flow import FlowData, Pressure
from polypore.models.materials import lame
from polypore.models.mechanics import DisplacementBC, MechanicsData, TractionBC
from polypore.models.poromechanics import STABILISATION, Poromechanics

E, NU, B, M, K, ETA, LOAD = 1e8, 0.25, 1.0, 1e9, 1e-13, 1e-3, 1e5
MU, LAM = lame(E, NU)
CV = K / ETA / (B * B / (LAM + 2 * MU) + 1 / M)                  # consolidation coefficient, m²/s
PU = B * M * LOAD / (LAM + 2 * MU + B * B * M)                    # undrained pressure, Pa
ZERO = lambda X, t: 0.0 * X  # noqa: E731


def sudden_load(mesh, permeability=K, **kw):
    """Unit square / cube: load on top for t > 0, drained top, rollers on the sides, fixed bottom
    (permeability in m², a number or one per cell)."""
    d = mesh.dim
    top, bot = ("ymax", "ymin") if d == 2 else ("zmax", "zmin")
    lateral = ("xmin", "xmax") if d == 2 else ("xmin", "xmax", "ymin", "ymax")

    def traction(X, t):
        v = np.zeros((len(X), d))
        v[:, -1] = -LOAD * (t > 0)
        return v

    md = MechanicsData(mu=np.full(mesh.n_cells, MU), lam=np.full(mesh.n_cells, LAM),
                       displacement=[DisplacementBC(bot, tuple(range(d)), ZERO)]
                       + [DisplacementBC(b, ("xyz".index(b[0]),), ZERO) for b in lateral],
                       traction=[TractionBC(top, traction)])
    fd = FlowData(permeability=permeability, viscosity=ETA, biot_modulus=M, biot_coefficient=B)
    return Poromechanics(FracturedMesh.build(mesh, []), md, fd, {top: Pressure(0.0)}, **kw)


def overshoot(P, thetas=(0.1, 0.03, 0.01)):
    """max over θ and cells of p_K/p_u − 1 after one step Δt = θ h²/c_v from rest (the exact
    pressure never exceeds the undrained p_u)."""
    mesh = P.fm.mesh
    h = float(np.mean(mesh.geometry.cell_volume ** (1.0 / mesh.dim)))
    st0 = P.initial_state(0.0)
    return max(float(P.cell_pressure(P.step(st0, th * h * h / CV, energy=False)[0]).max()) / PU - 1
               for th in thetas)


@pytest.mark.parametrize("dim,size", [(2, 0.1), (3, 0.3)])
def test_small_step_overshoot_on_simplices(dim, size):
    """Measured: 9.9 % (248 triangles) and 10.6 % (340 tetrahedra) without the stabilisation,
    0.035 % and 0.064 % with the default δ = 1/4 (benchmarks/biot_stabilisation.py: the same
    on finer meshes)."""
    mesh = simplicial_mesh(np.zeros(dim), np.ones(dim), [], size)
    assert STABILISATION == 0.25
    on = sudden_load(mesh)
    off = sudden_load(mesh, pressure_stabilisation=0.0)
    assert on.stabilisation == STABILISATION and on.stabilisation_weights.size > 0
    assert off.stabilisation_weights.size == 0
    assert overshoot(off) > 0.02
    assert overshoot(on) <= 0.005


def test_no_flow_through_a_permeability_barrier():
    """Unit square, tight lower half (k/10⁶) with the mesh conforming to y = 0.5, sudden load,
    drained top, steps up to 0.2 T_c: the lower half is undrained and keeps p = p_u. The
    stabilisation flux does not depend on k; without the harmonic/arithmetic permeability
    factor across the barrier it drains the tight cells at the interface by 14 % of p_u
    (measured); with it they stay within 0.04 % (0.1 % with the stabilisation off)."""
    from polypore.mesh import FractureSpec

    mesh = simplicial_mesh([0, 0], [1, 1], [], 0.1, interfaces=[FractureSpec("i", np.array([[0, 0.5], [1, 0.5]]))])
    tight = mesh.geometry.cell_centroid[:, 1] < 0.5
    P = sudden_load(mesh, permeability=np.where(tight, K / 1e6, K))
    assert P.stabilisation_weights.min() < 1e-5 * P.stabilisation_weights.max()   # the interface faces
    h = float(np.mean(mesh.geometry.cell_volume ** 0.5))
    st = P.initial_state(0.0)
    for dt in [0.03 * h * h / CV] + [0.05 / CV] * 4:
        st, _ = P.step(st, dt, energy=False)
    p = P.cell_pressure(st) / PU
    assert np.abs(p[tight] - 1).max() < 0.005
    assert p[~tight].max() < 0.6                                   # the upper half drains


def test_energy_identity_and_mass_with_stabilisation_on_fractured_triangles():
    """C4's six fractures on a coarse triangle mesh, default δ: the identity with the stored
    ½ S(p, p) closes to round-off and the estimate holds at every step (leaving out the
    stabilisation term would open a defect ~1e−5 × scale, far above round-off), and each
    cell's balance closes with the output fluxes (which include the stabilisation flux; none
    crosses a fracture)."""
    P, fs = _c4("mesh.size=0.2", "mesh.fracture_size=0.1")
    assert P.stabilisation == STABILISATION and P.n_ff > 0
    n = P.fm.mesh.n_cells
    key = lambda c: np.sort(c, axis=1) @ [n, 1]  # noqa: E731
    across = key(P.fm.mesh.face_cells[P.fm.network.faces].astype(np.int64))
    assert not np.isin(key(P.stabilisation_pairs), across).any()     # no jump penalised across Γ
    st = P.initial_state(fs.initial_pressure)
    terms = []
    mesh, g, d = P.fm.mesh, P.fm.mesh.geometry, P.dim
    for k in range(4):
        old = st
        st, info = P.step(st, 5.0, 5.0 * (k + 1))     # Δt far below h²/c (≈ 10⁴ s): the small-step regime
        e = info.energy
        terms.append(e)
        assert abs(e.defect) < 1e-11 * e.scale, e.as_dict()
        assert e.stabilisation > 0
        assert e.stabilisation == pytest.approx(0.5 * st.p @ (P.stabilisation_matrix() @ st.p), rel=1e-12)
        # without the stored stabilisation term the identity would be off by far more than round-off
        assert abs(e.delta_stabilisation) > 1e3 * abs(e.defect) + 1e-9 * e.scale
        du = st.u - old.u
        div = sum(P.mech.ops.D[j] @ du[:, j] for j in range(d))
        sol = P.flow_solution(st)
        out = np.bincount(mesh.cell_faces.rows_of_entries(), weights=sol.cell_flux, minlength=mesh.n_cells)
        res = g.cell_volume * (P.biot * div + (P.cell_pressure(st) - P.cell_pressure(old)) / P.flow.biot_modulus)
        res += 5.0 * out
        assert np.abs(res).max() < 1e-9 * 5.0 * np.abs(sol.cell_flux).max()
    assert not check_energy(terms)
    assert e.summary()["storage"] == pytest.approx(e.storage + e.stabilisation)


def _c4(*overrides):
    """The coupled model of the dfm-2d case (C4, six fractures) on a coarse triangle mesh."""
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh
    from polypore.setup.poromechanics import poro_setup

    case = load_case("dfm-2d", list(overrides))
    return poro_setup(case, build_fractured_mesh(case))[:2]


def test_case_file_switch(tmp_path, cli):
    """``[flow] pressure_stabilisation``: a negative value is refused, 0 switches the term off."""
    # the command line first: capsys then holds this run's output only
    code, _, err = cli("run", "dfm-2d", "--out", str(tmp_path / "o"), "--set", "mesh.size=0.3",
                       "--set", "flow.pressure_stabilisation=-1")
    assert code == 2 and "error: flow.pressure_stabilisation" in err and "Traceback" not in err
    assert not (tmp_path / "o" / "summary.json").exists()
    P, _ = _c4("mesh.size=0.3", "mesh.fracture_size=0.15", "flow.pressure_stabilisation=0")
    assert P.stabilisation == 0 and P.stabilisation_weights.size == 0
    P, _ = _c4("mesh.size=0.3", "mesh.fracture_size=0.15", "flow.pressure_stabilisation=0.5")
    assert P.stabilisation == 0.5 and P.stabilisation_weights.size > 0
