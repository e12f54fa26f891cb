"""Mesh and time-step sensitivity of C6 (``fault-injection``): slip onset time and final slip.

    .venv/bin/python benchmarks/c6_sensitivity.py [--out-root benchmarks/out/c6] [--json docs/c6_sensitivity.json]

Runs ``polypore run fault-injection`` (each under ``/usr/bin/time -v``) on three meshes at the
case's time step (mesh.size / fracture_size = 120/40, 60/15 (the case), 30/7.5 m) and with three
time steps on the case's mesh (10, 5 (the case), 2.5 days). For each run it records the slip
onset (the first step with a slipping face: its time and the previous step's time, which bracket
the onset), the overpressure at the fault in the reservoir at the onset, the maximum slip and
the number of slipping faces at the end (250 days), wall time and peak memory, and prints a
table. Existing results are reused unless --force.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from c4_demo import timed_run  # noqa: E402

DAY = 86400.0
MESHES = [("120/40", 120.0, 40.0), ("60/15", 60.0, 15.0), ("30/7.5", 30.0, 7.5)]
STEPS = [10.0, 5.0, 2.5]                                  # days


def configurations():
    """(label, overrides) of every run: the mesh series at Δt = 5 days, the Δt series on 60/15 m."""
    out = []
    for label, h, hf in MESHES:
        out.append((f"mesh {label} m, dt 5 d", [f"mesh.size={h}", f"mesh.fracture_size={hf}"]))
    for dt in STEPS:
        if dt != 5.0:
            out.append((f"mesh 60/15 m, dt {dt:g} d", [f"time.step={dt * DAY}"]))
    return out


def result(run_dir: Path, timing: dict) -> dict:
    s = json.loads((run_dir / "summary.json").read_text())
    on = s["slip_onset"] or {}
    m = s["monitor"]
    t = np.asarray(m["time"])
    p_fault = np.asarray(m["overpressure_at_points"]["fault_in_reservoir"])
    row = {"cells": s["mesh"]["cells"], "unknowns": s["mesh"]["unknowns"], "steps": len(s["steps"]),
           "newton_iterations": s["totals"]["newton_iterations"],
           "onset_days": on.get("time", np.nan) / DAY, "onset_previous_days": on.get("previous_time", np.nan) / DAY,
           "overpressure_at_fault_at_onset_mpa": float(np.interp(on.get("time", np.nan), t, p_fault)) / 1e6
           if on else None,
           "final_max_slip_mm": 1e3 * float(m["max_slip"]["fault"][-1]),
           "final_slipping_faces": s["steps"][-1]["slip"], "final_open_faces": s["steps"][-1]["open"],
           "energy_violations": len(s["energy_check"]["violations"]),
           "wall_seconds": timing.get("wall_seconds"), "peak_rss_mb": timing.get("peak_rss_mb")}
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out-root", type=Path, default=Path("benchmarks/out/c6"))
    ap.add_argument("--json", type=Path, default=Path("docs/c6_sensitivity.json"))
    ap.add_argument("--force", action="store_true")
    args = ap.parse_args()
    rows = {}
    for label, over in configurations():
        d = args.out_root / label.replace(" ", "_").replace("/", "-").replace(",", "")
        tfile = d.parent / (d.name + ".timing.json")
        if args.force or not (d / "summary.json").exists():
            cmd = [sys.executable, "-m", "polypore", "run", "fault-injection", "--out", str(d), "--force"]
            for o in over:
                cmd += ["--set", o]
            print(f"running {label} ...", flush=True)
            timing = timed_run(cmd, log=d.parent / (d.name + ".log"))
            if timing["returncode"] != 0:
                print(f"{label}: failed\n{timing['stderr_tail']}")
                continue
            tfile.write_text(json.dumps(timing, indent=1))
        timing = json.loads(tfile.read_text()) if tfile.exists() else {}
        rows[label] = result(d, timing)
    head = (f"{'configuration':26s} {'cells':>6s} {'onset (d)':>14s} {'Δp fault (MPa)':>14s} "
            f"{'slip (mm)':>9s} {'slip/open':>9s} {'wall (s)':>8s} {'RSS (MB)':>8s}")
    print(head)
    for label, r in rows.items():
        dp = r["overpressure_at_fault_at_onset_mpa"]
        print(f"{label:26s} {r['cells']:6d} {r['onset_previous_days']:6.1f}–{r['onset_days']:<6.1f} "
              f"{dp if dp is not None else float('nan'):14.2f} {r['final_max_slip_mm']:9.2f} "
              f"{r['final_slipping_faces']:4d}/{r['final_open_faces']:<4d} {r['wall_seconds'] or 0:8.1f} "
              f"{r['peak_rss_mb'] or 0:8.0f}")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"command": "python benchmarks/c6_sensitivity.py", "runs": rows}, indent=1))
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
