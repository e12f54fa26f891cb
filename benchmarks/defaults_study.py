"""Defaults of the discretisation against the alternatives: accuracy and cost on the validation cases (issue 25).

    PYTHONPATH=src python benchmarks/defaults_study.py            # the study (~26 min on 2 shared cores, ≤ 2.3 GB a run)
    PYTHONPATH=src python benchmarks/defaults_study.py --quick    # a smaller sample (~8 min)
    PYTHONPATH=src python benchmarks/defaults_study.py --c5-reference   # also the C5 reference (> 30 min more)
    PYTHONPATH=src python benchmarks/defaults_study.py --report   # tables again from docs/defaults_study.json
    PYTHONPATH=src python benchmarks/defaults_study.py --only cube penny-inclined   # some cases only

The options compared: ``mechanics.order`` (1: nodal + face bubbles; 2: quadratic, simplicial
meshes), ``mechanics.bubbles`` (one- / two-sided), ``mesh.front`` (isotropic / anisotropic
crack-front cells, where the case's fractures allow them) and ``mesh.mirror`` (none / fractures).
Every run is one ``polypore run`` process with the case's own settings plus the variant's
``--set`` overrides (``mechanics.order`` is always given explicitly, so the study measures the
same thing whatever the default is); wall time includes process start, meshing and output.

Cases and their accuracy measure:

- ``cube-slip-3d``: the case's errors against its P2 reference (summary.json: max slip, slip L2,
  slip L2 with the rim left out, λ_n L2 rim out, open faces — every face slides in the reference);
- ``penny-pressurised`` and ``penny-inclined``: the analytic solutions (``cases/penny_exact.py``:
  opening / slip / λ_n relative L2, faces in the wrong state — the exact crack is open everywhere,
  resp. closed and sliding everywhere);
- ``dfm-3d`` (C5, poromechanics, no closed form): the final-time (and T/2) slip, opening and λ_n on
  the four fractures: ∫ slip dA, ∫ opening dA and the mean λ_n of every run (no reference needed);
  with ``--c5-reference`` also against a reference run (order 2, two-sided bubbles, fracture faces
  half the size; it did not reach T/2 within 32 min on the shared machine of docs/defaults.md): per
  fracture, |∫ slip| and ∫ opening (mesh-independent integrals), and relative L2 of the face
  values with the reference faces sampled from the nearest face of the same fracture of the run
  (this sampling adds an O(h) error of its own: compare the variants with each other, the
  integrals are the cleaner measure), and the reference-area fraction in another contact state.

Cost: unknowns, Newton iterations (summed over steps), wall time, peak memory (the run's own),
the 1-minute load average at the start and end of each run (2 cores shared with other jobs:
wall times are inflated and only roughly comparable).

Writes ``<out>/defaults_study.json`` (every run; reused on a re-run: a configuration already in
the file is not run again unless ``--rerun``) and ``<out>/defaults_tables.md`` (the tables;
docs/defaults.md quotes them and gives the decision).
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from childrun import polypore_run  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FRACTURES = ("F1", "F2", "F3", "F4")
C5_TIMES = (50.0, 100.0)


def penny(n: int, order: int) -> list[str]:
    """Crack faces a/n; order 2 with bulk grading 0.5 (as benchmarks/penny_study.py: the bulk costs P2
    little accuracy and a/20 stays under 4.5 GB)."""
    return [f"mesh.fracture_size={1.0 / n:.10g}"] + (["mesh.grading=0.5"] if order == 2 else [])


# the cube's isotropic meshes: the P1 √r-graded family of docs/cube_slip.md (scale 1) and the P2
# r^0.6-graded mesh that was the case's default before the anisotropic fronts (docs/cube_slip_anisotropic.md)
CUBE_ISO_P1 = ["mesh.front=isotropic", "mesh.size=0.3", "mesh.fracture_size=0.08", "mesh.tip_size=0.015",
               "mesh.tip_grading=0.5", "mesh.grading=0.4"]
CUBE_ISO_P2 = ["mesh.front=isotropic", "mesh.size=1.0", "mesh.fracture_size=0.8", "mesh.tip_size=0.02",
               "mesh.tip_grading=0.6", "mesh.grading=0.4"]


def configs(quick: bool, c5_reference: bool = False) -> list[dict]:
    """The runs: case, label, the variant's choices and its overrides."""
    out = []

    def add(case, label, order, bubbles, front="isotropic", mirror="none", extra=(), level=None, ref=False):
        ov = [f"mechanics.order={order}", f"mechanics.bubbles={bubbles}"] + list(extra)
        out.append({"case": case, "label": label, "order": order, "bubbles": bubbles, "front": front,
                    "mirror": mirror, "level": level, "overrides": ov, "reference": ref,
                    "key": f"{case} | {label}"})

    # cube-slip-3d: the case's anisotropic fronts (scale 1), both orders and bubbles; isotropic meshes
    for order in (2, 1):
        for b in ("one-sided", "two-sided"):
            add("cube-slip-3d", f"P{order}, anisotropic fronts, {b}", order, b, front="anisotropic")
    add("cube-slip-3d", "P1, isotropic √r-graded (P1 family, scale 1)", 1, "one-sided", extra=CUBE_ISO_P1)
    add("cube-slip-3d", "P2, isotropic r^0.6-graded", 2, "one-sided", extra=CUBE_ISO_P2)
    add("cube-slip-3d", "P1, isotropic √r, mirrored, two-sided", 1, "two-sided", mirror="fractures",
        extra=CUBE_ISO_P1 + ["mesh.mirror=fractures"])
    if not quick:
        add("cube-slip-3d", "P1, isotropic √r-graded, scale 0.63", 1, "one-sided",
            extra=["mesh.front=isotropic", "mesh.size=0.189", "mesh.fracture_size=0.0504", "mesh.tip_size=0.00945",
                   "mesh.tip_grading=0.5", "mesh.grading=0.4"])
        add("cube-slip-3d", "P1, anisotropic fronts scale 0.25", 1, "one-sided", front="anisotropic",
            extra=["mesh.fracture_size=0.0875", "mesh.tip_size=0.00125"])

    # penny-pressurised: general mesh (the case's), both orders and bubbles; P1 on finer meshes (the
    # cost of P2); P1 on anisotropic front cells (the 64-gon's 64 fronts, each a tube: P2 there
    # would exceed ~200k unknowns)
    n = 5 if quick else 10
    for order in (1, 2):
        for b in ("one-sided", "two-sided"):
            add("penny-pressurised", f"a/{n}, P{order}, {b}", order, b, extra=penny(n, order), level=n)
    if not quick:
        add("penny-pressurised", "a/14, P1, one-sided", 1, "one-sided", extra=penny(14, 1), level=14)
        add("penny-pressurised", "a/20, P1, one-sided", 1, "one-sided", extra=penny(20, 1), level=20)
        add("penny-pressurised", "a/14, P2, one-sided", 2, "one-sided", extra=penny(14, 2), level=14)
        add("penny-pressurised", "anisotropic fronts (a/5, tip a/50), P1, one-sided", 1, "one-sided",
            front="anisotropic", extra=PENNY_ANISO, level=5)

    # penny-inclined: mirrored mesh (the case's) and general mesh, both orders and bubbles
    for mirror in ("fractures", "none"):
        for order in (1, 2):
            for b in ("two-sided", "one-sided"):
                if mirror == "fractures" and b == "one-sided" and (quick or order == 2):
                    continue
                add("penny-inclined", f"a/{n}, {'mirrored' if mirror != 'none' else 'general'} mesh, P{order}, {b}",
                    order, b, mirror=mirror, extra=penny(n, order) + [f"mesh.mirror={mirror}"], level=n)
    if not quick:
        add("penny-inclined", "a/14, general mesh, P1, one-sided", 1, "one-sided",
            extra=penny(14, 1) + ["mesh.mirror=none"], level=14)
        add("penny-inclined", "a/20, mirrored mesh, P1, two-sided", 1, "two-sided",
            mirror="fractures", extra=penny(20, 1) + ["mesh.mirror=fractures"], level=20)
        add("penny-inclined", "anisotropic fronts (a/5, tip a/50), P1, one-sided", 1, "one-sided",
            front="anisotropic", extra=PENNY_ANISO + ["mesh.mirror=none"], level=5)

    # dfm-3d (C5): general mesh (intersecting fractures and one on the boundary: no anisotropic
    # fronts, no mirror), both orders and bubbles, against a P2 two-sided reference with fracture
    # faces half the size (--quick: against P2 two-sided on the same mesh)
    size = 0.15 if quick else 0.1
    for order in (1, 2):
        for b in ("one-sided", "two-sided"):
            if quick and b == "two-sided" and order == 1:
                continue
            add("dfm-3d", f"size {size}, P{order}, {b}", order, b, extra=[f"mesh.size={size}"], level=size,
                ref=quick and order == 2 and b == "two-sided")
    if not quick:
        add("dfm-3d", f"size {size}, fracture_size {C5_REF_FRACTURE}, P1, one-sided", 1, "one-sided",
            extra=[f"mesh.size={size}", f"mesh.fracture_size={C5_REF_FRACTURE}", "mesh.grading=0.5"], level=size)
    if not quick and c5_reference:
        # one-sided P2 (the default's bubbles): the two-sided run stalled at t = 34 s with 4 and with
        # 10 halvings of the step (Newton's active sets cycling; docs/defaults.md)
        add("dfm-3d", f"reference: size {size}, fracture_size {C5_REF_FRACTURE}, P2, one-sided", 2, "one-sided",
            extra=[f"mesh.size={size}", f"mesh.fracture_size={C5_REF_FRACTURE}", "mesh.grading=0.5", "time.max_cuts=10"],
            level=size, ref=True)
    return out


