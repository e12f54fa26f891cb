"""Slip after onset on the displaced fault (issue 24): the `displaced-fault` case with a friction
low enough that depletion makes the fault slide near the inner reservoir corners, under nested
refinement, against the finest run as reference (its own error estimated from the convergence).

    PYTHONPATH=src .venv-fast/bin/python benchmarks/displaced_fault_slip.py [--friction 0.27]
        [--levels 0 1 2 3] [--reference-level 4] [--reference-near 100] [--variants default-aligned twosided-aligned default]
        [--out docs]   # ~30 min on 2 shared cores; the reference (152k cells) ~5 GB with PARDISO
    ... --report-only   # tables and plot again from docs/displaced_fault_slip.json

Why a numerical reference. The closed form of docs/displaced_fault_reference.md holds while the
fault sticks; once it slides, the slip solves a singular integral equation (Jansen & Meulenbroek's
semi-analytic treatment) that has no closed form. The reference here is polypore itself on the
finest mesh of a nested family whose convergence is measured: the slip profile of every level is
compared with the finest one, face by face (the finest faces averaged over each coarser face:
the refinement is nested), and the observed rates give the finest level's own error by
Richardson's estimate. A second discretisation (two-sided bubbles) and a second mesh family
(graded, with sliver faces near the outer corners) converge to the same profile: that is the
evidence that the limit is the solution and not an artefact of one variant.

Quantities, per level: the slip (tangential jump along the dip, m; negative = hanging wall down,
normal faulting) per fault face; the maximum slip of each patch; each patch's extent (the span of
faces whose multiplier is in the slip state); its potency ∫ slip dy (m²); Newton iterations,
states, cells, seconds. Errors against the reference: L2 of the slip difference over the fault
relative to the reference's L2, max-slip and potency differences, the ends of the patches in
units of the finest cell.

Loading: one static step from the in-situ state (σ⁰ of the case; τ⁰/σ'⁰_n = 0.168 on the fault)
to the depleted state Δp = −10 MPa (friction F = 0.27 by default: two slip patches grow inwards from
the inner corners y = ±75 m, where Δτ has its logarithmic peaks).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import displaced_fault_study as study  # noqa: E402
from polypore.mesh.cornerpoint.generate import write_grdecl  # noqa: E402
from polypore.runs.common import peak_memory_mb  # noqa: E402
from polypore.runs.static import solve_static  # noqa: E402
from polypore.setup.casefile import load_case  # noqa: E402

VARIANTS = {"default-aligned": ([], study.BAND), "twosided-aligned": (["mechanics.bubbles=two-sided"], study.BAND),
            "default": ([], 0)}
SLIP = 2   # contact state code of a sliding face


def run(k: int, variant: str, friction: float, dp: float, tmp: Path, near: float | None = None) -> dict:
    """One static run at level k (with ``near``: the locally refined :func:`reference_grid`)."""
    overrides, band = VARIANTS[variant]
    grid = study.level_grid(k, 2000.0, band) if near is None else reference_grid(k, near)
    path = write_grdecl(grid, tmp / f"dfs_l{k}_b{band}_{near}.grdecl")
    case = load_case("displaced-fault", [f"mesh.file={path}", f"parameters.dp={dp!r}",
                                         f"contact.friction={friction!r}", *overrides])
    t0 = time.perf_counter()
    problem, st, *_ = solve_static(case)
    secs = time.perf_counter() - t0
    fm = problem.fm
    net, g = fm.network, fm.mesh.geometry
    th = np.radians(study.DIP)
    e = np.array([np.cos(th), 0.0, np.sin(th)])          # up-dip unit vector in the x-z plane
    ly = study.H / (8 * 2 ** k)
    xc, area = g.face_centroid[net.faces], g.face_area[net.faces]
    ym = xc[:, 2] + study.DEPTH
    dy = area / ly * np.sin(th)
    o = np.argsort(ym)
    # the jump [[u]] = u⁺ − u⁻ along e, signed so that < 0 is the hanging wall moving down (normal
    # faulting under depletion) whichever side the mesh calls +
    n_ref = np.array([np.sin(th), 0.0, -np.cos(th)])
    sgn = np.sign(problem.normal @ n_ref)
    slip = sgn * (problem.jumps(st) @ e)
    return {"variant": variant, "level": k, "h": study.S0 / 2 ** k, "cells": int(fm.mesh.n_cells),
            "faces": int(net.n_faces), "newton": int(st.newton_iterations), "seconds": secs,
            "peak_mb": peak_memory_mb(), "states": np.bincount(st.state, minlength=3).tolist(),
            "y1": (ym - dy / 2)[o], "y2": (ym + dy / 2)[o], "slip": slip[o], "state": st.state[o]}


def coarsen(ref: dict, y1: np.ndarray, y2: np.ndarray) -> np.ndarray:
    """The reference slip averaged over each face [y1, y2] of another mesh: the exact mean of the
    reference's piecewise-constant profile (nested or not)."""
    edges = np.r_[ref["y1"][0], ref["y2"]]
    F = np.r_[0.0, np.cumsum(ref["slip"] * (ref["y2"] - ref["y1"]))]      # ∫ slip dy at the edges
    return (np.interp(y2, edges, F) - np.interp(y1, edges, F)) / (y2 - y1)


