"""Fault tractions of finished poromechanics runs against the poroelastic bound (issue 24).

    python benchmarks/fault_bounds.py RUN_DIR [RUN_DIR ...] [--json OUT]

For every run folder (summary.json, fractures.csv, case.toml of ``polypore run``):

- the largest |λ_n(t) − λ_n(0)| over fault faces and output times, divided by the run's largest
  overpressure (summary.json ``monitor.max_overpressure``), with the face, its area and its
  λ_n(0) → λ_n(t), and the number of face-steps above 3× (docs/contact_patches.md states the
  bound and why 3);
- the faces that slip at some output although their fracture pressure changed by less than
  0.2 MPa and their initial |λ_τ|/λ_n is below 0.9 × their friction ("far, unpressurised
  faces slipping": no stress path produces them);
- the slipping area fraction of each fault over time (faces in the slip state at that output),
  the slipped area fraction (faces whose slip since the start exceeds ``SLIPPED`` = 0.1 mm: the
  measure that converges with the time step, docs/fault_bounds.md "The time step") and its
  largest slip.

With ``--refinement COARSE FINE`` (a run and the same case on its refined grid) it also compares
each fault's slip at every common output time: the largest slip of each run, the fine run's slip
averaged by area onto the coarse faces (every fine face to the coarse face of its fault with the
nearest centroid: the same quantity at the coarse resolution), and the potency ∫ slip dA.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

MPA = 1e6
SLIPPED = 1e-4          # m: a face has slipped once its slip since the start exceeds this


def read_csv(path: Path) -> dict:
    """fractures.csv -> arrays (n_out, n_ff) of the columns used here."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    step = np.array([int(r["step"]) for r in rows])
    k = np.unique(step).size
    n = len(rows) // k
    col = lambda key: np.array([float(r[key]) if r[key] != "" else np.nan for r in rows]).reshape(k, n)  # noqa: E731
    xyz = {k: col(k)[0] for k in ("x", "y", "z") if k in rows[0]} if rows else {}
    return {**xyz, "time": col("time")[:, 0], "fracture": np.array([r["fracture"] for r in rows[:n]]),
            "face": col("face")[0].astype(int), "area": col("area")[0], "lambda_n": col("lambda_n"),
            "lambda_t": col("lambda_t"), "state": np.array([r["state"] for r in rows]).reshape(k, n),
            "p_f": col("p_f"), "jump_t": col("jump_t")}


def frictions(folder: Path, names) -> np.ndarray:
    """(n_ff,) friction of every face's fracture from the run's case.toml (constant values)."""
    import tomllib

    case = tomllib.loads((folder / "case.toml").read_text())
    default = case.get("contact", {}).get("friction", np.nan)
    per = {f["name"]: f.get("friction", default) for f in case.get("fractures", [])}
    return np.array([float(per.get(n, default)) for n in names])


def analyse(folder: Path) -> dict:
    folder = Path(folder)
    s = json.loads((folder / "summary.json").read_text())
    d = read_csv(folder / "fractures.csv")
    op = float(np.max(s["monitor"]["max_overpressure"]))
    dl = np.abs(d["lambda_n"] - d["lambda_n"][0])
    ratio = dl / max(op, 1e-300)
    k, f = np.unravel_index(np.argmax(ratio), ratio.shape)
    F = frictions(folder, d["fracture"])
    ln0, lt0 = d["lambda_n"][0], d["lambda_t"][0]
    r0 = lt0 / np.maximum(ln0, 1e-300)
    dpf = np.max(np.abs(d["p_f"] - d["p_f"][0]), axis=0)
    slipping = np.any(d["state"][1:] == "slip", axis=0)
    far = slipping & (dpf < 0.2 * MPA) & (r0 < 0.9 * F)
    faults = {}
    for name in np.unique(d["fracture"]):
        on = d["fracture"] == name
        a = d["area"][on]
        frac = [float(np.sum(a[d["state"][i, on] == "slip"]) / a.sum()) for i in range(len(d["time"]))]
        onset = next((float(d["time"][i]) for i, v in enumerate(frac) if v > 0), None)
        moved = (d["jump_t"][:, on] - d["jump_t"][0, on]) > SLIPPED
        slipped = [float(np.sum(a[moved[i]]) / a.sum()) for i in range(len(d["time"]))]
        faults[str(name)] = {"faces": int(on.sum()), "slip_fraction": frac, "onset_s": onset,
                             "slipped_fraction": slipped,
                             "max_slip_m": float(np.nanmax(d["jump_t"][:, on] - d["jump_t"][0, on]))}
    return {"run": str(folder), "unknowns": s["mesh"].get("unknowns"), "max_overpressure_MPa": op / MPA,
            "largest_ratio": float(ratio[k, f]),
            "largest_at": {"fracture": str(d["fracture"][f]), "face": int(d["face"][f]), "area_m2": float(d["area"][f]),
                           "lambda_n0_MPa": float(d["lambda_n"][0, f] / MPA),
                           "lambda_n_MPa": float(d["lambda_n"][k, f] / MPA), "time_s": float(d["time"][k])},
            "face_steps_above_3x": int(np.sum(ratio > 3)), "far_unpressurised_slipping": int(far.sum()),
            "faces": int(dl.shape[1]), "times_s": d["time"].tolist(), "faults": faults,
            "multiplier_patches": s["mesh"].get("multiplier_patches")}


