"""Monitor plots of 3D poromechanics runs: where and when the faults reactivate.

``polypore run`` writes these into the run folder of every 3D poromechanics case (the data are
prepared in :mod:`polypore.io.monitor3d`; each figure is written atomically, after the time
loop, and a figure that fails is skipped with a warning, never failing the run):

- ``slip_onset.png``: per fault, the percentage of its area that slips and that is open, and its
  largest slip since the start, against time; the first slipping face of each fault marked;
- ``fault_maps.png``: each fault's faces in its own plane (along strike against elevation, or up
  dip for gently dipping faults), coloured by the contact state and the slip since the start at
  the final time, and by the time each face first slipped (grey: never);
- ``fault_stress.png``: each fault in its plane at the final time, coloured by the Coulomb failure
  stress change ΔCFS since the start and by the slip tendency τ/σ_n′ (runs since issue 28);
- ``pressure.png``: overpressure p − p⁰ against time at the wells' cells (mean and largest),
  at the monitor points, on each fault and the largest in the domain, with the peak marked;
- ``pressure_map.png``: the overpressure at the final time in map view (largest over depth)
  and in a vertical section through the well (or the peak), with the faults drawn in.

Replot a finished run's folder (this version's or an older run's)::

    polypore plot RUN_DIR [--out DIR]
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from .monitor3d import (AREA_ONSET, PlotData, column_max_map, interest_box, outline_segments, project_faces,
                        section_traces, vertical_exaggeration, vertical_section)
from .plots import STATE_COLOURS, _plt, format_time, save, time_unit, value_unit

log = logging.getLogger("polypore")

FIGURES = ("slip_onset.png", "fault_maps.png", "fault_stress.png", "pressure.png", "pressure_map.png")
STATE_ORDER = ("open", "stick", "slip")
# slip below this (m) is round-off on any fault of these runs: not given a colour scale of its own
SLIP_FLOOR = 1e-9
NEVER = "0.82"                     # colour of faces that never slipped


def write_3d_plots(folder, d: PlotData, drawn: dict | None = None) -> list[Path]:
    """Write the figures of a 3D run into ``folder``; return the files written. A figure that
    fails is logged as a warning and skipped (the others are still written).

    drawn : dict, optional
        Filled with figure name -> what the figure drew, for the fault figures (see
        :func:`fault_maps_plot`, :func:`slip_onset_plot`): to be compared with summary.json.
    """
    folder = Path(folder)
    todo = [("pressure.png", pressure_plot), ("pressure_map.png", pressure_map_plot)]
    if d.fracture.size:
        todo = [("slip_onset.png", slip_onset_plot), ("fault_maps.png", fault_maps_plot)] + todo
        if d.delta_cfs is not None:
            todo.insert(2, ("fault_stress.png", fault_stress_plot))
    done = []
    for name, fn in todo:
        try:
            what = fn(folder / name, d)
            if drawn is not None and what is not None:
                drawn[name] = what
            done.append(folder / name)
        except Exception as exc:       # a figure must never fail the run
            log.warning("plot %s not written: %s: %s", name, type(exc).__name__, exc)
    return done


def _fault_colour(i: int) -> str:
    return f"C{i % 10}"


def _when(t, d: PlotData) -> str:
    return "never" if t is None else format_time(t, d.t_end)


# --------------------------------------------------------------------------- (a) slip onset

def slip_onset_plot(path, d: PlotData) -> dict:
    """Slipping and open area (% of each fault) and the largest slip against time.

    Returns fault -> {"slip_area_fraction", "open_area_fraction": (n_t,) the curves drawn (as
    fractions), "first_slip": s or None}: summary.json's series, drawn as they are."""
    plt = _plt()
    tf, tu = time_unit(d.t_end)
    t = d.fault_times / tf
    first, by_area = d.first_slip(), d.area_onset()
    smax = max((float(np.max(v)) for v in d.max_slip.values() if len(v)), default=0.0)
    fs, us = value_unit("m", smax)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.9), layout="constrained")
    out = {}
    for i, n in enumerate(d.names):
        c = _fault_colour(i)
        if first[n] is None:
            lab = f"{n}: no face slips"
        else:
            lab = f"{n}: first slip at {_when(first[n], d)}"
            lab += (f"; {100 * AREA_ONSET:g}% of its area at {_when(by_area[n], d)}" if by_area[n] is not None
                    else f"; never {100 * AREA_ONSET:g}% of its area")
        ls = axes[0].plot(t, 100 * d.slip_fraction[n], "o-", ms=3, color=c, label=lab)[0]
        lo = axes[1].plot(t, 100 * d.open_fraction[n], "o-", ms=3, color=c)[0]
        out[n] = {"slip_area_fraction": np.asarray(ls.get_ydata(), float) / 100,
                  "open_area_fraction": np.asarray(lo.get_ydata(), float) / 100, "first_slip": first[n]}
        if n in d.max_slip and len(d.max_slip[n]) == len(t):
            axes[2].plot(t, d.max_slip[n] / fs, "o-", ms=3, color=c)
        if first[n] is not None:
            for a in axes:
                a.axvline(first[n] / tf, color=c, ls=":", lw=1.2)
    for a, what in zip(axes, ("slipping area (% of the fault)", "open area (% of the fault)",
                              f"largest slip since t = 0 ({us})")):
        a.set_xlabel(f"t ({tu})")
        a.set_ylabel(what)
        a.grid(alpha=0.3)
        lo, hi = a.get_ylim()
        a.set_ylim(0.0, max(hi, 1.0 if "%" in what else 1e-12))
    axes[0].set_title("slipping area", fontsize=10)
    axes[1].set_title("open area", fontsize=10)
    axes[2].set_title("largest slip on the fault", fontsize=10)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=min(len(d.names), 2),
               fontsize=9, frameon=False)
    fig.suptitle(f"{d.case}: fault reactivation against time (dotted: first slipping face of each fault)",
                 fontsize=11)
    save(fig, path)
    return out


