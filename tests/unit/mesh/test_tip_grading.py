"""3D crack-front (tip-line) grading of simplicial meshes (``mesh.tip_size``): the fracture
edges inside the box are refined down to tip_size with an r^γ law (γ = ``tip_grading``, 1/2 by
default); edges on the box boundary and intersection lines are not tip lines."""

import numpy as np
import pytest

from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.generators.simplicial import simplicial_mesh

pytest.importorskip("gmsh")


def _face_sizes(fm):
    """Centroids (n, 3) and diameters (n,) of the fracture faces."""
    g = fm.mesh.geometry
    f = fm.network.faces
    return g.face_centroid[f], g.face_diameter[f]


def _square(name, z, half=0.3, normal=(0.0, 0.0, 1.0)):
    V = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]) + 0.5 * np.array([1, 1, 0])
    return FractureSpec(name, V, np.array(normal))


def test_tip_lines_of_an_interior_fracture_are_refined():
    spec = [_square("F", 0.5)]
    plain = FracturedMesh.build(simplicial_mesh([0, 0, 0], [1, 1, 1], spec, 0.3, fracture_size=0.08), spec)
    tipped = FracturedMesh.build(simplicial_mesh([0, 0, 0], [1, 1, 1], spec, 0.3, fracture_size=0.08,
                                                 tip_size=0.01), spec)
    c, h = _face_sizes(tipped)
    edge_dist = 0.3 - np.abs(c[:, :2] - 0.5).max(axis=1)     # distance to the square's edges
    near, far = edge_dist < 0.01, edge_dist > 0.2
    assert h[near].max() < 0.035                             # fracture_size 0.08 → ≤ ~3 tip sizes at the front
    assert np.median(h[far]) > 0.05                          # the middle keeps about fracture_size
    c0, h0 = _face_sizes(plain)
    d0 = 0.3 - np.abs(c0[:, :2] - 0.5).max(axis=1)
    assert h[near].mean() < 0.5 * h0[d0 < 0.04].mean()
    # the √r law: sizes grow away from the front (faces within 0.1 of it, binned by distance)
    band = edge_dist < 0.1
    slope = np.polyfit(np.log(edge_dist[band] + 1e-3), np.log(h[band]), 1)[0]
    assert 0.2 < slope < 1.0


def test_boundary_edges_and_intersections_are_not_tip_lines():
    # a fracture across the whole box (edges on the boundary) crossed by a small one: the only
    # tip lines are the three edges of the small fracture off the big one's plane
    big = FractureSpec("big", np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], float),
                       np.array([0.0, 0.0, 1.0]))
    small = FractureSpec("small", np.array([[0.5, 0.3, 0.3], [0.5, 0.7, 0.3], [0.5, 0.7, 0.5], [0.5, 0.3, 0.5]], float),
                         np.array([1.0, 0.0, 0.0]))
    specs = [big, small]
    fm = FracturedMesh.build(simplicial_mesh([0, 0, 0], [1, 1, 1], specs, 0.3, fracture_size=0.1, tip_size=0.01),
                             specs)
    c, h = _face_sizes(fm)
    on_big = fm.network.fracture == 0
    # the big fracture: fine only near the small one's line (y ∈ [0.3, 0.7], x = 0.5), not at the box edges
    rim = on_big & ((c[:, 0] < 0.05) | (c[:, 0] > 0.95) | (c[:, 1] < 0.05) | (c[:, 1] > 0.95))
    assert h[rim].min() > 0.05
    # ... nor along the T-junction line x = 0.5, z = 0.5 (0.2 from the small fracture's tip lines)
    mid = on_big & (np.linalg.norm(c - [0.5, 0.5, 0.5], axis=1) < 0.03)
    assert mid.any() and h[mid].min() > 0.03
    # the small fracture: fine at its lower edge z = 0.3 (a tip line), and not forced fine along
    # its intersection z = 0.5 with the big fracture beyond the tips' influence
    small_f = ~on_big
    low = small_f & (c[:, 2] < 0.31) & (np.abs(c[:, 1] - 0.5) < 0.1)
    assert h[low].max() < 0.035


