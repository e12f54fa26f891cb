"""C4 mesh self-convergence: (T⁺ − T⁻)/2 and the jump along F1–F3 at the final time against
the finest mesh (issue 5).

    .venv/bin/python benchmarks/c4_convergence.py [--levels 4] [--out docs/c4_convergence] [--set KEY=VALUE ...]

Level k uses mesh.size = 0.1/2^k and mesh.fracture_size = 0.04/2^k with C4's time step
(20 s, T = 2000 s). The finest level is the reference. Fracture quantities are compared as
profiles along each fracture's arc length s: the reference face values are averaged over each
coarse face's s-interval, and the relative L2 error is sqrt(Σ|σ| |q − q_ref|²)/sqrt(Σ|σ| |q_ref|²)
over F1–F3. (T⁺ − T⁻)/2 averages the one-sided tractions T^± = σ^T(K^±) n^± + p_f n^± of the
two cells of each face (the discrete T⁺ and −T⁻ differ); the multiplier λ = −T⁺ is reported
too. The error is plotted against the largest fracture face size, as on the slides. The same
errors are also given away from the fracture tips (faces within 10 % of the length from an end
left out), as for C3, and away from the tips and F1's kink (faces within 5 % of the length from
it left out too: the traction is singular at the kink, where most of λ's error sits; the share of each
error on those faces is reported as well).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

import numpy as np

from polypore.models.fracture_geometry import arc_length
from polypore.runs.convergence import fit_rate
from polypore.runs.march import march
from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh
from polypore.setup.poromechanics import poro_setup

FRACTURES = ("F1", "F2", "F3")


def solve_level(k: int, linear: str, overrides=()):
    case = load_case("dfm-2d", [f"mesh.size={0.1 / 2 ** k}", f"mesh.fracture_size={0.04 / 2 ** k}",
                                f"solver.linear={linear}", *overrides])
    fm = build_fractured_mesh(case)
    model, fs, _ = poro_setup(case, fm)
    st = model.initial_state(fs.initial_pressure)
    its = []

    def step(s, ta, tb):
        new, info = model.step(s, tb - ta, tb, energy=False)
        its.append(info.iterations)
        return new, {}

    st, _ = march(fs.schedule, st, step)
    fq = model.fracture_quantities(st)
    net = fm.network
    out = {"cells": fm.mesh.n_cells, "h_frac": float(fm.mesh.geometry.face_area[net.faces].max()),
           "newton_total": int(sum(its)), "profiles": {}}
    s = arc_length(fm)
    _, total = model.stresses(st)
    n = model.mech.normal
    # (T⁺ − T⁻)/2 with T^± = σ^T(K^±) n^± + p_f n^±: the two one-sided tractions averaged
    t_avg = 0.5 * np.einsum("fij,fj->fi", total[net.plus_cell] + total[net.minus_cell], n) + fq["p_f"][:, None] * n
    for name in FRACTURES:
        f = net.faces_of(name)
        V = np.asarray(net.specs[net.names.index(name)].vertices, float)
        kinks = np.cumsum(np.linalg.norm(np.diff(V, axis=0), axis=1))[:-1]   # arc length of interior vertices
        out["profiles"][name] = {"s": s[f], "area": model.mech.face_area[f], "traction": t_avg[f],
                                 "multiplier": st.lam[f], "jump": fq["jump"][f], "kinks": kinks}
    return out


def project(ref, s, area):
    """Average of the reference face values over the s-intervals of coarse faces (centres s, lengths area)."""
    lo, hi = s - area / 2, s + area / 2
    rs, ra = ref["s"], ref["area"]
    rlo, rhi = rs - ra / 2, rs + ra / 2
    out = {}
    for key in ("traction", "multiplier", "jump"):
        v = ref[key]
        acc = np.zeros((len(s), v.shape[1]))
        w = np.zeros(len(s))
        for j in range(len(rs)):             # 1D profiles with at most a few thousand faces
            ov = np.clip(np.minimum(hi, rhi[j]) - np.maximum(lo, rlo[j]), 0, None)
            acc += ov[:, None] * v[j]
            w += ov
        out[key] = acc / np.maximum(w, 1e-300)[:, None]
    return out


def main():
    logging.basicConfig(level=logging.WARNING)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--linear", default="auto")
    ap.add_argument("--out", default="docs/c4_convergence")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="extra case override for every level, e.g. mesh.mirror=tips")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = []
    for k in range(args.levels):
        t0 = time.perf_counter()
        r = solve_level(k, args.linear, args.set)
        r["seconds"] = time.perf_counter() - t0
        runs.append(r)
        print(f"level {k}: {r['cells']} cells, h_frac {r['h_frac']:.4g} m, {r['newton_total']} Newton iterations, "
              f"{r['seconds']:.0f} s", flush=True)
    ref = runs[-1]
    rows = []
    keys = ("traction", "multiplier", "jump")
    for k, r in enumerate(runs[:-1]):
        # "away": faces farther than 10 % of the fracture's length from both ends (the tips, as in C3);
        # "smooth": also farther than 5 % of the length from a kink (F1's), where the traction is singular too
        parts = ("all", "away", "smooth")
        num = {(key, part): 0.0 for key in keys for part in parts}
        at_kinks = {key: 0.0 for key in keys}   # squared error on the faces near a kink
        den = dict(num)
        for name in FRACTURES:
            p = r["profiles"][name]
            q = project(ref["profiles"][name], p["s"], p["area"])
            length = float(np.max(p["s"] + p["area"] / 2))
            away = (p["s"] > 0.1 * length) & (p["s"] < 0.9 * length)
            near_kink = np.zeros(len(p["s"]), bool)
            for sk in p["kinks"]:
                near_kink |= np.abs(p["s"] - sk) <= 0.05 * length
            smooth = away & ~near_kink
            for key in keys:
                e2 = p["area"] * np.sum((p[key] - q[key]) ** 2, axis=1)
                r2 = p["area"] * np.sum(q[key] ** 2, axis=1)
                at_kinks[key] += float(np.sum(e2[near_kink]))
                for part, m in (("all", slice(None)), ("away", away), ("smooth", smooth)):
                    num[key, part] += float(np.sum(e2[m]))
                    den[key, part] += float(np.sum(r2[m]))
        rows.append({"level": k, "cells": r["cells"], "h_frac": r["h_frac"], "newton_total": r["newton_total"],
                     "seconds": r["seconds"],
                     **{f"{key}_L2_rel": np.sqrt(num[key, "all"] / den[key, "all"]) for key in keys},
                     **{f"{key}_L2_rel_away_from_tips": np.sqrt(num[key, "away"] / den[key, "away"])
                        for key in keys},
                     **{f"{key}_L2_rel_away_from_tips_and_kinks": np.sqrt(num[key, "smooth"] / den[key, "smooth"])
                        for key in keys},
                     **{f"{key}_error_share_at_kinks": at_kinks[key] / num[key, "all"] for key in keys}})
    hs = [r["h_frac"] for r in rows]
    rates = {key: fit_rate(hs, [r[key] for r in rows]) for key in rows[0] if "_L2_rel" in key}
    result = {"overrides": args.set,
              "reference": {"cells": ref["cells"], "h_frac": ref["h_frac"], "seconds": ref["seconds"]},
              "levels": rows, "rates": rates}
    (out / "c4_convergence.json").write_text(json.dumps(result, indent=2))
    from polypore.io.plots import convergence_plot

    convergence_plot(out / "c4_convergence.png", hs, {"(T⁺−T⁻)/2": [r["traction_L2_rel"] for r in rows],
                                                      "λ": [r["multiplier_L2_rel"] for r in rows],
                                                      "[[u]]": [r["jump_L2_rel"] for r in rows]},
                     {"(T⁺−T⁻)/2": rates["traction_L2_rel"], "λ": rates["multiplier_L2_rel"],
                      "[[u]]": rates["jump_L2_rel"]},
                     title="C4: F1–F3 at T against the finest mesh")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
