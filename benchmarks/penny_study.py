"""3D penny-shaped crack: errors against the analytic solutions on four meshes, fitted rates, plots.

    .venv/bin/python benchmarks/penny_study.py [--levels 5 10 15 20] [--similar] [--set KEY=VALUE ...]
        [--series pressurised inclined general] [--extras-level 10 | --no-extras] [--out docs]

Level n meshes the crack (radius a = 1 m) with faces of size h = a/n (``mesh.fracture_size``)
and keeps the cases' grading (the size grows by 0.2 m per metre away from the crack): what a
user gets with ``--set mesh.fracture_size=...``. ``--similar`` scales the grading with h as
well (``mesh.grading = 2/n``), so that the meshes are similar to each other near the crack:
cleaner rates in h, but the far field is refined too (a/20: 142k unknowns instead of 62k for
a 20 % smaller error). ``--set`` overrides are applied to every run after the level's sizes
(e.g. ``--set mesh.tip_size=0.01`` or ``--set solver.linear=superlu``).
Each run is one ``polypore run`` in its own process, so wall time and peak memory are the
run's own. The built-in cases ``penny-pressurised`` (Sneddon) and ``penny-inclined`` (Coulomb
sliding, on its default mesh mirrored about the crack plane) report their errors in
summary.json (``cases/penny_exact.py``); the series "general" runs ``penny-inclined`` on a
general mesh (``mesh.mirror = "none"``) for comparison.

A numerical check of the analytic shear compliance runs at every level: the pressurised
crack in a remote shear τ = p (the clamped box given the simple shear u_x = (τ/μ) z) opens
and slides, and the ratio of the mean slip to the mean opening must tend to 2/(2 − ν) (1 at
ν = 0) — a check of the slip formula's factor that the discretisation error, common to
both modes, affects much less than each of them. At one level (``--extras-level``) a few
further runs measure what the level runs cannot: the box (±20a instead of ±10a: the
analytic solutions are for the infinite solid), the polygon (32, 48 and 96 sides instead of
64), the bubbles (the other variant) and the shear check at ν = 0.

Writes ``<out>/penny_study.json``, ``<out>/penny_profiles.png`` (opening, slip and λ_n against
r/a, per face, exact and computed, coarsest and finest level) and
``<out>/penny_convergence.png``; prints the table. About 6 min on 2 idle cores with PARDISO.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from polypore.setup.casefile import load_case
from polypore.solvers.linear import have_pardiso

RADIUS = 1.0          # a (m) in both built-in cases
# series: (case, overrides) refined over the levels
SERIES = {"pressurised": ("penny-pressurised", []),
          "inclined": ("penny-inclined", []),
          "general": ("penny-inclined", ["mesh.mirror=none"])}
LABELS = {"pressurised": "penny-pressurised", "inclined": "penny-inclined (mirrored mesh)",
          "general": "penny-inclined, general mesh"}
RATE_KEYS = ("opening_L2_rel", "opening_L2_rel_away_from_rim", "slip_L2_rel", "slip_L2_rel_away_from_rim",
             "lambda_n_L2_rel", "lambda_n_L2_rel_away_from_rim")
SIDES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")


def level_overrides(n: float, similar: bool = False) -> list[str]:
    """Mesh sizes of level n: crack faces a/n; with ``similar`` also grading 2/n (the size doubles
    a/2 from the crack at every level), else the case's grading."""
    return [f"mesh.fracture_size={RADIUS / n:.10g}"] + ([f"mesh.grading={2.0 / n:.10g}"] if similar else [])


def shear_overrides(nu: float, tau: float = 1.0e7) -> list[str]:
    """penny-pressurised plus a remote shear σ_xz = τ (Pa): the clamped box moved as u = ((τ/μ) z, 0, 0)."""
    E = load_case("penny-pressurised").data["material"]["E"]
    gamma = tau * 2 * (1 + nu) / E                       # τ/μ
    return ([f"material.nu={nu}", f"exact.stress=[[0, 0, {tau}], [0, 0, 0], [{tau}, 0, 0]]"]
            + [f'mechanics.boundary.{b}.u=["{gamma:.10g} * z", 0, 0]' for b in SIDES])


