"""Benchmark: convergence on flat corner-point cells (issue 15), aspect ratios 1, 10 and 100.

    .venv/bin/python benchmarks/cornerpoint_flat.py [--levels 4 8 16] [--ratios 1 10 100]
                                                    [--stabilisation 0.1 1 10] [--json out.json]

Family: ``generate_grid(n, n, n)`` over Lx = Ly = 1000 m and a stack of thickness
H = 1000 m / a, so every cell is a times wider than thick (a = dx/dz = 1, 10, 100), with a
vertical fault on the middle pillar line whose throw is a quarter of the stack (displaced,
non-matching cells on either side, bonded) and layers dipping so that the stack drops by H/2
along x (sloping, non-parallel top and bottom faces). Refinement n = 4, 8, 16 keeps the geometry
(the fault's throw and the dip are fixed fractions of the stack), so the grids are nested in
shape though not in cells.

Manufactured solutions on the unit cube mapped to the domain (x̂ = x/Lx, ŷ = y/Ly, ẑ = (z − z0)/H):

- mechanics (isotropic, E = 10 GPa, ν = 0.25): u = U (sin πx̂ sin πŷ sin πẑ, cos πx̂ sin πŷ ẑ,
  sin πx̂ cos πŷ cos πẑ) with U = 1e-3 H, body force f = −div σ(u) (sympy), u = exact on ∂Ω;
  errors: the cell displacement Π^K u against u at the centroids (volume-weighted L2, relative) and the cell
  gradients against the exact gradient at the cell centroids (volume-weighted L2, relative);
- flow (HFV, K = 1e-13 m² isotropic, η = 1e-3 Pa s): p = P (sin πx̂ sin πŷ + ẑ² cos πx̂), source
  h = −div(K/η ∇p), p = exact on ∂Ω; error: cell pressures at the HFV cell points (L2, relative).

Rates are least-squares slopes against h = Lx/n (the cells' largest size; the thickness is h/a).
``--stabilisation`` repeats the mechanics at a = 100 (and the other ratios) with the
stabilisation scaled by these factors ([mechanics] stabilisation).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import sympy as sp

from polypore.mesh import FracturedMesh
from polypore.mesh.cornerpoint import BOUNDARY_NAMES, FaultSpec, generate_grid, process_grid
from polypore.models.flow import FlowData, FlowModel, Pressure
from polypore.models.mechanics import ContactMechanics, ContactSpec, DisplacementBC, MechanicsData
from polypore.runs.convergence import fit_rate
from polypore.solvers.factory import SolverChoice
from polypore.solvers.linear import LinearSolver

L = 1000.0
E, NU = 1.0e10, 0.25
MU, LAM = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
K, ETA = 1.0e-13, 1.0e-3


def family(n: int, a: float):
    """(mesh, info, H, z0) of the n × n × n grid with aspect ratio a."""
    H = L / a
    dip = np.degrees(np.arctan(0.5 * H / L))
    grid = generate_grid(n, n, n, extent=(L, L, H), top=1000.0, dip=dip,
                         faults=[FaultSpec("i", n // 2, 0.25 * H, name="F")], properties=False)
    mesh, info = process_grid(grid)
    return mesh, info, H, float(mesh.nodes[:, 2].min())


def manufactured(H: float, z0: float):
    """Numpy callables of the exact u, ∇u, f (mechanics) and p, h (flow) on the mapped cube."""
    x, y, z = sp.symbols("x y z")
    xh, yh, zh = x / L, y / L, (z - z0) / H
    pi = sp.pi
    U = 1e-3 * H
    u = [U * sp.sin(pi * xh) * sp.sin(pi * yh) * sp.sin(pi * zh), U * sp.cos(pi * xh) * sp.sin(pi * yh) * zh,
         U * sp.sin(pi * xh) * sp.cos(pi * yh) * sp.cos(pi * zh)]
    X = (x, y, z)
    G = [[sp.diff(u[i], X[j]) for j in range(3)] for i in range(3)]
    div = sum(G[i][i] for i in range(3))
    sig = [[MU * (G[i][j] + G[j][i]) + (LAM * div if i == j else 0) for j in range(3)] for i in range(3)]
    f = [-sum(sp.diff(sig[i][j], X[j]) for j in range(3)) for i in range(3)]
    P = 1.0e6
    p = P * (sp.sin(pi * xh) * sp.sin(pi * yh) + zh ** 2 * sp.cos(pi * xh))
    h = -(K / ETA) * sum(sp.diff(p, X[j], 2) for j in range(3))
    lam = lambda e: sp.lambdify(X, e, "numpy")
    fu, fG, ff, fp, fh = lam(u), lam(G), lam(f), lam(p), lam(h)

    def vec(fn):
        def out(Xp, t=0.0):
            Xp = np.atleast_2d(Xp)
            return np.stack([np.broadcast_to(c, Xp.shape[0]) for c in fn(*Xp.T)], axis=1)
        return out

    def grad(Xp):
        g = fG(*Xp.T)
        return np.stack([np.stack([np.broadcast_to(c, Xp.shape[0]) for c in row], 1) for row in g], 1)

    def scal(fn):
        return lambda x_, y_, z_, t=0.0: np.broadcast_to(fn(x_, y_, z_), np.shape(x_)).astype(float)

    return vec(fu), grad, vec(ff), scal(fp), scal(fh)


def l2(err, ref, w):
    return float(np.sqrt(np.sum(w * err ** 2) / np.sum(w * ref ** 2)))


def solve(n: int, a: float, stabs, flow: bool, linear: str):
    mesh, info, H, z0 = family(n, a)
    u, grad, f, p, h = manufactured(H, z0)
    fm = FracturedMesh.build(mesh, [])
    names = [b for b in BOUNDARY_NAMES if info.boundary[b].size]
    g = mesh.geometry
    vol = g.cell_volume
    row = {"n": n, "a": a, "cells": mesh.n_cells, "h": L / n, "mech": {}}
    for s in stabs:
        data = MechanicsData(mu=np.full(mesh.n_cells, MU), lam=np.full(mesh.n_cells, LAM),
                             displacement=tuple(DisplacementBC(b, (0, 1, 2), u) for b in names), body_force=f,
                             contact=ContactSpec("coulomb", 1.0, 0.0), stabilisation=s)
        t0 = time.perf_counter()
        P = ContactMechanics(fm, data, solver=SolverChoice(linear))
        st = P.solve(verbose=False)
        Gh = P.gradients(st)
        xc = g.cell_centroid
        uh = P.cell_displacement(st)
        row["mech"][s] = {"u": l2(uh - u(xc), u(xc), vol[:, None]),     # Π^K u at the centroid
                          "grad": l2((Gh - grad(xc)).reshape(len(xc), -1), grad(xc).reshape(len(xc), -1),
                                     vol[:, None]),
                          "seconds": time.perf_counter() - t0}
    if flow:
        t0 = time.perf_counter()
        flow = FlowModel(fm, FlowData(permeability=K, viscosity=ETA), {b: Pressure(p) for b in names}, cell_source=h,
                         solver=LinearSolver("amg", symmetric=True, rtol=1e-12))
        sol = flow.solve_steady()
        xp = flow.assembler.hfv.points
        pe = p(*xp.T)
        row["flow"] = {"p": l2(sol.cell - pe, pe, vol), "seconds": time.perf_counter() - t0}
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", nargs="+", type=int, default=[4, 8, 16])
    ap.add_argument("--ratios", nargs="+", type=float, default=[1.0, 10.0, 100.0])
    ap.add_argument("--stabilisation", nargs="+", type=float, default=[0.1, 1.0, 10.0])
    ap.add_argument("--linear", default="auto")
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = []
    t_all = time.perf_counter()
    for ratio in a.ratios:
        for n in a.levels:
            r = solve(n, ratio, a.stabilisation, True, a.linear)
            rows.append(r)
            m = ", ".join(f"S×{s:g}: u {v['u']:.2e} ∇u {v['grad']:.2e}" for s, v in r["mech"].items())
            print(f"a = {ratio:g}, n = {n} ({r['cells']} cells): {m}; p {r['flow']['p']:.2e}", flush=True)
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s\n")
    ns = ", ".join(map(str, a.levels))
    print(f"| a = dx/dz | stabilisation | n = {ns}: displacement error | rate | gradient error | rate | "
          "HFV pressure error | rate |")
    print("|---|---|---|---|---|---|---|---|")
    for ratio in a.ratios:
        rs = [r for r in rows if r["a"] == ratio]
        h = [r["h"] for r in rs]
        for s in a.stabilisation:
            eu = [r["mech"][s]["u"] for r in rs]
            eg = [r["mech"][s]["grad"] for r in rs]
            ep = [r["flow"]["p"] for r in rs]
            flow = (f"{' / '.join(f'{e:.2e}' for e in ep)} | {fit_rate(h, ep):.2f}" if s == 1.0 else "| ")
            print(f"| {ratio:g} | {s:g} | {' / '.join(f'{e:.2e}' for e in eu)} | {fit_rate(h, eu):.2f} | "
                  f"{' / '.join(f'{e:.2e}' for e in eg)} | {fit_rate(h, eg):.2f} | {flow} |")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
