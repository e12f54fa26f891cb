"""Plots a run writes (PNG, matplotlib's Agg backend: works without a screen).

Every figure of one run uses the same time unit (:func:`time_unit`), and values are shown in
the SI prefix that suits their magnitude (MPa rather than Pa with a ×10⁷ offset, mm or µm
rather than m), so that no axis carries an offset label that collides with a panel title.
Figures with one panel per fracture wrap after :data:`MAX_COLUMNS` fractures so that they
stay readable on a screen.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .atomic import atomic_path

STATE_COLOURS = {"open": "tab:blue", "stick": "tab:green", "slip": "tab:red"}
MAX_COLUMNS = 3          # fractures side by side before a figure wraps to a new block of rows
DAY = 86400.0


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path) -> None:
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, dpi=130, bbox_inches="tight", format="png")
    _plt().close(fig)


def time_unit(t_end: float) -> tuple[float, str]:
    """(seconds per unit, unit name) for the time axes of a run ending at ``t_end`` s.

    Days once a run lasts a day or more (reservoir time scales), seconds otherwise: the same
    rule for every figure of a run, so its plots never mix seconds and days.
    """
    return (DAY, "days") if t_end >= DAY else (1.0, "s")


def format_time(t: float, t_end: float) -> str:
    """``t`` (s) in the run's unit: '100 days', '1 day', '500 s'."""
    f, name = time_unit(t_end)
    v = f"{t / f:.4g}"
    return f"{v} {'day' if name == 'days' and v == '1' else name}"


def time_tag(t: float, t_end: float) -> str:
    """File-name tag of a time: '500' in seconds (as before), '100d' in days."""
    f, name = time_unit(t_end)
    return f"{t / f:g}" + ("" if name == "s" else "d")


def value_unit(unit: str, magnitude: float) -> tuple[float, str]:
    """(factor, unit) so that values of the given magnitude read well: Pa → kPa/MPa/GPa,
    m → mm/µm. Other units are returned unchanged (factor 1)."""
    m = abs(float(magnitude)) if np.isfinite(magnitude) else 0.0
    if unit == "Pa":
        for f, name in ((1e9, "GPa"), (1e6, "MPa"), (1e3, "kPa")):
            if m >= f:
                return f, name
        return 1.0, "Pa"
    if unit == "m":
        if m >= 1.0 or m == 0.0:
            return 1.0, "m"
        return (1e-3, "mm") if m >= 1e-3 else (1e-6, "µm")
    return 1.0, unit


def _split_label(label: str) -> tuple[str, str]:
    """'λ_n (Pa)' → ('λ_n', 'Pa'); a label without a unit → (label, '')."""
    if label.endswith(")") and "(" in label:
        i = label.rfind("(")
        return label[:i].rstrip(), label[i + 1:-1]
    return label, ""


def _fracture_blocks(n: int) -> list[list[int]]:
    """Fracture indices grouped into blocks of at most MAX_COLUMNS (one block per row band)."""
    return [list(range(a, min(a + MAX_COLUMNS, n))) for a in range(0, n, MAX_COLUMNS)]


