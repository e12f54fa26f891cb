"""Cartesian (tensor-product) meshes: quadrilaterals in 2D, hexahedra in 3D.

Fractures must lie on grid lines/planes; :func:`grid_coordinates` inserts the
fractures' coordinates into the grid so that axis-aligned fractures conform.
"""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError
from ...core.ragged import INDEX, Ragged
from ..build import mesh_from_cells, mesh_from_polygons
from ..mesh import Mesh


def grid_coordinates(lo: float, hi: float, n: int, include=()) -> np.ndarray:
    """Coordinates of about n uniform cells on [lo, hi] that contain every value of ``include``.

    Each interval between consecutive required coordinates gets
    max(1, round(n * length / (hi - lo))) uniform cells.
    """
    if not hi > lo:
        raise InputError("hi", f"upper bound {hi} must exceed lower bound {lo}")
    if int(n) < 1:
        raise InputError("n", f"need at least one cell per direction, got {n}")
    req = np.unique(np.concatenate([[lo, hi], np.asarray(list(include), float)]))
    req = req[(req >= lo) & (req <= hi)]
    pieces = []
    for a, b in zip(req[:-1], req[1:]):
        k = max(1, int(round(n * (b - a) / (hi - lo))))
        pieces.append(np.linspace(a, b, k + 1)[:-1])
    pieces.append([hi])
    return np.concatenate(pieces)


def cartesian_mesh(axes, *, cell_region=None, region_names=None) -> Mesh:
    """Tensor-product mesh from per-axis node coordinates.

    Parameters
    ----------
    axes : sequence of 2 or 3 increasing 1D arrays
        Node coordinates along x, y (and z), in m.
    """
    axes = [np.asarray(a, float) for a in axes]
    dim = len(axes)
    if dim not in (2, 3):
        raise InputError("axes", f"a Cartesian mesh is 2D or 3D, got {dim} axes")
    for k, a in enumerate(axes):
        if a.ndim != 1 or a.size < 2 or np.any(np.diff(a) <= 0):
            raise InputError("axes", f"axis {'xyz'[k]} coordinates must increase strictly")
    shape = [a.size for a in axes]
    grids = np.meshgrid(*axes, indexing="ij")
    nodes = np.stack([g.ravel() for g in grids], axis=1)
    idx = np.arange(nodes.shape[0], dtype=INDEX).reshape(shape)
    if dim == 2:
        i0 = idx[:-1, :-1].ravel()
        i1 = idx[1:, :-1].ravel()
        i2 = idx[1:, 1:].ravel()
        i3 = idx[:-1, 1:].ravel()
        quads = np.stack([i0, i1, i2, i3], axis=1)
        return mesh_from_polygons(nodes, Ragged.from_dense(quads), cell_region=cell_region,
                                  region_names=region_names)
    c = [idx[:-1, :-1, :-1], idx[1:, :-1, :-1], idx[1:, 1:, :-1], idx[:-1, 1:, :-1],
         idx[:-1, :-1, 1:], idx[1:, :-1, 1:], idx[1:, 1:, 1:], idx[:-1, 1:, 1:]]
    hexes = np.stack([a.ravel() for a in c], axis=1)
    return mesh_from_cells(nodes, {"hexahedron": hexes}, cell_region=cell_region, region_names=region_names)
