"""``polypore run`` / ``polypore convergence`` for mixed-dimensional Darcy flow cases.

Files (interface.md), all staged and moved into DIR on success only: case.toml,
summary.json, fractures.csv (p_f and aperture; mechanics columns empty),
bulk_NNNN.vtu (cell pressure, Darcy velocity), fractures_NNNN.vtu (p_f, traces,
aperture, exchange), solution.pvd and, in 2D, ``pressure_map.png`` (matrix pressure
with the fractures drawn) and ``fracture_pressure.png`` (p_f and the traces along each
fracture).

Mass balance (m³/s, per metre in 2D): sources − storage rate − outflow through ∂Ω, where
the outflow includes the fracture ends on ∂Ω; it vanishes to round-off for the HFV scheme.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..cases.flow_exact import flow_errors, slot_values
from ..io.atomic import atomic_write_text
from ..io.legend import write_legend
from ..io.progress import Progress
from ..io.results import fracture_rows, staged_run_directory, write_json
from ..io.vtu import write_bulk_vtu, write_fracture_vtu
from ..mesh.fractures import BOUNDARY
from ..models.fracture_geometry import arc_length
from ..setup.casefile import CaseFile
from ..setup.flow import FlowSetup, flow_setup
from ..setup.meshing import build_fractured_mesh
from ..setup.translate import RUN_FLOW, case_keys
from .common import RunClock, corner_point_faults
from .recorder import OutputSeries

log = logging.getLogger("polypore")

MECHANICS_COLUMNS = ("jump_n", "jump_t", "jump_x", "jump_y", "jump_z", "lambda_n", "lambda_t", "state")


def flow_unknowns(model) -> int:
    """All pressure unknowns of the scheme: cells, faces, traces, fracture faces, fracture edges."""
    return int(model.assembler.dofs.n + model.mesh.n_cells)


def _prepare(case: CaseFile):
    t0 = time.perf_counter()
    fm = build_fractured_mesh(case)
    t1 = time.perf_counter()
    setup = flow_setup(case, fm)
    model = setup.model()
    t2 = time.perf_counter()
    return fm, setup, model, {"mesh": t1 - t0, "setup": t2 - t1, **model.setup_seconds}


# -- balances ------------------------------------------------------------------------------------
def balances(model, sol, old=None, dt: float | None = None) -> dict:
    """Global and per-fracture volume balances of one solve (m³/s, outflow positive).

    Parameters
    ----------
    old, dt : previous state and step (s) of a transient step; None for a steady solve.
    """
    mesh, net = model.mesh, model.network
    g = mesh.geometry
    area = g.face_area[net.faces]
    hm, hf = model.sources(sol.time)
    nfrac = len(net.names)
    # storage rates (the same terms as FlowModel.step; the conductivities there use d_f^{n−1})
    if old is None:
        st_cell = np.zeros(mesh.n_cells)
        st_frac = np.zeros(net.n_faces)
    else:
        st_cell = g.cell_volume * (sol.cell - old.cell) / (model.biot_modulus * dt)
        cf = float(model.data.fracture_compressibility)
        st_frac = area * (sol.aperture - old.aperture) / dt + area * old.aperture * cf * (sol.fracture - old.fracture) / dt
    outflow = float(sum(sol.boundary_flux.values()))
    sources = float(hm.sum() + hf.sum())
    storage = float(st_cell.sum() + st_frac.sum())
    residual = sources - storage - outflow
    scale = max(abs(sources), abs(storage), float(sum(abs(v) for v in sol.boundary_flux.values())), 1e-300)
    # per fracture: exchange in (matrix → fracture), edge outflow split into ∂Ω ends and the rest
    fe = model.fracture_cells.face_edges
    face_of = fe.rows_of_entries()
    on_bnd = net.edge_kind[fe.values] == BOUNDARY
    out_all = np.bincount(net.fracture[face_of], weights=sol.fracture_flux, minlength=nfrac)
    out_bnd = np.bincount(net.fracture[face_of[on_bnd]], weights=sol.fracture_flux[on_bnd], minlength=nfrac)
    exp = np.bincount(net.fracture, weights=sol.exchange[:, 0], minlength=nfrac)
    exm = np.bincount(net.fracture, weights=sol.exchange[:, 1], minlength=nfrac)
    src = np.bincount(net.fracture, weights=hf, minlength=nfrac)
    sto = np.bincount(net.fracture, weights=st_frac, minlength=nfrac)
    fractures = {}
    for i, name in enumerate(net.names):
        res = exp[i] + exm[i] + src[i] - sto[i] - out_all[i]
        fractures[name] = {"exchange_plus": exp[i], "exchange_minus": exm[i], "exchange": exp[i] + exm[i],
                           "source": src[i], "storage_rate": sto[i], "boundary_outflow": out_bnd[i],
                           "intersection_outflow": out_all[i] - out_bnd[i], "balance_residual": res}
    return {"boundary": dict(sol.boundary_flux), "fracture_boundary": dict(sol.fracture_boundary_flux),
            "fractures": fractures,
            "mass_balance": {"sources": sources, "storage_rate": storage, "outflow": outflow, "residual": residual,
                             "relative": abs(residual) / scale}}


# -- outputs -------------------------------------------------------------------------------------
def _darcy_velocity(model, sol, slot) -> np.ndarray:
    """−(K/η) ∇_K p per cell (m/s)."""
    gK, _, _ = model.assembler.hfv.gradients(sol.cell, slot)
    return -np.einsum("kij,kj->ki", model.permeability, gK) / model.viscosity


def _output(series: OutputSeries, step: int, model, setup: FlowSetup, sol, s) -> None:
    """Write the solution ``sol`` of schedule step ``step`` as the next output of ``series``: bulk
    and fracture VTU files, fractures.csv rows (``s``: (n_ff,) arc length, m)."""
    mesh, net = model.mesh, model.network
    g = mesh.geometry
    cell = {"pressure": sol.cell, "darcy_velocity": _darcy_velocity(model, sol, slot_values(model, sol))}
    if setup.exact is not None:
        c = g.cell_centroid
        pe = setup.exact.p(c[:, 0], c[:, 1], c[:, 2] if mesh.dim == 3 else 0.0)
        cell.update(pressure_exact=pe, pressure_error=sol.cell - pe)
    bulk, fractures = series.files()
    write_bulk_vtu(bulk, mesh, cell_data=cell)
    area = g.face_area[net.faces]
    write_fracture_vtu(fractures, model.fmesh, cell_data={
        "p_f": sol.fracture, "trace_plus": sol.trace[:, 0], "trace_minus": sol.trace[:, 1],
        "aperture": sol.aperture, "exchange": sol.exchange.sum(axis=1) / area})
    series.add(sol.time, _csv_block(step, model, sol, s))


def _csv_block(step: int, model, sol, s) -> dict:
    mesh, net = model.mesh, model.network
    g = mesh.geometry
    n, d = net.n_faces, mesh.dim
    z = np.zeros((n, d))
    cols = fracture_rows(step, sol.time, net.names, net.fracture, g.face_centroid[net.faces], s,
                         g.face_area[net.faces], z, np.asarray(net.normal, float), z, np.full(n, ""),
                         aperture=sol.aperture, p_f=sol.fracture)
    for key in MECHANICS_COLUMNS:
        cols[key] = np.full(n, "")
    return cols


def _plots_2d(stage: Path, case: CaseFile, model, setup: FlowSetup, sol, s):
    """pressure_map.png and fracture_pressure.png of a 2D run's last solution ``sol`` (``s``: (n_ff,)
    arc length, m)."""
    from ..io.plots import format_time, value_unit

    t_end = None if setup.steady else float(setup.schedule.times()[-1])
    when = "" if t_end is None else f", t = {format_time(sol.time, t_end)}"     # a steady run has no time
    fp, up = value_unit("Pa", float(np.abs(sol.cell).max()) if sol.cell.size else 0.0)
    _pressure_map(stage / "pressure_map.png", f"{case.name}: matrix pressure{when}", model, sol, fp, up)
    net = model.network
    if len(net.names) == 0 or net.n_faces == 0:
        return
    _fracture_pressure(stage / "fracture_pressure.png", f"{case.name}: fracture pressure and matrix traces{when}",
                       model, setup, sol, s, fp, up)


def _pressure_map(path: Path, title: str, model, sol, fp: float, up: str):
    """The matrix pressure (Pa / ``fp``, in unit ``up``) with the fractures drawn."""
    from ..io.plots import _plt, save
    from ..io.vtu import bulk_cells

    plt = _plt()
    from matplotlib.collections import LineCollection, PolyCollection

    mesh, net = model.mesh, model.network
    c = bulk_cells(mesh)
    starts = np.concatenate([[0], c["offsets"][:-1]])
    polys = [c["points"][c["connectivity"][a:b], :2] for a, b in zip(starts, c["offsets"])]
    lo, hi = mesh.bounding_box
    fig, ax = plt.subplots(figsize=(8, 8 * (hi[1] - lo[1]) / (hi[0] - lo[0]) + 0.8))
    pc = PolyCollection(polys, array=sol.cell / fp, cmap="viridis", edgecolors="face", linewidths=0.1)
    ax.add_collection(pc)
    seg = mesh.nodes[mesh.face_nodes.values.reshape(-1, 2)[net.faces]]
    ax.add_collection(LineCollection(seg, colors="white", linewidths=2.2))
    ax.add_collection(LineCollection(seg, colors="k", linewidths=1.0))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    fig.colorbar(pc, ax=ax, label=f"matrix pressure p_m ({up})", shrink=0.8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=10)
    save(fig, path)


def _fracture_pressure(path: Path, title: str, model, setup: FlowSetup, sol, s, fp: float, up: str):
    """p_f and the two matrix traces along each fracture (Pa / ``fp``, in unit ``up``) against the
    arc length ``s`` (m), with the exact p_f of a case that has one."""
    from ..io.plots import MAX_COLUMNS, _plt, save

    plt = _plt()
    mesh, net = model.mesh, model.network
    nf = len(net.names)
    ncol = min(nf, MAX_COLUMNS)
    nrow = -(-nf // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol + 1, 3.0 * nrow + 0.6), squeeze=False,
                             layout="constrained")
    for ax in axes.ravel()[nf:]:
        ax.axis("off")
    axes = axes.ravel()[None, :]
    xf = mesh.geometry.face_centroid[net.faces]
    for j, name in enumerate(net.names):
        ax = axes[0, j]
        f = np.flatnonzero(net.fracture == j)
        f = f[np.argsort(s[f])]
        ax.plot(s[f], sol.trace[f, 0] / fp, "-", lw=0.8, color="tab:orange", label="p⁺ (matrix trace)")
        ax.plot(s[f], sol.trace[f, 1] / fp, "-", lw=0.8, color="tab:green", label="p⁻ (matrix trace)")
        ax.plot(s[f], sol.fracture[f] / fp, ".-", ms=3, lw=1.0, color="tab:blue", label="p_f")
        if setup.exact is not None:
            ax.plot(s[f], setup.exact.p_f(xf[f], setup.on_gamma1[f]) / fp, "k--", lw=0.8, label="exact p_f")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("arc length s (m)", fontsize=8)
        ax.ticklabel_format(axis="y", useOffset=False)    # an offset label collides with the title
        if j % ncol == 0:
            ax.set_ylabel(f"pressure ({up})", fontsize=8)
        if j == 0:
            ax.legend(fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    save(fig, path)


# -- entry points --------------------------------------------------------------------------------
def run_flow(case: CaseFile, out: Path) -> dict:
    """Run a flow case (steady or transient) and write its files into ``out``; return the summary:
    set-up, solve (:func:`_solve_steady`) or march (:func:`_march_transient`), write."""
    clock = RunClock()
    fm, setup, model, stage_seconds = _prepare(case)
    mesh = fm.mesh
    faults = corner_point_faults(case, fm)
    s = arc_length(fm)
    with staged_run_directory(out) as stage:
        atomic_write_text(stage / "case.toml", case.to_toml())
        series = OutputSeries(stage)
        solve = _solve_steady if setup.steady else _march_transient
        with case_keys(RUN_FLOW):       # errors of the solve (time-dependent data, PETSc options)
            sol, bal, steps = solve(model, setup, series, s)
        series.write()
        if mesh.dim == 2:
            _plots_2d(stage, case, model, setup, sol, s)
        summary = {
            "case": case.name, "version": __version__, "model": "flow",
            "mesh": {"dim": mesh.dim, "cells": mesh.n_cells, "faces": mesh.n_faces, "nodes": mesh.n_nodes,
                     "fracture_faces": fm.network.n_faces, "unknowns": flow_unknowns(model),
                     "global_unknowns": int(model.assembler.dofs.n),
                     "h_max": float(mesh.geometry.cell_diameter.max())},
            **({"faults": faults} if faults is not None else {}),
            "steady": setup.steady,
            "steps": steps,
            "fluxes": bal,
            "totals": {**clock.totals(setup.solver), "seconds_by_stage": stage_seconds},
        }
        if setup.exact is not None:
            summary["errors"] = flow_errors(model, sol, setup.exact, setup.on_gamma1)
        write_legend(stage, summary, bulk=("pressure", "darcy_velocity") + (
            ("pressure_exact", "pressure_error") if setup.exact is not None else ()),
            fractures=("p_f", "trace_plus", "trace_minus", "aperture", "exchange"))
        write_json(stage / "summary.json", summary)
    return summary


def _solve_steady(model, setup: FlowSetup, series: OutputSeries, s):
    """The steady solve, written as output 0 of ``series``; return (solution, its balances,
    summary.json's steps)."""
    t0 = time.perf_counter()
    sol = model.solve_steady()
    bal = balances(model, sol)
    steps = [{"time": sol.time, "seconds": time.perf_counter() - t0,
              "mass_balance": bal["mass_balance"]["residual"], "timings": sol.timings}]
    log.info("steady solve: %d unknowns in %.2f s, mass balance %.2e m³/s", flow_unknowns(model),
             steps[-1]["seconds"], bal["mass_balance"]["residual"])
    _output(series, 0, model, setup, sol, s)
    return sol, bal, steps


def _march_transient(model, setup: FlowSetup, series: OutputSeries, s):
    """Implicit-Euler steps over the schedule from the initial state (output 0), outputs at the
    schedule's output times; return (last solution, its balances, summary.json's steps)."""
    times = setup.schedule.times()
    sol = model.initial_state(setup.initial_pressure, times[0])
    _output(series, 0, model, setup, sol, s)
    steps = []
    with Progress(times.size - 1, "steps") as bar:
        for n in range(1, times.size):
            t0 = time.perf_counter()
            old, sol = sol, model.step(sol, times[n] - times[n - 1])
            bal = balances(model, sol, old, times[n] - times[n - 1])
            steps.append({"time": sol.time, "seconds": time.perf_counter() - t0,
                          "mass_balance": bal["mass_balance"]["residual"]})
            log.info("step %d/%d: t = %g s, %.2f s, mass balance %.2e m³/s (%s)", n, times.size - 1,
                     sol.time, steps[-1]["seconds"], bal["mass_balance"]["residual"], bar.advance())
            if setup.schedule.is_output(n, float(times[n])):
                _output(series, n, model, setup, sol, s)
    return sol, bal, steps


def flow_convergence_point(case: CaseFile) -> dict:
    """Solve a flow case with an exact solution once (steady): h (max cell diameter, m), cells,
    unknowns and the relative errors ``p_cell_L2``, ``p_fracture_L2``, ``p_trace_L2``, ``grad_p_L2``."""
    fm, setup, model, _ = _prepare(case)
    if setup.exact is None:
        return {"h": float(fm.mesh.geometry.cell_diameter.max()), "cells": fm.mesh.n_cells,
                "unknowns": flow_unknowns(model), "errors": {}}
    sol = model.solve_steady()
    return {"h": float(fm.mesh.geometry.cell_diameter.max()), "cells": fm.mesh.n_cells,
            "unknowns": flow_unknowns(model), "errors": flow_errors(model, sol, setup.exact, setup.on_gamma1)}
