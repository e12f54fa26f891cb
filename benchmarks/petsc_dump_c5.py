"""Save the Newton Jacobians of a C5 (``dfm-3d``) run for the PETSc solver benchmark.

    .venv/bin/python benchmarks/petsc_dump_c5.py [--size 0.047] [--steps 1 2 10 25] [--out benchmarks/out/c5-jacobians]

benchmarks/dump_jacobians.py for ``dfm-3d`` with linear displacements (this script's options). Runs
the poromechanics model through the Python API (``--linear``, default PARDISO) and writes, for
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
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dump_jacobians  # noqa: E402


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
    argv = ["dfm-3d", "--out", args.out, "--steps", *map(str, args.steps)]
    for ov in (f"mesh.size={args.size:g}", "mechanics.order=1", f"mechanics.bubbles={args.bubbles}",
               f"solver.linear={args.linear}"):
        argv += ["--set", ov]
    return dump_jacobians.main(argv)


if __name__ == "__main__":
    sys.exit(main())
