"""The first Newton system of a day, saved by benchmarks/dump_jacobians.py: GMRES's residual after
every iteration with the block-amg preconditioner, and the pressure block alone under each coarse
AMG of the two-level preconditioner (docs/iterative_cornerpoint.md, eighth session).

    .venv-fast/bin/python benchmarks/first_solve_probe.py DIR [--tag s001_k01] [--weights s001_k02]
        [--rtol 1e-7] [--coarse classical aggregation] [--direct-coarse 20000]

``--weights TAG`` solves in the row weights saved with another system (the next iterate's: the
norm Newton tests there); ``--rtol`` replaces the saved forcing term. Printed per coarse AMG: the
coupled GMRES iterations, the weighted relative residual reached and the residual history, then
the pressure block alone (Ŝ_p, GMRES to 1e-10 in the same weights).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def main(argv=None) -> int:
    from polypore.solvers import block_contact as bc
    from polypore.solvers.block_contact import BlockPoroSolver, ContactCondensation, _amg, _gmres
    from polypore.solvers.line_smoother import LineSmoothedAMG
    from polypore.solvers.newton import KrylovTarget
    from polypore.solvers.pressure_twolevel import COARSE_AMG, TwoLevelPressure

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--tag", default="s001_k01")
    ap.add_argument("--weights", default=None, help="tag whose saved row weights to use")
    ap.add_argument("--rtol", type=float, default=None, help="relative residual (default: the saved forcing)")
    ap.add_argument("--coarse", nargs="+", default=list(COARSE_AMG), choices=COARSE_AMG)
    ap.add_argument("--direct-coarse", type=int, default=20000,
                    help="coarse spaces up to this many cells are factorised (0: AMG always)")
    a = ap.parse_args(argv)
    f, tag = Path(a.folder), a.tag
    meta = dict(np.load(f / "meta.npz"))
    J = sp.load_npz(f / f"J_{tag}.npz").tocsr()
    rhs, pns = np.load(f / f"rhs_{tag}.npy"), np.load(f / f"pns_{tag}.npy")
    w = np.load(f / f"w_{a.weights or tag}.npy")
    eta = a.rtol if a.rtol is not None else float(np.load(f / f"eta_{tag}.npy"))
    nu, nl, kind = int(meta["n_u"]), int(meta["n_l"]), meta["flow_kind"]
    po = nu + nl
    print(f"{f} {tag}: n = {J.shape[0]}, weights of {a.weights or tag}, rtol {eta:g}, "
          f"‖w∘b‖ = {np.linalg.norm(w * rhs):.3e}", flush=True)
    hist = []
    gmres = spla.gmres

    def recorded(*args, callback=None, **kw):
        def cb(v):
            hist.append(float(v))
            callback(v)
        return gmres(*args, callback=cb, **kw)

    bc.spla.gmres = recorded
    cond = ContactCondensation(meta["scale"], meta["normal"], float(meta["rho"]))
    holder = BlockPoroSolver(nu, int(meta["d"]), nl, cond, maxiter=1000)
    A, Bt, Gup = J[:nu, :nu], J[:nu, nu:po], J[:nu, po:]
    Cu, Cl, Gpu, F = J[nu:po, :nu], J[nu:po, nu:po], J[po:, :nu], J[po:, po:]
    Cinv, Cu_s, S = cond.condense(A, Bt, Cu, Cl)
    su = LineSmoothedAMG(S, meta["near_nullspace"], _amg).__matmul__
    lump = np.asarray((Gpu @ sp.diags(1.0 / A.diagonal())).multiply(Gup.T).sum(axis=1)).ravel()
    Sp = sp.csr_matrix(F - sp.diags(lump))
    wp, bp = w[po:], (w * rhs)[po:]
    for coarse in a.coarse:
        T = TwoLevelPressure(Sp, pns, np.isin(kind, (0, 3)), np.isin(kind, (2, 3, 4)), coarse_amg=coarse,
                             direct_coarse=a.direct_coarse)

        def apply(r):
            ru, rl, rp = r[:nu], r[nu:po], r[po:]
            xu = su(ru - Bt @ (Cinv @ rl))
            xp = T.apply(rp - Gpu @ xu)
            return np.concatenate([xu, Cinv @ (rl - Cu_s @ xu), xp])

        hist.clear()
        t0 = time.perf_counter()
        x = _gmres(J, rhs, apply, holder, KrylovTarget(w, eta))
        res = np.linalg.norm(w * (rhs - J @ x)) / np.linalg.norm(w * rhs)
        print(f"  coupled, {coarse:11s} coarse ({T.levels} levels): {holder.iterations[-1]:4d} iterations, "
              f"residual {res:.2e}, {time.perf_counter() - t0:.1f} s | " + " ".join(f"{v:.0e}" for v in hist[:40]),
              flush=True)
        n = Sp.shape[0]
        op = spla.LinearOperator((n, n), matvec=lambda v: wp * (Sp @ T.apply(v / wp)))
        h = []
        gmres(op, bp, rtol=1e-10, restart=200, maxiter=1, callback=h.append, callback_type="pr_norm")
        print(f"  pressure block alone:            {len(h):4d} iterations to 1e-10 | "
              + " ".join(f"{v:.0e}" for v in h[:40]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
