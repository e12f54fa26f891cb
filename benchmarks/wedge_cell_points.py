"""Benchmark: HFV accuracy on pinched-out (wedge) corner-point cells, cell point "centroid" vs "auto".

    .venv/bin/python benchmarks/wedge_cell_points.py [--levels 8 16 32] [--nonplanar keep]

Family: ``generate_grid(n, n, n/2)`` over 1000 × 1000 × 100 m with layers 1 and 2 pinched out
towards x = 0 (default: zero thickness for x ≤ 250 m, full from 500 m: collapsed cells, then
wedges whose thin end goes to zero; ``--pinch 0.25 5`` thins them over the whole grid: slivers of
aspect 10²–10⁴), dipping 2°. Manufactured pressure (as benchmarks/cornerpoint_flat.py) p =
P (sin πx̂ sin πŷ + ẑ² cos πx̂) on the mapped cube, K = 1e-13 m², source h = −div(K/η ∇p), p exact
on ∂Ω. Per setting: how many cells "auto" moves, the smallest λ_min/λ_max of the unit-diagonal
T_K, and the relative L2 error of the cell pressures at each setting's own cell points (weights
|K|), with the rate fitted against h = 1000 m / n.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from cornerpoint_flat import ETA, K, L, l2, manufactured  # noqa: E402

from polypore.discretisation.hfv import conditioning  # noqa: E402
from polypore.mesh import FracturedMesh  # noqa: E402
from polypore.mesh.cornerpoint import BOUNDARY_NAMES, generate_grid, process_grid  # noqa: E402
from polypore.models.flow import FlowData, FlowModel, Pressure  # noqa: E402
from polypore.runs.convergence import fit_rate  # noqa: E402
from polypore.solvers.linear import LinearSolver  # noqa: E402


def run(n: int, nonplanar: str, pinch=(0.25, 0.5)) -> dict:
    H = 100.0
    grid = generate_grid(n, n, max(n // 2, 4), extent=(L, L, H), top=1000.0, dip=2.0, pinchout=(1, 2),
                         pinch_range=tuple(pinch), properties=False)
    mesh, info = process_grid(grid, nonplanar=nonplanar)
    z0 = float(mesh.nodes[:, 2].min())
    _, _, _, p, h = manufactured(float(mesh.nodes[:, 2].max() - z0), z0)
    fm = FracturedMesh.build(mesh, [])
    names = [b for b in BOUNDARY_NAMES if info.boundary[b].size]
    out = {"n": n, "cells": mesh.n_cells, "h": L / n}
    points = {}
    for cp in ("centroid", "auto"):
        flow = FlowModel(fm, FlowData(permeability=K, viscosity=ETA), {b: Pressure(p) for b in names}, cell_source=h,
                         solver=LinearSolver("auto", symmetric=True), cell_point=cp)
        sol = flow.solve_steady()
        op = flow.assembler.hfv
        points[cp] = op.points
        pe = p(*op.points.T)
        out[cp] = {"p": l2(sol.cell - pe, pe, mesh.geometry.cell_volume), "worst": float(conditioning(op).min())}
    out["moved"] = int(np.any(points["auto"] != points["centroid"], axis=1).sum())
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", nargs="+", type=int, default=[8, 16, 32])
    ap.add_argument("--nonplanar", default="keep", choices=("keep", "centre", "diagonal"))
    ap.add_argument("--pinch", nargs=2, type=float, default=[0.25, 0.5],
                    help="pinch_range: zero thickness up to the first fraction of Lx, full from the second "
                         "(beyond 1: the layers thin over the whole grid, slivers everywhere)")
    a = ap.parse_args(argv)
    rows = [run(n, a.nonplanar, a.pinch) for n in a.levels]
    print(f"| n | cells | moved by auto | worst λ_min/λ_max centroid / auto | pressure L2 error centroid | auto |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['n']} | {r['cells']} | {r['moved']} | {r['centroid']['worst']:.1e} / {r['auto']['worst']:.1e} | "
              f"{r['centroid']['p']:.3e} | {r['auto']['p']:.3e} |")
    h = [r["h"] for r in rows]
    print(f"rates: centroid {fit_rate(h, [r['centroid']['p'] for r in rows]):.2f}, "
          f"auto {fit_rate(h, [r['auto']['p'] for r in rows]):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
