"""Issue 28: the nucleation half-length of a rate-and-state fault against Rubin and Ampuero (2005).

    .venv/bin/python benchmarks/rate_state_nucleation.py [--faces 1.0 0.5] [--json docs/rate_state_nucleation.json]

Aging law, in-plane (mode II) plane strain, μ′ = μ/(1 − ν). Rubin and Ampuero (2005, JGR 110,
B11312): with L_b = μ′ D_c/(b σ′), a fault nucleates over a half-length that approaches

    L∞ = (1/π) (b/(b − a))² L_b          for a/b ≳ 0.3781 (the zone expands to L∞),
    L_ν = 1.3774 L_b                      for a/b ≲ 0.3781 (a fixed length),

once the slip rate has grown far above its interseismic value. The model: a fault along y = 0
across a 400 m × 200 m plane-strain block, every side displaced as u = ((γ₀ + γ̇ t) y, −ε y): a
uniform σ′ = 10 MPa while it sticks and a shear stress μγ₀ = 0.5 σ′ rising at μγ̇ = 0.1 Pa/s;
f₀ = 0.6 − Δf exp(−(x/5 m)²), a weak spot (--spot, Δf = 0.005 by default: 50 kPa of strength)
that places the nucleation in the centre, far from the ends pinned by the boundary (with
Δf = 0.02 the zone stayed the spot's size, 0.66–0.88 L∞ at a/b = 0.5, from 1e-8 to 1e-2 m/s);
initial state θ₀ = D_c/V_i with V_i = 1e-12 m/s; D_c = 0.1 mm, b = 0.015, quasi-dynamic damping
with c_s = 3000 m/s.

Every accepted sub-step's slip-rate profile is read (:class:`Watched`); printed per
a/b and face size: the half-length of the zone where V > V_max/2 and V > V_max/10 when V_max
crosses 1e-8 … 1e-2 m/s, over L∞ and L_ν. The run stops there (the rupture then spreads along the
fault, ~100 sub-steps per face it reaches; with a/b = 0.75 V_max stays below 2 cm/s meanwhile).
"""

from __future__ import annotations

import argparse
import json
import logging
import tempfile
import time
from pathlib import Path

import numpy as np

from polypore.runs.coupled import CoupledMarch, set_up
from polypore.runs.recorder import OutputSeries
from polypore.setup.casefile import load_case

E, NU, SIGMA, B, DC, CS = 2.0e10, 0.25, 1.0e7, 0.015, 1.0e-4, 3000.0
MU = E / (2 * (1 + NU))
MU_P = MU / (1 - NU)                    # μ′ of mode II
LAMBDA = E * NU / ((1 + NU) * (1 - 2 * NU))
THRESHOLDS = (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2)
STOP = THRESHOLDS[-1]                   # m/s: radiation damping bounds V near Δτ/η (~1e-2–1e-1 m/s here)

CASE = """
name = "rate-state-nucleation"
description = "nucleation under a uniform rising shear stress (benchmarks/rate_state_nucleation.py)"
[mesh]
generator = "simplicial"
lower = [-200.0, -100.0]
upper = [200.0, 100.0]
size = 25.0
fracture_size = {face}

[[fractures]]
name = "fault"
vertices = [[-200.0, 0.0], [200.0, 0.0]]

[parameters]
g0 = {g0!r}
gd = {gd!r}
eps = {eps!r}

[material]
E = {E!r}
nu = {NU!r}

[mechanics]
biot = 0.0
{sides}
[contact]
law = "rate-and-state"
friction = "0.6 - {spot!r}*exp(-(x/5.0)**2)"
a = {a!r}
b = {B!r}
critical_slip = {DC!r}
reference_rate = 1.0e-6
initial_slip_rate = 1.0e-12
initial_state_from = "steady"
shear_wave_speed = {CS!r}

[flow]
permeability = 1.0e-15
porosity = 0.1
fluid_compressibility = 4.4e-10
viscosity = 1.0e-3
aperture = 1.0e-5
normal_permeability = 1.0e-15
initial_pressure = 0.0

[[flow.boundary]]
name = "ymax"
pressure = 0.0

[time]
end = 1.0e9
step = 1.0e6
output_times = [1.0e9]
rate_tolerance = {tol!r}
"""
SIDE = """
[[mechanics.boundary]]
name = "{name}"
ux = "(g0 + gd*t)*y"
uy = "-eps*y"
"""


class Stop(Exception):
    """V_max passed STOP, the last threshold: the nucleation is over."""


