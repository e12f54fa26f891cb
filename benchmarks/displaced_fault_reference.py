"""Closed-form stress changes along a displaced dipping fault (Jansen, Singhal & Vossepoel 2019 setting).

    .venv/bin/python benchmarks/displaced_fault_reference.py [--throws 0 50 100 200] [--dip 60]
        [--thickness 200] [--nu 0.25] [--out docs]

Reservoir of thickness h offset by a fault dipping at θ with throw t, laterally infinite, in a
plane-strain full space; a uniform pressure change Δp < 0 (depletion) in the reservoir
(``polypore.cases.displaced_fault``, derivation in ``docs/displaced_fault_reference.md``).
Stresses are divided by |C|, C = (1 − 2ν) α Δp / (2π (1 − ν)) (the prefactor of every term;
E drops out of the stresses), keeping their physical sign for depletion: injection flips every
curve. Plotted against the elevation y along the fault, three panels: the total normal stress
change Δσ_n, the effective one Δσ'_n = Δσ_n − Δp_f (Δp_f = Δp where the reservoir touches the
fault on either side), both compression positive, and the shear change Δτ (positive: the
footwall's traction on the hanging wall points up-dip, i.e. it drives normal slip). Dotted lines: the corners y_a … y_d of the first non-zero
throw. The peaks are logarithmic singularities, so the curves are clipped.

Writes ``<out>/displaced_fault_reference.png`` and ``<out>/displaced_fault_reference.json``
(per throw: y, s = y / sin θ in m, and the three normalised curves; the corners and the ln r
coefficients of (Δσ_n, Δτ) at each corner); prints the corner coefficients. Takes a second.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from polypore.cases.displaced_fault import DisplacedFault, scaling_factor
from polypore.io.plots import _plt, save


def curves(thickness, throw, dip, nu, alpha=1.0, dp=-1.0e6, n=301):
    """Normalised curves along the fault over y ∈ [−1.5 h, 1.5 h] (the corners themselves left out)."""
    g = DisplacedFault(thickness, throw, dip)
    y = np.linspace(-1.5 * thickness, 1.5 * thickness, n)
    # shift the grid so that no sample falls on a corner, and add samples approaching each corner
    # geometrically (1 mm to 10 m) so that the plots show the logarithmic peaks
    near = (g.corners_y[:, None, None] + np.array([-1.0, 1.0])[:, None] * np.logspace(-3, 1, 17)).ravel()
    y = np.unique(np.concatenate([y + 0.37 * (y[1] - y[0]), near]))
    C = abs(scaling_factor(dp, alpha, nu))
    r = g.fault_stress_changes(y, dp, alpha, nu)
    coef = g.corner_log_coefficients(dp, alpha, nu) / C
    def rounded(v):  # 7 significant digits: the JSON stays small
        return [float(f"{x:.7g}") for x in v]

    return g, {"y": rounded(y), "s": rounded(r["s"]), "sigma_n": rounded(r["sigma_n"] / C),
               "sigma_n_eff": rounded(r["sigma_n_eff"] / C), "tau": rounded(r["tau"] / C),
               "corners_y": g.corners_y.tolist(), "log_coefficients": coef.tolist()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--throws", type=float, nargs="+", default=[0.0, 50.0, 100.0, 200.0])
    ap.add_argument("--dip", type=float, default=60.0)
    ap.add_argument("--thickness", type=float, default=200.0)
    ap.add_argument("--nu", type=float, default=0.25)
    ap.add_argument("--out", type=Path, default=Path("docs"))
    a = ap.parse_args(argv)

    out = {"thickness_m": a.thickness, "dip_deg": a.dip, "nu": a.nu, "alpha": 1.0, "dp_sign": "depletion (dp < 0)",
           "normalisation": "stress / |C|, C = (1 - 2 nu) alpha dp / (2 pi (1 - nu))",
           "signs": "sigma_n, sigma_n_eff compression positive; tau > 0: traction of the footwall on the hanging wall points up-dip (drives normal slip)",
           "throws": {}}
    plt = _plt()
    fig, axs = plt.subplots(1, 3, figsize=(13, 6.2), sharey=True)
    keys = [("sigma_n", "Δσ_n / |C| (total, compression +)"), ("sigma_n_eff", "Δσ'_n / |C| (effective, compression +)"),
            ("tau", "Δτ / |C| (+: drives normal slip)")]
    first = None
    for t in a.throws:
        g, c = curves(a.thickness, t, a.dip, a.nu)
        out["throws"][f"{t:g}"] = c
        if first is None and t > 0:
            first = g
        y = np.asarray(c["y"])
        for ax, (k, _) in zip(axs, keys):
            ax.plot(c[k], y, lw=1.4, label=f"t = {t:g} m")
        print(f"t = {t:6g} m  corners y = {np.round(g.corners_y, 1)}  ln r coefficients (σ_n, τ)/|C| =",
              np.round(np.asarray(c["log_coefficients"]), 4).tolist())
    for ax, (k, label) in zip(axs, keys):
        ax.axvline(0.0, color="k", lw=0.6)
        if first is not None:
            for yc, name in zip(first.corners_y, "abcd"):
                ax.axhline(yc, color="0.6", ls=":", lw=0.8)
                if k == "sigma_n":
                    ax.text(-9.8, yc, f"y_{name}", va="bottom", fontsize=8, color="0.4")
        ax.set_xlim(-10, 10)
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axs[0].set_ylabel("elevation y along the fault (m), reservoir centre at 0")
    axs[0].legend(loc="lower left", fontsize=9)
    fig.suptitle(f"Depletion of a reservoir (h = {a.thickness:g} m) offset by a fault dipping {a.dip:g}°, ν = {a.nu:g}: "
                 f"closed-form plane-strain stress changes along the fault\n(dotted: corners of t = "
                 f"{first.throw if first else 0:g} m; a, b hanging wall bottom/top, c, d footwall bottom/top)", fontsize=10)
    a.out.mkdir(parents=True, exist_ok=True)
    save(fig, a.out / "displaced_fault_reference.png")
    (a.out / "displaced_fault_reference.json").write_text(json.dumps(out) + "\n")
    print("wrote", a.out / "displaced_fault_reference.png", a.out / "displaced_fault_reference.json")


if __name__ == "__main__":
    main()
