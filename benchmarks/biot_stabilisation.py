"""Small-step pressure overshoot and Terzaghi / Mandel accuracy, with and without the pressure
stabilisation of the coupled scheme (models/poromechanics.py, "Pressure stabilisation").

    .venv/bin/python benchmarks/biot_stabilisation.py        # 2.5 min CPU; prints the tables,
                                                              # writes docs/biot_stabilisation.json

1. **Overshoot.** Unit square (triangles, Cartesian) / unit cube (tetrahedra) under a sudden
   load σ on top, drained top (p = 0), rollers on the sides, fixed bottom; one implicit-Euler
   step Δt = θ h²/c_v from rest for θ = 1 … 10⁻³ (h = mean |K|^{1/d}). The exact pressure is
   at most the undrained p_u = b M σ/(K_d + b² M) everywhere; the overshoot is
   max_θ max_K (p_K − p_u)/p_u, and ``min`` is min_θ min_K p_K/p_u − 1 (the drained layer).
2. **Terzaghi.** The same column, 1D series solution (as in tests/cases/test_poromechanics.py):
   Cartesian column 0.1 × 1 one cell wide (ny = 10, 20, 40) and triangles on 0.2 × 1
   (size 0.1, 0.05, 0.025). First step 10⁻⁶ T_c (undrained), then Δt ∝ h² (50, 200, 800 steps
   to 0.5 T_c, T_c = H²/c_v). Errors of p_K against the series at the cell centroids, relative to p_u:
   max over cells and the L2 mean √(Σ|K| e_K²/|Ω|), at t/T_c = 0.05, 0.2, 0.5.
3. **Mandel.** Plane-strain slab −a < x < a, −ℓ < y < ℓ squeezed by frictionless rigid plates
   carrying 2F per unit length, drained lateral faces; the quarter 0 < x, y < 1 (a = ℓ = 1 m) with
   rollers on x = 0 and y = 0, u_y(x, 1, t) from the series (the plate) and free, drained x = a.
   Series (Abousleiman et al. 1996, plane strain): with tan α_n = α_n (1 − ν)/(ν_u − ν),

       p = (2 F B (1 + ν_u)/(3a)) Σ_n s_n/(α_n − s_n c_n) (cos(α_n x/a) − c_n) e^{−α_n² c t/a²}
       u_y/y = −F(1 − ν)/(2 μ a) + F(1 − ν_u)/(μ a) Σ_n s_n c_n/(α_n − s_n c_n) e^{−α_n² c t/a²}

   (s_n = sin α_n, c_n = cos α_n, B Skempton's coefficient, ν_u the undrained Poisson ratio, c the
   consolidation coefficient = k/η/(1/M + b²/(λ_L + 2μ))). Check of the series against the runs: the

   computed plate force (the Dirichlet reaction on y = 1) must be F = σ a at every time; its
   error is reported. Cartesian n × n (n = 8, 16, 32) and triangles (size 1/8, 1/16, 1/32);
   first step 10⁻⁵ T, then Δt ∝ h² (20, 80, 320 steps to 0.2 T, T = a²/c); pressure errors at
   t/T = 0.01, 0.05, 0.2 (the Mandel–Cryer rise at the centre peaks around 0.05–0.1), relative
   to the undrained p_0 = F B (1 + ν_u)/(3a).

Rates: least-squares slope of log(error) against log(h) over the three meshes.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from polypore.mesh import FracturedMesh
from polypore.mesh.generators.cartesian import cartesian_mesh
from polypore.mesh.generators.simplicial import simplicial_mesh
from polypore.models.flow import FlowData, Pressure
from polypore.models.materials import lame
from polypore.models.mechanics import DisplacementBC, MechanicsData, TractionBC
from polypore.models.poromechanics import STABILISATION, Poromechanics

ROOT = Path(__file__).resolve().parents[1]
MAT = dict(E=1e8, nu=0.25, b=1.0, M=1e9, k=1e-13, eta=1e-3, load=1e5)
MU, LAM = lame(MAT["E"], MAT["nu"])
KD = LAM + 2 * MU                                                    # oedometric modulus, Pa
CV = MAT["k"] / MAT["eta"] / (MAT["b"] ** 2 / KD + 1 / MAT["M"])     # consolidation coefficient, m²/s
PU = MAT["b"] * MAT["M"] * MAT["load"] / (KD + MAT["b"] ** 2 * MAT["M"])   # undrained pressure, Pa
ZERO = lambda X, t: 0.0 * X  # noqa: E731
DELTAS = (0.0, STABILISATION)


def _model(mesh, delta, displacement, traction, drained):
    fm = FracturedMesh.build(mesh, [])
    nc = mesh.n_cells
    md = MechanicsData(mu=np.full(nc, MU), lam=np.full(nc, LAM), displacement=displacement, traction=traction)
    fd = FlowData(permeability=MAT["k"], viscosity=MAT["eta"], biot_modulus=MAT["M"], biot_coefficient=MAT["b"])
    return Poromechanics(fm, md, fd, {drained: Pressure(0.0)}, pressure_stabilisation=delta)


def column_model(mesh, delta):
    """Load σ on top for t > 0, drained top, rollers on the sides, fixed bottom."""
    d = mesh.dim
    top, bot = ("ymax", "ymin") if d == 2 else ("zmax", "zmin")
    lateral = [b for b in ("xmin", "xmax", "ymin", "ymax")[: 2 * (d - 1)] if b not in (top, bot)]

    def traction(X, t):
        v = np.zeros((len(X), d))
        v[:, -1] = -MAT["load"] * (t > 0)
        return v

    disp = [DisplacementBC(bot, tuple(range(d)), ZERO)] + [DisplacementBC(b, ("xyz".index(b[0]),), ZERO)
                                                         for b in lateral]
    return _model(mesh, delta, disp, [TractionBC(top, traction)], top)


# ---- 1. overshoot -------------------------------------------------------------------------------
THETAS = (1.0, 0.3, 0.1, 0.03, 0.01, 1e-3)


def overshoot(mesh, delta):
    """(max_θ max_K p_K/p_u − 1, min_θ min_K p_K/p_u − 1, θ of the max) of one step Δt = θ h²/c_v."""
    P = column_model(mesh, delta)
    h = float(np.mean(mesh.geometry.cell_volume ** (1.0 / mesh.dim)))
    st0 = P.initial_state(0.0)
    hi, lo, arg = -np.inf, np.inf, None
    for th in THETAS:
        st, _ = P.step(st0, th * h * h / CV, energy=False)
        r = P.cell_pressure(st) / PU - 1
        if r.max() > hi:
            hi, arg = float(r.max()), th
        lo = min(lo, float(r.min()))
    return hi, lo, arg


# ---- 2. Terzaghi ----------------------------------------------------------------------------------
def terzaghi_pressure(z, t, H=1.0, n_terms=400):
    """Series p(z, t), drained top z = H, impervious bottom z = 0, Pa."""
    m = np.arange(n_terms)[:, None]
    a = (2 * m + 1) * np.pi / (2 * H)
    return (4 * PU / ((2 * m + 1) * np.pi) * np.sin(a * (H - z)) * np.exp(-a * a * CV * t)).sum(0)


def _errors(P, st, exact, ref):
    g = P.fm.mesh.geometry
    e = (P.cell_pressure(st) - exact) / ref
    return float(np.abs(e).max()), float(np.sqrt(np.sum(g.cell_volume * e * e) / g.cell_volume.sum()))


def terzaghi(mesh, delta, n_steps, marks=(0.05, 0.2, 0.5)):
    """{t/T_c: (max error, L2 error)} of the column run (first step 10⁻⁶ T_c, then n_steps to 0.5 T_c)."""
    Tc = 1.0 / CV
    P = column_model(mesh, delta)
    z = P.fm.mesh.geometry.cell_centroid[:, -1]
    return _march(P, 1e-6 * Tc, Tc, 0.5, n_steps, marks, lambda st: _errors(P, st, terzaghi_pressure(z, st.time), PU))


def _march(P, first, T, end, n_steps, marks, measure):
    """An undrained first step of ``first`` (s), then n_steps up to end·T (s); {mark: measure(state)}
    at the steps that reach mark·T (marks are fractions of the time scale T, s)."""
    st, _ = P.step(P.initial_state(0.0), first, energy=False)
    at = {round(f * n_steps / end): f for f in marks}
    out = {}
    for n in range(1, n_steps + 1):
        st, _ = P.step(st, end * T / n_steps, energy=False)
        if n in at:
            out[at[n]] = measure(st)
    return out


# ---- 3. Mandel ------------------------------------------------------------------------------------
class Mandel:
    """Mandel's series (plane strain) for the material MAT, half-width a, load σ = F/a."""

    def __init__(self, a=1.0, n_terms=3000):
        K = LAM + 2 * MU / 3
        Ku = K + MAT["b"] ** 2 * MAT["M"]
        self.B = MAT["b"] * MAT["M"] / Ku
        self.nu = (3 * K - 2 * MU) / (2 * (3 * K + MU))
        self.nuu = (3 * Ku - 2 * MU) / (2 * (3 * Ku + MU))
        self.c = CV
        self.a = a
        self.F = MAT["load"] * a
        r = (1 - self.nu) / (self.nuu - self.nu)                         # tan α = r α, r > 1
        f = lambda x: np.sin(x) - r * x * np.cos(x)  # noqa: E731  (no poles)
        eps = 1e-9
        self.alpha = np.array([brentq(f, max(i * np.pi, eps), i * np.pi + np.pi / 2 - eps) for i in range(n_terms)])
        al = self.alpha
        self.cp = np.sin(al) / (al - np.sin(al) * np.cos(al))
        self.cu = np.sin(al) * np.cos(al) / (al - np.sin(al) * np.cos(al))
        self.p0 = self.F * self.B * (1 + self.nuu) / (3 * a)             # undrained pressure, Pa

    def _decay(self, t):
        return np.exp(-self.alpha ** 2 * self.c * t / self.a ** 2)

    def pressure(self, x, t):
        al, e = self.alpha[:, None], self._decay(t)[:, None]
        return 2 * self.p0 * ((self.cp[:, None] * e) * (np.cos(al * x / self.a) - np.cos(al))).sum(0)

    def uy_over_y(self, t):
        """u_y/y, the plate's vertical strain (u_y(x, y, t) = this × y)."""
        F, a, mu = self.F, self.a, MU
        return -F * (1 - self.nu) / (2 * mu * a) + F * (1 - self.nuu) / (mu * a) * float(self.cu @ self._decay(t))


