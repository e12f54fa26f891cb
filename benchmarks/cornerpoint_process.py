"""Benchmark: read and process corner-point grids (GRDECL -> polytopal mesh -> faults as fractures).

    .venv/bin/python benchmarks/cornerpoint_process.py [--cells 500000] [--json out.json] [--data DIR]
                                                       [--process-file OLD_PROCESS_PY]

Grids: Emerald, b.grdecl and SPE9 from the shared test data, and a generated faulted grid of
about ``--cells`` cells (four faults, two of them ending inside the grid, a pinched-out layer,
2% inactive cells, dipping layers), written to a temporary GRDECL file so that the reader is
timed on it too. Stages: read (GRDECL text -> CornerPointGrid), process (nodes, faces, mesh =
topology checks and geometry, fault detection: process_grid's own split) and fractures (all
faults cut: FracturedMesh with node sides). Memory: tracemalloc peak of each stage (numpy
arrays included) and the process's peak resident size at the end. Target (issue 15): read +
process under 60 s and 4 GB for 500k cells.
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

from polypore.mesh.cornerpoint import FaultSpec, fractured_mesh, generate_grid, process_grid, read_grdecl, write_grdecl

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "grdecl"


def staged(fn):
    """Run fn() under tracemalloc; return (result, seconds, peak MB above the start)."""
    tracemalloc.start()
    base, _ = tracemalloc.get_traced_memory()
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return out, dt, (peak - base) / 2 ** 20


def generated(cells: int):
    """A faulted grid of about ``cells`` cells: n × n columns, nz = 50 layers."""
    nz = 50
    n = max(8, round((cells / nz) ** 0.5))
    faults = [FaultSpec("i", n // 3, 30.0, name="F1"),
              FaultSpec("i", 2 * n // 3, -45.0, start=n // 5, stop=4 * n // 5, name="F2"),
              FaultSpec("j", n // 2, 20.0, name="F3"),
              FaultSpec("j", n // 4, 60.0, start=0, stop=n // 2, name="F4")]
    return generate_grid(n, n, nz, (10_000.0, 10_000.0, 250.0), dip=2.0, faults=faults, pinchout=[5],
                         inactive=0.02, seed=1)


def run(label, path):
    grid, t_read, m_read = staged(lambda: read_grdecl(path))
    (mesh, info), t_proc, m_proc = staged(lambda: process_grid(grid))
    fm, t_frac, m_frac = staged(lambda: fractured_mesh(mesh, info))
    nx, ny, nz = grid.dims
    row = {
        "grid": label, "dims": [nx, ny, nz], "active": int(grid.actnum.sum()), "cells": mesh.n_cells,
        "faces": mesh.n_faces, "nodes": mesh.n_nodes, "faults": len(info.faults),
        "fault_faces": int(fm.network.n_faces), "node_sides": int(fm.sides.n_sides),
        "file_MB": round(Path(path).stat().st_size / 2 ** 20, 1),
        "read_s": round(t_read, 2), "read_peak_MB": round(m_read),
        "process_s": round(t_proc, 2), "process_peak_MB": round(m_proc),
        "stages_s": {k: round(v, 2) for k, v in info.seconds.items()},
        "fractures_s": round(t_frac, 2), "fractures_peak_MB": round(m_frac),
        "cells_per_s": round(mesh.n_cells / (t_read + t_proc)),
    }
    print(f"{label:>28s}: {mesh.n_cells:>8,d} cells {mesh.n_faces:>9,d} faces {mesh.n_nodes:>8,d} nodes "
          f"{len(info.faults):>2d} faults | read {t_read:6.2f} s {m_read:6.0f} MB | process {t_proc:6.2f} s "
          f"{m_proc:6.0f} MB ({', '.join(f'{k} {v:.2f}' for k, v in info.seconds.items())}) | fractures "
          f"{t_frac:5.2f} s {m_frac:5.0f} MB | {row['cells_per_s']:,d} cells/s", flush=True)
    return row


def _use_process_file(path: str):
    """Replace process_grid by the one of another version of process.py (run inside the package)."""
    import importlib.util
    import sys

    global process_grid
    spec = importlib.util.spec_from_file_location("polypore.mesh.cornerpoint._benchmarked_process", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    process_grid = module.process_grid
    print(f"process_grid from {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=500_000)
    ap.add_argument("--data", default=str(DATA))
    ap.add_argument("--json", default=None)
    ap.add_argument("--process-file", default=None, metavar="FILE",
                    help="time process_grid of this file instead (e.g. an older process.py from git show: "
                         "the before/after comparison of docs/cornerpoint.md)")
    args = ap.parse_args()
    if args.process_file:
        _use_process_file(args.process_file)
    rows = []
    data = Path(args.data)
    for name, label in (("eme_small_w_hole_grid_params.grdecl", "Emerald"), ("b.grdecl", "b.grdecl"),
                        ("SPE9.GRDECL", "SPE9")):
        if (data / name).exists():
            rows.append(run(label, data / name))
    if args.cells > 0:
        with tempfile.TemporaryDirectory() as tmp:
            grid, t_gen, _ = staged(lambda: generated(args.cells))
            path = Path(tmp) / "generated.grdecl"
            t0 = time.perf_counter()
            write_grdecl(grid, path, digits=10)
            print(f"generated {grid.dims} in {t_gen:.2f} s, written ({path.stat().st_size / 2 ** 20:.0f} MB) "
                  f"in {time.perf_counter() - t0:.2f} s (not timed below)", flush=True)
            del grid
            rows.append(run(f"generated {args.cells // 1000}k", path))
    peak_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 10
    print(f"peak resident size of this process: {peak_rss:.0f} MB")
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "peak_rss_MB": round(peak_rss)}, indent=1) + "\n")


if __name__ == "__main__":
    main()