C5_REF_FRACTURE = 0.05
# the penny on anisotropic crack-front cells: 64 fronts of a/10 each, so the cells are graded along
# every front towards its corners whatever fracture_size is (~60k cells)
PENNY_ANISO = ["mesh.front=anisotropic", "mesh.fracture_size=0.2", "mesh.tip_size=0.02", "mesh.grading=0.5"]


def run(cfg: dict, keep: Path) -> dict:
    """One ``polypore run``: its summary's mesh, cost and errors; for dfm-3d the fracture faces at
    the output times (saved to ``keep``/<name>.npz)."""
    with polypore_run(cfg["case"], cfg["overrides"]) as child:
        if child.proc.returncode != 0:
            return {"failed": child.proc.stderr[-2000:], "seconds": child.seconds}
        return _record(cfg, child.out, keep, child.seconds, list(child.load_average))


def imported(cfg: dict, folder: Path, keep: Path) -> dict:
    """The record of a finished run folder (the C5 reference run by hand: it takes ~40 min)."""
    case = (folder / "case.toml").read_text()
    for ov in cfg["overrides"]:                       # the folder must be the configuration's run
        key, val = ov.split("=", 1)
        leaf = key.split(".")[-1]
        if not re.search(rf"^{re.escape(leaf)}\s*=\s*\"?{re.escape(val)}\"?\s*$", case, re.M):
            raise SystemExit(f"{folder}: its case.toml does not have {ov}")
    s = json.loads((folder / "summary.json").read_text())
    # wall time: the run's own total; the load average was not recorded
    return _record(cfg, folder, keep, s["totals"].get("seconds"), [np.nan, np.nan]) | {"imported_from": str(folder)}