def run(case: str, overrides: list[str]) -> dict:
    """One ``polypore run`` in a child process: its summary and per-face results (r/a, w, slip, λ_n, state)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "polypore", "-q", "run", case, "--out", str(out), "--force"]
        for ov in overrides:
            cmd += ["--set", ov]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            raise SystemExit(f"{case} {' '.join(overrides)} failed:\n{proc.stderr[-3000:]}")
        summary = json.loads((out / "summary.json").read_text())
        with open(out / "fractures.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
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
            "peak_memory_mb": summary["totals"]["peak_memory_mb"], "errors": summary["errors"],
            "_faces": {"r": r, "area": col["area"], "opening": -col["jump_n"], "slip": col["jump_t"],
                       "lambda_n": col["lambda_n"], "state": np.array([r_["state"] for r_ in rows]),
                       # the analytic values at the centre (summary.json) that normalise the profiles
                       "scale": {"opening": summary["errors"].get("exact_opening_max", np.nan),
                                 "slip": summary["errors"].get("exact_slip_max", np.nan),
                                 "lambda_n": summary["errors"].get("exact_lambda_n", np.nan)}}}


BANDS = (0.0, 0.5, 0.8, 0.9, 1.0)    # r/a bands of the error breakdown


def bands(f) -> dict:
    """Per r/a band: the relative L2 error of each field over the band and the band's share of the
    squared error over the whole crack (where the error lives)."""
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
            rows.append({"r_over_a": [lo, hi], "faces": int(m.sum()),
                         "L2_rel": float(np.sqrt(err2[m].sum() / ref2[m].sum())) if m.any() else float("nan"),
                         "share": float(err2[m].sum() / err2.sum())})
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
    ap.add_argument("--similar", action="store_true", help="scale the grading with the face size (2/n)")
    ap.add_argument("--set", dest="sets", metavar="KEY=VALUE", action="append", default=[],
                    help="override applied to every run (after the level's mesh sizes)")
    ap.add_argument("--series", nargs="+", default=list(SERIES), choices=list(SERIES))
    ap.add_argument("--extras-level", type=float, default=10, help="level of the box/polygon/bubbles/shear runs")
    ap.add_argument("--no-extras", action="store_true")
    ap.add_argument("--out", default="docs")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    levels = sorted(args.levels)
    runs, faces = {}, {}
    for name in args.series:
        case, ov = SERIES[name]
        runs[name] = []
        for n in levels:
            rec = run(case, level_overrides(n, args.similar) + ov + args.sets)
            rec |= {"series": LABELS[name], "level": n, "h": RADIUS / n}
            faces[(name, n)] = rec.pop("_faces")
            rec["bands"] = bands(faces[(name, n)])
            runs[name].append(rec)
            _print_run(f"{LABELS[name]} a/{n:g}", rec)
    rates = {name: _rates(rows) for name, rows in runs.items()}
    shear = []
    if "pressurised" in args.series:
        for n in levels:
            rec = _shear_run(n, 0.25, args.similar, args.sets)
            shear.append(rec)
            _print_run(f"penny-pressurised a/{n:g} {rec['label']}", rec)
    extras = [] if args.no_extras else _extras(args.extras_level, args.similar, args.sets, args.series)
    result = {"command": " ".join(["benchmarks/penny_study.py"] + sys.argv[1:]), "pardiso": have_pardiso(),
              "levels": levels,
              "level_rule": "mesh.fracture_size = a/n" + (", mesh.grading = 2/n" if args.similar else ""),
              "overrides": args.sets,
              "runs": runs, "rates": rates, "shear_check": shear, "extras": extras,
              "seconds": time.perf_counter() - t_start}
    (out / "penny_study.json").write_text(json.dumps(result, indent=1))
    _table(runs, rates, shear, extras)
    _plot_profiles(out / "penny_profiles.png", faces, args.series, levels)
    _plot_convergence(out / "penny_convergence.png", runs, shear)
    print(f"wrote {out / 'penny_study.json'}, {out / 'penny_profiles.png'}, {out / 'penny_convergence.png'} "
          f"({result['seconds']:.0f} s)")


def _rates(rows) -> dict:
    h = [r["h"] for r in rows]
    N = [r["unknowns"] for r in rows]
    out = {}
    for k in RATE_KEYS:
        if all(k in r["errors"] for r in rows):
            e = [r["errors"][k] for r in rows]
            # the rate in h, and the same expressed per unknown (N ~ h^-3 in 3D)
            out[k] = {"h": fit(h, e), "unknowns_x3": -3 * fit(N, e)}
    return out


def _extras(n, similar, sets, series) -> list[dict]:
    base = level_overrides(n, similar)
    specs = []
    for name in ("pressurised", "inclined"):
        if name not in series:
            continue
        case = SERIES[name][0]
        specs.append((case, "box ±20a", ["mesh.lower=[-20, -20, -20]", "mesh.upper=[20, 20, 20]"]))
        other = "two-sided" if load_case(case).data["mechanics"].get("bubbles", "one-sided") == "one-sided" \
            else "one-sided"
        specs.append((case, f"{other} bubbles", [f"mechanics.bubbles={other}"]))
    if "general" in series:
        specs.append(("penny-inclined", "general mesh, one-sided bubbles",
                      ["mesh.mirror=none", "mechanics.bubbles=one-sided"]))
    if "pressurised" in series:
        specs += [("penny-pressurised", f"{k}-gon", [f"fractures.crack.sides={k}"]) for k in (32, 48, 96)]
    out = []
    for case, label, ov in specs:
        rec = run(case, base + ov + sets)
        rec.pop("_faces")
        rec |= {"level": n, "h": RADIUS / n, "label": label}
        out.append(rec)
        _print_run(f"{case} a/{n:g} {label}", rec)
    if "pressurised" in series:
        out.append(_shear_run(n, 0.0, similar, sets))
        _print_run(f"penny-pressurised a/{n:g} {out[-1]['label']}", out[-1])
    return out


def _shear_run(n, nu, similar, sets) -> dict:
    """The pressurised crack in a remote shear τ = p: discrete mean slip / mean opening against 2/(2 − ν)."""
    rec = run("penny-pressurised", level_overrides(n, similar) + shear_overrides(nu) + sets)
    f = rec.pop("_faces")
    rec |= {"case": "penny-pressurised", "level": n, "h": RADIUS / n, "label": f"pressure + shear τ = p, ν = {nu:g}",
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
          f"{rec['seconds']:6.1f} s {rec['peak_memory_mb']:6.0f} MB | "
          + " ".join(f"{k.replace('_L2_rel', '').replace('_away_from_rim', '(rim out)')} {e[k]:.4g}" for k in keys)
          + extra, flush=True)


def _pc(x):
    return f"{100 * x:.2f} %"


def _table(runs, rates, shear, extras):
    print("\n| case | h | faces | unknowns | Newton | w/slip L2 | w/slip L2 (rim out) | λ_n L2 | λ_n L2 (rim out) "
          "| direction (°) | open faces | wall (s) | peak (MB) |\n" + "|---" * 13 + "|")
    for name, rows in runs.items():
        case = LABELS[name]
        q = "opening" if "opening_L2_rel" in rows[0]["errors"] else "slip"
        for r in rows:
            e = r["errors"]
            ln = (_pc(e["lambda_n_L2_rel"]), _pc(e["lambda_n_L2_rel_away_from_rim"])) if "lambda_n_L2_rel" in e \
                else ("–", "–")
            d = f"{e['slip_direction_deg_mean']:.2f}" if "slip_direction_deg_mean" in e else "–"
            print(f"| {case} | a/{r['level']:g} | {r['faces']} | {r['unknowns']} | {r['newton_iterations']} | "
                  f"{_pc(e[q + '_L2_rel'])} | {_pc(e[q + '_L2_rel_away_from_rim'])} | {ln[0]} | {ln[1]} | {d} | "
                  f"{e['faces_open']} | {r['seconds']:.1f} | {r['peak_memory_mb']:.0f} |")
        rt = rates[name]
        lr = (f"{rt['lambda_n_L2_rel']['h']:.2f}", f"{rt['lambda_n_L2_rel_away_from_rim']['h']:.2f}") \
            if "lambda_n_L2_rel" in rt else ("–", "–")
        print(f"| {case}: fitted rate in h | | | | | {rt[q + '_L2_rel']['h']:.2f} | "
              f"{rt[q + '_L2_rel_away_from_rim']['h']:.2f} | {lr[0]} | {lr[1]} | | | | |")
    print("\nError by r/a band (relative L2 over the band; share of the squared error over the crack):")
    for name, rows in runs.items():
        case = LABELS[name]
        for key in ("opening", "slip", "lambda_n"):
            if key not in rows[0]["bands"]:
                continue
            cells = " | ".join(f"{b['r_over_a'][0]:g}–{b['r_over_a'][1]:g}" for b in rows[0]["bands"][key])
            print(f"\n| {case}, {key}: h | {cells} |\n|---|" + "---|" * len(BANDS[1:]))
            for r in rows:
                print(f"| a/{r['level']:g} | " + " | ".join(f"{_pc(b['L2_rel'])} ({100 * b['share']:.0f} %)"
                                                          for b in r["bands"][key]) + " |")
    if shear:
        dev = [abs(r["slip_over_opening"] / r["slip_over_opening_exact"] - 1) for r in shear]
        print("\n| h | unknowns | opening L2 | slip L2 | mean slip / mean opening | 2/(2 − ν) | deviation |"
              "\n|---|---|---|---|---|---|---|")
        for r, d in zip(shear, dev):
            e = r["errors"]
            print(f"| a/{r['level']:g} | {r['unknowns']} | {_pc(e['opening_L2_rel'])} | {_pc(e['slip_L2_rel'])} | "
                  f"{r['slip_over_opening']:.4f} | {r['slip_over_opening_exact']:.4f} | {_pc(d)} |")
        print(f"| fitted rate in h | | | | | | {fit([r['h'] for r in shear], dev):.2f} |")
    if extras:
        print("\n| case | variant | unknowns | w/slip L2 | w/slip L2 (rim out) | mean w/slip | λ_n L2 (rim out) "
              "| other |"
              "\n|---|---|---|---|---|---|---|---|")
        for r in extras:
            e = r["errors"]
            q = "opening" if "opening_L2_rel" in e else "slip"
            other = ""
            if "slip_over_opening" in r:
                other = (f"slip {_pc(e['slip_L2_rel'])}; slip/opening {r['slip_over_opening']:.4f} "
                         f"(2/(2 − ν) = {r['slip_over_opening_exact']:.4f})")
            ln = _pc(e["lambda_n_L2_rel_away_from_rim"]) if "lambda_n_L2_rel_away_from_rim" in e else "–"
            print(f"| {r['case']} a/{r['level']:g} | {r['label']} | {r['unknowns']} | {_pc(e[q + '_L2_rel'])} | "
                  f"{_pc(e[q + '_L2_rel_away_from_rim'])} | {100 * e[q + '_mean_rel']:+.2f} % | {ln} | {other} |")


def _plot_profiles(path, faces, series, levels):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from polypore.cases.penny_exact import RIM

    # (series, field, y label, the analytic state of every face)
    panels = [p for p in (("pressurised", "opening", "opening w / w(0)", "open"),
                          ("inclined", "slip", "slip |[[u]]_τ| / slip(0)", "slip"),
                          ("inclined", "lambda_n", "λ_n / σ sin²ψ", "slip"),
                          ("general", "lambda_n", "λ_n / σ sin²ψ", "slip")) if p[0] in series]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False)
    rr = np.linspace(0, 1, 300)
    for ax, (name, key, ylabel, state) in zip(axes[0], panels):
        for n, colour in ((levels[0], "tab:orange"), (levels[-1], "tab:blue")):
            f = faces[(name, n)]
            y = f[key] / f["scale"][key]
            wrong = f["state"] != state
            ax.plot(f["r"][~wrong], y[~wrong], ".", ms=2, color=colour, alpha=0.6, label=f"a/{n:g}, per face")
            if np.any(wrong):
                ax.plot(f["r"][wrong], y[wrong], "x", ms=3, color="tab:red" if n == levels[-1] else "salmon",
                        label=f"a/{n:g}, faces not {'open' if state == 'open' else 'slipping'}")
        ref = np.ones_like(rr) if key == "lambda_n" else np.sqrt(1 - rr ** 2)
        ax.plot(rr, ref, "k-", lw=1.2, label="analytic")
        ax.axvline(RIM, color="grey", lw=0.8, ls=":")
        ax.set_xlabel("r / a")
        ax.set_ylabel(ylabel)
        ax.set_title(LABELS[name], fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, markerscale=3)
    fig.suptitle("3D penny-shaped crack: per-face values against r/a (dotted: r = 0.9a, the rim band)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _plot_convergence(path, runs, shear):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lines = [("pressurised", "opening_L2_rel", "opening", "o-", "tab:blue"),
             ("pressurised", "opening_L2_rel_away_from_rim", "opening, rim out", "o--", "tab:blue"),
             ("inclined", "slip_L2_rel", "slip", "s-", "tab:green"),
             ("inclined", "slip_L2_rel_away_from_rim", "slip, rim out", "s--", "tab:green"),
             ("inclined", "lambda_n_L2_rel", "λ_n", "^-", "tab:purple"),
             ("inclined", "lambda_n_L2_rel_away_from_rim", "λ_n, rim out", "^--", "tab:purple"),
             ("general", "lambda_n_L2_rel", "λ_n, general mesh", "v-", "tab:brown"),
             ("general", "lambda_n_L2_rel_away_from_rim", "λ_n, general mesh, rim out", "v--", "tab:brown")]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    for name, key, label, style, colour in lines:
        if name not in runs:
            continue
        rows = runs[name]
        e = np.array([r["errors"][key] for r in rows])
        h = np.array([r["h"] for r in rows])
        N = np.array([r["unknowns"] for r in rows])
        axes[0].loglog(h, e, style, color=colour, ms=4, label=f"{label} (rate {fit(h, e):.2f})")
        axes[1].loglog(N, e, style, color=colour, ms=4, label=label)
    if shear:
        h = np.array([r["h"] for r in shear])
        dev = np.array([abs(r["slip_over_opening"] / r["slip_over_opening_exact"] - 1) for r in shear])
        axes[0].loglog(h, dev, "d:", color="grey",
                       label=f"|slip/opening ÷ 2/(2 − ν) − 1| (rate {fit(h, dev):.2f})")
    hs = np.array([r["h"] for r in next(iter(runs.values()))])
    axes[0].loglog(hs, 0.5 * hs / hs.max() * 0.2, "k:", lw=1, label="slope 1")
    axes[0].set_xlabel("crack face size h / a")
    axes[1].set_xlabel("unknowns")
    for ax in axes:
        ax.set_ylabel("relative L2 error over the crack faces")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.suptitle("3D penny-shaped crack: errors against the analytic solutions")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