def reference_grid(k_near: int, near: float, half: float = 2000.0, band: int = study.BAND):
    """The aligned family's level-0 grid with every column and layer within ``near`` of the fault
    and of the reservoir split 2^k_near times, and one power of 2 less for every doubling of the
    distance beyond it (a locally refined level k_near at a fraction of its cells)."""
    fault = study.FAULT
    ya, yb, yc, yd = fault.corners_y

    def split(sizes):
        out, pos = [], 0.0
        for v in sizes:
            k = k_near - int(np.floor(np.log2(max(pos / near, 1.0))))
            out += [v / 2 ** max(k, 0)] * 2 ** max(k, 0)
            pos += v
        return out

    cols = split(study.base_sizes(half))
    above = split(study.layer_sizes(half - max(yb, yd), band))
    below = split(study.layer_sizes(half + min(ya, yc), band))
    nres = 8 * 2 ** k_near
    return study.displaced_fault_grid(fault, half_width=half, half_height=half, nz_reservoir=nres, columns=cols,
                                      layers_above=above, layers_below=below, core=study.CORE, depth=study.DEPTH,
                                      strike_length=study.H / nres)


def patches(r: dict) -> list[dict]:
    """The slip patches (runs of sliding faces): extent, max slip, potency."""
    s = np.flatnonzero(r["state"] == SLIP)
    if s.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(s) > 1)
    out = []
    for a, b in zip(np.r_[s[0], s[cuts + 1]], np.r_[s[cuts], s[-1]]):
        sl = slice(a, b + 1)
        v = r["slip"][sl]
        out.append({"from_y": float(r["y1"][a]), "to_y": float(r["y2"][b]), "faces": int(b - a + 1),
                    "max_slip": float(v[np.argmax(np.abs(v))]),
                    "potency": float(np.sum(v * (r["y2"][sl] - r["y1"][sl])))})
    return out


def compare(r: dict, ref: dict) -> dict:
    L = r["y2"] - r["y1"]
    rs = coarsen(ref, r["y1"], r["y2"])
    d = r["slip"] - rs
    pr, pf = patches(r), patches(ref)
    out = {"l2": float(np.sqrt(np.sum(L * d ** 2) / np.sum(L * rs ** 2))),
           "linf_over_max": float(np.abs(d).max() / np.abs(ref["slip"]).max()),
           "max_slip": float(r["slip"][np.argmax(np.abs(r["slip"]))]),
           "potency": float(np.sum(L * r["slip"])), "patches": pr}
    out["max_slip_err"] = abs(out["max_slip"] / ref["slip"][np.argmax(np.abs(ref["slip"]))] - 1)
    out["potency_err"] = abs(out["potency"] / float(np.sum((ref["y2"] - ref["y1"]) * ref["slip"])) - 1)
    if len(pr) == len(pf):
        out["ends_m"] = [[p["from_y"] - q["from_y"], p["to_y"] - q["to_y"]] for p, q in zip(pr, pf)]
    return out


def _rate(hs, es):
    hs, es = np.asarray(hs, float), np.asarray(es, float)
    ok = es > 0
    return float(np.polyfit(np.log(hs[ok]), np.log(es[ok]), 1)[0]) if ok.sum() >= 2 else None


