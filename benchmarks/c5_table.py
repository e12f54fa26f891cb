"""Tables and plots of C5 (``dfm-3d``) runs made by ``benchmarks/c5_runs.py``.

    .venv/bin/python benchmarks/c5_table.py [RUN_DIR ...] [--out-root benchmarks/out/c5] [--md docs/c5_runs.md]
        [--json docs/c5_runs.json] [--plots-dir docs]

Reads the run directories given (else every subdirectory of ``--out-root``); a directory without
summary.json (run in progress or failed) is skipped with a message. With ``--keep`` the runs of
the existing ``--json`` file that are not read again stay in the table (the date column says when
each ran). Writes a Markdown table per
configuration (Newton and GMRES iterations, step cuts, ranks, wall time, peak memory, time
shares), the contact states (open / stick / slip faces per fracture) at the output times (T/2 and
T for C5) read from fractures.csv, and the Newton / GMRES iterations of every step side by side;
``c5_newton_per_step.png`` and, where GMRES iterations are recorded (the block solvers),
``c5_gmres_per_newton.png`` in ``--plots-dir``, and a JSON file
with every per-step number. Configurations are named from each run's case.toml (``mesh.size``,
``mechanics.bubbles``, ``solver.linear``), else from the directory name.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tomllib
from pathlib import Path

import numpy as np

STATES = ("open", "stick", "slip")


def contact_states(path: Path) -> dict:
    """Face counts per contact state and fracture at each output time of a fractures.csv.

    Parameters
    ----------
    path : Path
        fractures.csv of a run (step 0, the initial state, is left out).

    Returns
    -------
    dict
        ``{time: {fracture: {"open": n, "stick": n, "slip": n}}}`` with time as a float.
    """
    header = path.open().readline().strip().split(",")
    cols = [header.index(c) for c in ("step", "time", "fracture", "state")]
    a = np.loadtxt(path, delimiter=",", skiprows=1, usecols=cols, dtype=str, ndmin=2)
    step, t = a[:, 0].astype(int), a[:, 1].astype(float)
    out = {}
    for tt in np.unique(t[step > 0]):                 # output times, then fractures: a handful each
        sel = (step > 0) & (t == tt)
        fr, st = a[sel, 2], a[sel, 3]
        out[float(tt)] = {str(f): {s: int(np.sum((fr == f) & (st == s))) for s in STATES} for f in np.unique(fr)}
    return out


def cells_label(cells: int) -> str:
    """``46153`` → ``46k``; below 1000 the number itself."""
    return f"{cells / 1000:.0f}k" if cells >= 1000 else str(cells)


def load_run(d: Path) -> dict | None:
    """Configuration, totals, per-step numbers and contact states of one run directory.

    Parameters
    ----------
    d : Path
        Run directory (summary.json, case.toml, fractures.csv, optional timing.json).

    Returns
    -------
    dict or None
        None (after a message on stderr) if the run has no summary.json or its last attempt failed.
    """
    timing = json.loads((d / "timing.json").read_text()) if (d / "timing.json").exists() else {}
    if not (d / "summary.json").exists() or timing.get("returncode", 0) != 0:
        if (d / "failed.json").exists() or timing.get("returncode", 0) != 0:
            why = "failed: " + json.loads((d / "failed.json").read_text()).get("error", "") if (
                d / "failed.json").exists() else f"failed (exit status {timing['returncode']})"
        else:
            why = "no summary.json (in progress or not started)"
        print(f"skipping {d}: {why}", file=sys.stderr)
        return None
    s = json.loads((d / "summary.json").read_text())
    case = tomllib.loads((d / "case.toml").read_text()) if (d / "case.toml").exists() else None
    if case is not None:
        size = case.get("mesh", {}).get("size")
        bubbles = case.get("mechanics", {}).get("bubbles", "one-sided")
        linear = case.get("solver", {}).get("linear", "auto")
    else:                                             # fallback: size<h>-<bubbles>-<linear> as c5_runs.py names it
        m_size, m_bub = re.search(r"size([0-9.eE+-]+?)(?:-|$)", d.name), re.search(r"(one|two)-sided", d.name)
        size = float(m_size.group(1)) if m_size else None
        bubbles = m_bub.group(0) if m_bub else "?"
        m_lin = re.search(r"-sided-(.+)$", d.name)
        linear = m_lin.group(1) if m_lin else "?"
    steps, t = s["steps"], s["totals"]
    lin = [st.get("linear_iterations") for st in steps]
    has_gmres = any(lin)
    newton = [st["newton_iterations"] for st in steps]
    n_lin = sum(len(x) for x in lin if x)
    return {
        "name": d.name, "dir": str(d), "size": size, "bubbles": bubbles, "linear": linear,
        "label": f"{cells_label(s['mesh']['cells'])} {bubbles}",
        "cells": s["mesh"]["cells"], "unknowns": s["mesh"]["unknowns"], "fracture_faces": s["mesh"].get("fracture_faces"),
        "ranks": len(t.get("ranks") or []) or 1,
        "n_steps": len(steps), "newton_total": int(sum(newton)), "newton_mean": float(np.mean(newton)) if steps else None,
        "newton_max": int(max(newton)) if steps else None, "cuts": int(sum(st.get("cuts", 0) for st in steps)),
        "gmres_total": int(sum(sum(x) for x in lin if x)) if has_gmres else None,
        "gmres_per_newton": sum(sum(x) for x in lin if x) / n_lin if n_lin else None,
        "wall_seconds": timing.get("wall_seconds", t["seconds"]), "wall_from": "time -v" if timing else "summary",
        "threads": timing.get("threads"), "date": timing.get("date"),
        "peak_memory_mb": timing.get("peak_rss_mb", t["peak_memory_mb"]),
        "seconds": {k: t[f"seconds_{k}"] for k in ("assembly", "linear", "other")} | {"total": t["seconds"]},
        "shares_percent": {k: 100.0 * t[f"seconds_{k}"] / t["seconds"] for k in ("assembly", "linear", "other")},
        "energy_violations": len(s.get("energy_check", {}).get("violations", [])),
        "output_times": (case or {}).get("time", {}).get("output_times"),
        "steps": {
            **{k: [st.get(k) for st in steps] for k in ("time", "dt", "newton_iterations", "residual", "open", "stick",
                                                         "slip", "seconds", "cuts")},
            "gmres_total": [sum(x) if x else None for x in lin],
            "gmres_per_newton": [sum(x) / len(x) if x else None for x in lin],
            "linear_iterations": lin,
        },
        "contact_states": contact_states(d / "fractures.csv") if (d / "fractures.csv").exists() else {},
    }


def fmt(v, spec: str = "") -> str:
    """A table cell: ``–`` for None."""
    return "–" if v is None else format(v, spec)


def markdown(runs: list[dict], plots: list[Path], md_path: Path) -> str:
    """The Markdown of the run table, the plots (linked relative to ``md_path``) and the contact-state table."""
    lines = ["# C5 (dfm-3d) runs", "",
             "Generated by `benchmarks/c5_table.py` from runs of `benchmarks/c5_runs.py`. Wall time and peak memory "
             "from `/usr/bin/time -v` (timing.json; else the run's own summary.json); shares of the run's total.", "",
             "| configuration | mesh.size | cells | unknowns | bubbles | linear | steps | Newton total | Newton / step "
             "| max | step cuts | GMRES total | GMRES / Newton | threads | ranks | wall (s) | peak memory per process (MB) "
             "| assembly | linear solves | other | energy violations | date |",
             "|---|" + "---:|" * 2 + "---:|---|---|" + "---:|" * 15 + "---|"]
    for r in runs:
        sh = r["shares_percent"]
        lines.append(
            f"| {r['label']} | {fmt(r['size'], 'g')} | {r['cells']} | {r['unknowns']} | {r['bubbles']} | {r['linear']} | "
            f"{r['n_steps']} | {r['newton_total']} | {fmt(r['newton_mean'], '.2f')} | {fmt(r['newton_max'])} | "
            f"{r['cuts']} | {fmt(r['gmres_total'])} | {fmt(r['gmres_per_newton'], '.1f')} | {fmt(r['threads'])} | "
            f"{r.get('ranks', 1)} | {r['wall_seconds']:.1f} | {r['peak_memory_mb']:.0f} | {sh['assembly']:.0f} % | "
            f"{sh['linear']:.0f} % | {sh['other']:.0f} % | {r['energy_violations']} | {(r.get('date') or '–')[:10]} |")
    lines += [""] + [f"![{p.stem}]({os.path.relpath(p, md_path.parent)})" for p in plots] + [""]
    fractures = sorted({f for r in runs for states in r["contact_states"].values() for f in states})
    lines += ["## Contact states at the output times", "",
              "Faces open / stick / slip per fracture (fractures.csv) at the output times of each run (by default T/2 = 50 s and T = 100 s for C5).",
              "", "| configuration | t (s) | " + " | ".join(fractures) + " | all |",
              "|---|---:|" + "---:|" * (len(fractures) + 1)]
    for r in runs:
        for tt, states in r["contact_states"].items():
            tot = {s: sum(v[s] for v in states.values()) for s in STATES}
            cells = [" / ".join(str(states[f][s]) for s in STATES) if f in states else "–" for f in fractures]
            lines.append(f"| {r['label']} | {tt:g} | " + " | ".join(cells) + " | " +
                         " / ".join(str(tot[s]) for s in STATES) + " |")
    lines += per_step(runs)
    return "\n".join(lines) + "\n"


def per_step(runs: list[dict]) -> list[str]:
    """Markdown lines: Newton / GMRES iterations of every step, one column per run (– where a run has no
    GMRES count: a direct solver)."""
    n = max((r["n_steps"] for r in runs), default=0)
    out = ["", "## Newton / GMRES iterations per time step", "",
           "| step | " + " | ".join(r["label"] for r in runs) + " |", "|---:|" + "---:|" * len(runs)]
    for k in range(n):
        cells = []
        for r in runs:
            st = r["steps"]
            if k >= len(st["newton_iterations"]):
                cells.append("")
                continue
            g = st["gmres_total"][k]
            cells.append(f"{st['newton_iterations'][k]} / {fmt(g)}")
        out.append(f"| {k + 1} | " + " | ".join(cells) + " |")
    return out


def plot(runs: list[dict], key: str, ylabel: str, title: str, path: Path) -> bool:
    """Per-step ``key`` against time for every run that records it; False (no file) if none does."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    have = [r for r in runs if any(v is not None for v in r["steps"][key])]
    if not have:
        return False
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    meshes = sorted({r["cells"] for r in have})
    for r in have:                                    # colour: mesh; dashed: two-sided bubbles
        t = np.array(r["steps"]["time"], dtype=float)
        y = np.array([np.nan if v is None else v for v in r["steps"][key]], dtype=float)
        ax.plot(t, y, marker="o" if r["bubbles"] == "one-sided" else "s", ms=3, lw=1.2,
                ls="--" if r["bubbles"] == "two-sided" else "-", color=f"C{meshes.index(r['cells'])}", label=r["label"])
    ax.set_xlabel("time t (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if key == "newton_iterations":
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", help="run directories (default: every subdirectory of --out-root)")
    ap.add_argument("--out-root", default="benchmarks/out/c5")
    ap.add_argument("--md", default="docs/c5_runs.md")
    ap.add_argument("--json", default="docs/c5_runs.json")
    ap.add_argument("--plots-dir", default="docs")
    ap.add_argument("--keep", action="store_true",
                    help="keep the runs of the existing --json file that are not read again (same run name: "
                         "replaced), e.g. when only one configuration was re-run")
    args = ap.parse_args()
    dirs = [Path(d) for d in args.dirs] or sorted(p for p in Path(args.out_root).iterdir() if p.is_dir())
    runs = [r for r in map(load_run, dirs) if r is not None]
    if args.keep and Path(args.json).exists():
        names = {r["name"] for r in runs}
        for r in json.loads(Path(args.json).read_text())["runs"]:
            if r["name"] not in names:
                r["contact_states"] = {float(t): v for t, v in r["contact_states"].items()}
                r["label"] = f"{cells_label(r['cells'])} {r['bubbles']}"     # suffixes are given below
                runs.append(r)
    if not runs:
        print("no finished run found", file=sys.stderr)
        return 1
    runs.sort(key=lambda r: (r["cells"], r["bubbles"], r["linear"]))
    labels = [r["label"] for r in runs]
    for r in runs:                                    # same mesh and bubbles twice: tell them apart
        if labels.count(r["label"]) > 1:
            r["label"] += f" {r['linear']}"
    labels = [r["label"] for r in runs]
    for r in runs:                                    # and the rank count of distributed runs
        if labels.count(r["label"]) > 1 and r.get("ranks", 1) > 1:
            r["label"] += f" {r['ranks']} ranks"
    pdir = Path(args.plots_dir)
    plots = [p for p, ok in (
        (pdir / "c5_newton_per_step.png",
         plot(runs, "newton_iterations", "Newton iterations per time step (–)",
              "C5: Newton iterations per time step", pdir / "c5_newton_per_step.png")),
        (pdir / "c5_gmres_per_newton.png",
         plot(runs, "gmres_per_newton", "mean GMRES iterations per Newton iteration (–)",
              "C5: GMRES iterations per Newton iteration (block-AMG)", pdir / "c5_gmres_per_newton.png"))) if ok]
    md_path = Path(args.md)
    text = markdown(runs, plots, md_path)
    print(text)
    md_path.parent.mkdir(parents=True, exist_ok=True)
    md_path.write_text(text)
    data = {"runs": [{**r, "contact_states": {f"{t:g}": v for t, v in r["contact_states"].items()}} for r in runs]}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(data, indent=1) + "\n")
    print("wrote", md_path, args.json, *plots, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
