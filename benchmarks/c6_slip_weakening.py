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
    return {"steps": rows, "stopped": stop}


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
    if args.json:
        args.json.write_text(json.dumps({"command": " ".join(sys.argv), "runs": res}, indent=1))
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
        for name, r in res.items():
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