# --------------------------------------------------------------------------- (b) fault maps

def fault_panels(d: PlotData) -> list[dict]:
    """Per fault with faces: name, colour, frame, polygons (drawing coordinates), face indices,
    vertical exaggeration and the projected well positions."""
    out = []
    frames = d.frames()
    for i, n in enumerate(d.names):
        if n not in frames:
            continue
        fr = frames[n]
        faces = np.flatnonzero(d.fracture == i)
        polys = project_faces(fr, *d.polygons, faces)
        allp = np.concatenate(polys)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        k = vertical_exaggeration(hi[0] - lo[0], hi[1] - lo[1])
        wells = {w: fr.coords(x.mean(axis=0, keepdims=True))[0] for w, x in d.well_cells_xyz.items()}
        out.append({"name": n, "colour": _fault_colour(i), "frame": fr, "faces": faces, "polys": polys,
                    "lo": lo, "hi": hi, "k": k, "wells": wells})
    return out


def fault_maps_plot(path, d: PlotData) -> dict:
    """Each fault in its plane: contact state, slip since the start at the final time, onset time.

    The faces are coloured by ``d.state`` and ``d.onset`` (in a run: the recorder's arrays behind
    summary.json's series) and the titles quote the series at t_final; a map whose faces
    disagree with the series is drawn but logged as a warning.

    Returns fault -> what its row draws, read back from the drawn collections: ``faces``,
    ``open`` / ``stick`` / ``slip`` (faces of each colour), ``slip_area_fraction`` (area of the
    faces coloured slip / the fault's area), ``ever_slipped`` (faces with an onset colour),
    ``title_slip_area_fraction`` (the percentage of the title, as a fraction), ``first_slip``
    (the earliest onset drawn, s, or None) and ``time`` (s).
    """
    plt = _plt()
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.patches import Patch

    panels = fault_panels(d)
    if not panels:
        return {}
    series = d.series_at_final()
    out = {}
    tf, tu = time_unit(d.t_end)
    smax = float(np.max(d.slip)) if d.slip.size else 0.0
    fs, us = value_unit("m", max(smax, SLIP_FLOOR))
    vmax = max(smax, SLIP_FLOOR) / fs
    aspect = [float(np.clip((p["hi"][1] - p["lo"][1]) * p["k"] / max(p["hi"][0] - p["lo"][0], 1e-300), 0.2, 1.1))
              for p in panels]
    w = 5.0 if len(panels) <= 2 else 4.0                   # inches per panel
    fig, axes = plt.subplots(len(panels), 3, squeeze=False, layout="constrained",
                             figsize=(3 * w + 3.0, sum(w * a + 1.1 for a in aspect) + 0.9),
                             gridspec_kw={"height_ratios": [w * a + 1.1 for a in aspect]})
    onset_cmap = plt.get_cmap("viridis_r").with_extremes(bad=NEVER)
    state_cmap = ListedColormap([STATE_COLOURS[s] for s in STATE_ORDER])
    state_norm = BoundaryNorm([-0.5, 0.5, 1.5, 2.5], 3)
    when = format_time(d.t_final, d.t_end)
    onset_range = onset_limits(d.onset, d.t_end) / tf
    for r, p in enumerate(panels):
        f = p["faces"]
        a_state, a_slip, a_on = axes[r]
        ps = PolyCollection(p["polys"], array=np.asarray(d.state[f], float), cmap=state_cmap, norm=state_norm,
                            edgecolors="0.25", linewidths=0.15)
        a_state.add_collection(ps)
        cb = fig.colorbar(ps, ax=a_state, ticks=[0, 1, 2], shrink=0.9)
        cb.ax.set_yticklabels(STATE_ORDER, fontsize=8)
        pc = PolyCollection(p["polys"], array=d.slip[f] / fs, cmap="magma_r", edgecolors="0.5", linewidths=0.1)
        # each fault on its own scale (its own colour bar): on a scale shared with a fault that slips
        # 20× more, 3 mm of slip showed as blank faces
        # a fault that only moved by round-off (1e-14 mm next to a slipping one) takes the shared
        # scale and shows blank, not its round-off stretched over the whole colour bar
        fmax = float(d.slip[f].max()) if f.size else 0.0
        top = fmax / fs if fmax > max(SLIP_FLOOR, 1e-6 * smax) else vmax
        pc.set_clim(0.0, top)
        a_slip.add_collection(pc)
        fig.colorbar(pc, ax=a_slip, label=f"slip ({us})", shrink=0.9)
        on = np.ma.masked_invalid(d.onset[f] / tf)
        po = PolyCollection(p["polys"], array=on, cmap=onset_cmap, edgecolors="0.5", linewidths=0.1)
        po.set_clim(*onset_range)
        a_on.add_collection(po)
        fig.colorbar(po, ax=a_on, label=f"first slip ({tu})", shrink=0.9)
        # what the faces show, read back from the collections (the data the figure holds)
        shown = np.asarray(ps.get_array(), float)
        never = np.ma.getmaskarray(po.get_array())
        area = d.area[f]
        drawn_frac = float(area[shown == 2].sum() / max(area.sum(), 1e-300))
        frac = drawn_frac if series[p["name"]] is None else series[p["name"]][0]
        if abs(frac - drawn_frac) > 1e-9:
            log.warning("fault_maps.png: the faces of %s coloured slip cover %.3g%% of its area, the series of "
                        "summary.json %.3g%% at t = %g s", p["name"], 100 * drawn_frac, 100 * frac, d.t_final)
        out[p["name"]] = {"time": d.t_final, "faces": int(f.size),
                          **{s_: int(np.sum(shown == k)) for k, s_ in enumerate(STATE_ORDER)},
                          "slip_area_fraction": drawn_frac, "ever_slipped": int(np.sum(~never)),
                          "title_slip_area_fraction": frac, "slip_colour_max_m": top * fs}
        first = float(np.nanmin(d.onset[f])) if np.isfinite(d.onset[f]).any() else None
        out[p["name"]]["first_slip"] = first
        a_state.set_title(f"{p['name']} (dip {p['frame'].dip:.0f}°): state, {percent(frac)}% of the area slips "
                          f"({out[p['name']]['slip']} of {f.size} faces)", fontsize=9)
        a_slip.set_title(f"{p['name']}: slip since t = 0, largest {d.slip[f].max() / fs:.3g} {us}", fontsize=9)
        a_on.set_title(f"{p['name']}: time of first slip (first face: {_when(first, d)})", fontsize=9)
        for a in (a_state, a_slip, a_on):
            _frame_axes(a, p)
    handles = [Patch(facecolor=NEVER, label="never slipped")]
    if d.well_cells_xyz:
        handles.append(plt.Line2D([], [], ls="", marker="v", color="k", label="well, projected onto the plane"))
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9, frameon=False)
    fig.suptitle(f"{d.case}: the faults seen face-on at t = {when} (contact state, slip, and when each face "
                 "first slipped)", fontsize=11)
    save(fig, path)
    return out


