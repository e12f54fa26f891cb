"""Weak scaling of the coupled solve on generated faulted corner-point models (issue 26).

    .venv-fast/bin/python benchmarks/cornerpoint_weak_scaling.py [--cells 1e4 3e4 1e5 ...] [--steps 3]
        [--linear auto] [--json out.json] [--md out.md] [--set KEY=VALUE ...]

Each size is ``cornerpoint-injection`` on a grid of about the given number of cells over the same
2000 m × 1000 m × 160 m stack (nx : ny : nz = 40 : 25 : 10, scaled), with what makes corner-point
systems hard: pillars fanning out to 30° from vertical, two pinched-out layers, the two faults
crossing and both contact surfaces (friction 0.6 and 1.0), layered permeability (200, 0.01, 50, 0.0002 mD repeated down
the stack: a contrast of 10⁶, PERMZ a tenth) and the injector 350 m west of F1. ``--steps`` days
of injection at 10 kg/s, one step a day (at 120 kg/s the low-permeability layers open the faults on day 1 and the Newton iteration, not the linear solve, dominates). Each run is ``polypore run`` in a child process (the
same code path as a user's), so the figures include set-up and outputs.

Printed per size (and written as JSON / a markdown table): cells, unknowns, Newton iterations,
Krylov iterations per Newton iteration, wall and CPU seconds, CPU seconds per unknown per Newton
iteration, peak resident memory and memory per cell, and the machine's load average.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from childrun import polypore_run  # noqa: E402
from cornerpoint_reactivation import generated_overrides  # noqa: E402

LAYERS_MD = (200.0, 0.01, 50.0, 0.0002)


def grid_for(cells: float) -> tuple[int, int, int]:
    """(nx, ny, nz) ≈ 40 : 25 : 10 with nx·ny·nz ≈ cells."""
    r = (float(cells) / 1e4) ** (1.0 / 3.0)
    return max(int(round(40 * r)), 8), max(int(round(25 * r)), 6), max(int(round(10 * r)), 5)


def overrides(nx: int, ny: int, nz: int, steps: int, linear: str) -> list[str]:
    pinch = [2, max(nz // 2, 3)]
    out = generated_overrides(nx, ny, nz, tilt=30.0, pinchout=pinch, f2_contact=True)
    # friction 0.6 on F1 and 1.0 on F2 (in-situ ratios 0.42 and 0.82): generated_overrides puts them at 1.05 × their in-situ stress
    # ratio, where a third of F2 slips or opens on the first day and the Newton iteration, not the
    # linear solver, dominates (20 iterations with PARDISO; block-direct's inexact Newton stalled)
    out = [o for o in out if not o.startswith("fractures=")]
    out.append('fractures=[{name = "F1", friction = 0.6}, {name = "F2", friction = 1.0}]')
    out += [f"mesh.layer_permeability={list(LAYERS_MD)}", "parameters.mass_rate=10",
            "time.step=86400", f"time.end={86400 * steps}", f"solver.linear={linear}"]
    return out


def one(cells: float, steps: int, linear: str, extra=()) -> dict:
    nx, ny, nz = grid_for(cells)
    with polypore_run("cornerpoint-injection", overrides(nx, ny, nz, steps, linear) + list(extra)) as run:
        if run.proc.returncode != 0:
            tail = (run.proc.stderr or run.proc.stdout).strip().splitlines()[-3:]
            return {"grid": [nx, ny, nz], "failed": " | ".join(tail)}
        s = json.loads((run.out / "summary.json").read_text())
    tot, mesh = s["totals"], s["mesh"]
    newton = sum(st["newton_iterations"] for st in s["steps"])
    krylov = sum(sum(st.get("linear_iterations") or []) for st in s["steps"])
    # attempts given up and cut (summary.json steps[].failed_attempts): their work is part of the cost
    failed = [f for st in s["steps"] for f in st.get("failed_attempts", [])]
    newton_failed = sum(f.get("newton_iterations", 0) for f in failed)
    krylov_failed = sum(sum(f.get("linear_iterations", [])) for f in failed)
    # each step's first solve is the tight one (forcing 1e-9 or the round-off floor) and the hard
    # one; the later ones are loose: their means apart say which kind grows with the grid
    per_step = [list(st.get("linear_iterations") or []) for st in s["steps"]]
    first = [its[0] for its in per_step if its]
    later = [k for its in per_step for k in its[1:]]
    cpu = tot["cpu"]["seconds"]
    return {"grid": [nx, ny, nz], "cells": mesh["cells"], "unknowns": mesh["unknowns"],
            "linear_solver": tot.get("linear_solver"), "steps": len(s["steps"]), "newton": newton,
            "krylov": krylov, "krylov_per_newton": krylov / max(newton, 1), "krylov_per_step": per_step,
            "failed_attempts": len(failed), "newton_failed": newton_failed, "krylov_failed": krylov_failed,
            "krylov_first_mean": float(np.mean(first)) if first else None,
            "krylov_later_mean": float(np.mean(later)) if later else None, "wall_s": run.seconds,
            "cpu_s": cpu, "cpu_s_per_unknown_newton": cpu / max(newton + newton_failed, 1) / mesh["unknowns"],
            "peak_mb": tot.get("peak_memory_mb"), "kb_per_cell": 1024 * tot.get("peak_memory_mb", 0) / mesh["cells"],
            "slip_faces_end": s["steps"][-1]["slip"], "load_average": list(run.load_average)}


def _mean(v) -> str:
    return "–" if v is None else f"{v:.1f}"


def table(rows: list[dict]) -> str:
    head = ("| grid | cells | unknowns | solver | Newton (+ failed) | Krylov / Newton | Krylov: first / later solves | "
            "wall (s) | CPU (s) | CPU µs / unknown / Newton | peak (MB) | kB / cell | load |\n|" + "---|" * 13 + "\n")
    body = ""
    for r in rows:
        g = "×".join(str(v) for v in r["grid"])
        if "failed" in r:
            body += f"| {g} | failed: {r['failed']} |" + " |" * 11 + "\n"
            continue
        body += (f"| {g} | {r['cells']:,} | {r['unknowns']:,} | {r['linear_solver']} | {r['newton']}"
                 f"{' (+' + str(r['newton_failed']) + ')' if r.get('newton_failed') else ''} | "
                 f"{r['krylov_per_newton']:.1f} | {_mean(r.get('krylov_first_mean'))} / {_mean(r.get('krylov_later_mean'))} | "
                 f"{r['wall_s']:.0f} | {r['cpu_s']:.0f} | "
                 f"{1e6 * r['cpu_s_per_unknown_newton']:.2f} | {r['peak_mb']:.0f} | {r['kb_per_cell']:.0f} | "
                 f"{r['load_average'][0]:.1f}–{r['load_average'][1]:.1f} |\n")
    return head + body


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=float, nargs="+", default=[1e4, 3e4, 1e5])
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--linear", default="auto")
    ap.add_argument("--json", default=None)
    ap.add_argument("--md", default=None)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="further case overrides, e.g. mechanics.bubble_side=plus")
    a = ap.parse_args(argv)
    rows = []
    for c in a.cells:
        r = one(c, a.steps, a.linear, a.set)
        r["overrides"] = a.set
        rows.append(r)
        print(table([r]).splitlines()[-1], flush=True)
        if a.json:
            Path(a.json).write_text(json.dumps(rows, indent=1) + "\n")
    print(table(rows))
    if a.md:
        Path(a.md).write_text(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