class Profiles:
    """The slip-rate profile at the first accepted sub-step whose V_max passes each threshold
    (:meth:`add` from :class:`Watched`)."""

    def __init__(self, x):
        self.order = np.argsort(x)                  # the faces along the fault
        self.x, self.rows, self.steps = x[self.order], [], 0

    def add(self, t0, t1, rate, slip, injected=0.0):
        self.steps += 1
        rate = rate[self.order]
        vmax = float(rate.max())
        while len(self.rows) < len(THRESHOLDS) and vmax > THRESHOLDS[len(self.rows)]:
            self.rows.append({"threshold": THRESHOLDS[len(self.rows)], "time": t1, "v_max": vmax,
                              "x_peak": float(self.x[np.argmax(rate)]),
                              "half_length_half": half_length(self.x, rate, 0.5),
                              "half_length_tenth": half_length(self.x, rate, 0.1)})
            r = self.rows[-1]
            print(f"    V_max > {r['threshold']:g} m/s at t = {t1:.6g} s (sub-step {self.steps}): half-lengths "
                  f"{r['half_length_half']:.3g} m (V > V_max/2), {r['half_length_tenth']:.3g} m (V > V_max/10)",
                  flush=True)
        if vmax > STOP:
            raise Stop


class Watched(CoupledMarch):
    """The run's march, each sub-step that the step control accepts shown to ``profiles`` at once
    (a run's catalogue sees the sub-steps only after their schedule step, and the rupture that
    follows the nucleation spreads over the whole fault within one)."""

    def __init__(self, profiles, *args):
        super().__init__(*args, catalogue=Ignore())
        self.profiles = profiles

    def step(self, st, ta, tb):
        new, out = super().step(st, ta, tb)
        if out.get("rate_rejection") is None:
            self.profiles.add(*out["seismic"])
        return new, out


class Ignore:
    """A catalogue that keeps nothing (the march then hands each sub-step's slip rates over)."""

    def add(self, *args):
        pass


def half_length(x, v, frac):
    """Half the extent (m) of the connected zone around the peak where v > frac·max(v), to the
    faces' outer edges (uniform faces of width x[1] − x[0])."""
    i = int(np.argmax(v))
    above = v > frac * v[i]
    lo = i
    while lo > 0 and above[lo - 1]:
        lo -= 1
    hi = i
    while hi < len(v) - 1 and above[hi + 1]:
        hi += 1
    h = x[1] - x[0]
    return 0.5 * (x[hi] - x[lo] + h)


def estimates(a):
    lb = MU_P * DC / (B * SIGMA)
    return {"L_b": lb, "L_inf": (B / (B - a)) ** 2 * lb / np.pi, "L_nu": 1.3774 * lb}


def run(a, face, tol, spot=0.005):
    eps = SIGMA / (LAMBDA + 2 * MU)                     # σ_yy = −(λ + 2μ) ε = −σ′
    g0, gd = 0.5 * SIGMA / MU, 0.1 / MU
    sides = "".join(SIDE.format(name=n) for n in ("xmin", "xmax", "ymin", "ymax"))
    text = CASE.format(face=face, g0=g0, gd=gd, eps=eps, E=E, NU=NU, sides=sides, a=a, B=B, DC=DC, CS=CS, tol=tol,
                       spot=spot)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "case.toml"
        path.write_text(text)
        case = load_case(str(path))
        r, state, recorder = set_up(case)
        prof = Profiles(r.fm.mesh.geometry.face_centroid[r.fm.network.faces][:, 0])
        tic = time.perf_counter()
        try:
            Watched(prof, r.model, r.schedule, recorder, OutputSeries(Path(d))).run(state)
        except Stop:
            pass
        return {"a": a, "a/b": a / B, "face_m": face, "tol": tol, "spot": spot, "sub_steps": prof.steps,
                "seconds": time.perf_counter() - tic, "profiles": prof.rows, **estimates(a)}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--faces", type=float, nargs="+", default=[2.0, 1.0])
    p.add_argument("--ratios", type=float, nargs="+", default=[0.5, 0.25], help="a/b")
    p.add_argument("--tol", type=float, default=0.05)
    p.add_argument("--spot", type=float, default=0.005, help="Δf of the weak spot")
    p.add_argument("--json")
    p.add_argument("--log", action="store_true", help="the run's step log")
    args = p.parse_args()
    if args.log:
        logging.basicConfig(level=logging.INFO, format="%(message)s")
    out = []
    for ab in args.ratios:
        for face in args.faces:
            res = run(ab * B, face, args.tol, args.spot)
            out.append(res)
            ref = res["L_inf"] if ab > 0.3781 else res["L_nu"]
            name = "L∞" if ab > 0.3781 else "L_ν"
            print(f"a/b = {ab}, faces {face} m: L_b = {res['L_b']:.3g} m, {name} = {ref:.3g} m; "
                  f"{res['sub_steps']} sub-steps, {res['seconds']:.0f} s", flush=True)
            for row in res["profiles"]:
                print(f"  V_max {row['v_max']:.2e} m/s at t = {row['time']:.6g} s, peak x = {row['x_peak']:.1f} m: "
                      f"half-length (V > V_max/2) {row['half_length_half']:.3g} m = "
                      f"{row['half_length_half'] / ref:.2f} {name}, (V > V_max/10) {row['half_length_tenth']:.3g} m "
                      f"= {row['half_length_tenth'] / ref:.2f} {name}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