def report(data: dict, out: Path) -> str:
    ref = data["reference"]
    lines = [f"Reference: {ref['variant']} at level {ref['level']} (h = {ref['h']:g} m, {ref['cells']:,} cells, "
             f"{ref['faces']} fault faces, {ref['newton']} Newton, {ref['seconds']:.0f} s, {ref['peak_mb']:.0f} MB peak); "
             f"F = {data['friction']}, Δp = {data['dp'] / 1e6:g} MPa.", "",
             "Reference patches: " + "; ".join(f"y = {p['from_y']:.2f} … {p['to_y']:.2f} m ({p['faces']} faces), "
                                                f"max slip {1e3 * p['max_slip']:.3f} mm, potency {p['potency']:.4e} m²"
                                                for p in ref["patches"]), "",
             "| variant | h (m) | cells | Newton | slip L2 vs ref | max slip (mm) | its error | potency error | "
             "patch ends − ref (m) | s |", "|---|---|---|---|---|---|---|---|---|---|"]
    for name, rows in data["series"].items():
        for c in rows:
            ends = "; ".join(f"{a:+.2f}, {b:+.2f}" for a, b in c.get("ends_m", [])) or "patches differ"
            lines.append(f"| {name} | {c['h']:g} | {c['cells']:,} | {c['newton']} | {100 * c['l2']:.2f} % | "
                         f"{1e3 * c['max_slip']:.4f} | {100 * c['max_slip_err']:.2f} % | {100 * c['potency_err']:.2f} % | "
                         f"{ends} | {c['seconds']:.0f} |")
        hs = [c["h"] for c in rows]
        lines.append(f"| {name}: rates in h | | | | {_rate(hs, [c['l2'] for c in rows]) or 0:.2f} | | "
                     f"{_rate(hs, [c['max_slip_err'] for c in rows]) or 0:.2f} | "
                     f"{_rate(hs, [c['potency_err'] for c in rows]) or 0:.2f} | | |")
    for c in data.get("reference_checks", []):
        r = c["reference_vs_this"]
        lines.append(f"\nReference check: level {c['level']} refined within {c['near']:g} m ({c['cells']:,} cells, "
                     f"{c['newton']} Newton, {c['seconds']:.0f} s, {c['peak_mb']:.0f} MB): the reference differs from it "
                     f"by {100 * r['l2']:.2f} % (slip L2), {100 * r['max_slip_err']:.2f} % (max slip), "
                     f"{100 * r['potency_err']:.2f} % (potency); its patches: "
                     + "; ".join(f"{p['from_y']:.2f} … {p['to_y']:.2f} m, max {1e3 * p['max_slip']:.3f} mm"
                                 for p in c["patches"]))
    text = "\n".join(lines) + "\n"
    (out / "displaced_fault_slip_tables.md").write_text(text)
    return text


def plot(data: dict, runs: dict, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), sharey=True)
    ref = runs["reference"]
    for ax, (lo, hi) in zip(axes, ((-100.0, 0.0), (0.0, 100.0))):
        for key, r in runs.items():
            if key == "reference" or not key.startswith("default-aligned"):
                continue
            ax.step(np.c_[r["y1"], r["y2"]].ravel(), 1e3 * np.repeat(r["slip"], 2), where="post", lw=1,
                    label=f"h = {r['h']:g} m")
        ax.plot(0.5 * (ref["y1"] + ref["y2"]), 1e3 * ref["slip"], "k-", lw=1.6,
                label=f"reference (h = {ref['h']:g} m)")
        for c in (-125, -75, 75, 125):
            if lo <= c <= hi:
                ax.axvline(c, color="0.6", ls=":", lw=1)
        ax.set_xlim(lo, hi)
        ax.set_xlabel("elevation along the fault y (m); dotted: reservoir corners")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("slip along dip (mm; < 0: hanging wall down)")
    axes[1].legend(fontsize=8)
    fig.suptitle(f"Displaced fault, depletion {data['dp'] / 1e6:g} MPa, friction {data['friction']}: slip "
                 "after onset under refinement (default discretisation, aligned meshes)")
    fig.tight_layout()
    fig.savefig(out / "displaced_fault_slip.png", dpi=120)
    plt.close(fig)


def rebase(data: dict, runs: dict, key: str) -> dict:
    """``data`` with every level compared against the stored run ``key`` (a finer reference); the
    former reference joins the series as one more level of its variant ("local" rows)."""
    new, old = runs[key], runs["reference"]
    old_key = f"reference-{old['level']}"
    runs[old_key] = old
    data["runs"][old_key] = data["runs"]["reference"]
    runs["reference"] = new
    data["runs"]["reference"] = data["runs"][key]
    series = {}
    for name, rows in data["series"].items():
        series[name] = [{**{q: c[q] for q in ("level", "h", "cells", "newton", "seconds")},
                         **compare(runs[f"{name}-{c['level']}"], new)} for c in rows]
    series["default-aligned, locally refined"] = [
        {"level": old["level"], "h": old["h"], "cells": old["cells"], "newton": old["newton"],
         "seconds": old["seconds"], **compare(old, new)}]
    check = next(c for c in data["reference_checks"] if f"check-{c['level']}-{c['near']:g}" == key)
    data["reference"] = {**{q: v for q, v in new.items() if not isinstance(v, (np.ndarray, list))},
                         "variant": f"default-aligned, level {check['level']} refined within {check['near']:g} m",
                         "patches": patches(new)}
    data["series"] = series
    data["reference_checks"] = [c for c in data["reference_checks"] if c is not check]
    return data


