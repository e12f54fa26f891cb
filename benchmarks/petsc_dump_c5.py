"""Save the Newton Jacobians of a C5 (``dfm-3d``) run for the PETSc solver benchmark.

    .venv/bin/python benchmarks/petsc_dump_c5.py [--size 0.047] [--steps 1 2 10 25] [--out benchmarks/out/c5-jacobians]

Runs the poromechanics model through the Python API (``--linear``, default PARDISO) and writes, for
every Newton iteration of the listed steps, ``J_s<step>_k<iteration>.npz`` (scipy.sparse.save_npz,
uncompressed) and ``rhs_s<step>_k<iteration>.npy``, plus ``meta.npz`` with what the block solvers
are built from (n_u, d, n_l, the condensation data c_σ and n⁺, the rigid-body modes; ``pns_*.npy``
the pressure near-null space of each system) and ``solves.json`` with the Krylov iterations, wall
and CPU seconds of each solve in the run. The run goes on to the last listed step (steps in between
are solved, not saved), with the run's step cutting (a failed step is retried as two halves, whose
systems are saved too). Needs the main venv (numpy 2 is fine); benchmarks/petsc_solvers.py reads the
files in either venv.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp


class Recorder:
    """Wraps the model's block solver: saves each system, then solves it with the wrapped solver."""

    def __init__(self, inner, out: Path, save: set[int]):
        self.inner, self.out, self.save = inner, out, save
        self.step = self.k = 0
        self.log = []
        self.pressure_nullspace = None     # set by the model before each step (step_context)

    @property
    def iterations(self):
        return getattr(self.inner, "iterations", self.inner.stats.iterations)

    @property
    def takes_target(self):
        """True: Newton's KrylovTarget (row weights, forcing term) is saved with the system and
        passed on to an iterative inner solver (so the Newton path is the run's)."""
        return True

    def solve(self, J, rhs, target=None):
        self.k += 1
        tag = f"s{self.step:03d}_k{self.k:02d}"
        if self.step in self.save:
            sp.save_npz(self.out / f"J_{tag}.npz", sp.csr_matrix(J), compressed=False)
            np.save(self.out / f"rhs_{tag}.npy", np.asarray(rhs))
            np.save(self.out / f"pns_{tag}.npy", np.asarray(self.pressure_nullspace))
            if target is not None and target.weights is not None:
                np.save(self.out / f"w_{tag}.npy", np.asarray(target.weights))
                np.save(self.out / f"eta_{tag}.npy", np.asarray(target.rtol))
        if hasattr(self.inner, "pressure_nullspace"):
            self.inner.pressure_nullspace = self.pressure_nullspace
        t0, c0 = time.perf_counter(), time.process_time()
        x = (self.inner.solve(J, rhs, target=target) if getattr(self.inner, "takes_target", False)
             else self.inner.solve(J, rhs))
        its = self.iterations
        self.log.append({"tag": tag, "step": self.step, "newton": self.k, "saved": self.step in self.save,
                         "krylov": int(its[-1]) if its else None, "seconds": time.perf_counter() - t0,
                         "cpu": time.process_time() - c0})
        return x


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.047, help="mesh.size (0.047: 46k cells; 0.1: 5k)")
    ap.add_argument("--bubbles", choices=("one-sided", "two-sided"), default="two-sided")
    ap.add_argument("--steps", type=int, nargs="+", default=[1, 2, 10, 25], help="steps whose systems are saved")
    ap.add_argument("--out", default="benchmarks/out/c5-jacobians")
    ap.add_argument("--linear", default="pardiso",
                    help="solver.linear of the run (default pardiso: the Newton path does not depend on a "
                         "Krylov floor; block-amg records today's solver)")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh
    from polypore.setup.poromechanics import poro_setup

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    case = load_case("dfm-3d", [f"mesh.size={args.size:g}", "mechanics.order=1", f"mechanics.bubbles={args.bubbles}",
                                f"solver.linear={args.linear}"])
    t0 = time.perf_counter()
    fm = build_fractured_mesh(case)
    model, fs, _ = poro_setup(case, fm)
    inner = model.solver
    mech = model.mech
    cond = mech.condensation()
    np.savez(out / "meta.npz", n_u=mech.free.size, d=model.dim, n_l=model.n_ff * model.dim, scale=cond.scale,
             normal=cond.normal, rho=cond.rho, near_nullspace=mech.rigid_modes(), cells=fm.mesh.n_cells,
             size=args.size)
    rec = Recorder(inner, out, set(args.steps))
    model.solver = rec
    print(f"set up {fm.mesh.n_cells} cells, {model.n_unknowns} unknowns in {time.perf_counter() - t0:.1f} s",
          flush=True)
    from polypore.runs.march import march

    sched = fs.schedule
    state = model.initial_state(fs.initial_pressure, t0=sched.start)
    times = sched.times()
    last = max(args.steps)
    sched = dataclasses.replace(sched, end=float(times[last]), output_times=())

    def step(st, t0_, t1_):
        # the schedule step containing t1 (a cut step's halves share its number)
        n = int(np.searchsorted(times, t1_ - 1e-9 * sched.step))
        if rec.step != n:
            rec.step, rec.k = n, 0
        return model.step(st, t1_ - t0_, t1_, energy=False)

    def on_step(r, st, _):
        info = r.info
        print(f"step {r.index}: t = {r.time:g} s, {info.iterations} Newton, Krylov {info.linear_iterations}, "
              f"{info.open}/{info.stick}/{info.slip} open/stick/slip, {r.cuts} cuts, {r.seconds:.1f} s", flush=True)
        (out / "solves.json").write_text(json.dumps(rec.log, indent=1) + "\n")

    march(sched, state, step, on_step)
    return 0


if __name__ == "__main__":
    sys.exit(main())
