"""Rerun the validation cases on two versions of polypore and compare their results file by file.

    python benchmarks/rerun_cases.py BASE_REV [--cases a,b,...] [--set KEY=VALUE ...] [--out DIR] [--table FILE]

BASE_REV (a git revision of this repository, e.g. the commit before a refactoring) is exported with
``git archive`` into ``DIR/base-src``; the working tree's ``src/`` is the other side. Every case
runs once per side in a child process (``python -m polypore.cli run CASE``, the side's sources
first on PYTHONPATH) into ``DIR/{base,work}/CASE``. Then each result file is compared:

- CSV and VTU/PVD files byte for byte (the numbers as written, 10 significant digits in CSV,
  full binary precision in VTU);
- summary.json value by value, leaving out wall and CPU times, memory peaks and the version:
  the largest relative difference of any other number.

Prints one line per case and, with ``--table``, writes the Markdown table (issue 27, "Every
validation case gives the same figures as before"). ``DIR`` (default ``rerun/`` under the
system's temporary folder) holds only what this script writes; it refuses a ``DIR`` that holds
anything else.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the built-in validation and demonstration cases that run in about a minute each on this machine
CASES = ("single-crack", "six-fractures-static", "coulomb-2d", "tresca-2d", "frictionless-3d", "penny-pressurised",
         "darcy-dfm-2d", "darcy-manufactured-2d", "dfm-2d", "fault-injection", "displaced-fault",
         "cornerpoint-injection")
# summary.json keys that hold timings, memory or the version: they differ between any two runs
VOLATILE = ("seconds", "second", "timings", "memory", "_mb", "wall", "cpu", "version", "elapsed", "threads")
MARK = ".rerun_cases"


def volatile(key: str) -> bool:
    k = key.lower()
    return any(v in k for v in VOLATILE)


def numbers(obj, path=""):
    """{dotted path: value} of every non-volatile leaf of a JSON document."""
    out = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            if not volatile(str(k)):
                out.update(numbers(v, f"{path}.{k}" if path else str(k)))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out.update(numbers(v, f"{path}[{i}]"))
    else:
        out[path] = obj
    return out


def compare(a: Path, b: Path) -> dict:
    """File-by-file comparison of two result folders of one case."""
    fa = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    fb = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    data = sorted(p for p in fa & fb if p.suffix in (".csv", ".vtu", ".pvd"))
    differ = [str(p) for p in data if (a / p).read_bytes() != (b / p).read_bytes()]
    worst, where = 0.0, ""
    if (a / "summary.json").exists() and (b / "summary.json").exists():
        na = numbers(json.loads((a / "summary.json").read_text()))
        nb = numbers(json.loads((b / "summary.json").read_text()))
        for k in sorted(set(na) | set(nb)):
            x, y = na.get(k), nb.get(k)
            if isinstance(x, bool) or isinstance(y, bool) or not isinstance(x, (int, float)) \
                    or not isinstance(y, (int, float)):
                if x != y:
                    worst, where = float("inf"), k
                continue
            rel = abs(x - y) / max(abs(x), abs(y), 1e-300) if x != y else 0.0
            if rel > worst:
                worst, where = rel, k
    return {"files": len(data), "differ": differ, "missing": sorted(str(p) for p in fa ^ fb),
            "summary_rel": worst, "summary_key": where}


def run(case: str, src: Path, out: Path, sets=()) -> tuple[int, float]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(src), os.environ.get("PYTHONPATH", "")])}
    t0 = time.perf_counter()
    overrides = [a for kv in sets for a in ("--set", kv)]
    p = subprocess.run([sys.executable, "-m", "polypore.cli", "-q", "run", case, "--out", str(out), "--force",
                        *overrides], env=env, capture_output=True, text=True)
    if p.returncode:
        print(p.stderr[-2000:], file=sys.stderr)
    return p.returncode, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("base", help="git revision of the base version")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a case override for every case (e.g. solver.linear=block-amg)")
    ap.add_argument("--out", default=str(Path(tempfile.gettempdir()) / "rerun"))
    ap.add_argument("--table", help="write the Markdown table to this file")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if out.exists() and any(out.iterdir()) and not (out / MARK).exists():
        print(f"--out {out}: holds files this script did not write; choose another folder", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    (out / MARK).write_text("written by benchmarks/rerun_cases.py\n")
    rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", args.base], capture_output=True,
                         text=True, check=True).stdout.strip()
    base_src = out / f"base-{rev}"
    if not base_src.exists():
        base_src.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src"], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(base_src)], input=archive.stdout, check=True)
    sides = {"base": base_src / "src", "work": ROOT / "src"}
    rows = []
    for case in args.cases.split(","):
        status, secs = {}, {}
        for side, src in sides.items():
            status[side], secs[side] = run(case, src, out / side / case, args.set)
        if any(status.values()):
            rows.append((case, "run failed", status, "", ""))
            print(f"{case:24s} run failed: {status}")
            continue
        c = compare(out / "base" / case, out / "work" / case)
        same = not c["differ"] and not c["missing"]
        files = f"{c['files']} identical" if same else f"{len(c['differ'])} of {c['files']} differ"
        summ = "identical" if c["summary_rel"] == 0 else f"{c['summary_rel']:.1e} ({c['summary_key']})"
        rows.append((case, files, summ, f"{secs['base']:.0f}", f"{secs['work']:.0f}"))
        print(f"{case:24s} files: {files:18s} summary.json: {summ:30s} {secs['base']:.0f} s / {secs['work']:.0f} s")
        for p in c["differ"] + c["missing"]:
            print(f"{'':24s}   differs or missing: {p}")
    if args.table:
        label = " ".join(args.set)
        rows = [(f"{r[0]} ({label})" if label else r[0], *r[1:]) for r in rows]
        lines = [f"| case | result files (CSV, VTU, PVD) | summary.json numbers | s (base {rev}) | s (work) |",
                 "|---|---|---|---|---|"]
        lines += [f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]} |" for r in rows]
        Path(args.table).write_text("\n".join(lines) + "\n")
    return 0 if all(r[1].endswith("identical") and r[2] == "identical" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
