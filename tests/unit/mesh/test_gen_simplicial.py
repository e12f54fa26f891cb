"""gmsh simplicial meshes of the built-in case geometries: exact geometry, conformity, node sides."""

import logging

import numpy as np
import pytest
from scipy.spatial import cKDTree

from polypore.core.errors import InputError, MeshError
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.fractures import BOUNDARY, INTERIOR, INTERSECTION, KINK, TIP, validate_spec
from polypore.mesh.generators.simplicial import simplicial_mesh
from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh

gmsh = pytest.importorskip("gmsh")


def _fm(name, *overrides):
    return build_fractured_mesh(load_case(name, list(overrides)))


def _check_measures(fm):
    """Every fracture face found: the fracture faces cover each fracture's measure exactly."""
    net, g = fm.network, fm.mesh.geometry
    for i, spec in enumerate(net.specs):
        want = validate_spec(spec, fm.mesh.dim)["measure"]
        got = g.face_area[net.faces[net.fracture == i]].sum()
        assert abs(got - want) <= 1e-10 * want, (spec.name, got, want)


def _nodes_only_of(net, kind, *exclude):
    others = np.concatenate([net.nodes_of_kind(k) for k in exclude]) if exclude else np.zeros(0, int)
    return np.setdiff1d(net.nodes_of_kind(kind), others)


def _dist_to_polyline(X, V):
    d = np.full(len(X), np.inf)
    for a, b in zip(V[:-1], V[1:]):
        t = b - a
        s = np.clip((X - a) @ t / (t @ t), 0, 1)
        d = np.minimum(d, np.linalg.norm(X - a - s[:, None] * t, axis=1))
    return d


@pytest.fixture(scope="module")
def c1():
    return _fm("frictionless-3d", "mesh.size=0.5")


@pytest.fixture(scope="module")
def c5():
    return _fm("dfm-3d", "mesh.size=0.2")


def test_c1_t_network(c1, exact_geometry):
    mesh, net = c1.mesh, c1.network
    assert mesh.dim == 3 and mesh.cell_faces.counts.max() == 4
    exact_geometry(mesh, volume=8.0)
    _check_measures(c1)
    # sides from the geometry: 1 + [on Γ1 (z = 0)] + [on Γ2 (x = 0, z <= 0)]
    X = mesh.nodes
    tol = 1e-10
    on1 = np.abs(X[:, 2]) < tol
    on2 = (np.abs(X[:, 0]) < tol) & (X[:, 2] < tol)
    np.testing.assert_array_equal(c1.side_counts(), 1 + on1 + on2)
    line = on1 & on2 & (np.abs(X[:, 1]) < 1 - tol)
    assert line.sum() >= 3 and np.all(c1.side_counts()[line] == 3)
    # the intersection is one line of edges, each with 2 faces of Γ1 and 1 of Γ2 (none dropped)
    inter = net.edge_kind == INTERSECTION
    assert inter.any()
    assert np.all(net.edge_faces.counts[inter] == 3)
    assert set(net.nodes_of_kind(INTERSECTION)) == set(np.flatnonzero(on1 & on2))
    assert not np.any(net.edge_kind == TIP)


def test_c5_network(c5, exact_geometry):
    mesh, net = c5.mesh, c5.network
    exact_geometry(mesh, volume=1.0)
    _check_measures(c5)
    rep = c5.report()
    assert rep["F1"]["intersects"] == ["F2"] and rep["F2"]["intersects"] == ["F1"]
    assert rep["F4"]["reaches_boundary"] and not rep["F3"]["reaches_boundary"]
    assert rep["F3"]["tips"] >= 6  # the hexagon's six sides
    sides = c5.side_counts()
    inner = _nodes_only_of(net, INTERIOR, TIP, BOUNDARY, INTERSECTION)
    assert inner.size and np.all(sides[inner] == 2)
    tips = np.setdiff1d(net.nodes_of_kind(TIP), np.concatenate(
        [net.nodes_of_kind(BOUNDARY), net.nodes_of_kind(INTERSECTION)]))
    assert tips.size and np.all(sides[tips] == 1)
    # F1 × F2 cross along a segment: each intersection edge has 2 + 2 faces, inner nodes 4 sides
    inter = net.edge_kind == INTERSECTION
    assert inter.any() and np.all(net.edge_faces.counts[inter] == 4)
    cross = np.setdiff1d(net.nodes_of_kind(INTERSECTION), net.nodes_of_kind(TIP))
    assert cross.size and np.all(sides[cross] == 4)
    # F4's edge on y = 0 (not its corners) separates the boundary node into 2 sides
    bnd = np.setdiff1d(net.nodes_of_kind(BOUNDARY), net.nodes_of_kind(TIP))
    assert bnd.size and np.all(np.abs(mesh.nodes[bnd, 1]) < 1e-12) and np.all(sides[bnd] == 2)


