"""Benchmark: fault reactivation by injection on a corner-point grid, end to end (issue 15).

    .venv/bin/python benchmarks/cornerpoint_reactivation.py [--cells 60 50 10] [--out DIR] [--json out.json]
    .venv/bin/python benchmarks/cornerpoint_reactivation.py --cells 60 50 10 --tilt 60 --pinchout 2 9 \\
        --f1-x 1400 --f2-contact [--out DIR]          # tilted pillars, pinch-outs, crossing contact faults
    .venv/bin/python benchmarks/cornerpoint_reactivation.py --case emerald-injection [--out DIR]
    .venv/bin/python benchmarks/cornerpoint_reactivation.py --plots-only DIR     # a finished run's folder

Default: the built-in case ``cornerpoint-injection`` on a finer generated grid (``--cells nx ny nz``,
default 60 × 50 × 10 = 30,000 cells over the same 2000 m × 1000 m × 160 m stack, the faults and
the well moved to the same map positions), run by ``polypore run`` (the same code path: VTU/PVD
with slip per fault, fractures.csv, summary.json). ``--case NAME`` runs a built-in case or case
file as it is (e.g. ``emerald-injection``). Printed: wall time of the run, the process's peak
resident memory, unknowns, Newton iterations per step, and per fault the slip onset (the first
output time at which one of its faces is in the slip state), its slipping area and maximum slip
at the end. Plots written into the run folder:

- ``reactivation.png``: overpressure at the monitor points and the largest fracture pressure on
  each fault against time; the largest slip since the start on each fault, with each fault's
  onset marked (the first output time at which 1% of its area slips: a single sliver face of a
  real grid's fault can slip long before the fault does, docs/cornerpoint.md); the fraction of
  each fault's area that slips.
- ``slip_onset_map.png``: each fault's faces seen face-on (horizontal position along the fault
  against depth), coloured by their slip onset time (grey: never slipped) and by their final slip.

Linear solver: ``--linear`` (default ``auto``: on the 30,000-cell grid ``block-direct`` with
PARDISO installed, 60 s against PARDISO's 201 s, and ``block-amg`` without;
docs/iterative_cornerpoint.md).
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np

from polypore.cli import main as polypore
from polypore.io.plots import _plt, save
from polypore.runs.common import peak_memory_mb

DAY = 86400.0


def generated_overrides(nx: int, ny: int, nz: int, *, tilt: float = 0.0, pinchout=(), f1_x: float = 1000.0,
                        f2_contact: bool = False) -> list[str]:
    """--set overrides of cornerpoint-injection for an nx × ny × nz grid (same extent, faults and well
    at the same map positions: F1 at x = 1000 m, F2 at y = 500 m ending at x = 1200 m, the well at
    (650 m, 450 m) perforated over layers 3–6 of 8, i.e. the depths 40–120 m below the top).

    ``tilt``: mesh.pillar_angle (degrees from vertical of the outermost pillars); ``pinchout``:
    mesh.pinchout (layers of the nz); ``f1_x``: F1's map x at the top (F2 then ends 200 m past it,
    the well stays 350 m west of it); ``f2_contact``: F2 a contact surface too. With either of
    the last two, [[fractures]] is rewritten with each fault's friction 1.05 × its in-situ
    |τ|/σ_n' (:func:`insitu_ratio`; 0.42 → 0.44 on the vertical F1 as in the case)."""
    i_f1 = round(nx * f1_x / 2000.0)
    j_f2 = round(ny * 5 / 10)
    stop = round(nx * (f1_x + 200.0) / 2000.0)
    col = [int((f1_x - 350.0) / (2000.0 / nx)) + 1, int(450.0 / (1000.0 / ny)) + 1]
    layers = [int(40.0 / (160.0 / nz)) + 1, int(np.ceil(120.0 / (160.0 / nz)))]
    out = [f"mesh.cells=[{nx}, {ny}, {nz}]", f"mesh.faults.F1.index={i_f1}", f"mesh.faults.F2.index={j_f2}",
           f"mesh.faults.F2.stop={stop}", f"flow.wells.I1.column={col}", f"flow.wells.I1.layers={layers}"]
    if tilt:
        out.append(f"mesh.pillar_angle={float(tilt)}")
    if pinchout:
        out.append(f"mesh.pinchout={[int(k) for k in pinchout]}")
    if f2_contact or f1_x != 1000.0 or tilt:
        # F1's pillars lean by atan(tan(tilt)·(x − Lx/2)/(Lx/2)) towards +x: the fault's normal
        th = np.arctan(np.tan(np.radians(tilt)) * (2000.0 / nx * i_f1 - 1000.0) / 1000.0)
        fr = [f'{{name = "F1", friction = {1.05 * insitu_ratio([np.cos(th), 0.0, np.sin(th)]):.3f}}}']
        if f2_contact:
            fr.append(f'{{name = "F2", friction = {1.05 * insitu_ratio([0.0, 1.0, 0.0]):.3f}}}')
        out.append("fractures=[" + ", ".join(fr) + "]")
        # monitor points: the well and 50 m west of F1 at 1600 m depth (at the pillars' x there)
        out.append(f"monitor.points={{well = [{f1_x - 1350.0}, 450.0, -1600.0], "
                   f"fault = [{f1_x - 1050.0}, 450.0, -1600.0]}}")
    return out


