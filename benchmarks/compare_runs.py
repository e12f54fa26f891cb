"""Compare the fault results of two runs of the same case (e.g. two linear solvers).

    python benchmarks/compare_runs.py RUN_A RUN_B

Prints, from each run's fractures.csv: faces whose state (open/stick/slip) differs at any output
step, and the largest difference of λ_n and of the slip (absolute, and relative to the largest
value in run A; jump_t is the tangential jump, the slip), plus both runs' wall time, linear-solver time and peak memory from summary.json.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np


def faces(folder: Path) -> dict:
    rows = list(csv.DictReader(open(folder / "fractures.csv", newline="")))
    out = {}
    for key in ("state", "lambda_n", "jump_t"):
        if key in rows[0]:
            vals = [r[key] for r in rows]
            out[key] = np.array(vals if key == "state" else [float(v) for v in vals])
    out["step"] = np.array([int(r["step"]) for r in rows])
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__)
        return 2
    a, b = (Path(x) for x in argv)
    fa, fb = faces(a), faces(b)
    if fa["step"].shape != fb["step"].shape or not np.array_equal(fa["step"], fb["step"]):
        print("the runs have different output steps or faces")
        return 1
    if "state" in fa:
        print(f"face-steps with a different state: {int(np.count_nonzero(fa['state'] != fb['state']))} of {fa['state'].size}")
    for key, unit in (("lambda_n", "MPa"), ("jump_t", "mm")):
        if key in fa:
            d = np.abs(fa[key] - fb[key]).max()
            ref = np.abs(fa[key]).max()
            scale = 1e-6 if unit == "MPa" else 1e3
            rel = (f"{d / ref:.1e} of the largest |{key}| in A" if ref * scale > 1e-6
                   else f"A's largest |{key}| is {ref * scale:.1g} {unit}")
            print(f"max |Δ{key}| = {d * scale:.3g} {unit} ({rel})")
    for f in (a, b):
        t = json.loads((f / "summary.json").read_text())["totals"]
        print(f"{f.name}: {t.get('linear_solver')}: {t['seconds']:.1f} s wall, linear solves {t['seconds_linear']:.1f} s, "
              f"CPU {t['cpu']['seconds']:.1f} s, peak {t.get('peak_memory_mb', float('nan')):.0f} MB, "
              f"{t.get('newton_iterations')} Newton iterations")
    return 0


if __name__ == "__main__":
    sys.exit(main())
