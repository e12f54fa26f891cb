"""3D mirror-symmetric meshing about planar fractures (``mesh.mirror = "fractures"``)."""


import numpy as np
import pytest
from scipy.spatial import cKDTree

from polypore.core.errors import InputError
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.fractures import validate_spec
from polypore.mesh.generators.mirror import mirror_regions
from polypore.mesh.generators.mirror3d import BAND
from polypore.mesh.generators.simplicial import simplicial_mesh
from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh

pytest.importorskip("gmsh")

# the cube case's fault: x in [0.2, 0.8] on the plane y = z
CUBE_FAULT = FractureSpec("F", np.array([[0.2, 0.3, 0.3], [0.8, 0.3, 0.3], [0.8, 0.7, 0.7], [0.2, 0.7, 0.7]]))


def _tets(mesh):
    return mesh.cell_nodes.values.reshape(-1, 4)


def _assert_mirrored(mesh, prism, shrink=0.98):
    """The tetrahedra whose centroids lie inside the prism (shrunk by ``shrink``) are mapped
    onto tetrahedra of the mesh by the reflection about its mid-plane; none straddles it."""
    X, T = mesh.nodes, _tets(mesh)
    local = (X[T].mean(axis=1) - prism.centre) @ prism.frame.T
    inside = np.all(np.abs(local) < shrink * prism.half, axis=1)
    assert inside.sum() > 200
    # every node of those tetrahedra has a node at its mirror image ...
    dist, image = cKDTree(X).query(prism.reflect(X[T[inside]].reshape(-1, 3)))
    assert dist.max() < 1e-9 * prism.half.max()
    # ... and the images of the tetrahedra are tetrahedra of the mesh
    key = np.sort(T, axis=1) @ (mesh.n_nodes ** np.arange(4))
    mirrored = np.sort(image.reshape(-1, 4), axis=1) @ (mesh.n_nodes ** np.arange(4))
    assert np.isin(mirrored, key).all()
    side = np.sign(((X[T[inside]] - prism.centre) @ prism.frame[2]).round(12))
    assert not np.any((side.max(axis=1) > 0) & (side.min(axis=1) < 0))
    return int(inside.sum())


def _assert_conforming(mesh, fractures, volume):
    """Positive volumes summing to the box's, boundary faces only on the box surface (a
    non-conforming seam would leave interior faces with one cell), every fracture face found."""
    g = mesh.geometry
    assert g.cell_volume.min() > 0
    assert abs(g.cell_volume.sum() - volume) < 1e-10 * volume
    lo, hi = mesh.bounding_box
    c = g.face_centroid[mesh.boundary_faces]
    on_box = np.any(np.isclose(c, lo, atol=1e-12) | np.isclose(c, hi, atol=1e-12), axis=1)
    assert on_box.all()
    fm = FracturedMesh.build(mesh, fractures)
    for i, spec in enumerate(fractures):
        want = validate_spec(spec, 3)["measure"]
        got = g.face_area[fm.network.faces[fm.network.fracture == i]].sum()
        assert abs(got - want) < 1e-10 * want
    return fm