def insitu_ratio(normal, k=0.6, k_max=1.2, azimuth=30.0, rho_r=2300.0, rho_w=1000.0) -> float:
    """|τ|/σ_n' of cornerpoint-injection's in-situ state on a plane of this normal (x, y, z up): σ_v,
    k σ_v, k_max σ_v along ``azimuth`` from +x, hydrostatic pressure (the ratio is the same at
    every depth)."""
    a = np.radians(azimuth)
    h = np.array([np.cos(a), np.sin(a), 0.0])
    s = np.diag([k, k, 1.0]) + (k_max - k) * np.outer(h, h) - rho_w / rho_r * np.eye(3)   # compression > 0, / σ_v
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t = s @ n
    sn = float(n @ t)
    return float(np.linalg.norm(t - sn * n) / sn)


def grid_angles(case: str, sets: list[str]) -> dict:
    """Pillar angles from vertical (degrees) of the case's grid (generated, not processed)."""
    from polypore.mesh.cornerpoint import pillar_angles
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import _cornerpoint_grid

    spec = load_case(case, sets).spec
    if spec.mesh.generator != "cornerpoint":
        return {}
    a = pillar_angles(_cornerpoint_grid(spec))
    i_f1 = next(int(f.index) for f in spec.mesh.faults if f.name == "F1")
    return {"median_deg": float(np.median(a)), "max_deg": float(a.max()),
            "outer_deg": float(max(a[0].max(), a[-1].max())), "F1_deg": float(a[i_f1].max())}


def read_faces(folder: Path) -> dict:
    """fractures.csv -> per output step: time, and per face fracture, state, slip, position."""
    rows = list(csv.DictReader(open(folder / "fractures.csv")))
    steps = sorted({int(r["step"]) for r in rows})
    by = {s: [r for r in rows if int(r["step"]) == s] for s in steps}
    first = by[steps[0]]
    out = {"steps": steps, "time": np.array([float(by[s][0]["time"]) for s in steps]),
           "fracture": np.array([r["fracture"] for r in first]),
           "x": np.array([[float(r[k]) for k in "xyz"] for r in first]),
           "area": np.array([float(r["area"]) for r in first]),
           "state": np.array([[r["state"] for r in by[s]] for s in steps]),
           "jump_t": np.array([[float(r["jump_t"]) for r in by[s]] for s in steps])}
    # slip since the start: tangential jump minus its initial value
    out["slip"] = np.abs(out["jump_t"] - out["jump_t"][0])
    return out


AREA_ONSET = 0.01     # onset by area: the first output time at which 1% of the fault's area slips


def onset_per_fault(faces: dict) -> dict:
    """Fault -> {onset (s) or None: first output time with a slipping face; onset by area (s) or
    None: first output time with AREA_ONSET of the fault's area slipping; slipping area fraction
    at the end, max slip at the end (m)}."""
    res = {}
    slipping = faces["state"] == "slip"                          # (n_out, n_ff)
    for name in dict.fromkeys(faces["fracture"]):
        sel = faces["fracture"] == name
        A = faces["area"][sel]
        any_slip = slipping[:, sel].any(axis=1)
        k = int(np.argmax(any_slip)) if any_slip.any() else None
        by_area = (slipping[:, sel] * A).sum(axis=1) >= AREA_ONSET * A.sum()
        ka = int(np.argmax(by_area)) if by_area.any() else None
        res[name] = {"onset_s": None if k is None else float(faces["time"][k]),
                     "onset_area_s": None if ka is None else float(faces["time"][ka]),
                     "slip_area_fraction": float(A[slipping[-1, sel]].sum() / A.sum()),
                     "max_slip_m": float(faces["slip"][-1, sel].max()), "faces": int(sel.sum())}
    return res


