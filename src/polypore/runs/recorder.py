"""What a run records while it marches, for the files it writes at the end.

:class:`OutputSeries`: the numbered output steps of any run (bulk_NNNN.vtu / fractures_NNNN.vtu
pairs), their solution.pvd entries and fractures.csv rows. :class:`PoroRecorder`: everything a
poromechanics run keeps step by step (summary.json's step rows, the energy audit, fracture means,
monitor series, slip onset, the plots' snapshots), one object in place of loose accumulators.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..io.monitor3d import StepRecorder, tangential
from ..io.results import fracture_rows, write_fractures_csv
from ..io.vtu import symmetric_tensor, write_bulk_vtu, write_fracture_vtu, write_pvd
from ..models.contact import SLIP, STATE_NAMES
from ..models.energy import check_energy
from ..models.fault_stress import coulomb_fields
from ..models.friction import failure_coefficient

log = logging.getLogger("polypore")
# a step whose fracture conductivity grows more than this (aperture ×10 with the cubic law), on
# faces carrying flow, is warned of: the fluxes lag one step (Poromechanics.conductivity_growth).
# Growth does not measure the error: on the tilted grid of docs/fault_bounds.md 2e8 went with slip
# 60 % above its Δt → 0 value, on C6 (coarse) 54 at 5-day steps with 3.5 % and 2e4 at 30-day
# steps with 2.7 % at the end; the warning asks for the check that does (a shorter step)
CONDUCTIVITY_GROWTH_WARN = 1e3


class OutputSeries:
    """The output steps of a run in its folder: bulk_NNNN.vtu / fractures_NNNN.vtu pairs numbered
    from 0, their solution.pvd entries and fractures.csv row blocks (:meth:`write`).

    folder : the run's (staging) folder.
    """

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.pvd: list[tuple] = []          # (time, file, part) of solution.pvd
        self.blocks: list[dict] = []        # fractures.csv columns of each output step
        self.count = 0                      # outputs so far: the number of the next one

    def files(self) -> tuple[Path, Path]:
        """The paths of the next output's bulk and fracture VTU files."""
        return self.folder / f"bulk_{self.count:04d}.vtu", self.folder / f"fractures_{self.count:04d}.vtu"

    def add(self, time: float, block: dict) -> None:
        """Count the next output (its VTU files written) at ``time`` (s) with its fractures.csv rows."""
        bulk, fractures = self.files()
        self.pvd.extend([(time, bulk.name, 0), (time, fractures.name, 1)])
        self.blocks.append(block)
        self.count += 1

    def write(self) -> None:
        """Write solution.pvd and fractures.csv."""
        write_pvd(self.folder / "solution.pvd", self.pvd)
        write_fractures_csv(self.folder / "fractures.csv", self.blocks)