def fracture_profiles(path, names, fracture, s, fields: dict, states, title: str = "", reference: dict | None = None):
    """One column per fracture (wrapping after MAX_COLUMNS), one row per field against the
    arc length s (2D), and a row of contact states.

    fields : label -> (n_ff,) values; the label ends with its SI unit, '(Pa)' or '(m)', and
        the values are shown in the prefix that suits their magnitude;
    states : (n_ff,) state names;
    reference : label -> (s_ref, values) analytic curves drawn as dashed lines.
    """
    plt = _plt()
    nf = len(names)
    states = np.asarray(states)
    mags = _row_scales(fields, reference)
    shown = {}                                     # label -> (display label, factor)
    for label in fields:
        base, unit = _split_label(label)
        f, u = value_unit(unit, mags[label])
        shown[label] = (f"{base} ({u})" if unit else base, f)
    nrow = len(fields) + 1
    blocks = _fracture_blocks(nf)
    ncol = max(len(b) for b in blocks) if blocks else 1
    ratios = ([1.0] * len(fields) + [0.35]) * max(len(blocks), 1)
    fig, axes = plt.subplots(nrow * max(len(blocks), 1), ncol, squeeze=False, layout="constrained",
                             figsize=(3.4 * ncol + 0.8, sum(ratios) * 1.9 + 0.8),
                             gridspec_kw={"height_ratios": ratios})
    for b, block in enumerate(blocks):
        for col, j in enumerate(block):
            sel = np.flatnonzero(fracture == j)
            order = sel[np.argsort(s[sel])]
            top = b * nrow
            for i, (label, vals) in enumerate(fields.items()):
                ax = axes[top + i, col]
                disp, f = shown[label]
                vals = np.asarray(vals, float)
                ax.plot(s[order], vals[order] / f, ".-", ms=3, lw=0.8, label="polypore")
                seen = [vals[order] / f]
                if reference and label in reference and j == 0:
                    sr, vr = reference[label]
                    ax.plot(sr, np.asarray(vr, float) / f, "k--", lw=1, label="analytic")
                    ax.legend(fontsize=7, loc="best")
                    seen.append(np.asarray(vr, float) / f)
                _min_span(ax, np.concatenate(seen), mags[label] / f)
                if col == 0:
                    ax.set_ylabel(disp, fontsize=8)
                if i == 0:
                    ax.set_title(names[j], fontsize=9)
                ax.tick_params(labelsize=7, labelbottom=False)
                ax.grid(alpha=0.3)
            ax = axes[top + nrow - 1, col]
            for st, colour in STATE_COLOURS.items():
                m = order[states[order] == st]
                ax.scatter(s[m], np.zeros(m.size), c=colour, s=8, label=st)
            for i in range(nrow - 1):
                axes[top + i, col].sharex(ax)
            ax.set_yticks([])
            ax.set_xlabel("arc length s (m)", fontsize=8)
            if col == 0:
                ax.set_ylabel("state", fontsize=8)
            ax.tick_params(labelsize=7)
        for col in range(len(block), ncol):
            for i in range(nrow):
                axes[b * nrow + i, col].axis("off")
    handles = [plt.Line2D([], [], ls="", marker="o", ms=4, color=c, label=st) for st, c in STATE_COLOURS.items()]
    fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=7, frameon=False)
    if title:
        fig.suptitle(title, fontsize=10)
    save(fig, path)


def _row_scales(fields: dict, reference: dict | None) -> dict:
    """Magnitude (max |value|) of each field; fields in the same unit share the largest, except
    changes (labels starting with Δ): a ΔCFS of 50 kPa next to λ_n of 20 MPa would show flat."""
    mag = {}
    for label, vals in fields.items():
        v = [np.abs(np.asarray(vals, float))]
        if reference and label in reference:
            v.append(np.abs(np.asarray(reference[label][1], float)))
        v = np.concatenate(v)
        v = v[np.isfinite(v)]
        mag[label] = float(v.max()) if v.size else 0.0
    unit = {label: label if label.startswith("Δ") else (_split_label(label)[1] or label) for label in fields}
    return {label: max(mag[k] for k in fields if unit[k] == unit[label]) for label in fields}


def _min_span(ax, values, scale, rel=0.05):
    """Let the y axis span at least ``rel * scale``: variations far below a field's magnitude
    (a uniform λ_n off by 10^-4, round-off normal jumps of a closed fracture) then show flat
    instead of blown up to the full axis height."""
    v = values[np.isfinite(values)]
    if v.size == 0 or scale <= 0:
        return
    lo, hi = float(v.min()), float(v.max())
    if hi - lo < rel * scale:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - rel * scale, mid + rel * scale)
    ax.ticklabel_format(axis="y", useOffset=False)


