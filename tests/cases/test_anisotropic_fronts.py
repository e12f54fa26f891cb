"""Anisotropic crack-front meshes (``mesh.front = "anisotropic"``, mesh/generators/fronts.py): thin
cells across the fracture edges, long along them (issue 13, docs/cube_slip_anisotropic.md)."""

import numpy as np
import pytest

from polypore.core.errors import InputError
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.setup.casefile import load_case

pytest.importorskip("gmsh")

from polypore.mesh.generators.fronts import front_mesh, polar_ring, ring_radii, split_prisms  # noqa: E402

CUBE_F = np.array([[0.2, 0.3, 0.3], [0.8, 0.3, 0.3], [0.8, 0.7, 0.7], [0.2, 0.7, 0.7]])
# benchmarks/cube_slip.py ANISO_SIZES at a scale s: (fracture_size, tip_size) = (0.35, 0.005) m × s
SIZES = {"size": 0.5, "fracture_size": 0.35, "tip_size": 0.005, "tip_grading": 0.6, "grading": 0.2}


def _case_keys(scale, **change):
    v = dict(SIZES, fracture_size=0.35 * scale, tip_size=0.005 * scale)
    v.update(change)
    return ["mesh.front=anisotropic"] + [f"mesh.{k}={x:.6g}" for k, x in v.items()]


def _cube_mesh(scale=2.0, **kw):
    spec = [FractureSpec("F", CUBE_F)]
    v = dict(SIZES, fracture_size=0.35 * scale, tip_size=0.005 * scale)
    v.update(kw)
    size = v.pop("size")
    return FracturedMesh.build(front_mesh([0, 0, 0], [1, 1, 1], spec, size, **v), spec)


def _closure(mesh):
    """max over cells of |Σ_σ |σ| n_Kσ| (outward normals): 0 for closed cells."""
    g = mesh.geometry
    cf = mesh.cell_faces
    vec = g.face_area[cf.values, None] * g.face_normal[cf.values] * mesh.cell_face_sign[:, None]
    owner = cf.rows_of_entries()
    s = np.stack([np.bincount(owner, weights=vec[:, k], minlength=mesh.n_cells) for k in range(3)], axis=1)
    return float(np.abs(s).max())