def plots(folder: Path) -> dict:
    """Write reactivation.png and slip_onset_map.png into a run folder; return the onsets."""
    plt = _plt()
    summary = json.loads((folder / "summary.json").read_text())
    faces = read_faces(folder)
    onsets = onset_per_fault(faces)
    mon = summary["monitor"]
    t = np.asarray(mon["time"]) / DAY
    names = list(onsets)
    colours = {n: f"C{i}" for i, n in enumerate(names)}
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 4.6), layout="constrained")
    for i, (k, p) in enumerate(mon["overpressure_at_points"].items()):
        a1.plot(t, np.asarray(p) / 1e6, color=f"C{len(names) + i}", label=f"matrix at {k}")
    for n, p in mon["max_fracture_pressure"].items():
        a1.plot(t, np.asarray(p) / 1e6, "--", color=colours.get(n), label=f"max p_f on {n}")
    for n, v in mon["max_slip"].items():
        a2.plot(t, np.asarray(v) * 1e3, color=colours.get(n), label=f"{n}")
    to = faces["time"] / DAY
    slipping = faces["state"] == "slip"
    for n in names:
        sel = faces["fracture"] == n
        A = faces["area"][sel]
        a3.plot(to, (slipping[:, sel] * A).sum(axis=1) / A.sum() * 100, "o-", ms=3, color=colours[n], label=n)
        if onsets[n]["onset_area_s"] is not None:
            for a in (a1, a2, a3):
                a.axvline(onsets[n]["onset_area_s"] / DAY, color=colours[n], lw=0.8, ls=":")
    a1.set_ylabel("overpressure (MPa)")
    a2.set_ylabel("max slip since the start (mm)")
    a3.set_ylabel("slipping area (% of the fault)")
    for a in (a1, a2, a3):
        a.set_xlabel("t (days)")
        a.grid(alpha=0.3)
        a.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2, frameon=False)
    fig.suptitle(f"{summary['case']}: pressure and slip against time (dotted: slip onset of each fault, "
                 f"{100 * AREA_ONSET:g}% of its area slipping)",
                 fontsize=10)
    save(fig, folder / "reactivation.png")

    fig, axes = plt.subplots(2, len(names), figsize=(4.6 * len(names) + 0.8, 7.2), squeeze=False,
                             layout="constrained")
    onset_face = np.where(slipping.any(axis=0), faces["time"][np.argmax(slipping, axis=0)] / DAY, np.nan)
    vmax = float(faces["time"][-1] / DAY)
    for c, n in enumerate(names):
        sel = faces["fracture"] == n
        X = faces["x"][sel]
        # along-fault coordinate: the horizontal direction of largest spread of the face centroids
        h = X[:, :2] - X[:, :2].mean(axis=0)
        w = np.linalg.svd(h, full_matrices=False)[2][0]
        s = h @ w
        size = 8 + 60 * np.sqrt(faces["area"][sel] / faces["area"][sel].max())
        a, b = axes[0, c], axes[1, c]
        never = np.isnan(onset_face[sel])
        a.scatter(s[never], X[never, 2], s=size[never], c="0.8", label="never")
        sc = a.scatter(s[~never], X[~never, 2], s=size[~never], c=onset_face[sel][~never], cmap="viridis_r",
                       vmin=0.0, vmax=vmax)
        fig.colorbar(sc, ax=a, label="slip onset (days)")
        sc2 = b.scatter(s, X[:, 2], s=size, c=faces["slip"][-1, sel] * 1e3, cmap="magma_r")
        fig.colorbar(sc2, ax=b, label=f"slip at t = {vmax:.3g} days (mm)")
        on = onsets[n]["onset_s"]
        a.set_title(f"{n}: onset " + ("never" if on is None else f"{on / DAY:.3g} days"), fontsize=9)
        for ax in (a, b):
            ax.set_xlabel("along the fault (m)", fontsize=8)
            ax.set_ylabel("z (m)", fontsize=8)
            ax.grid(alpha=0.3)
    fig.suptitle(f"{summary['case']}: fault faces seen face-on (marker size ~ √area)", fontsize=10)
    save(fig, folder / "slip_onset_map.png")
    return onsets