def fault_stress_plot(path, d: PlotData) -> dict:
    """Each fault in its plane at the final time: ΔCFS since the start (diverging colours, white
    at 0, one symmetric scale per fault) and the slip tendency τ/σ_n′ (grey where open).

    Returns fault -> ``delta_cfs_min`` / ``delta_cfs_max`` (Pa) and ``slip_tendency_max`` drawn.
    """
    plt = _plt()
    from matplotlib.collections import PolyCollection

    panels = fault_panels(d)
    if not panels or d.delta_cfs is None:
        return {}
    cfs = np.asarray(d.delta_cfs, float)
    ts = np.asarray(d.slip_tendency, float) if d.slip_tendency is not None else np.full(cfs.size, np.nan)
    fc, uc = value_unit("Pa", float(np.nanmax(np.abs(cfs))) if cfs.size else 0.0)
    aspect = [float(np.clip((p["hi"][1] - p["lo"][1]) * p["k"] / max(p["hi"][0] - p["lo"][0], 1e-300), 0.2, 1.1))
              for p in panels]
    w = 5.0 if len(panels) <= 2 else 4.0
    fig, axes = plt.subplots(len(panels), 2, squeeze=False, layout="constrained",
                             figsize=(2 * w + 2.5, sum(w * a + 1.1 for a in aspect) + 0.9),
                             gridspec_kw={"height_ratios": [w * a + 1.1 for a in aspect]})
    ts_top = float(np.nanmax(ts)) if np.isfinite(ts).any() else 1.0
    out = {}
    for r, p in enumerate(panels):
        f = p["faces"]
        a_c, a_t = axes[r]
        c = cfs[f] / fc
        lim = max(float(np.max(np.abs(c))) if f.size else 0.0, 1e-12)
        pc = PolyCollection(p["polys"], array=c, cmap="RdBu_r", edgecolors="0.5", linewidths=0.1)
        pc.set_clim(-lim, lim)
        a_c.add_collection(pc)
        fig.colorbar(pc, ax=a_c, label=f"ΔCFS ({uc})", shrink=0.9)
        pt = PolyCollection(p["polys"], array=np.ma.masked_invalid(ts[f]),
                            cmap=plt.get_cmap("viridis").with_extremes(bad=NEVER), edgecolors="0.5", linewidths=0.1)
        pt.set_clim(0.0, ts_top)
        a_t.add_collection(pt)
        fig.colorbar(pt, ax=a_t, label="slip tendency τ/σ_n′ (–)", shrink=0.9)
        a_c.set_title(f"{p['name']}: ΔCFS = Δτ − μ Δσ_n′ since t = 0, {c.min():.3g} to {c.max():.3g} {uc}",
                      fontsize=9)
        a_t.set_title(f"{p['name']}: slip tendency, largest {np.nanmax(ts[f]) if np.isfinite(ts[f]).any() else 0:.3g}",
                      fontsize=9)
        for a in (a_c, a_t):
            _frame_axes(a, p)
        out[p["name"]] = {"delta_cfs_min": float(cfs[f].min()), "delta_cfs_max": float(cfs[f].max()),
                          "slip_tendency_max": float(np.nanmax(ts[f])) if np.isfinite(ts[f]).any() else None}
    from matplotlib.patches import Patch

    fig.legend(handles=[Patch(facecolor=NEVER, label="open (no slip tendency)")], loc="outside lower center",
               fontsize=9, frameon=False)
    fig.suptitle(f"{d.case}: Coulomb failure stress change (> 0: towards failure) and slip tendency at "
                 f"t = {format_time(d.t_final, d.t_end)}", fontsize=11)
    save(fig, path)
    return out


