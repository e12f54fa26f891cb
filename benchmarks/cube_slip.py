"""3D slip accuracy per unknown on the cube case (issue 13): uniform against tip-graded tetrahedra.

    .venv/bin/python benchmarks/cube_slip.py                 # the study (~3 min)
    .venv/bin/python benchmarks/cube_slip.py --diagnose      # what moves the error (~2 min)
    .venv/bin/python benchmarks/cube_slip.py --reference     # remake the fine-mesh reference (~25 min, 4 GB)

The built-in case ``cube-slip-3d``: unit cube, fracture x ∈ [0.2, 0.8] on y = z,
y, z ∈ [0.3, 0.7], ymin clamped, ymax displaced by (−2e-4, −2e-4, 0) m, μ = λ_L = 10 GPa,
F = 0.5. Each run is a separate ``polypore run`` process (wall time and peak memory are
its own), with PARDISO. Errors against the reference (cases/reference.py): maximum slip,
relative L2 of the slip magnitude over the whole fracture and with the 10 % next to every
edge left out, relative L2 of λ_n with the rim left out, open faces.

``--reference`` runs a sequence of √r-graded meshes (sizes scaled by ``REF_SCALES``),
extrapolates the maximum slip (Richardson with the rate fitted on the three levels) and
resamples the finest run's slip and λ_n on a grid of the fracture plane into
``src/polypore/cases/data/cube-slip-3d-reference.npz``.

Writes ``<out>/cube_slip.json``, ``<out>/cube_slip.md`` and ``<out>/cube_slip.png``.
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "src/polypore/cases/data/cube-slip-3d.toml"
REF = ROOT / "src/polypore/cases/data/cube-slip-3d-reference.npz"
POLYPORE = Path(sys.executable).parent / "polypore"

ORIGIN = np.array([0.2, 0.3, 0.3])
E1 = np.array([1.0, 0.0, 0.0])
E2 = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
LENGTHS = (0.6, 0.4 * np.sqrt(2.0))

# uniform meshes: the "before" (no grading: fracture_size = size, no tip refinement)
UNIFORM = [0.2, 0.1, 0.07, 0.05, 0.035]
# tip-graded meshes: the case's defaults (size 0.3, fracture_size 0.08, tip_size 0.015) scaled
GRADED = [1.6, 1.25, 1.0, 0.8, 0.63]
REF_SCALES = [0.33, 0.25, 0.2]


def graded(scale: float) -> list[str]:
    return [f"mesh.size={0.3 * scale:.6g}", f"mesh.fracture_size={0.08 * scale:.6g}",
            f"mesh.tip_size={0.015 * scale:.6g}"]


def uniform(h: float) -> list[str]:
    return [f"mesh.size={h}", f"mesh.fracture_size={h}", "mesh.tip_size=1e9"]


def run(case: Path, overrides: list[str], workdir: Path, tag: str) -> dict:
    """One ``polypore run`` in its own process; its summary.json plus the per-face table."""
    out = workdir / tag
    cmd = [str(POLYPORE), "-q", "run", str(case), "--out", str(out), "--force", "--set", "solver.linear=pardiso"]
    for o in overrides:
        cmd += ["--set", o]
    subprocess.run(cmd, check=True)
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "fractures.csv") as f:
        rows = list(csv.DictReader(f))
    col = lambda k: np.array([float(r[k]) for r in rows])  # noqa: E731
    X = np.column_stack([col("x"), col("y"), col("z")])
    q = np.column_stack([col("jump_x"), col("jump_y"), col("jump_z")])
    n = np.array([0.0, 1.0, -1.0]) / np.sqrt(2.0)
    slip = q - (q @ n)[:, None] * n
    return {"summary": summary, "X": X, "slip": slip, "lambda_n": col("lambda_n"), "area": col("area")}


def _case_without_reference(tmp: Path) -> Path:
    data = tomllib.loads(CASE.read_text())
    data.pop("exact", None)
    path = tmp / "cube-slip-3d-noref.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def make_reference(workdir: Path):
    """Three √r-graded levels; the maximum slip and the resampled slip and λ_n fields
    extrapolated to h → 0 (Richardson, rate fitted on the maximum slips of the three levels)."""
    from polypore.cases.reference import resample

    case = _case_without_reference(workdir)
    levels = []
    for sc in REF_SCALES:
        r = run(case, graded(sc) + ["mesh.grading=0.3"], workdir, f"ref-{sc}")
        m = float(np.linalg.norm(r["slip"], axis=1).max())
        s = r["summary"]
        print(f"reference level scale {sc}: {s['mesh']['unknowns']} unknowns, max slip {m:.5e} m, "
              f"{s['totals']['seconds']:.0f} s, {s['totals']['peak_memory_mb']:.0f} MB", flush=True)
        levels.append((sc, m, r))
    (s0, m0, _), (s1, m1, r1), (s2, m2, r2) = levels
    # m(s) = m* − C s^p: the rate p from (m1 − m0)/(m2 − m1) = (s0^p − s1^p)/(s1^p − s2^p) by bisection
    ratio = (m1 - m0) / (m2 - m1)
    f = lambda p: (s0 ** p - s1 ** p) / (s1 ** p - s2 ** p) - ratio  # noqa: E731
    lo, hi = 0.2, 4.0
    if f(lo) * f(hi) >= 0:
        raise SystemExit(f"the three maximum slips {m0:.5e}, {m1:.5e}, {m2:.5e} do not converge monotonically "
                         "with a rate in [0.2, 4]; refine the reference levels")
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    p = 0.5 * (lo + hi)
    w = s2 ** p / (s1 ** p - s2 ** p)           # Richardson weight: X* = X2 + w (X2 − X1)
    m_star = m2 + w * (m2 - m1)
    a1 = resample(r1["X"], r1["slip"], r1["lambda_n"], ORIGIN, E1, E2, LENGTHS)
    a2 = resample(r2["X"], r2["slip"], r2["lambda_n"], ORIGIN, E1, E2, LENGTHS)
    arrays = {**a2, "slip": a2["slip"] + w * (a2["slip"] - a1["slip"]),
              "lambda_n": a2["lambda_n"] + w * (a2["lambda_n"] - a1["lambda_n"])}
    note = (f"√r-graded tetrahedra, sizes (0.3, 0.08, 0.015) m × {REF_SCALES}, grading 0.3 "
            f"({', '.join(str(lv[2]['summary']['mesh']['unknowns']) for lv in levels)} unknowns); maximum slips "
            f"{m0:.5e}, {m1:.5e}, {m2:.5e} m, fitted rate {p:.2f}, extrapolated {m_star:.5e} m; slip and λ_n "
            "fields extrapolated the same way from the two finest levels")
    print(note)
    np.savez_compressed(REF, **{k: v.astype(np.float64) for k, v in arrays.items()}, max_slip=m_star, note=note)
    print(f"wrote {REF}")


def study(workdir: Path, out: Path, quick: bool):
    series = {"uniform": [(h, uniform(h)) for h in (UNIFORM[:3] if quick else UNIFORM)],
              "tip-graded (default)": [(sc, graded(sc)) for sc in (GRADED[:3] if quick else GRADED)]}
    keys = ("max_slip_error_rel", "slip_L2_rel", "slip_L2_rel_inner", "lambda_n_L2_rel_inner")
    results = {}
    for name, levels in series.items():
        rows = []
        for par, ov in levels:
            s = run(CASE, ov, workdir, f"{name.split()[0]}-{par}")["summary"]
            rec = {"parameter": par, "unknowns": s["mesh"]["unknowns"], "cells": s["mesh"]["cells"],
                   "seconds": s["totals"]["seconds"], "peak_memory_mb": s["totals"]["peak_memory_mb"],
                   "newton": s["steps"][0]["newton_iterations"], **s["errors"]}
            rows.append(rec)
            print(f"{name:22s} {par:<6g} {rec['unknowns']:7d} unknowns  max slip {rec['max_slip']:.4e} "
                  + " ".join(f"{k} {100 * rec[k]:.2f}%" for k in keys)
                  + f"  open {rec['open_faces']}  {rec['seconds']:.1f} s {rec['peak_memory_mb']:.0f} MB", flush=True)
        n = np.array([r["unknowns"] for r in rows], float)
        rates = {k: float(-np.polyfit(np.log(n), np.log([r[k] for r in rows]), 1)[0]) for k in keys}
        results[name] = {"runs": rows, "rates_per_unknown": rates}
    from polypore.cases.reference import load_reference

    ref = load_reference("cube-slip-3d")
    (out / "cube_slip.json").write_text(json.dumps({"reference": {"max_slip": ref.max_slip, "note": ref.note},
                                                    "series": results}, indent=1))
    _table(out / "cube_slip.md", results, ref)
    _plot(out / "cube_slip.png", results)
    print(f"wrote {out / 'cube_slip.json'}, {out / 'cube_slip.md'}, {out / 'cube_slip.png'}")


# What moves the error and what does not (one mesh family each, everything else fixed)
DIAGNOSIS = {
    "uniform h = 0.1": uniform(0.1),
    "  stabilisation × 0.1": uniform(0.1) + ["mechanics.stabilisation=0.1"],
    "  stabilisation × 3": uniform(0.1) + ["mechanics.stabilisation=3"],
    "  two-sided bubbles": uniform(0.1) + ["mechanics.bubbles=two-sided"],
    "  β × 10": uniform(0.1) + ["contact.beta=10"],
    "size 0.2, fracture_size 0.05, no tip refinement": ["mesh.size=0.2", "mesh.fracture_size=0.05",
                                                        "mesh.tip_size=1e9"],
    "  tip_size 0.01 (√r-graded fronts)": ["mesh.size=0.2", "mesh.fracture_size=0.05", "mesh.tip_size=0.01"],
    "  fracture_size 0.035 instead": ["mesh.size=0.2", "mesh.fracture_size=0.035", "mesh.tip_size=1e9"],
}


def diagnose(workdir: Path, out: Path):
    rows = []
    for name, ov in DIAGNOSIS.items():
        s = run(CASE, ov, workdir, f"diag-{len(rows)}")["summary"]
        rec = {"variant": name, "unknowns": s["mesh"]["unknowns"], **s["errors"]}
        rows.append(rec)
        print(f"{name:50s} {rec['unknowns']:7d} unknowns  max slip {rec['max_slip']:.4e}  slip L2 rim out "
              f"{100 * rec['slip_L2_rel_inner']:.1f} %  λ_n {100 * rec['lambda_n_L2_rel_inner']:.1f} %", flush=True)
    (out / "cube_slip_diagnosis.json").write_text(json.dumps(rows, indent=1))
    lines = ["Command: `.venv/bin/python benchmarks/cube_slip.py --diagnose`.", "",
             "| variant | unknowns | max slip (1e-5 m) | max-slip error | slip L2, rim out | λ_n L2, rim out | open |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['variant'].strip()} | {r['unknowns']:,} | {1e5 * r['max_slip']:.3f} | "
              f"{100 * r['max_slip_error_rel']:.1f} % | {100 * r['slip_L2_rel_inner']:.1f} % | "
              f"{100 * r['lambda_n_L2_rel_inner']:.1f} % | {r['open_faces']} |" for r in rows]
    (out / "cube_slip_diagnosis.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'cube_slip_diagnosis.md'}")


def _table(path, results, ref):
    lines = ["Command: `.venv/bin/python benchmarks/cube_slip.py` (figures in `docs/cube_slip.json`).", "",
             f"Reference: {ref.note}.", "",
             "| mesh | parameter | unknowns | max slip (1e-5 m) | max-slip error | slip L2 | slip L2, rim out | "
             "λ_n L2, rim out | open faces | wall | peak memory |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, res in results.items():
        for r in res["runs"]:
            lines.append(f"| {name} | {r['parameter']:g} | {r['unknowns']:,} | {1e5 * r['max_slip']:.3f} | "
                         f"{100 * r['max_slip_error_rel']:.1f} % | {100 * r['slip_L2_rel']:.1f} % | "
                         f"{100 * r['slip_L2_rel_inner']:.1f} % | {100 * r['lambda_n_L2_rel_inner']:.1f} % | "
                         f"{r['open_faces']} | {r['seconds']:.1f} s | {r['peak_memory_mb']:.0f} MB |")
        rt = res["rates_per_unknown"]
        lines.append(f"| {name}: rate per unknown | | | | {rt['max_slip_error_rel']:.2f} | {rt['slip_L2_rel']:.2f} | "
                     f"{rt['slip_L2_rel_inner']:.2f} | {rt['lambda_n_L2_rel_inner']:.2f} | | | |")
    lines.append("")
    lines.append("Parameter: h (m) for the uniform meshes; the scale of (size, fracture_size, tip_size) = "
                 "(0.3, 0.08, 0.015) m for the graded ones. Rates are −d log(error)/d log(unknowns).")
    path.write_text("\n".join(lines) + "\n")


def _plot(path, results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for (name, res), mk in zip(results.items(), ("s--", "o-")):
        n = [r["unknowns"] for r in res["runs"]]
        axes[0].loglog(n, [100 * r["max_slip_error_rel"] for r in res["runs"]], mk, label=name)
        axes[1].loglog(n, [100 * r["slip_L2_rel_inner"] for r in res["runs"]], mk, label=name)
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for ax, title in zip(axes, ("maximum slip", "slip profile, rim left out (relative L2)")):
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(plain)
        ax.axhline(3.0, color="0.5", lw=0.8, ls=":")
        ax.axvline(2e4, color="0.5", lw=0.8, ls=":")
        ax.set_xlabel("unknowns")
        ax.set_ylabel("error (%)")
        ax.set_title(title)
        ax.grid(alpha=0.3, which="both")
        ax.legend()
    fig.suptitle("cube-slip-3d: error against unknowns (dotted: 3 % at 20,000 unknowns)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", action="store_true", help="remake the fine-mesh reference file")
    ap.add_argument("--quick", action="store_true", help="three coarsest levels of each series only")
    ap.add_argument("--diagnose", action="store_true", help="what changes the error: stabilisation, bubbles, "
                    "β, tip grading, fracture size")
    ap.add_argument("--out", default=str(ROOT / "docs"))
    ap.add_argument("--workdir", help="keep the runs here (default: a temporary folder)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="cube-slip-") as tmp:
        work = Path(args.workdir or tmp)
        work.mkdir(parents=True, exist_ok=True)
        if args.reference:
            make_reference(work)
        elif args.diagnose:
            diagnose(work, out)
        else:
            study(work, out, args.quick)


if __name__ == "__main__":
    main()
