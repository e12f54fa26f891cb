"""3D slip accuracy per unknown on the cube case (issue 13): uniform against tip-graded tetrahedra.

    .venv/bin/python benchmarks/cube_slip.py                 # the study (~3 min)
    .venv/bin/python benchmarks/cube_slip.py --diagnose      # what moves the error (~2 min)
    .venv/bin/python benchmarks/cube_slip.py --reference     # remake the fine-mesh reference (~25 min, 4 GB)
    .venv/bin/python benchmarks/cube_slip.py --order 2       # quadratic displacements (~15 min)

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

``--order 2`` runs the quadratic space (``MechanicsData.order = 2``, docs/accuracy_3d.md) on its
own mesh series (``UNIFORM_P2``, ``GRADED_P2``) and the case's default mesh with order 1 for
comparison. The case file has no key for the order, so each of these runs builds the case
through the setup API in a separate process of this script (``--one``): wall time (mesh, set-up,
solve; no output files) and peak memory are again the run's own. The maximum slip of the graded
P2 series is extrapolated like the reference's, to compare the limits.

Writes ``<out>/cube_slip.json``, ``<out>/cube_slip.md`` and ``<out>/cube_slip.png`` (``--order 2``:
``<out>/cube_slip_p2.{json,md,png}``).
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

# order 2: "uniform" meshes refined on the fracture only (fracture_size = h, bulk size 0.5, no tip
# grading), and tip-graded meshes with a coarser fracture_size than P1's (the graded zone, of
# radius 4 fracture_size, then covers the cube: h = √(fracture_size/4) √r down to tip_size), the
# best of a sweep at ~20k unknowns (docs/accuracy_3d.md)
UNIFORM_P2 = [0.15, 0.1, 0.07, 0.05, 0.035]
GRADED_P2 = [1.6, 1.25, 1.0, 0.8, 0.63, 0.5]
P2_SIZES = (0.5, 0.3, 0.025)       # (size, fracture_size, tip_size) at scale 1, m


def graded_p2(scale: float) -> list[str]:
    return [f"mesh.size={P2_SIZES[0]:.6g}", f"mesh.fracture_size={P2_SIZES[1] * scale:.6g}",
            f"mesh.tip_size={P2_SIZES[2] * scale:.6g}"]


def uniform_p2(h: float) -> list[str]:
    return [f"mesh.size={P2_SIZES[0]:.6g}", f"mesh.fracture_size={h}", "mesh.tip_size=1e9"]


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
    area = col("area")
    # |∫_Γ [[u]]_τ| (m³): exact from the face means, a smooth functional of the solution
    summary["slip_integral"] = float(np.linalg.norm(area @ slip))
    return {"summary": summary, "X": X, "slip": slip, "lambda_n": col("lambda_n"), "area": area}


def run_one(order: int, overrides: list[str], workdir: Path, tag: str) -> dict:
    """One in-process run of the case at the given order, in its own process (``--one``)."""
    out = workdir / f"{tag}.json"
    cmd = [sys.executable, str(Path(__file__).resolve()), "--one", str(out), "--order", str(order)]
    for o in overrides + ["solver.linear=pardiso"]:
        cmd += ["--set", o]
    subprocess.run(cmd, check=True)
    return json.loads(out.read_text())


def one(path: Path, order: int, overrides: list[str], case_name: str = str(CASE)) -> None:
    """Mesh, set up and solve a static case (default: the cube) with ``MechanicsData.order = order``;
    write a summary.json-like record (unknowns, cells, seconds, peak_memory_mb, newton, errors)
    to ``path``."""
    import dataclasses
    import resource
    import time

    try:
        from polypore.setup.casefile import load_case
        from polypore.setup.meshing import build_fractured_mesh
        from polypore.setup.mechanics import mechanics_setup
    except ImportError:                       # the layout before the cases/setup/runs split
        from polypore.cases.casefile import load_case
        from polypore.cases.meshing import build_fractured_mesh
        from polypore.cases.mechanics_setup import mechanics_setup
    from polypore.models.contact import OPEN
    from polypore.models.mechanics import ContactMechanics

    t0 = time.perf_counter()
    case = load_case(case_name, overrides)
    fm = build_fractured_mesh(case)
    setup = mechanics_setup(case, fm)
    problem = ContactMechanics(fm, dataclasses.replace(setup.data, order=order), setup.solver, setup.newton)
    st = problem.solve(verbose=False)
    errors = setup.exact.errors(problem, st)
    seconds = time.perf_counter() - t0
    q = problem.jumps(st)
    qt = q - np.einsum("fi,fi->f", q, problem.normal)[:, None] * problem.normal
    rec = {"mesh": {"unknowns": int(problem.free.size + problem.n_ff * problem.dim), "cells": fm.mesh.n_cells,
                    "fracture_faces": problem.n_ff},
           "totals": {"seconds": seconds,
                      "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0},
           "steps": [{"newton_iterations": st.newton_iterations}], "errors": errors, "order": order,
           "slip_integral": float(np.linalg.norm(problem.face_area @ qt))}
    if order == 2 and hasattr(setup.exact, "errors_of"):
        # the P2 slip as a field: its values at the points of a face rule (6 per face) against the
        # reference there, weighted by the rule (the face-mean errors above compare P0 face means
        # with point values, which costs O(h²) by itself on coarse fracture meshes)
        X, W, Jq = problem.space.jump_quadrature()
        nq = W.size // max(problem.n_ff, 1)
        n = np.repeat(problem.normal, nq, axis=0)
        q = Jq @ st.u
        qt = q - np.einsum("fi,fi->f", q, n)[:, None] * n
        ln = np.repeat(np.einsum("fi,fi->f", st.lam, problem.normal), nq)
        rec["field_errors"] = setup.exact.errors_of(X, W, qt, ln, np.repeat(st.state == OPEN, nq))
    path.write_text(json.dumps(rec))


def richardson(s, m):
    """Extrapolate m(s) = m* − C s^p from three levels s0 > s1 > s2: (m*, p, w) with the Richardson
    weight w (X* = X2 + w (X2 − X1)); None if the values do not converge monotonically with a rate
    p in [0.2, 4]."""
    (s0, s1, s2), (m0, m1, m2) = s, m
    ratio = (m1 - m0) / (m2 - m1)
    f = lambda p: (s0 ** p - s1 ** p) / (s1 ** p - s2 ** p) - ratio  # noqa: E731
    lo, hi = 0.2, 4.0
    if f(lo) * f(hi) >= 0:
        return None
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    p = 0.5 * (lo + hi)
    w = s2 ** p / (s1 ** p - s2 ** p)
    return m2 + w * (m2 - m1), p, w


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
    fit = richardson((s0, s1, s2), (m0, m1, m2))
    if fit is None:
        raise SystemExit(f"the three maximum slips {m0:.5e}, {m1:.5e}, {m2:.5e} do not converge monotonically "
                         "with a rate in [0.2, 4]; refine the reference levels")
    m_star, p, w = fit                          # Richardson weight: X* = X2 + w (X2 − X1)
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


def study(workdir: Path, out: Path, quick: bool, order: int = 1):
    if order == 1:
        series = {"uniform": [(h, uniform(h)) for h in (UNIFORM[:3] if quick else UNIFORM)],
                  "tip-graded (default)": [(sc, graded(sc)) for sc in (GRADED[:3] if quick else GRADED)]}
        runner = lambda ov, tag: run(CASE, ov, workdir, tag)["summary"]  # noqa: E731
        stem = "cube_slip"
    else:
        series = {"order 1, tip-graded": [(sc, graded(sc)) for sc in GRADED[2:]],
                  "order 2, fracture-refined": [(h, uniform_p2(h)) for h in (UNIFORM_P2[:3] if quick else UNIFORM_P2)],
                  "order 2, tip-graded": [(sc, graded_p2(sc)) for sc in (GRADED_P2[:3] if quick else GRADED_P2)]}
        stem = "cube_slip_p2"
    keys = ("max_slip_error_rel", "slip_L2_rel", "slip_L2_rel_inner", "lambda_n_L2_rel_inner")
    results = {}
    for name, levels in series.items():
        rows = []
        if order == 2:
            k = 1 if name.startswith("order 1") else 2
            runner = lambda ov, tag, k=k: run_one(k, ov, workdir, tag)  # noqa: E731
        for par, ov in levels:
            s = runner(ov, "".join(c if c.isalnum() else "-" for c in name) + f"-{par}")
            rec = {"parameter": par, "unknowns": s["mesh"]["unknowns"], "cells": s["mesh"]["cells"],
                   "seconds": s["totals"]["seconds"], "peak_memory_mb": s["totals"]["peak_memory_mb"],
                   "newton": s["steps"][0]["newton_iterations"], **s["errors"],
                   "slip_integral": s.get("slip_integral"),
                   **{f"field_{k}": v for k, v in s.get("field_errors", {}).items()}}
            rows.append(rec)
            print(f"{name:22s} {par:<6g} {rec['unknowns']:7d} unknowns  max slip {rec['max_slip']:.4e} "
                  + " ".join(f"{k} {100 * rec[k]:.2f}%" for k in keys)
                  + ("  field: " + " ".join(f"{k} {100 * rec['field_' + k]:.2f}%" for k in keys[:3])
                     if "field_max_slip" in rec else "")
                  + f"  open {rec['open_faces']}  {rec['seconds']:.1f} s {rec['peak_memory_mb']:.0f} MB", flush=True)
        n = np.array([r["unknowns"] for r in rows], float)
        rates = ({k: float(-np.polyfit(np.log(n), np.log([r[k] for r in rows]), 1)[0]) for k in keys}
                 if len(rows) > 1 else {})
        results[name] = {"runs": rows, "rates_per_unknown": rates}
    from polypore.cases.reference import load_reference

    ref = load_reference("cube-slip-3d")
    # |∫_Γ [[u]]_τ| of the reference (trapezoid rule on its grid) and of each series extrapolated
    # from its three finest levels: the limits compared without sampling the slip at points
    ref_int = float(np.linalg.norm(np.trapezoid(np.trapezoid(ref.slip, ref.b, axis=1), ref.a, axis=0)))
    extra = {"slip_integral": {"reference": ref_int}}
    for name, res in results.items():
        runs = res["runs"][-3:]
        fit = richardson([r["parameter"] for r in runs], [r["slip_integral"] for r in runs]) if len(runs) == 3 else None
        extra["slip_integral"][name] = ({"finest": runs[-1]["slip_integral"], "limit": fit[0], "rate": fit[1],
                                         "vs_reference_rel": fit[0] / ref_int - 1} if fit else None)
    print("slip integrals:", extra["slip_integral"])
    if order == 2:
        # the limit of the P2 maximum slip (its point values, which converge monotonically; the
        # face means are not monotone on these meshes) from each series' three finest levels
        extra["p2_limit"] = {}
        for name in ("order 2, fracture-refined", "order 2, tip-graded"):
            runs = results[name]["runs"][-3:]
            fit = (richardson([r["parameter"] for r in runs], [r["field_max_slip"] for r in runs])
                   if len(runs) == 3 else None)
            extra["p2_limit"][name] = ({"max_slip": fit[0], "rate": fit[1],
                                        "vs_reference_rel": (fit[0] - ref.max_slip) / ref.max_slip} if fit else None)
        print("P2 maximum-slip limits:", extra["p2_limit"])
    (out / f"{stem}.json").write_text(json.dumps({"reference": {"max_slip": ref.max_slip, "note": ref.note},
                                                  "series": results, **extra}, indent=1))
    _table(out / f"{stem}.md", results, ref, order, extra.get("p2_limit"), extra["slip_integral"])
    _plot(out / f"{stem}.png", results)
    print(f"wrote {out / stem}.json, .md, .png")


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


def _table(path, results, ref, order=1, limit=None, integrals=None):
    cmd, fig = (("", "cube_slip") if order == 1 else (" --order 2", "cube_slip_p2"))
    fkeys = ("max_slip_error_rel", "slip_L2_rel", "slip_L2_rel_inner")
    head = ("| mesh | parameter | unknowns | max slip (1e-5 m) | max-slip error | slip L2 | slip L2, rim out | "
            "λ_n L2, rim out | open faces | wall | peak memory |")
    if order == 2:
        head += " field: max-slip error | field: slip L2 | field: slip L2, rim out |"
    lines = [f"Command: `.venv/bin/python benchmarks/cube_slip.py{cmd}` (figures in `docs/{fig}.json`).", "",
             f"Reference: {ref.note}.", "", head, "|---" * (head.count("|") - 1) + "|"]
    pct = lambda v: "–" if v is None else f"{100 * v:.1f} %"  # noqa: E731
    for name, res in results.items():
        for r in res["runs"]:
            row = (f"| {name} | {r['parameter']:g} | {r['unknowns']:,} | {1e5 * r['max_slip']:.3f} | "
                   f"{100 * r['max_slip_error_rel']:.1f} % | {100 * r['slip_L2_rel']:.1f} % | "
                   f"{100 * r['slip_L2_rel_inner']:.1f} % | {100 * r['lambda_n_L2_rel_inner']:.1f} % | "
                   f"{r['open_faces']} | {r['seconds']:.1f} s | {r['peak_memory_mb']:.0f} MB |")
            if order == 2:
                row += "".join(f" {pct(r.get('field_' + k))} |" for k in fkeys)
            lines.append(row)
        rt = res["rates_per_unknown"]
        if rt:
            lines.append(f"| {name}: rate per unknown | | | | {rt['max_slip_error_rel']:.2f} | "
                         f"{rt['slip_L2_rel']:.2f} | {rt['slip_L2_rel_inner']:.2f} | "
                         f"{rt['lambda_n_L2_rel_inner']:.2f} | | | |"
                         + (" | | |" if order == 2 else ""))
    lines.append("")
    if order == 1:
        lines.append("Parameter: h (m) for the uniform meshes; the scale of (size, fracture_size, tip_size) = "
                     "(0.3, 0.08, 0.015) m for the graded ones. Rates are −d log(error)/d log(unknowns).")
    else:
        lines.append("Parameter: the scale of (size, fracture_size, tip_size) = (0.3, 0.08, 0.015) m for order 1 (the "
                     "case's family, as in docs/cube_slip.md); "
                     f"fracture_size h (m, bulk size {P2_SIZES[0]} m, no tip grading) for the fracture-refined "
                     "P2 meshes; "
                     f"the scale of (fracture_size, tip_size) = {P2_SIZES[1:]} m (bulk size {P2_SIZES[0]} m) for the "
                     "tip-graded ones. Rates are −d log(error)/d log(unknowns). Wall: mesh, set-up and solve. "
                     "\"field\": the P2 slip at the 6 points of a face rule per fracture face (its maximum, and "
                     "L2 norms by that rule) instead of the face means.")
    integrals = integrals or {}
    if len(integrals) > 1:
        lines += ["", "Slip integrals and maxima extrapolated with the rate fitted on three levels; a fitted rate "
                  "below 1 means the levels are not asymptotic yet (docs/accuracy_3d.md discusses the limits)."]
    for name, lim in integrals.items():
        if name != "reference" and lim:
            lines += ["", f"{name}: |∫_Γ [[u]]_τ| = {1e6 * lim['finest']:.4f}e-6 m³ on the finest mesh, "
                      f"extrapolated {1e6 * lim['limit']:.4f}e-6 m³ (fitted rate {lim['rate']:.2f}), "
                      f"{100 * lim['vs_reference_rel']:+.2f} % from the reference's "
                      f"{1e6 * integrals['reference']:.4f}e-6 m³."]
    if order == 2:
        for name, lim in (limit or {}).items():
            lines += ["", f"{name}: maximum slip (point values) extrapolated to h → 0 from the three finest levels: "
                      + (f"{1e5 * lim['max_slip']:.4f}e-5 m (fitted rate {lim['rate']:.2f} in the mesh parameter), "
                         f"{100 * lim['vs_reference_rel']:+.2f} % from the reference's {1e5 * ref.max_slip:.4f}e-5 m."
                         if lim else "not monotone, no extrapolation.")]
    path.write_text("\n".join(lines) + "\n")


def _plot(path, results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for (name, res), mk, c in zip(results.items(), ("s--", "o-", "^-"), ("C0", "C1", "C2")):
        n = [r["unknowns"] for r in res["runs"]]
        axes[0].loglog(n, [100 * r["max_slip_error_rel"] for r in res["runs"]], mk, color=c, label=name)
        axes[1].loglog(n, [100 * r["slip_L2_rel_inner"] for r in res["runs"]], mk, color=c, label=name)
        if "field_max_slip_error_rel" in res["runs"][0]:     # order 2: the slip as a field, dotted
            axes[0].loglog(n, [100 * r["field_max_slip_error_rel"] for r in res["runs"]], mk[0] + ":", color=c,
                           mfc="none", label=f"{name} (field)")
            axes[1].loglog(n, [100 * r["field_slip_L2_rel_inner"] for r in res["runs"]], mk[0] + ":", color=c,
                           mfc="none", label=f"{name} (field)")
    from matplotlib.ticker import FuncFormatter, NullFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for ax, title in zip(axes, ("maximum slip", "slip profile, rim left out (relative L2)")):
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(plain if len(results) < 3 else NullFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.axhline(3.0, color="0.5", lw=0.8, ls=":")
        ax.axvline(2e4, color="0.5", lw=0.8, ls=":")
        ax.set_xlabel("unknowns")
        ax.set_ylabel("error (%)")
        ax.set_title(title)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize="small")
    fig.suptitle("cube-slip-3d: error against unknowns (dotted: 3 % at 20,000 unknowns)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", action="store_true", help="remake the fine-mesh reference file")
    ap.add_argument("--quick", action="store_true", help="three coarsest levels of each series only")
    ap.add_argument("--diagnose", action="store_true", help="what changes the error: stabilisation, bubbles, "
                    "β, tip grading, fracture size")
    ap.add_argument("--order", type=int, choices=(1, 2), default=1,
                    help="displacement order: 2 = quadratic on tetrahedra (its own mesh series)")
    ap.add_argument("--one", metavar="JSON", help="internal: one in-process run of the case, record to JSON")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="with --one: case overrides")
    ap.add_argument("--case", default=str(CASE), help="with --one: another built-in static case (e.g. penny-inclined)")
    ap.add_argument("--out", default=str(ROOT / "docs"))
    ap.add_argument("--workdir", help="keep the runs here (default: a temporary folder)")
    args = ap.parse_args()
    if args.one:
        one(Path(args.one), args.order, args.set, args.case)
        return
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
            study(work, out, args.quick, args.order)


if __name__ == "__main__":
    main()