def _tip_law_fit(tip_grading, fracture_size, tip_size=0.02):
    """Fracture-face diameters of a square crack (tip lines all round) against the tip law
    h(r) = fracture_size (r/R)^γ floored at tip_size, R = TIP_RADIUS fracture_size: the median
    and 95th percentile of h / law and the fitted slope of log h against log r, for r in
    [3 tip_size, 0.2]."""
    from polypore.mesh.generators.simplicial import TIP_RADIUS

    spec = [_square("F", 0.5)]
    kw = {} if tip_grading is None else {"tip_grading": tip_grading}
    mesh = simplicial_mesh([0, 0, 0], [1, 1, 1], spec, 2 * fracture_size, fracture_size=fracture_size,
                           tip_size=tip_size, **kw)
    c, h = _face_sizes(FracturedMesh.build(mesh, spec))
    r = 0.3 - np.abs(c[:, :2] - 0.5).max(axis=1)
    law = np.maximum(fracture_size * (r / (TIP_RADIUS * fracture_size)) ** (tip_grading or 0.5), tip_size)
    band = (r > 3 * tip_size) & (r < 0.2)
    q = h[band] / law[band]
    return mesh, np.median(q), np.percentile(q, 95), np.polyfit(np.log(r[band]), np.log(h[band]), 1)[0]


def test_default_tip_grading_is_the_sqrt_law_unchanged():
    # the default exponent is 1/2 and builds the field expression of before: the same mesh, bit for bit
    from polypore.mesh.generators.simplicial import TIP_GRADING

    assert TIP_GRADING == 0.5
    spec = [_square("F", 0.5)]
    a = simplicial_mesh([0, 0, 0], [1, 1, 1], spec, 0.3, fracture_size=0.08, tip_size=0.02)
    b = simplicial_mesh([0, 0, 0], [1, 1, 1], spec, 0.3, fracture_size=0.08, tip_size=0.02, tip_grading=0.5)
    assert np.array_equal(a.nodes, b.nodes) and np.array_equal(a.cell_nodes.values, b.cell_nodes.values)
    _, med, p95, slope = _tip_law_fit(None, 0.15)
    assert 0.75 < med < 1.25 and p95 < 1.5
    assert 0.4 < slope < 0.7


def test_tip_grading_exponent_sets_the_size_law():
    # h = fracture_size (r/R)^γ: γ = 3/4 (quadratic displacements) followed as closely as the √r law,
    # with a steeper slope (fracture_size larger so that both meshes stay small)
    _, med, p95, slope = _tip_law_fit(0.75, 0.6)
    _, _, _, slope_half = _tip_law_fit(0.5, 0.15)
    assert 0.75 < med < 1.25 and p95 < 1.5
    assert 0.65 < slope < 0.95
    assert slope > slope_half + 0.15


def test_tip_grading_input_check():
    from polypore.core.errors import InputError

    for bad in (0.0, -0.5, 1.5, "0.75"):
        with pytest.raises(InputError, match="^tip_grading:"):
            simplicial_mesh([0, 0, 0], [1, 1, 1], [_square("F", 0.5)], 0.3, fracture_size=0.08, tip_size=0.02,
                            tip_grading=bad)


def test_tip_grading_case_key(tmp_path):
    """``mesh.tip_grading`` reaches the generator from a case file; without tip_size, or out of
    (0, 1], it is an input error naming the field."""
    import re
    from importlib.resources import files

    from polypore.core.errors import InputError
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh

    coarse = ["mesh.front=isotropic", "mesh.grading=0.4", "mesh.size=0.48", "mesh.fracture_size=0.128",
              "mesh.tip_size=0.012"]
    n = [build_fractured_mesh(load_case("cube-slip-3d", [*coarse, f"mesh.tip_grading={g}"])).mesh.n_cells
         for g in (0.5, 0.75)]
    assert n[1] > 1.3 * n[0]                 # a steeper law keeps small cells further from the edge
    with pytest.raises(InputError, match=r"mesh\.tip_grading.*\(0, 1\]"):
        load_case("cube-slip-3d", ["mesh.tip_grading=1.5"])
    src = (files("polypore.cases") / "data" / "cube-slip-3d.toml").read_text()
    path = tmp_path / "c.toml"
    without = re.sub(r"(?m)^(tip_size|front) = .*\n", "", src)
    assert without != src and "tip_grading" in without
    path.write_text(without)
    with pytest.raises(InputError, match=r"mesh\.tip_grading.*tip_size"):
        load_case(str(path))