def report(folder: Path, seconds: float | None, onsets: dict) -> dict:
    s = json.loads((folder / "summary.json").read_text())
    newton = [st["newton_iterations"] for st in s["steps"]]
    out = {"case": s["case"], "cells": s["mesh"]["cells"], "faces": s["mesh"]["faces"], "nodes": s["mesh"]["nodes"],
           "unknowns": s["mesh"]["unknowns"], "fracture_faces": s["mesh"]["fracture_faces"],
           "wall_s": seconds, "run_s": s["totals"]["seconds"], "linear_s": s["totals"]["seconds_linear"],
           "peak_rss_mb": s["totals"]["peak_memory_mb"], "newton_per_step": newton,
           "newton_total": int(sum(newton)), "faults": onsets}
    print(f"{out['case']}: {out['cells']} cells, {out['faces']} faces, {out['nodes']} nodes, {out['unknowns']} "
          f"unknowns, {out['fracture_faces']} fault faces")
    if seconds is not None:
        print(f"wall time {seconds:.1f} s (run {out['run_s']:.1f} s, linear solves {out['linear_s']:.1f} s), "
              f"peak resident {out['peak_rss_mb']:.0f} MB")
    print(f"Newton iterations per step {newton} (total {out['newton_total']})")
    print(f"| fault | faces | first slipping face (days) | onset: {100 * AREA_ONSET:g}% of the area slips (days) | "
          "slipping area at the end | max slip at the end (mm) |")
    print("|---|---|---|---|---|---|")
    for n, o in onsets.items():
        on, ona = ("never" if v is None else f"{v / DAY:.3g}" for v in (o["onset_s"], o["onset_area_s"]))
        print(f"| {n} | {o['faces']} | {on} | {ona} | {100 * o['slip_area_fraction']:.1f}% | "
              f"{1e3 * o['max_slip_m']:.3g} |")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", nargs=3, type=int, default=[60, 50, 10], metavar=("NX", "NY", "NZ"))
    ap.add_argument("--case", default=None, help="run this built-in case or case file as it is instead")
    ap.add_argument("--out", default="results/cornerpoint-reactivation")
    ap.add_argument("--linear", default="auto")
    ap.add_argument("--set", action="append", default=[], help="more KEY=VALUE overrides")
    ap.add_argument("--tilt", type=float, default=0.0, metavar="DEG",
                    help="mesh.pillar_angle: the outermost pillars this far from vertical (generated grid)")
    ap.add_argument("--pinchout", type=int, nargs="+", default=[], metavar="K",
                    help="mesh.pinchout: these layers (1-based, of NZ) thin to zero towards x = 0")
    ap.add_argument("--f1-x", type=float, default=1000.0, metavar="X",
                    help="map x (m) of F1 at the top; off the centre its pillars lean with --tilt, so it dips")
    ap.add_argument("--f2-contact", action="store_true",
                    help="F2 (along x, crossing F1) a contact surface too, not bonded")
    ap.add_argument("--json", default=None)
    ap.add_argument("--plots-only", default=None, metavar="DIR", help="only plot a finished run's folder")
    a = ap.parse_args(argv)
    if a.plots_only:
        folder = Path(a.plots_only)
        res = report(folder, None, plots(folder))
    else:
        case = a.case or "cornerpoint-injection"
        gen = generated_overrides(*a.cells, tilt=a.tilt, pinchout=a.pinchout, f1_x=a.f1_x, f2_contact=a.f2_contact)
        sets = ([] if a.case else gen) + [f"solver.linear={a.linear}"] + a.set
        angles = grid_angles(case, sets)
        if angles:
            print("pillar angles from vertical: median {median_deg:.1f}°, max {max_deg:.1f}°, outermost "
                  "{outer_deg:.1f}°, F1's {F1_deg:.1f}°".format(**angles))
        args = ["run", case, "--out", a.out, "--force"]
        for s in sets:
            args += ["--set", s]
        print("polypore", " ".join(args))
        t0 = time.perf_counter()
        rc = polypore(args)
        wall = time.perf_counter() - t0
        if rc != 0:
            return rc
        folder = Path(a.out)
        res = report(folder, wall, plots(folder))
        res["peak_rss_mb_process"] = peak_memory_mb()
        res["pillar_angles"] = angles
        res["command_sets"] = sets
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