def state_map(path, mesh, fm_faces, states, title=""):
    """2D map of the fracture faces coloured by contact state over the domain outline."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 7 * np.ptp(mesh.nodes[:, 1]) / max(np.ptp(mesh.nodes[:, 0]), 1e-300) + 0.5))
    lo, hi = mesh.bounding_box
    ax.plot([lo[0], hi[0], hi[0], lo[0], lo[0]], [lo[1], lo[1], hi[1], hi[1], lo[1]], "k-", lw=0.8)
    seg = mesh.face_nodes.values.reshape(-1, 2)[fm_faces]
    states = np.asarray(states)
    for st, col in STATE_COLOURS.items():
        m = states == st
        if m.any():
            P = mesh.nodes[seg[m]]
            for k, p in enumerate(P):
                ax.plot(p[:, 0], p[:, 1], "-", color=col, lw=2.5, label=st if k == 0 else None)
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title, fontsize=10)
    save(fig, path)


def convergence_plot(path, h, errors: dict, rates: dict, title=""):
    """Log-log plot of each error against h with its fitted rate and a slope-1 guide."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    h = np.asarray(h, float)
    for name, e in errors.items():
        e = np.asarray(e, float)
        if np.all(e > 0):
            ax.loglog(h, e, "o-", label=f"{name} (rate {rates.get(name, float('nan')):.2f})")
    ref = np.asarray(list(errors.values())[0], float) if errors else None
    if ref is not None and np.all(ref > 0):
        ax.loglog(h, ref[0] * (h / h[0]), "k:", lw=1, label="slope 1")
    ax.set_xlabel("h (m)")
    ax.set_ylabel("error")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    save(fig, path)


def _cell_polygons(mesh):
    from .vtu import bulk_cells

    c = bulk_cells(mesh)
    conn, off = c["connectivity"], c["offsets"]
    starts = np.concatenate([[0], off[:-1]])
    P = c["points"][:, :2]
    return [P[conn[a:b]] for a, b in zip(starts, off)]


