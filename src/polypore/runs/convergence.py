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


def pair_rate(h0: float, h1: float, e0: float, e1: float) -> float:
    """Observed rate log(e0/e1) / log(h0/h1) between two levels (NaN without positive errors)."""
    if not (e0 > 0 and e1 > 0 and h0 > 0 and h1 > 0 and h0 != h1):
        return float("nan")
    return float(np.log(e0 / e1) / np.log(h0 / h1))


def rises(errors) -> list[int]:
    """Levels k at which an error sequence rises (e_k > e_{k-1}): there the fitted rate does not
    describe the finest meshes (coulomb-2d at 4 levels: fitted 1.19, last pair −0.45)."""
    return [k for k in range(1, len(errors)) if errors[k] > errors[k - 1]]


def rate_summary(hs, errors: dict) -> dict:
    """Fitted rates, the rates of the last pair of levels and, per error measure, the levels at
    which it rises (errors: name -> sequence per level)."""
    return {"rates": {n: fit_rate(hs, e) for n, e in errors.items()},
            "last_pair_rates": {n: pair_rate(hs[-2], hs[-1], e[-2], e[-1]) for n, e in errors.items()},
            "rising": {n: rises(e) for n, e in errors.items() if rises(e)}}


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
    rates_info = rate_summary(hs, {n: [r["errors"][n] for r in rows] for n in names})
    rates = rates_info["rates"]
    result = {"case": case.name, "levels": rows, **rates_info}
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
    """The study as printed: errors per level with the rate of each pair of levels in brackets
    ("!" where the error rose), the fitted and last-pair rates, and a warning naming every error
    measure whose sequence is not monotone."""
    names = list(result["levels"][0]["errors"])
    head = f"{'level':>5} {'h':>10} {'unknowns':>9} " + " ".join(f"{n:>17}" for n in names)
    lines = [head]
    prev = None
    for r in result["levels"]:
        cells = []
        for n in names:
            e = r["errors"][n]
            if prev is None:
                cells.append(f"{e:17.4e}")
            else:
                rate = pair_rate(prev["h"], r["h"], prev["errors"][n], e)
                cells.append(f"{e:10.4e} ({rate:5.2f}){'!' if e > prev['errors'][n] else ' '}")
        lines.append(f"{r['level']:>5} {r['h']:10.4g} {r['unknowns']:>9} " + " ".join(cells))
        prev = r
    levels = result["levels"]
    last = result.get("last_pair_rates") or {
        n: pair_rate(levels[-2]["h"], levels[-1]["h"], levels[-2]["errors"][n], levels[-1]["errors"][n])
        for n in names}
    rising = result.get("rising")
    if rising is None:
        rising = {n: rises([r["errors"][n] for r in levels]) for n in names}
        rising = {n: v for n, v in rising.items() if v}
    lines.append("fitted rates:    " + ", ".join(f"{n} {v:.2f}" for n, v in result["rates"].items()))
    lines.append(f"last-pair rates: " + ", ".join(f"{n} {v:.2f}" for n, v in last.items()) +
                 f" (levels {levels[-2]['level']}-{levels[-1]['level']})")
    for n, ks in rising.items():
        at = ", ".join(f"{levels[k - 1]['level']}->{levels[k]['level']}" for k in ks)
        lines.append(f"warning: {n} is not monotone: it rises at levels {at} (marked !); its fitted rate "
                     f"{result['rates'][n]:.2f} does not describe the finest meshes")
    return "\n".join(lines)