def mandel_model(mesh, delta, sol: Mandel):
    plate = lambda X, t: np.outer(X[:, 1], [0.0, sol.uy_over_y(t) if t > 0 else 0.0])  # noqa: E731
    disp = [DisplacementBC("xmin", (0,), ZERO), DisplacementBC("ymin", (1,), ZERO), DisplacementBC("ymax", (1,), plate)]
    return _model(mesh, delta, disp, [], "xmax")


def plate_force(P, st):
    """Vertical force of the plate on the quarter, N/m (the Dirichlet reaction on y = 1)."""
    mech = P.mech
    u = st.u.ravel()
    R = mech.A @ u - P.G @ st.p - P.load_vector(st.time)
    top = np.isclose(P.fm.mesh.nodes[P.fm.sides.side_node][:, 1], 1.0)
    return float(R.reshape(-1, 2)[: P.fm.sides.n_sides][top, 1].sum())


def mandel(mesh, delta, n_steps, sol: Mandel, marks=(0.01, 0.05, 0.2)):
    """{t/T: (max error, L2 error, plate-force error)} (first step 10⁻⁵ T, then n_steps to 0.2 T)."""
    T = sol.a ** 2 / sol.c
    P = mandel_model(mesh, delta, sol)
    x = P.fm.mesh.geometry.cell_centroid[:, 0]
    return _march(P, 1e-5 * T, T, 0.2, n_steps, marks,
                  lambda st: _errors(P, st, sol.pressure(x, st.time), sol.p0) + (abs(plate_force(P, st) + sol.F) / sol.F,))


