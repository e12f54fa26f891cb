"""HFV on cells whose centroid lies outside them: the Chebyshev-centre cell point keeps the
scheme exact on affine pressures; non-star-shaped cells are rejected."""

import numpy as np
import pytest

from polypore.core.errors import MeshError
from polypore.core.ragged import Ragged
from polypore.discretisation.hfv import cell_points
from polypore.mesh import FracturedMesh, mesh_from_polygons
from polypore.models.flow import FlowData, FlowModel, Pressure


def _l_shape_mesh():
    # an L-shaped cell with thin arms (centroid outside it) and the rectangle it wraps
    nodes = np.array([[0, 0], [2, 0], [2, 2], [1.8, 2], [1.8, 0.2], [0, 0.2], [0, 2]], float)
    polys = Ragged.from_rows([[0, 1, 2, 3, 4, 5], [5, 4, 3, 6]])
    return mesh_from_polygons(nodes, polys)


def test_centroid_outside_the_cell_uses_an_interior_point_and_stays_exact():
    mesh = _l_shape_mesh()
    g = mesh.geometry
    xK = cell_points(mesh)
    # the L's centroid is outside it (no face plane at positive distance): x_K moved inside
    assert not np.allclose(xK[0], g.cell_centroid[0])
    assert (xK[0, 0] > 1.8 or xK[0, 1] < 0.2)
    assert np.allclose(xK[1], g.cell_centroid[1])

    def p(x, y, z=0.0, t=0.0):
        return 1.0 + 2.0 * x - 0.7 * y

    fm = FracturedMesh.build(mesh, [])
    data = FlowData(permeability=np.array([[2.0, 0.3], [0.3, 1.0]]), viscosity=1.0, aperture=1e-3,
                    normal_permeability=1.0)
    model = FlowModel(fm, data, {b: Pressure(p) for b in ("xmin", "xmax", "ymin", "ymax")})
    sol = model.solve_steady()
    assert np.allclose(sol.cell, p(xK[:, 0], xK[:, 1]), rtol=0, atol=1e-11)


def test_non_star_shaped_cell_is_rejected():
    # a U shape: no interior point sees all of its faces
    nodes = np.array([[0, 0], [3, 0], [3, 2], [2, 2], [2, 0.5], [1, 0.5], [1, 2], [0, 2]], float)
    mesh = mesh_from_polygons(nodes, Ragged.from_rows([[0, 1, 2, 3, 4, 5, 6, 7]]))
    with pytest.raises(MeshError, match="not star-shaped"):
        cell_points(mesh)


def test_wedge_slivers_get_well_conditioned_cell_points_and_stay_exact():
    """b.grdecl's wedge slivers (840 m wide, centimetres thick; warped faces kept whole, as its case
    has them): with x_K at the centroid their HFV matrices are near-singular (λ_min/λ_max 1e-8 at
    unit diagonal); "auto" moves x_K to the face-area mean on exactly those cells, inside them, and
    every matrix is then conditioned above SLIVER_RATIO; an affine pressure is still reproduced
    (direct solve) at the moved points where the faces are planar (warped faces split)."""
    from test_cornerpoint import BOUNDARY_NAMES, grid_of

    from polypore.discretisation.hfv import SLIVER_RATIO, conditioning, matrix_hfv
    from polypore.mesh.cornerpoint import process_grid
    from polypore.solvers.linear import LinearSolver

    mesh, info = process_grid(grid_of("b.grdecl"), nonplanar="keep")
    K = np.full(mesh.n_cells, 1e-13)
    before = matrix_hfv(mesh, K, cell_point="centroid")
    after = matrix_hfv(mesh, K)
    r0, r1 = conditioning(before), conditioning(after)
    moved = np.any(after.points != before.points, axis=1)
    assert r0.min() < 1e-7 and 0 < moved.sum() < 0.05 * mesh.n_cells
    assert np.all(r0[moved] < SLIVER_RATIO) and r1.min() >= SLIVER_RATIO
    assert np.array_equal(after.points[~moved], before.points[~moved])
    # inside: every face plane at a positive distance from the moved points
    g = mesh.geometry
    cf = mesh.cell_faces
    cell = cf.rows_of_entries()
    vec = mesh.cell_face_sign.astype(float)[:, None] * g.face_vector_area[cf.values]
    dist = np.einsum("ki,ki->k", g.face_centroid[cf.values] - after.points[cell], vec)
    assert np.all(dist[moved[cell]] > 0)
    with pytest.raises(ValueError, match="cell_point"):
        matrix_hfv(mesh, K, cell_point="middle")

    # exactness where the faces are planar: the default processing (warped faces split); some of
    # its slivers move too
    mesh, info = process_grid(grid_of("b.grdecl"))
    K = np.full(mesh.n_cells, 1e-13)
    moved = np.any(matrix_hfv(mesh, K).points != matrix_hfv(mesh, K, cell_point="centroid").points, axis=1)
    assert moved.sum() > 0
    names = [n for n in BOUNDARY_NAMES if info.boundary[n].size]
    x0 = mesh.nodes.mean(0)
    p = lambda x, y, z, t=0.0: 3.0 + (np.stack([x, y, z], -1) - x0) @ np.array([1.0, -2.0, 0.5])
    fm = FracturedMesh.build(mesh, [])
    flow = FlowModel(fm, FlowData(permeability=1e-13, viscosity=1e-3), {n: Pressure(p) for n in names},
                     solver=LinearSolver("superlu"))
    sol = flow.solve_steady()
    scale = np.abs(p(*mesh.nodes.T)).max()
    assert np.abs(sol.cell - p(*flow.assembler.hfv.points.T)).max() < 1e-11 * scale
