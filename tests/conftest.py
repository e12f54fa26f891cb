import functools
import sys
from pathlib import Path

import numpy as np
import pytest

# Tiers (unit/<layer>, exactness, convergence, cases, mpi, structure) share a few helpers by
# importing one test module from another (test_cornerpoint's grids, test_poromechanics' Terzaghi
# constants): every tier folder is importable, as the flat folder was. Test module names stay unique.
for _tier in sorted({p.parent for p in Path(__file__).parent.rglob("test_*.py")}):
    if str(_tier) not in sys.path:
        sys.path.append(str(_tier))

# A 2D static contact case on a 4 × 4 grid that loads in milliseconds (input-check tests)
STATIC_2D = """
name = "t"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [4, 4]
[[fractures]]
name = "F"
vertices = [[0.25, 0.5], [0.75, 0.5]]
[material]
E = 1e9
nu = 0.25
[[mechanics.boundary]]
name = "ymin"
u = [0.0, 0.0]
[[mechanics.boundary]]
name = "ymax"
u = [0.0, -0.001]
[contact]
friction = 0.5
"""



def geometry_defects(mesh):
    """Largest relative defects of the per-cell geometric identities (scheme.md §3).

    Returns a dict: 'closure' max |Σ_σ |σ| n_Kσ| / h^(d-1); 'moment' max |Σ_σ M_Kσ - |K| I| / |K|;
    'centroid_moment' the same with |σ| x̄_σ ⊗ n_Kσ in place of M_Kσ (exact for planar faces);
    'face_weights' / 'cell_weights' max |Σ ω_s x_s - x̄| / h; 'min_weight' the smallest weight.
    """
    from polypore.mesh import face_moments

    g = mesh.geometry
    d = mesh.dim
    cf = mesh.cell_faces
    rows = cf.rows_of_entries()
    sgn = mesh.cell_face_sign.astype(float)
    h = g.cell_diameter
    S = np.zeros((mesh.n_cells, d))
    np.add.at(S, rows, sgn[:, None] * g.face_vector_area[cf.values])
    M = face_moments(mesh)
    T = np.zeros((mesh.n_cells, d, d))
    np.add.at(T, rows, sgn[:, None, None] * M[cf.values])
    C = np.zeros((mesh.n_cells, d, d))
    outer = g.face_centroid[:, :, None] * g.face_vector_area[:, None, :]
    np.add.at(C, rows, sgn[:, None, None] * outer[cf.values])
    I = np.eye(d)[None]
    vol = g.cell_volume[:, None, None]
    fn = mesh.face_nodes
    fx = np.zeros((mesh.n_faces, d))
    np.add.at(fx, fn.rows_of_entries(), g.face_node_weight[:, None] * mesh.nodes[fn.values])
    cn = mesh.cell_nodes
    cx = np.zeros((mesh.n_cells, d))
    np.add.at(cx, cn.rows_of_entries(), g.cell_node_weight[:, None] * mesh.nodes[cn.values])
    fsum = np.bincount(fn.rows_of_entries(), weights=g.face_node_weight)
    csum = np.bincount(cn.rows_of_entries(), weights=g.cell_node_weight)
    return {
        "closure": float((np.linalg.norm(S, axis=1) / h ** (d - 1)).max()),
        "moment": float((np.abs(T - vol * I).max(axis=(1, 2)) / g.cell_volume).max()),
        "centroid_moment": float((np.abs(C - vol * I).max(axis=(1, 2)) / g.cell_volume).max()),
        "face_weights": float((np.linalg.norm(fx - g.face_centroid, axis=1) / g.face_diameter).max()),
        "cell_weights": float((np.linalg.norm(cx - g.cell_centroid, axis=1) / h).max()),
        "weight_sums": float(max(np.abs(fsum - 1).max(), np.abs(csum - 1).max())),
        "min_weight": float(min(g.face_node_weight.min(), g.cell_node_weight.min())),
    }