def _record(cfg: dict, out: Path, keep: Path, wall: float, load: list) -> dict:
    """A run's record from its folder: mesh, cost, errors, final states; dfm-3d: its faces file."""
    s = json.loads((out / "summary.json").read_text())
    rec = {"unknowns": s["mesh"]["unknowns"], "cells": s["mesh"]["cells"],
           "fracture_faces": s["mesh"]["fracture_faces"],
           "newton_iterations": int(sum(st["newton_iterations"] for st in s["steps"])),
           "steps": len(s["steps"]), "seconds": wall, "seconds_solve": s["totals"].get("seconds"),
           "peak_memory_mb": s["totals"].get("peak_memory_mb"), "load_average": load,
           "errors": s.get("errors") or {}, "choices": s.get("choices"),
           "final_states": {k: s["steps"][-1].get(k) for k in ("open", "stick", "slip")}}
    if cfg["case"] == "dfm-3d":
        keep.mkdir(parents=True, exist_ok=True)
        name = cfg["key"].replace(" | ", "__").replace(" ", "_")
        path = keep / (re.sub(r"[,/:]", lambda m: "_" if m.group() == "/" else "", name) + ".npz")
        np.savez_compressed(path, **_c5_faces(out / "fractures.csv"))
        rec["faces_file"] = str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)
    return rec


