"""AMG on the pressure block of a saved Newton system (issue 26, docs/iterative_cornerpoint.md).

    PYTHONPATH=src .venv-fast/bin/python benchmarks/pressure_amg_probe.py [DIR] [TAG]

Ŝ_p = F − diag(G_pu diag(A)⁻¹ G_up) (BlockPoroSolver's fixed-stress block): pyamg smoothed
aggregation (strengths, near-null spaces) and Ruge–Stüben as CG preconditioners on it and on the
face system left after eliminating the cell pressures with the cell block's diagonal only (the
cell block is not diagonal: the poromechanics pressure-jump stabilisation couples neighbours).
Prints CG iterations to 1e-8 (cap 200) and the residual reached.
"""
import sys, time, numpy as np, scipy.sparse as sp, scipy.sparse.linalg as spla, pyamg
d = sys.argv[1] if len(sys.argv) > 1 else "/tmp/jac-emerald"
tag = sys.argv[2] if len(sys.argv) > 2 else "s008_k01"
J=sp.load_npz(f"{d}/J_{tag}.npz").tocsr(); m=dict(np.load(f"{d}/meta.npz")); nu,nl=int(m["n_u"]),int(m["n_l"]); po=nu+nl
A=J[:nu,:nu]; Gup=J[:nu,po:]; Gpu=J[po:,:nu]; F=J[po:,po:].tocsr()
lump=np.asarray((Gpu@sp.diags(1.0/A.diagonal())).multiply(Gup.T).sum(axis=1)).ravel()
Sp=sp.csr_matrix(F-sp.diags(lump))
n=Sp.shape[0]
cell=np.zeros(n,bool); cell[np.flatnonzero(np.diff(Gpu.indptr)>0)]=True
C=Sp[cell][:,cell]; print("cell-cell block: nnz", C.nnz, "n", C.shape[0], "offdiag nnz", (C-sp.diags(C.diagonal())).nnz)
print("symmetric?", abs(Sp-Sp.T).max()/abs(Sp).max(), "sign of diag", np.sign(Sp.diagonal()).min(), np.sign(Sp.diagonal()).max())
# eliminate the cells (assuming the cell-cell block is diagonal-dominant / use its inverse exactly via splu when not diagonal)
f=~cell
Sff=Sp[f][:,f]; Sfc=Sp[f][:,cell]; Scf=Sp[cell][:,f]
Cd=C.diagonal()
if (C-sp.diags(Cd)).nnz==0:
    R=(Sff - Sfc@sp.diags(1/Cd)@Scf).tocsr()
else:
    R=None; print("cell block not diagonal")
rng=np.random.default_rng(0)
def test(M, name, B=None):
    sign = -1.0 if np.mean(M.diagonal())<0 else 1.0
    Ms = sign*0.5*(M+M.T)
    t0=time.perf_counter(); ml=pyamg.smoothed_aggregation_solver(Ms, B=B, max_coarse=1000); t1=time.perf_counter()
    b=rng.standard_normal(M.shape[0]); res=[]
    x=ml.solve(b, tol=1e-8, maxiter=200, accel="cg", residuals=res)
    print(f"{name}: n {M.shape[0]}, SA-AMG CG iterations to 1e-8: {len(res)-1} (set-up {t1-t0:.1f} s), final {res[-1]/res[0]:.1e}")
    res=[]; x=ml.solve(b, tol=1e-8, maxiter=200, accel="gmres", residuals=res)
    print(f"   gmres: {len(res)-1}")
test(Sp, "full pressure block, constants"); pns=np.load(f"{d}/pns_{tag}.npy").reshape(-1,1); test(Sp, "full pressure block, B = scaled constant", pns)
for st in ("evolution", ("symmetric", {"theta": 0.0}), ("symmetric", {"theta": 0.25})):
    import functools
    def t2(M=Sp, B=pns, st=st):
        Ms=-0.5*(M+M.T); ml=pyamg.smoothed_aggregation_solver(Ms, B=B, strength=st, max_coarse=1000); res=[]; b=rng.standard_normal(M.shape[0]); ml.solve(b, tol=1e-8, maxiter=200, accel="cg", residuals=res); print("  strength", st, len(res)-1, "%.1e"%(res[-1]/res[0]))
    t2()
if R is not None: test(R, "faces after eliminating cells")
Cd=C.diagonal()
R=(Sff - Sfc@sp.diags(1/Cd)@Scf).tocsr()
print("face system n", R.shape[0], "nnz", R.nnz)
Rs=-0.5*(R+R.T)
dR=Rs.diagonal(); print("diag range %.2e %.2e" % (dR.min(), dR.max()))
Bf=pns[f] if False else None
for st in (("symmetric", {"theta": 0.0}), ("symmetric", {"theta": 0.25}), "evolution"):
    for B in (None, np.load(f"{d}/pns_{tag}.npy")[f].reshape(-1,1)):
        ml=pyamg.smoothed_aggregation_solver(Rs, B=B, strength=st, max_coarse=1000); res=[]; b=rng.standard_normal(R.shape[0])
        ml.solve(b, tol=1e-8, maxiter=200, accel="cg", residuals=res)
        print("  faces: strength", st, "B", None if B is None else "pns", len(res)-1, "%.1e"%(res[-1]/res[0]))
ml=pyamg.ruge_stuben_solver(Rs); res=[]; ml.solve(b, tol=1e-8, maxiter=200, accel="cg", residuals=res); print("  faces RS", len(res)-1, "%.1e"%(res[-1]/res[0]))
ml=pyamg.ruge_stuben_solver(-0.5*(Sp+Sp.T)); res=[]; b=rng.standard_normal(Sp.shape[0]); ml.solve(b, tol=1e-8, maxiter=200, accel="cg", residuals=res); print("  full RS", len(res)-1, "%.1e"%(res[-1]/res[0]))
