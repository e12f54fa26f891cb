"""``polypore run`` for static contact-mechanics cases: mesh, solve, write, report.

Files (interface.md): case.toml, summary.json, fractures.csv, bulk_0000.vtu,
fractures_0000.vtu, solution.pvd and, in 2D, profiles along the fractures and a
contact-state map (PNG). Everything is staged and moved into DIR on success only.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..io.plots import fracture_profiles, state_map
from ..io.results import fracture_rows, staged_run_directory, write_json
from ..io.vtu import symmetric_tensor, write_bulk_vtu, write_fracture_vtu
from ..io.atomic import atomic_write_text
from ..io.legend import write_legend
from ..models.contact import OPEN, SLIP, STATE_NAMES, STICK
from ..models.fracture_geometry import arc_length
from ..cases.exact import PiecewiseSolution, SingleCrack, piecewise_errors
from ..cases.penny_exact import PennyCrack
from ..cases.reference import ReferenceSlip
from ..setup.casefile import CaseFile
from ..setup.mechanics import mechanics_setup
from ..setup.meshing import build_fractured_mesh
from ..setup.translate import RUN_MECHANICS, case_keys
from .common import RunClock, corner_point_faults, unknowns
from .recorder import OutputSeries

log = logging.getLogger("polypore")


def solve_static(case: CaseFile):
    """Mesh the case, set up and solve the static problem; return (problem, state, setup, errors, timings)."""
    t0 = time.perf_counter()
    fm = build_fractured_mesh(case)
    t1 = time.perf_counter()
    setup = mechanics_setup(case, fm)
    problem = setup.problem(fm)         # errors name the case-file keys (setup/translate.py)
    t2 = time.perf_counter()
    with case_keys(RUN_MECHANICS):      # errors of the solve (time-dependent data, PETSc options)
        st = problem.solve()
    problem.release_solver()            # no solve follows (ContactMechanics.release_solver)
    t3 = time.perf_counter()
    errors = {}
    if isinstance(setup.exact, PiecewiseSolution):
        errors = piecewise_errors(problem, st, setup.exact)
    elif isinstance(setup.exact, SingleCrack):
        errors = setup.exact.errors(problem, st, arc_length(fm))
    elif isinstance(setup.exact, PennyCrack):
        errors = setup.exact.errors(problem, st)
    elif isinstance(setup.exact, ReferenceSlip):
        errors = setup.exact.errors(problem, st)
    timings = {"mesh": t1 - t0, "setup": t2 - t1, "solve": t3 - t2, **{f"solve_{k}": v for k, v in st.seconds.items()}}
    return problem, st, setup, errors, timings


def run_static(case: CaseFile, out: Path, plots: bool = True) -> dict:
    """Run a static case and write its files into ``out``; return the summary."""
    clock = RunClock()
    problem, st, setup, errors, timings = solve_static(case)
    fm, mesh = problem.fm, problem.fm.mesh
    faults = corner_point_faults(case, fm)
    net = fm.network
    g = mesh.geometry
    d = mesh.dim
    s = arc_length(fm)
    with staged_run_directory(out) as stage:
        atomic_write_text(stage / "case.toml", case.to_toml())
        series = OutputSeries(stage)
        cols = _output(series, problem, st, s)
        series.write()
        if plots and d == 2 and net.n_faces:
            _plots_2d(stage, case, problem, st, cols, setup, s)
        summary = {
            "case": case.name, "version": __version__,
            "mesh": {"dim": d, "cells": mesh.n_cells, "faces": mesh.n_faces, "nodes": mesh.n_nodes,
                     "fracture_faces": net.n_faces, "unknowns": unknowns(problem),
                     "h_max": float(g.cell_diameter.max())},
            **({"faults": faults} if faults is not None else {}),
            "choices": setup.choices,
            "steps": [{"time": 0.0, "newton_iterations": st.newton_iterations, "residual": st.residual,
                       "open": int(np.sum(st.state == OPEN)), "stick": int(np.sum(st.state == STICK)),
                       "slip": int(np.sum(st.state == SLIP)), "seconds": timings["solve"], "history": st.history}],
            "totals": {**clock.totals(setup.solver), "seconds_by_stage": timings},
        }
        if errors:
            summary["errors"] = errors
        write_legend(stage, summary, bulk=("displacement", "stress", "von_mises"),
                     fractures=("jump", "jump_n", "jump_t", "lambda", "lambda_n", "lambda_t", "state"))
        write_json(stage / "summary.json", summary)
    return summary


def _output(series: OutputSeries, problem, st, s) -> dict:
    """Write the solution ``st`` as the output at t = 0 of ``series`` (bulk and fracture VTU files,
    fractures.csv rows; ``s``: (n_ff,) arc length, m); return its fractures.csv columns."""
    fm = problem.fm
    net, g = fm.network, fm.mesh.geometry
    q = problem.jumps(st)
    stress = problem.stress(st)
    sv, comps = symmetric_tensor(stress)
    bulk, fractures = series.files()
    write_bulk_vtu(bulk, fm.mesh, cell_data={
        "displacement": problem.cell_displacement(st), "stress": sv,
        "von_mises": _von_mises(stress)}, point_data={"displacement": problem.node_displacement(st)},
        component_names={"stress": comps})
    qn = np.einsum("fi,fi->f", q, problem.normal)
    ln = np.einsum("fi,fi->f", st.lam, problem.normal)
    write_fracture_vtu(fractures, fm, cell_data={
        "jump": q, "jump_n": qn, "jump_t": np.linalg.norm(q - qn[:, None] * problem.normal, axis=1),
        "lambda": st.lam, "lambda_n": ln,
        "lambda_t": np.linalg.norm(st.lam - ln[:, None] * problem.normal, axis=1),
        "state": st.state.astype(np.int32)})
    cols = fracture_rows(0, 0.0, net.names, net.fracture, g.face_centroid[net.faces], s, problem.face_area, q,
                         problem.normal, st.lam, [STATE_NAMES[k] for k in st.state])
    series.add(0.0, cols)
    return cols


def _von_mises(S):
    d = S.shape[1]
    dev = S - np.trace(S, axis1=1, axis2=2)[:, None, None] / d * np.eye(d)
    return np.sqrt(1.5 * np.einsum("kij,kij->k", dev, dev))


def _plots_2d(stage, case, problem, st, cols, setup, s):
    net = problem.fm.network
    fields = {"λ_n (Pa)": np.asarray(cols["lambda_n"], float), "|λ_τ| (Pa)": np.asarray(cols["lambda_t"], float),
              "|[[u]]_τ| (m)": np.asarray(cols["jump_t"], float), "[[u]]_n (m)": np.asarray(cols["jump_n"], float)}
    ref = None
    if isinstance(setup.exact, SingleCrack):
        ss = np.linspace(0, 2 * setup.exact.half_length, 400)
        ref = {"λ_n (Pa)": (ss, setup.exact.lambda_n(ss)), "|[[u]]_τ| (m)": (ss, setup.exact.slip(ss))}
    fracture_profiles(stage / "profiles.png", net.names, net.fracture, s, fields, cols["state"],
                      title=f"{case.name}: multipliers and jumps along the fractures", reference=ref)
    state_map(stage / "contact_states.png", problem.fm.mesh, net.faces, cols["state"],
              title=f"{case.name}: contact states")
