"""3D penny-shaped crack, P1 and P2 displacements: errors against the analytic solutions on four meshes, fitted rates, plots.

    .venv/bin/python benchmarks/penny_study.py [--levels 5 10 15 20] [--orders 1 2] [--p2-grading 0.5]
        [--similar] [--set KEY=VALUE ...] [--series pressurised inclined general ...]
        [--extras-level 10 | --no-extras] [--out docs]

Level n meshes the crack (radius a = 1 m) with faces of size h = a/n (``mesh.fracture_size``).
Order 1 (``mechanics.order = 1``, the nodal space with face bubbles) keeps the cases' grading
(the size grows by 0.2 m per metre away from the crack): what a user gets with
``--set mesh.fracture_size=...``. Order 2 (``mechanics.order = 2``, continuous P2 on each side
of the crack) uses ``mesh.grading = 0.5`` (``--p2-grading``): the bulk coarsens faster, which
costs P2 little accuracy (a/5: 7.4 % at grading 0.2 and 73k unknowns against 7.8 % at 0.5 and
22k) and keeps a/20 under 4.5 GB. ``--similar`` scales the grading with h instead
(``mesh.grading = 2/n``) for both orders. ``--set`` overrides are applied to every run after the
level's sizes (e.g. ``--set solver.linear=superlu``).

Each run is one ``polypore run`` in its own process, so wall time and peak memory are the
run's own (wall includes process start and meshing; the load average over the run is
recorded: on a shared machine the wall times are inflated). The built-in cases
``penny-pressurised`` (Sneddon) and ``penny-inclined`` (Coulomb sliding, on its default mesh
mirrored about the crack plane, two-sided bubbles) report their errors in summary.json
(``cases/penny_exact.py``: order 1, face-mean jumps and face λ_n against the analytic values
at the face centroids; order 2, the jump as a field at the points of a face rule). Series (``--series``; a "-p2" suffix is order 2, ``--orders`` filters):
"pressurised", "inclined", "general" (``penny-inclined`` on a general mesh, ``mesh.mirror =
"none"``), and the same with "-p2".

A numerical check of the analytic shear compliance runs at every level and order: the
pressurised crack in a remote shear τ = p (the clamped box given the simple shear
u_x = (τ/μ) z) opens and slides, and the ratio of the mean slip to the mean opening must tend
to 2/(2 − ν) (1 at ν = 0) — a check of the slip formula's factor that the discretisation
error, common to both modes, affects much less than each of them. At one level
(``--extras-level``) a few further runs measure what the level runs cannot: the box (±20a
instead of ±10a: the analytic solutions are for the infinite solid), the polygon (32, 48 and
96 sides instead of 64), the bubbles (the other variant) and the shear check at ν = 0 (order
1), and the box for order 2 (where the λ_n error is small enough for the box to show).

Writes ``<out>/penny_study.json``, ``<out>/penny_study.md`` (the tables),
``<out>/penny_profiles.png`` (opening, slip and λ_n against r/a, per face, exact and computed,
P1 and P2 on the finest level) and ``<out>/penny_convergence.png`` (errors against unknowns and
h, P1 and P2, with the issue's targets); prints the tables. About 30 min on 2 shared cores
with PARDISO; peak memory of one run about 4.3 GB (P2, a/20).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from childrun import polypore_run  # noqa: E402

import polypore
from polypore.setup.casefile import load_case
from polypore.solvers.linear import have_pardiso

RADIUS = 1.0          # a (m) in both built-in cases
P2_GRADING = 0.5      # the order-2 series' mesh.grading (see the module docstring)
P1_GRADING = 0.2      # the order-1 series' (the cases' own before order "auto", docs/defaults.md)
# series: (case, overrides, displacement order), refined over the levels
SERIES = {"pressurised": ("penny-pressurised", ["mechanics.order=1"], 1),
          "inclined": ("penny-inclined", ["mechanics.order=1"], 1),
          "general": ("penny-inclined", ["mesh.mirror=none", "mechanics.order=1"], 1),
          "pressurised-p2": ("penny-pressurised", ["mechanics.order=2"], 2),
          "inclined-p2": ("penny-inclined", ["mechanics.order=2"], 2),
          "general-p2": ("penny-inclined", ["mesh.mirror=none", "mechanics.order=2"], 2)}
LABELS = {"pressurised": "pressurised, P1", "inclined": "inclined (mirrored mesh), P1",
          "general": "inclined, general mesh, P1", "pressurised-p2": "pressurised, P2",
          "inclined-p2": "inclined (mirrored mesh), P2", "general-p2": "inclined, general mesh, P2"}
RATE_KEYS = ("opening_L2_rel", "opening_L2_rel_away_from_rim", "slip_L2_rel", "slip_L2_rel_away_from_rim",
             "lambda_n_L2_rel", "lambda_n_L2_rel_away_from_rim")
NAMES = {"opening_L2_rel": "opening L2", "opening_L2_rel_away_from_rim": "opening L2, rim out",
         "slip_L2_rel": "slip L2", "slip_L2_rel_away_from_rim": "slip L2, rim out",
         "lambda_n_L2_rel": "λ_n L2", "lambda_n_L2_rel_away_from_rim": "λ_n L2, rim out"}
SIDES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")
# the targets at a/20: (kind of series, error key, bound)
TARGETS = (("pressurised", "opening_L2_rel_away_from_rim", 0.02), ("pressurised", "opening_L2_rel", 0.04),
           ("inclined", "slip_L2_rel_away_from_rim", 0.03), ("inclined", "lambda_n_L2_rel_away_from_rim", 0.05))


def order_of(name: str) -> int:
    return SERIES[name][2]


def level_overrides(n: float, order: int = 1, similar: bool = False, p2_grading: float = P2_GRADING) -> list[str]:
    """Mesh sizes of level n: crack faces a/n; with ``similar`` also grading 2/n (the size doubles
    a/2 from the crack at every level), else the case's grading (order 1) or ``p2_grading`` (order 2)."""
    ov = [f"mesh.fracture_size={RADIUS / n:.10g}"]
    if similar:
        ov.append(f"mesh.grading={2.0 / n:.10g}")
    elif order == 2:
        ov.append(f"mesh.grading={p2_grading:.10g}")
    else:
        ov.append(f"mesh.grading={P1_GRADING:.10g}")    # the cases' grading until they took 0.5 for P2
    return ov


