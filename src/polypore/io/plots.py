"""Plots a run writes (PNG, matplotlib's Agg backend: works without a screen)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .atomic import atomic_path

STATE_COLOURS = {"open": "tab:blue", "stick": "tab:green", "slip": "tab:red"}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path) -> None:
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, dpi=130, bbox_inches="tight", format="png")
    _plt().close(fig)


def fracture_profiles(path, names, fracture, s, fields: dict, states, title: str = "", reference: dict | None = None):
    """One column per fracture, one row per field against the arc length s (2D).

    fields : name -> (n_ff,) values (label includes the unit); states : (n_ff,) state names;
    reference : field name -> (s_ref, values) analytic curves drawn as lines.
    """
    plt = _plt()
    nf = len(names)
    rows = len(fields) + 1
    fig, axes = plt.subplots(rows, nf, figsize=(3.2 * nf + 1, 2.0 * rows + 0.6), squeeze=False, sharex="col")
    states = np.asarray(states)
    scale = _row_scales(fields, reference)
    for j, name in enumerate(names):
        sel = np.flatnonzero(fracture == j)
        order = sel[np.argsort(s[sel])]
        for i, (label, vals) in enumerate(fields.items()):
            ax = axes[i, j]
            ax.plot(s[order], vals[order], ".-", ms=3, lw=0.8, label="polypore")
            shown = [vals[order]]
            if reference and label in reference and j == 0:
                sr, vr = reference[label]
                ax.plot(sr, vr, "k--", lw=1, label="analytic")
                ax.legend(fontsize=7)
                shown.append(np.asarray(vr, float))
            _min_span(ax, np.concatenate(shown), scale[label])
            if j == 0:
                ax.set_ylabel(label, fontsize=8)
            if i == 0:
                ax.set_title(name, fontsize=9)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
        ax = axes[-1, j]
        for st, col in STATE_COLOURS.items():
            m = order[states[order] == st]
            ax.scatter(s[m], np.zeros(m.size), c=col, s=8, label=st)
        ax.set_yticks([])
        ax.set_xlabel("arc length s (m)", fontsize=8)
        if j == 0:
            ax.set_ylabel("state", fontsize=8)
            ax.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.45))
        ax.tick_params(labelsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    save(fig, path)


def _row_scales(fields: dict, reference: dict | None) -> dict:
    """Magnitude (max |value|) of each field; fields in the same unit share the largest."""
    mag = {}
    for label, vals in fields.items():
        v = [np.abs(np.asarray(vals, float))]
        if reference and label in reference:
            v.append(np.abs(np.asarray(reference[label][1], float)))
        v = np.concatenate(v)
        v = v[np.isfinite(v)]
        mag[label] = float(v.max()) if v.size else 0.0
    unit = {label: label[label.rfind("("):] if "(" in label else label for label in fields}
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


def poro_plots(stage, case_name, mesh, net, s, snapshots, series, t_end):
    """The C4 figures: overpressure maps, contact states along the fractures at T/4 and T,
    mean aperture and mean fracture pressure per fracture against time (2D; without
    fractures only the overpressure maps)."""
    plt = _plt()
    from matplotlib.collections import PolyCollection

    polys = _cell_polygons(mesh)
    seg = mesh.face_nodes.values.reshape(-1, 2)[net.faces]
    # overpressure maps
    k = len(snapshots)
    cols = min(3, k)
    rows = int(np.ceil(k / cols))
    lo, hi = mesh.bounding_box
    aspect = (hi[1] - lo[1]) / max(hi[0] - lo[0], 1e-300)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 5.2 * cols * aspect / cols * 1.15 * rows + 0.6),
                             squeeze=False)
    vmax = max(float(np.abs(sn["overpressure"]).max()) for sn in snapshots) or 1.0
    for ax, sn in zip(axes.ravel(), snapshots):
        pc = PolyCollection(polys, array=sn["overpressure"], cmap="RdBu_r", edgecolors="none")
        pc.set_clim(-vmax, vmax)
        ax.add_collection(pc)
        for P in mesh.nodes[seg]:
            ax.plot(P[:, 0], P[:, 1], "k-", lw=1.0)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_title(f"t = {sn['time']:g} s", fontsize=9)
        ax.tick_params(labelsize=7)
        fig.colorbar(pc, ax=ax, shrink=0.8, label="p − p⁰ (Pa)")
    for ax in axes.ravel()[k:]:
        ax.axis("off")
    fig.suptitle(f"{case_name}: matrix overpressure", fontsize=10)
    save(fig, stage / "overpressure.png")
    if not net.n_faces:
        return
    # contact states along the fractures at T/4 and T
    times = np.array([sn["time"] for sn in snapshots])
    picks = sorted({int(np.argmin(np.abs(times - t_end / 4))), len(snapshots) - 1})
    for j in picks:
        sn = snapshots[j]
        fields = {"λ_n (Pa)": sn["lambda_n"], "|[[u]]_τ| (m)": sn["jump_t"], "aperture (m)": sn["aperture"]}
        fracture_profiles(stage / f"contact_t{sn['time']:g}.png", net.names, net.fracture, s, fields,
                          [("open", "stick", "slip")[v] for v in sn["state"]],
                          title=f"{case_name}: contact along the fractures at t = {sn['time']:g} s")
    # mean aperture and mean fracture pressure per fracture against time
    t = np.array([r["time"] for r in series])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for name in net.names:
        a1.plot(t, [r[name][0] for r in series], label=name)
        a2.plot(t, [r[name][1] for r in series], label=name)
    a1.set_xlabel("t (s)")
    a1.set_ylabel("mean aperture (m)")
    a2.set_xlabel("t (s)")
    a2.set_ylabel("mean fracture pressure (Pa)")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle(f"{case_name}: fracture means against time", fontsize=10)
    save(fig, stage / "fracture_means.png")


def monitor_plots(stage, case_name, net, s, monitor: dict, snapshots, onset, unit_time=1.0, time_label="t (s)"):
    """Monitoring figures of a poromechanics run (C6).

    monitor : {"time": (n,), "points": {name: (n,) overpressure, Pa}, "fault_p": {fracture: (n,)
        max p_f, Pa}, "fault_slip": {fracture: (n,) max slip since the start, m}}
    snapshots : output snapshots with "time", "slip" (n_ff,) and "aperture" (n_ff,)
    onset : time of the first slipping face (s) or None
    Writes monitor.png (pressures and max slip against time; not without monitor points and
    fractures) and slip_profiles.png (slip and aperture along each fracture at every output
    time, against the arc length s; not without fractures).
    """
    if not monitor["points"] and not net.n_faces:
        return                     # nothing to monitor
    plt = _plt()
    t = np.asarray(monitor["time"]) / unit_time
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for name, p in monitor["points"].items():
        a1.plot(t, np.asarray(p) / 1e6, label=f"matrix at {name}")
    for name, p in monitor["fault_p"].items():
        a1.plot(t, np.asarray(p) / 1e6, "--", label=f"max p_f on {name}")
    for name, v in monitor["fault_slip"].items():
        a2.plot(t, np.asarray(v) * 1e3, label=f"max slip on {name}")
    for a in (a1, a2):
        if onset is not None:
            a.axvline(onset / unit_time, color="0.4", lw=0.8, ls=":", label="slip onset")
        a.set_xlabel(time_label)
        a.grid(alpha=0.3)
        if a.get_legend_handles_labels()[0]:     # the slip panel is empty without fractures
            a.legend(fontsize=8)
    a1.set_ylabel("overpressure (MPa)")
    a2.set_ylabel("slip |[[u − u⁰]]_τ| (mm)")
    fig.suptitle(f"{case_name}: pressures and slip against time", fontsize=10)
    save(fig, stage / "monitor.png")
    nfr = len(net.names)
    if not net.n_faces:
        return
    fig, axes = plt.subplots(2, nfr, figsize=(4.5 * nfr + 1, 6), squeeze=False, sharex="col")
    cmap = plt.get_cmap("viridis")
    for j, name in enumerate(net.names):
        sel = np.flatnonzero(net.fracture == j)
        order = sel[np.argsort(s[sel])]
        for k, sn in enumerate(snapshots):
            c = cmap(k / max(len(snapshots) - 1, 1))
            lab = f"t = {sn['time'] / unit_time:.4g}"
            axes[0, j].plot(s[order], sn["slip"][order] * 1e3, color=c, lw=1, label=lab)
            axes[1, j].plot(s[order], sn["aperture"][order] * 1e6, color=c, lw=1, label=lab)
        axes[0, j].set_title(name, fontsize=9)
        axes[1, j].set_xlabel("arc length along the fracture (m)")
        for a in axes[:, j]:
            a.grid(alpha=0.3)
    axes[0, 0].set_ylabel("slip (mm)")
    axes[1, 0].set_ylabel("aperture (µm)")
    axes[0, -1].legend(fontsize=7, title=time_label.split(" ")[-1], title_fontsize=7)
    fig.suptitle(f"{case_name}: slip and aperture along the fractures", fontsize=10)
    save(fig, stage / "slip_profiles.png")
