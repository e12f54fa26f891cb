"""A distributed PETSc solve on 2 ranks (``mpiexec -n 2``) gives SciPy's solution of the same
3D elasticity system to 1e-8 relative; each rank passes only the rows it owns. Needs petsc4py and
Open MPI's mpiexec (``make test-mpi``); skipped elsewhere."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as spla
    from mpi4py import MPI
    sys.path.insert(0, {tests!r})
    from test_petsc_solvers import elasticity
    from polypore.solvers.petsc import PetscLinearSolver, owned_range

    A, b, B = elasticity(6)                       # every rank builds it here; a real run assembles its rows
    s, e = owned_range(A.shape[0], bs=3)
    out = {{}}
    for amg in ("gamg", "hypre"):
        solver = PetscLinearSolver(symmetric=True, rtol=1e-13, near_nullspace=B[s:e], amg=amg)
        x_local = solver.solve(A[s:e], b[s:e])
        x = np.concatenate(MPI.COMM_WORLD.allgather(x_local))
        ref = spla.spsolve(A.tocsc(), b)
        out[amg] = {{"error": float(np.linalg.norm(x - ref) / np.linalg.norm(ref)),
                    "iterations": solver.iterations[-1], "block_size": solver.block_size}}
    rows = MPI.COMM_WORLD.gather((s, e))
    if MPI.COMM_WORLD.rank == 0:
        print(json.dumps({{"ranks": MPI.COMM_WORLD.size, "rows": rows, "n": A.shape[0], **out}}))
""")


def test_two_rank_solve_equals_scipy(tmp_path):
    pytest.importorskip("petsc4py.PETSc")
    pytest.importorskip("mpi4py")
    mpiexec = shutil.which("mpiexec")
    if mpiexec is None:
        pytest.skip("no mpiexec (Open MPI's openmpi-bin)")
    script = tmp_path / "two_ranks.py"
    script.write_text(SCRIPT.format(tests=os.path.dirname(__file__)))
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    p = subprocess.run([mpiexec, "--allow-run-as-root", "--oversubscribe", "-n", "2", sys.executable, str(script)],
                       capture_output=True, text=True, timeout=600, env=env)
    assert p.returncode == 0, p.stderr[-3000:]
    res = json.loads([ln for ln in p.stdout.splitlines() if ln.startswith("{")][-1])
    assert res["ranks"] == 2
    (s0, e0), (s1, e1) = res["rows"]
    assert s0 == 0 and e0 == s1 and e1 == res["n"] and 0 < e0 < res["n"] and e0 % 3 == 0   # whole blocks
    for amg in ("gamg", "hypre"):
        assert res[amg]["error"] <= 1e-8, res
        assert res[amg]["block_size"] == 3 and res[amg]["iterations"] > 0
