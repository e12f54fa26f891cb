"""Benchmark: C1 (frictionless-3d) on a tetrahedral mesh of about 1e5 cells.

    .venv/bin/python benchmarks/contact_c1.py [--size 0.062] [--linear auto|superlu|pardiso] [--json out.json]

Prints the mesh size, unknowns, set-up (assembly) time, Newton iterations, time per
iteration (assembly of the Jacobian and linear solve separately), total time, peak
resident memory and the C1 errors. Aim (issue 3): assembly under 5 s, the solve dominating.
"""

from __future__ import annotations

import argparse
import json
import resource
import time

from polypore.cases.exact import piecewise_errors
from polypore.models.mechanics import ContactMechanics
from polypore.setup.casefile import load_case
from polypore.setup.mechanics import mechanics_setup
from polypore.setup.meshing import build_fractured_mesh
from polypore.solvers.factory import SolverChoice


def main():
    import logging

    logging.basicConfig(level=logging.INFO, format="%(message)s")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.062, help="gmsh size (0.062 gives about 1e5 tetrahedra)")
    ap.add_argument("--linear", default="auto")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    case = load_case("frictionless-3d", [f"mesh.size={args.size}", "mechanics.order=1", f"solver.linear={args.linear}"])
    t0 = time.perf_counter()
    fm = build_fractured_mesh(case)
    t1 = time.perf_counter()
    setup = mechanics_setup(case, fm)
    t2 = time.perf_counter()
    problem = ContactMechanics(fm, setup.data, SolverChoice(args.linear), setup.newton)
    t3 = time.perf_counter()
    st = problem.solve(verbose=True)
    t4 = time.perf_counter()
    err = piecewise_errors(problem, st, setup.exact)
    it = max(st.newton_iterations, 1)
    row = {
        "cells": fm.mesh.n_cells, "fracture_faces": fm.network.n_faces,
        "unknowns": int(problem.free.size + problem.n_ff * problem.dim), "linear": problem.solver.backend,
        "seconds_mesh": round(t1 - t0, 2), "seconds_data": round(t2 - t1, 2),
        "seconds_assembly_setup": round(t3 - t2, 2), "newton_iterations": st.newton_iterations,
        "seconds_per_iteration": round((t4 - t3) / it, 2),
        "seconds_jacobian_per_iteration": round(st.seconds["assembly"] / it, 3),
        "seconds_linear_per_iteration": round(st.seconds["linear"] / it, 2),
        "seconds_solve_total": round(t4 - t3, 2), "peak_rss_mb": round(resource.getrusage(
            resource.RUSAGE_SELF).ru_maxrss / 1024), **{k: float(f"{v:.4e}") for k, v in err.items()},
    }
    for k, v in row.items():
        print(f"{k:32s} {v}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(row, fh, indent=2)


if __name__ == "__main__":
    main()