def percent(fraction: float) -> str:
    """A fraction as a percentage for a title: one decimal, two significant digits below 0.1%
    (a few thin slipping faces must not read as 0.0%)."""
    v = 100 * float(fraction)
    return "0" if v == 0 else f"{v:.2g}" if v < 0.1 else f"{v:.1f}"


def onset_limits(onset, t_end) -> np.ndarray:
    """Colour range (s) of onset times: from the earliest onset (0 without any) to the end of
    the run, so that faults reactivating late in a long run still show their sequence."""
    v = np.asarray(onset, float)
    v = v[np.isfinite(v)]
    lo = float(v.min()) if v.size else 0.0
    return np.array([lo if lo < t_end else 0.0, float(t_end)])


def _frame_axes(ax, p) -> None:
    lo, hi = p["lo"], p["hi"]
    pad = 0.03 * (hi - lo) + 1e-9
    ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
    ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.set_aspect(p["k"])
    for w, (u, v) in p["wells"].items():
        if lo[0] - pad[0] <= u <= hi[0] + pad[0] and lo[1] - pad[1] <= v <= hi[1] + pad[1]:
            ax.plot([u], [v], "v", color="k", ms=7)
            ax.annotate(w, (u, v), xytext=(4, 4), textcoords="offset points", fontsize=8)
    stretch = "" if p["k"] == 1 else f", stretched ×{p['k']:g}"
    ax.set_xlabel(f"along strike (m), towards {_direction(p['frame'].strike)}", fontsize=8)
    ax.set_ylabel(("z (m)" if p["frame"].vertical == "z" else "up dip (m)") + stretch, fontsize=8)
    ax.tick_params(labelsize=7)


