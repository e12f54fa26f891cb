"""Convergence studies of the contact-mechanics cases C1 and C2 (issue 3).

    .venv/bin/python benchmarks/contact_convergence.py [--quick] [--only NAME ...] [--out docs/contact_convergence]

Runs ``polypore convergence`` on every (case, mesh family, bubble variant) of the table
below, prints each table and writes ``<out>/<name>/convergence.{json,csv,png}`` plus a
summary ``<out>/summary.md`` with the fitted rates. Expected (cases.md): first order for
‖∇^D u_D − ∇u‖ and for the λ errors.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from polypore.runs.convergence import format_table, run_convergence
from polypore.setup.casefile import load_case

STUDIES = {
    # name: (case, overrides, levels)
    "C1-tetra": ("frictionless-3d", ["mesh.size=0.5", "mechanics.order=1"], 4),
    "C1-hexa": ("frictionless-3d", ["mesh.generator=cartesian", "mesh.cells=[4,4,4]"], 4),
    "C1-voronoi": ("frictionless-3d", ["mesh.generator=voronoi", "mesh.size=0.5"], 3),
    "C1-tetra-2sided": ("frictionless-3d", ["mesh.size=0.5", "mechanics.order=1", "mechanics.bubbles=two-sided"], 4),
    "C2-coulomb-2d": ("coulomb-2d", ["mesh.size=0.2"], 5),
    "C2-coulomb-2d-2sided": ("coulomb-2d", ["mesh.size=0.2", "mechanics.bubbles=two-sided"], 5),
    "C2-tresca-2d": ("tresca-2d", ["mesh.size=0.2"], 5),
    "C2-coulomb-2d-voronoi": ("coulomb-2d", ["mesh.generator=voronoi", "mesh.size=0.2"], 4),
    "C2-coulomb-3d": ("coulomb-3d", ["mesh.size=0.3"], 3),
    "C2-tresca-3d-2sided": ("tresca-3d", ["mesh.size=0.3", "mechanics.bubbles=two-sided"], 3),
}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--quick", action="store_true", help="one level fewer everywhere")
    ap.add_argument("--linear", default="auto")
    ap.add_argument("--out", default="docs/contact_convergence")
    args = ap.parse_args()
    out = Path(args.out)
    lines = ["| study | case | levels | h finest | unknowns finest | " + "rates | seconds |", "|---|---|---|---|---|---|---|"]
    for name, (case_name, overrides, levels) in STUDIES.items():
        if args.only and name not in args.only:
            continue
        levels -= int(args.quick)
        t0 = time.perf_counter()
        case = load_case(case_name, overrides + [f"solver.linear={args.linear}"])
        res = run_convergence(case, levels, out / name)
        print(f"== {name}\n{format_table(res)}\n", flush=True)
        last = res["levels"][-1]
        rates = ", ".join(f"{k} {v:.2f}" for k, v in res["rates"].items() if not k.endswith("_rel"))
        lines.append(f"| {name} | {case_name} {' '.join(overrides)} | {levels} | {last['h']:.3g} | {last['unknowns']} | "
                     f"{rates} | {time.perf_counter() - t0:.0f} |")
        (out / "summary.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
