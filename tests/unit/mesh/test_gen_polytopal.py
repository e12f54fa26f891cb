"""Polytopal generators: clipped Voronoi, agglomerated and perturbed meshes."""

import numpy as np
import pytest
from conftest import assert_exact_geometry, geometry_defects

from polypore.core.errors import InputError, MeshError
from polypore.mesh import FracturedMesh, FractureSpec, build_network
from polypore.mesh.generators.agglomerate import agglomerate
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.mesh.generators.perturb import _shortest_edge, perturb
from polypore.mesh.generators.voronoi import voronoi_mesh

# axis-aligned T network in the unit cube: G1 the whole plane z = 0.5, G2 the half plane x = 0.5, z < 0.5
AXIS3 = [
    FractureSpec("G1", np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]]), normal=np.array([0, 0, 1.0])),
    FractureSpec("G2", np.array([[0.5, 0, 0], [0.5, 1, 0], [0.5, 1, 0.5], [0.5, 0, 0.5]])),
]
IFACE3 = FractureSpec("I", np.array([[0, 0.25, 0], [1, 0.25, 0], [1, 0.25, 1], [0, 0.25, 1]]))   # interface y = 0.25
# 2D: T network, a fracture with two tips and an interface x = 0.75
AXIS2 = [
    FractureSpec("H", np.array([[0, 0.5], [1, 0.5]])),
    FractureSpec("V", np.array([[0.5, 0.5], [0.5, 0.0]])),
    FractureSpec("T", np.array([[0.25, 0.75], [0.625, 0.75]])),
]
IFACE2 = FractureSpec("I", np.array([[0.75, 0.0], [0.75, 1.0]]))


def _node(X, x):
    return np.all(np.abs(X - np.asarray(x)) < 1e-9, axis=1)


def check_network(mesh, specs, dim):
    """Every fracture face found; side counts: 2 inside, 1 at tips, 3 on the T line."""
    fm = FracturedMesh.build(mesh, specs)
    net = fm.network
    area = mesh.geometry.face_area
    for i, s in enumerate(specs):
        assert np.isclose(area[net.faces[net.fracture == i]].sum(), net.measures[i], rtol=1e-12)
    c = fm.side_counts()
    X = mesh.nodes
    inside = np.all((X > 1e-9) & (X < 1 - 1e-9), axis=1)
    if dim == 2:
        on_h = np.abs(X[:, 1] - 0.5) < 1e-12
        on_v = (np.abs(X[:, 0] - 0.5) < 1e-12) & (X[:, 1] < 0.5 + 1e-12)
        on_t = (np.abs(X[:, 1] - 0.75) < 1e-12) & (X[:, 0] > 0.25 - 1e-12) & (X[:, 0] < 0.625 + 1e-12)
        tips = _node(X, [0.25, 0.75]) | _node(X, [0.625, 0.75])
        assert tips.sum() == 2 and np.all(c[tips] == 1)
        assert np.all(c[_node(X, [0.5, 0.5])] == 3) and _node(X, [0.5, 0.5]).sum() == 1
        assert np.all(c[inside & (on_h ^ on_v)] == 2)
        assert np.all(c[on_t & ~tips] == 2) and np.count_nonzero(on_t & ~tips) >= 1
        assert np.all(c[~(on_h | on_v | on_t)] == 1)
    else:
        on1 = np.abs(X[:, 2] - 0.5) < 1e-12
        on2 = (np.abs(X[:, 0] - 0.5) < 1e-12) & (X[:, 2] < 0.5 + 1e-12)
        line = on1 & on2 & inside
        assert line.sum() >= 2 and np.all(c[line] == 3)
        assert np.all(c[inside & (on1 ^ on2)] == 2)
        assert np.all(c[~(on1 | on2)] == 1)
    return fm


@pytest.mark.parametrize("dim", [2, 3])
def test_voronoi_conforms_and_is_exact(dim):
    if dim == 2:
        specs, m = AXIS2, voronoi_mesh([0, 0], [1, 1], 1 / 12, AXIS2 + [IFACE2], seed=3)
        assert 130 <= m.n_cells <= 220
    else:
        specs, m = AXIS3, voronoi_mesh([0, 0, 0], [1, 1, 1], 1 / 6, AXIS3 + [IFACE3], seed=1)
        assert 200 <= m.n_cells <= 350
        assert m.geometry.face_nonplanarity.max() < 1e-10
        assert m.cell_faces.counts.max() > 6              # genuinely polyhedral
    assert_exact_geometry(m, volume=1.0, tol=1e-10)
    assert sorted(n for n, f in m.boundary.items() if f.size) == sorted(f"{a}{s}" for a in "xyz"[:dim]
                                                                       for s in ("min", "max"))
    check_network(m, specs, dim)
    # the interface is a union of faces too
    FracturedMesh.build(m, [IFACE2 if dim == 2 else IFACE3])


def test_voronoi_is_random_but_reproducible():
    a = voronoi_mesh([0, 0], [1, 1], 0.2, seed=1)
    b = voronoi_mesh([0, 0], [1, 1], 0.2, seed=1)
    c = voronoi_mesh([0, 0], [1, 1], 0.2, seed=2)
    assert np.array_equal(a.nodes, b.nodes)
    assert a.nodes.shape != c.nodes.shape or not np.allclose(a.nodes, c.nodes)
    assert a.n_cells == 25 and a.n_nodes > 36              # not a lattice (36 nodes): 3-valent vertices


