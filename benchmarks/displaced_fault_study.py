"""Verification study of the displaced-fault case (issue 24): polypore's fault multipliers against the
closed-form full-space reference under refinement.

    PYTHONPATH=src .venv-fast/bin/python benchmarks/displaced_fault_study.py [--levels 0 1 2 3]
        [--variants default facewise twosided] [--domain-level 1] [--injection-level 2] [--out docs]

The case is the built-in ``displaced-fault`` (h = 200 m, throw 50 m, dip 60°, Δp = −10 MPa in the
reservoir, friction 100 so that the fault sticks) on graded corner-point slabs written by
``displaced_fault_grid`` (``columns``/``layers_*``/``core``): level 0 has 25 m layers in the reservoir
(8 layers), columns of 25 m next to the fault growing by 1.2 outwards to ±2000 m, layers above and
below the reservoir likewise from 25 m to ±2000 m; level k splits every cell of level 0 into 2^k × 2^k
(a nested, uniform refinement of a graded mesh). Pillars within 500 m of the fault (at the reservoir's
mid-plane) are parallel to it, so the cells near the fault are the same when the slab is enlarged.
The slab is one cell thick along the strike, of the reservoir layer's thickness (cubes near the fault).

Per fault face the multiplier change Δλ_n = λ_n − λ_n⁰ and the shear Δτ = −sgn(n⁺·n) λ·e − τ⁰
(λ⁰, τ⁰ from the case's uniform in-situ stress) are compared with the **face mean** of the
reference Δσ'_n = Δσ_n − Δp_f and Δτ (``DisplacedFault.fault_closed_form``, laterally infinite
reservoir, integrated exactly over each face's extent along the fault: the ln|y − y_k| terms have the
primitive u ln|u| − u). Δp_f is the case's fault pressure (Δp for −125 < y < 125 m), constant per face.

Figures per level and variant:
* ``linf``: max |num − ref| over the faces outside two cells (2 × the reservoir layer) around each of
  the four corners, divided by the largest |ref| over those same faces (the strict choice); also
  the same error divided by the largest |ref| over all faces (``linf_allpeak``) and by |C|.
* ``l2``: (Σ |σ| (num − ref)²)^½ / (Σ |σ| ref²)^½ over the whole fault (corner faces included).
* ``peaks``: at each corner, the face touching it with the larger |ref|: num and ref there.
* rates: least-squares slopes of log error against log h.

Variants: ``default`` (one-sided bubbles, multiplier patches with contact.patch_ratio = 0.2),
``facewise`` (contact.patch_ratio = 0: one multiplier per face), ``twosided`` (mechanics.bubbles =
"two-sided", patches as default). Domain effect: the default variant at one level on slabs of
±2000, ±4000 and ±8000 m (same cells near the fault), face by face. Injection: Δp = +10 MPa.

Writes ``<out>/displaced_fault_study.json`` and PNG plots ``<out>/displaced_fault_study_*.png``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from polypore.cases.displaced_fault import DisplacedFault, displaced_fault_grid, graded_sizes, scaling_factor
from polypore.mesh.cornerpoint.generate import write_grdecl
from polypore.runs.static import solve_static
from polypore.setup.casefile import load_case

H, THROW, DIP, DEPTH = 200.0, 50.0, 60.0, 3000.0
NU, ALPHA = 0.25, 1.0
S0, RATIO, CORE = 25.0, 1.2, 500.0
SIGMA0 = np.diag([-2.1e7, -2.5e7, -3.0e7])   # the case's initial_stress (x, y, z), Pa
BAND = 12     # aligned meshes: 12 layers of S0 (300 m at level 0) above and below the reservoir
# name: (overrides, band); graded meshes have sliver faces near the outer corners (horizons of the two
# sides start growing at different elevations), aligned ones have none near the reservoir
VARIANTS = {"default": ([], 0), "facewise": (["contact.patch_ratio=0"], 0),
            "twosided": (["mechanics.bubbles=two-sided"], 0),
            "cell": (["mechanics.bubble_stabilisation=cell"], 0),
            "cell-facewise": (["mechanics.bubble_stabilisation=cell", "contact.patch_ratio=0"], 0),
            "twosided-facewise": (["mechanics.bubbles=two-sided", "contact.patch_ratio=0"], 0),
            "default-aligned": ([], BAND), "twosided-aligned": (["mechanics.bubbles=two-sided"], BAND),
            # the scale of the stabilisation (× the scheme's weights; the default on these grids is 0.3):
            # its reaction enters the multipliers (setup/mechanics.py, resolve_stabilisation)
            "scale1": (["mechanics.stabilisation=1"], 0), "scale0.1": (["mechanics.stabilisation=0.1"], 0),
            "scale3": (["mechanics.stabilisation=3"], 0)}
FAULT = DisplacedFault(H, THROW, DIP)


def base_sizes(length: float, s0: float = S0, r: float = RATIO) -> list[float]:
    """Geometric sizes s0, s0 r, … filling ``length`` (:func:`graded_sizes`)."""
    return graded_sizes(length, s0, r)


def split(sizes, k: int) -> list[float]:
    return [v / 2 ** k for v in sizes for _ in range(2 ** k)]


def layer_sizes(length: float, band: int) -> list[float]:
    """``band`` layers of S0 next to the reservoir, then geometric growth from S0 to fill ``length``."""
    return [S0] * band + base_sizes(length - band * S0)


def level_grid(k: int, half: float = 2000.0, band: int = 0):
    ya, yb, yc, yd = FAULT.corners_y
    cols = split(base_sizes(half), k)
    # the shorter side (the footwall above, the hanging wall below); the other's outermost layer grows
    above = split(layer_sizes(half - max(yb, yd), band), k)
    below = split(layer_sizes(half + min(ya, yc), band), k)
    nres = 8 * 2 ** k
    return displaced_fault_grid(FAULT, half_width=half, half_height=half, nz_reservoir=nres, columns=cols,
                                layers_above=above, layers_below=below, core=CORE, depth=DEPTH,
                                strike_length=H / nres)


def run_level(k: int, overrides, dp: float = -1e7, half: float = 2000.0, band: int = 0,
              tmp: Path = Path(".")) -> dict:
    grid = level_grid(k, half, band)
    path = write_grdecl(grid, tmp / f"df_l{k}_h{int(half)}_b{band}.grdecl")
    case = load_case("displaced-fault", [f"mesh.file={path}", f"parameters.dp={dp!r}", *overrides])
    t0 = time.perf_counter()
    problem, st, setup, _, _ = solve_static(case)
    secs = time.perf_counter() - t0
    fm = problem.fm
    net, g = fm.network, fm.mesh.geometry
    th = np.radians(DIP)
    n_ref = np.array([np.sin(th), 0.0, -np.cos(th)])
    e = np.array([np.cos(th), 0.0, np.sin(th)])
    ly = H / (8 * 2 ** k)
    xc = g.face_centroid[net.faces]
    area = g.face_area[net.faces]
    ym = xc[:, 2] + DEPTH
    dy = area / ly * np.sin(th)                       # faces are parallelograms spanning the strike
    y1, y2 = ym - dy / 2, ym + dy / 2
    assert np.isclose(dy.sum(), 2 * half, rtol=1e-9), dy.sum()
    sgn = np.sign(problem.normal @ n_ref)
    lam = st.lam
    ln = np.einsum("fi,fi->f", lam, problem.normal)
    dln = ln - (-(n_ref @ SIGMA0 @ n_ref))
    dtau = -sgn * (lam @ e) - (e @ SIGMA0 @ n_ref)
    o = np.argsort(ym)
    fmean = FAULT.fault_face_means(y1[o], y2[o], dp, ALPHA, NU)
    rn, rt = fmean["sigma_n_eff"], fmean["tau"]
    # the reference averaged over each multiplier's support (its patch; the face itself without patches)
    fp = problem.patches.face_patch[o]
    A = area[o]
    wsum = np.bincount(fp, A)
    pn, pt = np.bincount(fp, A * rn) / wsum, np.bincount(fp, A * rt) / wsum
    return {"face_patch": fp, "sn_ref_face": rn, "tau_ref_face": rt, "band": band,
            "level": k, "h": S0 / 2 ** k, "half": half, "dp": dp, "seconds": secs,
            "cells": fm.mesh.n_cells, "faces": int(net.n_faces), "patches": int(problem.patches.n),
            "newton": st.newton_iterations, "states": np.bincount(st.state, minlength=3).tolist(),
            "y1": y1[o], "y2": y2[o], "area": area[o], "sn": dln[o], "tau": dtau[o], "sn_ref": pn[fp], "tau_ref": pt[fp]}


def metrics(r: dict) -> dict:
    h = r["h"]
    y1, y2, A = r["y1"], r["y2"], r["area"]
    corners = FAULT.corners_y
    keep = np.ones(y1.size, bool)
    for yk in corners:
        keep &= (y2 <= yk - 2 * h + 1e-9) | (y1 >= yk + 2 * h - 1e-9)
    C = abs(scaling_factor(r["dp"], ALPHA, NU))
    out = {"level": r["level"], "h": h, "faces": r["faces"], "kept": int(keep.sum()), "C": C}
    for q in ("sn", "tau"):
        v, ref = r[q], r[q + "_ref"]
        err = np.abs(v - ref)
        i = np.argmax(np.where(keep, err, -1))
        out[q] = {
            "linf": float(err[keep].max() / np.abs(ref[keep]).max()),
            "linf_allpeak": float(err[keep].max() / np.abs(ref).max()),
            "linf_over_C": float(err[keep].max() / C),
            "linf_at_y": float(0.5 * (y1[i] + y2[i])),
            "peak_ref_kept": float(np.abs(ref[keep]).max() / C),
            "l2": float(np.sqrt(np.sum(A * (v - ref) ** 2) / np.sum(A * ref ** 2))),
            "l2_outside": float(np.sqrt(np.sum((A * (v - ref) ** 2)[keep]) / np.sum((A * ref ** 2)[keep]))),
            "l2_vs_face_means": float(np.sqrt(np.sum(A * (v - r[q + "_ref_face"]) ** 2) / np.sum(A * ref ** 2))),
            "linf_vs_face_means": float(np.abs(v - r[q + "_ref_face"])[keep].max() / np.abs(ref[keep]).max()),
            "peaks": []}
        for dist in (25.0, 50.0):
            far = np.ones(y1.size, bool)
            for yk in corners:
                far &= (y2 <= yk - dist + 1e-9) | (y1 >= yk + dist - 1e-9)
            out[q][f"linf_{int(dist)}m"] = float(err[far].max() / np.abs(ref[far]).max())
            out[q][f"linf_{int(dist)}m_over_C"] = float(err[far].max() / C)
        # error on the j-th face from each corner (j = 0, 1, 2, 3 on each side), / |C|: a log
        # singularity makes it a function of j only under uniform refinement
        rows = {}
        for yk in corners:
            for side, dist in (("below", yk - y2), ("above", y1 - yk)):
                idx = np.flatnonzero(dist >= -1e-9)
                idx = idx[np.argsort(dist[idx])][:4]
                rows[f"{yk:g} {side}"] = [[float(dist[i] / h), float((v[i] - ref[i]) / C)] for i in idx]
        out[q]["near_corner"] = rows
        rf = r[q + "_ref_face"]
        for yk in corners:
            # the face touching the corner with the larger |reference face mean|
            touch = np.flatnonzero((np.abs(y1 - yk) < 1e-6) | (np.abs(y2 - yk) < 1e-6))
            j = touch[np.argmax(np.abs(rf[touch]))]
            out[q]["peaks"].append({"corner": float(yk), "face": [float(y1[j]), float(y2[j])],
                                    "num_over_C": float(v[j] / C), "ref_face_over_C": float(rf[j] / C),
                                    "ref_support_over_C": float(ref[j] / C), "ratio": float(v[j] / rf[j])})
    return out


def _short(v: np.ndarray) -> list:
    """Per-face arrays for the JSON: 7 significant digits."""
    return [float(f"{x:.7g}") for x in v.tolist()] if v.dtype.kind == "f" else v.tolist()


def rate(hs, errs):
    hs, errs = np.asarray(hs), np.asarray(errs)
    if len(hs) < 2:
        return None
    return float(np.polyfit(np.log(hs), np.log(errs), 1)[0])


def profile_plot(path, runs, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    C = abs(scaling_factor(runs[0]["dp"], ALPHA, NU))
    y = np.linspace(-400, 400, 4001)
    y = y[np.min(np.abs(y[:, None] - FAULT.corners_y[None]), 1) > 0.05]
    rs = FAULT.fault_stress_changes(y, runs[0]["dp"], ALPHA, NU)
    fig, axes = plt.subplots(1, 2, figsize=(12, 6), sharey=True)
    for ax, q, rq, lab in ((axes[0], "sn", "sigma_n_eff", "Δλ_n vs Δσ'_n"), (axes[1], "tau", "tau", "Δτ")):
        ax.plot(rs[rq] / C, y, "k-", lw=0.8, label="reference (point values)")
        for r, col in zip(runs, ["C0", "C1", "C2", "C3", "C4"]):
            m = (r["y2"] > -400) & (r["y1"] < 400)
            yy = np.stack([r["y1"][m], r["y2"][m]], 1).ravel()
            ax.plot(np.repeat(r[q][m] / C, 2), yy, "-", color=col, lw=1.0, label=f"h = {r['h']:g} m")
            ax.plot(np.repeat(r[q + "_ref"][m] / C, 2), yy, ":", color=col, lw=1.0)
        for yk in FAULT.corners_y:
            ax.axhline(yk, color="0.7", lw=0.5)
        ax.set_xlim(-12, 12)
        ax.set_xlabel(f"{lab} / |C|  (dotted: reference face means)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("elevation y along the fault (m)")
    axes[1].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def convergence_plot(path, table):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 9), sharex=True)
    cols = ["C0", "C1", "C2", "C3", "C4", "C5"]
    for j, (q, lab) in enumerate((("sn", "Δλ_n vs Δσ'_n"), ("tau", "Δτ"))):
        for (name, rows), col in zip(table.items(), cols):
            hs = [m["h"] for m in rows]
            axes[0, j].loglog(hs, [m[q]["linf"] for m in rows], "o-", color=col, label=f"{name}: outside 2 cells")
            axes[0, j].loglog(hs, [m[q]["linf_25m"] for m in rows], "^:", color=col, label=f"{name}: outside 25 m")
            axes[1, j].loglog(hs, [m[q]["l2"] for m in rows], "s--", color=col, label=name)
        axes[0, j].axhline(0.02, color="k", lw=0.6, ls=":")
        axes[0, j].set_title(f"{lab}: L∞ / largest |ref| over the same faces")
        axes[1, j].set_title(f"{lab}: L2 over the whole fault (relative)")
        for ax in axes[:, j]:
            ax.grid(alpha=0.3, which="both")
        axes[1, j].set_xlabel("reservoir layer h (m)")
    axes[0, 0].legend(fontsize=7)
    axes[1, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown_tables(result: dict) -> str:
    """The per-variant tables of docs/displaced_fault_study.md (errors in %) from a study's result."""
    out = []
    for name, v in result["variants"].items():
        out += [f"**{name}** ({' '.join(v['overrides']) or 'defaults'}; mesh {'aligned' if v['band'] else 'graded'})",
                "", "| h (m) | faces | Δλ_n L∞ 2 cells | L∞ 25 m | L∞ 50 m | L2 | Δτ L∞ 2 cells | L∞ 25 m | L∞ 50 m | L2 |"
                " L∞ 2 cells / \\|C\\| (Δλ_n, Δτ) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        for m in v["levels"]:
            out.append(f"| {m['h']:g} | {m['faces']} | " + " | ".join(
                f"{100 * m[q]['linf']:.2f} % | {100 * m[q]['linf_25m']:.2f} % | {100 * m[q]['linf_50m']:.2f} % | "
                f"{100 * m[q]['l2']:.1f} %" for q in ("sn", "tau"))
                + f" | {m['sn']['linf_over_C']:.3f}, {m['tau']['linf_over_C']:.3f} |")
        r = v["rates"]
        out.append("| rate | | " + " | ".join(f"{r[q]['linf']:.2f} | {r[q]['linf_25m']:.2f} | {r[q]['linf_50m']:.2f} | "
                                              f"{r[q]['l2']:.2f}" for q in ("sn", "tau")) + " | |")
        out.append("")
    return "\n".join(out)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2, 3])
    p.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    p.add_argument("--variant-levels", type=int, nargs="+", default=None,
                   help="levels for the non-default variants (default: --levels)")
    p.add_argument("--domain-level", type=int, default=1)
    p.add_argument("--domain-halves", type=float, nargs="+", default=[2000.0, 4000.0, 8000.0])
    p.add_argument("--injection-level", type=int, default=2)
    p.add_argument("--out", default="docs")
    p.add_argument("--stem", default="displaced_fault_study",
                   help="name of the output files (docs/displaced_fault_scale: the stabilisation-scale study)")
    p.add_argument("--tables-only", action="store_true",
                   help="only write <out>/displaced_fault_study_tables.md from <out>/displaced_fault_study.json")
    a = p.parse_args(argv)
    out = Path(a.out)
    if a.tables_only:
        result = json.loads((out / f"{a.stem}.json").read_text())
        (out / f"{a.stem}_tables.md").write_text(markdown_tables(result))
        print(f"wrote {out}/{a.stem}_tables.md")
        return
    result = {"setup": {"thickness": H, "throw": THROW, "dip": DIP, "s0": S0, "ratio": RATIO, "core": CORE,
                        "corners_y": FAULT.corners_y.tolist(), "C": abs(scaling_factor(-1e7, ALPHA, NU))},
              "variants": {}, "runs": {}}
    table = {}
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        for name in a.variants:
            levels = a.levels if (name == "default" or a.variant_levels is None) else a.variant_levels
            runs, rows = [], []
            for k in levels:
                r = run_level(k, VARIANTS[name][0], band=VARIANTS[name][1], tmp=tmp)
                m = metrics(r)
                runs.append(r)
                rows.append(m)
                print(f"[{name}] level {k} h={r['h']:g} m: {r['cells']} cells, {r['faces']} faces, {r['patches']} "
                      f"patches, states {r['states']}, {r['seconds']:.1f} s; Δσ'_n L∞ {m['sn']['linf']:.4f} "
                      f"L2 {m['sn']['l2']:.4f}; Δτ L∞ {m['tau']['linf']:.4f} L2 {m['tau']['l2']:.4f}", flush=True)
            hs = [m["h"] for m in rows]
            rates = {q: {k2: rate(hs, [m[q][k2] for m in rows]) for k2 in ("linf", "linf_25m", "linf_50m", "l2",
                                                                            "l2_outside")}
                     for q in ("sn", "tau")}
            table[name] = rows
            result["variants"][name] = {"overrides": VARIANTS[name][0], "band": VARIANTS[name][1], "levels": rows,
                                        "rates": rates}
            result["runs"][name] = [{k2: (_short(v) if isinstance(v, np.ndarray) else v) for k2, v in r.items()}
                                    for r in runs]
            profile_plot(out / f"{a.stem}_{name}.png", runs,
                         f"displaced fault, {name}: face values (solid) vs reference face means (dotted)")
        convergence_plot(out / f"{a.stem}_convergence.png", table)

        # domain effect: same cells near the fault, bigger slab
        dom = []
        if a.domain_level >= 0:
            for half in a.domain_halves:
                r = run_level(a.domain_level, [], half=half, tmp=tmp)
                dom.append(r)
                m = metrics(r)
                print(f"[domain ±{half:g} m] level {a.domain_level}: {r['cells']} cells; Δσ'_n L∞ {m['sn']['linf']:.4f} "
                      f"L2 {m['sn']['l2']:.4f}; Δτ L∞ {m['tau']['linf']:.4f} L2 {m['tau']['l2']:.4f}", flush=True)
            big = dom[-1]
            rows = []
            for r in dom:
                m = metrics(r)
                # face-by-face against the biggest slab, faces within ±1500 m (the same cells)
                sel = (r["y1"] > -1500) & (r["y2"] < 1500)
                selb = (big["y1"] > -1500) & (big["y2"] < 1500)
                assert np.allclose(r["y1"][sel], big["y1"][selb]), "the near-fault faces differ"
                row = {"half": r["half"], "cells": r["cells"], "metrics": m}
                C = m["C"]
                for q in ("sn", "tau"):
                    d = np.abs(r[q][sel] - big[q][selb])
                    row[q + "_vs_biggest_over_C"] = float(d.max() / C)
                    row[q + "_vs_biggest_rel_peak_kept"] = float(d.max() / (m[q]["peak_ref_kept"] * C))
                    row[q + "_vs_biggest_at_y"] = float(0.5 * (r["y1"][sel] + r["y2"][sel])[np.argmax(d)])
                rows.append(row)
                print(f"  ±{r['half']:g} m vs ±{big['half']:g} m: max |Δ| Δλ_n {row['sn_vs_biggest_over_C']:.4f} |C| "
                      f"({row['sn_vs_biggest_rel_peak_kept']:.4f} of peak), Δτ {row['tau_vs_biggest_over_C']:.4f} |C| "
                      f"({row['tau_vs_biggest_rel_peak_kept']:.4f} of peak)", flush=True)
            result["domain"] = {"level": a.domain_level, "rows": rows}

        if a.injection_level >= 0:
            r = run_level(a.injection_level, [], dp=1e7, tmp=tmp)
            m = metrics(r)
            ref_dep = next((x for x in table.get("default", []) if x["level"] == a.injection_level), None)
            print(f"[injection] level {a.injection_level}: states {r['states']}; Δσ'_n L∞ {m['sn']['linf']:.4f} L2 "
                  f"{m['sn']['l2']:.4f}; Δτ L∞ {m['tau']['linf']:.4f} L2 {m['tau']['l2']:.4f}", flush=True)
            result["injection"] = {"level": a.injection_level, "states": r["states"], "metrics": m,
                                   "depletion_metrics": ref_dep}
            profile_plot(out / f"{a.stem}_injection.png", [r],
                         f"displaced fault, injection Δp = +10 MPa, h = {r['h']:g} m")

    # summary tables
    for name, v in result["variants"].items():
        print(f"\n{name} ({' '.join(v['overrides']) or 'defaults'}, band {v['band']})")
        print(" h (m) | faces | Δσ'_n L∞ 2 cells | 25 m | 50 m | L2 | Δτ L∞ 2 cells | 25 m | 50 m | L2 |"
              " L∞ 2 cells / |C|: Δσ'_n, Δτ")
        for m in v["levels"]:
            print(f" {m['h']:6.3f} | {m['faces']:5d} | " + " | ".join(
                f"{m[q]['linf']:.4f} | {m[q]['linf_25m']:.4f} | {m[q]['linf_50m']:.4f} | {m[q]['l2']:.4f}"
                for q in ("sn", "tau")) + f" | {m['sn']['linf_over_C']:.3f}, {m['tau']['linf_over_C']:.3f}")
        print(" rates:", json.dumps(v["rates"]))
        print(" corner faces, num / ref face mean (/|C|), corners y = -125 (a), 75 (b), -75 (c), 125 (d):")
        for m in v["levels"]:
            print(f"  h={m['h']:g}: Δσ'_n " + " ".join(f"{pk['num_over_C']:+.2f}/{pk['ref_face_over_C']:+.2f}"
                                                    for pk in m["sn"]["peaks"])
                  + " | Δτ " + " ".join(f"{pk['num_over_C']:+.2f}/{pk['ref_face_over_C']:+.2f}" for pk in m["tau"]["peaks"]))
    (out / f"{a.stem}.json").write_text(json.dumps(result, indent=1))
    (out / f"{a.stem}_tables.md").write_text(markdown_tables(result))
    print(f"wrote {out}/displaced_fault_study.json, displaced_fault_study_tables.md and PNGs")


if __name__ == "__main__":
    main()