def _direction(v) -> str:
    """'+y', '−x' or '(0.87, 0.5)' for a horizontal unit vector."""
    for i, a in enumerate("xy"):
        if abs(v[i]) > 0.97:
            return f"{'+' if v[i] > 0 else '−'}{a}"
    return f"({v[0]:.2f}, {v[1]:.2f}) in (x, y)"


# --------------------------------------------------------------------------- (c) pressure history

def pressure_plot(path, d: PlotData) -> None:
    """Overpressure against time: wells (mean and largest over their cells), monitor points,
    faults (largest fracture overpressure) and the largest in the domain; peak annotated."""
    plt = _plt()
    tf, tu = time_unit(d.t_end)
    t = d.pressure_times / tf
    series = [d.max_overpressure, *d.well_mean.values(), *d.well_max.values(), *d.points.values(),
              *d.max_fracture_overpressure.values()]
    mag = max((float(np.max(np.abs(s))) for s in series if len(s)), default=0.0)
    f, u = value_unit("Pa", mag)
    fig, ax = plt.subplots(figsize=(10.5, 5.2), layout="constrained")
    ax.plot(t, d.max_overpressure / f, "k-", lw=2.2, label="largest in the domain")
    nf = len(d.names)
    for i, w in enumerate(d.well_mean):
        c = f"C{(nf + i) % 10}"
        ax.plot(t, d.well_mean[w] / f, "-", lw=1.6, color=c, label=f"well {w}: mean over its cells")
        ax.plot(t, d.well_max[w] / f, "--", lw=1.2, color=c, label=f"well {w}: largest of its cells")
    for i, (k, v) in enumerate(d.points.items()):
        ax.plot(t, np.asarray(v) / f, ":", lw=1.4, color=f"C{(nf + len(d.well_mean) + i) % 10}",
                label=f"matrix at monitor point {k}")
    first = d.first_slip() if d.fracture.size else {}
    for i, n in enumerate(d.names):
        v = d.max_fracture_overpressure.get(n)
        if v is not None and len(v) == len(t):
            ax.plot(t, np.asarray(v) / f, "-.", lw=1.3, color=_fault_colour(i),
                    label=f"fault {n}: largest p_f − p_f⁰")
        if first.get(n) is not None:
            ax.axvline(first[n] / tf, color=_fault_colour(i), lw=1.0, ls=(0, (1, 3)),
                       label=f"fault {n}: first slip ({_when(first[n], d)})")
    if len(t):
        i = int(np.argmax(d.max_overpressure))
        ax.plot([t[i]], [d.max_overpressure[i] / f], "o", color="k", ms=6)
        ax.annotate(f"peak {d.max_overpressure[i] / f:.3g} {u} at t = {format_time(d.pressure_times[i], d.t_end)}",
                    (t[i], d.max_overpressure[i] / f), xytext=(-12, -34), textcoords="offset points", ha="right",
                    fontsize=9, bbox=dict(boxstyle="round,pad=0.25", fc="white", ec="0.6"),
                    arrowprops=dict(arrowstyle="-", color="0.4", lw=0.8))
    ax.set_xlabel(f"t ({tu})")
    ax.set_ylabel(f"overpressure p − p⁰ ({u})")
    ax.grid(alpha=0.3)
    fig.legend(*ax.get_legend_handles_labels(), loc="outside right upper", fontsize=8, frameon=False)
    ax.set_title(f"{d.case}: overpressure against time", fontsize=11)
    save(fig, path)