def test_c3_single_crack_grading(exact_geometry):
    fm = _fm("single-crack", "mesh.size=10", "mesh.fracture_size=0.25")
    mesh, net = fm.mesh, fm.network
    assert mesh.dim == 2 and mesh.nodes.shape[1] == 2
    exact_geometry(mesh, volume=6400.0)
    _check_measures(fm)
    g = mesh.geometry
    # fine along the crack, coarse in the bulk
    assert g.face_area[net.faces].max() < 1.5 * 0.25
    assert 5 < g.cell_diameter.max() < 1.6 * 10
    sides = fm.side_counts()
    tips = net.nodes_of_kind(TIP)
    assert tips.size == 2 and np.all(sides[tips] == 1)
    np.testing.assert_allclose(np.sort(np.abs(mesh.nodes[tips, 0])), [0.9396926207859084] * 2, rtol=1e-12)
    inner = net.nodes_of_kind(INTERIOR)
    assert inner.size >= 6 and np.all(sides[inner] == 2)
    assert sides.sum() == mesh.n_nodes + inner.size


def test_c4_six_fractures(exact_geometry):
    fm = _fm("dfm-2d", "mesh.size=0.1", "mesh.fracture_size=0.05")
    mesh, net = fm.mesh, fm.network
    exact_geometry(mesh, volume=2.0)
    _check_measures(fm)
    X = mesh.nodes
    sides = fm.side_counts()
    # sides from the geometry: 2 on a fracture except at its tips (no crossings in C4)
    on = np.zeros(len(X), bool)
    tip = np.zeros(len(X), bool)
    for spec in net.specs:
        V = np.asarray(spec.vertices)
        on |= _dist_to_polyline(X, V) < 1e-10
        for end in (V[0], V[-1]):
            if np.all((end > 0) & (end < [2.0, 1.0])):
                tip |= np.linalg.norm(X - end, axis=1) < 1e-10
    assert tip.sum() == 11  # F5 reaches x = 2
    np.testing.assert_array_equal(sides, 1 + (on & ~tip))
    kink = net.nodes_of_kind(KINK)
    assert kink.size == 1
    np.testing.assert_allclose(X[kink[0]], [0.5, 0.7], atol=1e-14)
    assert sides[kink[0]] == 2
    assert np.array_equal(np.sort(net.nodes_of_kind(TIP)), np.flatnonzero(tip))
    bnd = net.nodes_of_kind(BOUNDARY)
    assert bnd.size == 1 and np.allclose(X[bnd[0]], [2.0, 0.55]) and sides[bnd[0]] == 2


def test_c6_layers_and_fault(exact_geometry):
    fm = _fm("fault-injection", "mesh.size=200", "mesh.fracture_size=100")
    mesh, net = fm.mesh, fm.network
    exact_geometry(mesh, volume=2000.0 * 2000.0)
    _check_measures(fm)
    assert not np.any(net.edge_kind == TIP)
    vol = np.bincount(mesh.cell_region, weights=mesh.geometry.cell_volume)
    thick = {"upper_aquifer": 800, "upper_caprock": 150, "reservoir": 100, "lower_caprock": 150,
             "lower_aquifer": 800}
    for i, name in enumerate(mesh.region_names):
        assert abs(vol[i] - 2000.0 * thick[name]) < 1e-9 * vol[i], name
    # the fault crosses the whole section: each of its nodes has 2 sides, the rest 1
    on = _dist_to_polyline(mesh.nodes, np.asarray(net.specs[0].vertices)) < 1e-8
    np.testing.assert_array_equal(fm.side_counts(), 1 + on)


def test_reproducible_and_logged(caplog):
    spec = [FractureSpec("a", np.array([[0.2, 0.2], [0.8, 0.7]])), FractureSpec("b", np.array([[0.2, 0.8], [0.8, 0.3]]))]
    with caplog.at_level(logging.INFO, logger="polypore"):
        m1 = simplicial_mesh([0, 0], [1, 1], spec, 0.2, fracture_size=0.1, seed=3)
    assert "triangles" in caplog.text
    m2 = simplicial_mesh([0, 0], [1, 1], spec, 0.2, fracture_size=0.1, seed=3)
    np.testing.assert_array_equal(m1.nodes, m2.nodes)
    fm = FracturedMesh.build(m1, spec)
    # two crossing fractures: the crossing node has 4 sides
    X = m1.nodes[fm.network.nodes_of_kind(INTERSECTION)]
    assert X.shape[0] == 1 and fm.side_counts()[fm.network.nodes_of_kind(INTERSECTION)[0]] == 4
    _check_measures(fm)


