"""Wall time, peak memory and time shares of the C4 run of ``make demo`` (``polypore run dfm-2d``).

    .venv/bin/python benchmarks/c4_demo.py --linear pardiso [--out results/dfm-2d] [--json docs/c4_demo_timing.json]

The run is a subprocess under ``/usr/bin/time -v`` (wall clock and maximum resident set size of
the whole process); assembly / linear / other seconds, cells, unknowns, steps, Newton iterations
and energy violations come from the run's summary.json. Shares are percentages of the run's own
total (summary.json ``totals.seconds``). No JSON is written if the run fails.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import subprocess
import sys
from pathlib import Path

TIME = "/usr/bin/time"


def parse_time_v(text: str) -> dict:
    """Wall time (s) and peak RSS (MB) from the report of ``/usr/bin/time -v``.

    Parameters
    ----------
    text : str
        Standard error of the timed command (the report is at its end).

    Returns
    -------
    dict
        ``wall_seconds`` and ``peak_rss_mb`` (None where the report lacks the line).
    """
    wall = re.findall(r"Elapsed \(wall clock\) time.*?:\s*([\d:.]+)\s*$", text, re.M)
    rss = re.findall(r"Maximum resident set size \(kbytes\):\s*(\d+)", text)
    seconds = None
    if wall:
        seconds = 0.0
        for part in wall[-1].split(":"):       # h:mm:ss or m:ss.ss
            seconds = 60.0 * seconds + float(part)
    return {"wall_seconds": seconds, "peak_rss_mb": int(rss[-1]) / 1024.0 if rss else None}


def timed_run(cmd: list[str], log: Path | None = None, env: dict | None = None) -> dict:
    """Run ``cmd`` under ``/usr/bin/time -v``.

    Parameters
    ----------
    cmd : list of str
        The command.
    log : Path, optional
        File receiving stdout and stderr as the run goes (else both are captured in memory).
    env : dict, optional
        Variables added to the current environment.

    Returns
    -------
    dict
        ``returncode``, ``wall_seconds``, ``peak_rss_mb`` and ``stderr_tail`` (last 30 lines).
    """
    full_env = {**os.environ, **(env or {})}
    if log is None:
        p = subprocess.run([TIME, "-v", *cmd], capture_output=True, text=True, env=full_env)
        rc, err = p.returncode, p.stderr
    else:
        log.parent.mkdir(parents=True, exist_ok=True)
        with open(log, "w") as fh:
            rc = subprocess.run([TIME, "-v", *cmd], stdout=fh, stderr=subprocess.STDOUT, env=full_env).returncode
        err = log.read_text(errors="replace")
    tail = err.split("Command being timed:")[0] if rc != 0 else err
    return {"returncode": rc, **parse_time_v(err), "stderr_tail": "\n".join(tail.splitlines()[-30:])}


def shares(totals: dict) -> dict:
    """Assembly / linear / other seconds of summary.json ``totals`` as percentages of ``totals['seconds']``."""
    total = totals["seconds"]
    return {k: 100.0 * totals[f"seconds_{k}"] / total for k in ("assembly", "linear", "other")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--linear", choices=("auto", "superlu", "pardiso"), default="auto",
                    help="solver.linear of the run (default: auto)")
    ap.add_argument("--out", default="results/dfm-2d", help="run directory (default: results/dfm-2d, as make demo)")
    ap.add_argument("--json", default="docs/c4_demo_timing.json", help="result file")
    ap.add_argument("--case", default="dfm-2d", help="case (default: dfm-2d = C4)")
    ap.add_argument("--set", metavar="KEY=VALUE", action="append", default=[],
                    help="further case override, e.g. time.end=200 for a quick check")
    args = ap.parse_args()
    sets = [f"solver.linear={args.linear}", *args.set]
    cmd = [sys.executable, "-m", "polypore", "run", args.case, "--out", args.out, "--force"]
    cmd += [a for s in sets for a in ("--set", s)]
    print("running:", " ".join(cmd), flush=True)
    r = timed_run(cmd)
    summary_path = Path(args.out) / "summary.json"
    if r["returncode"] != 0 or not summary_path.exists():
        print(f"run failed (exit status {r['returncode']}); last lines of stderr:\n{r['stderr_tail']}", file=sys.stderr)
        return 1
    s = json.loads(summary_path.read_text())
    t = s["totals"]
    result = {
        "case": args.case, "linear": args.linear, "overrides": sets, "command": " ".join(cmd),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "cpu_count": os.cpu_count(), "wall_seconds": r["wall_seconds"], "peak_rss_mb": r["peak_rss_mb"],
        "seconds": {"total": t["seconds"], "assembly": t["seconds_assembly"], "linear": t["seconds_linear"],
                    "other": t["seconds_other"]},
        "shares_percent": shares(t), "cells": s["mesh"]["cells"], "unknowns": s["mesh"]["unknowns"],
        "fracture_faces": s["mesh"].get("fracture_faces"), "steps": len(s["steps"]),
        "newton_iterations": t["newton_iterations"], "energy_violations": len(s["energy_check"]["violations"]),
    }
    sh = result["shares_percent"]
    print(f"{args.case} ({args.linear}): {result['cells']} cells, {result['unknowns']} unknowns, {result['steps']} steps, "
          f"{result['newton_iterations']} Newton iterations, {result['energy_violations']} energy violations\n"
          f"wall {r['wall_seconds']:.1f} s, peak RSS {r['peak_rss_mb']:.0f} MB; assembly {t['seconds_assembly']:.1f} s "
          f"({sh['assembly']:.0f} %), linear {t['seconds_linear']:.1f} s ({sh['linear']:.0f} %), "
          f"other {t['seconds_other']:.1f} s ({sh['other']:.0f} %)")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    print("wrote", args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
