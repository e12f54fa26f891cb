"""The immutable polytopal mesh (scheme.md §1).

Topology conventions
--------------------
* ``face_nodes``: ordered node list of every face. In 2D a face is a segment (a, b)
  whose normal is (b - a) turned clockwise; in 3D a polygon whose normal follows
  the right-hand rule.
* ``cell_faces`` with ``cell_face_sign`` (+1: the face normal points out of the cell).
* ``face_cells[f] = (K, L)``: K is the cell the normal points out of, L the other
  one, or -1 on the boundary (boundary normals therefore point out of Ω).
* ``cell_nodes``: the sorted distinct nodes of every cell (the set V_K).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..core.errors import MeshError
from ..core.ragged import INDEX, Ragged, frozen
from .geometry import Geometry, compute_geometry


@dataclass(frozen=True, eq=False)
class Mesh:
    """Immutable polytopal mesh of a domain Ω ⊂ R^d with its geometry.

    Build it with :func:`polypore.mesh.build.mesh_from_polygons`,
    :func:`~polypore.mesh.build.mesh_from_polyhedra` or
    :func:`~polypore.mesh.build.mesh_from_cells`, not directly.

    Attributes
    ----------
    dim : int
        2 or 3.
    nodes : (n_nodes, d) float64
        Node coordinates in m.
    face_nodes, cell_faces, cell_nodes : Ragged
        Connectivity (see module docstring).
    cell_face_sign : (nnz(cell_faces),) int8
        +1 where the face normal points out of the cell, -1 otherwise.
    face_cells : (n_faces, 2) int32
        (K, L) per face, L = -1 on the boundary.
    boundary : mapping str -> (k,) int32
        Named sets of boundary faces (``xmin`` ... ``zmax`` for the bounding box
        planes, plus physical groups of imported meshes).
    cell_region : (n_cells,) int32
        Index into ``region_names`` (material tags).
    region_names : tuple of str
    geometry : Geometry
    """

    dim: int
    nodes: np.ndarray
    face_nodes: Ragged
    cell_faces: Ragged
    cell_face_sign: np.ndarray
    face_cells: np.ndarray
    cell_nodes: Ragged
    boundary: Mapping[str, np.ndarray]
    cell_region: np.ndarray
    region_names: tuple
    geometry: Geometry = field(repr=False)

    @property
    def n_nodes(self) -> int:
        return self.nodes.shape[0]

    @property
    def n_faces(self) -> int:
        return len(self.face_nodes)

    @property
    def n_cells(self) -> int:
        return len(self.cell_faces)

    @property
    def boundary_faces(self) -> np.ndarray:
        """(k,) int32 ids of all faces on ∂Ω."""
        return np.flatnonzero(self.face_cells[:, 1] < 0).astype(INDEX)

    @property
    def interior_faces(self) -> np.ndarray:
        return np.flatnonzero(self.face_cells[:, 1] >= 0).astype(INDEX)

    @property
    def bounding_box(self) -> np.ndarray:
        """(2, d) lower and upper corners."""
        return np.stack([self.nodes.min(0), self.nodes.max(0)])

    @property
    def volume(self) -> float:
        return float(self.geometry.cell_volume.sum())

    def boundary_group(self, name: str) -> np.ndarray:
        """Faces of the named boundary part; raises InputError naming the known parts."""
        try:
            return self.boundary[name]
        except KeyError:
            from ..core.errors import InputError
            raise InputError("boundary", f"unknown boundary name {name!r}; this mesh has "
                             f"{sorted(self.boundary)}") from None

    def stats(self) -> dict:
        """Counts and sizes for ``polypore mesh`` and ``summary.json``."""
        g = self.geometry
        return {
            "dim": self.dim,
            "nodes": self.n_nodes,
            "faces": self.n_faces,
            "cells": self.n_cells,
            "boundary_faces": int(self.boundary_faces.size),
            "h_max": float(g.cell_diameter.max()),
            "h_mean": float(g.cell_diameter.mean()),
            "volume": self.volume,
            "faces_per_cell": [int(self.cell_faces.counts.min()), int(self.cell_faces.counts.max())],
            "nonplanar_faces": int(np.count_nonzero(g.face_nonplanarity > 1e-10)),
            "regions": {n: int(np.count_nonzero(self.cell_region == i)) for i, n in enumerate(self.region_names)},
            "boundary": {n: int(f.size) for n, f in self.boundary.items()},
        }

    def nbytes(self) -> int:
        arrays = [self.nodes, self.cell_face_sign, self.face_cells, self.cell_region]
        return (sum(a.nbytes for a in arrays) + self.face_nodes.nbytes() + self.cell_faces.nbytes()
                + self.cell_nodes.nbytes() + self.geometry.nbytes()
                + sum(f.nbytes for f in self.boundary.values()))


def cell_node_sets(face_nodes: Ragged, cell_faces: Ragged, n_nodes: int) -> Ragged:
    """Ragged sorted distinct nodes of each cell, from cells -> faces -> nodes."""
    nc = len(cell_faces)
    counts = np.zeros(nc, dtype=np.int64)
    parts = []
    inc_cell = cell_faces.rows_of_entries()
    step = 16384  # cells per batch: bounds the int64 temporaries
    for c0 in range(0, nc, step):
        c1 = min(nc, c0 + step)
        faces = cell_faces.values[cell_faces.offsets[c0]:cell_faces.offsets[c1]]
        sub = face_nodes.take(faces)
        owner = np.repeat(inc_cell[cell_faces.offsets[c0]:cell_faces.offsets[c1]], sub.counts)
        keys = np.sort(owner.astype(np.int64) * n_nodes + sub.values)
        keys = keys[np.concatenate([[True], keys[1:] != keys[:-1]])]
        cells = keys // n_nodes
        counts[c0:c1] = np.bincount(cells - c0, minlength=c1 - c0)
        parts.append((keys - cells * n_nodes).astype(INDEX))
    return Ragged.from_counts(counts, np.concatenate(parts) if parts else np.zeros(0, INDEX))


def _box_boundary(nodes: np.ndarray, face_nodes: Ragged, bfaces: np.ndarray) -> dict:
    """Name boundary faces that lie on the planes of the bounding box."""
    dim = nodes.shape[1]
    lo, hi = nodes.min(0), nodes.max(0)
    tol = 1e-9 * float(np.max(hi - lo))
    names = {}
    sub = face_nodes.take(bfaces)
    starts = sub.offsets[:-1]
    for k, ax in enumerate("xyz"[:dim]):
        c = nodes[sub.values, k]
        for side, val in (("min", lo[k]), ("max", hi[k])):
            on = np.abs(c - val) <= tol
            all_on = np.logical_and.reduceat(on, starts) if sub.nnz else np.zeros(0, bool)
            names[f"{ax}{side}"] = frozen(bfaces[all_on].astype(INDEX))
    return names


def assemble_mesh(dim: int, nodes: np.ndarray, face_nodes: Ragged, cell_faces: Ragged,
                  cell_face_sign: np.ndarray, boundary: Mapping[str, np.ndarray] | None = None,
                  cell_region: np.ndarray | None = None, region_names=None) -> Mesh:
    """Validate the topology, fix boundary face orientation and compute the geometry.

    Every face must belong to one cell (boundary) or to two cells with opposite
    signs (interior). Boundary faces are flipped when needed so that their normal
    points out of Ω. ``boundary`` names are added to the bounding-box names.
    """
    nodes = np.ascontiguousarray(nodes, dtype=float)
    if nodes.ndim != 2 or nodes.shape[1] != dim:
        raise MeshError("nodes", f"expected an (n, {dim}) array of coordinates, got shape {nodes.shape}")
    if not np.all(np.isfinite(nodes)):
        raise MeshError("nodes", "node coordinates must be finite numbers")
    nf = len(face_nodes)
    sign = np.asarray(cell_face_sign, dtype=np.int8)
    inc_face = cell_faces.values
    if inc_face.size and (inc_face.min() < 0 or inc_face.max() >= nf):
        raise MeshError("cells", "a cell refers to a face that does not exist")
    plus = sign > 0
    n_plus = np.bincount(inc_face[plus], minlength=nf)
    n_minus = np.bincount(inc_face[~plus], minlength=nf)
    total = n_plus + n_minus
    if np.any(total == 0):
        raise MeshError("faces", f"{np.count_nonzero(total == 0)} face(s) belong to no cell")
    bad = (total > 2) | ((total == 2) & (n_plus != 1))
    if np.any(bad):
        f = int(np.flatnonzero(bad)[0])
        raise MeshError("faces", f"face {f} is shared by {int(total[f])} cells or is oriented the same "
                        "way in both of its cells; faces must be shared by at most two cells, with "
                        "opposite orientations")
    # flip boundary faces seen only with sign -1 so that boundary normals point out of Ω
    flip = (total == 1) & (n_plus == 0)
    if np.any(flip):
        vals = face_nodes.values.copy()
        fl = np.flatnonzero(flip)
        counts = face_nodes.counts
        for m in np.unique(counts[fl]):
            rows = fl[counts[fl] == m]
            pos = face_nodes.positions(rows, m)
            vals[pos] = vals[pos][:, ::-1]
        face_nodes = Ragged(face_nodes.offsets, vals)
        sign = np.where(flip[inc_face], np.int8(1), sign)
    inc_cell = cell_faces.rows_of_entries()
    face_cells = np.full((nf, 2), -1, dtype=INDEX)
    pl = sign > 0
    face_cells[inc_face[pl], 0] = inc_cell[pl]
    face_cells[inc_face[~pl], 1] = inc_cell[~pl]

    cell_nodes = cell_node_sets(face_nodes, cell_faces, nodes.shape[0])
    used = np.zeros(nodes.shape[0], bool)
    used[face_nodes.values] = True
    if not used.all():
        raise MeshError("nodes", f"{np.count_nonzero(~used)} node(s) belong to no face; remove unused nodes")
    geometry = compute_geometry(dim, nodes, face_nodes, cell_faces, sign, cell_nodes)

    bfaces = np.flatnonzero(face_cells[:, 1] < 0).astype(INDEX)
    names = _box_boundary(nodes, face_nodes, bfaces)
    for name, faces in (boundary or {}).items():
        faces = np.unique(np.asarray(faces, dtype=INDEX))
        if faces.size and np.any(face_cells[faces, 1] >= 0):
            raise MeshError(f"boundary.{name}", "contains faces that are not on the boundary of the domain")
        names[name] = frozen(faces)
    nc = len(cell_faces)
    if cell_region is None:
        cell_region = np.zeros(nc, dtype=INDEX)
        region_names = ("domain",)
    cell_region = np.asarray(cell_region, dtype=INDEX)
    if cell_region.shape != (nc,):
        raise MeshError("cell_region", f"expected one region tag per cell ({nc}), got {cell_region.shape}")
    region_names = tuple(region_names) if region_names is not None else tuple(
        f"region{i}" for i in range(int(cell_region.max()) + 1))
    return Mesh(dim, frozen(nodes), face_nodes, cell_faces, frozen(sign), frozen(face_cells), cell_nodes,
                MappingProxyType(names), frozen(cell_region), region_names, geometry)


def with_regions(mesh: Mesh, cell_region: np.ndarray, region_names) -> Mesh:
    """The same mesh with new cell regions (material tags)."""
    import dataclasses

    cell_region = np.asarray(cell_region, dtype=INDEX)
    if cell_region.shape != (mesh.n_cells,):
        raise MeshError("cell_region", f"expected one region tag per cell ({mesh.n_cells}), got {cell_region.shape}")
    if cell_region.size and (cell_region.min() < 0 or cell_region.max() >= len(region_names)):
        raise MeshError("cell_region", "region tags must index region_names")
    return dataclasses.replace(mesh, cell_region=frozen(cell_region), region_names=tuple(region_names))


def with_boundary_parts(mesh: Mesh, parts: Mapping[str, np.ndarray]) -> Mesh:
    """The same mesh with extra named boundary parts (faces on ∂Ω, int32 ids)."""
    import dataclasses

    b = dict(mesh.boundary)
    bset = np.zeros(mesh.n_faces, bool)
    bset[mesh.boundary_faces] = True
    for name, faces in parts.items():
        faces = np.asarray(faces, dtype=INDEX)
        if faces.size and (faces.min() < 0 or faces.max() >= mesh.n_faces or not bset[faces].all()):
            raise MeshError(f"parts.{name}", "a boundary part must consist of faces on ∂Ω")
        b[name] = frozen(faces)
    return dataclasses.replace(mesh, boundary=MappingProxyType(b))
