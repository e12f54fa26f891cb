"""3D steady HFV flow with a fracture T-network on about 1e5 cells (scheme.md §5).

Network: F1 = {x = ½} crossing Ω = (0, 1)³, F2 = {z = ½, ½ ≤ x ≤ ¾} meeting F1 along a
line (intersection) with a tip line at x = ¾. Data of the C5 case (K_m = 1e−14 m², η =
1e−3 Pa·s, d_f = 1e−3 m, K_fn = 1e−14 m²); p = 2e5 Pa on x = 0, 1e5 Pa on x = 1, no-flow
elsewhere, a fracture source of 1e−6 m/s on F2.

Usage::

    .venv/bin/python benchmarks/flow_3d.py [--n 46] [--solver amg|superlu|auto] [--tets SIZE]

Prints per mesh: mesh and network build, local operators + pattern, assembly (of which
condensation), solve and recovery times, dof counts, the tracemalloc peak (Python/numpy
allocations) and the process's max RSS.
"""

from __future__ import annotations

import argparse
import resource
import time
import tracemalloc

import numpy as np

from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.models.flow import FlowData, FlowModel, Pressure
from polypore.solvers.linear import LinearSolver

SPECS = [FractureSpec("F1", np.array([[0.5, 0, 0], [0.5, 1, 0], [0.5, 1, 1], [0.5, 0, 1.0]]), normal=np.array([1.0, 0, 0])),
         FractureSpec("F2", np.array([[0.5, 0, 0.5], [0.75, 0, 0.5], [0.75, 1, 0.5], [0.5, 1, 0.5]]))]


def run(label: str, make_mesh, solver: str) -> dict:
    tracemalloc.start()
    t0 = time.perf_counter()
    mesh = make_mesh()
    t1 = time.perf_counter()
    fm = FracturedMesh.build(mesh, SPECS)
    t2 = time.perf_counter()
    f2 = fm.network.fracture == 1
    data = FlowData(permeability=1e-14, viscosity=1e-3, aperture=1e-3, normal_permeability=1e-14)
    model = FlowModel(fm, data, {"xmin": Pressure(2e5), "xmax": Pressure(1e5)},
                      fracture_source=np.where(f2, 1e-6, 0.0),
                      solver=LinearSolver(solver, symmetric=True, rtol=1e-10, maxiter=2000))
    t3 = time.perf_counter()
    sol = model.solve_steady()
    t4 = time.perf_counter()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    tm = sol.timings
    hm, hf = model.sources(0.0)
    balance = sum(sol.boundary_flux.values()) - hm.sum() - hf.sum()
    out = {
        "mesh": label, "cells": mesh.n_cells, "fracture_faces": fm.network.n_faces,
        "dofs": model.assembler.dofs.n, "solved_dofs": int(model._cache[2].size), "nnz": int(model._cache[3].nnz),
        "mesh_s": t1 - t0, "network_s": t2 - t1, "setup_s": t3 - t2,
        "local_operators_s": model.assembler.setup_timings["local_operators"],
        "pattern_s": model.assembler.setup_timings["pattern"],
        "assembly_s": tm["assembly"], "condensation_s": tm["condensation"], "solve_s": tm["solve"],
        "recovery_s": tm["recovery"], "total_solve_call_s": t4 - t3,
        "krylov_iterations": model.solver.stats.iterations[-1] if model.solver.stats.iterations else None,
        "tracemalloc_peak_MB": peak / 2 ** 20,
        "max_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "global_balance_m3_per_s": balance, "outflow_xmax": sol.boundary_flux["xmax"],
    }
    for k, v in out.items():
        print(f"  {k:26s} {v:.4g}" if isinstance(v, float) else f"  {k:26s} {v}")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=46, help="Cartesian cells per direction (n³ hexahedra)")
    ap.add_argument("--solver", default="amg", help="linear solver backend")
    ap.add_argument("--tets", type=float, default=None, help="also run gmsh tetrahedra of this size (m)")
    args = ap.parse_args(argv)
    n = args.n
    print(f"hexahedra {n}^3")
    run(f"hex {n}^3", lambda: cartesian_mesh([grid_coordinates(0, 1, n, [0.5, 0.75])] * 3), args.solver)
    if args.tets:
        from polypore.mesh.generators.simplicial import simplicial_mesh
        print(f"tetrahedra size {args.tets}")
        run(f"tet h={args.tets}", lambda: simplicial_mesh([0, 0, 0], [1, 1, 1], SPECS, size=args.tets), args.solver)


if __name__ == "__main__":
    main()
