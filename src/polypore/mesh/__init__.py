"""Mesh layer: immutable polytopal meshes, fracture networks, node sides, generators."""

from .build import mesh_from_cells, mesh_from_polygons, mesh_from_polyhedra
from .fractures import FracturedMesh, FractureNetwork, FractureSpec, build_network
from .geometry import Geometry, face_moments, face_node_vector_areas
from .mesh import Mesh
from .sides import NodeSides, node_sides

__all__ = [
    "Mesh", "Geometry", "FracturedMesh", "FractureNetwork", "FractureSpec", "NodeSides",
    "mesh_from_cells", "mesh_from_polygons", "mesh_from_polyhedra", "build_network", "node_sides",
    "face_moments", "face_node_vector_areas",
]