def _c5_faces(path: Path) -> dict:
    """Per output time: fracture index, centroid, area, normal jump, tangential jump, λ_n, state."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    out = {}
    for t in C5_TIMES:
        sel = [r for r in rows if abs(float(r["time"]) - t) < 1e-9]
        tag = f"t{int(t)}"
        out[f"{tag}_fracture"] = np.array([FRACTURES.index(r["fracture"]) for r in sel])
        out[f"{tag}_x"] = np.array([[float(r[k]) for k in "xyz"] for r in sel])
        for k in ("area", "jump_n", "jump_t", "lambda_n"):
            out[f"{tag}_{k}"] = np.array([float(r[k]) for r in sel])
        out[f"{tag}_state"] = np.array([{"open": 0, "stick": 1, "slip": 2}[r["state"]] for r in sel])
    return out


def c5_integrals(run_file: Path) -> dict:
    """Per output time: ∫ |slip| dA and ∫ opening dA over all fracture faces (m³) and the mean λ_n
    (Pa): mesh-independent measures that need no reference."""
    a = np.load(run_file)
    out = {}
    for t in C5_TIMES:
        tag = f"t{int(t)}"
        A = a[f"{tag}_area"]
        out[tag] = {"slip_integral": float(np.sum(A * a[f"{tag}_jump_t"])),
                    "opening_integral": float(np.sum(A * np.maximum(-a[f"{tag}_jump_n"], 0.0))),
                    "lambda_n_mean": float(np.sum(A * a[f"{tag}_lambda_n"]) / A.sum())}
    return out


def c5_compare(run_file: Path, ref_file: Path) -> dict:
    """Errors of a C5 run against the reference at each output time (see the module docstring)."""
    from scipy.spatial import cKDTree

    a, r = np.load(run_file), np.load(ref_file)
    res = {}
    for t in C5_TIMES:
        tag = f"t{int(t)}"
        fr_r, X_r, A_r = r[f"{tag}_fracture"], r[f"{tag}_x"], r[f"{tag}_area"]
        fr_a, X_a, A_a = a[f"{tag}_fracture"], a[f"{tag}_x"], a[f"{tag}_area"]
        idx = np.empty(fr_r.size, int)
        for f in range(len(FRACTURES)):
            ra, rr = np.flatnonzero(fr_a == f), np.flatnonzero(fr_r == f)
            if rr.size:
                idx[rr] = ra[cKDTree(X_a[ra]).query(X_r[rr])[1]]
        out = {}
        fields = {"slip": (a[f"{tag}_jump_t"], r[f"{tag}_jump_t"]),
                  "opening": (np.maximum(-a[f"{tag}_jump_n"], 0.0), np.maximum(-r[f"{tag}_jump_n"], 0.0)),
                  "lambda_n": (a[f"{tag}_lambda_n"], r[f"{tag}_lambda_n"])}
        for name, (va, vr) in fields.items():
            num = np.sum(A_r * (va[idx] - vr) ** 2)
            den = np.sum(A_r * vr ** 2)
            out[f"{name}_L2_rel"] = float(np.sqrt(num / den)) if den > 0 else None
            if name != "lambda_n":
                ia = np.array([np.sum(A_a[fr_a == f] * va[fr_a == f]) for f in range(len(FRACTURES))])
                ir = np.array([np.sum(A_r[fr_r == f] * vr[fr_r == f]) for f in range(len(FRACTURES))])
                out[f"{name}_integral_rel"] = {FRACTURES[f]: (float(ia[f] / ir[f] - 1.0) if ir[f] > 0 else None)
                                               for f in range(len(FRACTURES))}
                out[f"{name}_integral_total_rel"] = float(ia.sum() / ir.sum() - 1.0) if ir.sum() > 0 else None
        st_a, st_r = a[f"{tag}_state"][idx], r[f"{tag}_state"]
        out["area_wrong_state"] = float(np.sum(A_r * (st_a != st_r)) / A_r.sum())
        out["area_wrongly_open"] = float(np.sum(A_r * ((st_a == 0) & (st_r != 0))) / A_r.sum())
        out["area_wrongly_stuck"] = float(np.sum(A_r * ((st_a == 1) & (st_r == 2))) / A_r.sum())
        out["faces"] = {"open": int(np.sum(a[f"{tag}_state"] == 0)), "stick": int(np.sum(a[f"{tag}_state"] == 1)),
                        "slip": int(np.sum(a[f"{tag}_state"] == 2))}
        res[tag] = out
    return res


# ---------------------------------------------------------------- tables

def _pc(x, digits=1):
    return "–" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{100 * x:.{digits}f} %"


def _cost(r):
    load = max(r["load_average"])
    return (f"{r['unknowns']:,} | {r['newton_iterations']} | {r['seconds']:.1f} s | "
            f"{r['peak_memory_mb']:.0f} MB | " + ("–" if not np.isfinite(load) else f"{load:.1f}"))


def tables(result: dict) -> str:
    runs = result["runs"]
    lines = []
    cube = [r for r in runs if r["case"] == "cube-slip-3d" and "failed" not in r]
    if cube:
        lines += ["### cube-slip-3d (against the P2 reference)", "",
                  "| variant | max slip | slip L2 | slip L2, rim out | λ_n L2, rim out | open faces | unknowns | "
                  "Newton | wall | peak | load |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in cube:
            e = r["errors"]
            lines.append(f"| {r['label']} | {_pc(e.get('max_slip_error_rel'))} | {_pc(e.get('slip_L2_rel'))} | "
                         f"{_pc(e.get('slip_L2_rel_inner'))} | {_pc(e.get('lambda_n_L2_rel_inner'))} | "
                         f"{e.get('open_faces')} | {_cost(r)} |")
        lines.append("")
    for case, what in (("penny-pressurised", "opening"), ("penny-inclined", "slip")):
        rows = [r for r in runs if r["case"] == case and "failed" not in r]
        if not rows:
            continue
        lines += [f"### {case} (against the analytic solution)", "",
                  f"| variant | {what} L2 | {what} L2, rim out | λ_n L2 | λ_n L2, rim out | faces open / stick / slip "
                  "| wrong state | unknowns | Newton | wall | peak | load |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            e = r["errors"]
            lines.append(f"| {r['label']} | {_pc(e.get(what + '_L2_rel'), 2)} | "
                         f"{_pc(e.get(what + '_L2_rel_away_from_rim'), 2)} | {_pc(e.get('lambda_n_L2_rel'), 2)} | "
                         f"{_pc(e.get('lambda_n_L2_rel_away_from_rim'), 2)} | {e.get('faces_open')} / "
                         f"{e.get('faces_stick')} / {e.get('faces_slip')} | {e.get('faces_wrong_state')} | "
                         f"{_cost(r)} |")
        lines.append("")
    c5 = [r for r in runs if r["case"] == "dfm-3d" and "failed" not in r]
    if c5:
        ref = next((r for r in c5 if r["reference"]), None)
        lines += ["### dfm-3d (C5, poromechanics)" + (f" against {ref['label']}" if ref else
                                                         " (no reference run: errors left out)"), "",
                  "| variant | t | ∫ slip dA (1e-6 m³) | ∫ opening dA (1e-9 m³) | mean λ_n (MPa) | slip L2 | ∫ slip | "
                  "opening L2 | ∫ opening | λ_n L2 | area in another state "
                  "(wrongly open / stuck) | faces open / stick / slip | unknowns | Newton | wall | peak | load |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in c5:
            for tag in ("t50", "t100"):
                c = (r.get("compare") or {}).get(tag, {})
                f = c.get("faces") or _faces_only(ROOT / r["faces_file"], tag)
                cost = _cost(r) if tag == "t50" else " | | | | "
                g = (r.get("integrals") or {}).get(tag, {})
                ints = (f"{1e6 * g.get('slip_integral', np.nan):.4g} | {1e9 * g.get('opening_integral', np.nan):.4g} | "
                        f"{1e-6 * g.get('lambda_n_mean', np.nan):.4g}")
                if r["reference"] or not c.get("slip_L2_rel"):
                    lines.append(f"| {r['label']} | {tag[1:]} s | {ints} | – | – | – | – | – | – | "
                                 f"{f.get('open')} / {f.get('stick')} / {f.get('slip')} | {cost} |")
                    continue
                lines.append(f"| {r['label']} | {tag[1:]} s | {ints} | {_pc(c.get('slip_L2_rel'))} | "
                             f"{_pc(c.get('slip_integral_total_rel'))} | {_pc(c.get('opening_L2_rel'))} | "
                             f"{_pc(c.get('opening_integral_total_rel'))} | {_pc(c.get('lambda_n_L2_rel'))} | "
                             f"{_pc(c.get('area_wrong_state'))} ({_pc(c.get('area_wrongly_open'))} / "
                             f"{_pc(c.get('area_wrongly_stuck'))}) | {f.get('open')} / {f.get('stick')} / "
                             f"{f.get('slip')} | {cost} |")
        lines.append("")
    failed = [r for r in runs if "failed" in r]
    if failed:
        lines += ["Runs that failed:", ""] + [f"- {r['key']}: `{r['failed'].strip().splitlines()[-1]}`"
                                              for r in failed] + [""]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a smaller sample (coarser penny, fewer variants)")
    ap.add_argument("--only", nargs="+", metavar="CASE", help="cases to run: cube penny-pressurised penny-inclined dfm-3d")
    ap.add_argument("--out", default=str(ROOT / "docs"), help="output folder (default docs/)")
    ap.add_argument("--report", action="store_true", help="tables from the JSON only")
    ap.add_argument("--rerun", action="store_true", help="run configurations already in the JSON again")
    ap.add_argument("--c5-reference", action="store_true",
                    help="also the C5 reference run (order 2, two-sided, fracture faces 0.05: > 30 min)")
    ap.add_argument("--reference-run", metavar="DIR", default=None,
                    help="a finished `polypore run dfm-3d` folder with the C5 reference's overrides, taken as its "
                         "run instead of running it (its summary.json gives the cost)")
    ap.add_argument("--keep", default=str(ROOT / "docs/defaults_study_c5"),
                    help="folder of the C5 fracture faces (.npz) per run")
    args = ap.parse_args()
    out = Path(args.out)
    path = out / ("defaults_study_quick.json" if args.quick else "defaults_study.json")
    result = json.loads(path.read_text()) if path.exists() else {"runs": []}
    done = {r["key"]: r for r in result["runs"]}
    if args.reference_run:
        cfg = next(c for c in configs(args.quick, True) if c["reference"] and c["case"] == "dfm-3d")
        done[cfg["key"]] = cfg | imported(cfg, Path(args.reference_run), Path(args.keep) / "full")
        result["runs"] = list(done.values())
    if not args.report:
        only = {("cube-slip-3d" if c == "cube" else c) for c in (args.only or [])}
        todo = [c for c in configs(args.quick, args.c5_reference) if not only or c["case"] in only]
        for cfg in todo:
            if cfg["key"] in done and "failed" not in done[cfg["key"]] and not args.rerun:
                continue
            print(f"[{time.strftime('%H:%M:%S')}] {cfg['key']}  {' '.join(cfg['overrides'])}", flush=True)
            rec = cfg | run(cfg, Path(args.keep) / ("quick" if args.quick else "full"))
            done[cfg["key"]] = rec
            e = rec.get("errors") or {}
            print("    " + ("FAILED: " + rec["failed"].strip().splitlines()[-1] if "failed" in rec else
                            f"{rec['unknowns']} unknowns, {rec['newton_iterations']} Newton, {rec['seconds']:.1f} s, "
                            f"{rec['peak_memory_mb']:.0f} MB, load {max(rec['load_average']):.1f}; "
                            + ", ".join(f"{k} {v:.4g}" for k, v in e.items()
                                        if isinstance(v, float) and ("L2" in k or "max_slip_error" in k))),
                  flush=True)
            result["runs"] = list(done.values())
            result["date"] = time.strftime("%Y-%m-%d")
            path.write_text(json.dumps(result, indent=1, default=float))
    # C5: compare against the reference (or, without one, leave the errors out)
    runs = result["runs"]
    ref = next((r for r in runs if r["case"] == "dfm-3d" and r.get("reference") and "failed" not in r), None)
    for r in runs:
        if r["case"] == "dfm-3d" and "failed" not in r:
            r["integrals"] = c5_integrals(ROOT / r["faces_file"])
        if r["case"] == "dfm-3d" and "failed" not in r and ref is not None and not r.get("reference"):
            r["compare"] = c5_compare(ROOT / r["faces_file"], ROOT / ref["faces_file"])
        if r["case"] == "dfm-3d" and r.get("reference") and "failed" not in r:
            r["compare"] = {tag: {"faces": c} for tag, c in
                            ((t, _faces_only(ROOT / r["faces_file"], t)) for t in ("t50", "t100"))}
    order = {c["key"]: i for i, c in enumerate(configs(args.quick, c5_reference=True))}
    runs.sort(key=lambda r: order.get(r["key"], len(order)))
    path.write_text(json.dumps(result, indent=1, default=float))
    text = tables(result)
    (out / ("defaults_tables_quick.md" if args.quick else "defaults_tables.md")).write_text(
        "<!-- made by benchmarks/defaults_study.py" + (" --quick" if args.quick else "") + " -->\n\n" + text)
    print(text)


def _faces_only(path: Path, tag: str) -> dict:
    s = np.load(path)[f"{tag}_state"]
    return {"open": int(np.sum(s == 0)), "stick": int(np.sum(s == 1)), "slip": int(np.sum(s == 2))}


if __name__ == "__main__":
    main()
