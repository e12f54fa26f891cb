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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..core import live
from ..core.errors import InputError, RunError
from ..io.atomic import atomic_write_text
from ..io.legend import POROMECHANICS_ARRAYS, write_legend
from ..io.monitor3d import collect, from_run_directory, tangential
from ..io.plots import monitor_plots, poro_plots, time_unit
from ..io.plots3d import write_3d_plots
from ..io.results import staged_run_directory, write_json
from ..io.seismicity_plots import seismicity_plot
from ..models.contact import OPEN, SLIP, STICK
from ..models.fracture_geometry import arc_length
from ..models.friction import RateLaw
from ..setup.casefile import CaseFile, load_case
from ..setup.flow import well_cells
from ..setup.meshing import build_fractured_mesh
from ..setup.poromechanics import monitor_points, poro_setup
from ..setup.translate import RUN_POROMECHANICS, case_keys
from .common import RunClock, corner_point_faults
from .march import march
from .recorder import OutputSeries, PoroRecorder
from .seismicity import EventCatalogue

log = logging.getLogger("polypore")


# a face whose tangential jump since the start is above SLIPPED, at least BUBBLE_SHARE of it its
# bubble's and the bubble's part at least BUBBLE_OVER_NODAL × the nodal part's: the sliver of
# docs/fault_bounds.md has 38.9 of 40.5 mm in its bubble (1.6 mm nodal); near C6's tips a bubble
# corrects a nodal jump (0.60 against 1.12 mm) and is not a slip of its own
BUBBLE_SHARE = 0.75
BUBBLE_OVER_NODAL = 3.0
SLIPPED = 1e-4          # m
# rate-and-state: the smallest sub-step is at least time.step / 2^RATE_CUTS (a year to 4e-7 s)
RATE_CUTS = 48
# a step whose rate-law step error (RateLaw.step_error) is above RATE_REJECT × time.rate_tolerance is redone; the
# next step grows at most RATE_GROWTH-fold
RATE_REJECT = 2.0
RATE_GROWTH = 1.5


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


@dataclass
class CoupledRun:
    """What the set-up phase of a poromechanics run makes, besides its initial state and recorder."""

    case: CaseFile
    fm: object                  # FracturedMesh
    model: object               # Poromechanics
    schedule: object            # TimeSchedule
    solver_setup: object        # the mechanics set-up: ``choices`` and ``solver`` for summary.json
    faults: dict | None         # summary.json's faults of a corner-point grid
    points: dict                # {name: cell} of the monitor points


def run_poromechanics(case: CaseFile, out: Path) -> dict:
    """Run a poromechanics case and write its files into ``out``; return the summary: set-up
    (:func:`set_up`), march (:class:`CoupledMarch`), write (:func:`write_results`)."""
    clock = RunClock()
    run, state, recorder = set_up(case)
    with staged_run_directory(out) as stage:
        atomic_write_text(stage / "case.toml", case.to_toml())
        series = OutputSeries(stage)
        recorder.record(state)          # before the output: its VTU holds the onsets up to now
        recorder.output(series, 0, state)
        catalogue = event_catalogue(run)
        with case_keys(RUN_POROMECHANICS):      # errors of the march (time-dependent data, aperture laws, PETSc)
            state = CoupledMarch(run.model, run.schedule, recorder, series, catalogue).run(state)
        if catalogue is not None:
            catalogue.finish(state.time)
            catalogue.write(stage / "events.csv")
            catalogue.write_series(stage / "seismicity.csv")
        summary = write_results(run, recorder, series, state, clock, catalogue)
    return summary


def set_up(case: CaseFile) -> tuple[CoupledRun, object, PoroRecorder]:
    """The mesh, model, schedule and initial state of a poromechanics case, and the run's recorder."""
    fm = build_fractured_mesh(case)
    model, fs, ms = poro_setup(case, fm)
    mesh = fm.mesh
    faults = corner_point_faults(case, fm)
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
        p_ref = ref.pressure(mesh.geometry.cell_centroid)      # outputs: absolute pressure = p_h + p
    p0 = model.cell_pressure(state).copy()
    points = monitor_points(case, mesh)
    recorder = PoroRecorder(model, fm, s_arc, points, case_wells(case, mesh), p0, p_ref, state,
                            schedule.max_conductivity_growth)
    log.info("initial state at t = %g s: %d open, %d stick, %d slip faces (%.2f s)", schedule.start,
             int(np.sum(state.state == OPEN)), int(np.sum(state.state == STICK)), int(np.sum(state.state == SLIP)),
             time.perf_counter() - t0)
    return CoupledRun(case, fm, model, schedule, ms, faults, points), state, recorder


