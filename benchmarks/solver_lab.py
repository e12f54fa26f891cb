"""Try linear solvers on saved Newton systems (benchmarks/dump_jacobians.py) and print the figures.

    .venv-fast/bin/python benchmarks/solver_lab.py DIR [--tags s004_k01 ...] [--methods pardiso block-amg ...]

For each system: the method's set-up and solve seconds (wall and CPU), Krylov iterations, the
relative residual reached, and the difference from PARDISO's solution (relative, per block).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def load(folder: Path, tag: str):
    J = sp.load_npz(folder / f"J_{tag}.npz").tocsr()
    rhs = np.load(folder / f"rhs_{tag}.npy")
    pns = np.load(folder / f"pns_{tag}.npy")
    w = folder / f"w_{tag}.npy"
    return J, rhs, pns, (np.load(w) if w.exists() else None)


def method_pardiso(J, rhs, meta, pns, w=None):
    import pypardiso

    ps = pypardiso.PyPardisoSolver()
    ps.factorize(J)
    x = ps.solve(J, rhs)
    ps.free_memory(everything=True)
    return x, 0


RTOL = [1e-6]
RHO = [None]


def method_block_amg(J, rhs, meta, pns, w=None, pressure="auto"):
    from polypore.solvers.block_contact import BlockPoroSolver, ContactCondensation

    cond = ContactCondensation(meta["scale"], meta["normal"], float(meta["rho"]))
    s = BlockPoroSolver(int(meta["n_u"]), int(meta["d"]), int(meta["n_l"]), cond,
                        near_nullspace=meta["near_nullspace"], pressure=pressure, rtol=RTOL[0], maxiter=1000)
    s.pressure_nullspace = pns
    from polypore.solvers.newton import KrylovTarget

    x = s.solve(J, rhs, target=KrylovTarget(w, RTOL[0]))
    return x, s.iterations[-1]


def method_blocks(J, rhs, meta, pns, w=None, u="amg", p="pardiso"):
    """The block preconditioner of BlockPoroSolver with a choice of inner solves: u "amg" (today's
    smoothed aggregation on the condensed S), "ls" (that AMG inside the line smoother, block-amg's
    3-D choice) or "exact" (PARDISO on S); p "pardiso" (Ŝ_p, today's
    default with the fast extra), "amg" or "exact-schur" (the pressure Schur complement
    F − G_pu S⁻¹ G_up applied exactly, by inner PARDISO solves: the splitting's own limit)."""
    import pypardiso

    from polypore.solvers.block_contact import BlockPoroSolver, ContactCondensation, _amg, _gmres
    from polypore.solvers.newton import KrylovTarget

    nu, nl = int(meta["n_u"]), int(meta["n_l"])
    po = nu + nl
    cond = ContactCondensation(meta["scale"], meta["normal"], float(meta["rho"]) if RHO[0] is None else RHO[0])
    holder = BlockPoroSolver(nu, int(meta["d"]), nl, cond, rtol=RTOL[0], maxiter=1000)
    t0 = time.perf_counter()
    A, Bt, Gup = J[:nu, :nu], J[:nu, nu:po], J[:nu, po:]
    Cu, Cl = J[nu:po, :nu], J[nu:po, nu:po]
    Gpu, F = J[po:, :nu], J[po:, po:]
    Cinv, Cu_s, S = cond.condense(A, Bt, Cu, Cl)
    if u == "amg":
        Mu = _amg(S, meta["near_nullspace"])
        su = Mu.__matmul__
    elif u == "ls":                      # what block-amg uses in 3D: AMG inside line Gauss–Seidel
        from polypore.solvers.line_smoother import LineSmoothedAMG

        su = LineSmoothedAMG(S, meta["near_nullspace"], _amg).__matmul__
    else:
        psu = pypardiso.PyPardisoSolver()
        psu.factorize(S)
        su = lambda r: psu.solve(S, np.asarray(r, float))
    if p == "exact-schur":
        psf = pypardiso.PyPardisoSolver()
        Fc = sp.csr_matrix(F)
        psf.factorize(Fc)
        import scipy.sparse.linalg as spla
        n_p = F.shape[0]
        schur = spla.LinearOperator((n_p, n_p), matvec=lambda v: F @ v - Gpu @ su(Gup @ v), dtype=float)
        def sp_(r):
            x, info = spla.gmres(schur, np.asarray(r, float), rtol=1e-10, restart=50, maxiter=20,
                                 M=spla.LinearOperator((n_p, n_p), matvec=lambda v: psf.solve(Fc, np.asarray(v, float)),
                                                       dtype=float))
            return x
    elif p == "twolevel":
        from polypore.solvers.pressure_twolevel import TwoLevelPressure

        lump = np.asarray((Gpu @ sp.diags(1.0 / A.diagonal())).multiply(Gup.T).sum(axis=1)).ravel()
        kind = meta["flow_kind"]
        T = TwoLevelPressure(sp.csr_matrix(F - sp.diags(lump)), pns, np.isin(kind, (0, 3)), np.isin(kind, (2, 3, 4)))
        sp_ = T.apply
    else:
        holder._p.method = "pardiso" if p == "pardiso" else "amg"
        holder._p.update(F, Gpu, Gup, A.diagonal(), pns)
        sp_ = holder._p.apply
    setup = time.perf_counter() - t0

    def apply(r):
        ru, rl, rp = r[:nu], r[nu:po], r[po:]
        xu = su(ru - Bt @ (Cinv @ rl))
        xp = sp_(rp - Gpu @ xu)
        xl = Cinv @ (rl - Cu_s @ xu)
        return np.concatenate([xu, xl, xp])

    t1 = time.perf_counter()
    x = _gmres(J, rhs, apply, holder, KrylovTarget(w, RTOL[0]))
    print(f"      set-up {setup:.2f} s, Krylov {time.perf_counter() - t1:.2f} s", flush=True)
    return x, holder.iterations[-1]


METHODS = {"pardiso": method_pardiso, "block-amg": method_block_amg,
           "block-amg-pamg": lambda *a: method_block_amg(*a, pressure="amg"),
           "u-amg/p-pardiso": lambda *a: method_blocks(*a, u="amg", p="pardiso"),
           "u-exact/p-pardiso": lambda *a: method_blocks(*a, u="exact", p="pardiso"),
           "u-exact/p-amg": lambda *a: method_blocks(*a, u="exact", p="amg"),
           "u-amg/p-amg": lambda *a: method_blocks(*a, u="amg", p="amg"),
           "u-exact/p-twolevel": lambda *a: method_blocks(*a, u="exact", p="twolevel"),
           "u-amg/p-twolevel": lambda *a: method_blocks(*a, u="amg", p="twolevel"),
           "u-ls/p-twolevel": lambda *a: method_blocks(*a, u="ls", p="twolevel"),
           "u-ls/p-pardiso": lambda *a: method_blocks(*a, u="ls", p="pardiso"),
           "u-exact/p-schur": lambda *a: method_blocks(*a, u="exact", p="exact-schur")}


def wres(J, x, rhs, w):
    """‖w∘(b − J x)‖ / ‖w∘b‖ (the Newton row weights; 1 without)."""
    w = 1.0 if w is None else w
    return np.linalg.norm(w * (J @ x - rhs)) / np.linalg.norm(w * rhs)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--tags", nargs="+", default=None)
    ap.add_argument("--methods", nargs="+", default=["pardiso", "block-amg"])
    ap.add_argument("--rho", type=float, default=None, help="the condensation's ρ (default: the run's)")
    ap.add_argument("--rtol", type=float, default=1e-6, help="Krylov relative residual")
    args = ap.parse_args()
    RTOL[0] = args.rtol
    RHO[0] = args.rho
    folder = Path(args.folder)
    meta = dict(np.load(folder / "meta.npz"))
    tags = args.tags or sorted(p.stem[2:] for p in folder.glob("J_*.npz"))
    nu, nl = int(meta["n_u"]), int(meta["n_l"])
    for tag in tags:
        J, rhs, pns, w = load(folder, tag)
        print(f"{tag}: n = {J.shape[0]} (u {nu}, λ {nl}, p {J.shape[0] - nu - nl}), nnz = {J.nnz}", flush=True)
        ref = None
        for m in args.methods:
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                x, its = METHODS[m](J, rhs, meta, pns, w)
            except Exception as exc:      # noqa: BLE001 - a method that fails is a result
                print(f"  {m:16s} FAILED: {str(exc)[:150]}", flush=True)
                continue
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            res = wres(J, x, rhs, w)
            if ref is None:
                ref = x
                diff = ""
            else:
                parts = [(0, nu), (nu, nu + nl), (nu + nl, J.shape[0])]
                diff = " ".join(f"{n} {np.linalg.norm(x[a:b] - ref[a:b]) / max(np.linalg.norm(ref[a:b]), 1e-300):.1e}"
                                for n, (a, b) in zip("uλp", parts))
            print(f"  {m:16s} {wall:7.2f} s wall {cpu:7.2f} s CPU  its {its:4d}  res {res:.1e}  {diff}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
