"""``polypore convergence``: a mesh-refinement study of a case with an exact or analytic solution."""

from __future__ import annotations

import copy
import logging
import time
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..io.atomic import atomic_write_text
from ..io.plots import convergence_plot
from ..io.progress import Progress
from ..io.results import staged_run_directory, write_json
from ..setup.casefile import CaseFile, case_model
from .common import unknowns
from .flow import flow_convergence_point
from .static import solve_static

log = logging.getLogger("polypore")


def refined(case: CaseFile, level: int) -> CaseFile:
    """The case with its mesh refined ``level`` times by a factor 2 (sizes halved, cells doubled)."""
    data = copy.deepcopy(case.data)
    mesh = data.setdefault("mesh", {})
    f = 2 ** level
    if mesh.get("generator") == "cartesian" and "cells" in mesh:
        mesh["cells"] = [int(c) * f for c in mesh["cells"]]
    elif mesh.get("generator") == "file":
        raise InputError("mesh.generator", "a convergence study needs a generated mesh, not a mesh file")
    else:
        for key in ("size", "fracture_size"):
            if key in mesh:
                mesh[key] = float(mesh[key]) / f
    return CaseFile(case.name, case.source, data)


def convergence_point(case: CaseFile) -> dict:
    """Solve a case with an exact solution once: h (max cell diameter, m), cells, unknowns,
    iterations and the error measures."""
    if case_model(case) == "flow":
        return flow_convergence_point(case)
    problem, st, setup, errors, _ = solve_static(case)
    return {"h": float(problem.fm.mesh.geometry.cell_diameter.max()), "cells": problem.fm.mesh.n_cells,
            "unknowns": unknowns(problem), "newton_iterations": st.newton_iterations, "errors": errors}


def fit_rate(h, e) -> float:
    """Least-squares slope of log e against log h (NaN with fewer than 2 positive values)."""
    h, e = np.asarray(h, float), np.asarray(e, float)
    ok = (e > 0) & (h > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(h[ok]), np.log(e[ok]), 1)[0])


def run_convergence(case: CaseFile, levels: int, out: Path) -> dict:
    if levels < 2:
        raise InputError("--levels", f"need at least 2 levels to fit a rate, got {levels}")
    rows = []
    # each level halves h: about 2^d times the unknowns, and at least that much work
    with Progress(levels, "levels", growth=4.0) as bar:
        for k in range(levels):
            t0 = time.perf_counter()
            c = refined(case, k)
            point = convergence_point(c)
            errors, h = point["errors"], point["h"]
            if not errors:
                raise InputError("exact", f"case {case.name!r} has no exact or analytic solution ([exact] table); "
                                 "a convergence study needs one")
            rows.append({"level": k, **point, "seconds": time.perf_counter() - t0})
            log.info("level %d: h %.4g, %d unknowns, %s (%s)", k, h, rows[-1]["unknowns"],
                     ", ".join(f"{n} {v:.3e}" for n, v in errors.items()), bar.advance(rows[-1]["seconds"]))
    names = list(rows[0]["errors"])
    hs = [r["h"] for r in rows]
    rates = {n: fit_rate(hs, [r["errors"][n] for r in rows]) for n in names}
    result = {"case": case.name, "levels": rows, "rates": rates}
    with staged_run_directory(out) as stage:
        lines = [",".join(["level", "h", "cells", "unknowns", "newton_iterations"] + names)]
        for r in rows:
            lines.append(",".join([str(r["level"]), f"{r['h']:.6g}", str(r["cells"]), str(r["unknowns"]),
                                   str(r.get("newton_iterations", ""))] + [f"{r['errors'][n]:.6e}" for n in names]))
        atomic_write_text(stage / "convergence.csv", "\n".join(lines) + "\n")
        convergence_plot(stage / "convergence.png", hs, {n: [r["errors"][n] for r in rows] for n in names}, rates,
                         title=f"{case.name}: errors against mesh size")
        atomic_write_text(stage / "case.toml", case.to_toml())
        write_json(stage / "convergence.json", result)
    return result


def format_table(result: dict) -> str:
    names = list(result["levels"][0]["errors"])
    head = f"{'level':>5} {'h':>10} {'unknowns':>9} " + " ".join(f"{n:>16}" for n in names)
    lines = [head]
    prev = None
    for r in result["levels"]:
        cells = []
        for n in names:
            e = r["errors"][n]
            if prev is None:
                cells.append(f"{e:16.4e}")
            else:
                rate = np.log(prev["errors"][n] / e) / np.log(prev["h"] / r["h"]) if e > 0 and prev["errors"][n] > 0 \
                    else float("nan")
                cells.append(f"{e:10.4e} ({rate:4.2f})")
        lines.append(f"{r['level']:>5} {r['h']:10.4g} {r['unknowns']:>9} " + " ".join(cells))
        prev = r
    lines.append("fitted rates: " + ", ".join(f"{n} {v:.2f}" for n, v in result["rates"].items()))
    return "\n".join(lines)