def test_voronoi_rejects_oblique_fracture():
    obl = FractureSpec("F", np.array([[0.1, 0.1, 0.2], [0.9, 0.1, 0.4], [0.9, 0.9, 0.4], [0.1, 0.9, 0.2]]))
    with pytest.raises(MeshError, match="axis-aligned.*agglomerated"):
        voronoi_mesh([0, 0, 0], [1, 1, 1], 0.25, [obl])
    with pytest.raises(MeshError, match="axis-aligned"):
        voronoi_mesh([0, 0], [1, 1], 0.25, [FractureSpec("F", np.array([[0.1, 0.1], [0.8, 0.7]]))])


def _cartesian(dim, n):
    return cartesian_mesh([grid_coordinates(0, 1, n, [0.25, 0.5, 0.625, 0.75])] * dim)


def _nonconvex(mesh):
    """Number of cells whose area is smaller than their nodes' convex hull (2D)."""
    from scipy.spatial import ConvexHull
    cn = mesh.cell_nodes
    hull = np.array([ConvexHull(mesh.nodes[cn.row(k)]).volume for k in range(mesh.n_cells)])
    return int(np.count_nonzero(hull > mesh.geometry.cell_volume * (1 + 1e-9)))


@pytest.mark.parametrize("dim", [2, 3])
def test_agglomerate_keeps_fractures(dim):
    base = _cartesian(dim, 8 if dim == 2 else 4)
    specs = AXIS2 if dim == 2 else AXIS3
    iface = IFACE2 if dim == 2 else FractureSpec("I", np.array([[0, 0.75, 0], [1, 0.75, 0], [1, 0.75, 1],
                                                                [0, 0.75, 1.]]))
    keep = build_network(base, specs + [iface]).faces
    m = agglomerate(base, keep, rounds=2, seed=4)
    assert m.n_cells < 0.45 * base.n_cells
    assert_exact_geometry(m, volume=1.0)
    assert m.n_nodes <= base.n_nodes
    fm = check_network(m, specs, dim)
    assert fm.network.n_faces == build_network(base, specs).n_faces     # fracture faces are kept
    FracturedMesh.build(m, [iface])
    if dim == 2:
        assert _nonconvex(m) > 0
    else:
        assert m.cell_faces.counts.max() > 10                # unions of several hexahedra


def test_agglomerate_regions_and_rounds():
    base = _cartesian(2, 8)
    region = (base.geometry.cell_centroid[:, 0] > 0.5).astype(np.int32)
    from polypore.mesh.mesh import with_regions
    base = with_regions(base, region, ("left", "right"))
    m = agglomerate(base, [], rounds=3, seed=0)
    d = geometry_defects(m)
    assert d["closure"] < 1e-12 and d["moment"] < 1e-12
    assert np.isclose(m.volume, 1.0)
    # every merged cell lies on one side of x = 0.5 and keeps its region
    cn = m.cell_nodes
    xmax = np.maximum.reduceat(m.nodes[cn.values, 0], cn.offsets[:-1])
    assert np.array_equal(m.cell_region == 1, xmax > 0.5 + 1e-12)
    assert m.n_cells < base.n_cells / 4
    same = agglomerate(base, [], rounds=0)
    assert same.n_cells == base.n_cells


@pytest.mark.parametrize("dim", [2, 3])
def test_perturbed_cartesian(dim):
    base = _cartesian(dim, 8 if dim == 2 else 4)
    specs = AXIS2 if dim == 2 else AXIS3
    m = perturb(base, 0.3, specs + [IFACE2 if dim == 2 else IFACE3], seed=5)
    assert m.n_cells == base.n_cells and np.array_equal(m.face_nodes.values, base.face_nodes.values)
    move = np.linalg.norm(m.nodes - base.nodes, axis=1)
    assert move.max() > 0.01 and np.all(move <= 0.3 * _shortest_edge(base) * (1 + 1e-12))
    assert np.all(move[_node(base.nodes, [0.5, 0.5] if dim == 2 else [0, 0, 0])] == 0)
    assert_exact_geometry(m, volume=1.0, planar=(dim == 2))
    if dim == 3:
        assert np.count_nonzero(m.geometry.face_nonplanarity > 1e-3) > m.n_faces / 4
        assert geometry_defects(m)["centroid_moment"] > 1e-6     # non-planar faces: only the moment form is exact
    check_network(m, specs, dim)
    # the box and the interface stay in place
    assert np.allclose(m.nodes.min(0), 0) and np.allclose(m.nodes.max(0), 1)
    FracturedMesh.build(m, [IFACE2 if dim == 2 else IFACE3])


def test_perturbed_voronoi():
    v = voronoi_mesh([0, 0, 0], [1, 1, 1], 1 / 5, AXIS3, seed=2)
    m = perturb(v, 0.25, AXIS3, seed=1)
    assert np.count_nonzero(m.geometry.face_nonplanarity > 1e-6) > 0
    assert_exact_geometry(m, volume=1.0, planar=False, tol=1e-10)
    check_network(m, AXIS3, 3)


def test_perturb_too_large_raises():
    base = _cartesian(2, 8)
    with pytest.raises(MeshError, match="inverts"):
        perturb(base, 0.95, AXIS2, seed=0)
    with pytest.raises(MeshError, match="inverts"):
        perturb(_cartesian(3, 3), 0.9, AXIS3, seed=0)
    with pytest.raises(InputError, match=r"\[0, 1\)"):
        perturb(base, 1.5)
