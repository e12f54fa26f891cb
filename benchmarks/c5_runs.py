"""C5 (``dfm-3d``) runs for a list of mesh sizes and bubble options, each under ``/usr/bin/time -v``.

    .venv/bin/python benchmarks/c5_runs.py [--sizes 0.047 0.0332] [--bubbles one-sided two-sided] [--threads 1]
    .venv-mpi/bin/python benchmarks/c5_runs.py --ranks 2 --linear block-petsc --sizes 0.0332 --bubbles one-sided

With ``--ranks N`` (N > 1) the run is ``mpiexec -n N`` of the same command (docs/parallel.md; the
PETSc venv); the directory name gets ``-nN``, summary.json's ``totals.ranks`` holds every rank's
time split and peak memory.

Run directory ``<out-root>/size<size>-<bubbles>-<linear>`` (default out-root benchmarks/out/c5),
log ``<out-root>/size<size>-<bubbles>-<linear>.log`` (stdout and stderr as the run goes), and after
the run ``<run dir>/timing.json`` (wall time, peak RSS, exit status, command). A configuration
whose summary.json exists is skipped unless ``--force``; ``--extra`` overrides do not enter the
directory name. Tabulate and plot with ``benchmarks/c5_table.py``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
from pathlib import Path

from c4_demo import timed_run


def run_dir_name(size: float, bubbles: str, linear: str) -> str:
    """Directory name of a configuration, e.g. ``size0.047-one-sided-block-amg``."""
    return f"size{size:g}-{bubbles}-{linear}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[0.047, 0.0332],
                    help="mesh.size values (0.047: about 46k tetrahedra, 0.0332: 127k)")
    ap.add_argument("--bubbles", nargs="+", choices=("one-sided", "two-sided"), default=["one-sided", "two-sided"])
    ap.add_argument("--linear", default="block-amg", help="solver.linear (default: block-amg)")
    ap.add_argument("--threads", type=int, default=1, help="OMP_NUM_THREADS and MKL_NUM_THREADS (default: 1)")
    ap.add_argument("--out-root", default="benchmarks/out/c5")
    ap.add_argument("--extra", metavar="KEY=VALUE", action="append", default=[], help="further --set (repeatable)")
    ap.add_argument("--case", default="dfm-3d")
    ap.add_argument("--force", action="store_true", help="rerun configurations that have a summary.json")
    ap.add_argument("--ranks", type=int, default=1, help="MPI ranks (mpiexec -n; default 1: no mpiexec)")
    args = ap.parse_args()
    root = Path(args.out_root)
    env = {"OMP_NUM_THREADS": str(args.threads), "MKL_NUM_THREADS": str(args.threads)}
    failed = 0
    for size in args.sizes:
        for bubbles in args.bubbles:
            name = run_dir_name(size, bubbles, args.linear) + (f"-n{args.ranks}" if args.ranks > 1 else "")
            out = root / name
            if (out / "summary.json").exists() and not args.force:
                print(f"{name}: skipped (summary.json exists; --force reruns)", flush=True)
                continue
            sets = [f"mesh.size={size:g}", "mechanics.order=1", f"mechanics.bubbles={bubbles}", f"solver.linear={args.linear}", *args.extra]
            cmd = [sys.executable, "-m", "polypore", "run", args.case, "--out", str(out), "--force"]
            cmd += [a for s in sets for a in ("--set", s)]
            if args.ranks > 1:
                cmd = ["mpiexec", "--allow-run-as-root", "-n", str(args.ranks), *cmd]
            print(f"{name}: running (log {root / (name + '.log')})", flush=True)
            r = timed_run(cmd, log=root / f"{name}.log", env=env)
            out.mkdir(parents=True, exist_ok=True)
            timing = {k: r[k] for k in ("wall_seconds", "peak_rss_mb", "returncode")}
            timing.update(threads=args.threads, command=" ".join(cmd),
                          date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
            (out / "timing.json").write_text(json.dumps(timing, indent=2) + "\n")
            if r["returncode"] != 0 or not (out / "summary.json").exists():
                failed += 1
                print(f"{name}: FAILED (exit status {r['returncode']}); last lines of the log:\n{r['stderr_tail']}",
                      flush=True)
                continue
            s = json.loads((out / "summary.json").read_text())
            print(f"{name}: {s['mesh']['cells']} cells, {s['mesh']['unknowns']} unknowns, {len(s['steps'])} steps, "
                  f"{s['totals']['newton_iterations']} Newton iterations, wall {r['wall_seconds']:.1f} s, "
                  f"peak RSS {r['peak_rss_mb']:.0f} MB", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