@pytest.mark.parametrize("tip_size", [None, 0.02])
def test_cube_fault_prism_is_mirrored(tip_size):
    mesh = simplicial_mesh([0, 0, 0], [1, 1, 1], [CUBE_FAULT], 0.3, fracture_size=0.12, tip_size=tip_size,
                           mirror="fractures")
    (prism,) = mirror_regions("fractures", [CUBE_FAULT], [0, 0, 0], [1, 1, 1], fracture_size=0.12)
    # in-plane axes from the rectangle; margin BAND of its longer side (0.6), 0.15 m, shrunk to
    # 0.14 m to keep half the fracture_size (0.06 m) clear of x = 0 and x = 1
    np.testing.assert_allclose(np.abs(prism.frame[0]), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(prism.half, [0.3 + 0.14, 0.2 * np.sqrt(2) + 0.14, 0.14], rtol=1e-12)
    assert BAND * 0.6 > 0.14
    fm = _assert_conforming(mesh, [CUBE_FAULT], 1.0)
    n = _assert_mirrored(mesh, prism)
    assert n > 500 and fm.network.n_faces > 50
    if tip_size is not None:  # the √r grading towards the tip lines acts inside the prism
        g = mesh.geometry
        faces = fm.network.faces
        assert g.face_diameter[faces].min() < 0.3 * 0.12


def test_two_fractures_and_a_penny_polygon():
    """Two prisms (a hexagon with an oblique normal and a triangle) in one box, and an interface
    away from both: each prism mirrored, the mesh conforming."""
    from polypore.setup.meshing import regular_polygon

    hexagon = FractureSpec("hex", regular_polygon(np.array([-0.8, 0.2, 0.0]), 0.5, np.array([0.34, 0.2, 0.92]), 6))
    tri = FractureSpec("tri", np.array([[0.5, -0.6, -0.5], [1.3, -0.6, -0.4], [0.9, 0.2, -0.45]]))
    itf = [FractureSpec("z=1.5", np.array([[-2, -2, 1.5], [2, -2, 1.5], [2, 2, 1.5], [-2, 2, 1.5]], float))]
    fr = [hexagon, tri]
    mesh = simplicial_mesh([-2, -2, -2], [2, 2, 2], fr, 0.8, fracture_size=0.12, mirror="fractures",
                           interfaces=itf)
    _assert_conforming(mesh, fr, 64.0)
    for prism in mirror_regions("fractures", fr, [-2, -2, -2], [2, 2, 2], itf, 0.12):
        _assert_mirrored(mesh, prism)


def test_case_file_option_and_input_checks():
    fm = build_fractured_mesh(load_case("cube-slip-3d", ["mesh.front=isotropic", "mesh.mirror=fractures", "mesh.size=0.4",
                                                          "mesh.fracture_size=0.12", "mesh.tip_size=0.04"]))
    (prism,) = mirror_regions("fractures", fm.network.specs, [0, 0, 0], [1, 1, 1], fracture_size=0.12)
    _assert_mirrored(fm.mesh, prism)
    box = ([0, 0, 0], [1, 1, 1])
    with pytest.raises(InputError, match=r"^mirror:.*\"tips\" is available for 2D meshes only"):
        simplicial_mesh(*box, [CUBE_FAULT], 0.5, mirror="tips")
    # a fracture reaching the boundary: no room for the prism
    edge = FractureSpec("edge", np.array([[0.0, 0.3, 0.3], [0.8, 0.3, 0.3], [0.8, 0.7, 0.7], [0.0, 0.7, 0.7]]))
    with pytest.raises(InputError, match="^mirror:.*'edge' cannot fit"):
        simplicial_mesh(*box, [edge], 0.5, fracture_size=0.1, mirror="fractures")
    # a second fault parallel to the first, 0.1 m away: it cuts the first's prism
    near = FractureSpec("near", CUBE_FAULT.vertices + [0, 0.1, 0])
    with pytest.raises(InputError, match="^mirror:.*fracture 'F' meets 'near'"):
        simplicial_mesh(*box, [CUBE_FAULT, near], 0.5, fracture_size=0.05, mirror="fractures")
    # two small faults side by side in one plane: clear of each other, but their prisms overlap
    a = FractureSpec("a", np.array([[0.2, 0.4, 0.5], [0.45, 0.4, 0.5], [0.45, 0.6, 0.5], [0.2, 0.6, 0.5]]))
    b = FractureSpec("b", a.vertices + [0.35, 0, 0])  # prisms (margins 0.0625 m) overlap on 0.4875 < x < 0.5125
    with pytest.raises(InputError, match="^mirror:.*prisms around the fracture 'a' and the fracture 'b' overlap"):
        simplicial_mesh(*box, [a, b], 0.5, fracture_size=0.05, mirror="fractures")
    # a region interface through the prism (x up to 0.8), not through the fracture (x up to 0.7)
    itf = FractureSpec("x=0.75", np.array([[0.75, 0, 0], [0.75, 1, 0], [0.75, 1, 1], [0.75, 0, 1]], float))
    small = FractureSpec("s", np.array([[0.3, 0.4, 0.4], [0.7, 0.4, 0.4], [0.7, 0.6, 0.6], [0.3, 0.6, 0.6]]))
    with pytest.raises(InputError, match="^mirror:.*'s' meets 'x=0.75'"):
        simplicial_mesh(*box, [small], 0.5, fracture_size=0.05, mirror="fractures", interfaces=[itf])
    with pytest.raises(InputError, match="^mirror:.*at least one fracture"):
        simplicial_mesh(*box, [], 0.5, mirror="fractures")


PENNY = """
name = "penny-mirror-test"
[mesh]
generator = "simplicial"
lower = [-6.0, -6.0, -6.0]
upper = [6.0, 6.0, 6.0]
size = 3.0
fracture_size = 0.3
[[fractures]]
name = "crack"
centre = [0.0, 0.0, 0.0]
radius = 1.0
sides = 32
normal = [0.3420201433256687, 0.0, 0.9396926207859084]
[material]
E = 25.0e9
nu = 0.25
[mechanics]
bubbles = "two-sided"
[[mechanics.boundary]]
name = "xmin"
ux = 0.0
[[mechanics.boundary]]
name = "ymin"
uy = 0.0
[[mechanics.boundary]]
name = "zmin"
uz = 0.0
[[mechanics.boundary]]
name = "xmax"
traction = [-1.0e8, 0.0, 0.0]
[contact]
law = "coulomb"
friction = 0.5773502691896257
"""


def test_mirror_removes_the_lambda_n_scatter_of_a_sliding_penny_crack(tmp_path):
    """A penny crack (32-gon, radius 1 m) at ψ = 20° to a uniaxial compression σ, friction
    tan 30° < cot ψ: it slides everywhere with the uniform λ_n = σ sin²ψ. On a general mesh
    the crack-edge error scatters λ_n (tens of %) and opens faces near the rim; mirrored about
    the crack plane with two-sided bubbles, λ_n is within a few % everywhere and no face opens."""
    from polypore.runs.static import solve_static
    from polypore.models.contact import OPEN

    path = tmp_path / "penny.toml"
    path.write_text(PENNY)
    exact = 1.0e8 * np.sin(np.radians(20.0)) ** 2
    out = {}
    for mirror in ("none", "fractures"):
        # the nodal + bubble space, whose defect the mirror removes (the default "auto" takes the
        # quadratic space on these tetrahedra, which has most of it gone already: docs/defaults.md)
        problem, st, *_ = solve_static(load_case(str(path), [f"mesh.mirror={mirror}", "mechanics.order=1"]))
        ln = np.einsum("fi,fi->f", st.lam, problem.normal)
        X = problem.fm.mesh.geometry.face_centroid[problem.fm.network.faces]
        n = problem.normal[0]
        r = np.linalg.norm(X - (X @ n)[:, None] * n, axis=1)
        inner, A = r < 0.8, problem.face_area
        scatter = np.sqrt(np.sum(A[inner] * (ln[inner] - exact) ** 2) / A[inner].sum()) / exact
        out[mirror] = (int(np.sum(st.state == OPEN)), float(scatter), float(ln.min() / exact))
    (open0, scatter0, min0), (open1, scatter1, min1) = out["none"], out["fractures"]
    assert open0 > 0 and min0 < 0.5 and scatter0 > 0.15           # the defect
    assert open1 == 0 and min1 > 0.8 and scatter1 < 0.05          # gone with the mirror
    assert scatter1 < 0.2 * scatter0
