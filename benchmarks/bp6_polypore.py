"""polypore's BP6-QD against the reference (docs/bp6.md, "polypore's run").

Runs benchmarks/cases/bp6-qd.toml (plane strain, ν = 0, the fault y = 0, |x| ≤ 20 km, in a clamped
square box of half-width R) at a fault face size h and a variant, reads the run's fractures_*.vtu,
and compares with docs/bp6_reference.json (the reference's finest grid, h = 5 m) and, with
--same-h, with the reference solver run at polypore's face size (and in a clamped circle of
radius R): the fault pressure against eq. (26) (`bp6.pore_pressure`), the slip at the stations
0, 0.5, 1, 1.5, 2.5, 3.5 km at 50, 100, 200, 365, 730 days (those run), the slip profile, and the
slip fronts. Errors of slip are relative to the reference's largest slip. One core:

    .venv/bin/python benchmarks/bp6_polypore.py --variant C --h 200 --R 50 --json out.json

--days N runs the first N days; --reuse reads a finished run in --out instead of running it;
--dt is the time step (days; rate-and-state: the largest step, sub-stepped by polypore).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))

from polypore.cases import bp6  # noqa: E402
from polypore.io.monitor3d import read_pvd, read_vtu  # noqa: E402

DAY = bp6.DAY
CASE = os.path.join(HERE, "cases", "bp6-qd.toml")
REFERENCE = os.path.join(ROOT, "docs", "bp6_reference.json")
POLYPORE = os.path.join(ROOT, ".venv", "bin", "polypore")
STATIONS = (0.0, 500.0, 1000.0, 1500.0, 2500.0, 3500.0)
DAYS = (50, 100, 200, 365, 730)
PROFILE_HALF = 5000.0           # profile errors over |x| ≤ 5 km
PRESSURE_HALF = 7500.0          # pressure errors over |x| ≤ 7.5 km (the stations' range)
TIP_SLIP = 1e-6                 # QD-C: a face has slipped when its slip exceeds 1 µm
VARIANTS = {"C": "QD-C", "A": "QD-A", "S": "QD-S"}
PRM = bp6.Bp6Parameters()
RATE_STATE = {"contact.law": '"rate-and-state"', "contact.a": PRM.a, "contact.b": PRM.b,
              "contact.critical_slip": PRM.Dc, "contact.reference_rate": PRM.V0,
              "contact.initial_slip_rate": PRM.V_init, "contact.initial_state_from": '"traction"',
              "contact.shear_wave_speed": PRM.cs}


def output_days(end_days: float) -> list[float]:
    days = set(np.arange(10, end_days + 0.5, 10).tolist()) | {d for d in (50, 60, 150, 365, 730) if d <= end_days}
    days.add(float(end_days))
    return sorted(float(d) for d in days)


def overrides(variant: str, h: float, R: float, size: float, end_days: float, dt_days: float) -> list[str]:
    out = [f"mesh.fracture_size={h}", f"parameters.h={h}", f"mesh.lower=[{-R}, {-R}]", f"mesh.upper=[{R}, {R}]",
           f"mesh.size={size}", f"time.end={end_days * DAY}", f"time.step={dt_days * DAY}",
           "time.output_times=[" + ", ".join(f"{d * DAY}" for d in output_days(end_days)) + "]"]
    if variant in ("A", "S"):
        out += [f"{k}={v}" for k, v in RATE_STATE.items()]
        out.append(f'contact.state_law="{"aging" if variant == "A" else "slip"}"')
    return out


def run(args, out: str) -> float:
    cmd = [POLYPORE, "run", CASE, "--out", out, "--force"]
    for s in overrides(args.variant, args.h, args.R * 1e3, args.size, args.days, args.dt) + args.set:
        cmd += ["--set", s]
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    print(shlex.join(cmd), flush=True)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env)
    return time.perf_counter() - t0


def read_run(out: str) -> dict:
    """Face centroids x (sorted), and per output time slip, p_f, λ_n, λ_t, state (slip rate for
    rate-and-state), all (n_t, n_faces) in the order of x."""
    series = read_pvd(os.path.join(out, "solution.pvd"))
    files = sorted({(t, f) for t, f, _ in series if os.path.basename(f).startswith("fractures")})
    t = np.array([a for a, _ in files])
    data = {}
    for _, f in files:
        v = read_vtu(os.path.join(out, f))
        for k in ("jump_t", "jump", "p_f", "lambda_n", "lambda_t", "state", "slip_rate"):
            if k in v:
                data.setdefault(k, []).append(v[k])
    v = read_vtu(os.path.join(out, files[0][1]), ["Points", "connectivity"])
    P, c = v["Points"], v["connectivity"].reshape(-1, 2)
    x = 0.5 * (P[c[:, 0], 0] + P[c[:, 1], 0])
    order = np.argsort(x)
    res = {k: np.asarray(a)[:, order] for k, a in data.items()}
    res["x"], res["t"] = x[order], t
    res["length"] = np.abs(P[c[order, 1], 0] - P[c[order, 0], 0])
    res["summary"] = json.load(open(os.path.join(out, "summary.json")))
    return res


def front_tip(x, slip, h):
    """QD-C front: the reference's `crack_tip` on the faces (centroids), δ below TIP_SLIP as 0."""
    pos = x > 0
    z = x[pos]
    d = np.where(slip[pos] > TIP_SLIP, slip[pos], 0.0)
    if not np.any(d > 0):
        return 0.0
    i = np.nonzero(d > 0)[0][-1]
    if i == 0 or d[i - 1] <= d[i]:
        return float(z[i] + 0.5 * h)
    s0, s1 = d[i - 1] ** (2 / 3), d[i] ** (2 / 3)
    return float(z[i] + s1 * (z[i] - z[i - 1]) / (s0 - s1))