def _overpressure_maps(path, case_name, mesh, seg, snapshots, t_end):
    """Maps of p − p⁰ at the output times; one colour scale (and bar) for all panels."""
    plt = _plt()
    from matplotlib.collections import LineCollection, PolyCollection

    polys = _cell_polygons(mesh)
    k = len(snapshots)
    cols = min(3, k)
    rows = int(np.ceil(k / cols))
    lo, hi = mesh.bounding_box
    aspect = (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-300)
    vmax = max(float(np.abs(sn["overpressure"]).max()) for sn in snapshots) or 1.0
    f, unit = value_unit("Pa", vmax)
    fig, axes = plt.subplots(rows, cols, squeeze=False, layout="constrained", sharex=True, sharey=True,
                             figsize=(3.6 * cols + 1.2, 3.6 * aspect * rows + 0.9))
    for ax, sn in zip(axes.ravel(), snapshots):
        pc = PolyCollection(polys, array=sn["overpressure"] / f, cmap="RdBu_r", edgecolors="none")
        pc.set_clim(-vmax / f, vmax / f)
        ax.add_collection(pc)
        ax.add_collection(LineCollection(mesh.nodes[seg][:, :, :2], colors="k", linewidths=1.0))
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_title(f"t = {format_time(sn['time'], t_end)}", fontsize=9)
        ax.tick_params(labelsize=7)
    for c in range(cols):
        last = axes[(k - 1 - c) // cols, c]          # lowest used panel of the column
        last.set_xlabel("x (m)", fontsize=8)
        last.tick_params(labelbottom=True)
    for ax in axes.ravel():
        ax.locator_params(axis="x", nbins=5)
    for ax in axes[:, 0]:
        ax.set_ylabel("y (m)", fontsize=8)
    for ax in axes.ravel()[k:]:
        ax.axis("off")
    fig.colorbar(pc, ax=axes.ravel().tolist(), shrink=0.8, label=f"p − p⁰ ({unit})")
    fig.suptitle(f"{case_name}: matrix overpressure", fontsize=10)
    save(fig, path)


def poro_plots(stage, case_name, mesh, net, s, snapshots, series, t_end):
    """The C4 figures: overpressure maps, contact states along the fractures at T/4 and T,
    mean aperture and mean fracture pressure per fracture against time (2D; without
    fractures only the overpressure maps). Times in the run's unit (:func:`time_unit`)."""
    plt = _plt()
    seg = mesh.face_nodes.values.reshape(-1, 2)[net.faces]
    _overpressure_maps(stage / "overpressure.png", case_name, mesh, seg, snapshots, t_end)
    if not net.n_faces:
        return
    # contact states along the fractures at T/4 and T
    times = np.array([sn["time"] for sn in snapshots])
    picks = sorted({int(np.argmin(np.abs(times - t_end / 4))), len(snapshots) - 1})
    for j in picks:
        sn = snapshots[j]
        fields = {"λ_n (Pa)": sn["lambda_n"], "|[[u]]_τ| (m)": sn["jump_t"], "aperture (m)": sn["aperture"],
                  "ΔCFS since t = 0 (Pa)": sn["delta_cfs"], "slip tendency τ/σ_n′": sn["slip_tendency"]}
        fracture_profiles(stage / f"contact_t{time_tag(sn['time'], t_end)}.png", net.names, net.fracture, s, fields,
                          [("open", "stick", "slip")[v] for v in sn["state"]],
                          title=f"{case_name}: contact along the fractures at t = {format_time(sn['time'], t_end)}")
    # mean aperture and mean fracture pressure per fracture against time
    tf, tname = time_unit(t_end)
    t = np.array([r["time"] for r in series]) / tf
    ap = {name: np.array([r[name][0] for r in series], float) for name in net.names}
    pf = {name: np.array([r[name][1] for r in series], float) for name in net.names}
    fa, ua = value_unit("m", max((np.abs(v).max() for v in ap.values()), default=0.0))
    fp, up = value_unit("Pa", max((np.abs(v).max() for v in pf.values()), default=0.0))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4), layout="constrained")
    for name in net.names:
        a1.plot(t, ap[name] / fa, label=name)
        a2.plot(t, pf[name] / fp, label=name)
    a1.set_ylabel(f"mean aperture ({ua})")
    a2.set_ylabel(f"mean fracture pressure ({up})")
    for a in (a1, a2):
        a.set_xlabel(f"t ({tname})")
        a.grid(alpha=0.3)
    fig.legend(*a1.get_legend_handles_labels(), loc="outside lower center", ncol=min(len(net.names), 6),
               fontsize=8, frameon=False)
    fig.suptitle(f"{case_name}: fracture means against time", fontsize=10)
    save(fig, stage / "fracture_means.png")