def test_interfaces_conform_without_refinement():
    itf = [FractureSpec("i", np.array([[0.0, 0.0, 0.3], [1.0, 0.0, 0.3], [1.0, 1.0, 0.3], [0.0, 1.0, 0.3]]))]
    mesh = simplicial_mesh([0, 0, 0], [1, 1, 1], [], 0.4, fracture_size=0.05, interfaces=itf)
    c = mesh.geometry.cell_centroid
    below = c[:, 2] < 0.3
    assert abs(mesh.geometry.cell_volume[below].sum() - 0.3) < 1e-12
    assert mesh.n_cells < 2000  # fracture_size does not apply to interfaces


def test_bad_input():
    with pytest.raises(InputError, match="^size:"):
        simplicial_mesh([0, 0], [1, 1], [], 0.0)
    with pytest.raises(InputError, match="^upper:"):
        simplicial_mesh([0, 0], [1, -1], [], 0.1)
    with pytest.raises(InputError, match="^fracture out:.*outside the domain"):
        simplicial_mesh([0, 0], [1, 1], [FractureSpec("out", np.array([[0.5, 0.5], [1.5, 0.5]]))], 0.1)


def test_gmsh_failure_is_mesh_error(monkeypatch):
    def boom(*args, **kwargs):
        raise Exception("PLC Error: a segment and a facet intersect at a point")

    monkeypatch.setattr(gmsh.model.mesh, "generate", boom)
    with pytest.raises(MeshError, match="gmsh could not mesh.*PLC Error"):
        simplicial_mesh([0, 0, 0], [1, 1, 1], [], 0.5)
    assert not gmsh.isInitialized()


def test_caller_session_kept():
    gmsh.initialize([], readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("caller")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 7.0)
        mesh = simplicial_mesh([0, 0], [1, 1], [], 0.5)
        assert mesh.n_cells > 0
        assert gmsh.isInitialized() and gmsh.model.getCurrent() == "caller"
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 7.0
    finally:
        gmsh.finalize()


def test_tip_refinement_2d_and_its_input_check():
    from polypore.core.errors import InputError
    from polypore.mesh import FracturedMesh, FractureSpec
    from polypore.mesh.generators.simplicial import simplicial_mesh

    crack = [FractureSpec("c", np.array([[-0.5, 0.0], [0.5, 0.0]]))]
    plain = FracturedMesh.build(simplicial_mesh([-2, -2], [2, 2], crack, 0.5, fracture_size=0.05), crack)
    tipped = FracturedMesh.build(simplicial_mesh([-2, -2], [2, 2], crack, 0.5, fracture_size=0.05, tip_size=0.005),
                                 crack)

    def tip_face_length(fm):
        g = fm.mesh.geometry
        f = fm.network.faces
        c = g.face_centroid[f]
        near = np.linalg.norm(np.abs(c) - [0.5, 0.0], axis=1).argmin()
        return g.face_area[f][near]

    assert tip_face_length(tipped) < 0.6 * tip_face_length(plain)
    assert tipped.network.n_faces > plain.network.n_faces
    with pytest.raises(InputError, match="^tip_size:"):
        simplicial_mesh([0, 0, 0], [1, 1, 1], [], 0.5, tip_size=-0.01)


def _reflect(X, a, b):
    """Reflect points X (n, 2) about the line through a and b."""
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([t[1], -t[0]])
    return X - 2.0 * ((X - a) @ n)[:, None] * n


def _assert_mirrored(mesh, centre, a, b, half_t, half_n):
    """The triangles inside the rectangle centre ± half_t t ± half_n n (t along a→b) are
    mapped onto each other by the reflection about the line ab; none straddles the line."""
    X = mesh.nodes
    cells = mesh.cell_nodes.values.reshape(-1, 3)
    centroid = X[cells].mean(axis=1)
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([t[1], -t[0]])
    inside = (np.abs((centroid - centre) @ t) < half_t) & (np.abs((centroid - centre) @ n) < half_n)
    assert inside.sum() > 50
    tri = X[cells[inside]]
    mirrored = _reflect(tri.reshape(-1, 2), a, b).reshape(tri.shape)

    def key(T):  # a triangle as its vertices in lexicographic order, (m, 6)
        order = np.lexsort((T[..., 1], T[..., 0]), axis=1)
        return np.take_along_axis(T, order[..., None], axis=1).reshape(len(T), 6)

    dist, _ = cKDTree(key(tri)).query(key(mirrored))
    assert dist.max() < 1e-9 * half_t
    side = np.sign(((tri - a) @ n).round(12))
    assert not np.any((side.max(axis=1) > 0) & (side.min(axis=1) < 0))