def station_values(x, values, stations):
    """Linear interpolation between face centroids (station 0 lies between the two faces at ±h/2)."""
    return np.interp(np.asarray(stations), x, values)


def row(ref, t):
    k = int(np.argmin(np.abs(np.asarray(ref["t"]) - t)))
    if abs(ref["t"][k] - t) > 1.0:
        raise ValueError(f"reference has no row at t = {t}")
    return k


def compare(run_: dict, ref: dict, variant: str, h: float, label: str) -> dict:
    """Errors of one polypore run against one reference (a `Bp6Result.to_dict()`-like mapping)."""
    x, t = run_["x"], run_["t"]
    st = np.asarray(ref["stations"])
    cols = [list(st).index(s) for s in STATIONS]
    slip_ref = np.asarray(ref["slip"])[:, cols]
    scale = float(np.max(np.asarray(ref["slip"])))
    out = {"reference": label, "slip_scale_m": scale, "stations_m": list(STATIONS), "days": [], "slip_polypore": [],
           "slip_reference": [], "slip_error_rel": []}
    for d in DAYS:
        j = np.nonzero(np.abs(t - d * DAY) < 1.0)[0]
        if not j.size:
            continue
        j = int(j[0])
        sp = station_values(x, run_["jump_t"][j], STATIONS)
        sr = slip_ref[row(ref, d * DAY)]
        out["days"].append(d)
        out["slip_polypore"].append(sp.tolist())
        out["slip_reference"].append(sr.tolist())
        out["slip_error_rel"].append(((sp - sr) / scale).tolist())
    e = np.abs(np.asarray(out["slip_error_rel"]))
    out["max_slip_error_rel"] = float(e.max()) if e.size else None
    out["max_slip_error_rel_without_x0"] = float(e[:, 1:].max()) if e.size else None
    # profiles: the reference's profile interpolated to the face centroids, |x| ≤ PROFILE_HALF
    prof = []
    pz, pt, ps = np.asarray(ref["profile_z"]), np.asarray(ref["profile_t"]), np.asarray(ref["profile_slip"])
    inner = np.abs(x) <= min(PROFILE_HALF, pz.max())
    for k, tp in enumerate(pt):
        j = np.nonzero(np.abs(t - tp) < 1.0)[0]
        if not j.size:
            continue
        diff = run_["jump_t"][int(j[0])][inner] - np.interp(x[inner], pz, ps[k])
        prof.append({"day": tp / DAY, "max_error_rel": float(np.abs(diff).max() / scale),
                     "rms_error_rel": float(np.sqrt(np.mean(diff ** 2)) / scale)})
    out["profiles"] = prof
    # fronts at every output: δ ≥ 1 mm (front_slip), QD-C the slipped region's edge (front_tip),
    # rate-and-state V ≥ 1e-9 m/s (front_rate)
    fronts = []
    for j, tj in enumerate(t):
        if tj <= 0:
            continue
        k = row(ref, tj)
        pos = x >= 0
        f = {"day": tj / DAY, "front_slip": bp6._front(x[pos], run_["jump_t"][j][pos], ref["front_slip_threshold"]),
             "front_slip_reference": ref["front_slip"][k]}
        if variant == "C":
            f["front_tip"] = front_tip(x, run_["jump_t"][j], h)
            f["front_tip_reference"] = ref["front_tip"][k]
            f["front_error_m"] = f["front_tip"] - f["front_tip_reference"]
        elif "slip_rate" in run_:
            f["front_rate"] = bp6._front(x[pos], run_["slip_rate"][j][pos], ref["front_rate_threshold"], log=True)
            f["front_rate_reference"] = ref["front_rate"][k]
            f["front_error_m"] = f["front_rate"] - f["front_rate_reference"]
        f["front_slip_error_m"] = f["front_slip"] - f["front_slip_reference"]
        fronts.append(f)
    out["fronts"] = fronts
    out["max_front_error_m"] = max((abs(f["front_error_m"]) for f in fronts if "front_error_m" in f), default=None)
    out["max_front_slip_error_m"] = max((abs(f["front_slip_error_m"]) for f in fronts), default=None)
    return out


