"""Compare the Newton histories and contact states of two ``polypore run`` result folders (e.g. 1 and
2 MPI ranks; docs/parallel.md "Distributed runs").

    python benchmarks/mpi_compare.py results/c4-n1 results/c4-n2

Compared, step by step and iteration by iteration (summary.json ``steps[*].history``):

* the scaled Newton residual (max block norm) and every block norm: relative difference
  |a − b| / max(|a|, |b|) over the values above ``floor`` (default 1e-6) and, separately, above
  the Newton tolerance 1e-8; over all values the absolute difference (the norms are scaled: 1 =
  nothing solved). Just above the tolerance a value is mostly the round-off or Krylov error of the
  previous solve: C4's step 90 starts at 1.0653781e-8 on one rank and 1.0653779e-8 on two (an
  absolute 1.6e-12);
* the open/stick/slip counts of every iterate, and the final contact state of every fracture face
  (fractures.csv's ``state``);
* the fields of fractures.csv (jumps, tractions, pressures) and summary.json's boundary fluxes
  (max difference relative to the largest value).

Prints a JSON report; exit status 1 when the iteration counts or active sets differ or a residual
above the floor differs by more than ``--rtol`` (default 1e-8).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path


def _rows(folder: Path) -> list[dict]:
    with open(folder / "fractures.csv") as f:
        return list(csv.DictReader(f))


def compare(a: Path, b: Path, floor: float = 1e-6, tol: float = 1e-8) -> dict:
    sa, sb = (json.loads((Path(x) / "summary.json").read_text()) for x in (a, b))
    out = {"steps": [len(sa["steps"]), len(sb["steps"])], "iterations": [], "same_iterations": True,
           "same_counts": True, "max_rel_residual": 0.0, "max_rel_block": 0.0, "max_abs": 0.0,
           "max_rel_above_tol": 0.0,
           "worst": None}
    if len(sa["steps"]) != len(sb["steps"]):
        out["same_iterations"] = False
        return out
    for k, (x, y) in enumerate(zip(sa["steps"], sb["steps"])):
        hx, hy = x.get("history", []), y.get("history", [])
        out["iterations"].append([len(hx), len(hy)])
        if len(hx) != len(hy):
            out["same_iterations"] = False
            continue
        for it, (p, q) in enumerate(zip(hx, hy)):
            for key in ("open", "stick", "slip"):
                if p.get(key) != q.get(key):
                    out["same_counts"] = False
            for key, v in p.items():
                if key in ("iteration", "increment", "step", "open", "stick", "slip") or not isinstance(v, float):
                    continue
                w = q[key]
                big = max(abs(v), abs(w))
                out["max_abs"] = max(out["max_abs"], abs(v - w))
                if big > tol:
                    out["max_rel_above_tol"] = max(out["max_rel_above_tol"], abs(v - w) / big)
                if big > floor:
                    rel = abs(v - w) / big
                    name = "max_rel_residual" if key == "residual" else "max_rel_block"
                    if rel > out[name]:
                        out[name] = rel
                        if key == "residual":
                            out["worst"] = {"step": k, "iteration": it, "a": v, "b": w}
    ra, rb = _rows(Path(a)), _rows(Path(b))
    out["fracture_rows"] = [len(ra), len(rb)]
    out["same_states"] = len(ra) == len(rb) and all(p["state"] == q["state"] for p, q in zip(ra, rb))
    worst = 0.0
    if len(ra) == len(rb):
        cols = {}
        for col in ra[0] if ra else []:
            try:
                cols[col] = ([float(r[col]) for r in ra], [float(r[col]) for r in rb])
            except ValueError:
                continue
        # a jump component is compared against the largest jump of any component: on closed
        # faces jump_n is round-off (1e-17 m) on both runs, and relative to itself it is noise
        jumps = max((abs(v) for c, (va, _) in cols.items() if c.startswith("jump_") for v in va), default=0.0)
        # ΔCFS is a difference of tractions: its round-off is the tractions', not its own (0 at
        # the start, round-off where the load does not reach the fault)
        tractions = max((abs(v) for c in ("lambda_n", "lambda_t") if c in cols for v in cols[c][0]), default=0.0)
        for col, (va, vb) in cols.items():
            if col == "slip_tendency":
                # λ_t/λ_n of the λ columns compared here; near opening (λ_n at round-off) the ratio
                # is ill-conditioned and the two runs may disagree on which faces are NaN
                continue
            ref = jumps if col.startswith("jump_") else tractions if col == "delta_cfs" else 0.0
            # faces open on both runs have no slip tendency
            pairs = [(p, q) for p, q in zip(va, vb, strict=True) if not (math.isnan(p) and math.isnan(q))]
            if any(math.isnan(p) or math.isnan(q) for p, q in pairs):
                worst = math.inf                    # open on one run only
                continue
            scale = max(max((abs(p) for p, _ in pairs), default=0.0), ref, 1e-300)
            worst = max(worst, max((abs(p - q) for p, q in pairs), default=0.0) / scale)
    out["max_rel_fracture_fields"] = worst
    fa, fb = _numbers(sa.get("fluxes")), _numbers(sb.get("fluxes"))
    if fa and len(fa) == len(fb):
        scale = max(max(abs(v) for v in fa), 1e-300)
        out["max_rel_fluxes"] = max(abs(p - q) for p, q in zip(fa, fb)) / scale
    return out


def _numbers(tree) -> list[float]:
    """The numbers of a JSON tree, depth first (dict keys sorted), without the balance residuals
    (round-off measures, not results)."""
    if isinstance(tree, dict):
        return [v for k in sorted(tree) if "residual" not in k and "relative" not in k for v in _numbers(tree[k])]
    if isinstance(tree, list):
        return [v for x in tree for v in _numbers(x)]
    return [float(tree)] if isinstance(tree, (int, float)) and not isinstance(tree, bool) else []


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--floor", type=float, default=1e-6)
    p.add_argument("--rtol", type=float, default=1e-8)
    args = p.parse_args(argv)
    rep = compare(Path(args.a), Path(args.b), args.floor)
    print(json.dumps(rep, indent=1))
    ok = rep["same_iterations"] and rep["same_counts"] and rep.get("same_states", False) and \
        rep["max_rel_residual"] <= args.rtol and not math.isnan(rep["max_rel_residual"])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
