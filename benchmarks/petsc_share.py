"""PETSc's own memory per rank in a ``polypore run``: the largest ``PetscMallocGetCurrentUsage``
after any Krylov solve (docs/parallel.md, "C5 at 127k cells", item 1). hypre's allocations are not
PETSc's and are not counted.

    OMP_NUM_THREADS=1 PETSC_OPTIONS=-malloc_debug mpiexec -x PETSC_OPTIONS -n 2 .venv-mpi/bin/python \\
        benchmarks/petsc_share.py run dfm-3d --set mesh.size=0.047 --set solver.linear=block-petsc \\
        --set time.end=4 --set 'time.output_times=[4.0]' [--set solver.petsc.pc_type=fieldsplit]

PETSc tracks its current usage only with ``-malloc_debug`` (or ``-malloc_view``); without it the
figure printed is 0. Every rank prints one line to stderr.
"""

from __future__ import annotations

import ctypes
import sys


def main(argv) -> int:
    from mpi4py import MPI
    from petsc4py import PETSc  # noqa: F401  (loads libpetsc)

    import polypore.solvers.petsc as spetsc
    from polypore.cli import main as cli

    path = sorted({ln.split()[-1] for ln in open("/proc/self/maps") if "libpetsc" in ln})[0]
    lib = ctypes.CDLL(path)
    usage, best = ctypes.c_double(), [0.0]
    krylov = spetsc.KrylovDriver._krylov

    def measured(self, *a, **k):
        out = krylov(self, *a, **k)
        lib.PetscMallocGetCurrentUsage(ctypes.byref(usage))
        best[0] = max(best[0], usage.value)
        return out

    spetsc.KrylovDriver._krylov = measured
    rc = cli(argv)
    print(f"rank {MPI.COMM_WORLD.Get_rank()}: PETSc's current usage after a Krylov solve, largest "
          f"{best[0] / 2**20:.1f} MB", file=sys.stderr)
    return rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