def pressure_errors(run_: dict) -> dict:
    """p_f at the face centroids against eq. (26) at the same points (|x| ≤ PRESSURE_HALF), and at
    the stations by interpolation, relative to the peak p(0, t_off)."""
    x, t = run_["x"], run_["t"]
    peak = float(bp6.pore_pressure(np.array([0.0]), PRM.t_off)[0])
    inner = np.abs(x) <= PRESSURE_HALF
    rows = []
    for j, tj in enumerate(t):
        if tj <= 0:
            continue
        p = run_["p_f"][j]
        pe = bp6.pore_pressure(x, tj)
        ps = station_values(x, p, STATIONS)
        pse = bp6.pore_pressure(np.asarray(STATIONS), tj)
        rows.append({"day": tj / DAY, "faces_max_error_rel": float(np.max(np.abs(p - pe)[inner]) / peak),
                     "stations_error_rel": ((ps - pse) / peak).tolist(),
                     "injected_m2": float(np.sum(p * 1e-9 * run_["length"]))})
    return {"peak_Pa": peak, "rows": rows,
            "faces_max_error_rel": max(r["faces_max_error_rel"] for r in rows),
            "stations_max_error_rel_without_x0": max(max(abs(v) for v in r["stations_error_rel"][1:]) for r in rows),
            "stations_max_error_rel_x0": max(abs(r["stations_error_rel"][0]) for r in rows)}


