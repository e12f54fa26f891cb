"""Save the Newton Jacobians of a poromechanics run, for solver experiments (benchmarks/solver_lab.py).

    .venv-fast/bin/python benchmarks/dump_jacobians.py CASE [--set KEY=VALUE ...] [--steps 1 4 8]
        [--out benchmarks/out/jac-CASE]

Runs the case's poromechanics model through the Python API with ``solver.linear`` of the case
(``--set solver.linear=pardiso`` for a Newton path that does not depend on a Krylov floor) and
writes, for every Newton iteration of the listed steps, ``J_s<step>_k<iteration>.npz``
(scipy.sparse.save_npz, uncompressed), ``rhs_...npy`` and ``pns_...npy`` (the pressure near-null
space), plus ``meta.npz`` (n_u, d, n_l, the condensation data c_σ and n⁺, rigid-body modes, the
displacement dofs' node coordinates, the cells' ijk and volumes of a corner-point grid) and
``solves.json`` (Krylov iterations, wall and CPU seconds of each solve of the run). The run stops
after the last listed step.
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
        return self.inner.krylov_iterations

    krylov_iterations = iterations

    @property
    def backend(self) -> str:
        return self.inner.backend

    def release(self) -> None:
        self.inner.release()

    def set_pressure_nullspace(self, b) -> None:
        self.pressure_nullspace = b

    @property
    def takes_target(self):
        """True: Newton's KrylovTarget (row weights, forcing term) is saved with the system and
        passed on to an iterative inner solver (so the Newton path is the run's)."""
        return True

    @property
    def takes_blocks(self):
        """As the inner solver: the model hands it the Jacobian by blocks (saved assembled)."""
        return self.inner.takes_blocks

    def solve(self, J, rhs, target=None):
        self.k += 1
        tag = f"s{self.step:03d}_k{self.k:02d}"
        if self.step in self.save:
            sp.save_npz(self.out / f"J_{tag}.npz", sp.csr_matrix(J.tocsr() if hasattr(J, "tocsr") else J),
                        compressed=False)
            np.save(self.out / f"rhs_{tag}.npy", np.asarray(rhs))
            np.save(self.out / f"pns_{tag}.npy", np.asarray(self.pressure_nullspace))
            if target is not None and target.weights is not None:
                np.save(self.out / f"w_{tag}.npy", np.asarray(target.weights))
                np.save(self.out / f"eta_{tag}.npy", np.asarray(target.rtol))
        self.inner.set_pressure_nullspace(self.pressure_nullspace)
        t0, c0 = time.perf_counter(), time.process_time()
        x = self.inner.solve(J, rhs, target=target) if self.inner.takes_target else self.inner.solve(J, rhs)
        its = self.iterations
        self.log.append({"tag": tag, "step": self.step, "newton": self.k, "saved": self.step in self.save,
                         "krylov": int(its[-1]) if its else None, "seconds": time.perf_counter() - t0,
                         "cpu": time.process_time() - c0})
        return x


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", help="built-in case name or case file")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="case overrides")
    ap.add_argument("--steps", type=int, nargs="+", default=[1, 4, 8], help="steps whose systems are saved")
    ap.add_argument("--out", default=None, help="folder (default benchmarks/out/jac-<case>)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
    from polypore.runs.march import march
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh
    from polypore.setup.poromechanics import poro_setup

    out = Path(args.out or f"benchmarks/out/jac-{Path(args.case).stem}")
    out.mkdir(parents=True, exist_ok=True)
    case = load_case(args.case, args.set)
    t0 = time.perf_counter()
    fm = build_fractured_mesh(case)
    model, fs, _ = poro_setup(case, fm)
    mech = model.mech
    cond = mech.condensation()
    from polypore.setup.meshing import cornerpoint_of

    cp = cornerpoint_of(fm.mesh)
    extra = {} if cp is None else {"cell_ijk": cp[1].cell_ijk}
    np.savez(out / "meta.npz", n_u=mech.free.size, d=model.dim, n_l=mech.n_c * model.dim, scale=cond.scale,
             normal=cond.normal, rho=cond.rho, near_nullspace=mech.rigid_modes(), cells=fm.mesh.n_cells,
             cell_volume=fm.mesh.geometry.cell_volume,
             flow_kind=model.unknowns.kind, **extra)
    rec = Recorder(model.solver, out, set(args.steps))
    model.solver = rec
    print(f"set up {fm.mesh.n_cells} cells, {model.n_unknowns} unknowns in {time.perf_counter() - t0:.1f} s",
          flush=True)
    sched = fs.schedule
    # as runs/coupled.py: the in-situ state of [initial_state] when the case has one
    state = (model.initial_state(fs.initial_pressure, t0=sched.start) if model.reference is None
             else model.reference_state(fs.initial_pressure, t0=sched.start))
    times = sched.times()
    last = max(args.steps)
    sched = dataclasses.replace(sched, end=float(times[last]), output_times=())

    def step(st, t0_, t1_):
        n = int(np.searchsorted(times, t1_ - 1e-9 * sched.step))
        if rec.step != n:
            rec.step, rec.k = n, 0
        return model.step(st, t1_ - t0_, t1_, energy=False)

    def on_step(r, st, _):
        info = r.info
        print(f"step {r.index}: t = {r.time:g} s, {info.iterations} Newton, Krylov {info.linear_iterations}, "
              f"{info.open}/{info.stick}/{info.slip} open/stick/slip, {r.seconds:.1f} s", flush=True)
        (out / "solves.json").write_text(json.dumps(rec.log, indent=1) + "\n")

    march(sched, state, step, on_step)
    return 0


if __name__ == "__main__":
    sys.exit(main())