def monitor_plots(stage, case_name, net, s, monitor: dict, snapshots, onset, unit_time=None, time_label=None):
    """Monitoring figures of a poromechanics run (C6).

    monitor : {"time": (n,), "points": {name: (n,) overpressure p − p⁰, Pa}, "fault_p": {fracture:
        (n,) max p_f, Pa: the model's fracture pressure, absolute without [initial_state] and
        relative to the hydrostatic reference with it}, "fault_slip": {fracture: (n,) max slip
        since the start, m}}
    snapshots : output snapshots with "time", "slip" (n_ff,) and "aperture" (n_ff,)
    onset : time of the first slipping face (s) or None
    unit_time, time_label : seconds per plotted time unit and the axis label; by default the
        run's unit from :func:`time_unit` (the same as the other figures of the run).
    Writes monitor.png (pressures and max slip against time; not without monitor points and
    fractures) and slip_profiles.png (slip and aperture along each fracture at every output
    time, against the arc length s; not without fractures).
    """
    if not monitor["points"] and not net.n_faces:
        return                     # nothing to monitor
    plt = _plt()
    t_end = float(np.max(monitor["time"])) if len(monitor["time"]) else 0.0
    if unit_time is None:
        unit_time, name = time_unit(t_end)
        time_label = f"t ({name})"
    t = np.asarray(monitor["time"]) / unit_time
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.6), layout="constrained")
    # two quantities share the panel: the matrix overpressure at the points and the fractures'
    # pressure p_f itself (absolute without [initial_state]), so each curve says which it is
    for name, p in monitor["points"].items():
        a1.plot(t, np.asarray(p) / 1e6, label=f"overpressure p − p⁰ at {name}")
    for name, p in monitor["fault_p"].items():
        a1.plot(t, np.asarray(p) / 1e6, "--", label=f"max fracture pressure p_f on {name}")
    for name, v in monitor["fault_slip"].items():
        a2.plot(t, np.asarray(v) * 1e3, label=f"max slip on {name}")
    for a in (a1, a2):
        if onset is not None:
            a.axvline(onset / unit_time, color="0.4", lw=0.8, ls=":", label="slip onset")
        a.set_xlabel(time_label)
        a.grid(alpha=0.3)
        handles, labels = a.get_legend_handles_labels()
        if handles:                # the slip panel is empty without fractures
            # below the axes: inside, the legend hides the curves it names
            a.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)
    a1.set_ylabel("pressure (MPa)" if monitor["fault_p"] else "overpressure p − p⁰ (MPa)")
    a2.set_ylabel("slip |[[u − u⁰]]_τ| (mm)")
    fig.suptitle(f"{case_name}: pressures and slip against time", fontsize=10)
    save(fig, stage / "monitor.png")
    if not net.n_faces:
        return
    _slip_profiles(stage / "slip_profiles.png", case_name, net, s, snapshots, unit_time, time_label)


def _slip_profiles(path, case_name, net, s, snapshots, unit_time, time_label):
    """Slip and aperture along every fracture at every output time (wrapped after
    MAX_COLUMNS fractures; one legend of times for the figure)."""
    plt = _plt()
    blocks = _fracture_blocks(len(net.names))
    ncol = max(len(b) for b in blocks)
    amax = max(float(np.abs(sn["aperture"]).max()) for sn in snapshots) if snapshots else 0.0
    smax = max(float(np.abs(sn["slip"]).max()) for sn in snapshots) if snapshots else 0.0
    fa, ua = value_unit("m", amax)
    fs, us = value_unit("m", smax)
    fig, axes = plt.subplots(2 * len(blocks), ncol, squeeze=False, layout="constrained",
                             figsize=(4.0 * ncol + 0.8, 3.0 * 2 * len(blocks) + 0.8))
    cmap = plt.get_cmap("viridis")
    for b, block in enumerate(blocks):
        for col, j in enumerate(block):
            sel = np.flatnonzero(net.fracture == j)
            order = sel[np.argsort(s[sel])]
            top, bottom = axes[2 * b, col], axes[2 * b + 1, col]
            for k, sn in enumerate(snapshots):
                c = cmap(k / max(len(snapshots) - 1, 1))
                lab = f"t = {sn['time'] / unit_time:.4g}"
                top.plot(s[order], sn["slip"][order] / fs, color=c, lw=1, label=lab)
                bottom.plot(s[order], sn["aperture"][order] / fa, color=c, lw=1, label=lab)
            top.sharex(bottom)
            top.tick_params(labelbottom=False)
            top.set_title(net.names[j], fontsize=9)
            bottom.set_xlabel("arc length along the fracture (m)", fontsize=8)
            for a in (top, bottom):
                a.grid(alpha=0.3)
                a.tick_params(labelsize=7)
            if col == 0:
                top.set_ylabel(f"slip ({us})", fontsize=8)
                bottom.set_ylabel(f"aperture ({ua})", fontsize=8)
        for col in range(len(block), ncol):
            axes[2 * b, col].axis("off")
            axes[2 * b + 1, col].axis("off")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=7, title=time_label, title_fontsize=7)
    fig.suptitle(f"{case_name}: slip and aperture along the fractures", fontsize=10)
    save(fig, path)