def same_h_reference(variant: str, h: float, R: float | None, end_days: float) -> dict:
    """The reference solver at the cell size h (and in a clamped circle of radius R), as a dict."""
    t_out = np.array(sorted({d * DAY for d in output_days(end_days)} | {d * DAY for d in DAYS if d <= end_days}))
    prof_t = np.array([d for d in (10, 30, 60, 100, 150, 200, 365, 730) if d <= end_days]) * DAY
    kw = dict(dz=h, t_out=t_out, profile_t=prof_t, t_final=end_days * DAY, R_clamp=R)
    if variant == "C":
        r = bp6.run_constant_friction(PRM, dt_max=DAY, **kw)
    else:
        r = bp6.run_rate_state(PRM, law="aging" if variant == "A" else "slip", **kw)
    return r.to_dict(digits=12)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--variant", choices=tuple(VARIANTS), default="C")
    ap.add_argument("--h", type=float, default=200.0, help="fault face size (m)")
    ap.add_argument("--R", type=float, default=50.0, help="half-width of the clamped box (km)")
    ap.add_argument("--size", type=float, default=None, help="far cell size (m; default R/10)")
    ap.add_argument("--days", type=float, default=730.0, help="end (days; BP6: 730)")
    ap.add_argument("--dt", type=float, default=1.0, help="time step (days)")
    ap.add_argument("--out", default=None, help="run folder (default /tmp/bp6_polypore/<variant>_h<h>_R<R>)")
    ap.add_argument("--reuse", action="store_true", help="read the finished run in --out, do not run")
    ap.add_argument("--same-h", action="store_true", help="also compare with the reference solver at h "
                    "(whole space and clamped circle of radius R)")
    ap.add_argument("--json", default=None, help="write the errors here")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="another case override, passed to polypore run (repeatable)")
    ap.add_argument("--tag", default=None, help="run folder name under /tmp/bp6_polypore (default from the options)")
    args = ap.parse_args()
    args.size = args.size or args.R * 1e3 / 10
    tag = args.tag or f"{args.variant}_h{args.h:g}_R{args.R:g}" + (f"_d{args.days:g}" if args.days != 730 else "")
    out = args.out or os.path.join("/tmp/bp6_polypore", tag)
    wall = None
    if not args.reuse:
        wall = run(args, out)
    r = read_run(out)
    variant = VARIANTS[args.variant]
    ref = json.load(open(REFERENCE))["reference"][variant]
    summ = r["summary"]
    result = {"variant": variant, "h_m": args.h, "R_km": args.R, "far_size_m": args.size, "days": args.days,
              "dt_days": args.dt, "faces": int(r["x"].size), "cells": summ["mesh"].get("cells"),
              "wall_s": wall if wall is not None else summ["totals"]["seconds"],
              "run_seconds": summ["totals"]["seconds"], "steps": len(summ["steps"]),
              "newton_iterations": summ["totals"].get("newton_iterations"),
              "overrides": overrides(args.variant, args.h, args.R * 1e3, args.size, args.days, args.dt) + args.set,
              "pressure": pressure_errors(r), "vs_finest": compare(r, ref, args.variant, args.h, "finest (h = 5 m)")}
    if args.same_h:
        result["vs_same_h"] = compare(r, same_h_reference(args.variant, args.h, None, args.days), args.variant,
                                      args.h, f"reference solver at h = {args.h:g} m")
        result["vs_same_h_clamped"] = compare(r, same_h_reference(args.variant, args.h, args.R * 1e3, args.days),
                                              args.variant, args.h,
                                              f"reference solver at h = {args.h:g} m, clamped circle R = {args.R:g} km")
    report(result)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


def report(res: dict):
    p = res["pressure"]
    print(f"\n{res['variant']}: h = {res['h_m']:g} m, R = {res['R_km']:g} km, {res['faces']} faces, "
          f"{res['cells']} cells, {res['steps']} steps, {res['run_seconds']:.0f} s")
    print(f"pressure: faces |x| ≤ 7.5 km max |Δp|/p_peak = {p['faces_max_error_rel']:.2e}; stations 0.5-3.5 km "
          f"{p['stations_max_error_rel_without_x0']:.2e}, station 0 (between the faces at ±h/2) "
          f"{p['stations_max_error_rel_x0']:.2e}")
    for key in ("vs_finest", "vs_same_h", "vs_same_h_clamped"):
        if key not in res:
            continue
        c = res[key]
        print(f"-- against {c['reference']} (max slip {c['slip_scale_m']:.5f} m)")
        print("   day  " + "  ".join(f"{s / 1e3:>12.1f} km" for s in c["stations_m"]))
        for d, sp, sr, e in zip(c["days"], c["slip_polypore"], c["slip_reference"], c["slip_error_rel"], strict=True):
            print(f"   {d:>4}  " + "  ".join(f"{a:.5f}/{b:.5f}" for a, b in zip(sp, sr, strict=True)))
            print("         " + "  ".join(f"{v:>+15.2e}" for v in e))
        if c["max_slip_error_rel"] is not None:
            print(f"   max |Δslip|/max δ: {c['max_slip_error_rel']:.2e} (without x = 0: "
                  f"{c['max_slip_error_rel_without_x0']:.2e})")
        print("   profiles |x| ≤ 5 km (max, rms): " + ", ".join(
            f"{q['day']:g} d {q['max_error_rel']:.1e}/{q['rms_error_rel']:.1e}" for q in c["profiles"]))
        fr = [f for f in c["fronts"] if f["day"] in DAYS or f["day"] in (10, 30)]
        name = "front_tip" if res["variant"] == "QD-C" else "front_rate"
        print(f"   {name} (m) polypore/reference: " + ", ".join(
            f"{f['day']:g} d {f.get(name, float('nan')):.0f}/{f.get(name + '_reference', float('nan')):.0f}"
            for f in fr))
        print(f"   max |Δfront| {c['max_front_error_m']:.0f} m, max |Δfront_slip (1 mm)| "
              f"{c['max_front_slip_error_m']:.0f} m")


if __name__ == "__main__":
    main()
