"""Issue 28: C6 (fault-injection) and cornerpoint-injection with rate-and-state faults against their
static-friction runs: the event catalogue, the moments against the injected volume, ΔCFS and the
cost.

    .venv/bin/python benchmarks/rate_state_reruns.py [--cases fault-injection cornerpoint-injection]
        [--critical-slip 5e-3] [--stick-rate 1e-8] [--out results/rate_state_reruns] [--set KEY=VALUE]
        [--json FILE]

Each case runs twice into OUT/<case>/coulomb and OUT/<case>/rate-and-state (the run folders hold
events.csv, seismicity.csv/png, the ΔCFS maps). Rate-and-state: f₀ = the case's friction at
V₀ = 1 µm/s, a = 0.010, b = 0.015 (velocity weakening), D_c from the command line,
V_i = 1e-12 m/s with the state from the initial traction, c_s = √(μ/ρ_r), aging law. Printed
per run: wall and CPU seconds, sub-steps, Newton iterations, events (count, largest M₀ / M_w),
the seismic and aseismic moments and McGarr's bound μ_s ΔV, the largest slip and ΔCFS.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from polypore.io.monitor3d import read_vtu
from polypore.runs.dispatch import run_case
from polypore.setup.casefile import load_case

RS = {"a": 0.010, "b": 0.015, "reference_rate": 1e-6, "initial_slip_rate": 1e-12}
ROCK = {"fault-injection": (1.0e10, 0.25, 2260.0), "cornerpoint-injection": (1.0e10, 0.25, 2300.0)}


def overrides(case: str, law: str, dc: float, stick: float) -> list[str]:
    if law == "coulomb":
        return []
    E, nu, rho = ROCK[case]
    cs = float(np.sqrt(E / (2 * (1 + nu)) / rho))
    return (["contact.law=rate-and-state", f"contact.critical_slip={dc}", f"contact.shear_wave_speed={cs:.1f}",
             f"contact.stick_rate={stick}"] + [f"contact.{k}={v}" for k, v in RS.items()])


def one(case: str, law: str, dc: float, stick: float, out: Path, extra=()) -> dict:
    c = load_case(case, overrides=overrides(case, law, dc, stick) + list(extra))
    tic, cpu = time.perf_counter(), time.process_time()
    s = run_case(c, out)
    wall, cpu = time.perf_counter() - tic, time.process_time() - cpu
    last = sorted(out.glob("fractures_*.vtu"))[-1]
    v = read_vtu(last, ["delta_cfs", "jump_t"])
    g = s["conductivity_growth"]
    row = {"case": case, "law": law, "wall_s": wall, "cpu_s": cpu, "sub_steps": g["substeps"],
           "rejected": g["rejected"], "newton": s["totals"]["newton_iterations"],
           "slip_onset_days": None if not s["slip_onset"] else s["slip_onset"]["time"] / 86400.0,
           "max_slip_m": {k: v_[-1] for k, v_ in s["monitor"]["max_slip"].items()},
           "delta_cfs_max_pa": float(np.max(v["delta_cfs"])), "delta_cfs_min_pa": float(np.min(v["delta_cfs"]))}
    if "seismicity" in s:
        row["seismicity"] = s["seismicity"]
    return row


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--cases", nargs="+", default=["fault-injection", "cornerpoint-injection"])
    p.add_argument("--critical-slip", type=float, default=5e-3)
    p.add_argument("--stick-rate", type=float, default=1e-8)
    p.add_argument("--out", default="results/rate_state_reruns")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="more overrides, both laws")
    p.add_argument("--json")
    args = p.parse_args()
    rows = []
    for case in args.cases:
        for law in ("coulomb", "rate-and-state"):
            r = one(case, law, args.critical_slip, args.stick_rate, Path(args.out) / case / law, args.set)
            rows.append(r)
            seis = r.get("seismicity")
            extra = "" if seis is None else (
                f"; {seis['events']} events, seismic M₀ {seis['seismic_moment']:.3g}, aseismic "
                f"{sum(seis['aseismic_moment'].values()):.3g} ({seis['moment_units']}), "
                f"ΔV {seis['injected_volume']:.4g}")
            print(f"{case} {law}: {r['wall_s']:.0f} s wall ({r['cpu_s']:.0f} s CPU), {r['sub_steps']} sub-steps "
                  f"({r['rejected']} rejected), {r['newton']} Newton; slip onset {r['slip_onset_days']} days, "
                  f"largest slip {max(r['max_slip_m'].values()):.3g} m, ΔCFS {r['delta_cfs_min_pa'] / 1e6:.3g} to "
                  f"{r['delta_cfs_max_pa'] / 1e6:.3g} MPa{extra}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