def assert_exact_geometry(mesh, volume=None, planar=True, tol=1e-11):
    """Assert the geometric identities to round-off; ``planar`` adds the centroid form."""
    d = geometry_defects(mesh)
    assert d["closure"] < tol, d
    assert d["moment"] < tol, d
    if planar:
        assert d["centroid_moment"] < tol, d
    assert d["face_weights"] < tol, d
    assert d["cell_weights"] < tol, d
    assert d["weight_sums"] < tol, d
    assert d["min_weight"] >= -tol, d
    if volume is not None:
        assert abs(mesh.volume - volume) < tol * volume
    return d


@pytest.fixture
def exact_geometry():
    return assert_exact_geometry


@pytest.fixture
def cli(capsys):
    """Run ``polypore`` in-process: ``cli(*argv)`` returns (exit code, stdout, stderr)."""
    from polypore.cli import main

    def run(*argv):
        code = main(list(argv))
        out = capsys.readouterr()
        return code, out.out, out.err

    return run


@functools.lru_cache(maxsize=None)
def fractured_box(dim: int, n: int):
    """Unit square/cube, n Cartesian cells a side, one fracture with tips at y (z) = 0.5
    (x (and y) in [0.25, 0.75]). Cached: meshes are immutable."""
    from polypore.mesh import FracturedMesh, FractureSpec
    from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates

    mesh = cartesian_mesh([grid_coordinates(0, 1, n, [0.25, 0.5, 0.75])] * dim)
    if dim == 2:
        frac = [FractureSpec("F", np.array([[0.25, 0.5], [0.75, 0.5]]))]
    else:
        frac = [FractureSpec("F", np.array([[0.25, 0.25, 0.5], [0.75, 0.25, 0.5], [0.75, 0.75, 0.5],
                                            [0.25, 0.75, 0.5]]))]
    return FracturedMesh.build(mesh, frac)


def sheared_mechanics(fm, ramp: float, two_sided: bool = False):
    """MechanicsData of :func:`fractured_box`: E = 10 GPa, ν = 0.2, bottom fixed, top displaced by
    min(t/ramp, 1)(2e-4 shear, −1e-4) m, Coulomb F = 0.5: the fracture slips while loading."""
    from polypore.models.materials import lame
    from polypore.models.mechanics import ContactSpec, DisplacementBC, MechanicsData

    dim, nc = fm.mesh.dim, fm.mesh.n_cells
    mu, lam = lame(1e10, 0.2)
    top, bot = ("ymax", "ymin") if dim == 2 else ("zmax", "zmin")
    utop = np.array([2e-4, -1e-4]) if dim == 2 else np.array([2e-4, 1e-4, -1e-4])
    return MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam),
                         displacement=[DisplacementBC(bot, tuple(range(dim)), lambda X, t: 0.0 * X),
                                       DisplacementBC(top, tuple(range(dim)),
                                                      lambda X, t: np.tile(min(t / ramp, 1.0) * utop, (len(X), 1)))],
                         contact=ContactSpec("coulomb", 0.5), two_sided=two_sided)


def case(tmp_path, text, *sets, name="c.toml"):
    """The case file ``text`` written to ``tmp_path / name`` and loaded with the ``--set`` overrides ``sets``."""
    from polypore.setup.casefile import load_case

    p = tmp_path / name
    p.write_text(text)
    return load_case(str(p), sets)


# a generated 6x4x3 corner-point grid with two faults along i (tests/test_cornerpoint_*.py)
CORNERPOINT_MESH = """
[mesh]
generator = "cornerpoint"
cells = [6, 4, 3]
extent = [600.0, 400.0, 60.0]
top = 1500.0
[[mesh.faults]]
name = "F1"
axis = "i"
index = 2
throw = 25.0
[[mesh.faults]]
name = "F2"
axis = "i"
index = 4
throw = -10.0
"""
