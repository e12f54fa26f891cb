"""Hand estimate of the C6 slip onset from the Coulomb criterion, against a computed run.

    .venv/bin/python benchmarks/c6_onset.py RUN_DIR      # a `polypore run fault-injection` output

At the first face that slips (depth z, fault normal n at 80° dip), the in-situ state gives
σ_v = ρ_r g z, σ_h = k σ_v, p_h = ρ_w g z, the effective normal stress σ'_n0 = n·σ n − p_h
(compression positive) and the shear stress τ_0. Ignoring the poroelastic change of the total
stress, Coulomb slip needs the fault overpressure Δp* = σ'_n0 − τ_0/F. The estimated onset time
is when the computed fracture overpressure on that face reaches Δp* (interpolated in the
run's fracture output times is too coarse, so the matrix pressure monitored at
``fault_in_reservoir`` is used); the computed onset is the first step with a slipping face.
The gap between the two measures the poroelastic stress change that the hand estimate ignores.
"""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path

import numpy as np

DAY = 86400.0


def main() -> int:
    run = Path(sys.argv[1])
    s = json.loads((run / "summary.json").read_text())
    case = tomllib.loads((run / "case.toml").read_text())
    ini = case["initial_state"]
    g, rr, rw, k = ini.get("gravity", 9.81), ini["rock_density"], ini.get("fluid_density", 1000.0), ini["stress_ratio"]
    surface = ini.get("surface", 0.0)
    F = float(case["contact"]["friction"])
    (a, b) = np.asarray(case["fractures"][0]["vertices"], float)
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([t[1], -t[0]])
    on = s["slip_onset"]
    x = np.asarray(on["first_slipping_faces"][0])
    z = surface - x[1]
    sv, ph = rr * g * z, rw * g * z
    sigma = -np.diag([k * sv, sv])                           # total in-situ stress, compression < 0
    sn0 = -(n @ sigma @ n) - ph                              # effective normal stress, Pa
    tau0 = abs(t @ sigma @ n)
    dp_star = sn0 - tau0 / F
    m = s["monitor"]
    tm = np.asarray(m["time"])
    p = np.asarray(m["overpressure_at_points"]["fault_in_reservoir"])
    t_hand = float(np.interp(dp_star, p, tm)) if p.max() >= dp_star else float("nan")
    p_at_onset = float(np.interp(on["time"], tm, p))
    out = {"first_slipping_face": x.tolist(), "depth_m": z, "sigma_v_mpa": sv / 1e6, "sigma_h_mpa": k * sv / 1e6,
           "p_h_mpa": ph / 1e6, "effective_normal_stress_mpa": sn0 / 1e6, "shear_stress_mpa": tau0 / 1e6,
           "friction": F, "hand_overpressure_mpa": dp_star / 1e6, "hand_onset_days": t_hand / DAY,
           "computed_onset_days": [on["previous_time"] / DAY, on["time"] / DAY],
           "computed_overpressure_at_onset_mpa": p_at_onset / 1e6}
    for key, v in out.items():
        print(f"{key:38s} {v}")
    (run / "onset_estimate.json").write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
