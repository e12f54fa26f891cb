"""seismicity.png of a rate-and-state run (issue 28): slip rate, event sizes and McGarr's bound.

Three panels from the run's seismicity series and event catalogue
(:class:`polypore.runs.seismicity.EventCatalogue`):

1. the peak slip rate of each fault against time (log scale), the seismic threshold dashed, the
   events shaded;
2. the events' size against their onset: M_w in 3D, M₀ per metre of strike in 2D (no magnitude);
3. the cumulative seismic and aseismic moments and each event's M₀ against the injected volume
   ΔV, with McGarr's (2014) bound M₀,max = μ_s ΔV (μ_s the largest shear modulus next to a fault
   face); without injection the panel says so.
"""

from __future__ import annotations

import numpy as np

from .plots import _plt, save, time_unit

COLOURS = ("tab:red", "tab:blue", "tab:green", "tab:purple", "tab:orange", "tab:brown")


def seismicity_plot(path, case: str, series: dict, events: list, dim: int, threshold: float,
                    shear_modulus: float, t_end: float) -> dict:
    """Write seismicity.png; return what it drew: ``events``, ``largest_moment`` (N·m, per metre
    in 2D), ``injected_volume`` (the final ΔV) and ``mcgarr_bound`` (μ_s ΔV, None without
    injection).

    series : :meth:`EventCatalogue.series`;  events : the catalogue's rows;  threshold : m/s;
    shear_modulus : μ_s of the bound, Pa;  t_end : the run's end (s), for the time unit.
    """
    plt = _plt()
    tf, tu = time_unit(t_end)
    t = series["time"] / tf
    fig, (a_v, a_m, a_g) = plt.subplots(1, 3, figsize=(16.5, 4.6), layout="constrained")
    for k, (name, v) in enumerate(series["peak_slip_rate"].items()):
        a_v.semilogy(t, np.maximum(v, 1e-300), color=COLOURS[k % len(COLOURS)], lw=1.0, label=name)
    a_v.axhline(threshold, color="k", ls="--", lw=0.8, label=f"seismic threshold {threshold:g} m/s")
    for e in events:
        a_v.axvspan(e["onset_s"] / tf, e["end_s"] / tf, color="0.85", lw=0, zorder=0)
    positive = [float(v[v > 0].min()) for v in series["peak_slip_rate"].values() if np.any(v > 0)]
    if positive:            # faces at rest (V = 0 exactly) would stretch the axis to 1e-300
        a_v.set_ylim(bottom=max(min(positive) / 3, 1e-20))
    a_v.set_xlabel(f"t ({tu})")
    a_v.set_ylabel("peak slip rate on the fault (m/s)")
    a_v.set_title("slip rate (events shaded)", fontsize=10)
    a_v.legend(fontsize=8, loc="best")

    per_m = " per metre of strike" if dim == 2 else ""
    unit = "N·m/m" if dim == 2 else "N·m"
    names = list(series["peak_slip_rate"])
    if events:
        for k, name in enumerate(names):
            ev = [e for e in events if e["fault"] == name]
            if not ev:
                continue
            x = np.array([e["onset_s"] for e in ev]) / tf
            if dim == 3:
                y = np.array([e["magnitude_mw"] for e in ev])
                a_m.vlines(x, y.min() - 0.5, y, color=COLOURS[k % len(COLOURS)], lw=0.8)
                a_m.plot(x, y, "o", ms=4, color=COLOURS[k % len(COLOURS)], label=name)
            else:
                y = np.array([e["moment"] for e in ev])
                a_m.semilogy(x, y, "o", ms=4, color=COLOURS[k % len(COLOURS)], label=name)
        a_m.legend(fontsize=8, loc="best")
    else:
        a_m.text(0.5, 0.5, f"no event: no face slid faster than {threshold:g} m/s", ha="center", va="center",
                 transform=a_m.transAxes, fontsize=9)
    a_m.set_xlim(0, t_end / tf)
    a_m.set_xlabel(f"onset ({tu})")
    a_m.set_ylabel("moment magnitude M_w" if dim == 3 else f"seismic moment M₀ ({unit})")
    a_m.set_title(f"events ({len(events)})" + ("" if dim == 3 else ": M₀ per metre (no M_w in 2D)"), fontsize=10)

    dv = series["injected_volume"]
    vmax = float(dv.max()) if dv.size else 0.0
    bound = None
    if vmax > 0:
        pos = dv > 0
        a_g.loglog(dv[pos], np.maximum(series["seismic_moment"][pos], 1e-300), color="tab:red", lw=1.2,
                   label="seismic moment, cumulative")
        a_g.loglog(dv[pos], np.maximum(series["aseismic_moment"][pos], 1e-300), color="tab:blue", lw=1.0, ls="--",
                   label="aseismic moment, cumulative")
        vv = np.geomspace(dv[pos].min(), vmax, 50)
        a_g.loglog(vv, shear_modulus * vv, color="k", lw=1.0,
                   label=f"McGarr bound μ_s ΔV (μ_s = {shear_modulus:.3g} Pa)")
        ev = [e for e in events if e["injected_volume"] > 0]
        if ev:
            a_g.loglog([e["injected_volume"] for e in ev], [e["moment"] for e in ev], "o", ms=4, color="tab:red",
                       label="events (at their end)")
        bound = shear_modulus * vmax
        finals = [float(series[k][-1]) for k in ("seismic_moment", "aseismic_moment") if series[k][-1] > 0]
        top = max([bound, *finals])
        # down to the smaller final moment: an aseismic moment 12 decades under the bound still shows
        a_g.set_ylim(max(min([top * 1e-8, *finals]) / 10, top * 1e-20), top * 3)
        a_g.legend(fontsize=8, loc="best")
    else:
        a_g.text(0.5, 0.5, "no fluid injected (sources and rate boundaries): no McGarr bound", ha="center",
                 va="center", transform=a_g.transAxes, fontsize=9)
    vol = "m³" if dim == 3 else "m² per metre"
    a_g.set_xlabel(f"injected volume ΔV ({vol})")
    a_g.set_ylabel(f"moment ({unit})")
    a_g.set_title("moment against injected volume", fontsize=10)
    fig.suptitle(f"{case}: seismicity (slip rate, events{per_m}, McGarr's bound)", fontsize=11)
    save(fig, path)
    big = max((e["moment"] for e in events), default=None)
    return {"events": len(events), "largest_moment": big, "injected_volume": vmax, "mcgarr_bound": bound}
