"""Slip-weakening nucleation against Uenishi and Rice (2003): the critical slipping length.

    .venv/bin/python benchmarks/slip_weakening_nucleation.py [--refine 10 20 40] [--json out.json] [--png out.png]

A fault of linear slip-weakening friction, F(δ) = F_s − (F_s − F_d) δ/D_c for δ < D_c, under a
constant normal traction σ_n and a slowly growing, locally peaked excess of shear stress over
strength, slips over a growing zone |x| < a that becomes unstable (no nearby quasi-static
equilibrium) when a reaches

    a_c = β₀ μ*/W,   W = (F_s − F_d) σ_n / D_c,   μ* = μ/(1 − ν) (in-plane, plane strain),

whatever the load's shape (Uenishi and Rice 2003, JGR 108(B1), 2042). β₀ is the smallest
eigenvalue of K δ = β δ with K the crack's stiffness on |x| < 1 (μ* = 1/2-normalised); it is
computed here, not copied: with δ = √(1 − x²) Σ c_n U_{n−1}(x) (Chebyshev of the second kind),
K δ = Σ c_n (μ*/2a) n U_{n−1}, and Galerkin with the same functions gives diag(nπ/4) c =
β M c, M_mn = ∫(1 − x²) U_{m−1} U_{n−1} dx; β₀ = 0.578887 (2a_c = 1.1578 μ*/W).

In the slipping zone K[δ] − W δ = τ⁰(x, t) − F_s(x) σ_n: only the excess of the load over the
static strength enters, so a uniform load against a strength with a local minimum is U–R's
problem as well (with F_s − F_d, hence W, uniform). The polypore model: plane strain, a fault
along y = 0 with tips at x = ±0.75 L in a square [−L, L]² (L = 20 a_c), every side displaced as
simple shear u = (γ y, 0) (the fault's shear stress μγ exactly, uniform, while it sticks), a
uniform in-situ stress −σ_n I, F_s(x) = 0.6 + 0.2 (1 − exp(−(x/w)²)) with w = 5 a_c and F_d =
F_s − 0.2. The load γ grows in steps (each a static solve from the last one, with the friction
law's slip path carried); a step whose Newton iteration fails or whose slip jumps by more than
D_c/2 is retried at half the increment, until the increment is below 10⁻⁶ of the onset load:
the last converged state is the edge of stability. Printed per mesh: a/a_c there (a: half the extent of the faces whose slip
path is positive, to their outer edges), the slip at the centre over D_c (U–R's result assumes
it below 1), and the slip increment's shape against the eigenfunction.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sl
from numpy.polynomial import legendre
from scipy.special import eval_chebyu

from polypore.core.errors import RunError
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.generators.cartesian import cartesian_mesh
from polypore.models.materials import lame
from polypore.models.mechanics import ContactMechanics, ContactSpec, DisplacementBC, MechanicsData
from polypore.solvers.linear import LinearSolver
from polypore.solvers.newton import NewtonOptions

E, NU = 25e9, 0.25
SIGMA_N = 10e6
FS, FD, DC = 0.6, 0.4, 1e-4          # at the strength minimum; F_s − F_d is the same everywhere
STRENGTHEN, WIDTH = 0.2, 5.0           # F_s rises by this much away from x = 0, over WIDTH a_c


def critical_beta(n_modes: int = 40) -> tuple[float, np.ndarray]:
    """(β₀, its eigenvector's coefficients c_n) of the crack-stiffness eigenproblem (docstring)."""
    x, w = legendre.leggauss(4 * n_modes + 40)
    n = np.arange(1, n_modes + 1)
    U = np.array([eval_chebyu(k - 1, x) for k in n])
    M = (U * (w * (1 - x * x))) @ U.T
    vals, vecs = sl.eigh(np.diag(n * np.pi / 4), M)
    return float(vals[0]), vecs[:, 0]


def eigen_slip(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The critical mode √(1 − x²) Σ c_n U_{n−1}(x) on |x| < 1 (0 outside)."""
    xi = np.clip(x, -1, 1)
    out = np.sqrt(1 - xi * xi) * sum(ck * eval_chebyu(k, xi) for k, ck in enumerate(c))
    return np.where(np.abs(x) < 1, out, 0.0)


def axis(h: float, fine: float, half: float, ratio: float = 1.12) -> np.ndarray:
    """Node coordinates on [−half, half]: spacing h on |x| ≤ fine, then growing by ``ratio``."""
    right = list(np.arange(0.0, fine + 0.5 * h, h))
    step = h
    while right[-1] < half:
        step *= ratio
        right.append(right[-1] + step)
    right = np.array(right)
    right[-1] = half
    if right[-1] - right[-2] < 0.5 * step:
        right = np.delete(right, -2)
    return np.concatenate([-right[:0:-1], right])


def model(refine: int):
    """(ContactMechanics, a_c, face centroids' x, face widths, h) for h = a_c / refine."""
    mu, lam = lame(E, NU)
    W = (FS - FD) * SIGMA_N / DC
    beta0, _ = critical_beta()
    ac = beta0 * mu / (1 - NU) / W
    L = 20 * ac
    h = ac / refine
    xs = axis(h, 2.5 * ac, L)
    tip = 0.75 * L
    for s in (-1, 1):                                 # the tips on nodes
        xs[np.argmin(np.abs(xs - s * tip))] = s * tip
    ys = axis(h, 2 * h, L)
    mesh = cartesian_mesh([xs, ys])
    fm = FracturedMesh.build(mesh, [FractureSpec("fault", np.array([[-tip, 0.0], [tip, 0.0]]))])
    nc = mesh.n_cells
    xf = mesh.geometry.face_centroid[fm.network.faces][:, 0]
    fs = FS + STRENGTHEN * (1 - np.exp(-(xf / (WIDTH * ac)) ** 2))

    def simple_shear(X, t):
        return np.column_stack([t * X[:, 1], 0 * X[:, 0]])

    data = MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam),
                         displacement=[DisplacementBC(b, (0, 1), simple_shear) for b in ("xmin", "xmax", "ymin", "ymax")],
                         initial_stress=lambda X, t: np.tile(-SIGMA_N * np.eye(2).ravel(), (len(X), 1)),
                         contact=ContactSpec("slip-weakening", fs, patch_ratio=0.0,
                                             coefficients={"dynamic_friction": fs - (FS - FD), "critical_slip": DC}))
    M = ContactMechanics(fm, data, LinearSolver("superlu"),
                         NewtonOptions(tol=1e-10, max_iterations=15, label="contact Newton"))
    return M, ac, xf, mesh.geometry.face_area[fm.network.faces], h


def tractions(M, st):
    """(λ_n, λ_τ) per fault face (Pa), the shear signed along +x."""
    n = M.normal
    ln = np.einsum("fi,fi->f", st.lam, n)
    t = np.column_stack([-n[:, 1], n[:, 0]])
    t *= np.sign(t[:, :1])
    return ln, np.einsum("fi,fi->f", st.lam, t)


def run(refine: int, verbose: bool = True) -> dict:
    t0 = time.perf_counter()
    M, ac, xf, wf, h = model(refine)
    # the onset load: the bonded response is linear in U, and slip starts where λ_τ = F_s σ_n first
    U1 = 0.5 * FS * SIGMA_N * (1 - NU) * 2 / E          # about half the onset load: every face sticks
    probe = M.solve(U1, verbose=False)
    ln, lt = tractions(M, probe)
    fs = M.law.friction_law.friction
    U_on = U1 * np.min(fs * ln / np.abs(lt))
    q = lambda st: (M.Jcv @ st.u.ravel()).reshape(M.n_c, -1)     # noqa: E731
    st = M.solve(0.99 * U_on, verbose=False)
    U, dU = 0.99 * U_on, 0.02 * U_on
    history, newton = [], 0
    while dU > 1e-6 * U_on:
        try:
            nxt = M.solve(U + dU, initial=st, q_old=q(st), friction=st.friction, verbose=False)
            jumped = (nxt.friction[:, 0] - st.friction[:, 0]).max() > 0.5 * DC
        except RunError:
            nxt, jumped = None, True
        if jumped:
            dU *= 0.5
            continue
        newton += nxt.newton_iterations
        last_increment = nxt.friction[:, 0] - st.friction[:, 0]
        st, U = nxt, U + dU
        path = st.friction[:, 0]
        slipping = path > 1e-6 * DC                   # stuck faces move by Newton's tolerance only
        a = float(np.max(np.abs(xf[slipping]) + 0.5 * wf[slipping])) if slipping.any() else 0.0
        history.append((U / U_on, a / ac, float(path.max() / DC)))
        if verbose:
            print(f"  U/U_on = {U / U_on:.7f}  a/a_c = {a / ac:.4f}  δ_max/D_c = {path.max() / DC:.4f}  "
                  f"(ΔU/U_on = {dU / U_on:.1e}, {nxt.newton_iterations} Newton)", flush=True)
        dU = min(2 * dU, 0.02 * U_on) if nxt.newton_iterations < 8 else dU
    # the last increment's slip against the critical mode: at the edge of stability the tangent
    # stiffness is singular and the increment is its null vector, √(1 − (x/a)²) Σ c_n U_{n−1}(x/a);
    # its half-length a, fitted (least squares over a, the amplitude linear), is not bound to the faces
    beta0, c = critical_beta()
    prev = np.array(history)
    path = st.friction[:, 0]

    def misfit(a):
        m = eigen_slip(xf / a, c) * np.sqrt(wf)
        y = last_increment * np.sqrt(wf)
        amp = (m @ y) / max(m @ m, 1e-300)
        return float(np.linalg.norm(y - amp * m) / max(np.linalg.norm(y), 1e-300))

    grid = np.linspace(0.5, 1.5, 201) * ac
    errs = np.array([misfit(a) for a in grid])
    k = int(np.argmin(errs))
    fine = np.linspace(grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)], 201)
    errs_f = np.array([misfit(a) for a in fine])
    a_fit = float(fine[np.argmin(errs_f)])
    mode = eigen_slip(xf / a_fit, c)
    return {"refine": refine, "h_over_ac": 1.0 / refine, "faces": int(M.n_c), "a_c_m": ac, "beta0": beta0,
            "onset_load_m": U_on, "critical_load_ratio": U / U_on, "a_over_ac": prev[-1, 1],
            "a_fit_over_ac": a_fit / ac, "mode_misfit": float(errs_f.min()),
            "slip_centre_over_Dc": float(path[np.argmin(np.abs(xf))] / DC), "steps": len(history), "newton": newton,
            "seconds": time.perf_counter() - t0, "history": prev.tolist(),
            "slip_profile": {"x_over_ac": (xf / ac).tolist(), "path_m": path.tolist(),
                             "last_increment_m": last_increment.tolist(), "mode": mode.tolist()}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--refine", type=int, nargs="+", default=[10, 20, 40], help="a_c / h of each mesh")
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--png", type=Path, help="plot a/a_c against the load and the slip profiles")
    args = ap.parse_args(argv)
    beta0, _ = critical_beta()
    print(f"β₀ = {beta0:.6f}: 2a_c = {2 * beta0:.4f} μ*/W")
    out = []
    for r in args.refine:
        print(f"h = a_c/{r}:", flush=True)
        res = run(r)
        out.append(res)
        print(f"h = a_c/{r}: {res['faces']} fault faces; last stable state at U = {res['critical_load_ratio']:.6f} "
              f"U_onset: a/a_c = {res['a_over_ac']:.4f} (slipping faces), {res['a_fit_over_ac']:.4f} (the last "
              f"increment's shape, misfit {res['mode_misfit']:.3f}), slip at the centre {res['slip_centre_over_Dc']:.3f} D_c "
              f"({res['steps']} load steps, {res['newton']} Newton iterations, {res['seconds']:.1f} s)", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"command": " ".join(sys.argv), "results": out}, indent=1))
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
        for res in out:
            hst = np.array(res["history"])
            a1.plot(hst[:, 0], hst[:, 1], ".-", ms=3, label=f"h = a_c/{res['refine']}")
            sp = res["slip_profile"]
            x, p = np.array(sp["x_over_ac"]), np.array(sp["last_increment_m"])
            o = np.argsort(x)
            a2.plot(x[o], p[o] / p.max(), ".-", ms=3, label=f"last increment, h = a_c/{res['refine']}")
        a1.axhline(1.0, color="k", ls="--", lw=1, label="Uenishi–Rice a_c")
        a1.set_xlabel("load U / U_onset")
        a1.set_ylabel("slipping half-length a / a_c")
        a1.set_title("growth of the slipping zone to instability")
        a1.legend()
        sp = out[-1]["slip_profile"]
        x = np.array(sp["x_over_ac"])
        o = np.argsort(x)
        m = eigen_slip(x, critical_beta()[1])
        a2.plot(x[o], m[o] / np.abs(m).max(), "k--", lw=1, label="critical mode, half-length a_c")
        a2.set_xlim(-1.5, 1.5)
        a2.set_xlabel("x / a_c")
        a2.set_ylabel("normalised")
        a2.set_title("slip increment at the edge of stability")
        a2.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(args.png, dpi=130)
    return 0


if __name__ == "__main__":
    sys.exit(main())
