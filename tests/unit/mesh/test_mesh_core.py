"""Mesh layer core: builders, geometry identities, fracture mapping and node sides."""

import numpy as np
import pytest

from polypore.core.errors import InputError, MeshError
from polypore.core.ragged import Ragged
from polypore.mesh import FracturedMesh, FractureSpec, mesh_from_cells, mesh_from_polygons
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates


def _box3(n=4, include=(0.0,)):
    return cartesian_mesh([grid_coordinates(-1, 1, n, include) for _ in range(3)])


def test_mesh_is_immutable():
    m = _box3(2)
    with pytest.raises(ValueError):
        m.nodes[0, 0] = 5.0
    with pytest.raises(ValueError):
        m.geometry.cell_volume[0] = 1.0
    with pytest.raises(Exception):
        m.dim = 2


def test_cartesian_geometry_exact(exact_geometry):
    m = _box3(4)
    exact_geometry(m, volume=8.0)
    assert set(m.boundary) == {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"}
    assert all(f.size == 16 for f in m.boundary.values())
    # boundary normals point out of the domain
    g = m.geometry
    for name, axis, sgn in [("xmin", 0, -1), ("zmax", 2, 1)]:
        assert np.allclose(g.face_normal[m.boundary[name], axis], sgn)


def test_tetrahedra_with_inverted_cells(exact_geometry):
    rng = np.random.default_rng(0)
    m0 = _box3(3)
    # split each hex into 6 tets (Kuhn), then invert some of them: orientation is repaired
    hexes = []
    nodes = m0.nodes
    from polypore.mesh.generators.cartesian import cartesian_mesh as cm
    ax = [np.linspace(0, 1, 4)] * 3
    grid = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange(64).reshape(4, 4, 4)
    c = [idx[:-1, :-1, :-1], idx[1:, :-1, :-1], idx[1:, 1:, :-1], idx[:-1, 1:, :-1],
         idx[:-1, :-1, 1:], idx[1:, :-1, 1:], idx[1:, 1:, 1:], idx[:-1, 1:, 1:]]
    H = np.stack([a.ravel() for a in c], 1)
    kuhn = [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]]
    tets = np.concatenate([H[:, k] for k in kuhn])
    flip = rng.random(len(tets)) < 0.3
    tets[flip] = tets[flip][:, [1, 0, 2, 3]]
    m = mesh_from_cells(grid, {"tetra": tets})
    exact_geometry(m, volume=1.0)
    assert m.n_cells == 27 * 6


def test_polygons_mixed_shapes(exact_geometry):
    # a unit square cut into a pentagon, a triangle and a quad (given clockwise on purpose)
    nodes = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [1, 0.5], [0.4, 0.6]], float)
    polys = Ragged.from_rows([[0, 4, 6, 3][::-1], [4, 1, 5, 6], [6, 5, 2, 3]])
    m = mesh_from_polygons(nodes, polys)
    exact_geometry(m, volume=1.0)
    assert m.n_faces == 9 and m.boundary_faces.size == 6


def test_degenerate_cell_rejected():
    nodes = np.array([[0, 0], [1, 0], [2, 0]], float)
    with pytest.raises(MeshError, match="(degenerate|non-positive)"):
        mesh_from_polygons(nodes, Ragged.from_rows([[0, 1, 2]]))


