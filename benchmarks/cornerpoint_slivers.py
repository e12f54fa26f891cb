"""Benchmark: sliver fault faces of a corner-point grid and what snapping does to them (issue 15).

    .venv/bin/python benchmarks/cornerpoint_slivers.py geometry [--snap 0 0.05 0.1 0.2 0.3] [--grid FILE]
    .venv/bin/python benchmarks/cornerpoint_slivers.py run [--snap 0 0.2] [--out DIR] [--linear auto]
    .venv/bin/python benchmarks/cornerpoint_slivers.py table DIR [DIR ...] [--bins]

``geometry``: per fault of the grid (default: the Emerald grid of the built-in case, processed as
the case does, ``nonplanar="keep"``) and per ``snap`` of ``process_grid``: faces, nodes snapped,
histograms of the face areas relative to the fault's median face area and of the aspect ratio
d²/|σ| (d the face diameter), the smallest face, the total fault area (the surface kept).

``run``: runs the built-in case ``emerald-injection`` once per ``snap`` into ``DIR/snap_<value>``
(``polypore run``; the case file has no key for ``snap``, so the script sets the default of
``process_grid``'s keyword for the run) and prints the table of ``table``.

``table``: for finished runs (folders with fractures.csv and summary.json), per contact fault:
faces, smallest face / median, max λ_n on day 1 and at the end, faces whose λ_n changed by more
than its in-situ value, open faces (under 10–15 MPa of compression and ≤ 0.7 MPa of overpressure
none can open: every open face is spurious), slipping faces, first slipping face and onset (1%
of the area slipping), slipping area and max slip at the end, Newton iterations per step. With
``--bins`` (run folders of the Emerald case; the ``snap`` of a run is read from its
``snap.json``, written by ``run``, else the default): faces that are not stuck on day 1 / at the end,
and faces with a λ_n outlier, by bins of area / median and of thickness |σ|/d over the thinner
cell's height (the faces matched to the mesh by their centroids).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

from polypore.mesh.cornerpoint import process_grid, read_grdecl
from polypore.mesh.cornerpoint import process as _process

EMERALD = Path(__file__).resolve().parents[1] / "src" / "polypore" / "cases" / "data" / "emerald.grdecl"
AREA_BINS = [0.0, 1e-3, 1e-2, 3e-2, 1e-1, 0.3, 1.0, np.inf]
ASPECT_BINS = [1.0, 10.0, 30.0, 100.0, 300.0, np.inf]
THICK_BINS = [0.0, 1e-2, 3e-2, 0.1, 0.3, np.inf]


def _hist(x, bins):
    return np.histogram(x, bins=bins)[0].tolist()


def _label(bins):
    return ", ".join(f"[{a:g}, {b:g})" for a, b in zip(bins[:-1], bins[1:]))


def geometry(grid_file: Path, snaps, nonplanar="keep") -> dict:
    grid = read_grdecl(grid_file)
    out = {}
    print(f"{grid_file.name}: area / median in {_label(AREA_BINS)}; d²/|σ| in {_label(ASPECT_BINS)}")
    for s in snaps:
        mesh, info = process_grid(grid, nonplanar=nonplanar, snap=s)
        A, D = mesh.geometry.face_area, mesh.geometry.face_diameter
        rows = {}
        for name, f in info.faults.items():
            a, med = A[f], float(np.median(A[f]))
            rows[name] = {"faces": int(f.size), "median_m2": med, "min_m2": float(a.min()),
                          "min_over_median": float(a.min() / med), "area_m2": float(a.sum()),
                          "area_hist": _hist(a / med, AREA_BINS), "aspect_hist": _hist(D[f] ** 2 / a, ASPECT_BINS)}
        out[str(s)] = {"snapped_nodes": info.n_snapped, "volume_m3": float(mesh.volume), "faults": rows}
        print(f"snap {s}: {info.n_snapped} nodes snapped, total volume {mesh.volume:.6e} m³")
        for name, r in rows.items():
            print(f"  {name}: {r['faces']} faces, median {r['median_m2']:.1f} m², smallest {r['min_m2']:.3g} m² "
                  f"({r['min_over_median']:.1e} of the median), fault area {r['area_m2']:.4e} m²; "
                  f"area/median {r['area_hist']}; d²/|σ| {r['aspect_hist']}")
    return out


def _load(folder: Path) -> dict:
    rows = list(csv.DictReader(open(folder / "fractures.csv")))
    steps = sorted({int(r["step"]) for r in rows})
    by = {s: [r for r in rows if int(r["step"]) == s] for s in steps}
    f0 = by[steps[0]]
    d = {"fracture": np.array([r["fracture"] for r in f0]), "area": np.array([float(r["area"]) for r in f0]),
         "x": np.array([[float(r[k]) for k in "xyz"] for r in f0])}
    for k in ("lambda_n", "jump_t"):
        d[k] = np.array([[float(r[k]) for r in by[s]] for s in steps])
    d["state"] = np.array([[r["state"] for r in by[s]] for s in steps])
    d["summary"] = json.loads((folder / "summary.json").read_text())
    return d


def table(folders, bins: bool = False) -> list:
    print("| run | fault | faces | smallest face / median | max λ_n day 1 / end (MPa) | λ_n at the end: 1st–99th "
          "percentile (MPa) | faces with \\|Δλ_n\\| > λ_n⁰ at the end | open day 1 / end | slipping day 1 / end | "
          "first slipping face / 1% of the area (day) | slipping area at the end | max slip at the end (mm) | "
          "Newton per step (total) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    out = []
    for folder in map(Path, folders):
        d = _load(folder)
        newton = [s["newton_iterations"] for s in d["summary"]["steps"]]
        for fr in dict.fromkeys(d["fracture"]):
            m = d["fracture"] == fr
            a = d["area"][m]
            ln, st = d["lambda_n"][:, m], d["state"][:, m]
            slip = np.abs(d["jump_t"][:, m] - d["jump_t"][0, m])
            first = next((k for k in range(1, len(st)) if (st[k] == "slip").any()), None)
            onset = next((k for k in range(1, len(st)) if a[st[k] == "slip"].sum() >= 0.01 * a.sum()), None)
            row = {"run": folder.name, "fault": fr, "faces": int(m.sum()),
                   "min_over_median": float(a.min() / np.median(a)),
                   "max_ln_day1": float(ln[1].max()), "max_ln_end": float(ln[-1].max()),
                   "ln_p1_end": float(np.percentile(ln[-1], 1)), "ln_p99_end": float(np.percentile(ln[-1], 99)),
                   "outliers_end": int((np.abs(ln[-1] - ln[0]) > np.abs(ln[0])).sum()),
                   "open": [int((st[1] == "open").sum()), int((st[-1] == "open").sum())],
                   "slip": [int((st[1] == "slip").sum()), int((st[-1] == "slip").sum())],
                   "first_slip_step": first, "onset_step": onset,
                   "slip_area_end": float(a[st[-1] == "slip"].sum() / a.sum()), "max_slip_end_m": float(slip[-1].max()),
                   "newton": newton}
            out.append(row)
            print(f"| {row['run']} | {fr} | {row['faces']} | {row['min_over_median']:.1e} | "
                  f"{row['max_ln_day1'] / 1e6:.3g} / {row['max_ln_end'] / 1e6:.3g} | "
                  f"{row['ln_p1_end'] / 1e6:.3g}–{row['ln_p99_end'] / 1e6:.3g} | {row['outliers_end']} | "
                  f"{row['open'][0]} / {row['open'][1]} | {row['slip'][0]} / {row['slip'][1]} | {first} / {onset} | "
                  f"{100 * row['slip_area_end']:.1f}% | {1e3 * row['max_slip_end_m']:.2f} | "
                  f"{', '.join(map(str, newton))} ({sum(newton)}) |")
    if bins:
        for folder in map(Path, folders):
            _bins(folder)
    return out


def _bins(folder: Path):
    """Misbehaving faces of a run of emerald-injection by area and thickness bins."""
    from scipy.spatial import cKDTree

    d = _load(folder)
    marker = folder / "snap.json"              # written by ``run``; else the run used the default
    snap = json.loads(marker.read_text())["snap"] if marker.is_file() else _process.process_grid.__kwdefaults__["snap"]
    mesh, info = process_grid(read_grdecl(EMERALD), nonplanar="keep", snap=snap)
    g = mesh.geometry
    dist, face = cKDTree(g.face_centroid).query(d["x"])
    if dist.max() > 1e-3:
        raise SystemExit(f"{folder}: the run's faces do not match the mesh processed with snap={snap}")
    A, D = g.face_area[face], g.face_diameter[face]
    X = mesh.nodes
    height = np.array([np.ptp(X[mesh.cell_nodes.row(c), 2]) for c in range(mesh.n_cells)])
    h = height[mesh.face_cells[face]].min(axis=1)
    st, ln = d["state"], d["lambda_n"]
    bad1, badn = st[1] != "stick", st[-1] != "stick"
    out = np.abs(ln[-1] - ln[0]) > np.abs(ln[0])
    print(f"\n{folder.name} (snap {snap}): faces not stuck on day 1 / at the end, faces with |Δλ_n| > λ_n⁰ "
          "at the end")
    for fr in dict.fromkeys(d["fracture"]):
        m = d["fracture"] == fr
        r = A / np.median(A[m])
        t = (A / D) / h
        for label, x, bins in (("area / median", r, AREA_BINS), ("(|σ|/d) / h", t, THICK_BINS)):
            print(f"  {fr}, {label}:")
            for lo, hi in zip(bins[:-1], bins[1:]):
                b = m & (x >= lo) & (x < hi)
                if b.any():
                    print(f"    [{lo:g}, {hi:g}): {b.sum()} faces, {(b & bad1).sum()} / {(b & badn).sum()} not stuck, "
                          f"{(b & out).sum()} outliers")


def run(snaps, out: Path, linear: str) -> list:
    from polypore.cli import main as polypore

    folders = []
    default = _process.process_grid.__kwdefaults__["snap"]
    for s in snaps:
        folder = out / f"snap_{s:g}"
        _process.process_grid.__kwdefaults__["snap"] = float(s)
        try:
            args = ["run", "emerald-injection", "--out", str(folder), "--force", "--set", f"solver.linear={linear}"]
            print(f"snap = {s:g}: polypore " + " ".join(args))
            if polypore(args) != 0:
                raise SystemExit(f"the run with snap = {s:g} failed")
        finally:
            _process.process_grid.__kwdefaults__["snap"] = default
        (folder / "snap.json").write_text(json.dumps({"snap": float(s)}))
        folders.append(folder)
    return folders


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("geometry")
    g.add_argument("--snap", nargs="+", type=float, default=[0.0, 0.05, 0.1, 0.2, 0.3])
    g.add_argument("--grid", default=str(EMERALD))
    g.add_argument("--json", default=None)
    r = sub.add_parser("run")
    r.add_argument("--snap", nargs="+", type=float, default=[0.0, 0.2])
    r.add_argument("--out", default="results/cornerpoint-slivers")
    r.add_argument("--linear", default="auto")
    r.add_argument("--bins", action="store_true")
    t = sub.add_parser("table")
    t.add_argument("folders", nargs="+")
    t.add_argument("--bins", action="store_true")
    a = ap.parse_args(argv)
    if a.cmd == "geometry":
        res = geometry(Path(a.grid), a.snap)
        if a.json:
            Path(a.json).write_text(json.dumps(res, indent=1))
    elif a.cmd == "run":
        table(run(a.snap, Path(a.out), a.linear), a.bins)
    else:
        table(a.folders, a.bins)
    return 0


if __name__ == "__main__":
    sys.exit(main())