class CoupledMarch:
    """The march of a poromechanics run: the model's implicit-Euler steps over the schedule
    (:func:`polypore.runs.march.march`), each step recorded and, at output times, written.

    model : Poromechanics; schedule : TimeSchedule; recorder : PoroRecorder; series : OutputSeries.
    """

    def __init__(self, model, schedule, recorder: PoroRecorder, series: OutputSeries,
                 catalogue: EventCatalogue | None = None):
        self.model, self.schedule, self.recorder, self.series = model, schedule, recorder, series
        self.catalogue = catalogue
        self.limit = schedule.max_conductivity_growth
        self.n_steps = len(schedule.times()) - 1
        # a rate law's steps follow the slip rate (years between events, milliseconds inside one)
        self.rate_law = isinstance(model.mech.law.friction_law, RateLaw)
        self.rate_tolerance = schedule.rate_tolerance

    def run(self, state):
        """March from ``state``; return the final state."""
        cuts = max(self.schedule.growth_cuts, RATE_CUTS) if self.rate_law else self.schedule.growth_cuts
        try:
            state, _ = march(self.schedule, state, self.step, self.on_step,
                             accept=self.accept if self.limit is not None or self.rate_law else None,
                             max_rejections=cuts)
        except RunError as exc:
            # a Newton iteration that found no equilibrium with a softening friction law: say what it likely is
            hint = self.model.mech.law.friction_law.instability_hint
            if hint and "Newton" in str(exc):
                raise RunError(f"{exc}. {hint}") from None
            raise
        return state

    def step(self, st, ta, tb):
        new, info = self.model.step(st, tb - ta, tb)
        out = {"info": info, "dt": tb - ta}
        if info.rate_error is not None:
            out["rate_rejection"], out["size_factor"] = rate_step_control(info.rate_error, self.rate_tolerance)
        if self.catalogue is not None:
            # the face slip rates and slip increments, for the catalogue once the sub-step is accepted
            m = self.model
            rate = m.mech.face_values(new.friction[:, 1])
            slip = tangential(m.jumps(new.u) - m.jumps(st.u), m.mech.normal)
            out["seismic"] = (ta, tb, rate, slip, m.injection_rate(tb) * (tb - ta))
        return new, out

    def accept(self, sub):
        """None, or why a converged step is redone at a smaller size (time.max_conductivity_growth;
        a rate law's sub-step, :func:`rate_step_control`)."""
        info = sub["info"]
        g, limit = info.conductivity_growth, self.limit
        if limit is not None and g > limit:
            return f"a fracture conductivity grew {g:.2g}-fold, above {limit:g}"
        return sub.get("rate_rejection")

    def on_step(self, rec, st, is_out):
        """After a schedule step: record it, log it, write its outputs at an output time."""
        if self.catalogue is not None:
            for sub in rec.substeps:          # the accepted sub-steps, in order (their arrays go)
                if "seismic" in sub:
                    self.catalogue.add(*sub.pop("seismic"))
        row = self.recorder.step_row(rec)
        _log_step(rec, row, self.n_steps)
        if rec.index == self.n_steps:
            # no solve follows: the solver's matrices and set-ups (a third of a rank's memory
            # at C5 127k) go before the last outputs and the plots
            self.model.release_solver()
        self.recorder.record(st)
        if is_out:
            self.recorder.output(self.series, rec.index, st)


def rate_step_control(rate_error: tuple, tolerance: float) -> tuple[str | None, float]:
    """A rate law's sub-step: (why it is redone, or None; the next size's factor), from its
    :meth:`RateLaw.step_error` (the largest change of ln V, times the state's sensitivity to it
    where that is above 1; the patches where it was too long for the state) and time.rate_tolerance. The change per step ∝ Δt: the next size aims at
    0.9 tol, growing at most RATE_GROWTH-fold so that the steps' lag (implicit Euler's mean rate)
    changes smoothly; a step too long for the state is followed by at most half its size."""
    err, soft = rate_error
    factor = float(np.clip(0.9 / max(err / tolerance, 1e-12), 0.2, RATE_GROWTH))
    if soft:
        return f"the step was too long for the friction state on {soft} patch(es) (ΔtV/D_c ≳ a/b)", min(factor, 0.5)
    if err > RATE_REJECT * tolerance:
        return (f"the slip rate's logarithm changed by {err:.2g} in the step (with the state's sensitivity), above "
                f"{RATE_REJECT:g} × time.rate_tolerance ({tolerance:g})"), factor
    return None, factor


def _log_step(rec, row: dict, n_steps: int) -> None:
    """The progress line of a schedule step (``row``: its summary.json row)."""
    info = rec.info["info"]
    n_sub = len(rec.substeps)
    lin = f", {sum(row['linear_iterations'])} GMRES iterations" if "linear_iterations" in row else ""
    sub = f" in {n_sub} sub-steps" if n_sub > 1 else ""
    if rec.failed:
        sub += f" (+{sum(f.get('newton_iterations', 0) for f in rec.failed)} in {len(rec.failed)} failed attempt" \
               f"{'s' if len(rec.failed) > 1 else ''})"
    log.info("step %d/%d: t = %g s, %d Newton iterations%s (residual %.1e)%s, open %d, stick %d, slip %d, "
             "%.2f s (%s)", rec.index, n_steps, rec.time, row["newton_iterations"], sub,
             info.residual, lin, info.open, info.stick, info.slip, rec.seconds, rec.progress)