def _json_run(r: dict) -> dict:
    return {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in r.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--friction", type=float, default=0.27)
    ap.add_argument("--dp", type=float, default=-1e7)
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2, 3])
    ap.add_argument("--reference-level", type=int, default=4)
    ap.add_argument("--reference-near", type=float, default=100.0,
                    help="the reference's full refinement within this distance (m) of the fault and the "
                         "reservoir, one halving less per doubling of the distance (0: uniform)")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--out", type=Path, default=Path("docs"))
    ap.add_argument("--check-reference", type=float, nargs=2, metavar=("LEVEL", "NEAR"),
                    help="also run the locally refined grid LEVEL/NEAR and compare the reference with it "
                         "(the reference's own error; with --report-only: added to the JSON)")
    ap.add_argument("--reference-run", default=None,
                    help="with --report-only: compare every level with this stored run instead (e.g. "
                         "check-5-25, a finer reference added by --check-reference)")
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args(argv)
    js = args.out / "displaced_fault_slip.json"
    if args.report_only:
        data = json.loads(js.read_text())
        runs = {k: {q: np.asarray(v) if isinstance(v, list) else v for q, v in r.items()}
                for k, r in data["runs"].items()}
        if args.check_reference:
            k, near = int(args.check_reference[0]), args.check_reference[1]
            with tempfile.TemporaryDirectory() as tmp:
                fine = run(k, "default-aligned", data["friction"], data["dp"], Path(tmp), near=near)
            c = compare(runs["reference"], fine)
            data.setdefault("reference_checks", []).append(
                {"level": k, "near": near, "cells": fine["cells"], "newton": fine["newton"],
                 "seconds": fine["seconds"], "peak_mb": fine["peak_mb"], "patches": patches(fine),
                 "reference_vs_this": {q: c[q] for q in ("l2", "linf_over_max", "max_slip", "max_slip_err",
                                                         "potency_err")}})
            runs[f"check-{k}-{near:g}"] = fine
            data["runs"][f"check-{k}-{near:g}"] = _json_run(fine)
            js.write_text(json.dumps(data))
        if args.reference_run:
            data = rebase(data, runs, args.reference_run)
            js.write_text(json.dumps(data))
        print(report(data, args.out))
        plot(data, runs, args.out)
        return 0
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        ref = run(args.reference_level, "default-aligned", args.friction, args.dp, Path(tmp),
                  near=args.reference_near or None)
        print(f"reference: level {ref['level']}, {ref['cells']} cells, {ref['newton']} Newton, {ref['seconds']:.0f} s, "
              f"{ref['peak_mb']:.0f} MB, patches {patches(ref)}", flush=True)
        runs["reference"] = ref
        series = {}
        for v in args.variants:
            rows = []
            for k in args.levels:
                r = run(k, v, args.friction, args.dp, Path(tmp))
                runs[f"{v}-{k}"] = r
                c = {"level": k, "h": r["h"], "cells": r["cells"], "newton": r["newton"], "seconds": r["seconds"],
                     **compare(r, ref)}
                rows.append(c)
                print(f"{v} level {k}: slip L2 {100 * c['l2']:.2f} %, max slip {1e3 * c['max_slip']:.4f} mm "
                      f"({100 * c['max_slip_err']:.2f} %), potency {100 * c['potency_err']:.2f} %, "
                      f"{r['newton']} Newton, {r['seconds']:.0f} s", flush=True)
            series[v] = rows
    data = {"friction": args.friction, "dp": args.dp,
            "reference": {**{k: v for k, v in ref.items() if not isinstance(v, np.ndarray)},
                          "variant": "default-aligned", "patches": patches(ref)},
            "series": series, "runs": {k: _json_run(r) for k, r in runs.items()}}
    args.out.mkdir(parents=True, exist_ok=True)
    js.write_text(json.dumps(data))
    print(report(data, args.out))
    plot(data, runs, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
