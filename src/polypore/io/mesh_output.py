"""Files written by ``polypore mesh``: mesh.vtu, fractures.vtu, mesh.json, case.toml."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .. import __version__
from ..mesh import FracturedMesh
from ..mesh.fractures import EDGE_KINDS
from .atomic import atomic_write_text
from .vtu import write_bulk_vtu, write_fracture_vtu


def mesh_report(case_name: str, fm: FracturedMesh, seconds: float | None = None) -> dict:
    """Statistics of a fractured mesh as a JSON-ready dict."""
    stats = fm.mesh.stats()
    stats["node_sides"] = int(fm.sides.n_sides)
    stats["fracture_faces"] = int(fm.network.n_faces)
    kinds = np.bincount(fm.network.edge_kind, minlength=len(EDGE_KINDS))
    report = {
        "case": case_name,
        "version": __version__,
        "mesh": stats,
        "fractures": fm.report(),
        "fracture_edges": {k: int(c) for k, c in zip(EDGE_KINDS, kinds)},
        "sides_per_node": {str(k): int(c) for k, c in enumerate(np.bincount(fm.side_counts())) if c},
    }
    if seconds is not None:
        report["seconds"] = round(seconds, 3)
    return report


def write_mesh_outputs(out: Path, case, fm: FracturedMesh, seconds: float | None = None,
                       faults: dict | None = None) -> dict:
    """Write the mesh files of ``polypore mesh`` into ``out``; mesh.json last (it marks completion).
    ``faults``: the per-fault report of a corner-point grid (summary.json's ``faults``), kept
    under the same key in mesh.json."""
    mesh = fm.mesh
    g = mesh.geometry
    write_bulk_vtu(out / "mesh.vtu", mesh,
                   cell_data={"volume": g.cell_volume, "diameter": g.cell_diameter,
                              "n_faces": mesh.cell_faces.counts.astype(np.int32)},
                   point_data={"sides": fm.side_counts().astype(np.int32)})
    net = fm.network
    write_fracture_vtu(out / "fractures.vtu", fm, cell_data={"area": g.face_area[net.faces]})
    atomic_write_text(out / "case.toml", case.to_toml())
    report = mesh_report(case.name, fm, seconds)
    if faults is not None:
        report["faults"] = faults
    atomic_write_text(out / "mesh.json", json.dumps(report, indent=2))
    return report