# ---- driver ---------------------------------------------------------------------------------------
def slope(h, e):
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def study(name, meshes, hs, steps, run, marks):
    """Errors per δ, mesh and time, the fitted rates and the range of error(δ)/error(0); prints a table."""
    t0 = time.perf_counter()
    rows = {}
    for delta in DELTAS:
        errs = [run(m, delta, n) for m, n in zip(meshes, steps)]
        rows[str(delta)] = {"errors": [{str(k): v for k, v in e.items()} for e in errs],
                            "rate_max": {str(f): slope(hs, [e[f][0] for e in errs]) for f in marks},
                            "rate_l2": {str(f): slope(hs, [e[f][1] for e in errs]) for f in marks}}
    off, on = (rows[str(d)]["errors"] for d in DELTAS)
    ratio = [b[str(f)][i] / a[str(f)][i] for a, b in zip(off, on) for f in marks for i in (0, 1)]
    print(f"\n{name}: cells {[m.n_cells for m in meshes]}; max, L2 error / p_undrained at t/T = {marks}")
    for delta, r in rows.items():
        for m, e in zip(meshes, r["errors"]):
            cols = "  ".join(f"{e[str(f)][0]:.2e} {e[str(f)][1]:.2e}" for f in marks)
            print(f"  δ = {delta:<5} {m.n_cells:6d} cells: {cols}")
        print(f"  δ = {delta:<5} rate max {[round(r['rate_max'][str(f)], 2) for f in marks]}, "
              f"L2 {[round(r['rate_l2'][str(f)], 2) for f in marks]}")
    print(f"  error(δ = {DELTAS[1]}) / error(δ = 0): {min(ratio):.2f} … {max(ratio):.2f}")
    return {"cells": [m.n_cells for m in meshes], "h": list(hs), "steps": list(steps), "marks": list(marks),
            "delta": rows, "ratio_range": [min(ratio), max(ratio)], "seconds": time.perf_counter() - t0}


