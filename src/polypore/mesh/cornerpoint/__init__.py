"""Corner-point (Eclipse GRDECL) grids: reader, generator, writer, edge-conformal processor, faults.

Typical use::

    from polypore.mesh.cornerpoint import read_grdecl, process_grid, fractured_mesh

    grid = read_grdecl("model.grdecl")
    mesh, info = process_grid(grid)               # Mesh + CornerPointInfo
    fm = fractured_mesh(mesh, info, ["F1", "F2"])  # selected faults as contact surfaces

See docs/cornerpoint.md.
"""

from .faults import detect_faults, fault_faces, fault_normals, fault_report, fault_table, fractured_mesh
from .generate import FaultSpec, generate_grid, pillar_angles, write_grdecl
from .info import BOUNDARY_NAMES, CornerPointInfo
from .permeability import MILLIDARCY, cell_permeability
from .pillars import pillar_points
from .process import process_grid, split_nonplanar_faces
from .reader import CornerPointGrid, read_grdecl

__all__ = [
    "CornerPointGrid", "CornerPointInfo", "FaultSpec", "BOUNDARY_NAMES",
    "read_grdecl", "write_grdecl", "generate_grid", "pillar_angles", "process_grid", "pillar_points", "cell_permeability",
    "MILLIDARCY", "split_nonplanar_faces",
    "detect_faults", "fault_faces", "fault_normals", "fault_report", "fault_table", "fractured_mesh",
]
