"""Benchmark: what snapping does to sliver fault faces and to cell volumes (issue 24).

    .venv/bin/python benchmarks/cornerpoint_snap_volumes.py [--grid FILE ...]

For Emerald (the built-in case's grid) and every grid of ../shared/data/grdecl/, processed
with ``snap=0``, with the snapping of before issue 24 (``snap=0.2``, no volume bound) and with
the default (``snap=0.2`` within ``max_volume_change=1e-3``): nodes snapped, fault faces below
1 % and below 10 % of their fault's median face area (``nonplanar="keep"``: the faces as the
grid makes them, before any splitting), and the largest relative change of a processed cell's
volume against ``snap=0`` (``nonplanar="centre"``, the default processing, and ``"keep"``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from polypore.mesh.cornerpoint import process_grid, read_grdecl

ROOT = Path(__file__).resolve().parents[1]
EMERALD = ROOT / "src" / "polypore" / "cases" / "data" / "emerald.grdecl"
SHARED = Path("/work/shared/data/grdecl")
VARIANTS = {"snap=0": dict(snap=0.0), "old 0.2": dict(snap=0.2, max_volume_change=np.inf),
            "new 0.2": dict(snap=0.2)}


def slivers(mesh, info):
    A = mesh.geometry.face_area
    below = np.zeros(2, int)
    for f in info.faults.values():
        med = np.median(A[f])
        below += [(A[f] < 1e-2 * med).sum(), (A[f] < 1e-1 * med).sum()]
    return below


def volume_change(grid, kw, nonplanar):
    m0, i0 = process_grid(grid, snap=0, nonplanar=nonplanar, find_faults=False)
    m1, i1 = process_grid(grid, nonplanar=nonplanar, find_faults=False, **kw)
    assert np.array_equal(i0.cell_index, i1.cell_index)
    v0, v1 = m0.geometry.cell_volume, m1.geometry.cell_volume
    return float(np.max(np.abs(v1 - v0) / v0)), i1.n_snapped


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", nargs="+", default=[str(EMERALD)] + sorted(map(str, SHARED.glob("*.[gG][rR][dD][eE][cC][lL]"))))
    a = ap.parse_args(argv)
    print("| grid | faults | processing | nodes snapped | fault faces < 1% / < 10% of median | max rel. volume "
          "change (centre) | (keep) | s |")
    print("|---|---|---|---|---|---|---|---|")
    for path in map(Path, a.grid):
        grid = read_grdecl(path)
        for label, kw in VARIANTS.items():
            t = time.perf_counter()
            mesh, info = process_grid(grid, nonplanar="keep", **kw)
            b = slivers(mesh, info)
            dc, n = volume_change(grid, kw, "centre")
            dk, _ = volume_change(grid, kw, "keep")
            print(f"| {path.name} | {len(info.faults)} | {label} | {n} | {b[0]} / {b[1]} | {dc:.2e} | {dk:.2e} | "
                  f"{time.perf_counter() - t:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
