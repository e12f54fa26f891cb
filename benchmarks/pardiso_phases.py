"""One solve with PARDISO's Cholesky factors of a condensed displacement block S, by phase 33 (with
PARDISO's iterative refinement) and by the substitution phases 331–333 that the block
preconditioner uses (solvers/block_contact._Factorised); docs/iterative_cornerpoint.md, "Eleventh
session". Needs PARDISO (.venv-fast) and a folder of benchmarks/dump_jacobians.py:

    .venv-fast/bin/python benchmarks/dump_jacobians.py emerald-injection --set solver.linear=block-direct \\
        --steps 2 --out /tmp/jac-emerald
    .venv-fast/bin/python benchmarks/pardiso_phases.py /tmp/jac-emerald [--tag s002_k01] [--repeat 30]

Prints wall and CPU milliseconds per solve and the relative residual of each way.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--tag", default="s002_k01")
    ap.add_argument("--repeat", type=int, default=30)
    a = ap.parse_args(argv)
    import pypardiso

    from polypore.solvers.block_contact import ContactCondensation, _Factorised

    folder = Path(a.folder)
    J = sp.load_npz(folder / f"J_{a.tag}.npz").tocsr()
    meta = np.load(folder / "meta.npz")
    nu, nl = int(meta["n_u"]), int(meta["n_l"])
    po = nu + nl
    cond = ContactCondensation(meta["scale"], meta["normal"], float(meta["rho"]))
    S = sp.csr_matrix(cond.condense(J[:nu, :nu], J[:nu, nu:po], J[nu:po, :nu], J[nu:po, nu:po])[2])
    U = sp.triu(S, format="csr")
    U.sort_indices()
    r = np.random.default_rng(0).standard_normal(S.shape[0])

    ps = pypardiso.PyPardisoSolver(mtype=2)
    ps.factorize(U)

    def phase33(b):
        ps.set_phase(33)
        return ps._call_pardiso(U, b)

    fact = _Factorised(S)
    print(f"S: {S.shape[0]:,} rows, {S.nnz:,} entries")
    for label, f in (("phase 33 (PARDISO's refinement)", phase33), ("phases 331-333 (the preconditioner's)",
                                                                    fact.__matmul__)):
        for _ in range(3):
            x = f(r)
        t, c = time.perf_counter(), time.process_time()
        for _ in range(a.repeat):
            x = f(r)
        w, cpu = (time.perf_counter() - t) / a.repeat * 1e3, (time.process_time() - c) / a.repeat * 1e3
        res = np.linalg.norm(S @ x - r) / np.linalg.norm(r)
        print(f"{label}: {w:.1f} ms wall, {cpu:.1f} ms CPU per solve, relative residual {res:.1e}")
    print(f"refinement steps PARDISO reports for phase 33: {ps.get_iparm(7)}")
    ps.free_memory(everything=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