def main() -> int:
    t_all = time.perf_counter()
    out = {"material": MAT, "undrained_pressure": PU, "consolidation_coefficient": CV, "thetas": list(THETAS),
           "default_delta": STABILISATION}
    # 1. overshoot
    cases = {"triangles (unit square, size 0.1)": simplicial_mesh([0, 0], [1, 1], [], 0.1),
             "triangles (unit square, size 0.05)": simplicial_mesh([0, 0], [1, 1], [], 0.05),
             "tetrahedra (unit cube, size 0.3)": simplicial_mesh([0, 0, 0], [1, 1, 1], [], 0.3),
             "tetrahedra (unit cube, size 0.2)": simplicial_mesh([0, 0, 0], [1, 1, 1], [], 0.2),
             "Cartesian 20 × 20": cartesian_mesh([np.linspace(0, 1, 21)] * 2),
             "Cartesian 8 × 8 × 8": cartesian_mesh([np.linspace(0, 1, 9)] * 3)}
    print("overshoot max_θ max_K (p_K − p_u)/p_u (θ of the max) | min_θ min_K p_K/p_u − 1, "
          "one step Δt = θ h²/c_v")
    ov = {}
    for name, mesh in cases.items():
        ov[name] = {"cells": mesh.n_cells}
        line = []
        for delta in DELTAS:
            hi, lo, arg = overshoot(mesh, delta)
            ov[name][str(delta)] = {"overshoot": hi, "min": lo, "theta": arg}
            line.append(f"δ = {delta}: {100 * hi:6.3f} % (θ = {arg:g}) | {100 * lo:6.1f} %")
        print(f"  {name:36s} {mesh.n_cells:6d} cells  " + "   ".join(line))
    out["overshoot"] = ov
    out["seconds_overshoot"] = time.perf_counter() - t_all
    # 2. Terzaghi
    hs = (0.1, 0.05, 0.025)
    steps = (50, 200, 800)
    columns = [cartesian_mesh([np.linspace(0, 0.1, 2), np.linspace(0, 1, round(1 / h) + 1)]) for h in hs]
    out["terzaghi_cartesian"] = study("Terzaghi, Cartesian column 0.1 × 1", columns, hs, steps, terzaghi,
                                      (0.05, 0.2, 0.5))
    out["terzaghi_triangles"] = study("Terzaghi, triangles on 0.2 × 1",
                                      [simplicial_mesh([0, 0], [0.2, 1], [], h) for h in hs], hs, steps, terzaghi,
                                      (0.05, 0.2, 0.5))
    # 3. Mandel
    sol = Mandel()
    hs = (1 / 8, 1 / 16, 1 / 32)
    steps = (20, 80, 320)
    run = lambda m, d, n: mandel(m, d, n, sol)  # noqa: E731
    squares = [cartesian_mesh([np.linspace(0, 1, round(1 / h) + 1)] * 2) for h in hs]
    out["mandel_cartesian"] = study("Mandel, Cartesian quarter", squares, hs, steps, run, (0.01, 0.05, 0.2))
    out["mandel_triangles"] = study("Mandel, triangles on the quarter",
                                    [simplicial_mesh([0, 0], [1, 1], [], h) for h in hs], hs, steps, run,
                                    (0.01, 0.05, 0.2))
    # the series' plate displacement must carry the force F: its error, per mesh (all runs, times)
    force = [max(r["errors"][i][str(f)][2] for k in ("mandel_cartesian", "mandel_triangles")
                 for r in out[k]["delta"].values() for f in (0.01, 0.05, 0.2)) for i in range(len(hs))]
    print(f"\nMandel plate force from the series' u_y against F, largest relative error per mesh (coarse → fine): "
          + ", ".join(f"{v:.1e}" for v in force))
    out["mandel_plate_force_error"] = force
    out["seconds"] = time.perf_counter() - t_all
    path = ROOT / "docs" / "biot_stabilisation.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"\nwrote {path.relative_to(ROOT)} ({out['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
