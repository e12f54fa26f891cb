"""The multipliers' discrete inf-sup constant on thinning fault faces (issue 24, docs/contact_patches.md).

    .venv/bin/python benchmarks/inf_sup.py [--throws 12.5 2.5 0.25 0.025]

A 4 × 2 × 4 corner-point grid of 100 m × 100 m × 25 m cells with a vertical fault on the pillar line
i = 2 whose throw t leaves fault faces of heights t and 25 − t (no snapping); β
(:func:`polypore.models.inf_sup.inf_sup_constant`) for the bubble stabilisations "cell" (the scheme's
h_K^{d−2}) and "face" (|σ|²/|K|, the default), with one multiplier per face and with patches (0.2).
tests/unit/discretisation/test_contact_patches.py asserts the same family.
"""

from __future__ import annotations

import argparse

import numpy as np

from polypore.mesh.cornerpoint import fractured_mesh, process_grid
from polypore.mesh.cornerpoint.generate import FaultSpec, generate_grid
from polypore.models.inf_sup import inf_sup_constant
from polypore.models.mechanics import ContactMechanics, ContactSpec, DisplacementBC, MechanicsData


def mechanics(throw: float, ratio: float, bubbles: str) -> ContactMechanics:
    grid = generate_grid(4, 2, 4, extent=(400.0, 200.0, 100.0), faults=[FaultSpec("i", 2, throw, name="F")],
                         properties=False)
    mesh, info = process_grid(grid, snap=0.0)
    fm = fractured_mesh(mesh, info, ["F"])
    zero = lambda X, t: np.zeros_like(X)  # noqa: E731
    bcs = [DisplacementBC("bottom", (0, 1, 2), zero)] + [DisplacementBC(b, (0, 1), zero)
                                                         for b in ("west", "east", "south", "north")]
    n = mesh.n_cells
    return ContactMechanics(fm, MechanicsData(mu=np.full(n, 1e10), lam=np.full(n, 1e10), displacement=bcs,
                                              contact=ContactSpec("coulomb", 0.6, patch_ratio=ratio),
                                              bubble_stabilisation=bubbles))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--throws", type=float, nargs="+", default=[12.5, 2.5, 0.25, 0.025])
    a = ap.parse_args(argv)
    variants = [(0.0, "cell"), (0.2, "cell"), (0.0, "face"), (0.2, "face")]
    print("throw (m) | smallest |σ|/A_K | " + " | ".join(f"{b} bubbles, {'patches' if r else 'face-wise'}"
                                                        for r, b in variants))
    for t in a.throws:
        ms = [mechanics(t, r, b) for r, b in variants]
        ratio = float(ms[0].patches.ratio.min())
        print(f"{t:9g} | {ratio:16.4g} | " + " | ".join(f"{inf_sup_constant(m):.3f}" for m in ms))


if __name__ == "__main__":
    main()
