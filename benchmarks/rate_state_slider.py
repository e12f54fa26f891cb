"""Issue 28: polypore's rate-and-state step on the spring-slider against the ODE (Radau, rtol 1e-11).

    .venv/bin/python benchmarks/rate_state_slider.py [--json docs/rate_state_slider.json]

1. Fixed steps, a 10 % velocity step, stable (k = 2k_c) and growing (k = 0.8k_c, η > 0), both
   state laws: the largest errors in slip (relative), ln V and ln θ over the run for n, 2n, 4n, 8n
   steps, their observed order, and Richardson's 2X(Δt/2) − X(Δt) of the last two.
2. Stick-slip (k = 0.2k_c, η = μ/(2c_s)) with the run's time step control (runs/coupled.py
   rate_step_control on RateAndState.step_error: ln V and ln θ change by ≈ tol per step): the times of the first three
   events (peak V) against Radau's, and the steps taken, for tol = 0.1, 0.05, 0.025.
The scheme is the one a contact patch takes in the model (cases/spring_slider.py, PatchSlider).
"""

import argparse
import json
import time

import numpy as np

from polypore.cases.spring_slider import PatchSlider, SpringSlider, polypore_steps
from polypore.runs.coupled import rate_step_control

A, B, DC, F0, V0, SIGMA = 0.010, 0.015, 1e-4, 0.6, 1e-6, 50e6
KC = (B - A) * SIGMA / DC
ETA = 30e9 / (2 * 3464.0)
Y0 = np.array([0.0, np.log(1.1e-9), np.log(DC / 1e-9)])


def errors(s, t, d, V, th):
    ref = s.integrate(t[-1], Y0, t_eval=t)
    return [float(np.max(np.abs(d - ref.y[0])) / np.max(np.abs(ref.y[0]))),
            float(np.max(np.abs(np.log(V[1:]) - ref.y[1][1:]))), float(np.max(np.abs(np.log(th) - ref.y[2])))]


def fixed(law, k, eta, T, ns=(1000, 2000, 4000, 8000)):
    s = SpringSlider(k=k, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, law=law, eta=eta)
    rows, runs = [], []
    for n in ns:
        t, d, V, th, _ = polypore_steps(s, Y0, T / n, n)
        runs.append((t, d, V, th))
        rows.append({"steps": n, "errors": errors(s, t, d, V, th)})
    (t1, d1, V1, th1), (_, d2, V2, th2) = runs[-2], runs[-1]
    # Richardson on the coarse run's times: X(Δt/2) at every other step
    d_r, lv_r, lt_r = 2 * d2[::2] - d1, 2 * np.log(V2[::2][1:]) - np.log(V1[1:]), 2 * np.log(th2[::2]) - np.log(th1)
    ref = s.integrate(T, Y0, t_eval=t1)
    rich = [float(np.max(np.abs(d_r - ref.y[0])) / np.max(np.abs(ref.y[0]))),
            float(np.max(np.abs(lv_r - ref.y[1][1:]))), float(np.max(np.abs(lt_r - ref.y[2])))]
    e = np.array([r["errors"] for r in rows])
    return {"law": law, "k/kc": k / KC, "eta": eta, "T": T, "rows": rows,
            "order": np.log2(e[:-1] / e[1:]).tolist(), "richardson": rich}


def adaptive(law, tol, T, k=0.2 * KC):
    """The slider stepped with the run's control (runs/coupled.py rate_step_control on the law's
    step_error): Δt so that ln V and ln θ change by ≈ tol per step."""
    p = PatchSlider(SpringSlider(k=k, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, law=law, eta=ETA), Y0)
    delta, state = p.delta0, p.state0
    t, h, steps, rejected = 0.0, 1.0, 0, 0
    ts, Vs = [0.0], [state[0, 1]]
    sigma = np.full(1, SIGMA)
    while t < T:
        h = min(h, T - t)
        new = p.step(t + h, h, delta, state)
        why, factor = rate_step_control(p.law.step_error(state, new, h, sigma), tol)
        if why:
            h *= factor
            rejected += 1
            continue
        t, delta, state = t + h, delta + new[0, 1] * h, new
        steps += 1
        ts.append(t)
        Vs.append(state[0, 1])
        h *= factor
    return np.array(ts), np.array(Vs), steps, rejected


def event_times(t, V, threshold=1e-3, count=3):
    """Times of the peak V of the first ``count`` episodes above ``threshold`` m/s."""
    above = V > threshold
    out, i = [], 0
    while i < len(V) and len(out) < count:
        if above[i]:
            j = i
            while j < len(V) and above[j]:
                j += 1
            out.append(float(t[i + int(np.argmax(V[i:j]))]))
            i = j
        else:
            i += 1
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--json", help="write the results here")
    args = p.parse_args()
    res = {"fixed": [], "stick_slip": []}
    for law in ("aging", "slip"):
        for k, eta, T in ((2 * KC, 0.0, 4e5), (0.8 * KC, ETA, 2e6)):
            r = fixed(law, k, eta, T)
            res["fixed"].append(r)
            print(f"{law:5s} k = {r['k/kc']:.1f} k_c: " + "; ".join(
                f"n {row['steps']}: slip {row['errors'][0]:.2e} lnV {row['errors'][1]:.2e} lnθ {row['errors'][2]:.2e}"
                for row in r["rows"]) + f"; order {np.round(r['order'][-1], 3).tolist()}; Richardson "
                f"{', '.join(f'{x:.1e}' for x in r['richardson'])}", flush=True)
    T = 3e8
    for law in ("aging", "slip"):
        s = SpringSlider(k=0.2 * KC, sigma=SIGMA, a=A, b=B, Dc=DC, f0=F0, V0=V0, law=law, eta=ETA)
        ref = s.integrate(T, Y0)
        t_ref = event_times(ref.t, np.exp(ref.y[1]))
        for tol in (0.1, 0.05, 0.025):
            tic = time.perf_counter()
            t, V, steps, rej = adaptive(law, tol, T)
            ev = event_times(t, V)
            rel = [abs(a - b) / b for a, b in zip(ev, t_ref, strict=False)]   # a run may find fewer events
            row = {"law": law, "tol": tol, "steps": steps, "rejected": rej, "events": ev, "events_ref": t_ref,
                   "relative_time_error": rel, "peak_V": float(V.max()), "peak_V_ref": float(np.exp(ref.y[1].max())),
                   "seconds": time.perf_counter() - tic}
            res["stick_slip"].append(row)
            print(f"stick-slip {law:5s} tol {tol}: {steps} steps ({rej} rejected), events at "
                  f"{', '.join(f'{e:.6g}' for e in ev)} s (Radau {', '.join(f'{e:.6g}' for e in t_ref)}), relative "
                  f"{', '.join(f'{e:.1e}' for e in rel)}; peak V {V.max():.3g} (Radau {row['peak_V_ref']:.3g}) m/s",
                  flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
