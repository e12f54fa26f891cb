"""Benchmark: time-step convergence of fault slip and fault pressure on the tilted corner-point grid
(issue 24, docs/fault_bounds.md "The time step").

    PYTHONPATH=src .venv-fast/bin/python benchmarks/timestep_study.py --out DIR [--days 5 2.5 1 0.5]
        [--limited 1] [--growth-limit 1000] [--dilatancy 20] [--cells 60 50 11] [--json docs/timestep_study.json]
    PYTHONPATH=src .venv-fast/bin/python benchmarks/timestep_study.py --out DIR --analyse-only

Runs ``benchmarks/cornerpoint_reactivation.py`` (the tilted grid of docs/fault_bounds.md: 60°
pillars, pinch-outs, crossing contact faults F1 and F2, 100 kg/s for 10 days, ``block-amg``) once
per time step, one after the other, into DIR/dt<days>, then compares the runs at the output times
of the coarsest step. Per fault and time it prints the largest slip, the slipped area (faces with
slip since the start above ``--slipped`` mm, default 0.1), the area in the slip state, and the
largest and mean fracture pressure; for the largest slip at the end it adds the Richardson
estimate from the two finest steps (first order: s₀ ≈ 2 s(Δt/2) − s(Δt)). ``--limited`` steps are
run once more with ``time.max_conductivity_growth = --growth-limit`` (sub-steps wherever a fracture
conductivity would grow more in one, DIR/dt<days>_g<limit>) and shown beside the plain ones. Writes
DIR/timestep_study.png (largest slip and largest fault pressure against time, per fault and step).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

DAY = 86400.0
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from fault_bounds import read_csv  # noqa: E402


def run(out: Path, days: float, cells, dilatancy: float, limit: float | None = None) -> None:
    cmd = [sys.executable, str(HERE / "cornerpoint_reactivation.py"), "--cells", *map(str, cells), "--tilt", "60",
           "--pinchout", "2", str(cells[2] - 1), "--f1-x", "1400", "--f2-contact", "--linear", "block-amg",
           "--set", "parameters.mass_rate=100", "--set", f"time.step={days * DAY:g}",
           "--set", f"flow.dilatancy_angle={dilatancy:g}", "--out", str(out), "--json", str(out) + ".json"]
    if limit is not None:
        cmd += ["--set", f"time.max_conductivity_growth={limit:g}", "--set", "time.growth_cuts=10"]
    print("running:", " ".join(cmd[1:]), flush=True)
    subprocess.run(cmd, check=True)


def measures(folder: Path, times, slipped_mm: float) -> dict:
    """Per fault: lists over ``times`` (s) of max slip (m), slipped and slip-state area fractions,
    max and area-mean p_f (Pa)."""
    d = read_csv(folder / "fractures.csv")         # (n_out, n_ff) arrays, fault_bounds.py's reader
    res = {}
    for name in np.unique(d["fracture"]):
        f = d["fracture"] == name
        a = d["area"][f]
        keys = ("max_slip", "slipped_area", "slip_state_area", "max_p_f", "mean_p_f")
        r = {k: [] for k in keys}
        for t in times:
            hit = np.flatnonzero(np.isclose(d["time"], t, rtol=0, atol=1.0))
            if not hit.size:
                raise SystemExit(f"{folder}: no output at t = {t:g} s")
            s, pf = d["jump_t"][hit[0], f], d["p_f"][hit[0], f]
            r["max_slip"].append(float(s.max()))
            r["slipped_area"].append(float(a[s > slipped_mm * 1e-3].sum() / a.sum()))
            r["slip_state_area"].append(float(a[d["state"][hit[0], f] == "slip"].sum() / a.sum()))
            r["max_p_f"].append(float(pf.max()))
            r["mean_p_f"].append(float(np.average(pf, weights=a)))
        res[str(name)] = r
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--days", type=float, nargs="+", default=[5.0, 2.5, 1.0, 0.5])
    ap.add_argument("--dilatancy", type=float, default=20.0)
    ap.add_argument("--cells", type=int, nargs=3, default=[60, 50, 11])
    ap.add_argument("--slipped", type=float, default=0.1, help="slip (mm) above which a face counts as slipped")
    ap.add_argument("--limited", type=float, nargs="*", default=[], help="steps (days) also run with the growth limit")
    ap.add_argument("--growth-limit", type=float, default=1e3, help="time.max_conductivity_growth of those runs")
    ap.add_argument("--analyse-only", action="store_true")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    plain = sorted(a.days, reverse=True)
    # runs by label: (folder, step in days, growth limit)
    runs = {f"{dd:g}": (a.out / f"dt{dd:g}", dd, None) for dd in plain}
    runs |= {f"{dd:g} g{a.growth_limit:g}": (a.out / f"dt{dd:g}_g{a.growth_limit:g}", dd, a.growth_limit)
             for dd in sorted(a.limited, reverse=True)}
    if not a.analyse_only:
        a.out.mkdir(parents=True, exist_ok=True)
        for folder, dd, lim in runs.values():
            run(folder, dd, a.cells, a.dilatancy, lim)
    days = list(runs)
    coarsest = max(v[1] for v in runs.values())
    times = np.arange(0.0, 10.0 + 1e-9, coarsest) * DAY
    res = {k: measures(v[0], times, a.slipped) for k, v in runs.items()}
    print(f"\nψ = {a.dilatancy:g}°; columns per step Δt: largest slip (mm) | slipped area (%) | slip state (%) | "
          f"max / mean p_f (MPa)")
    for name in res[days[0]]:
        print(f"\n{name}")
        print("| day | " + " | ".join(f"Δt = {k.replace(' g', ' d, growth ≤ ')}" + ("" if " g" in k else " d")
                                      for k in days) + " |")
        print("|---" * (len(days) + 1) + "|")
        for i, t in enumerate(times):
            cells = []
            for dd in days:
                r = res[dd][name]
                cells.append(f"{1e3 * r['max_slip'][i]:.2f} mm, {100 * r['slipped_area'][i]:.1f} %, "
                             f"{100 * r['slip_state_area'][i]:.1f} %, {r['max_p_f'][i] / 1e6:.2f}/"
                             f"{r['mean_p_f'][i] / 1e6:.2f} MPa")
            print(f"| {t / DAY:g} | " + " | ".join(cells) + " |")
        if len(plain) >= 2 and plain[-2] == 2 * plain[-1]:
            s1, s2 = (res[f"{dd:g}"][name]["max_slip"][-1] for dd in plain[-2:])
            print(f"largest slip at the end, Richardson (first order) from Δt = {plain[-2]:g}, {plain[-1]:g} d: "
                  f"{1e3 * (2 * s2 - s1):.2f} mm")
    own = {k: np.arange(0.0, 10.0 + 1e-9, v[1]) * DAY for k, v in runs.items()}
    _plot({k: measures(v[0], own[k], a.slipped) for k, v in runs.items()}, own, days, a.out / "timestep_study.png")
    if a.json:
        a.json.write_text(json.dumps({"dilatancy_deg": a.dilatancy, "cells": a.cells, "times_s": times.tolist(),
                                      "slipped_mm": a.slipped, "growth_limit": a.growth_limit if a.limited else None,
                                      "runs": {k: res[k] for k in days}}, indent=1))
    return 0


def _plot(res, times: dict, days, path: Path) -> None:
    """Largest slip and fault pressure against time, each run at its own step times."""
    sys.path.insert(0, str(HERE.parent / "src"))
    from polypore.io.plots import _plt, save

    plt = _plt()
    names = list(res[days[0]])
    fig, axes = plt.subplots(2, len(names), figsize=(5.5 * len(names), 7), squeeze=False)
    for j, name in enumerate(names):
        for dd in days:
            r = res[dd][name]
            lab = f"Δt = {dd.replace(' g', ' d, growth ≤ ')}" + ("" if " g" in dd else " d")
            axes[0, j].plot(times[dd] / DAY, 1e3 * np.array(r["max_slip"]), ".-", label=lab)
            axes[1, j].plot(times[dd] / DAY, 1e-6 * np.array(r["max_p_f"]), ".-", label=lab)
        axes[0, j].set(title=f"{name}: largest slip", ylabel="slip (mm)")
        axes[1, j].set(title=f"{name}: largest fracture overpressure", xlabel="time (days)", ylabel="p_f (MPa)")
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
            ax.legend()
    save(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