@pytest.mark.parametrize("tip_size", [None, 0.01])
def test_mirror_fractures_band_is_symmetric_about_each_crack(tip_size):
    cracks = [FractureSpec("a", np.array([[-0.9, -0.3], [0.1, 0.1]])),
              FractureSpec("b", np.array([[0.6, 1.2], [1.3, 0.9]]))]
    mesh = simplicial_mesh([-2, -2], [2, 2], cracks, 0.5, fracture_size=0.05, mirror="fractures", tip_size=tip_size)
    _check_measures(FracturedMesh.build(mesh, cracks))
    for spec in cracks:
        a, b = spec.vertices
        L = np.linalg.norm(b - a)
        _assert_mirrored(mesh, 0.5 * (a + b), a, b, 0.75 * L, 0.25 * L)


def test_mirror_tips_on_a_network():
    """Patches at the tips of a kinked fracture and of one reaching the boundary; a T-junction
    end and a boundary end get none; a patch shrinks to keep clear of a nearby fracture."""
    from polypore.mesh.generators.mirror import mirror_regions

    fr = [FractureSpec("kinked", np.array([[-1.5, 0.0], [-0.5, 0.2], [0.5, 0.0]])),
          FractureSpec("edge", np.array([[1.0, -1.0], [2.0, -1.5]])),        # ends on the boundary x = 2
          FractureSpec("tee", np.array([[-1.0, -1.0], [-1.0, 0.1]])),       # ends on "kinked"
          FractureSpec("near", np.array([[0.55, 0.2], [1.2, 0.9]]))]       # its tip 0.21 from kinked's
    regions = mirror_regions("tips", fr, [-2, -2], [2, 2], fracture_size=0.02)
    labels = sorted(r.label.split(" at ")[0] for r in regions)
    assert labels == ["tip of 'edge'", "tip of 'kinked'", "tip of 'kinked'", "tip of 'near'", "tip of 'near'",
                      "tip of 'tee'"]
    half = {r.label: np.linalg.norm(r.upper[1] - r.upper[0]) / 2 for r in regions}
    kinked_right = half["tip of 'kinked' at [0.5, 0.0]"]
    assert kinked_right < 0.1 * np.hypot(1.0, 0.2) - 1e-6  # shrunk: "near" starts 0.21 m away
    mesh = simplicial_mesh([-2, -2], [2, 2], fr, 0.5, fracture_size=0.02, mirror="tips")
    _check_measures(FracturedMesh.build(mesh, fr))
    for r in regions:
        centre = r.upper[0] + 0.5 * (r.upper[1] - r.upper[0])
        h = np.linalg.norm(r.upper[1] - r.upper[0]) / 2
        _assert_mirrored(mesh, centre, r.upper[0], r.upper[1], 0.9 * h, 0.9 * h)


def test_mirror_input_checks():
    kinked = FractureSpec("k", np.array([[-0.5, 0.0], [0.0, 0.1], [0.5, 0.0]]))
    with pytest.raises(InputError, match="^mirror:.*'k' has 2 segments"):
        simplicial_mesh([-2, -2], [2, 2], [kinked], 0.5, fracture_size=0.05, mirror="fractures")
    edge = FractureSpec("e", np.array([[-1.9, 0.0], [0.0, 0.0]]))
    with pytest.raises(InputError, match="^mirror:.*'e'.*leaves the domain"):
        simplicial_mesh([-2, -2], [2, 2], [edge], 0.5, fracture_size=0.05, mirror="fractures")
    close = [FractureSpec("p", np.array([[-0.5, 0.0], [0.5, 0.0]])),
             FractureSpec("q", np.array([[-0.5, 0.4], [0.5, 0.4]]))]
    with pytest.raises(InputError, match="^mirror:.*'p'.*'q' overlap"):
        simplicial_mesh([-2, -2], [2, 2], close, 0.5, fracture_size=0.05, mirror="fractures")
    crossing = FractureSpec("x", np.array([[0.0, -0.2], [0.0, -1.5]]))  # a region interface into the band of "p"
    with pytest.raises(InputError, match="^mirror:.*'p' meets 'x'"):
        simplicial_mesh([-2, -2], [2, 2], [close[0]], 0.5, fracture_size=0.05, mirror="fractures",
                        interfaces=[crossing])
    with pytest.raises(InputError, match="^mirror:.*2D"):
        simplicial_mesh([0, 0, 0], [1, 1, 1], [], 0.5, mirror="tips")
    with pytest.raises(InputError, match="^mirror:.*unknown value 'yes'.*none, tips, fractures"):
        simplicial_mesh([-2, -2], [2, 2], [close[0]], 0.5, mirror="yes")
    through = FractureSpec("t", np.array([[-2.0, 0.0], [2.0, 0.5]]))
    with pytest.raises(InputError, match="^mirror:.*no fracture tip"):
        simplicial_mesh([-2, -2], [2, 2], [through], 0.5, mirror="tips")
