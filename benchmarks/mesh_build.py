"""Benchmark: build a 3D fractured mesh of about 1e5 cells (topology, geometry, fractures, node sides).

    .venv/bin/python benchmarks/mesh_build.py [--cells 100000] [--json out.json]

Generation (gmsh, Voronoi, ...) is excluded: each generator's output is turned back into
raw cells (tetrahedra) or outward face loops (polyhedra) and the timed part is what
polypore does with them: face deduplication, validation, geometry (areas, normals,
centroids, volumes, diameters, weights ω), fracture mapping and node sides.
Peak memory is the tracemalloc peak above the raw input, per cell. Target (issue 2):
under 5 s and under 1 KB per cell.
"""

from __future__ import annotations

import argparse
import json
import time
import tracemalloc

import numpy as np

from polypore.core.ragged import Ragged
from polypore.mesh import FracturedMesh, FractureSpec, mesh_from_cells, mesh_from_polyhedra

C5 = [
    FractureSpec("F1", np.array([[0.15, 0.15, 0.35], [0.85, 0.15, 0.55], [0.85, 0.85, 0.55], [0.15, 0.85, 0.35]])),
    FractureSpec("F2", np.array([[0.30, 0.45, 0.20], [0.70, 0.53, 0.20], [0.70, 0.53, 0.80], [0.30, 0.45, 0.80]])),
    FractureSpec("F4", np.array([[0.55, 0.00, 0.15], [0.90, 0.00, 0.25], [0.90, 0.30, 0.25], [0.55, 0.30, 0.15]])),
]
AXIS = [  # C1-like T network, axis-aligned, scaled to the unit cube
    FractureSpec("G1", np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]]), normal=np.array([0, 0, 1.0])),
    FractureSpec("G2", np.array([[0.5, 0, 0], [0.5, 1, 0], [0.5, 1, 0.5], [0.5, 0, 0.5]])),
]


def outward_loops(mesh):
    """Raw input of a polyhedral mesh: every cell's faces as outward node loops."""
    cf = mesh.cell_faces
    loops = mesh.face_nodes.take(cf.values)
    vals = loops.values.copy()
    rev = np.flatnonzero(mesh.cell_face_sign < 0)
    for m in np.unique(loops.counts[rev]):
        rows = rev[loops.counts[rev] == m]
        pos = loops.positions(rows, m)
        vals[pos] = vals[pos][:, ::-1]
    return Ragged(loops.offsets, vals), cf.rows_of_entries()


def measure(label, build, n_cells_hint):
    tracemalloc.start()
    tracemalloc.reset_peak()
    base, _ = tracemalloc.get_traced_memory()
    t0 = time.perf_counter()
    mesh = build["mesh"]()
    t1 = time.perf_counter()
    fm = FracturedMesh.build(mesh, build["fractures"])
    t2 = time.perf_counter()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    nc = mesh.n_cells
    row = {
        "mesh": label, "cells": nc, "faces": mesh.n_faces, "nodes": mesh.n_nodes,
        "nonplanar_faces": int(np.count_nonzero(mesh.geometry.face_nonplanarity > 1e-10)),
        "fracture_faces": fm.network.n_faces, "node_sides": fm.sides.n_sides,
        "seconds_mesh_geometry": round(t1 - t0, 3), "seconds_fractures_sides": round(t2 - t1, 3),
        "seconds_total": round(t2 - t0, 3),
        "peak_bytes_per_cell": round((peak - base) / nc), "retained_bytes_per_cell":
            round((mesh.nbytes() + fm.sides.nbytes()) / nc),
    }
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=100_000)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    rows = []

    from polypore.mesh.generators.simplicial import simplicial_mesh
    size = 0.036 * (1e5 / args.cells) ** (1 / 3)   # gmsh gives about 1e5 tetrahedra at 0.036 on this network
    t = time.perf_counter()
    tet = simplicial_mesh([0, 0, 0], [1, 1, 1], C5, size)
    gen = time.perf_counter() - t
    nodes, tets = tet.nodes.copy(), tet.cell_nodes.values.reshape(-1, 4).copy()
    del tet
    r = measure("tetrahedra (gmsh, C5 network)", {"mesh": lambda: mesh_from_cells(nodes, {"tetra": tets}),
                                                   "fractures": C5}, args.cells)
    r["seconds_generation"] = round(gen, 2)
    rows.append(r)

    from polypore.mesh.generators.voronoi import voronoi_mesh
    t = time.perf_counter()
    vor = voronoi_mesh([0, 0, 0], [1, 1, 1], args.cells ** (-1 / 3), AXIS, seed=1)
    gen = time.perf_counter() - t
    vn, (vl, vc) = vor.nodes.copy(), outward_loops(vor)
    del vor
    r = measure("Voronoi polyhedra (T network)", {"mesh": lambda: mesh_from_polyhedra(vn, vl, vc, oriented=True),
                                                  "fractures": AXIS}, args.cells)
    r["seconds_generation"] = round(gen, 2)
    rows.append(r)

    from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
    from polypore.mesh.generators.perturb import perturb
    n = int(round(args.cells ** (1 / 3)))
    t = time.perf_counter()
    hexm = perturb(cartesian_mesh([grid_coordinates(0, 1, n, [0.5])] * 3), 0.3, AXIS, seed=2)
    gen = time.perf_counter() - t
    hn, (hl, hc) = hexm.nodes.copy(), outward_loops(hexm)
    del hexm
    r = measure("perturbed hexahedra (non-planar faces)",
                {"mesh": lambda: mesh_from_polyhedra(hn, hl, hc, oriented=True), "fractures": AXIS}, args.cells)
    r["seconds_generation"] = round(gen, 2)
    rows.append(r)

    head = f"{'mesh':40s} {'cells':>8s} {'faces':>8s} {'sides':>8s} {'geom s':>7s} {'frac+sides s':>12s} " \
           f"{'total s':>8s} {'peak B/cell':>11s} {'kept B/cell':>11s}"
    print(head)
    for r in rows:
        print(f"{r['mesh']:40s} {r['cells']:8d} {r['faces']:8d} {r['node_sides']:8d} {r['seconds_mesh_geometry']:7.2f} "
              f"{r['seconds_fractures_sides']:12.2f} {r['seconds_total']:8.2f} {r['peak_bytes_per_cell']:11d} "
              f"{r['retained_bytes_per_cell']:11d}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