def test_fracture_mapping_and_sides_3d():
    m = _box3(4)
    G1 = FractureSpec("G1", np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0.]]), normal=np.array([0, 0, 1.]))
    G2 = FractureSpec("G2", np.array([[0, -1, -1], [0, 1, -1], [0, 1, 0], [0, -1, 0.]]))
    fm = FracturedMesh.build(m, [G1, G2])
    net = fm.network
    assert np.isclose(m.geometry.face_area[net.faces_of("G1") * 0 + net.faces[net.faces_of("G1")]].sum(), 4.0)
    # n^+ points out of the + cell and along the fracture normal
    g = m.geometry
    assert np.allclose(net.normal[net.faces_of("G1")], [0, 0, 1])
    assert np.allclose(net.normal[net.faces_of("G2")], [1, 0, 0])
    d = g.face_centroid[net.faces] - g.cell_centroid[net.plus_cell]
    assert np.all(np.einsum("ki,ki->k", d, net.normal) > 0)
    counts = fm.side_counts()
    X = m.nodes
    inner = np.all(np.abs(X) < 1 - 1e-12, axis=1)
    on_z0 = np.abs(X[:, 2]) < 1e-12
    on_line = on_z0 & (np.abs(X[:, 0]) < 1e-12)
    assert np.all(counts[inner & on_line] == 3)
    assert np.all(counts[inner & on_z0 & ~on_line] == 2)
    assert np.all(counts[~on_z0 & ~((np.abs(X[:, 0]) < 1e-12) & (X[:, 2] < 0))] == 1)
    rep = fm.report()
    assert rep["G1"]["intersects"] == ["G2"] and rep["G2"]["intersects"] == ["G1"]
    assert rep["G1"]["tips"] == 0 and rep["G1"]["reaches_boundary"]


def test_sides_tips_and_kink_2d():
    ax = [grid_coordinates(0, 2, 20), grid_coordinates(0, 1, 10)]
    m = cartesian_mesh(ax)
    # an L-shaped (kinked) fracture with two tips, and a straight one reaching the boundary x=2
    L = FractureSpec("L", np.array([[0.4, 0.3], [1.0, 0.3], [1.0, 0.7]]))
    B = FractureSpec("B", np.array([[1.5, 0.5], [2.0, 0.5]]))
    fm = FracturedMesh.build(m, [L, B])
    c = fm.side_counts()
    X = m.nodes

    def node(x, y):
        return int(np.argmin(np.hypot(X[:, 0] - x, X[:, 1] - y)))
    assert c[node(0.4, 0.3)] == 1 and c[node(1.0, 0.7)] == 1          # tips
    assert c[node(1.0, 0.3)] == 2                                        # kink
    assert c[node(0.7, 0.3)] == 2 and c[node(1.0, 0.5)] == 2             # interior fracture nodes
    assert c[node(1.5, 0.5)] == 1 and c[node(2.0, 0.5)] == 2             # tip; boundary end
    rep = fm.report()
    assert rep["L"]["tips"] == 2 and rep["L"]["kinks"] == 1 and not rep["L"]["reaches_boundary"]
    assert rep["B"]["tips"] == 1 and rep["B"]["reaches_boundary"]
    # + side of a 2D fracture: on the left of the polyline
    net = fm.network
    first = net.faces_of("L")[0]
    assert np.allclose(net.normal[net.faces_of("B")], [0, -1])


def test_nonconforming_and_bad_fractures():
    m = cartesian_mesh([grid_coordinates(0, 1, 4), grid_coordinates(0, 1, 4)])
    with pytest.raises(MeshError, match="does not conform"):
        FracturedMesh.build(m, [FractureSpec("F", np.array([[0.1, 0.3], [0.9, 0.3]]))])
    with pytest.raises(InputError, match="outside the domain"):
        FracturedMesh.build(m, [FractureSpec("F", np.array([[0.25, 0.5], [1.5, 0.5]]))])
    with pytest.raises(InputError, match="zero length"):
        FracturedMesh.build(m, [FractureSpec("F", np.array([[0.25, 0.5], [0.25, 0.5], [0.5, 0.5]]))])
    with pytest.raises(InputError, match="boundary"):
        FracturedMesh.build(m, [FractureSpec("F", np.array([[0.0, 0.25], [0.0, 0.75]]))])
    m3 = _box3(2)
    with pytest.raises(InputError, match="degenerate polygon"):
        FracturedMesh.build(m3, [FractureSpec("P", np.array([[0, 0, 0], [0.5, 0, 0], [1, 0, 0.]]))])
    with pytest.raises(InputError, match="not planar"):
        FracturedMesh.build(m3, [FractureSpec("P", np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.5], [0, 1, 0.]]))])
    with pytest.raises(InputError, match="self-intersecting"):
        FracturedMesh.build(m3, [FractureSpec("P", np.array([[0, 0, 0], [1, 1, 0], [1, 0, 0], [0, 1, 0.]]))])
