"""The fixed-stress pressure approximation on a saved Newton system (issue 26, docs/iterative_cornerpoint.md).

    PYTHONPATH=src .venv-fast/bin/python benchmarks/fixed_stress_probe.py [TAG] [DIR]

Ŝ_p = F − D with D a diagonal approximation of G_pu S⁻¹ G_up: (a) lumped with diag(A) (today's
BlockPoroSolver), (b) its exact-ish diagonal probed with coloured PARDISO solves (distance-2
colouring of the cell graph), (c) (a) scaled by the median ratio of (b) to (a). The mechanics
block is solved exactly (PARDISO on the condensed S), so the GMRES counts printed measure the
pressure approximation alone. DIR: a folder of benchmarks/dump_jacobians.py (default
/tmp/jac-emerald).
"""
import sys, time
import numpy as np, scipy.sparse as sp, scipy.sparse.linalg as spla, pypardiso
sys.path.insert(0, "src")
from polypore.solvers.block_contact import ContactCondensation, _gmres, BlockPoroSolver
from polypore.solvers.newton import KrylovTarget
tag = sys.argv[1] if len(sys.argv) > 1 else "s008_k01"
d = sys.argv[2] if len(sys.argv) > 2 else "/tmp/jac-emerald"
J = sp.load_npz(f"{d}/J_{tag}.npz").tocsr(); rhs = np.load(f"{d}/rhs_{tag}.npy"); w = np.load(f"{d}/w_{tag}.npy")
m = dict(np.load(f"{d}/meta.npz")); nu, nl = int(m["n_u"]), int(m["n_l"]); po = nu + nl
A, Bt, Gup = J[:nu, :nu], J[:nu, nu:po], J[:nu, po:]
Cu, Cl = J[nu:po, :nu], J[nu:po, nu:po]
Gpu, F = J[po:, :nu], J[po:, po:]
cond = ContactCondensation(m["scale"], m["normal"], 0.1)
Cinv, Cu_s, S = cond.condense(A, Bt, Cu, Cl)
ps = pypardiso.PyPardisoSolver(); ps.factorize(S)
su = lambda r: ps.solve(S, np.asarray(r, float))
n_p = F.shape[0]
# which pressure unknowns couple to displacements (cell pressures)
coupled = np.flatnonzero(np.diff(Gpu.indptr) > 0)
print("pressure unknowns", n_p, "coupled to u", coupled.size)
# colouring: distance-2 on the graph Gpu Gup (cells sharing nodes), greedy
t0 = time.perf_counter()
Gb = (abs(Gpu) @ abs(Gup)).tocsr(); Gb.data[:] = 1
G2 = (Gb @ Gb).tocsr()
colour = -np.ones(n_p, int)
for i in coupled:
    nb = G2.indices[G2.indptr[i]:G2.indptr[i + 1]]
    used = set(colour[nb][colour[nb] >= 0])
    c = 0
    while c in used: c += 1
    colour[i] = c
nc = colour.max() + 1
print("colours", nc, "%.1f s" % (time.perf_counter() - t0))
diag = np.zeros(n_p)
t0 = time.perf_counter()
for c in range(nc):
    v = (colour == c).astype(float)
    y = Gpu @ su(Gup @ v)
    diag[colour == c] = y[colour == c]
print("probe %.1f s" % (time.perf_counter() - t0))
lump = np.asarray((Gpu @ sp.diags(1.0 / A.diagonal())).multiply(Gup.T).sum(axis=1)).ravel()
k = coupled
print("probed/lumped ratio: median %.3f  p10 %.3f p90 %.3f" % tuple(np.percentile(diag[k] / lump[k], [50, 10, 90])))
holder = BlockPoroSolver(nu, 3, nl, cond, rtol=1e-6, maxiter=1000)
for name, D in (("lumped diag(A)", lump), ("probed", diag), ("lumped x median ratio", lump * np.median(diag[k] / lump[k]))):
    Sp = sp.csr_matrix(F - sp.diags(D)); pp = pypardiso.PyPardisoSolver(); pp.factorize(Sp)
    def apply(r):
        ru, rl, rp = r[:nu], r[nu:po], r[po:]
        xu = su(ru - Bt @ (Cinv @ rl)); xp = pp.solve(Sp, np.asarray(rp - Gpu @ xu, float)); xl = Cinv @ (rl - Cu_s @ xu)
        return np.concatenate([xu, xl, xp])
    x = _gmres(J, rhs, apply, holder, KrylovTarget(w, 1e-6))
    print(f"  {name:24s} GMRES {holder.iterations[-1]}")
