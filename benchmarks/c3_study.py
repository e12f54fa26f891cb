"""C3 (single crack under compression): errors against the analytic profiles, general vs mirrored meshes.

    .venv/bin/python benchmarks/c3_study.py [--sizes 0.05 0.025 ...] [--out docs]

For every crack face size and each variant — general mesh, mesh mirrored about the crack
around its tips or in a band along it (``mesh.mirror``), one- or two-sided bubbles — runs
the built-in ``single-crack`` case (bulk size 4 m, grading 0.1); records the relative L2 errors of
the slip and of λ_n over the whole crack and away from the tips. The remaining λ_n error
of the band-mirrored two-sided runs comes from the finite domain (the analytic solution is for
the infinite plane): a fifth series and a domain sweep at one mesh enlarge the domain.
Writes ``<out>/c3_study.json``, ``<out>/c3_study.md`` and ``<out>/c3_tip_profiles.png``
(λ_n next to both tips, general vs mirrored). About 30 s on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from polypore.models.fracture_geometry import arc_length
from polypore.runs.static import solve_static, unknowns
from polypore.setup.casefile import load_case

VARIANTS = {
    # name: overrides
    "general, one-sided": ["mesh.mirror=none", "mechanics.bubbles=one-sided"],
    "general, two-sided": ["mesh.mirror=none", "mechanics.bubbles=two-sided"],
    "tips mirrored, two-sided": ["mesh.mirror=tips", "mechanics.bubbles=two-sided"],
    "band mirrored, one-sided": ["mesh.mirror=fractures", "mechanics.bubbles=one-sided"],
    "band mirrored, two-sided": ["mesh.mirror=fractures", "mechanics.bubbles=two-sided"],
    # the same in a 4x wider domain: the finite-domain part of the λ_n error shrinks
    "band mirrored, two-sided, R = 160 m": ["mesh.mirror=fractures", "mechanics.bubbles=two-sided",
                                            "mesh.lower=[-160, -160]", "mesh.upper=[160, 160]"],
}
KEYS = ("slip_L2_rel", "lambda_n_L2_rel", "lambda_n_L2_rel_away_from_tips")


def run(overrides):
    t0 = time.perf_counter()
    case = load_case("single-crack", overrides)
    problem, st, setup, err, _ = solve_static(case)
    ln = np.einsum("fi,fi->f", st.lam, problem.normal)
    s = arc_length(problem.fm)
    o = np.argsort(s)
    rec = {"faces": int(problem.n_ff), "cells": int(problem.fm.mesh.n_cells), "unknowns": unknowns(problem),
           "seconds": time.perf_counter() - t0, **{k: float(err[k]) for k in KEYS}}
    return rec, s[o], ln[o] / setup.exact.lambda_n(s[o])


def rate(h, e):
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=float, nargs="+", default=[0.05, 0.025, 0.0125, 0.00625, 0.003125])
    ap.add_argument("--out", default="docs")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results, profiles = {}, {}
    for name, ov in VARIANTS.items():
        rows = []
        for fs in args.sizes:
            rec, s, rel = run(ov + [f"mesh.fracture_size={fs}"])
            rec["fracture_size"] = fs
            rows.append(rec)
            print(f"{name:36s} fracture_size {fs:<9g} faces {rec['faces']:5d} "
                  + " ".join(f"{k} {rec[k]:.3e}" for k in KEYS) + f"  ({rec['seconds']:.1f} s)", flush=True)
            if fs == args.sizes[-1] and "R =" not in name:
                profiles[name] = (s, rel)
        h = [r["fracture_size"] for r in rows]
        results[name] = {"runs": rows, "rates": {k: rate(h, [r[k] for r in rows]) for k in KEYS}}
    # where the mirrored two-sided λ_n error comes from: the finite domain (the analytic solution is
    # for the infinite plane), so it shrinks when the domain grows at a fixed crack mesh
    domain = []
    for half in (40.0, 80.0, 160.0):
        rec, _, _ = run(VARIANTS["band mirrored, two-sided"] + ["mesh.fracture_size=0.0125", f"mesh.lower=[{-half}, {-half}]",
                                                          f"mesh.upper=[{half}, {half}]"])
        rec["half_width"] = half
        domain.append(rec)
        print(f"domain half-width {half:g} m: lambda_n_L2_rel {rec['lambda_n_L2_rel']:.3e}", flush=True)
    (out / "c3_study.json").write_text(json.dumps({"variants": results, "domain": domain}, indent=1))
    _table(out / "c3_study.md", results, domain)
    _plot(out / "c3_tip_profiles.png", profiles, args.sizes[-1])
    print(f"wrote {out / 'c3_study.json'}, {out / 'c3_study.md'}, {out / 'c3_tip_profiles.png'}")


def _table(path, results, domain):
    lines = ["Command: `.venv/bin/python benchmarks/c3_study.py` (figures in `docs/c3_study.json`).", "",
             "| variant | fracture_size (m) | faces | unknowns | slip | λ_n whole crack | λ_n away from tips |",
             "|---|---|---|---|---|---|---|"]
    for name, res in results.items():
        for r in res["runs"]:
            lines.append(f"| {name} | {r['fracture_size']:g} | {r['faces']} | {r['unknowns']} | "
                         f"{100 * r['slip_L2_rel']:.2f} % | {100 * r['lambda_n_L2_rel']:.3g} % | "
                         f"{100 * r['lambda_n_L2_rel_away_from_tips']:.3g} % |")
        lines.append(f"| {name}: fitted rate | | | | {res['rates']['slip_L2_rel']:.2f} | "
                     f"{res['rates']['lambda_n_L2_rel']:.2f} | {res['rates']['lambda_n_L2_rel_away_from_tips']:.2f} |")
    lines += ["", "Band mirrored, two-sided, fracture_size 0.0125 m, larger domains (−R, R)²:", "",
              "| R (m) | cells | λ_n whole crack |", "|---|---|---|"]
    lines += [f"| {d['half_width']:g} | {d['cells']} | {d['lambda_n_L2_rel']:.2e} |" for d in domain]
    path.write_text("\n".join(lines) + "\n")


def _plot(path, profiles, fs):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for name, (s, rel) in profiles.items():
        style = "-o" if "mirrored" in name else "--s"
        window = 20 * fs  # the last 20 faces before each tip
        for ax, near in zip(axes, (s < window, s > s.max() + 0.5 * fs - window)):
            ax.plot(s[near], rel[near], style, ms=3, lw=1, label=name)
    for ax, title in zip(axes, ("first tip (ξ = 0)", "second tip (ξ = 2ℓ)")):
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xlabel("ξ (m)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("λ_n / analytic")
    axes[1].legend(fontsize=8)
    fig.suptitle(f"C3: normal multiplier next to the crack tips, fracture_size {fs:g} m")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
