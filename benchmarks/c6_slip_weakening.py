"""C6 (``fault-injection``) with slip-weakening friction: stable and unstable growth of the slipping patch.

    .venv/bin/python benchmarks/c6_slip_weakening.py [--json out.json] [--png out.png]

Three runs of the built-in case, the same injection, the fault's static friction tan 25° = 0.466:

* ``coulomb``: the case as shipped (constant friction);
* ``weakening, F_d = 0.36``: slip-weakening to 0.36 over D_c = 5 mm. The fault's in-situ shear
  over effective normal traction is about 0.19, below F_d: even fully weakened it holds its
  background stress, so the slipping patch can only grow as the pressure front drives it
  (an "understressed" fault; Garagash and Germanovich 2012) — more slip than with Coulomb, stably;
* ``weakening, F_d = 0.15``: to 0.15 over D_c = 2 mm, below the background ratio: once a patch
  has weakened it cannot hold the background shear, and past its nucleation length it runs away.
  A quasi-static model has no equilibrium near the last one there; the run stops at that step,
  after the time loop's cuts, with the instability named in its error (issue 28 adds the
  radiation damping that carries a run through such an event).

Printed and plotted per run: the largest slip since the start and the largest slip rate (per
step) against time, and the day the last equilibrium was found.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from polypore.core.errors import RunError
from polypore.io.monitor3d import tangential
from polypore.models.contact import SLIP
from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh
from polypore.setup.poromechanics import poro_setup

VARIANTS = {
    "coulomb": [],
    "weakening, F_d = 0.36": ["contact.law=slip-weakening", "contact.dynamic_friction=0.36",
                              "contact.critical_slip=0.005"],
    "weakening, F_d = 0.15": ["contact.law=slip-weakening", "contact.dynamic_friction=0.15",
                              "contact.critical_slip=0.002"],
}
MAX_CUTS = 4            # the case's time.max_cuts: a step is halved at most this often


def run(overrides) -> dict:
    """The case's schedule stepped with the library (the run driver's step and its cuts), recording
    per step the faces in the slip state, the largest slip since the start and the largest slip
    increment per day; stops at a step that fails at the smallest cut."""
    case = load_case("fault-injection", overrides)
    fm = build_fractured_mesh(case)
    model, fs, _ = poro_setup(case, fm)
    times = fs.schedule.times()
    st = model.initial_state(fs.initial_pressure, t0=times[0])
    fq0 = model.fracture_quantities(st)
    n = model.mech.normal
    q0 = model.jumps(st.u)
    rows, stop = [], None

    def advance(st, ta, tb, depth):
        try:
            return model.step(st, tb - ta, tb)[0]
        except RunError as exc:
            if depth >= MAX_CUTS:
                raise RunError(f"day {ta / 86400:.3f} → {tb / 86400:.3f}: {exc}") from None
            mid = advance(st, ta, 0.5 * (ta + tb), depth + 1)
            return advance(mid, 0.5 * (ta + tb), tb, depth + 1)

    for ta, tb in zip(times[:-1], times[1:]):
        try:
            new = advance(st, float(ta), float(tb), 0)
        except RunError as exc:
            stop = str(exc)
            break
        slip = tangential(model.jumps(new.u) - q0, n)
        rate = tangential(model.jumps(new.u) - model.jumps(st.u), n) / ((tb - ta) / 86400)
        rows.append({"day": float(tb) / 86400, "slip_faces": int(np.sum(new.state == SLIP)),
                     "largest_slip_m": float(slip.max()), "largest_rate_m_per_day": float(rate.max()),
                     "slipped_area_m": float(model.mech.face_area[slip > 1e-4].sum())})
        st = new
    # the fields at the last converged step: the law holds on every face, and the traction change
    # against the overpressure
    fq = model.fracture_quantities(st)
    F = model.friction_fields(st).get("friction_coefficient")
    if F is None:
        F = model.mech.face_values(model.mech.law.friction_law.friction)
    ln, lt, slipping = fq["lambda_n"], fq["lambda_t"], fq["state"] == SLIP
    fields = {"slip_law_misfit": float(np.max(np.abs(lt[slipping] / ln[slipping] - F[slipping]), initial=0.0)),
              "stuck_inside_cone": bool(np.all(lt[~slipping] <= F[~slipping] * np.maximum(ln[~slipping], 0) * (1 + 1e-9)
                                               + 1e-9 * np.abs(ln).max())),
              "largest_dlambda_n_Pa": float(np.abs(ln - fq0["lambda_n"]).max()),
              "largest_p_f_Pa": float(fq["p_f"].max()),
              "s": fq["jump_t"].tolist(), "lambda_t": lt.tolist(),
              "slipped": (tangential(model.jumps(st.u) - q0, n) > 1e-4).tolist(),
              "length": model.mech.face_area.tolist()}
    return {"steps": rows, "stopped": stop, "fields": fields}


def dilatancy_free_pair() -> dict:
    """Coulomb against F_d = 0.36 without dilatancy (whose hardening damps the slip): the shear the
    weakened patch sheds, the extra slip, and a crack's bound 2Δτa/μ* for that drop (μ* = μ/(1 − ν))."""
    c = run(["flow.dilatancy_angle=0"])["fields"]
    w = run(["flow.dilatancy_angle=0"] + VARIANTS["weakening, F_d = 0.36"])["fields"]
    on = np.array(w["slipped"])
    length = np.array(w["length"])
    drop = np.array(c["lambda_t"]) - np.array(w["lambda_t"])
    case = load_case("fault-injection")
    E, nu = case.spec.material.E, case.spec.material.nu
    mu_star = E / (2 * (1 + nu)) / (1 - nu)
    bound = 2 * drop[on].mean() * 0.5 * length[on].sum() / mu_star
    return {"slipped_length_m": float(length[on].sum()), "mean_shear_drop_Pa": float(drop[on].mean()),
            "largest_shear_drop_Pa": float(drop[on].max()), "crack_bound_m": float(bound),
            "extra_slip_m": float(max(w["s"]) - max(c["s"])), "slip_coulomb_m": float(max(c["s"])),
            "slip_weakening_m": float(max(w["s"]))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path)
    ap.add_argument("--png", type=Path)
    args = ap.parse_args(argv)
    res = {}
    for name, ov in VARIANTS.items():
        r = run(ov)
        res[name] = r
        last = r["steps"][-1]
        print(f"{name:24s} to day {last['day']:.1f}: largest slip {1e3 * last['largest_slip_m']:.2f} mm, slipped "
              f"(> 0.1 mm) {last['slipped_area_m']:.0f} m of fault, largest slip rate over the run "
              f"{1e3 * max(x['largest_rate_m_per_day'] for x in r['steps']):.3f} mm/day"
              + (f"\n    stopped: {r['stopped'][:300]}" if r["stopped"] else ""), flush=True)
        f = r["fields"]
        print(f"    fields at the last converged step: slipping faces |λ_τ|/λ_n − F(δ) ≤ {f['slip_law_misfit']:.1e}, "
              f"stuck faces inside their cone: {f['stuck_inside_cone']}, largest |Δλ_n| "
              f"{f['largest_dlambda_n_Pa'] / 1e6:.2f} MPa against p_f {f['largest_p_f_Pa'] / 1e6:.2f} MPa", flush=True)
    pair = dilatancy_free_pair()
    res["without dilatancy"] = pair
    print(f"without dilatancy: the weakened patch ({pair['slipped_length_m']:.0f} m) sheds "
          f"{pair['mean_shear_drop_Pa'] / 1e6:.3f} MPa of shear on average ({pair['largest_shear_drop_Pa'] / 1e6:.2f} "
          f"at most); a crack with that uniform drop slips {1e3 * pair['crack_bound_m']:.1f} mm more at its centre "
          f"(an upper bound); the runs differ by {1e3 * pair['extra_slip_m']:.2f} mm "
          f"({1e3 * pair['slip_weakening_m']:.2f} against {1e3 * pair['slip_coulomb_m']:.2f} mm)", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"command": " ".join(sys.argv), "runs": res}, indent=1))
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
        for name, r in res.items():
            if "steps" not in r:
                continue
            d = [x["day"] for x in r["steps"]]
            lab = name + (" (no equilibrium after)" if r["stopped"] else "")
            a1.plot(d, [1e3 * x["largest_slip_m"] for x in r["steps"]], ".-", ms=3, label=lab)
            a2.semilogy(d, [max(1e3 * x["largest_rate_m_per_day"], 1e-6) for x in r["steps"]], ".-", ms=3, label=lab)
        a1.set_xlabel("day")
        a1.set_ylabel("largest slip since the start (mm)")
        a1.set_title("C6: Coulomb and slip-weakening friction")
        a1.legend(fontsize=8)
        a2.set_xlabel("day")
        a2.set_ylabel("largest slip rate (mm/day, per step)")
        a2.set_ylim(1e-4, None)
        a2.set_title("largest slip rate per step")
        fig.tight_layout()
        fig.savefig(args.png, dpi=130)
    return 0


if __name__ == "__main__":
    sys.exit(main())