def shear_overrides(nu: float, tau: float = 1.0e7) -> list[str]:
    """penny-pressurised plus a remote shear σ_xz = τ (Pa): the clamped box moved as u = ((τ/μ) z, 0, 0)."""
    E = load_case("penny-pressurised").data["material"]["E"]
    gamma = tau * 2 * (1 + nu) / E                       # τ/μ
    return ([f"material.nu={nu}", f"exact.stress=[[0, 0, {tau}], [0, 0, 0], [{tau}, 0, 0]]"]
            + [f'mechanics.boundary.{b}.u=["{gamma:.10g} * z", 0, 0]' for b in SIDES])


def run(case: str, overrides: list[str]) -> dict:
    """One ``polypore run`` in a child process: its summary and per-face results (r/a, w, slip, λ_n, state)."""
    with polypore_run(case, overrides) as child:
        if child.proc.returncode != 0:
            raise SystemExit(f"{case} {' '.join(overrides)} failed:\n{child.proc.stderr[-3000:]}")
        summary = json.loads((child.out / "summary.json").read_text())
        with open(child.out / "fractures.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
    wall, (load0, load1) = child.seconds, child.load_average
    c = load_case(case, overrides)
    crack = next(f for f in c.data["fractures"] if f["name"] == "crack")
    n = np.asarray(crack["normal"], float)
    n /= np.linalg.norm(n)
    X = np.array([[float(r[k]) for k in "xyz"] for r in rows]) - np.asarray(crack["centre"], float)
    r = np.linalg.norm(X - np.outer(X @ n, n), axis=1) / float(crack["radius"])
    col = {k: np.array([float(r_[k]) for r_ in rows]) for k in ("area", "jump_n", "jump_t", "lambda_n")}
    mesh = summary["mesh"]
    return {"case": case, "overrides": overrides, "faces": mesh["fracture_faces"], "cells": mesh["cells"],
            "unknowns": mesh["unknowns"], "newton_iterations": summary["steps"][0]["newton_iterations"],
            "seconds": wall, "seconds_by_stage": summary["totals"]["seconds_by_stage"],
            "peak_memory_mb": summary["totals"]["peak_memory_mb"], "load_average": [load0, load1],
            "errors": summary["errors"],
            "_faces": {"r": r, "area": col["area"], "opening": -col["jump_n"], "slip": col["jump_t"],
                       "lambda_n": col["lambda_n"], "state": np.array([r_["state"] for r_ in rows]),
                       # the analytic values at the centre (summary.json) that normalise the profiles
                       "scale": {"opening": summary["errors"].get("exact_opening_max", np.nan),
                                 "slip": summary["errors"].get("exact_slip_max", np.nan),
                                 "lambda_n": summary["errors"].get("exact_lambda_n", np.nan)}}}


BANDS = (0.0, 0.5, 0.8, 0.9, 1.0)    # r/a bands of the error breakdown


def bands(f) -> dict:
    """Per r/a band: the relative L2 error of each field over the band, the band's share of the
    squared error over the whole crack (where the error lives) and, for λ_n, the signed mean
    error and the face-to-face scatter (RMS about the band's mean) relative to the exact value."""
    prof = np.sqrt(np.clip(1 - f["r"] ** 2, 0, None))
    out = {}
    for key in ("opening", "slip", "lambda_n"):
        scale = f["scale"][key]
        if not scale > 0:
            continue
        ex = scale * (np.ones_like(prof) if key == "lambda_n" else prof)
        err2, ref2 = f["area"] * (f[key] - ex) ** 2, f["area"] * ex ** 2
        rows = []
        for lo, hi in zip(BANDS[:-1], BANDS[1:]):
            m = (f["r"] >= lo) & (f["r"] < hi)
            row = {"r_over_a": [lo, hi], "faces": int(m.sum()),
                   "L2_rel": float(np.sqrt(err2[m].sum() / ref2[m].sum())) if m.any() else float("nan"),
                   "share": float(err2[m].sum() / err2.sum())}
            if key == "lambda_n" and m.any():
                A, x = f["area"][m], f[key][m] / scale
                mean = float(np.sum(A * x) / A.sum())
                row |= {"mean_rel": mean - 1, "scatter_rel": float(np.sqrt(np.sum(A * (x - mean) ** 2) / A.sum()))}
            rows.append(row)
        out[key] = rows
    return out


def fit(x, e) -> float:
    """Least-squares slope of log e against log x (NaN with fewer than 2 positive values)."""
    x, e = np.asarray(x, float), np.abs(np.asarray(e, float))
    ok = (e > 0) & np.isfinite(e)
    return float(np.polyfit(np.log(x[ok]), np.log(e[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=float, nargs="+", default=[5, 10, 15, 20], help="n: crack faces a/n")
    ap.add_argument("--orders", type=int, nargs="+", default=[1, 2], choices=[1, 2],
                    help="displacement orders to run (filters --series)")
    ap.add_argument("--p2-grading", type=float, default=P2_GRADING, help="mesh.grading of the order-2 series")
    ap.add_argument("--similar", action="store_true", help="scale the grading with the face size (2/n)")
    ap.add_argument("--set", dest="sets", metavar="KEY=VALUE", action="append", default=[],
                    help="override applied to every run (after the level's mesh sizes)")
    ap.add_argument("--series", nargs="+", default=list(SERIES), choices=list(SERIES))
    ap.add_argument("--extras-level", type=float, default=10, help="level of the box/polygon/bubbles/shear runs")
    ap.add_argument("--no-extras", action="store_true")
    ap.add_argument("--out", default="docs")
    ap.add_argument("--report", action="store_true",
                    help="no runs: remake penny_study.md and penny_convergence.png from <out>/penny_study.json "
                         "(the profiles need the per-face results of a full run)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.report:
        result = json.loads((out / "penny_study.json").read_text())
        _write_md(out, result)
        _plot_convergence(out / "penny_convergence.png", result["runs"])
        return
    t_start = time.perf_counter()
    levels = sorted(args.levels)
    series = [s for s in args.series if order_of(s) in args.orders]
    lo = lambda n, order: level_overrides(n, order, args.similar, args.p2_grading)  # noqa: E731
    runs, faces = {}, {}
    for name in series:
        case, ov, order = SERIES[name]
        runs[name] = []
        for n in levels:
            rec = run(case, lo(n, order) + ov + args.sets)
            rec |= {"series": LABELS[name], "order": order, "level": n, "h": RADIUS / n}
            faces[(name, n)] = rec.pop("_faces")
            rec["bands"] = bands(faces[(name, n)])
            runs[name].append(rec)
            _print_run(f"{LABELS[name]} a/{n:g}", rec)
    rates = {name: _rates(rows) for name, rows in runs.items()}
    shear = {}
    for order in args.orders:
        if ("pressurised" if order == 1 else "pressurised-p2") in series:
            shear[str(order)] = []
            for n in levels:
                rec = _shear_run(n, order, 0.25, lo, args.sets)
                shear[str(order)].append(rec)
                _print_run(f"penny-pressurised P{order} a/{n:g} {rec['label']}", rec)
    extras = [] if args.no_extras else _extras(args.extras_level, lo, args.sets, series)
    targets = _targets(runs, rates, levels)
    result = {"command": " ".join(["benchmarks/penny_study.py"] + sys.argv[1:]), "pardiso": have_pardiso(),
              "levels": levels,
              "level_rule": ("mesh.fracture_size = a/n, mesh.grading = 2/n" if args.similar else
                             f"mesh.fracture_size = a/n; order 1: the cases' mesh.grading (0.2), order 2: "
                             f"mesh.grading = {args.p2_grading:g}"),
              "overrides": args.sets, "cores": os.cpu_count(), "polypore": str(Path(polypore.__file__).parent),
              "runs": runs, "rates": rates, "shear_check": shear, "extras": extras, "targets": targets,
              "seconds": time.perf_counter() - t_start}
    (out / "penny_study.json").write_text(json.dumps(result, indent=1))
    _write_md(out, result)
    _plot_profiles(out / "penny_profiles.png", faces, series, levels)
    _plot_convergence(out / "penny_convergence.png", runs)
    print(f"wrote {out / 'penny_study.json'}, {out / 'penny_study.md'}, {out / 'penny_profiles.png'}, "
          f"{out / 'penny_convergence.png'} ({result['seconds']:.0f} s)")


def _write_md(out: Path, result: dict):
    md = _tables(result["runs"], result["rates"], result["shear_check"], result["extras"], result["targets"])
    print("\n" + md)
    (out / "penny_study.md").write_text(
        "# 3D penny-shaped crack: P1 and P2 against the analytic solutions\n\n"
        f"`.venv/bin/python {result['command']}` ({result['seconds'] / 60:.0f} min; mesh rule: "
        f"{result['level_rule']}; discussion in docs/accuracy_3d.md, \"Penny-shaped cracks\"). Wall times include "
        "process start and meshing, on 2 cores shared with other jobs (\"load\": the larger of the 1-minute load "
        "averages at the start and the end of the run): they are inflated, and only roughly comparable. "
        "Errors: relative L2 over the crack faces, face-mean jumps (order 1) or the jump at the points of a "
        "face rule (order 2; before commit 'penny P2 errors as a field' the face means too, 0.1-0.9 points "
        "higher) and face λ_n against the analytic values (`cases/penny_exact.py`); \"rim out\": r ≤ 0.9a. Rates: least-squares slopes over "
        "the four meshes, in h (e ~ h^p) and per unknown (e ~ N^-q).\n\n" + md)


def _rates(rows) -> dict:
    h = [r["h"] for r in rows]
    N = [r["unknowns"] for r in rows]
    out = {}
    for k in RATE_KEYS:
        if all(k in r["errors"] for r in rows):
            e = [r["errors"][k] for r in rows]
            # the rate in h (e ~ h^p), and per unknown (e ~ N^-q)
            out[k] = {"h": fit(h, e), "unknowns": -fit(N, e)}
    return out


def _targets(runs, rates, levels) -> list[dict]:
    """The issue's targets at a/20 (the finest level if a/20 was not run), per order."""
    out = []
    for order, suffix in ((1, ""), (2, "-p2")):
        for kind, key, bound in TARGETS:
            name = kind + suffix
            if name not in runs:
                continue
            r = runs[name][-1]
            out.append({"order": order, "series": name, "level": r["level"], "measure": key, "bound": bound,
                        "value": r["errors"][key], "met": bool(r["errors"][key] <= bound)})
        if "inclined" + suffix in runs:
            rows = runs["inclined" + suffix]
            not_sliding = [r["errors"]["faces"] - r["errors"]["faces_slip"] for r in rows]
            out.append({"order": order, "series": "inclined" + suffix, "level": rows[-1]["level"],
                        "measure": "faces not slipping", "bound": 0, "value": not_sliding[-1],
                        "met": not_sliding[-1] == 0, "every_level": not_sliding})
            for key in ("lambda_n_L2_rel_away_from_rim", "lambda_n_L2_rel"):
                rate = rates["inclined" + suffix][key]
                e = [r["errors"][key] for r in rows]
                out.append({"order": order, "series": "inclined" + suffix, "measure": f"{key}: converging",
                            "rate_h": rate["h"], "rate_unknowns": rate["unknowns"],
                            "monotone": bool(all(b < a for a, b in zip(e, e[1:]))),
                            "met": bool(rate["h"] > 0)})
    return out


def _extras(n, lo, sets, series) -> list[dict]:
    specs = []
    for name in ("pressurised", "inclined"):
        if name not in series:
            continue
        case = SERIES[name][0]
        specs.append((case, 1, "box ±20a", ["mesh.lower=[-20, -20, -20]", "mesh.upper=[20, 20, 20]"]))
        other = "two-sided" if load_case(case).data["mechanics"].get("bubbles", "one-sided") == "one-sided" \
            else "one-sided"
        specs.append((case, 1, f"{other} bubbles", [f"mechanics.bubbles={other}"]))
    if "general" in series:
        specs.append(("penny-inclined", 1, "general mesh, one-sided bubbles",
                      ["mesh.mirror=none", "mechanics.bubbles=one-sided"]))
    if "pressurised" in series:
        specs += [("penny-pressurised", 1, f"{k}-gon", [f"fractures.crack.sides={k}"]) for k in (32, 48, 96)]
    for name in ("pressurised-p2", "inclined-p2"):
        if name in series:
            specs.append((SERIES[name][0], 2, "P2, box ±20a", ["mechanics.order=2", "mesh.lower=[-20, -20, -20]",
                                                               "mesh.upper=[20, 20, 20]"]))
    out = []
    for case, order, label, ov in specs:
        rec = run(case, lo(n, order) + [f"mechanics.order={order}"] + ov + sets)
        rec.pop("_faces")
        rec |= {"order": order, "level": n, "h": RADIUS / n, "label": label}
        out.append(rec)
        _print_run(f"{case} a/{n:g} {label}", rec)
    if "pressurised" in series:
        out.append(_shear_run(n, 1, 0.0, lo, sets))
        _print_run(f"penny-pressurised a/{n:g} {out[-1]['label']}", out[-1])
    return out


def _shear_run(n, order, nu, lo, sets) -> dict:
    """The pressurised crack in a remote shear τ = p: discrete mean slip / mean opening against 2/(2 − ν)."""
    rec = run("penny-pressurised", lo(n, order) + shear_overrides(nu) + [f"mechanics.order={order}"] + sets)
    f = rec.pop("_faces")
    rec |= {"case": "penny-pressurised", "order": order, "level": n, "h": RADIUS / n,
            "label": f"pressure + shear τ = p, ν = {nu:g}",
            "slip_over_opening": float(np.sum(f["area"] * f["slip"]) / np.sum(f["area"] * f["opening"])),
            "slip_over_opening_exact": 2 / (2 - nu)}
    return rec


def _print_run(label, rec):
    e = rec["errors"]
    keys = [k for k in ("opening_L2_rel", "opening_L2_rel_away_from_rim", "opening_mean_rel", "slip_L2_rel",
                        "slip_L2_rel_away_from_rim", "slip_mean_rel", "slip_direction_deg_mean",
                        "lambda_n_L2_rel", "lambda_n_L2_rel_away_from_rim", "lambda_n_mean_rel") if k in e]
    extra = f" slip/opening {rec['slip_over_opening']:.4f} (exact {rec['slip_over_opening_exact']:.4f})" \
        if "slip_over_opening" in rec else ""
    print(f"{label:55s} faces {rec['faces']:5d} unknowns {rec['unknowns']:7d} open {e['faces_open']:4d} "
          f"slip {e['faces_slip']:4d} {rec['seconds']:6.1f} s {rec['peak_memory_mb']:6.0f} MB "
          f"load {rec['load_average'][0]:.1f}/{rec['load_average'][1]:.1f} | "
          + " ".join(f"{k.replace('_L2_rel', '').replace('_away_from_rim', '(rim out)')} {e[k]:.4g}" for k in keys)
          + extra, flush=True)


def _pc(x, digits=2):
    return f"{100 * x:.{digits}f} %"


def _tables(runs, rates, shear, extras, targets) -> str:
    """The study's tables, as markdown."""
    L = ["| series | h | crack faces | unknowns | Newton | opening/slip L2 | rim out | mean | λ_n L2 | λ_n rim out "
         "| mean λ_n | direction (°) | faces not open/slipping | wall (s) | peak (MB) | load |", "|---" * 16 + "|"]
    for name, rows in runs.items():
        q = "opening" if "opening_L2_rel" in rows[0]["errors"] else "slip"
        for r in rows:
            e = r["errors"]
            ln = (_pc(e["lambda_n_L2_rel"], 3), _pc(e["lambda_n_L2_rel_away_from_rim"], 3),
                  f"{100 * e['lambda_n_mean_rel']:+.3f} %") if "lambda_n_L2_rel" in e else ("–", "–", "–")
            d = f"{e['slip_direction_deg_mean']:.2f}" if "slip_direction_deg_mean" in e else "–"
            wrong = e["faces"] - (e["faces_open"] if q == "opening" else e["faces_slip"])
            L.append(f"| {LABELS[name]} | a/{r['level']:g} | {r['faces']} | {r['unknowns']} | "
                     f"{r['newton_iterations']} | {_pc(e[q + '_L2_rel'])} | {_pc(e[q + '_L2_rel_away_from_rim'])} | "
                     f"{100 * e[q + '_mean_rel']:+.2f} % | {ln[0]} | {ln[1]} | {ln[2]} | {d} | {wrong} | "
                     f"{r['seconds']:.1f} | {r['peak_memory_mb']:.0f} | {max(r['load_average']):.1f} |")
        rt = rates[name]
        for kind, label in (("h", "fitted rate in h"), ("unknowns", "fitted rate per unknown")):
            lr = (f"{rt['lambda_n_L2_rel'][kind]:.2f}", f"{rt['lambda_n_L2_rel_away_from_rim'][kind]:.2f}") \
                if "lambda_n_L2_rel" in rt else ("", "")
            L.append(f"| {LABELS[name]}: {label} | | | | | {rt[q + '_L2_rel'][kind]:.2f} | "
                     f"{rt[q + '_L2_rel_away_from_rim'][kind]:.2f} | | {lr[0]} | {lr[1]} | | | | | | |")
    finest = max(r["level"] for rows in runs.values() for r in rows)
    L.append(f"\nThe issue's targets (at a/20{'' if finest == 20 else f'; here measured at a/{finest:g}'}):\n\n"
             "| order | case | target | measured | met |\n|---|---|---|---|---|")
    for t in targets:
        case = t["series"].removesuffix("-p2")
        if "bound" in t and isinstance(t["value"], float):
            L.append(f"| P{t['order']} | {case} | {NAMES[t['measure']]} ≤ {_pc(t['bound'], 0)} | {_pc(t['value'])} | "
                     f"{'yes' if t['met'] else 'no'} |")
        elif "bound" in t:
            L.append(f"| P{t['order']} | {case} | every face slipping | faces not slipping: {t['value']} (every "
                     f"level: {', '.join(map(str, t['every_level']))}) | {'yes' if t['met'] else 'no'} |")
        else:
            key = t["measure"].split(":")[0]
            L.append(f"| P{t['order']} | {case} | {NAMES[key]} converging | rate {t['rate_h']:.2f} in h, "
                     f"{t['rate_unknowns']:.2f} per unknown; {'decreasing' if t['monotone'] else 'not decreasing'} "
                     f"at every level | {'yes' if t['met'] else 'no'} |")
    L.append("\nError by r/a band (relative L2 over the band; in brackets the band's share of the squared error "
             "over the crack; for λ_n also the band's mean error and face-to-face scatter):")
    for name, rows in runs.items():
        for key in ("opening", "slip", "lambda_n"):
            if key not in rows[0]["bands"]:
                continue
            cells = " | ".join(f"{b['r_over_a'][0]:g}–{b['r_over_a'][1]:g}" for b in rows[0]["bands"][key])
            L.append(f"\n| {LABELS[name]}, {key}: h | {cells} |\n|---|" + "---|" * len(BANDS[1:]))
            for r in rows:
                if key == "lambda_n":
                    cells = [f"{_pc(b['L2_rel'], 3)} ({100 * b['share']:.0f} %; mean {100 * b['mean_rel']:+.3f} %, "
                             f"scatter {_pc(b['scatter_rel'], 3)})" for b in r["bands"][key]]
                else:
                    cells = [f"{_pc(b['L2_rel'])} ({100 * b['share']:.0f} %)" for b in r["bands"][key]]
                L.append(f"| a/{r['level']:g} | " + " | ".join(cells) + " |")
    for order, rows in shear.items():
        dev = [abs(r["slip_over_opening"] / r["slip_over_opening_exact"] - 1) for r in rows]
        L.append(f"\nShear check, P{order} (pressure + remote shear τ = p, ν = 0.25):\n\n"
                 "| h | unknowns | opening L2 | slip L2 | mean slip / mean opening | 2/(2 − ν) | deviation |"
                 "\n|---|---|---|---|---|---|---|")
        for r, d in zip(rows, dev):
            e = r["errors"]
            L.append(f"| a/{r['level']:g} | {r['unknowns']} | {_pc(e['opening_L2_rel'])} | {_pc(e['slip_L2_rel'])} | "
                     f"{r['slip_over_opening']:.4f} | {r['slip_over_opening_exact']:.4f} | {_pc(d)} |")
        L.append(f"| fitted rate in h | | | | | | {fit([r['h'] for r in rows], dev):.2f} |")
    if extras:
        L.append("\nFurther runs at one level:\n\n| case | order | variant | unknowns | opening/slip L2 | rim out | "
                 "mean | λ_n L2 | λ_n rim out | mean λ_n | other |\n|---|---|---|---|---|---|---|---|---|---|---|")
        for r in extras:
            e = r["errors"]
            q = "opening" if "opening_L2_rel" in e else "slip"
            other = ""
            if "slip_over_opening" in r:
                other = (f"slip {_pc(e['slip_L2_rel'])}; slip/opening {r['slip_over_opening']:.4f} "
                         f"(2/(2 − ν) = {r['slip_over_opening_exact']:.4f})")
            ln = (_pc(e["lambda_n_L2_rel"], 3), _pc(e["lambda_n_L2_rel_away_from_rim"], 3),
                  f"{100 * e['lambda_n_mean_rel']:+.3f} %") if "lambda_n_L2_rel" in e else ("–", "–", "–")
            L.append(f"| {r['case']} a/{r['level']:g} | P{r['order']} | {r['label']} | {r['unknowns']} | "
                     f"{_pc(e[q + '_L2_rel'])} | {_pc(e[q + '_L2_rel_away_from_rim'])} | "
                     f"{100 * e[q + '_mean_rel']:+.2f} % | {ln[0]} | {ln[1]} | {ln[2]} | {other} |")
    return "\n".join(L) + "\n"


def _plot_profiles(path, faces, series, levels):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from polypore.cases.penny_exact import RIM

    n = levels[-1]
    # (series P1, series P2, field, title, y label, the analytic state of every face)
    panels = [p for p in (("pressurised", "pressurised-p2", "opening", "penny-pressurised: opening",
                           "opening w / w(0)", "open"),
                          ("inclined", "inclined-p2", "slip", "penny-inclined: slip", "slip |[[u]]_τ| / slip(0)",
                           "slip"),
                          ("inclined", "inclined-p2", "lambda_n", "penny-inclined (mirrored mesh): λ_n",
                           "λ_n / (σ sin²ψ)", "slip"),
                          ("general", "general-p2", "lambda_n", "penny-inclined, general mesh: λ_n",
                           "λ_n / (σ sin²ψ)", "slip"))
              if (p[0], n) in faces or (p[1], n) in faces]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.8 * len(panels), 4.4), squeeze=False)
    rr = np.linspace(0, 1, 300)
    for ax, (s1, s2, key, title, ylabel, state) in zip(axes[0], panels):
        for name, colour, marker, order in ((s1, "tab:orange", "o", 1), (s2, "tab:blue", "o", 2)):
            if (name, n) not in faces:
                continue
            f = faces[(name, n)]
            y = f[key] / f["scale"][key]
            wrong = f["state"] != state
            ax.plot(f["r"][~wrong], y[~wrong], marker, ms=1.5, color=colour, alpha=0.5, mec="none",
                    label=f"P{order}, a/{n:g}, per face ({f['r'].size} faces)")
            if np.any(wrong):
                ax.plot(f["r"][wrong], y[wrong], "x", ms=3, color="tab:red" if order == 2 else "salmon",
                        label=f"P{order}: {wrong.sum()} faces not {'open' if state == 'open' else 'slipping'}")
        ref = np.ones_like(rr) if key == "lambda_n" else np.sqrt(1 - rr ** 2)
        ax.plot(rr, ref, "k-", lw=1.2, label="analytic")
        ax.axvline(RIM, color="grey", lw=0.8, ls=":")
        if key == "lambda_n" and "general" not in s1:     # a tight band about 1, holding 99.5 % of the faces
            dev = [np.abs(faces[(s, n)][key] / faces[(s, n)]["scale"][key] - 1) for s in (s1, s2) if (s, n) in faces]
            half = max(0.002, 1.2 * float(np.quantile(np.concatenate(dev), 0.995)))
            ax.set_ylim(1 - half, 1 + half)
        ax.set_xlim(0, 1.0)
        ax.set_xlabel("distance from the centre r / a")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, markerscale=4, loc="lower left")
    fig.suptitle(f"3D penny-shaped crack at a/{n:g}, P1 and P2: per-face values against r/a "
                 "(dotted: r = 0.9a, the rim band's edge)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _plot_convergence(path, runs):
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # (series without the order suffix, key, label, colour); P1 dashed with open markers, P2 solid
    fields = [("pressurised", "opening_L2_rel", "opening", "tab:blue"),
              ("pressurised", "opening_L2_rel_away_from_rim", "opening, rim out", "tab:cyan"),
              ("inclined", "slip_L2_rel", "slip", "tab:green"),
              ("inclined", "slip_L2_rel_away_from_rim", "slip, rim out", "tab:olive")]
    lam = [("inclined", "lambda_n_L2_rel", "λ_n (mirrored)", "tab:purple"),
           ("inclined", "lambda_n_L2_rel_away_from_rim", "λ_n (mirrored), rim out", "tab:pink"),
           ("general", "lambda_n_L2_rel", "λ_n (general mesh)", "tab:brown"),
           ("general", "lambda_n_L2_rel_away_from_rim", "λ_n (general mesh), rim out", "tab:gray")]
    fig, axes = plt.subplots(1, 3, figsize=(18, 6.6))
    for ax, lines, x in ((axes[0], fields, "unknowns"), (axes[1], fields, "h"), (axes[2], lam, "unknowns")):
        for base, key, label, colour in lines:
            for order, suffix, style in ((1, "", "o--"), (2, "-p2", "s-")):
                rows = runs.get(base + suffix)
                if not rows or key not in rows[0]["errors"]:
                    continue
                e = np.array([r["errors"][key] for r in rows])
                xs = np.array([r[x] for r in rows], float)
                rate = fit(xs, e) if x == "h" else -fit(xs, e)
                ax.loglog(xs, e, style, color=colour, ms=5, mfc="none" if order == 1 else colour,
                          label=f"P{order} {label} ({'rate' if x == 'h' else 'per unknown'} {rate:.2f})")
    for ax, lines in ((axes[0], ((0.02, "opening rim out ≤ 2 %"), (0.03, "slip rim out ≤ 3 %"),
                                 (0.04, "opening ≤ 4 %"))), (axes[2], ((0.05, "λ_n rim out ≤ 5 %"),))):
        for y, text in lines:
            ax.axhline(y, color="k", lw=0.7, ls=":")
            ax.text(ax.get_xlim()[0] * 1.05, y * 1.03, f"target at a/20: {text}", fontsize=7)
    h = np.array([r["h"] for r in next(iter(runs.values()))])
    axes[1].loglog(h, 0.1 * h / h.max(), "k:", lw=1, label="slope 1")
    axes[0].set_xlabel("unknowns")
    axes[1].set_xlabel("crack face size h / a")
    axes[2].set_xlabel("unknowns")
    axes[0].set_title("opening (pressurised) and slip (inclined)", fontsize=10)
    axes[1].set_title("the same against the crack face size", fontsize=10)
    axes[2].set_title("λ_n (inclined; exact: uniform σ sin²ψ)", fontsize=10)
    for ax in (axes[0], axes[2]):                      # no labels on the minor ticks (they overlap)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    for ax in axes:
        ax.set_ylabel("relative L2 error over the crack faces")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7.5, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.13))
    fig.suptitle("3D penny-shaped crack, a/5 … a/20: P1 (dashed, open markers) and P2 (solid) against the "
                 "analytic solutions", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
