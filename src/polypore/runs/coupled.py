"""``polypore run`` for poromechanics cases (scheme.md §6): the time loop, outputs, energy audit.

The case is set up by :func:`polypore.setup.poromechanics.poro_setup` (the mechanics and flow
tables, ``[time]``, ``[initial_state]``); ``[monitor]`` names points whose overpressure is recorded.
Files: case.toml, summary.json (steps with Newton counts, states and energy terms),
fractures.csv, bulk/fractures VTU series + solution.pvd and monitor plots: in 2D, overpressure
maps, contact states along the fractures and mean aperture / fracture pressure against time; in
3D, slip onset per fault, the faults seen face-on, pressures against time and an overpressure map
(:mod:`polypore.io.plots3d`). Plots are written after the data and a plot that fails is a
warning, never a failed run.

Replot a finished run's folder (3D; also runs of older versions)::

    polypore plot RUN_DIR [--out DIR]
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..core import live
from ..core.errors import InputError, RunError
from ..io.atomic import atomic_write_text
from ..io.legend import POROMECHANICS_ARRAYS, write_legend
from ..io.monitor3d import StepRecorder, collect, from_run_directory, tangential
from ..io.plots import monitor_plots, poro_plots, time_unit
from ..io.plots3d import write_3d_plots
from ..io.results import fracture_rows, staged_run_directory, write_fractures_csv, write_json
from ..io.vtu import symmetric_tensor, write_bulk_vtu, write_fracture_vtu, write_pvd
from ..models.contact import SLIP, STATE_NAMES
from ..models.energy import check_energy
from ..models.fracture_geometry import arc_length
from ..models.mechanics import MechanicsState
from ..setup.casefile import CaseFile, load_case
from ..setup.flow import well_cells
from ..setup.meshing import build_fractured_mesh
from ..setup.poromechanics import monitor_points, poro_setup
from .common import RunClock, corner_point_faults
from .march import march

log = logging.getLogger("polypore")
# a step whose fracture conductivity grows more than this (aperture ×10 with the cubic law), on
# faces carrying flow, is warned of: the fluxes lag one step (Poromechanics.conductivity_growth).
# Growth does not measure the error: on the tilted grid of docs/fault_bounds.md 2e8 went with slip
# 60 % above its Δt → 0 value, on C6 (coarse) 54 at 5-day steps with 3.5 % and 2e4 at 30-day
# steps with 2.7 % at the end; the warning asks for the check that does (a shorter step)
CONDUCTIVITY_GROWTH_WARN = 1e3


# a face whose tangential jump since the start is above SLIPPED, at least BUBBLE_SHARE of it its
# bubble's and the bubble's part at least BUBBLE_OVER_NODAL × the nodal part's: the sliver of
# docs/fault_bounds.md has 38.9 of 40.5 mm in its bubble (1.6 mm nodal); near C6's tips a bubble
# corrects a nodal jump (0.60 against 1.12 mm) and is not a slip of its own
BUBBLE_SHARE = 0.75
BUBBLE_OVER_NODAL = 3.0
SLIPPED = 1e-4          # m


def bubble_slip(model, st, net) -> dict:
    """The fault faces whose slip since the start (> SLIPPED) is mostly their face bubble's (at least
    BUBBLE_SHARE of it, and BUBBLE_OVER_NODAL × the nodal part; :meth:`ContactMechanics.jump_parts`):
    count, and the one with the largest bubble part."""
    mech = model.mech
    u0 = model.u_ref if model.u_ref is not None else np.zeros_like(st.u)
    pts, bub = mech.jump_parts(st.u - u0)
    n = mech.normal
    total, tb, tp = tangential(pts + bub, n), tangential(bub, n), tangential(pts, n)
    hit = (total > SLIPPED) & (tb >= BUBBLE_SHARE * total) & (tb >= BUBBLE_OVER_NODAL * tp)
    out = {"faces": int(hit.sum()), "share": BUBBLE_SHARE, "over_nodal": BUBBLE_OVER_NODAL, "slipped_m": SLIPPED,
           "largest": None}
    if hit.any():
        i = int(np.argmax(np.where(hit, tb, -1.0)))
        name = net.names[net.fracture[i]]
        local = int(np.count_nonzero(net.fracture[:i] == net.fracture[i]))
        out["largest"] = {"fracture": name, "face": local, "area_m2": float(mech.face_area[i]),
                          "slip_m": float(total[i]), "bubble_m": float(tb[i]), "nodal_m": float(tp[i])}
    return out


def run_poromechanics(case: CaseFile, out: Path) -> dict:
    clock = RunClock()
    fm = build_fractured_mesh(case)
    model, fs, ms = poro_setup(case, fm)
    mesh, net = fm.mesh, fm.network
    faults = corner_point_faults(case, fm)
    g = mesh.geometry
    schedule = fs.schedule
    live.update(steps=len(schedule.times()) - 1, unit="step")   # the live line's run estimate, from the start
    s_arc = arc_length(fm)
    t0 = time.perf_counter()
    ref = model.reference
    if ref is None:
        state = model.initial_state(fs.initial_pressure, t0=schedule.start)
        p_ref = np.zeros(mesh.n_cells)
    else:
        try:
            state = model.reference_state(fs.initial_pressure, t0=schedule.start)
        except RunError as exc:
            raise InputError("initial_state", str(exc)) from None
        p_ref = ref.pressure(g.cell_centroid)                  # outputs: absolute pressure = p_h + p
    p0 = model.cell_pressure(state).copy()
    points = monitor_points(case, mesh)
    recorder = StepRecorder(net.names, net.fracture, model.mech.face_area, case_wells(case, mesh), g.cell_volume)
    q_start = model.jumps(state.u)
    n_hat = model.mech.normal

    def slip_since_start(st):
        return tangential(model.jumps(st.u) - q_start, n_hat)

    monitor = {"time": [], "points": {k: [] for k in points}, "fault_p": {k: [] for k in net.names},
               "fault_slip": {k: [] for k in net.names}}
    onset = {}
    log.info("initial state at t = %g s: %d open, %d stick, %d slip faces (%.2f s)", schedule.start,
             int(np.sum(state.state == 0)), int(np.sum(state.state == 1)), int(np.sum(state.state == 2)),
             time.perf_counter() - t0)
    steps, energies, pvd, blocks, series, snapshots = [], [], [], [], [], []
    warned = []                         # the step of the conductivity-growth warning (once per run)

    with staged_run_directory(out) as stage:
        atomic_write_text(stage / "case.toml", case.to_toml())

        def output(k_out: int, n: int, st):
            fq = model.fracture_quantities(st)
            p = model.cell_pressure(st)
            eff, tot = model.stresses(st)
            (eff, comps), (tot, _) = symmetric_tensor(eff), symmetric_tensor(tot)
            write_bulk_vtu(stage / f"bulk_{k_out:04d}.vtu", mesh, cell_data={
                "pressure": p + p_ref, "overpressure": p - p0, "displacement": model.mech.cell_displacement(
                    _mstate(st)), "effective_stress": eff, "total_stress": tot},
                point_data={"displacement": model.mech.node_displacement(_mstate(st))},  # for Warp By Vector
                component_names={"effective_stress": comps, "total_stress": comps})
            write_fracture_vtu(stage / f"fractures_{k_out:04d}.vtu", fm, cell_data={
                "jump": fq["jump"], "jump_n": fq["jump_n"], "jump_t": fq["jump_t"], "lambda": st.lam,
                "lambda_n": fq["lambda_n"], "lambda_t": fq["lambda_t"], "state": fq["state"].astype(np.int32),
                "aperture": fq["aperture"], "p_f": fq["p_f"], **model.friction_fields(st),
                # every step's onset (the recorder saw this time already): replots draw the same
                "first_slip": recorder.onset.copy()})
            pvd.extend([(st.time, f"bulk_{k_out:04d}.vtu", 0), (st.time, f"fractures_{k_out:04d}.vtu", 1)])
            blocks.append(fracture_rows(n, st.time, net.names, net.fracture, g.face_centroid[net.faces], s_arc,
                                        model.mech.face_area, fq["jump"], model.mech.normal, st.lam,
                                        [STATE_NAMES[k] for k in fq["state"]], fq["aperture"], fq["p_f"]))
            snapshots.append({"time": st.time, "overpressure": p - p0, "state": fq["state"].copy(),
                              "lambda_n": fq["lambda_n"].copy(), "jump_t": fq["jump_t"].copy(),
                              "aperture": fq["aperture"].copy(), "slip": slip_since_start(st)})

        def record(st):
            fq = model.fracture_quantities(st)
            A = model.mech.face_area
            row = {"time": st.time}
            for i, name in enumerate(net.names):
                sel = net.fracture == i
                w = A[sel].sum()
                row[name] = (float((A[sel] * fq["aperture"][sel]).sum() / w),
                             float((A[sel] * fq["p_f"][sel]).sum() / w))
            series.append(row)
            monitor["time"].append(st.time)
            pc = model.cell_pressure(st)
            for k, cell in points.items():
                monitor["points"][k].append(float(pc[cell] - p0[cell]))
            recorder.add(st.time, st.state, pc - p0, fq["p_f"])
            slip = slip_since_start(st)
            for i, name in enumerate(net.names):
                sel = net.fracture == i
                monitor["fault_p"][name].append(float(fq["p_f"][sel].max()) if sel.any() else 0.0)
                monitor["fault_slip"][name].append(float(slip[sel].max()) if sel.any() else 0.0)
            if not onset and np.any(st.state == SLIP):
                x = g.face_centroid[net.faces][st.state == SLIP]
                onset.update({"time": st.time, "previous_time": monitor["time"][-2] if len(monitor["time"]) > 1
                              else st.time, "faces": int(np.sum(st.state == SLIP)),
                              "first_slipping_faces": np.round(x, 3).tolist()[:20]})

        record(state)                   # before the output: its VTU holds the onsets up to now
        output(0, 0, state)
        k_out = [1]

        def step(st, ta, tb):
            new, info = model.step(st, tb - ta, tb)
            return new, {"info": info, "dt": tb - ta}

        limit = schedule.max_conductivity_growth

        def accept(sub):
            """None, or why a converged step is redone at half the size (time.max_conductivity_growth)."""
            g = sub["info"].conductivity_growth
            return None if limit is None or g <= limit else f"a fracture conductivity grew {g:.2g}-fold, above {limit:g}"

        def on_step(rec, st, is_out):
            info = rec.info["info"]
            subs = [sub["info"] for sub in rec.substeps]
            growth = max(i.conductivity_growth for i in subs)
            row = {"time": rec.time, "dt": rec.dt, "newton_iterations": sum(i.iterations for i in subs),
                   "residual": info.residual, "open": info.open, "stick": info.stick, "slip": info.slip,
                   "seconds": rec.seconds, "cuts": rec.cuts, "history": info.history}
            if len(subs) > 1 or rec.rejected:
                row["substeps"] = {"accepted": len(subs), "rejected": rec.rejected, "kept_above_limit": rec.forced,
                                   "smallest_dt": min(sub["dt"] for sub in rec.substeps)}
            lin_its = [k for i in subs for k in (i.linear_iterations or [])]
            if lin_its:
                row["linear_iterations"] = lin_its
            if rec.failed:
                # attempts given up and cut: not part of the accepted step's counts, but of its cost
                row["failed_attempts"] = rec.failed
            row["conductivity_growth"] = growth
            if growth > CONDUCTIVITY_GROWTH_WARN and not warned:
                warned.append(rec.index)
                log.warning("step %d (t = %g s): the fracture conductivity grew up to %.1e-fold on faces that carry "
                            "flow; the step's fluxes use the previous step's conductivity (scheme.md §6), so slip and "
                            "fault pressure after it may depend on time.step (here Δt = %g s): compare with a "
                            "shorter step, or set time.max_conductivity_growth (docs/fault_bounds.md, \"The time "
                            "step\"; summary.json steps[].conductivity_growth)",
                            rec.index, rec.time, growth, rec.dt)
            if info.energy is not None:
                row["energy"] = info.energy.summary()           # the last sub-step's; all are checked
                energies.extend(i.energy for i in subs if i.energy is not None)
            steps.append(row)
            lin = f", {sum(lin_its)} GMRES iterations" if lin_its else ""
            sub = f" in {len(subs)} sub-steps" if len(subs) > 1 else ""
            if rec.failed:
                sub += f" (+{sum(f.get('newton_iterations', 0) for f in rec.failed)} in {len(rec.failed)} failed attempt" \
                       f"{'s' if len(rec.failed) > 1 else ''})"
            log.info("step %d/%d: t = %g s, %d Newton iterations%s (residual %.1e)%s, open %d, stick %d, slip %d, "
                     "%.2f s (%s)", rec.index, len(schedule.times()) - 1, rec.time, row["newton_iterations"], sub,
                     info.residual, lin, info.open, info.stick, info.slip, rec.seconds, rec.progress)
            if rec.index == len(schedule.times()) - 1:
                # no solve follows: the solver's matrices and set-ups (a third of a rank's memory
                # at C5 127k) go before the last outputs and the plots
                model.release_solver()
            record(st)
            if is_out:
                output(k_out[0], rec.index, st)
                k_out[0] += 1

        try:
            state, _ = march(schedule, state, step, on_step, accept=accept if limit is not None else None,
                             max_rejections=schedule.growth_cuts)
        except RunError as exc:
            # a Newton iteration that found no equilibrium with a softening friction law: say what it likely is
            hint = model.mech.law.friction_law.instability_hint
            if hint and "Newton" in str(exc):
                raise RunError(f"{exc}. {hint}") from None
            raise
        bubble = bubble_slip(model, state, net)
        if bubble["faces"]:
            w = bubble["largest"]
            log.warning("%d fault face(s) slip mostly through their face bubble, a cell-local mode rather than a "
                        "motion of the fault's sides (largest: %s face %d, %.3g m², slip %.3g mm of which %.3g mm "
                        "bubble); such faces are slivers or faces of thin cells: their slip is an artefact "
                        "(summary.json slip_bubble; docs/fault_bounds.md, \"a sliver face that runs away\")",
                        bubble["faces"], w["fracture"], w["face"], w["area_m2"], 1e3 * w["slip_m"], 1e3 * w["bubble_m"])
        violations = check_energy(energies)
        for v in violations:
            log.warning("energy estimate violated: %s", v)
        write_pvd(stage / "solution.pvd", pvd)
        write_fractures_csv(stage / "fractures.csv", blocks)
        t_plots = time.perf_counter()
        if mesh.dim == 2:
            tf, tname = time_unit(schedule.end)
            _plot_safely("overpressure and contact", lambda: poro_plots(stage, case.name, mesh, net, s_arc, snapshots,
                                                                        series, schedule.end))
            _plot_safely("monitor", lambda: monitor_plots(stage, case.name, net, s_arc, monitor, snapshots,
                                                          onset.get("time"), tf, f"t ({tname})"))
        else:
            # the face states and onsets are the recorder's (those of summary.json's series)
            last = {"time": state.time, "slip": slip_since_start(state)}
            op = model.cell_pressure(state) - p0
            _plot_safely("3D monitor", lambda: write_3d_plots(stage, collect(
                case.name, schedule.end, fm, model.mech.face_area, recorder, monitor, last, points, op)))
        t_plots = time.perf_counter() - t_plots
        summary = {
            "case": case.name, "version": __version__, "model": "poromechanics",
            "mesh": {"dim": mesh.dim, "cells": mesh.n_cells, "faces": mesh.n_faces, "nodes": mesh.n_nodes,
                     "fracture_faces": net.n_faces, "multiplier_patches": model.mech.patches.summary(),
                     "unknowns": int(model.mech.free.size + model.mech.n_c * model.dim + model.flow_free.size),
                     "blocks": model.block_counts()},
            **({"faults": faults} if faults is not None else {}),
            "choices": ms.choices,
            "steps": steps,
            "energy_check": {"violations": violations, "steps_checked": len(energies)},
            "conductivity_growth": {"max": max((r["conductivity_growth"] for r in steps), default=1.0),
                                    "warned_at_step": warned[0] if warned else None,
                                    "warn_above": CONDUCTIVITY_GROWTH_WARN, "step_limit": limit,
                                    "substeps": sum(r.get("substeps", {}).get("accepted", 1) for r in steps),
                                    "rejected": sum(r.get("substeps", {}).get("rejected", 0) for r in steps)},
            "fracture_means": series,
            "slip_onset": onset or None,
            "slip_bubble": bubble,
            "monitor": {"time": monitor["time"], "overpressure_at_points": monitor["points"],
                        "max_fracture_pressure": monitor["fault_p"], "max_slip": monitor["fault_slip"],
                        "points": {k: np.round(g.cell_centroid[c], 6).tolist() for k, c in points.items()},
                        **recorder.summary(g.cell_centroid)},
            # the time split covers the whole run, the initial equilibrium included; the plots are
            # part of "other"
            "totals": {**clock.totals(ms.solver), "seconds_plots": t_plots,
                       "newton_iterations": int(sum(s["newton_iterations"] for s in steps)),
                       "newton_iterations_failed": int(sum(f.get("newton_iterations", 0) for s in steps
                                                           for f in s.get("failed_attempts", ()))),
                       "linear_iterations_failed": int(sum(sum(f.get("linear_iterations", ())) for s in steps
                                                           for f in s.get("failed_attempts", ())))},
        }
        # README.txt and summary's "legend"; the friction law's state arrays with a law that has one
        bulk_arrays, fracture_arrays = POROMECHANICS_ARRAYS
        write_legend(stage, summary, bulk_arrays, fracture_arrays + tuple(model.friction_fields(state)))
        write_json(stage / "summary.json", summary)
    return summary


def case_wells(case: CaseFile, mesh) -> dict:
    """{well name: cells} of the case's ``[[flow.wells]]`` (empty without)."""
    flow = getattr(case.spec, "flow", None)
    wells = getattr(flow, "wells", None) or ()
    return {w.name: well_cells(mesh, w, f"flow.wells.{w.name}") for w in wells}


