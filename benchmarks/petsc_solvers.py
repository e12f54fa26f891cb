"""PETSc against today's pyamg: 3D elasticity and C5's Newton systems (issue 16, docs/parallel.md).

    .venv-mpi/bin/python benchmarks/petsc_solvers.py elasticity [--cells 32 55 69] [--ranks 1 2]
    .venv-mpi/bin/python benchmarks/petsc_solvers.py c5 [--dir benchmarks/out/c5-jacobians] [--tags s001_k01 ...]

``elasticity``: the displacement block of polypore's VEM elasticity on an n³ Cartesian mesh of the
unit cube (no fracture, clamped at z = 0, a uniform load), 3 (n + 1)² n unknowns: n = 32, 55, 69 give
1.0e5, 5.2e5, 1.0e6. CG to 1e-8 with pyamg smoothed aggregation (block_contact._amg, the AMG of
today's block solvers; one rank), PETSc GAMG (block size 3, rigid-body near-null space) and hypre
BoomerAMG (nodal coarsening, rigid-body interpolation), on each number of ranks in ``--ranks``
(``mpiexec -n R``; every rank reads only its rows from a cache under benchmarks/out/elasticity).
Reports set-up seconds, iterations, Krylov seconds and peak memory per rank.

``c5``: the Jacobians saved by benchmarks/petsc_dump_c5.py; BlockPoroSolver (GMRES + pyamg on S, and
on Ŝ_p PARDISO when pypardiso is installed (the main venv: today's C5 runs), else pyamg) against
PetscBlockPoroSolver with GAMG or BoomerAMG on the displacement block, and the reuse of the set-up
over a step's Newton iterations.

Results: a table on stdout and benchmarks/out/petsc_solvers_<mode>.json.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "out"
MPIEXEC = ["mpiexec", "--allow-run-as-root", "--oversubscribe", "--bind-to", "none"]


def _rss_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# ---- elasticity --------------------------------------------------------------------------------
def _split(n: int, size: int, bs: int = 3) -> list[tuple[int, int]]:
    """PETSc's default row split in whole blocks (solvers.petsc.owned_range)."""
    nb = n // bs
    counts = [(nb // size + (r < nb % size)) * bs for r in range(size)]
    starts = np.r_[0, np.cumsum(counts)]
    return [(int(starts[r]), int(starts[r + 1])) for r in range(size)]


def build_elasticity(n: int, ranks: list[int]) -> Path:
    """Cache the system for n³ cells: full (for pyamg) and per-rank row slices."""
    d = OUT / "elasticity"
    d.mkdir(parents=True, exist_ok=True)
    full = d / f"n{n}.npz"
    if not full.exists():
        from polypore.mesh import FracturedMesh
        from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
        from polypore.models.mechanics import ContactMechanics, DisplacementBC, MechanicsData

        t0 = time.perf_counter()
        mesh = cartesian_mesh([grid_coordinates(0, 1, n, []) for _ in range(3)])
        fm = FracturedMesh.build(mesh, [])
        nc = mesh.n_cells
        data = MechanicsData(mu=np.full(nc, 4.0e9), lam=np.full(nc, 3.0e9),
                             displacement=[DisplacementBC("zmin", (0, 1, 2), lambda X, t: 0 * X)])
        P = ContactMechanics(fm, data)
        A = sp.csr_matrix(P.A.tocsr()[P.free][:, P.free])
        B = P.rigid_modes()
        b = np.zeros(A.shape[0])
        b[2::3] = -1.0 / A.shape[0]                     # a uniform downward load
        np.savez(full, indptr=A.indptr, indices=A.indices, data=A.data, shape=A.shape, b=b, B=B)
        print(f"elasticity n={n}: {nc} cells, {A.shape[0]} unknowns, nnz {A.nnz}, built in "
              f"{time.perf_counter() - t0:.1f} s", flush=True)
    missing = [(size, r) for size in ranks for r in range(size) if not (d / f"n{n}_r{r}of{size}.npz").exists()]
    if missing:
        A, b, B = _load_full(full)
        for size, r in missing:
            s, e = _split(A.shape[0], size)[r]
            Ar = A[s:e]
            np.savez(d / f"n{n}_r{r}of{size}.npz", indptr=Ar.indptr, indices=Ar.indices, data=Ar.data,
                     shape=Ar.shape, b=b[s:e], B=B[s:e])
    return full


def _load_full(path):
    z = np.load(path)
    A = sp.csr_matrix((z["data"], z["indices"], z["indptr"]), shape=tuple(z["shape"]))
    return A, z["b"], z["B"]


def worker_elasticity(n: int, method: str, rtol: float) -> None:
    """One measurement (under mpiexec for PETSc): prints one JSON line on rank 0."""
    d = OUT / "elasticity"
    if method == "pyamg":
        A, b, B = _load_full(d / f"n{n}.npz")
        import scipy.sparse.linalg as spla

        from polypore.solvers.block_contact import _amg

        t0, c0 = time.perf_counter(), time.process_time()
        M = _amg(A, B)
        t1, c1 = time.perf_counter(), time.process_time()
        its = [0]
        x, info = spla.cg(A, b, rtol=rtol, maxiter=1000, M=M, callback=lambda _: its.__setitem__(0, its[0] + 1))
        t2, c2 = time.perf_counter(), time.process_time()
        res = np.linalg.norm(b - A @ x) / np.linalg.norm(b)
        print(json.dumps({"n": n, "unknowns": A.shape[0], "method": "pyamg SA", "ranks": 1, "setup": t1 - t0,
                          "iterations": its[0], "solve": t2 - t1, "setup_cpu": [c1 - c0], "solve_cpu": [c2 - c1],
                          "residual": res, "memory_mb": [_rss_mb()]}))
        return
    from petsc4py import PETSc

    from polypore.solvers.petsc import PetscLinearSolver

    comm = PETSc.COMM_WORLD
    size, rank = comm.getSize(), comm.getRank()
    z = np.load(d / f"n{n}_r{rank}of{size}.npz")
    A = sp.csr_matrix((z["data"], z["indices"], z["indptr"]), shape=tuple(z["shape"]))
    s = PetscLinearSolver(symmetric=True, rtol=rtol, maxiter=1000, near_nullspace=z["B"], block_size=3,
                          amg=method)
    t0 = time.perf_counter()
    x = s.solve(A, z["b"])
    t = time.perf_counter() - t0
    mpi = comm.tompi4py()
    mem = mpi.gather(_rss_mb())
    cpu_setup, cpu_solve = mpi.gather(s.stats.setup_cpu), mpi.gather(s.stats.krylov_cpu)
    nglob = comm.tompi4py().allreduce(A.shape[0])
    del x
    if rank == 0:
        st = s.stats
        print(json.dumps({"n": n, "unknowns": nglob, "method": f"PETSc {method}", "ranks": size,
                          "setup": st.setup_seconds, "iterations": s.iterations[-1], "solve": st.krylov_seconds,
                          "setup_cpu": cpu_setup, "solve_cpu": cpu_solve, "convert": st.convert_seconds,
                          "total": t, "memory_mb": mem}))


def run_elasticity(args) -> list[dict]:
    rows = []
    for n in args.cells:
        build_elasticity(n, args.ranks)
        jobs = [("pyamg", 1)] if "pyamg" in args.methods else []
        jobs += [(m, r) for m in args.methods if m != "pyamg" for r in args.ranks]
        for method, ranks in jobs:
            cmd = [sys.executable, __file__, "worker-elasticity", str(n), method, str(args.rtol)]
            if method != "pyamg":
                cmd = MPIEXEC + ["-n", str(ranks)] + cmd
            env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
            p = subprocess.run(cmd, capture_output=True, text=True, env=env)
            line = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
            if p.returncode or not line:
                print(f"n={n} {method} ranks={ranks}: FAILED\n{p.stderr[-2000:]}", flush=True)
                continue
            row = json.loads(line[-1])
            rows.append(row)
            print(f"{row['unknowns']:>9} {row['method']:<13} {row['ranks']} ranks: set-up {row['setup']:7.2f} s "
                  f"(CPU/rank {max(row['setup_cpu']):6.2f}), {row['iterations']:4d} its, solve {row['solve']:7.2f} s "
                  f"(CPU/rank {max(row['solve_cpu']):6.2f}), peak memory/rank {max(row['memory_mb']):6.0f} MB",
                  flush=True)
    return rows


# ---- C5 Newton systems -------------------------------------------------------------------------
def run_c5(args) -> list[dict]:
    from polypore.core.errors import RunError
    from polypore.solvers.block_contact import BlockPoroSolver, ContactCondensation
    from polypore.solvers.petsc import ReusePolicy
    from polypore.solvers.petsc_fieldsplit import PetscBlockPoroSolver

    d = Path(args.dir)
    m = np.load(d / "meta.npz")
    cond = ContactCondensation(m["scale"], m["normal"], float(m["rho"]))
    base = (int(m["n_u"]), int(m["d"]), int(m["n_l"]), cond)
    tags = args.tags or sorted(p.name[2:-4] for p in d.glob("J_*.npz"))
    ref = {}
    if (d / "solves.json").exists():
        ref = {r["tag"]: r for r in json.loads((d / "solves.json").read_text())}
    solvers = {}
    rows = []
    for method in args.methods:
        for tag in tags:
            J = sp.load_npz(d / f"J_{tag}.npz").tocsr()
            b = np.load(d / f"rhs_{tag}.npy")
            pns = np.load(d / f"pns_{tag}.npy")
            step = tag.split("_")[0]
            key = (method, step)
            if method == "pyamg":
                # one solver per step, as in the run: the pressure AMG is built once per step
                s = solvers.get(key) or BlockPoroSolver(*base, near_nullspace=m["near_nullspace"])
            else:
                amg, _, reuse = method.partition("-")[2].partition("-reuse")
                policy = ReusePolicy(max_age=int(reuse)) if reuse else ReusePolicy()
                s = solvers.get(key) or PetscBlockPoroSolver(*base, near_nullspace=m["near_nullspace"], amg=amg,
                                                             reuse=policy)
            solvers[key] = s
            s.pressure_nullspace = pns
            label = method if method != "pyamg" else f"pyamg+{s._p.method}"
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                x = s.solve(J, b)
            except RunError as exc:
                print(f"{tag} {label:<20} FAILED after {time.perf_counter() - t0:.1f} s: {exc}", flush=True)
                rows.append({"tag": tag, "method": label, "failed": str(exc), "seconds": time.perf_counter() - t0,
                             "cpu": time.process_time() - c0, "unknowns": J.shape[0]})
                solvers.pop(key, None)
                continue
            t, c = time.perf_counter() - t0, time.process_time() - c0
            res = float(np.linalg.norm(J @ x - b) / np.linalg.norm(b))
            row = {"tag": tag, "method": label, "iterations": int(s.iterations[-1]), "seconds": t, "cpu": c,
                   "residual": res, "unknowns": J.shape[0], "memory_mb": _rss_mb()}
            if method != "pyamg":
                row["setups"] = s.stats.setups
            if tag in ref:
                row["run_seconds"] = ref[tag]["seconds"]
            rows.append(row)
            print(f"{tag} {label:<20} {row['iterations']:4d} its, {t:7.2f} s (CPU {c:7.2f} s), residual {res:.1e}"
                  , flush=True)
    return rows


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "worker-elasticity":
        worker_elasticity(int(sys.argv[2]), sys.argv[3], float(sys.argv[4]))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    e = sub.add_parser("elasticity")
    e.add_argument("--cells", type=int, nargs="+", default=[32, 55])
    e.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    e.add_argument("--methods", nargs="+", default=["pyamg", "gamg", "hypre"])
    e.add_argument("--rtol", type=float, default=1e-8)
    c = sub.add_parser("c5")
    c.add_argument("--dir", default=str(OUT / "c5-jacobians"))
    c.add_argument("--tags", nargs="*")
    c.add_argument("--methods", nargs="+", default=["pyamg", "petsc-gamg", "petsc-hypre", "petsc-hypre-reuse3"])
    args = ap.parse_args()
    rows = run_elasticity(args) if args.mode == "elasticity" else run_c5(args)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"petsc_solvers_{args.mode}.json").write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