# --------------------------------------------------------------------------- (d) pressure map

def colour_scale(values) -> tuple[str, float]:
    """(colour map, lower limit) of an overpressure field: sequential from 0 when it is (nearly)
    one-signed, as around an injection, else diverging and symmetric about 0."""
    v = np.asarray(values, float)
    top = float(np.max(np.abs(v))) if v.size else 0.0
    if v.size and float(v.min()) >= -0.05 * top:
        return "YlOrRd", 0.0
    return "RdBu_r", -top


def contour_levels(lo: float, hi: float, n: int = 6) -> np.ndarray:
    """Round contour levels strictly inside (lo, hi), zero left out."""
    from matplotlib.ticker import MaxNLocator

    if not hi > lo:
        return np.array([])
    lv = MaxNLocator(n).tick_values(lo, hi)
    return lv[(lv > lo) & (lv < hi) & (lv != 0)]


def section_choice(d: PlotData) -> tuple[int, float, np.ndarray]:
    """(axis held fixed, its value, the centre point): a vertical section through the first well
    (else the cell of largest overpressure), across the largest fault: at constant y when that
    fault's normal is closer to x, else at constant x."""
    if d.well_cells_xyz:
        centre = next(iter(d.well_cells_xyz.values())).mean(axis=0)
    else:
        centre = d.cell_centroid[int(np.argmax(d.overpressure))]
    axis = 1
    if d.fracture.size:
        big = int(np.argmax(np.bincount(d.fracture, weights=d.area)))
        frames = d.frames()
        n = frames[d.names[big]].normal if d.names[big] in frames else np.array([1.0, 0.0, 0.0])
        axis = 1 if abs(n[0]) >= abs(n[1]) else 0
    return axis, float(centre[axis]), centre