def run_folder_wells(folder, centroid, lo, hi) -> tuple[dict, str | None]:
    """({well: cells}, note) of a finished run's folder, from the mesh rebuilt from its case.toml;
    no wells (and a note) when that mesh's cells are not the run's (another version of the
    processor) or it cannot be built. centroid, lo, hi: the run's cells (node means, boxes)."""
    try:
        case = load_case(str(Path(folder) / "case.toml"))
        if not (getattr(case.spec, "flow", None) and case.spec.flow.wells):
            return {}, None
        mesh = build_fractured_mesh(case).mesh
        c = mesh.geometry.cell_centroid
        # the same cells: every rebuilt centroid within half the run's cell box of its node mean
        if len(c) != len(centroid) or np.any(np.abs(c - centroid) > 0.5 * (hi - lo) + 1e-9):
            return {}, "wells left out: the mesh rebuilt from case.toml is not the run's"
        return case_wells(case, mesh), None
    except Exception as exc:            # the figures are still worth having without the wells
        return {}, f"wells left out: {type(exc).__name__}: {exc}"


def replot(run_dir, out=None) -> list[Path]:
    """Write the 3D monitor plots of a finished poromechanics run's folder into ``out`` (default:
    the folder); return the files written (see :func:`polypore.io.monitor3d.from_run_directory`)."""
    d = from_run_directory(run_dir, wells_of=lambda c, lo, hi: run_folder_wells(run_dir, c, lo, hi))
    for note in d.notes:
        log.info("note: %s", note)
    return write_3d_plots(Path(out or run_dir), d)


def _plot_safely(what: str, draw) -> None:
    """Draw plots; a failure is a warning (the run's data are already written)."""
    try:
        draw()
    except Exception as exc:
        log.warning("%s plots not written: %s: %s", what, type(exc).__name__, exc)


def _mstate(st):
    return MechanicsState(st.u, st.lam, st.state, st.time)