class PoroRecorder:
    """The record of a poromechanics run, step by step.

    :meth:`record` takes a state (the initial one and each schedule step's end), :meth:`step_row`
    a schedule step's :class:`polypore.runs.march.StepRecord`, :meth:`output` writes an output
    step's VTU files; :meth:`summary` and :meth:`totals` are summary.json's parts.

    Parameters
    ----------
    model : Poromechanics
    fm : FracturedMesh
    s_arc : (n_ff,) arc length of each fracture face along its fracture (m)
    points : {name: cell} of the monitor points
    wells : {name: cells} of the wells (may be empty)
    p0 : (n_cells,) initial cell pressure (Pa), the reference of the overpressure
    p_ref : (n_cells,) pressure added to the model's for the absolute pressure of the outputs (Pa)
    start : the initial state; its jumps are the reference of the slip
    growth_limit : time.max_conductivity_growth (None: no limit)
    """

    def __init__(self, model, fm, s_arc, points: dict, wells: dict, p0, p_ref, start, growth_limit=None):
        self.model, self.fm, self.s_arc = model, fm, s_arc
        net = fm.network
        self.points, self.p0, self.p_ref, self.growth_limit = points, p0, p_ref, growth_limit
        # fault-face area fractions, onsets and well series (summary.json monitor, 3D plots)
        self.fault_monitor = StepRecorder(net.names, net.fracture, model.mech.face_area, wells,
                                          fm.mesh.geometry.cell_volume)
        self.q_start = model.jumps(start.u)
        # the reference of ΔCFS and the law's failure coefficient per face (the maps of each output)
        self.lam_start = np.array(start.lam, float)
        mech = model.mech
        self.failure_mu = mech.face_values(failure_coefficient(mech.law.friction_law, mech.n_c)) if model.n_ff \
            else np.zeros(0)
        self.monitor = {"time": [], "points": {k: [] for k in points}, "fault_p": {k: [] for k in net.names},
                        "fault_slip": {k: [] for k in net.names}}
        self.onset: dict = {}
        self.series: list[dict] = []        # area-weighted mean aperture and p_f of each fracture per time
        self.snapshots: list[dict] = []     # the fields of each output step for the 2D plots
        self.steps: list[dict] = []         # summary.json's steps
        self.energies: list = []            # every accepted sub-step's energy terms
        self.violations: list = []          # of the energy estimate (:meth:`check_energy`)
        self.warned_at: int | None = None   # the step of the conductivity-growth warning (once per run)

    def slip_since_start(self, st) -> np.ndarray:
        """(n_ff,) tangential jump since the initial state (m)."""
        return tangential(self.model.jumps(st.u) - self.q_start, self.model.mech.normal)

    def fault_stress(self, st) -> dict:
        """ΔCFS since the start, slip tendency, Δτ and Δσ_n′ per fracture face (n_ff,) of the state
        ``st`` (:func:`polypore.models.fault_stress.coulomb_fields`)."""
        return coulomb_fields(st.lam, self.lam_start, self.model.mech.normal, self.failure_mu)

    def record(self, st) -> None:
        """Record the state ``st``: fracture means, monitor series, face states and the slip onset."""
        model, net = self.model, self.fm.network
        fq = model.fracture_quantities(st)
        A = model.mech.face_area
        row = {"time": st.time}
        for i, name in enumerate(net.names):
            sel = net.fracture == i
            w = A[sel].sum()
            row[name] = (float((A[sel] * fq["aperture"][sel]).sum() / w),
                         float((A[sel] * fq["p_f"][sel]).sum() / w))
        self.series.append(row)
        monitor, p0 = self.monitor, self.p0
        monitor["time"].append(st.time)
        pc = model.cell_pressure(st)
        for k, cell in self.points.items():
            monitor["points"][k].append(float(pc[cell] - p0[cell]))
        self.fault_monitor.add(st.time, st.state, pc - p0, fq["p_f"])
        slip = self.slip_since_start(st)
        for i, name in enumerate(net.names):
            sel = net.fracture == i
            monitor["fault_p"][name].append(float(fq["p_f"][sel].max()) if sel.any() else 0.0)
            monitor["fault_slip"][name].append(float(slip[sel].max()) if sel.any() else 0.0)
        if not self.onset and np.any(st.state == SLIP):
            x = self.fm.mesh.geometry.face_centroid[net.faces][st.state == SLIP]
            self.onset.update({"time": st.time, "previous_time": monitor["time"][-2] if len(monitor["time"]) > 1
                               else st.time, "faces": int(np.sum(st.state == SLIP)),
                               "first_slipping_faces": np.round(x, 3).tolist()[:20]})

    def step_row(self, rec) -> dict:
        """Record a schedule step (a StepRecord whose sub-steps' infos are ``{"info": StepInfo, "dt":
        s}``): its summary.json row (returned), its energy terms; warn once of a conductivity growth
        above CONDUCTIVITY_GROWTH_WARN."""
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
        if growth > CONDUCTIVITY_GROWTH_WARN and self.warned_at is None:
            self.warned_at = rec.index
            log.warning("step %d (t = %g s): the fracture conductivity grew up to %.1e-fold on faces that carry "
                        "flow; the step's fluxes use the previous step's conductivity (scheme.md §6), so slip and "
                        "fault pressure after it may depend on time.step (here Δt = %g s): compare with a "
                        "shorter step, or set time.max_conductivity_growth (docs/fault_bounds.md, \"The time "
                        "step\"; summary.json steps[].conductivity_growth)",
                        rec.index, rec.time, growth, rec.dt)
        if info.energy is not None:
            row["energy"] = info.energy.summary()           # the last sub-step's; all are checked
            self.energies.extend(i.energy for i in subs if i.energy is not None)
        self.steps.append(row)
        return row

    def output(self, series: OutputSeries, n: int, st) -> None:
        """Write the state ``st`` of schedule step ``n`` as the next output of ``series`` (bulk and
        fracture VTU files, fractures.csv rows) and keep its fields for the plots."""
        model, mesh, net = self.model, self.fm.mesh, self.fm.network
        g = mesh.geometry
        fq = model.fracture_quantities(st)
        cfs = self.fault_stress(st)
        p = model.cell_pressure(st)
        eff, tot = model.stresses(st)
        (eff, comps), (tot, _) = symmetric_tensor(eff), symmetric_tensor(tot)
        bulk, fractures = series.files()
        write_bulk_vtu(bulk, mesh, cell_data={
            "pressure": p + self.p_ref, "overpressure": p - self.p0, "displacement": model.mech.cell_displacement(st),
            "effective_stress": eff, "total_stress": tot},
            point_data={"displacement": model.mech.node_displacement(st)},  # for Warp By Vector
            component_names={"effective_stress": comps, "total_stress": comps})
        write_fracture_vtu(fractures, self.fm, cell_data={
            "jump": fq["jump"], "jump_n": fq["jump_n"], "jump_t": fq["jump_t"], "lambda": st.lam,
            "lambda_n": fq["lambda_n"], "lambda_t": fq["lambda_t"], "state": fq["state"].astype(np.int32),
            "aperture": fq["aperture"], "p_f": fq["p_f"], **model.friction_fields(st), **cfs,
            # every step's onset (the recorder saw this time already): replots draw the same
            "first_slip": self.fault_monitor.onset.copy()})
        series.add(st.time, fracture_rows(n, st.time, net.names, net.fracture, g.face_centroid[net.faces],
                                          self.s_arc, model.mech.face_area, fq["jump"], model.mech.normal, st.lam,
                                          [STATE_NAMES[k] for k in fq["state"]], fq["aperture"], fq["p_f"],
                                          cfs["delta_cfs"], cfs["slip_tendency"]))
        self.snapshots.append({"time": st.time, "overpressure": p - self.p0, "state": fq["state"].copy(),
                               "lambda_n": fq["lambda_n"].copy(), "jump_t": fq["jump_t"].copy(),
                               "aperture": fq["aperture"].copy(), "slip": self.slip_since_start(st),
                               "delta_cfs": cfs["delta_cfs"], "slip_tendency": cfs["slip_tendency"]})

    def check_energy(self) -> list:
        """Check the energy estimate on every recorded sub-step; log and return the violations."""
        self.violations = check_energy(self.energies)
        for v in self.violations:
            log.warning("energy estimate violated: %s", v)
        return self.violations

    def summary(self, slip_bubble: dict) -> dict:
        """summary.json's steps, energy_check, conductivity_growth, fracture_means, slip_onset,
        slip_bubble (given: :func:`polypore.runs.coupled.bubble_slip`) and monitor."""
        steps, monitor = self.steps, self.monitor
        centroid = self.fm.mesh.geometry.cell_centroid
        return {
            "steps": steps,
            "energy_check": {"violations": self.violations, "steps_checked": len(self.energies)},
            "conductivity_growth": {"max": max((r["conductivity_growth"] for r in steps), default=1.0),
                                    "warned_at_step": self.warned_at,
                                    "warn_above": CONDUCTIVITY_GROWTH_WARN, "step_limit": self.growth_limit,
                                    "substeps": sum(r.get("substeps", {}).get("accepted", 1) for r in steps),
                                    "rejected": sum(r.get("substeps", {}).get("rejected", 0) for r in steps)},
            "fracture_means": self.series,
            "slip_onset": self.onset or None,
            "slip_bubble": slip_bubble,
            "monitor": {"time": monitor["time"], "overpressure_at_points": monitor["points"],
                        "max_fracture_pressure": monitor["fault_p"], "max_slip": monitor["fault_slip"],
                        "points": {k: np.round(centroid[c], 6).tolist() for k, c in self.points.items()},
                        **self.fault_monitor.summary(centroid)},
        }

    def totals(self) -> dict:
        """summary.json totals' Newton iterations of the accepted steps and the Newton and linear
        iterations of the failed attempts."""
        steps = self.steps
        return {"newton_iterations": int(sum(s["newton_iterations"] for s in steps)),
                "newton_iterations_failed": int(sum(f.get("newton_iterations", 0) for s in steps
                                                    for f in s.get("failed_attempts", ()))),
                "linear_iterations_failed": int(sum(sum(f.get("linear_iterations", ())) for s in steps
                                                    for f in s.get("failed_attempts", ())))}