def test_cube_mesh_is_valid_and_conforms_to_the_fracture():
    fm = _cube_mesh(2.0)
    mesh, g = fm.mesh, fm.mesh.geometry
    assert _closure(mesh) < 1e-12
    assert g.cell_volume.min() > 0
    assert g.cell_volume.sum() == pytest.approx(1.0, rel=1e-12)
    # the fracture is a union of interior faces of the right total area
    f = fm.network.faces
    assert np.all(mesh.face_cells[f, 1] >= 0)
    assert g.face_area[f].sum() == pytest.approx(0.6 * 0.4 * np.sqrt(2.0), rel=1e-12)
    n = np.array([0.0, 1.0, -1.0]) / np.sqrt(2.0)
    assert np.abs((g.face_centroid[f] - CUBE_F[0]) @ n).max() < 1e-12
    # every boundary face lies on the box (the fill kept the slab's surface: no hidden internal boundary)
    bfaces = np.flatnonzero(mesh.face_cells[:, 1] < 0)
    named = np.concatenate([mesh.boundary[k] for k in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")])
    assert np.array_equal(np.sort(named), bfaces)


def test_front_cells_are_long_along_the_front_and_thin_across():
    fm = _cube_mesh(1.0)
    mesh, g = fm.mesh, fm.mesh.geometry
    f = fm.network.faces
    c = g.face_centroid[f]
    e2 = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
    b = (c - CUBE_F[0]) @ e2                                   # distance from the front y = z = 0.3
    near = (b < 0.01) & (c[:, 0] > 0.35) & (c[:, 0] < 0.65)     # middle of that front
    assert near.sum() >= 2
    # extent of those faces along the front (x) and across it (e2)
    X = mesh.nodes[mesh.face_nodes.take(f[near]).values].reshape(-1, 3, 3)
    along = np.ptp(X[:, :, 0], axis=1)
    across = np.ptp(X @ e2, axis=1)
    assert np.median(along / across) > 10
    # the innermost ring radius is at most tip_size
    assert across.min() <= 0.005 + 1e-12


def test_prism_split_is_conforming_for_any_numbering():
    rng = np.random.default_rng(1)
    # a column of 2 × 2 × 2 prisms (two triangles per layer, two layers) numbered at random
    base = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    X = np.array([[x, y, z] for z in (0.0, 0.5, 1.3) for x, y in base])
    tri = np.array([[0, 1, 2], [1, 3, 2]])
    prisms = np.array([np.r_[t + 4 * k, t + 4 * (k + 1)] for k in range(2) for t in tri])
    for _ in range(20):
        perm = rng.permutation(len(X))
        P, Y = perm[prisms], np.empty_like(X)
        Y[perm] = X
        T = split_prisms(P)
        E = Y[T[:, 1:]] - Y[T[:, :1]]
        vol = np.abs(np.einsum("ki,ki->k", E[:, 0], np.cross(E[:, 1], E[:, 2]))) / 6
        assert vol.min() > 1e-3 and vol.sum() == pytest.approx(1.3 * 1.0, rel=1e-12)
        faces = np.sort(np.concatenate([T[:, [0, 1, 2]], T[:, [0, 1, 3]], T[:, [0, 2, 3]], T[:, [1, 2, 3]]]), axis=1)
        _, count = np.unique(faces, axis=0, return_counts=True)
        assert count.max() == 2                  # no face shared by three cells ...
        # ... and the number of faces seen once is the surface of the column: 2 × 2 end triangles, and
        # 4 side quads per layer cut in two
        assert np.sum(count == 1) == 4 + 2 * 4 * 2


def test_ring_is_graded_and_symmetric():
    r = ring_radii(0.1, 0.005, 0.6)
    assert len(r) == 4 and r[0] == pytest.approx(0.1) and r[-1] <= 0.005 < r[-2]
    X, T = polar_ring(0.1, 8, r / 0.1)
    assert len(X) == 1 + 8 * 4
    mirror = X * [1.0, -1.0]
    d = np.linalg.norm(mirror[:, None] - X[None], axis=2).min(axis=1)
    assert d.max() < 1e-14
    E = X[T[:, 1:]] - X[T[:, :1]]
    area = 0.5 * np.abs(E[:, 0, 0] * E[:, 1, 1] - E[:, 0, 1] * E[:, 1, 0])
    assert area.sum() == pytest.approx(0.2 ** 2, rel=1e-12)


def _write_case(tmp_path, mesh_lines):
    text = ("[mesh]\n" + "\n".join(mesh_lines) + "\n[[fractures]]\nname = \"F\"\n"
            "vertices = [[0.2, 0.3, 0.3], [0.8, 0.3, 0.3], [0.8, 0.7, 0.7], [0.2, 0.7, 0.7]]\n"
            "[material]\nE = 1e10\nnu = 0.25\n")
    path = tmp_path / "case.toml"
    path.write_text(text)
    return str(path)


def test_case_keys_are_validated(tmp_path):
    with pytest.raises(InputError, match=r"^mesh.front: unknown value 'aniso'; allowed: isotropic, anisotropic"):
        load_case("cube-slip-3d", ["mesh.front=aniso"])
    with pytest.raises(InputError, match=r"^mesh.mirror: 'fractures' does not combine with front = \"anisotropic\""):
        load_case("cube-slip-3d", _case_keys(1.0) + ["mesh.mirror=fractures"])
    with pytest.raises(InputError, match=r"^mesh.front: \"anisotropic\" applies to 3D boxes"):
        load_case("single-crack", ["mesh.front=anisotropic", "mesh.tip_size=0.01"])
    box = ['lower = [0, 0, 0]', 'upper = [1, 1, 1]', 'size = 0.5']
    with pytest.raises(InputError, match=r"^mesh.front: does not apply to generator = 'voronoi' \(only to "
                                         r"simplicial\)"):
        load_case(_write_case(tmp_path, ['generator = "voronoi"', *box, 'front = "anisotropic"']))
    with pytest.raises(InputError, match=r"^mesh.tip_size: is required with front = \"anisotropic\""):
        load_case(_write_case(tmp_path, ['generator = "simplicial"', *box, 'front = "anisotropic"']))
    assert load_case("cube-slip-3d").spec.mesh.front == "anisotropic"   # the case's default (issue 13)
    case = load_case("cube-slip-3d", ["mesh.front=isotropic"])
    assert case.spec.mesh.front == "isotropic"
    assert load_case(_write_case(tmp_path, ['generator = "simplicial"', *box])).spec.mesh.front == "isotropic"


def test_fractures_it_cannot_mesh_are_refused():
    sq = lambda z, lo=0.3, hi=0.7: np.array([[lo, lo, z], [hi, lo, z], [hi, hi, z], [lo, hi, z]])  # noqa: E731
    with pytest.raises(InputError, match=r"^fracture L: .*convex"):
        V = np.array([[0.2, 0.2, 0.5], [0.8, 0.2, 0.5], [0.8, 0.8, 0.5], [0.5, 0.5, 0.5], [0.2, 0.8, 0.5]])
        front_mesh([0, 0, 0], [1, 1, 1], [FractureSpec("L", V)], 0.5, fracture_size=0.2, tip_size=0.01)
    with pytest.raises(InputError, match=r"^fracture B: is too close to the box boundary"):
        front_mesh([0, 0, 0], [1, 1, 1], [FractureSpec("B", sq(0.5, 0.0, 1.0))], 0.5, fracture_size=0.2,
                   tip_size=0.01)
    with pytest.raises(InputError, match=r"^fracture: fractures 'A' and 'C' are too close"):
        front_mesh([0, 0, 0], [1, 1, 1], [FractureSpec("A", sq(0.45)), FractureSpec("C", sq(0.5))], 0.5,
                   fracture_size=0.2, tip_size=0.01)
    # two fractures far enough apart are meshed, each with its slab
    fm = FracturedMesh.build(front_mesh([0, 0, 0], [1, 1, 1], [FractureSpec("A", sq(0.25)),
                                                               FractureSpec("C", sq(0.75))],
                                        0.5, fracture_size=0.3, tip_size=0.01), [FractureSpec("A", sq(0.25)),
                                                                                 FractureSpec("C", sq(0.75))])
    assert _closure(fm.mesh) < 1e-12
    area = fm.mesh.geometry.face_area[fm.network.faces]         # per fracture face
    assert area[fm.network.faces_of("A")].sum() == pytest.approx(0.16, rel=1e-12)
    assert area[fm.network.faces_of("C")].sum() == pytest.approx(0.16, rel=1e-12)


@pytest.mark.slow
def test_p2_on_a_coarse_anisotropic_mesh_beats_the_isotropic_default():
    """Scale 2 (9.6k unknowns, docs/cube_slip_anisotropic.md: max slip 2.2 %, slip L2 3.9 %, rim out
    3.3 %) against the case's isotropic r^0.6 mesh with 22.5k unknowns (2.7 / 7.0 / 4.6 %)."""
    from polypore.runs.static import solve_static, unknowns

    case = load_case("cube-slip-3d", ["solver.linear=auto", "mechanics.order=2"] + _case_keys(2.0))
    problem, st, _, err, _ = solve_static(case)
    assert 8_000 < unknowns(problem) < 11_000
    assert err["max_slip_error_rel"] < 0.03
    assert err["slip_L2_rel"] < 0.045 and err["slip_L2_rel_inner"] < 0.04
    assert err["open_faces"] == 0


def test_tilted_hexagon_mitres_match():
    """Corners of 120° and a plane oblique to every axis: the tubes of neighbouring edges meet on
    their mitre planes (the mesh is closed, conforming and tiles the box)."""
    from polypore.setup.meshing import regular_polygon

    n = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    spec = [FractureSpec("H", regular_polygon(np.array([0.5, 0.5, 0.5]), 0.25, n, 6), n)]
    fm = FracturedMesh.build(front_mesh([0, 0, 0], [1, 1, 1], spec, 0.4, fracture_size=0.15, tip_size=0.01,
                                        tip_grading=0.6), spec)
    g = fm.mesh.geometry
    assert _closure(fm.mesh) < 1e-12 and g.cell_volume.min() > 0
    assert g.cell_volume.sum() == pytest.approx(1.0, rel=1e-12)
    assert g.face_area[fm.network.faces].sum() == pytest.approx(1.5 * np.sqrt(3) * 0.25 ** 2, rel=1e-12)
    assert fm.network.n_faces > 6 * 4          # every edge swept with its layers