def refinement(coarse: Path, fine: Path) -> dict:
    """Per fault: lists over the common output times of the coarse and fine largest slip (m), the
    largest of the fine slip averaged onto the coarse faces (m), and both potencies (m³)."""
    from scipy.spatial import cKDTree

    c, f = read_csv(Path(coarse) / "fractures.csv"), read_csv(Path(fine) / "fractures.csv")
    if "x" not in c or "x" not in f:
        raise SystemExit("--refinement needs the face centroids (x, y, z) in fractures.csv")
    out = {}
    for name in np.unique(c["fracture"]):
        mc, mf = c["fracture"] == name, f["fracture"] == name
        if not mf.any():
            continue
        xc = np.c_[c["x"][mc], c["y"][mc], c["z"][mc]]
        owner = cKDTree(xc).query(np.c_[f["x"][mf], f["y"][mf], f["z"][mf]])[1]
        ac, af = c["area"][mc], f["area"][mf]
        covered = np.bincount(owner, af, mc.sum())
        r = {k: [] for k in ("time_s", "max_slip_coarse", "max_slip_fine", "max_slip_fine_on_coarse",
                              "potency_coarse", "potency_fine")}
        for i, t in enumerate(c["time"]):
            j = np.flatnonzero(np.isclose(f["time"], t, rtol=0, atol=1.0))
            if not j.size:
                continue
            sc = np.abs(c["jump_t"][i, mc] - c["jump_t"][0, mc])
            sf = np.abs(f["jump_t"][j[0], mf] - f["jump_t"][0, mf])
            on = np.bincount(owner, af * sf, mc.sum()) / np.maximum(covered, 1e-300)
            for k, v in (("time_s", t), ("max_slip_coarse", sc.max()), ("max_slip_fine", sf.max()),
                         ("max_slip_fine_on_coarse", on[covered > 0].max(initial=0.0)),
                         ("potency_coarse", np.sum(ac * sc)), ("potency_fine", np.sum(af * sf))):
                r[k].append(float(v))
        out[str(name)] = r
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--refinement", action="store_true", help="two runs: a grid and its refinement; compare slip")
    args = ap.parse_args(argv)
    if args.refinement and len(args.runs) != 2:
        ap.error("--refinement takes exactly two runs: the grid's and its refinement's")
    out = [analyse(r) for r in args.runs]
    for r in out:
        w = r["largest_at"]
        print(f"{r['run']}: unknowns {r['unknowns']}, max overpressure {r['max_overpressure_MPa']:.2f} MPa; largest "
              f"|Δλ_n|/overpressure {r['largest_ratio']:.2f} ({w['fracture']} face {w['face']}, {w['area_m2']:.3g} m², "
              f"{w['lambda_n0_MPa']:.2f} -> {w['lambda_n_MPa']:.2f} MPa); face-steps above 3x: "
              f"{r['face_steps_above_3x']}; far unpressurised faces slipping: {r['far_unpressurised_slipping']} "
              f"of {r['faces']}")
        for name, fd in r["faults"].items():
            print(f"    {name}: {fd['faces']} faces, slipping fraction at the end {fd['slip_fraction'][-1]:.3f}, "
                  f"slipped (> {1e3 * SLIPPED:g} mm) {fd['slipped_fraction'][-1]:.3f}, onset {fd['onset_s']}, "
                  f"largest slip {fd['max_slip_m']:.3e} m")
    if args.refinement:
        ref = refinement(*args.runs)
        for name, r in ref.items():
            print(f"{name}: day, largest slip coarse / fine / fine averaged on the coarse faces (mm), potency (m³)")
            for i, t in enumerate(r["time_s"]):
                a, b, m = r["max_slip_coarse"][i], r["max_slip_fine"][i], r["max_slip_fine_on_coarse"][i]
                rel = f"{100 * (m / a - 1):+.1f} %" if a > 1e-6 else "-"
                print(f"    {t / 86400:6.2f}: {1e3 * a:8.3f} / {1e3 * b:8.3f} / {1e3 * m:8.3f} ({rel})   "
                      f"{r['potency_coarse'][i]:10.3f} / {r['potency_fine'][i]:10.3f}")
        out = {"runs": out, "refinement": ref}
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