def pressure_map_plot(path, d: PlotData) -> None:
    """Overpressure at the final time: map view (largest over depth) and a vertical section."""
    plt = _plt()
    from matplotlib.collections import LineCollection

    pts, conn, off = d.polygons
    extra = [np.asarray(pts, float)] + list(d.well_cells_xyz.values())
    wlo, whi = interest_box(d.lo, d.hi, d.overpressure, np.concatenate(extra) if extra else ())
    full_lo, full_hi = d.lo[:, :2].min(axis=0), d.hi[:, :2].max(axis=0)
    zoomed = bool(np.any(whi - wlo < 0.9 * (full_hi - full_lo)))
    img, grid = column_max_map(d.lo, d.hi, d.overpressure, window=(wlo, whi))
    axis, at, centre = section_choice(d)
    h = 1 - axis
    lo = np.array([wlo[0], wlo[1], d.lo[:, 2].min()])
    hi = np.array([whi[0], whi[1], d.hi[:, 2].max()])
    inside = (d.hi[:, h] >= lo[h]) & (d.lo[:, h] <= hi[h]) & (d.lo[:, axis] <= at) & (d.hi[:, axis] >= at)
    if inside.any():
        lo[2], hi[2] = d.lo[inside, 2].min(), d.hi[inside, 2].max()
    k = vertical_exaggeration(hi[h] - lo[h], hi[2] - lo[2], max_ratio=2.5)
    sec, sgrid, _ = vertical_section(d.lo, d.hi, d.cell_centroid, d.overpressure, axis, at, aspect=k,
                                     window=(lo[h], hi[h]))
    vmax = float(np.nanmax(np.abs(d.overpressure))) if d.overpressure.size else 0.0
    vmax = vmax or 1.0
    f, u = value_unit("Pa", vmax)
    a_map = (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-300)              # height / width on screen
    a_sec = (hi[2] - lo[2]) * k / max(hi[h] - lo[h], 1e-300)
    ratio = float(np.clip(a_map / max(a_sec, 1e-300), 0.6, 2.5))      # section width / map width
    w_map = 12.0 / (1.0 + ratio)
    height = float(np.clip(max(w_map * a_map, w_map * ratio * a_sec) + 1.4, 3.8, 9.0))
    fig, (am, asec) = plt.subplots(1, 2, figsize=(14.5, height), layout="constrained",
                                   gridspec_kw={"width_ratios": [1.0, ratio]})
    cmap, lo_v = colour_scale(d.overpressure)
    kw = dict(origin="lower", cmap=cmap, vmin=lo_v / f, vmax=vmax / f, interpolation="nearest")
    im = am.imshow(img / f, extent=grid.extent, **kw)
    am.set_facecolor("0.93")
    asec.imshow(sec / f, extent=sgrid.extent, **kw)
    levels = contour_levels(lo_v / f, vmax / f, 5)
    if np.isfinite(img).sum() > 4 and len(levels):                     # labelled contours in the map
        xs, ys = grid.centres()
        cs = am.contour(xs, ys, np.ma.masked_invalid(img / f), levels=levels, colors="k", linewidths=0.6, alpha=0.7)
        am.clabel(cs, fontsize=7, fmt="%g")
    asec.set_facecolor("0.93")
    asec.set_xlim(lo[h], hi[h])
    asec.set_ylim(lo[2], hi[2])
    asec.set_aspect(k)
    # faults: face polygons seen from above; their traces in the section
    if d.fracture.size:
        am.add_collection(LineCollection(outline_segments(pts, conn, off, d.fracture)[:, :, :2], colors="k",
                                         linewidths=1.2))
        placed = []
        for i, n in enumerate(d.names):
            sel = d.fracture == i
            if sel.any():
                c = (d.centroid[sel] * d.area[sel, None]).sum(axis=0) / d.area[sel].sum()
                near = sum(np.hypot(*(c[:2] - q) / (whi - wlo)) < 0.05 for q in placed)
                placed.append(c[:2])
                am.annotate(n, c[:2], xytext=(3, 3 - 13 * near), textcoords="offset points", fontsize=9,
                            fontweight="bold", ha="left", va="bottom",
                            bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.75))
        seg = section_traces(pts, conn, off, axis, at)
        if len(seg):
            asec.add_collection(LineCollection(seg, colors="k", linewidths=1.4))
    for w, x in d.well_cells_xyz.items():
        c = x.mean(axis=0)
        am.plot([c[0]], [c[1]], "v", color="k", ms=8)
        am.annotate(f"well {w}", c[:2], xytext=(5, 5), textcoords="offset points", fontsize=9)
        asec.plot([c[h], c[h]], [x[:, 2].min(), x[:, 2].max()], "k-", lw=3, solid_capstyle="butt")
        asec.annotate(f"well {w}", (c[h], x[:, 2].max()), xytext=(3, 4), textcoords="offset points", fontsize=9)
    wells_xy = [x.mean(axis=0)[:2] for x in d.well_cells_xyz.values()]
    for name, x in d.point_xyz.items():
        am.plot([x[0]], [x[1]], "x", color="0.2", ms=6)
        if not any(np.hypot(*((x[:2] - q) / (whi - wlo))) < 0.04 for q in wells_xy):   # not on top of a well's label
            am.annotate(name, x[:2], xytext=(4, -10), textcoords="offset points", fontsize=8, color="0.2")
    if axis == 1:
        am.plot([lo[0], hi[0]], [at, at], "--", color="0.3", lw=1)
    else:
        am.plot([at, at], [lo[1], hi[1]], "--", color="0.3", lw=1)
    am.set_xlim(lo[0], hi[0])
    am.set_ylim(lo[1], hi[1])
    am.set_aspect("equal")
    am.set_xlabel("x (m)")
    am.set_ylabel("y (m)")
    am.set_title("map view" + (" (zoomed)" if zoomed else "") + ": largest over depth, contours\n"
                 + ("thick: fault outlines; " if d.fracture.size else "") + "dashed: the section", fontsize=10)
    xyz = "xyz"
    asec.set_xlabel(f"{xyz[h]} (m)")
    asec.set_ylabel("z (m)" + ("" if k == 1 else f", stretched ×{k:g}"))
    asec.set_title(f"vertical section at {xyz[axis]} = {at:.4g} m" + ("\nblack: faults" if d.fracture.size else ""),
                   fontsize=10)
    below = d.overpressure.size and float(d.overpressure.min()) < lo_v
    fig.colorbar(im, ax=[am, asec], label=f"p − p⁰ ({u})", shrink=0.85, extend="min" if below else "neither")
    fig.suptitle(f"{d.case}: overpressure at t = {format_time(d.t_final, d.t_end)} (grey: outside the grid)",
                 fontsize=11)
    save(fig, path)
