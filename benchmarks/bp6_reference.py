"""BP6-QD-A/S/C reference (issue 28; src/polypore/cases/bp6.py, docs/bp6.md).

Runs the three variants on four grids, prints station values and the slip front, checks the
QD-C solver against the crack with bounded stress, the time step (QD-C) and the tolerance
(QD-A/S), the no-slip ends of the fault and a clamped outer boundary (the finite-domain study for
polypore), and writes a JSON and a PNG. One core (BLAS limited to one thread):

    .venv/bin/python benchmarks/bp6_reference.py --json docs/bp6_reference.json

``--quick``: coarse grids only (a smoke run, about 30 s). ``--cyclaps DIR``: compare QD-A with
the CYCLAPS station files fltst_strk+00/+05 (SCEC server, P. Dublanchet's upload) found in DIR.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "src"))

from polypore.cases import bp6  # noqa: E402

DAY = bp6.DAY
TABLE_DAYS = (10, 30, 100, 200, 365, 730)
TABLE_STATIONS = (0.0, 500.0, 1500.0, 2500.0, 5000.0, 7500.0)
CONV_DAYS = (30, 100, 200, 730)
CONV_STATIONS = (0.0, 500.0, 1500.0, 2500.0, 5000.0)
FRONT_DAYS = (30, 100, 365, 730)


def at(res, days):
    """Row index of the output time closest to ``days``."""
    return int(np.argmin(np.abs(res.t - days * DAY)))


def col(res, z):
    return list(res.stations).index(z)


def front_of(res):
    """The front used for the comparisons: the slipped region's edge for QD-C, V ≥ 1e-9 m/s else."""
    return res.front_tip if res.front_tip is not None else res.front_rate


def run_variant(prm, variant, dz, **kw):
    if variant == "QD-C":
        return bp6.run_constant_friction(prm, dz=dz, **kw)
    return bp6.run_rate_state(prm, law="aging" if variant == "QD-A" else "slip", dz=dz, **kw)


def station_table(res):
    rows = []
    for d in TABLE_DAYS:
        i = at(res, d)
        rows.append(dict(
            day=d, slip_m=[float(res.slip[i, col(res, z)]) for z in TABLE_STATIONS],
            log10_V=[float(np.log10(res.slip_rate[i, col(res, z)])) if res.slip_rate[i, col(res, z)] > 0 else None
                     for z in TABLE_STATIONS],
            shear_MPa_z0=float(res.shear_stress[i, col(res, 0.0)] / 1e6),
            pressure_MPa_z0=float(res.pore_pressure[i, col(res, 0.0)] / 1e6),
            front_m=float(front_of(res)[i]), front_slip_1mm_m=float(res.front_slip[i])))
    return rows


def print_table(variant, res):
    print(f"\n{variant}, h = {res.h:.3f} m ({res.stats['n_cells']} cells, {res.stats['wall_s']:.1f} s)")
    print("  day " + "".join(f"  δ({z / 1e3:g} km)" for z in TABLE_STATIONS)
          + "  log10V(0)  τ(0) MPa  p(0) MPa  front m")
    for r in station_table(res):
        lv = f"{r['log10_V'][0]:9.4f}" if r["log10_V"][0] is not None else "   locked"
        print(f"{r['day']:5d} " + "".join(f"{v:11.5f}" for v in r["slip_m"])
              + f"  {lv}  {r['shear_MPa_z0']:8.4f}  {r['pressure_MPa_z0']:8.4f}  {r['front_m']:7.1f}")


