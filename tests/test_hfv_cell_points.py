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
