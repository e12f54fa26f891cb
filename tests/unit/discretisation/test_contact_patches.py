"""Multiplier patches on slivers (discretisation/contact_patches.py, docs/contact_patches.md)."""

import json

import numpy as np
import pytest

from polypore.cli import main
from polypore.discretisation.contact_patches import (_face_links, _face_widths, contact_patches, cross_section_ratio,
                                                     side_cross_sections, width_ratio)
from polypore.mesh.cornerpoint import fractured_mesh, process_grid
from polypore.mesh.cornerpoint.generate import FaultSpec, generate_grid
from polypore.models.inf_sup import inf_sup_constant
from polypore.models.mechanics import ContactMechanics, ContactSpec, DisplacementBC, MechanicsData


def _fault_mesh(throw, nx=4, ny=2, nz=4):
    """A 4 × 2 × 4 grid of 100 m × 100 m × 25 m cells, a vertical fault on pillar line i = 2 with
    the given throw: its faces are overlaps of 25 − throw and throw m height (slivers as
    throw → 0), no snapping."""
    grid = generate_grid(nx, ny, nz, extent=(400.0, 200.0, 100.0), faults=[FaultSpec("i", nx // 2, throw, name="F")],
                         properties=False)
    mesh, info = process_grid(grid, snap=0.0)
    return fractured_mesh(mesh, info, ["F"])


def _mechanics(fm, ratio, bubbles="face", side="regular", **kw):
    """Clamped sides and bottom (or ``bcs``), Coulomb contact with patch ratio ``ratio``, bubble
    weight ``bubbles`` and side ``side``; further MechanicsData fields in ``kw``."""
    zero = lambda X, t: np.zeros_like(X)  # noqa: E731
    bcs = kw.pop("bcs", [DisplacementBC("bottom", (0, 1, 2), zero)]
                 + [DisplacementBC(b, (0, 1), zero) for b in ("west", "east", "south", "north")])
    n = fm.mesh.n_cells
    data = MechanicsData(mu=np.full(n, 1e10), lam=np.full(n, 1e10), displacement=bcs,
                         contact=ContactSpec("coulomb", 0.6, patch_ratio=ratio), bubble_stabilisation=bubbles,
                         bubble_side=side, **kw)
    return ContactMechanics(fm, data)


@pytest.fixture(scope="module")
def inf_sup_family():
    """β on faces thinning from 1/2 to 1/1000 of the layer height: {throw: {(patch ratio, bubble
    stabilisation): β}}."""
    out = {}
    for t in (12.5, 2.5, 0.25, 0.025):
        fm = _fault_mesh(t)
        out[t] = {(r, b): inf_sup_constant(_mechanics(fm, r, b)) for r in (0.0, 0.2) for b in ("cell", "face")}
    return out


def _betas(family, key):
    return np.array([v[key] for v in family.values()])


def test_cell_scaled_bubbles_lose_the_inf_sup_like_the_root_of_the_face_ratio(inf_sup_family):
    # the measurement itself must see the defect: with the scheme's h_K^{d-2} bubble weight and
    # one multiplier per face, β ∝ √(|σ|/A_K)
    b = dict(zip(inf_sup_family, _betas(inf_sup_family, (0.0, "cell"))))
    assert b[0.025] < 0.15 * b[2.5]
    rate = np.log(b[0.25] / b[0.025]) / np.log(10.0)
    assert 0.35 < rate < 0.65


@pytest.mark.parametrize("key", [(0.2, "cell"), (0.0, "face"), (0.2, "face")])
def test_inf_sup_does_not_degrade_with_patches_or_face_scaled_bubbles(inf_sup_family, key):
    b = _betas(inf_sup_family, key)
    assert b.min() > 0.8 * b.max() and b.min() > 0.1
    if key[0] > 0:                       # patch multipliers: a subspace of the face-wise ones
        assert np.all(b >= _betas(inf_sup_family, (0.0, key[1])) - 1e-12)
    assert inf_sup_family[12.5][key] == pytest.approx(inf_sup_family[12.5][(0.0, key[1])])   # no sliver: no patch


def test_patches_are_connected_sized_and_identity_on_regular_faces():
    fm = _fault_mesh(1.0)
    P = contact_patches(fm, 0.2)
    assert not P.identity and P.patch_ratio.min() >= 0.2
    assert np.allclose(P.mean.sum(axis=1), 1.0) and np.allclose(np.linalg.norm(P.normal, axis=1), 1.0)
    assert np.all(P.fracture[P.face_patch] == fm.network.fracture)
    sizes = np.bincount(P.face_patch)
    assert sizes.max() <= 3 and np.sum(sizes > 1) > 0
    # each sliver (ratio 0.04) joined a full face of its own fault
    r = cross_section_ratio(fm)
    assert np.all(sizes[P.face_patch[r < 0.2]] > 1)
    Q = contact_patches(_fault_mesh(12.5), 0.2)
    assert Q.identity


def test_patch_contact_reproduces_a_uniform_traction():
    # a compressed bar with a slivered fault: the multipliers carry the uniform stress exactly
    fm = _fault_mesh(0.5)
    mech = _mechanics(fm, 0.2)
    assert not mech.patches.identity
    n = fm.mesh.n_cells
    sxx = -5e6
    s0 = lambda X, t: np.broadcast_to(np.diag([sxx, sxx, sxx]), (len(X), 3, 3))  # noqa: E731
    zero = lambda X, t: np.zeros_like(X)  # noqa: E731
    bcs = [DisplacementBC(b, (0, 1, 2), zero) for b in ("west", "east", "south", "north", "bottom", "top")]
    data = MechanicsData(mu=np.full(n, 1e10), lam=np.full(n, 1e10), displacement=bcs, initial_stress=s0,
                         contact=ContactSpec("coulomb", 0.6, patch_ratio=0.2))
    st = ContactMechanics(fm, data).solve(verbose=False)
    ln = np.einsum("fi,fi->f", st.lam, fm.network.normal)
    # λ = −T⁺ = −σ⁰ n⁺ (the fault is vertical; the patch normals are the faces')
    np.testing.assert_allclose(ln, -sxx, rtol=1e-8)
    assert np.all(st.state == 1)


def test_slivered_cornerpoint_run_keeps_the_energy_identity(tmp_path):
    out = tmp_path / "o"
    assert main(["run", "cornerpoint-injection", "--out", str(out), "--set", "mesh.cells=[10, 4, 4]",
                 "--set", "mesh.extent=[1000.0, 400.0, 80.0]", "--set", "mesh.faults.F1.index=5",
                 "--set", "mesh.faults.F1.throw=1.5", "--set", "mesh.faults.F2.index=2", "--set", "mesh.faults.F2.stop=6",
                 "--set", "mesh.snap=0",
                 "--set", "flow.wells.I1.column=[3, 2]", "--set", "flow.wells.I1.layers=[2, 3]",
                 "--set", "monitor.points={ well = [250.0, 150.0, -1530.0], fault = [500.0, 150.0, -1530.0] }",
                 "--set", "time.end=172800"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["energy_check"]["violations"] == [] and s["energy_check"]["steps_checked"] == 2
    mp = s["mesh"]["multiplier_patches"]
    assert mp["faces_in_shared_patches"] > 0 and mp["smallest_patch_ratio"] >= 0.2
    # the state counts of the log and summary are fracture faces, not patches
    assert all(st["open"] + st["stick"] + st["slip"] == s["mesh"]["fracture_faces"] for st in s["steps"])


def test_thickness_weight_is_the_diameter_on_regular_cells_and_softer_on_flat_ones():
    """mechanics.nodal_stabilisation = "thickness": h_K^{d−2} min(1, 4 t_K/h_K). Unchanged on
    shape-regular cells (cubes, tetrahedra of a gmsh mesh are close to regular), ≈ 4 t_K on flat
    ones, and the scheme stays exact for affine fields (the stabilisation vanishes on them)."""
    from polypore.assembly.elasticity import nodal_weight
    from polypore.mesh.generators.cartesian import cartesian_mesh

    ax = np.linspace(0, 1, 4)
    cube = cartesian_mesh([ax, ax, ax])
    assert np.allclose(nodal_weight(cube, "thickness"), nodal_weight(cube, "diameter"))
    flat = cartesian_mesh([np.array([0.0, 20.0]), np.array([0.0, 20.0]), np.array([0.0, 1.0])])   # one 20 x 20 x 1 cell
    h = np.sqrt(801.0)
    assert np.isclose(nodal_weight(flat, "diameter")[0], h)
    assert np.isclose(nodal_weight(flat, "thickness")[0], 4.0)          # 4 t_K, t_K = 400 / 400
    with pytest.raises(ValueError):
        nodal_weight(flat, "volume")


def _thin_layer_fault_mesh(high_side: bool):
    """4 × 2 × 4 cells of 100 m × 100 m × 25 m; on one side of the pillar line i = 2 layer 1 is
    1 m thick (layer 2 takes the rest). The layers' mismatch makes a fault: its faces against
    the thin cells are 1 m × 100 m, regular faces of the thin cell (|σ|/A_K = 1) and slivers of
    the 25 m cell across (0.04). ``high_side``: the thin layer on the high-index (+) side."""
    import dataclasses

    grid = generate_grid(4, 2, 4, extent=(400.0, 200.0, 100.0), faults=[FaultSpec("i", 2, 0.0)], properties=False)
    z = grid.zcorn.copy()
    cols = slice(4, 8) if high_side else slice(0, 4)
    z[cols, :, 3] = z[cols, :, 2] + 1.0
    z[cols, :, 4] = z[cols, :, 3]
    mesh, info = process_grid(dataclasses.replace(grid, zcorn=z), snap=0.0)
    return fractured_mesh(mesh, info, sorted(info.faults))


def _jump_per_traction(mech) -> np.ndarray:
    """(n_ff,) tangential jump per unit tangential traction on the face alone (m/Pa): the
    diagonal of B A⁻¹ Bᵀ over |σ| (B carries |σ|), along y."""
    import scipy.sparse.linalg as spla

    from polypore.models.inf_sup import local_rows

    A = local_rows(mech.A).tocsc()[mech.free][:, mech.free]
    B = mech.Bcv[:, mech.free].toarray()
    S = B @ spla.splu(A).solve(B.T)
    iy = np.arange(mech.fm.network.n_faces) * 3 + 1
    return S[iy, iy] / mech.face_area


def test_a_sliver_bubble_lives_in_the_cell_of_which_the_face_is_regular():
    """mechanics.bubble_side = "regular" (default, discretisation/space.py bubble_sides): the
    one-sided bubble of a face that is a sliver of the + cell but a regular face of the − cell
    lives in the − cell. With the face-scaled weight |σ|²/|K| the bubble in the large cell made
    the 100 m² face 23× more compliant per unit traction than the fault's 2,400 m² faces (the
    runaway sliver of docs/fault_bounds.md); in the thin cell it is stiffer than they are, as a
    smaller patch of a fault must be."""
    from polypore.discretisation.space import bubble_sides

    fm = _thin_layer_fault_mesh(high_side=True)
    area = fm.mesh.geometry.face_area[fm.network.faces]
    thin = np.isclose(area, 100.0)
    full = area > 2000.0
    assert thin.sum() == 2 and full.sum() >= 2
    r = area / side_cross_sections(fm)
    assert np.allclose(r[0, thin], 0.04) and np.allclose(r[1, thin], 1.0)     # a sliver of its + cell
    assert np.array_equal(bubble_sides(fm) < 0, thin) and np.all(bubble_sides(fm, "plus") == 1)
    plus, regular = (_jump_per_traction(_mechanics(fm, 0.0, side=s)) for s in ("plus", "regular"))
    assert plus[thin].min() > 10 * plus[full].max()                            # the defect, measured
    assert regular[thin].max() < 0.2 * regular[full].min()
    # where the thin cell is the + cell nothing moves
    low = _thin_layer_fault_mesh(high_side=False)
    assert np.all(bubble_sides(low) == 1)
    # both sides keep the inf-sup constant of the face-scaled weight
    assert inf_sup_constant(_mechanics(fm, 0.0)) > 0.8 * inf_sup_constant(_mechanics(low, 0.0))


def test_minus_side_bubbles_carry_a_uniform_stress_exactly():
    # the compressed block of the patch test with bubbles in − cells: λ = −σ⁰ n⁺ on every face
    fm = _thin_layer_fault_mesh(high_side=True)
    zero = lambda X, t: np.zeros_like(X)  # noqa: E731
    s = -5e6
    s0 = lambda X, t: np.broadcast_to(np.diag([s, 0.7 * s, 0.9 * s]), (len(X), 3, 3))  # noqa: E731
    bcs = [DisplacementBC(b, (0, 1, 2), zero) for b in ("west", "east", "south", "north", "bottom", "top")]
    mech = _mechanics(fm, 0.0, bcs=bcs, initial_stress=s0)
    assert np.any(mech.space.bubble_sign < 0)
    st = mech.solve(verbose=False)
    n = fm.network.normal
    expected = -np.einsum("ij,fj->fi", np.diag([s, 0.7 * s, 0.9 * s]), n)
    np.testing.assert_allclose(st.lam, expected, rtol=0, atol=1e-8 * abs(s))
    assert np.abs(st.u).max() < 1e-12


def test_wedge_faces_join_a_patch():
    """b.grdecl's pinched-out wedges: their fault faces are regular faces of the wedge by
    cross-section (the area rule keeps them alone) but centimetres to a metre wide against
    cells tens of metres thick. The width rule joins each to a neighbour: every face narrower
    than 0.2 × its thicker cell lies in a shared patch, and every patch meets both rules."""
    from test_cornerpoint import grid_of

    mesh, info = process_grid(grid_of("b.grdecl"), nonplanar="keep")
    fm = fractured_mesh(mesh, info, sorted(info.faults))
    P = contact_patches(fm, 0.2)
    wr, r = width_ratio(fm), cross_section_ratio(fm)
    # faces without a neighbour on their fault (edges only on the boundary or where faults meet)
    # cannot join: one such on b.grdecl, at fault_1's junction with fault_2
    a, b, _ = _face_links(fm)
    lone = ~np.isin(np.arange(fm.network.n_faces), np.concatenate([a, b]))
    wedge = (wr < 0.2) & ~lone
    assert wedge.sum() >= 10 and np.any(wedge & (r >= 0.2))        # faces only the width rule sees
    sizes = np.bincount(P.face_patch)
    assert np.all(sizes[P.face_patch[wedge]] > 1)
    keep = ~np.isin(np.arange(P.n), P.face_patch[lone])
    assert P.patch_ratio[keep].min() >= 0.2
    diam, thick = np.zeros(P.n), np.zeros(P.n)
    np.maximum.at(diam, P.face_patch, mesh.geometry.face_diameter[fm.network.faces])
    np.maximum.at(thick, P.face_patch, _face_widths(fm)[1])
    width = P.area / diam
    assert np.all(width[keep] >= 0.2 * thick[keep] * (1 - 1e-12))
    assert P.summary()["smallest_face_width_ratio"] == pytest.approx(wr.min())