def convergence(results):
    """Slip at CONV_STATIONS × CONV_DAYS and the front at FRONT_DAYS on each grid against the finest:
    max |Δslip| / max slip, max |Δfront| (m), observed orders, Richardson estimate of the finest's error."""
    def slips(r):
        return np.array([[r.slip[at(r, d), col(r, z)] for z in CONV_STATIONS] for d in CONV_DAYS])

    def fronts(r):
        return np.array([front_of(r)[at(r, d)] for d in FRONT_DAYS])

    S = [slips(r) for r in results]
    F = [fronts(r) for r in results]
    scale = np.abs(S[-1]).max()
    e_slip = [float(np.abs(s - S[-1]).max() / scale) for s in S[:-1]]
    e_front = [float(np.abs(f - F[-1]).max()) for f in F[:-1]]
    # successive differences (no reference needed): d_k = max|Q_k − Q_{k+1}|
    d_slip = [float(np.abs(S[k] - S[k + 1]).max() / scale) for k in range(len(S) - 1)]
    d_front = [float(np.abs(F[k] - F[k + 1]).max()) for k in range(len(F) - 1)]
    order_slip = [float(np.log2(d_slip[k] / d_slip[k + 1])) for k in range(len(d_slip) - 1)]
    order_front = [float(np.log2(d_front[k] / d_front[k + 1])) if d_front[k + 1] > 0 else None
                   for k in range(len(d_front) - 1)]
    p = max(order_slip[-1], 0.5)
    return dict(h=[r.h for r in results], slip_scale_m=float(scale), slip_error_vs_finest=e_slip,
                front_error_vs_finest_m=e_front, successive_slip_differences=d_slip,
                successive_front_differences_m=d_front, observed_order_slip=order_slip,
                observed_order_front=order_front,
                richardson_slip_error_finest=float(d_slip[-1] / (2 ** p - 1)),
                slip_z0=[[float(r.slip[at(r, d), col(r, 0.0)]) for d in CONV_DAYS] for r in results],
                front=[[float(front_of(r)[at(r, d)]) for d in FRONT_DAYS] for r in results],
                days=list(CONV_DAYS), front_days=list(FRONT_DAYS), stations_m=list(CONV_STATIONS))


def qdc_semi_analytic(results, prm):
    out = []
    for d in (10, 30, 60, 100):
        t = d * DAY
        a = bp6.constant_friction_crack(t, prm)
        ref = bp6.constant_friction_slip([0.0, 500.0, 1500.0], t, prm)
        row = dict(day=d, a_m=float(a), slip_m=ref.tolist(), grids=[])
        for r in results:
            i = at(r, d)
            num = np.array([r.slip[i, col(r, z)] for z in (0.0, 500.0, 1500.0)])
            row["grids"].append(dict(h=r.h, tip_m=float(r.front_tip[i]), tip_error_m=float(r.front_tip[i] - a),
                                     slip_rel_error=float(np.abs(num - ref).max() / ref[0])))
        out.append(row)
    return out


def compare(a, b, stations=(0.0, 500.0, 1500.0, 2500.0)):
    """max over CONV_DAYS of |Δslip|/max slip, |Δlog10 V|, |Δτ| (Pa), |Δfront| (m) between runs."""
    ds, dv, dt_, df = 0.0, 0.0, 0.0, 0.0
    scale = np.abs(b.slip).max()
    for d in CONV_DAYS:
        i, j = at(a, d), at(b, d)
        for z in stations:
            ds = max(ds, abs(a.slip[i, col(a, z)] - b.slip[j, col(b, z)]) / scale)
            va, vb = a.slip_rate[i, col(a, z)], b.slip_rate[j, col(b, z)]
            if va > 1e-14 and vb > 1e-14:
                dv = max(dv, abs(np.log10(va) - np.log10(vb)))
            dt_ = max(dt_, abs(a.shear_stress[i, col(a, z)] - b.shear_stress[j, col(b, z)]))
        df = max(df, abs(front_of(a)[i] - front_of(b)[j]))
    return dict(slip_rel=float(ds), log10_V=float(dv), shear_Pa=float(dt_), front_m=float(df))