def event_catalogue(run: CoupledRun) -> EventCatalogue | None:
    """The run's event catalogue with a rate law (None otherwise): threshold contact.seismic_rate."""
    model = run.model
    if not isinstance(model.mech.law.friction_law, RateLaw) or not model.n_ff:
        return None
    mech, net = model.mech, run.fm.network
    contact = run.case.spec.contact
    mu = mech.face_values(mech.mu[mech.patches.plus_cell])
    return EventCatalogue(net.fracture, tuple(net.names), mech.face_area, mu,
                          run.fm.mesh.geometry.face_centroid[net.faces], run.fm.mesh.dim,
                          float(contact.seismic_rate))


def write_results(run: CoupledRun, recorder: PoroRecorder, series: OutputSeries, state, clock: RunClock,
                  catalogue: EventCatalogue | None = None) -> dict:
    """The write phase: solution.pvd, fractures.csv, the plots, README.txt and summary.json (returned)
    into the series' folder, after the checks of the final state (bubble slip, energy estimate)."""
    model, mesh, net = run.model, run.fm.mesh, run.fm.network
    bubble = bubble_slip(model, state, net)
    if bubble["faces"]:
        w = bubble["largest"]
        log.warning("%d fault face(s) slip mostly through their face bubble, a cell-local mode rather than a "
                    "motion of the fault's sides (largest: %s face %d, %.3g m², slip %.3g mm of which %.3g mm "
                    "bubble); such faces are slivers or faces of thin cells: their slip is an artefact "
                    "(summary.json slip_bubble; docs/fault_bounds.md, \"a sliver face that runs away\")",
                    bubble["faces"], w["fracture"], w["face"], w["area_m2"], 1e3 * w["slip_m"], 1e3 * w["bubble_m"])
    recorder.check_energy()
    series.write()
    t_plots = time.perf_counter()
    _plots(run, recorder, series.folder, state, catalogue)
    t_plots = time.perf_counter() - t_plots
    summary = {
        "case": run.case.name, "version": __version__, "model": "poromechanics",
        "mesh": {"dim": mesh.dim, "cells": mesh.n_cells, "faces": mesh.n_faces, "nodes": mesh.n_nodes,
                 "fracture_faces": net.n_faces, "multiplier_patches": model.mech.patches.summary(),
                 "unknowns": int(model.n_unknowns),
                 "blocks": model.block_counts()},
        **({"faults": run.faults} if run.faults is not None else {}),
        "choices": run.solver_setup.choices,
        **recorder.summary(bubble),
        **({"seismicity": catalogue.summary()} if catalogue is not None else {}),
        # the time split covers the whole run, the initial equilibrium included; the plots are
        # part of "other"
        "totals": {**clock.totals(run.solver_setup.solver), "seconds_plots": t_plots, **recorder.totals()},
    }
    # README.txt and summary's "legend"; the friction law's state arrays with a law that has one
    bulk_arrays, fracture_arrays = POROMECHANICS_ARRAYS
    write_legend(series.folder, summary, bulk_arrays, fracture_arrays + tuple(model.friction_fields(state)))
    write_json(series.folder / "summary.json", summary)
    return summary


def _plots(run: CoupledRun, recorder: PoroRecorder, stage: Path, state, catalogue: EventCatalogue | None = None
           ) -> None:
    """The monitor plots of a finished run: 2D overpressure, contact and monitor plots, or the 3D
    monitor plots (:mod:`polypore.io.plots3d`), and seismicity.png with a rate law; a plot that
    fails is a warning."""
    case, fm, model, end = run.case, run.fm, run.model, run.schedule.end
    if catalogue is not None:
        mu_s = float(catalogue.shear_modulus.max()) if catalogue.shear_modulus.size else 0.0
        _plot_safely("seismicity", lambda: seismicity_plot(stage / "seismicity.png", case.name, catalogue.series(),
                                                           catalogue.events, fm.mesh.dim, catalogue.threshold,
                                                           mu_s, end))
    mesh, net, s_arc = fm.mesh, fm.network, recorder.s_arc
    if mesh.dim == 2:
        tf, tname = time_unit(end)
        _plot_safely("overpressure and contact", lambda: poro_plots(stage, case.name, mesh, net, s_arc,
                                                                    recorder.snapshots, recorder.series, end))
        _plot_safely("monitor", lambda: monitor_plots(stage, case.name, net, s_arc, recorder.monitor,
                                                      recorder.snapshots, recorder.onset.get("time"), tf,
                                                      f"t ({tname})"))
    else:
        # the face states and onsets are the recorder's (those of summary.json's series)
        last = {"time": state.time, "slip": recorder.slip_since_start(state), **recorder.fault_stress(state)}
        op = model.cell_pressure(state) - recorder.p0
        _plot_safely("3D monitor", lambda: write_3d_plots(stage, collect(
            case.name, end, fm, model.mech.face_area, recorder.fault_monitor, recorder.monitor, last, run.points,
            op)))


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