def cyclaps_comparison(res, directory):
    out = {}
    for tag, z in (("00", 0.0), ("05", 500.0)):
        files = glob.glob(os.path.join(directory, f"*strk*{tag}*"))
        if not files:
            continue
        data = np.loadtxt(files[0], comments=("#", "t "))
        rows = []
        for d in TABLE_DAYS:
            t = d * DAY
            i = at(res, d)
            c = col(res, z)
            slip_c = np.interp(t, data[:, 0], data[:, 1])
            rows.append(dict(day=d, slip_ref=float(res.slip[i, c]), slip_cyclaps=float(slip_c),
                             log10V_ref=float(np.log10(res.slip_rate[i, c])),
                             log10V_cyclaps=float(np.interp(t, data[:, 0], data[:, 2])),
                             shear_MPa_ref=float(res.shear_stress[i, c] / 1e6),
                             shear_MPa_cyclaps=float(np.interp(t, data[:, 0], data[:, 3])),
                             p_MPa_ref=float(res.pore_pressure[i, c] / 1e6),
                             p_MPa_cyclaps=float(np.interp(t, data[:, 0], data[:, 4]))))
        out[f"z={z:g} m"] = dict(file=os.path.basename(files[0]), rows=rows)
    return out


def plot(refs, conv, semi, prm, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(3, 3, figsize=(16, 12.5), constrained_layout=True)
    zs = (0.0, 500.0, 1000.0, 1500.0, 2500.0, 3500.0, 5000.0, 7500.0)
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(zs)))
    for j, v in enumerate(bp6.VARIANTS):
        r = refs[v]
        td = r.t / DAY
        for z, c in zip(zs, colors, strict=True):
            ax[0, j].plot(td, r.slip[:, col(r, z)] * 1e3, color=c, label=f"z = {z / 1e3:g} km")
            V = r.slip_rate[:, col(r, z)]
            m = V > 0
            ax[1, j].semilogy(td[m], V[m], color=c)
        ax[0, j].set_title(f"BP6-{v}  (h = {r.h:.2f} m)")
        ax[0, j].set_ylabel("slip (mm)")
        ax[1, j].set_ylabel("slip rate (m/s)")
        ax[1, j].set_ylim(1e-13, 1e-6)
        for i in (0, 1):
            ax[i, j].set_xlabel("time (days)")
            ax[i, j].axvline(prm.t_off / DAY, color="0.6", lw=0.8, ls=":")
            ax[i, j].grid(alpha=0.3)
    ax[0, 0].legend(fontsize=8, ncol=2)
    styles = {"QD-A": "C0", "QD-S": "C1", "QD-C": "C2"}
    for v in bp6.VARIANTS:
        r = refs[v]
        lab = f"{v}: V ≥ 1e-9 m/s" if v != "QD-C" else "QD-C: slipped region (δ > 0)"
        ax[2, 0].plot(r.t / DAY, front_of(r) / 1e3, color=styles[v], label=lab)
        ax[2, 0].plot(r.t / DAY, r.front_slip / 1e3, color=styles[v], ls="--", lw=0.9,
                      label=f"{v}: δ ≥ 1 mm")
    ts = np.linspace(1, prm.t_off / DAY, 60)
    ax[2, 0].plot(ts, [bp6.constant_friction_crack(t * DAY, prm) / 1e3 for t in ts], "k:", lw=2,
                  label="QD-C crack, η → 0 (semi-analytical)")
    ax[2, 0].set_xlabel("time (days)")
    ax[2, 0].set_ylabel("slip front z (km)")
    ax[2, 0].set_title("slip front")
    ax[2, 0].legend(fontsize=8)
    ax[2, 0].grid(alpha=0.3)
    r = refs["QD-A"]
    for z, c in zip(zs, colors, strict=True):
        ax[2, 1].plot(r.t / DAY, r.pore_pressure[:, col(r, z)] / 1e6, color=c, label=f"z = {z / 1e3:g} km")
    ax[2, 1].set_xlabel("time (days)")
    ax[2, 1].set_ylabel("pore-pressure change p (MPa)")
    ax[2, 1].set_title("pore pressure, eq. (26) (all variants)")
    ax[2, 1].grid(alpha=0.3)
    ax[2, 1].legend(fontsize=8)
    for v in bp6.VARIANTS:
        c = conv[v]
        h = np.array(c["h"][:-1])
        ax[2, 2].loglog(h, c["slip_error_vs_finest"], "o-", color=styles[v], label=f"{v}: slip error / max slip")
        ax[2, 2].loglog(h, np.array(c["front_error_vs_finest_m"]) / 1e4, "s--", color=styles[v],
                        label=f"{v}: front error (m) / 10 km")
    hh = np.array([5.0, 40.0])
    ax[2, 2].loglog(hh, 2e-5 * (hh / 5) ** 2, "k:", label="∝ h²")
    ax[2, 2].loglog(hh, 2e-4 * (hh / 5), "k-.", lw=0.8, label="∝ h")
    ax[2, 2].set_xlabel("cell size h (m)")
    ax[2, 2].set_ylabel("max difference to the finest grid")
    ax[2, 2].set_title("grid convergence (stations 0–5 km, 30–730 days)")
    ax[2, 2].legend(fontsize=7)
    ax[2, 2].grid(alpha=0.3, which="both")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", default="docs/bp6_reference.json")
    ap.add_argument("--png", default="docs/bp6_reference.png")
    ap.add_argument("--grids", default="40,20,10,5", help="cell sizes (m), coarse to fine")
    ap.add_argument("--quick", action="store_true", help="grids 80,40,20 and fewer checks")
    ap.add_argument("--cyclaps", default=None, help="directory with CYCLAPS fltst_strk files")
    args = ap.parse_args(argv)
    grids = [80.0, 40.0, 20.0] if args.quick else [float(g) for g in args.grids.split(",")]
    prm = bp6.Bp6Parameters()
    t_start = time.perf_counter()
    runs, refs, conv, timing = {}, {}, {}, {}
    with threadpool_limits(1):
        for v in bp6.VARIANTS:
            runs[v] = []
            for dz in grids:
                t0 = time.perf_counter()
                runs[v].append(run_variant(prm, v, dz))
                timing[f"{v} h={dz:g}"] = time.perf_counter() - t0
                print(f"{v} dz = {dz:g} m: {timing[f'{v} h={dz:g}']:.1f} s", flush=True)
            refs[v] = runs[v][-1]
            conv[v] = convergence(runs[v])
            print_table(v, refs[v])

        checks = {}
        checks["qdc_semi_analytic"] = qdc_semi_analytic(runs["QD-C"], prm)
        mid = grids[-3] if len(grids) > 2 else grids[0]        # the checks' grid (20 m by default)
        # QD-C time step: the reference's dt_max = 6 h against 1 day and 1.5 h
        c_ref = runs["QD-C"][grids.index(mid)]
        checks["qdc_time_step"] = {
            f"dt_max={d:g} day": compare(bp6.run_constant_friction(prm, dz=mid, dt_max=d * DAY), c_ref)
            for d in ((1.0,) if args.quick else (1.0, 1 / 16))}
        # QD-A/S tolerance: rtol 1e-8 (reference) against 1e-10
        checks["rate_state_tolerance"] = {v: compare(run_variant(prm, v, mid, rtol=1e-10), runs[v][grids.index(mid)])
                                          for v in ("QD-A", "QD-S")}
        # the no-slip ends at ±l_f: slip stopped at ±10 km instead of ±20 km (flow unchanged)
        checks["no_slip_ends_10km_vs_20km"] = {v: compare(run_variant(prm, v, mid, half_length=10e3),
                                                          runs[v][grids.index(mid)]) for v in ("QD-A", "QD-S")}
        # finite domain: the fault in a clamped circle of radius R (antiplane images)
        coarse = grids[0]                                        # the domain study's grid (40 m)
        domain = {"QD-C": {}, "QD-A": {}, "QD-S": {}}
        c_free = bp6.run_constant_friction(prm, dz=coarse, dt_max=DAY)
        for R in ((20e3, 40e3, 80e3) if args.quick else (10e3, 20e3, 40e3, 80e3, 160e3)):
            rc = bp6.run_constant_friction(prm, dz=coarse, dt_max=DAY, R_clamp=R, half_length=min(12e3, 0.9 * R))
            domain["QD-C"][f"R={R / 1e3:g} km"] = compare(rc, c_free)
        for v in ("QD-A", "QD-S"):
            free = runs[v][grids.index(coarse)]
            for R in ((40e3,) if args.quick else (40e3, 80e3, 160e3)):
                domain[v][f"R={R / 1e3:g} km"] = compare(run_variant(prm, v, coarse, R_clamp=R), free)
        checks["clamped_circle"] = dict(h=coarse, runs=domain)
        # symmetry of the rate-and-state runs (QD-C is solved on z ≥ 0)
        checks["symmetry_pm1.5km"] = {v: float(np.abs(refs[v].slip[:, col(refs[v], -1500.0)]
                                                      - refs[v].slip[:, col(refs[v], 1500.0)]).max())
                                      for v in ("QD-A", "QD-S")}
        if args.cyclaps:
            checks["cyclaps_QD-A"] = cyclaps_comparison(refs["QD-A"], args.cyclaps)
    total = time.perf_counter() - t_start

    sig_min = prm.sigma0 - float(bp6.pore_pressure(0.0, prm.t_off, prm))
    lengths = {f"L_{c} = mu Dc/({c} sigma') at sigma0, sigma0 - p_max (m)":
               [prm.mu * prm.Dc / (getattr(prm, c) * s) for s in (prm.sigma0, sig_min)] for c in ("b", "a")}
    print("\nconvergence (max |Δslip|/max slip against the finest grid; front in m):")
    for v in bp6.VARIANTS:
        c = conv[v]
        print(f"  {v}: h = {[round(x, 2) for x in c['h']]}, "
              f"slip {['%.2e' % e for e in c['slip_error_vs_finest']]}, "
              f"front {['%.1f' % e for e in c['front_error_vs_finest_m']]} m, "
              f"orders {['%.2f' % o for o in c['observed_order_slip']]}")
    print("QD-C against the crack with bounded stress:")
    for row in checks["qdc_semi_analytic"]:
        g = row["grids"][-1]
        print(f"  day {row['day']:3d}: a = {row['a_m']:8.2f} m, finest tip error {g['tip_error_m']:+.2f} m, "
              f"slip error {g['slip_rel_error']:.1e}")
    for k in ("qdc_time_step", "rate_state_tolerance", "no_slip_ends_10km_vs_20km", "clamped_circle"):
        print(f"{k}: {json.dumps(checks[k])}")
    print(f"process-zone lengths: {lengths}")
    print(f"total {total:.0f} s")

    out = dict(
        source=("SEAS BP6-QD-A/S/C description (V. Lambert and E. M. Dunham, 8 Nov 2021), "
                "https://strike.scec.org/cvws/seas/benchmark_descriptions.html; docs/bp6.md"),
        parameters={**{k: getattr(prm, k) for k in prm.__dataclass_fields__}, "alpha": prm.alpha, "eta": prm.eta,
                    "theta0": prm.theta0, "tau0_rate_state": prm.tau0("QD-A"), "tau0_constant": prm.tau0("QD-C")},
        units="SI: m, s, Pa, m/s; state log10(theta/s)", grids=grids, timing_s=timing, total_s=total,
        process_zone=lengths, station_tables={v: station_table(refs[v]) for v in bp6.VARIANTS},
        convergence=conv, checks=checks, reference={v: refs[v].to_dict(digits=6) for v in bp6.VARIANTS})
    os.makedirs(os.path.dirname(args.json) or ".", exist_ok=True)
    with open(args.json, "w") as fh:
        json.dump(out, fh, separators=(",", ":"))
    plot(refs, conv, checks["qdc_semi_analytic"], prm, args.png)
    print(f"wrote {args.json}, {args.png}")


if __name__ == "__main__":
    main()
