"""3D slip accuracy per unknown on the cube case (issue 13): uniform against tip-graded tetrahedra.

    .venv/bin/python benchmarks/cube_slip.py                 # the study (~3 min)
    .venv/bin/python benchmarks/cube_slip.py --diagnose      # what moves the error (~2 min)
    .venv/bin/python benchmarks/cube_slip.py --reference --order 2   # remake the reference (~12 min, 3.2 GB)
    .venv/bin/python benchmarks/cube_slip.py --reference     # the former P1 reference (~25 min, 4 GB)
    .venv/bin/python benchmarks/cube_slip.py --order 2       # quadratic displacements (~15 min)
    .venv/bin/python benchmarks/cube_slip.py --anisotropic   # anisotropic crack-front meshes (~7 min)
    .venv/bin/python benchmarks/cube_slip.py --one out.json --order 2 --set mesh.tip_grading=0.75 ...
                                                             # one run (any --set of the case file)

The built-in case ``cube-slip-3d``: unit cube, fracture x ∈ [0.2, 0.8] on y = z,
y, z ∈ [0.3, 0.7], ymin clamped, ymax displaced by (−2e-4, −2e-4, 0) m, μ = λ_L = 10 GPa,
F = 0.5. Each run is a separate ``polypore run`` process (wall time and peak memory are
its own), with PARDISO. Errors against the reference (cases/reference.py): maximum slip,
relative L2 of the slip magnitude over the whole fracture and with the 10 % next to every
edge left out, relative L2 of λ_n with the rim left out, open faces.

``--reference --order 2`` (the reference in use) runs quadratic displacements on r^(2/3)-graded
meshes (``REF_P2_*``: tip_grading 2/3, fracture_size and tip_size scaled together, seven levels of
16k-169k unknowns), evaluates each run's P2 slip on a grid of the fracture plane, extrapolates
the maximum slip (Richardson with the rate fitted on three levels of scale ratio 2) and the grid
fields the same way from the two finest, into ``src/polypore/cases/data/cube-slip-3d-reference.npz``
(``--ref-out`` to write elsewhere); the levels go to ``<out>/cube_slip_reference.json``.
``--reference`` alone remakes the former P1 reference (√r-graded meshes, sizes scaled by
``REF_SCALES``, face means resampled), which the P2 runs showed to be 1.6 % low.

``--order 2`` runs the quadratic space (``MechanicsData.order = 2``, docs/accuracy_3d.md) on its
own mesh series (``UNIFORM_P2``, ``GRADED_P2``, ``GRADED_P2_34``) and the case's default mesh with order 1 for
comparison. Each of these runs builds the case through the setup API with the order set in
``MechanicsData`` (whatever the case file says), in a separate process of this script (``--one``): wall time (mesh, set-up,
solve; no output files) and peak memory are again the run's own. The maximum slip of the graded
P2 series is extrapolated like the reference's, to compare the limits.

``--anisotropic`` runs the meshes of ``mesh.front = "anisotropic"`` (thin cells across the crack
fronts, long along them: :mod:`polypore.mesh.generators.fronts`) with order 2 (``ANISO``, and
order 1 on some of the same meshes), the case's default mesh for comparison, and variants of one
level (``ANISO_VARIANTS``: what each knob does), into ``<out>/cube_slip_anisotropic.{json,md,png}``
(the isotropic P2 series of ``<out>/cube_slip_p2.json`` are drawn in the plot, not rerun).

Writes ``<out>/cube_slip.json``, ``<out>/cube_slip.md`` and ``<out>/cube_slip.png`` (``--order 2``:
``<out>/cube_slip_p2.{json,md,png}``).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "src/polypore/cases/data/cube-slip-3d.toml"
REF = ROOT / "src/polypore/cases/data/cube-slip-3d-reference.npz"
POLYPORE = Path(sys.executable).parent / "polypore"

ORIGIN = np.array([0.2, 0.3, 0.3])
E1 = np.array([1.0, 0.0, 0.0])
E2 = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
LENGTHS = (0.6, 0.4 * np.sqrt(2.0))

# uniform meshes: the issue's "before" (no grading: fracture_size = size, no tip refinement)
UNIFORM = [0.2, 0.1, 0.07, 0.05, 0.035]
# tip-graded meshes: the case's defaults (size 0.3, fracture_size 0.08, tip_size 0.015) scaled
GRADED = [1.6, 1.25, 1.0, 0.8, 0.63]
REF_SCALES = [0.33, 0.25, 0.2]

# order 2: "uniform" meshes refined on the fracture only (fracture_size = h, bulk size 0.5, no tip
# grading), and tip-graded meshes with a coarser fracture_size than P1's (the graded zone, of
# radius 4 fracture_size, then covers the cube: h = √(fracture_size/4) √r down to tip_size), the
# best of a sweep at ~20k unknowns (docs/accuracy_3d.md)
UNIFORM_P2 = [0.15, 0.1, 0.07, 0.05, 0.035]
GRADED_P2 = [1.6, 1.25, 1.0, 0.8, 0.63, 0.5]
P2_SIZES = (0.5, 0.3, 0.025)       # (size, fracture_size, tip_size) at scale 1, m
# order 2 on r^(3/4)-graded meshes (mesh.tip_grading = 0.75): the size law covers the cube, the bulk
# size 5 m is never reached (it must exceed fracture_size for the generator to grade at all);
# (fracture_size, tip_size) scaled together, a family independent of the reference's r^(2/3) one
GRADED_P2_34 = [1.41, 1.0, 0.707, 0.5]
P2_34_SIZES = (5.0, 2.5, 0.025, 0.75)   # (size, fracture_size, tip_size, tip_grading) at scale 1


def graded_p2(scale: float) -> list[str]:
    return [f"mesh.size={P2_SIZES[0]:.6g}", f"mesh.fracture_size={P2_SIZES[1] * scale:.6g}",
            f"mesh.tip_size={P2_SIZES[2] * scale:.6g}"]


def graded_p2_34(scale: float) -> list[str]:
    return [f"mesh.size={P2_34_SIZES[0]:.6g}", f"mesh.fracture_size={P2_34_SIZES[1] * scale:.6g}",
            f"mesh.tip_size={P2_34_SIZES[2] * scale:.6g}", f"mesh.tip_grading={P2_34_SIZES[3]:g}"]


def uniform_p2(h: float) -> list[str]:
    return [f"mesh.size={P2_SIZES[0]:.6g}", f"mesh.fracture_size={h}", "mesh.tip_size=1e9"]


# the order-2 reference: r^γ-graded meshes, (fracture_size, tip_size) scaled together (for γ = 3/4
# the balanced family: the cell count grows like 1/scale, compliance-type errors fall like scale)
REF_P2_GRADING = 2 / 3
REF_P2_SIZES = (3.0, 2.5, 0.025)   # (size, fracture_size, tip_size) at scale 1, m
REF_P2_SCALES = [1.0, 0.707, 0.5, 0.354, 0.25, 0.177, 0.125]
REF_P2_FIT = (0.5, 0.25, 0.125)


def graded_ref_p2(scale: float) -> list[str]:
    return [f"mesh.size={REF_P2_SIZES[0]:.6g}", f"mesh.fracture_size={REF_P2_SIZES[1] * scale:.6g}",
            f"mesh.tip_size={REF_P2_SIZES[2] * scale:.6g}", f"mesh.tip_grading={REF_P2_GRADING:.6g}"]


# anisotropic crack-front meshes (mesh.front = "anisotropic"): (fracture_size, tip_size) scaled together,
# bulk size 0.5 m, fill grading 0.2, tip_grading 0.6 (rings of 4 squares, 33 nodes, at scales ≤ 1.4; at
# scales ≥ 2 the box caps the ring radius at 0.15 m)
ANISO = [6.0, 3.0, 2.0, 1.4, 1.0, 0.7, 0.5]
ANISO_P1 = [1.0, 0.5, 0.35, 0.25]
ANISO_SIZES = {"size": 0.5, "fracture_size": 0.35, "tip_size": 0.005, "tip_grading": 0.6, "grading": 0.2}
# one knob at a time at scale 1 (case keys; the rest as ANISO_SIZES), and the cheapest mesh found that meets
# 3 % on the maximum slip and the slip L2 (a search over scale and grading, docs/cube_slip_anisotropic.md)
ANISO_VARIANTS = {
    "scale 1 (as the series)": (1.0, {}),
    "tip_size × 4 (rings of 2 squares instead of 4)": (1.0, {"tip_size": 0.02}),
    "tip_size / 10 (9 squares)": (1.0, {"tip_size": 0.0005}),
    "tip_grading 0.5 (5 squares)": (1.0, {"tip_grading": 0.5}),
    "tip_grading 0.75 (3 squares)": (1.0, {"tip_grading": 0.75}),
    "grading 0.4 (coarser fill)": (1.0, {"grading": 0.4}),
    "grading 0.1 (finer fill)": (1.0, {"grading": 0.1}),
    "bulk size 0.25": (1.0, {"size": 0.25}),
    "scale 1.7, grading 0.1 (the cheapest found within 3 %)": (1.7, {"grading": 0.1}),
    "scale 2, grading 0.1": (2.0, {"grading": 0.1}),
    "scale 0.5, grading 0.1 (the bulk refined with the fronts)": (0.5, {"grading": 0.1}),
}


def anisotropic(scale: float, **change) -> list[str]:
    v = dict(ANISO_SIZES)
    v["fracture_size"] *= scale
    v["tip_size"] *= scale
    v.update(change)
    return ["mesh.front=anisotropic"] + [f"mesh.{k}={x:.6g}" for k, x in v.items()]


# the isotropic series were made on the case file as it was before it took anisotropic fronts
# (mesh.front = "isotropic", size 1, fracture_size 0.8, tip_size 0.02, grading 0.4, tip_grading 0.6):
# pinned here, every series' own overrides come later and win
ISO_CASE = ["mesh.front=isotropic", "mesh.size=1.0", "mesh.fracture_size=0.8", "mesh.tip_size=0.02",
            "mesh.grading=0.4", "mesh.tip_grading=0.6"]
P1_PINS = ISO_CASE + ["mechanics.order=1", "mesh.tip_grading=0.5"]


def graded(scale: float) -> list[str]:
    return [f"mesh.size={0.3 * scale:.6g}", f"mesh.fracture_size={0.08 * scale:.6g}",
            f"mesh.tip_size={0.015 * scale:.6g}"]


def uniform(h: float) -> list[str]:
    return [f"mesh.size={h}", f"mesh.fracture_size={h}", "mesh.tip_size=1e9"]


def _target_axes(ax, title: str) -> None:
    """Error-against-unknowns axes with issue 13's target (3 % at 20,000 unknowns) dotted."""
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.axhline(3.0, color="0.5", lw=0.8, ls=":")
    ax.axvline(2e4, color="0.5", lw=0.8, ls=":")
    ax.set_xlabel("unknowns")
    ax.set_ylabel("error (%)")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")


def run(case: Path, overrides: list[str], workdir: Path, tag: str) -> dict:
    """One ``polypore run`` in its own process; its summary.json plus the per-face table."""
    out = workdir / tag
    cmd = [str(POLYPORE), "-q", "run", str(case), "--out", str(out), "--force", "--set", "solver.linear=pardiso"]
    # these runs are the linear space's series: its order and √r law pinned (the case file runs P2 on
    # an r^0.6 mesh); the overrides come later and win
    for o in P1_PINS + overrides:
        cmd += ["--set", o]
    subprocess.run(cmd, check=True)
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "fractures.csv") as f:
        rows = list(csv.DictReader(f))
    col = lambda k: np.array([float(r[k]) for r in rows])  # noqa: E731
    X = np.column_stack([col("x"), col("y"), col("z")])
    q = np.column_stack([col("jump_x"), col("jump_y"), col("jump_z")])
    n = np.array([0.0, 1.0, -1.0]) / np.sqrt(2.0)
    slip = q - (q @ n)[:, None] * n
    area = col("area")
    # |∫_Γ [[u]]_τ| (m³): exact from the face means, a smooth functional of the solution
    summary["slip_integral"] = float(np.linalg.norm(area @ slip))
    return {"summary": summary, "X": X, "slip": slip, "lambda_n": col("lambda_n"), "area": area}


def run_one(order: int, overrides: list[str], workdir: Path, tag: str, case: Path = CASE,
            field: bool = False) -> dict:
    """One in-process run of the case at the given order, in its own process (``--one``); with
    ``field``, the run's slip field is in ``<workdir>/<tag>.npz``."""
    out = workdir / f"{tag}.json"
    cmd = [sys.executable, str(Path(__file__).resolve()), "--one", str(out), "--order", str(order),
           "--case", str(case)]
    if field:
        cmd += ["--field", str(workdir / f"{tag}.npz")]
    # the case's own tip_grading (0.6) is not the series': the generator's √r law unless a series
    # gives its exponent
    pins = ISO_CASE + ["mesh.tip_grading=0.5"] if Path(case) == CASE else []
    for o in pins + overrides + ["solver.linear=pardiso"]:
        cmd += ["--set", o]
    subprocess.run(cmd, check=True)
    return json.loads(out.read_text())


def reference_grid(n: int = 121) -> tuple[np.ndarray, np.ndarray]:
    """The grid of the reference file (cases/reference.py ``resample``): a along E1, b along E2."""
    La, Lb = LENGTHS
    return np.linspace(0.0, La, n), np.linspace(0.0, Lb, int(round(n * Lb / La)) | 1)


def p2_jump_on_grid(problem, u: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The P2 jump [[u]](x) (na, nb, 3) at the points ORIGIN + a E1 + b E2 of the fracture: each
    point located in its fracture face, where ``QuadraticSpace.jump_at`` evaluates the traces of
    both sides and the face bubbles. Edge points are moved 1e-9 m inside."""
    from matplotlib.tri import Triangulation

    mesh, net = problem.fm.mesh, problem.fm.network
    F = mesh.face_nodes.values.reshape(mesh.n_faces, 3)[net.faces]                # (n_ff, 3)
    used, local = np.unique(F, return_inverse=True)
    R = mesh.nodes[used] - ORIGIN
    P = np.stack([R @ E1, R @ E2], axis=1)
    tri = Triangulation(P[:, 0], P[:, 1], local.reshape(F.shape))
    A, B = np.meshgrid(np.clip(a, 1e-9, LENGTHS[0] - 1e-9), np.clip(b, 1e-9, LENGTHS[1] - 1e-9), indexing="ij")
    x, y = A.ravel(), B.ravel()
    k = tri.get_trifinder()(x, y)
    if np.any(k < 0):
        raise RuntimeError(f"{int(np.sum(k < 0))} grid points outside the fracture triangulation")
    T = P[local.reshape(F.shape)[k]]                                             # (n, 3, 2)
    M = np.stack([T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]], axis=2)                # (n, 2, 2)
    l12 = np.linalg.solve(M, (np.stack([x, y], axis=1) - T[:, 0])[..., None])[..., 0]
    L = np.column_stack([1.0 - l12.sum(axis=1), l12])                           # face_nodes order
    return (problem.space.jump_at(k, L) @ u).reshape(a.size, b.size, 3)


def _penny_field_errors(exact, X, W, q, n) -> dict:
    """Relative L2 errors of the P2 opening and slip as fields (values q (m, 3) at the points X of a face
    rule with weights W, normals n) against the penny-shaped crack's analytic ones at those points:
    over the crack, and with the outer 10 % of the radius left out (r ≤ 0.9 a, by point)."""
    from polypore.cases.penny_exact import RIM as PENNY_RIM

    r = exact.radial(X)
    away = r <= PENNY_RIM * exact.radius
    qn = np.einsum("fi,fi->f", q, n)
    out = {}

    def rel(x, x_ex, m):
        return float(np.sqrt(np.sum((W * (x - x_ex) ** 2)[m]) / np.sum((W * x_ex ** 2)[m])))

    every = np.ones(r.size, bool)
    for name, amp, comp, ex in (("opening", exact.opening_amplitude, -qn, exact.opening),
                                ("slip", exact.slip_amplitude, np.linalg.norm(q - qn[:, None] * n, axis=1),
                                 exact.slip)):
        if amp > 0:
            out |= {f"{name}_L2_rel": rel(comp, ex(r), every), f"{name}_L2_rel_away_from_rim": rel(comp, ex(r), away),
                    f"{name}_mean_rel": float(np.sum(W * comp) / np.sum(W * ex(r)) - 1)}
    return out


def one(path: Path, order: int, overrides: list[str], case_name: str = str(CASE), field: Path | None = None) -> None:
    """Mesh, set up and solve a static case (default: the cube) with ``MechanicsData.order = order``;
    write a summary.json-like record (unknowns, cells, seconds, peak_memory_mb, newton, errors)
    to ``path``. With ``field``, also save the slip at the points of a face rule (order 2; the face
    centroids for order 1) and λ_n at the face centroids there (.npz), for a reference."""
    import dataclasses
    import resource
    import time

    try:
        from polypore.setup.casefile import load_case
        from polypore.setup.meshing import build_fractured_mesh
        from polypore.setup.mechanics import mechanics_setup
    except ImportError:                       # the layout before the cases/setup/runs split
        from polypore.cases.casefile import load_case
        from polypore.cases.meshing import build_fractured_mesh
        from polypore.cases.mechanics_setup import mechanics_setup
    from polypore.models.contact import OPEN
    from polypore.models.mechanics import ContactMechanics

    t0 = time.perf_counter()
    case = load_case(case_name, overrides)
    fm = build_fractured_mesh(case)
    setup = mechanics_setup(case, fm)
    problem = ContactMechanics(fm, dataclasses.replace(setup.data, order=order), setup.solver, setup.newton)
    st = problem.solve(verbose=False)
    errors = setup.exact.errors(problem, st) if setup.exact is not None else {}
    seconds = time.perf_counter() - t0
    q = problem.jumps(st)
    qt = q - np.einsum("fi,fi->f", q, problem.normal)[:, None] * problem.normal
    rec = {"mesh": {"unknowns": int(problem.free.size + problem.n_ff * problem.dim), "cells": fm.mesh.n_cells,
                    "fracture_faces": problem.n_ff},
           "totals": {"seconds": seconds,
                      "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0},
           "steps": [{"newton_iterations": st.newton_iterations}], "errors": errors, "order": order,
           "slip_integral": float(np.linalg.norm(problem.face_area @ qt))}
    ln_face = np.einsum("fi,fi->f", st.lam, problem.normal)
    Xc = fm.mesh.geometry.face_centroid[fm.network.faces]
    if order == 2:
        # the P2 slip as a field: its values at the points of a face rule (6 per face) against the
        # reference there, weighted by the rule (the face-mean errors above compare P0 face means
        # with point values, which costs O(h²) by itself on coarse fracture meshes)
        X, W, Jq = problem.space.jump_quadrature()
        nq = W.size // max(problem.n_ff, 1)
        n = np.repeat(problem.normal, nq, axis=0)
        q = Jq @ st.u
        qt_q = q - np.einsum("fi,fi->f", q, n)[:, None] * n
        rec["field_max_slip"] = float(np.linalg.norm(qt_q, axis=1).max(initial=0.0))
        if hasattr(setup.exact, "errors_of"):
            ln = np.repeat(ln_face, nq)
            rec["field_errors"] = setup.exact.errors_of(X, W, qt_q, ln, np.repeat(st.state == OPEN, nq))
        elif hasattr(setup.exact, "opening_amplitude"):
            rec["field_errors"] = _penny_field_errors(setup.exact, X, W, q, n)
    else:
        X, qt_q = Xc, qt
    if field is not None:
        # the slip on the reference grid: the P2 field there (order 2), or the face means
        # interpolated as the reference of order 1 did; λ_n (P0) interpolated from the centroids
        from polypore.cases.reference import resample

        a, b = reference_grid()
        arr = resample(Xc, qt, ln_face, ORIGIN, E1, E2, LENGTHS, n=a.size)
        if order == 2:
            g = p2_jump_on_grid(problem, st.u, a, b)
            n = np.array([0.0, 1.0, -1.0]) / np.sqrt(2.0)
            arr["slip"] = g - (g @ n)[..., None] * n
            arr["slip"][[0, -1]] = 0.0
            arr["slip"][:, [0, -1]] = 0.0
        rec["grid_max_slip"] = float(np.linalg.norm(arr["slip"], axis=2).max())
        np.savez_compressed(field, X=X, slip_points=qt_q, Xc=Xc, lambda_n_faces=ln_face, area=problem.face_area,
                            **arr)
    path.write_text(json.dumps(rec))


def richardson(s, m):
    """Extrapolate m(s) = m* − C s^p from three levels s0 > s1 > s2: (m*, p, w) with the Richardson
    weight w (X* = X2 + w (X2 − X1)); None if the values do not converge monotonically with a rate
    p in [0.2, 4]."""
    (s0, s1, s2), (m0, m1, m2) = s, m
    ratio = (m1 - m0) / (m2 - m1)
    f = lambda p: (s0 ** p - s1 ** p) / (s1 ** p - s2 ** p) - ratio  # noqa: E731
    lo, hi = 0.2, 4.0
    if f(lo) * f(hi) >= 0:
        return None
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    p = 0.5 * (lo + hi)
    w = s2 ** p / (s1 ** p - s2 ** p)
    return m2 + w * (m2 - m1), p, w


def _case_without_reference(tmp: Path) -> Path:
    data = tomllib.loads(CASE.read_text())
    data.pop("exact", None)
    path = tmp / "cube-slip-3d-noref.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def make_reference(workdir: Path):
    """Three √r-graded levels; the maximum slip and the resampled slip and λ_n fields
    extrapolated to h → 0 (Richardson, rate fitted on the maximum slips of the three levels)."""
    from polypore.cases.reference import resample

    case = _case_without_reference(workdir)
    levels = []
    for sc in REF_SCALES:
        r = run(case, graded(sc) + ["mesh.grading=0.3"], workdir, f"ref-{sc}")
        m = float(np.linalg.norm(r["slip"], axis=1).max())
        s = r["summary"]
        print(f"reference level scale {sc}: {s['mesh']['unknowns']} unknowns, max slip {m:.5e} m, "
              f"{s['totals']['seconds']:.0f} s, {s['totals']['peak_memory_mb']:.0f} MB", flush=True)
        levels.append((sc, m, r))
    (s0, m0, _), (s1, m1, r1), (s2, m2, r2) = levels
    # m(s) = m* − C s^p: the rate p from (m1 − m0)/(m2 − m1) = (s0^p − s1^p)/(s1^p − s2^p) by bisection
    fit = richardson((s0, s1, s2), (m0, m1, m2))
    if fit is None:
        raise SystemExit(f"the three maximum slips {m0:.5e}, {m1:.5e}, {m2:.5e} do not converge monotonically "
                         "with a rate in [0.2, 4]; refine the reference levels")
    m_star, p, w = fit                          # Richardson weight: X* = X2 + w (X2 − X1)
    a1 = resample(r1["X"], r1["slip"], r1["lambda_n"], ORIGIN, E1, E2, LENGTHS)
    a2 = resample(r2["X"], r2["slip"], r2["lambda_n"], ORIGIN, E1, E2, LENGTHS)
    arrays = {**a2, "slip": a2["slip"] + w * (a2["slip"] - a1["slip"]),
              "lambda_n": a2["lambda_n"] + w * (a2["lambda_n"] - a1["lambda_n"])}
    note = (f"√r-graded tetrahedra, sizes (0.3, 0.08, 0.015) m × {REF_SCALES}, grading 0.3 "
            f"({', '.join(str(lv[2]['summary']['mesh']['unknowns']) for lv in levels)} unknowns); maximum slips "
            f"{m0:.5e}, {m1:.5e}, {m2:.5e} m, fitted rate {p:.2f}, extrapolated {m_star:.5e} m; slip and λ_n "
            "fields extrapolated the same way from the two finest levels")
    print(note)
    np.savez_compressed(REF, **{k: v.astype(np.float64) for k, v in arrays.items()}, max_slip=m_star, note=note)
    print(f"wrote {REF}")


def _grid_integral(a, b, slip) -> float:
    """|∫_Γ [[u]]_τ| (m³) of a slip field on the reference grid (trapezoid rule)."""
    return float(np.linalg.norm(np.trapezoid(np.trapezoid(slip, b, axis=1), a, axis=0)))


def make_reference_p2(workdir: Path, path: Path = REF, out: Path = ROOT / "docs"):
    """Quadratic displacements on r^γ-graded meshes (γ = REF_P2_GRADING), (fracture_size, tip_size)
    scaled together by REF_P2_SCALES (the balanced family: compliance-type errors ∝ scale ∝
    1/unknowns); the P2 slip evaluated on the reference grid. The maximum slip and the grid fields
    are extrapolated with the rate fitted on the levels REF_P2_FIT (scale ratio 2: Richardson
    weight 1/(2^p − 1)); every level is reported (and recorded in ``<out>/cube_slip_reference.json``),
    and reused from ``workdir`` if there."""
    case = _case_without_reference(workdir)
    levels = []
    for sc in REF_P2_SCALES:
        tag = f"ref2-{sc:g}"
        if (workdir / f"{tag}.json").is_file() and (workdir / f"{tag}.npz").is_file():
            rec = json.loads((workdir / f"{tag}.json").read_text())
        else:
            rec = run_one(2, graded_ref_p2(sc), workdir, tag, case=case, field=True)
        with np.load(workdir / f"{tag}.npz") as z:
            arr = {k: z[k] for k in ("origin", "e1", "e2", "a", "b", "slip", "lambda_n")}
        m = float(np.linalg.norm(arr["slip"], axis=2).max())
        integral = _grid_integral(arr["a"], arr["b"], arr["slip"])
        print(f"reference level scale {sc:g}: {rec['mesh']['unknowns']} unknowns, max slip {m:.6e} m, "
              f"∫ slip {integral:.6e} m³, {rec['totals']['seconds']:.0f} s, "
              f"{rec['totals']['peak_memory_mb']:.0f} MB", flush=True)
        levels.append({"scale": sc, "max": m, "integral": integral, "arrays": arr,
                       "unknowns": rec["mesh"]["unknowns"], "seconds": rec["totals"]["seconds"],
                       "memory": rec["totals"]["peak_memory_mb"]})
    fit_levels = [lv for lv in levels if lv["scale"] in REF_P2_FIT]
    s3 = [lv["scale"] for lv in fit_levels]
    fit = richardson(s3, [lv["max"] for lv in fit_levels])
    fit_int = richardson(s3, [lv["integral"] for lv in fit_levels])
    if fit is None:
        raise SystemExit("the maximum slips of the fit levels do not converge monotonically with a rate in [0.2, 4]")
    m_star, p, w = fit
    print(f"maximum slip: limit {m_star:.6e} m, rate {p:.3f}, weight {w:.3f}")
    if fit_int:
        print(f"∫ slip: limit {fit_int[0]:.6e} m³, rate {fit_int[1]:.3f}")
    # the rate-p fit through every level (least squares on m* and C with p fixed), as a check
    S = np.array([lv["scale"] for lv in levels]) ** p
    for key in ("max", "integral"):
        coef, *_ = np.linalg.lstsq(np.column_stack([np.ones_like(S), -S]), [lv[key] for lv in levels], rcond=None)
        print(f"{key}: least squares over all {len(levels)} levels with rate {p:.3f}: limit {coef[0]:.6e}")
    a1, a2 = fit_levels[1]["arrays"], fit_levels[2]["arrays"]
    arrays = {**a2, "slip": a2["slip"] + w * (a2["slip"] - a1["slip"]),
              "lambda_n": a2["lambda_n"] + w * (a2["lambda_n"] - a1["lambda_n"])}
    ext_int = _grid_integral(arrays["a"], arrays["b"], arrays["slip"])
    ext_max = float(np.linalg.norm(arrays["slip"], axis=2).max())
    print(f"extrapolated grid field: max {ext_max:.6e} m, ∫ slip {ext_int:.6e} m³")
    maxima = [lv["max"] for lv in fit_levels]
    note = (f"quadratic displacements (order 2) on r^{REF_P2_GRADING:.3g}-graded tetrahedra (tip_grading "
            f"{REF_P2_GRADING:.3g}), (size, fracture_size, tip_size) = ({REF_P2_SIZES[0]:g}, {REF_P2_SIZES[1]:g} s, "
            f"{REF_P2_SIZES[2]:g} s) m, s = {', '.join(f'{x:g}' for x in s3)} "
            f"({', '.join(str(lv['unknowns']) for lv in fit_levels)} unknowns); P2 slip on the grid, "
            f"maximum slips {', '.join(f'{m:.5e}' for m in maxima)} m, fitted rate {p:.2f}, "
            f"extrapolated {m_star:.5e} m; slip and λ_n fields extrapolated the same way from the two finest "
            f"levels (benchmarks/cube_slip.py --reference --order 2)")
    print(note)
    np.savez_compressed(path, **{k: np.asarray(v, np.float64) for k, v in arrays.items()}, max_slip=m_star,
                        note=note)
    summary = {"levels": [{k: v for k, v in lv.items() if k != "arrays"} for lv in levels],
               "fit": {"max_slip": m_star, "rate": p, "weight": w,
                       "integral": fit_int[0] if fit_int else None, "integral_rate": fit_int[1] if fit_int else None},
               "extrapolated_grid": {"max": ext_max, "integral": ext_int}, "note": note}
    (out / "cube_slip_reference.json").write_text(json.dumps(summary, indent=1))
    print(f"wrote {path} and {out / 'cube_slip_reference.json'}")


def _ref_p2_34(scale: float) -> list[str]:
    return [f"mesh.size={REF_P2_SIZES[0]:.6g}", f"mesh.fracture_size={2.5 * scale:.6g}",
            f"mesh.tip_size={0.025 * scale:.6g}", "mesh.tip_grading=0.75"]


# independent P2 mesh families checking the reference: two levels each, scale ratio 2
VALIDATION = {"sqrt": ("√r-graded (tip_grading 0.5, P2_SIZES)", (0.8, 0.4), graded_p2),
              "r34": ("r^(3/4)-graded (tip_grading 0.75, size 3, (2.5, 0.025) m × s)", (0.5, 0.25), _ref_p2_34),
              "fr": ("fracture-refined (h, no tip grading, bulk 0.5)", (0.05, 0.025), uniform_p2)}


def _grid_l2(m, m_ref, a, b, inner: bool) -> float:
    """Relative L2 difference of two fields on the reference grid (whole fracture, or rim out)."""
    from polypore.cases.reference import RIM

    A, B = np.meshgrid(a / a[-1], b / b[-1], indexing="ij")
    w = np.outer(np.gradient(a), np.gradient(b))
    k = ((A > RIM) & (A < 1 - RIM) & (B > RIM) & (B < 1 - RIM)) if inner else np.ones(A.shape, bool)
    return float(np.sqrt(np.sum((w * (m - m_ref) ** 2)[k]) / np.sum((w * m_ref ** 2)[k])))


def validate_reference(workdir: Path, out: Path):
    """Each VALIDATION family's two levels extrapolated with rate 1 (Richardson weight 1) against the
    reference file: maximum slip, ∫ slip, L2 differences of the slip and λ_n fields on its grid.
    Runs reused from ``workdir``; the table is added to ``<out>/cube_slip_reference.json``."""
    from polypore.cases.reference import load_reference

    ref = load_reference("cube-slip-3d")
    m_ref = np.linalg.norm(ref.slip, axis=2)
    ref_int = _grid_integral(ref.a, ref.b, ref.slip)
    rows = []
    for key, (label, params, make) in VALIDATION.items():
        fields = []
        for par in params:
            tag = f"val-{key}-{par:g}"
            if (workdir / f"{tag}.json").is_file() and (workdir / f"{tag}.npz").is_file():
                rec = json.loads((workdir / f"{tag}.json").read_text())
            else:
                rec = run_one(2, make(par), workdir, tag, field=True)
            with np.load(workdir / f"{tag}.npz") as z:
                fields.append((rec["mesh"]["unknowns"], z["slip"], z["lambda_n"]))
        (n1, s1, l1), (n2, s2, l2) = fields
        slip, ln = 2 * s2 - s1, 2 * l2 - l1
        m = np.linalg.norm(slip, axis=2)
        row = {"family": label, "parameters": list(params), "unknowns": [n1, n2],
               "max_slip": float(m.max()), "max_slip_vs_reference": float(m.max() / ref.max_slip - 1),
               "slip_integral": _grid_integral(ref.a, ref.b, slip),
               "slip_integral_vs_reference": _grid_integral(ref.a, ref.b, slip) / ref_int - 1,
               "slip_L2_diff": _grid_l2(m, m_ref, ref.a, ref.b, False),
               "slip_L2_diff_inner": _grid_l2(m, m_ref, ref.a, ref.b, True),
               "lambda_n_L2_diff_inner": _grid_l2(ln, ref.lambda_n, ref.a, ref.b, True),
               "finest_level": {"slip_L2": _grid_l2(np.linalg.norm(s2, axis=2), m_ref, ref.a, ref.b, False),
                                "slip_L2_inner": _grid_l2(np.linalg.norm(s2, axis=2), m_ref, ref.a, ref.b, True),
                                "max_slip_error": float(np.linalg.norm(s2, axis=2).max() / ref.max_slip - 1)}}
        rows.append(row)
        print(f"{label}: {n1}, {n2} unknowns → max slip {row['max_slip']:.5e} "
              f"({100 * row['max_slip_vs_reference']:+.2f} %), "
              f"∫ slip {row['slip_integral']:.5e} ({100 * row['slip_integral_vs_reference']:+.2f} %), slip L2 "
              f"{100 * row['slip_L2_diff']:.2f} %, rim out {100 * row['slip_L2_diff_inner']:.2f} %, λ_n rim out "
              f"{100 * row['lambda_n_L2_diff_inner']:.2f} %", flush=True)
    path = out / "cube_slip_reference.json"
    summary = json.loads(path.read_text()) if path.is_file() else {}
    summary["validation"] = {"method": "each family's two levels extrapolated with rate 1 (X* = 2 X2 − X1), "
                                       "compared with the reference on its grid", "reference_integral": ref_int,
                             "families": rows}
    path.write_text(json.dumps(summary, indent=1))
    print(f"wrote {path}")


def study(workdir: Path, out: Path, quick: bool, order: int = 1):
    if order == 1:
        series = {"uniform": [(h, uniform(h)) for h in (UNIFORM[:3] if quick else UNIFORM)],
                  "tip-graded (default)": [(sc, graded(sc)) for sc in (GRADED[:3] if quick else GRADED)]}
        runner = lambda ov, tag: run(CASE, ov, workdir, tag)["summary"]  # noqa: E731
        stem = "cube_slip"
    else:
        series = {"order 1, tip-graded": [(sc, graded(sc)) for sc in GRADED[2:]],
                  "order 2, fracture-refined": [(h, uniform_p2(h)) for h in (UNIFORM_P2[:3] if quick else UNIFORM_P2)],
                  "order 2, tip-graded": [(sc, graded_p2(sc)) for sc in (GRADED_P2[:3] if quick else GRADED_P2)],
                  "order 2, r^(3/4)-graded": [(sc, graded_p2_34(sc))
                                              for sc in (GRADED_P2_34[:3] if quick else GRADED_P2_34)]}
        stem = "cube_slip_p2"
    keys = ("max_slip_error_rel", "slip_L2_rel", "slip_L2_rel_inner", "lambda_n_L2_rel_inner")
    results = {}
    for name, levels in series.items():
        rows = []
        if order == 2:
            k = 1 if name.startswith("order 1") else 2
            runner = lambda ov, tag, k=k: run_one(k, ov, workdir, tag)  # noqa: E731
        for par, ov in levels:
            s = runner(ov, "".join(c if c.isalnum() else "-" for c in name) + f"-{par}")
            rec = {"parameter": par, "unknowns": s["mesh"]["unknowns"], "cells": s["mesh"]["cells"],
                   "seconds": s["totals"]["seconds"], "peak_memory_mb": s["totals"]["peak_memory_mb"],
                   "newton": s["steps"][0]["newton_iterations"], **s["errors"],
                   "slip_integral": s.get("slip_integral"),
                   **{f"field_{k}": v for k, v in s.get("field_errors", {}).items()}}
            rows.append(rec)
            print(f"{name:22s} {par:<6g} {rec['unknowns']:7d} unknowns  max slip {rec['max_slip']:.4e} "
                  + " ".join(f"{k} {100 * rec[k]:.2f}%" for k in keys)
                  + ("  field: " + " ".join(f"{k} {100 * rec['field_' + k]:.2f}%" for k in keys[:3])
                     if "field_max_slip" in rec else "")
                  + f"  open {rec['open_faces']}  {rec['seconds']:.1f} s {rec['peak_memory_mb']:.0f} MB", flush=True)
        n = np.array([r["unknowns"] for r in rows], float)
        rates = ({k: float(-np.polyfit(np.log(n), np.log([r[k] for r in rows]), 1)[0]) for k in keys}
                 if len(rows) > 1 else {})
        results[name] = {"runs": rows, "rates_per_unknown": rates}
    (out / f"{stem}.json").write_text(json.dumps({"series": results}, indent=1))
    report(out, stem, order)


def _record(s: dict, par) -> dict:
    """One row of a series from a run's record."""
    return {"parameter": par, "unknowns": s["mesh"]["unknowns"], "cells": s["mesh"]["cells"],
            "fracture_faces": s["mesh"].get("fracture_faces"),
            "seconds": s["totals"]["seconds"], "peak_memory_mb": s["totals"]["peak_memory_mb"],
            "newton": s["steps"][0]["newton_iterations"], **s["errors"],
            "slip_integral": s.get("slip_integral"), "field_max_slip": s.get("field_max_slip"),
            **{f"field_{k}": v for k, v in s.get("field_errors", {}).items()}}


def anisotropic_study(workdir: Path, out: Path, quick: bool):
    """Order 2 (and 1) on anisotropic crack-front meshes, the case's default mesh, and one-knob variants:
    ``<out>/cube_slip_anisotropic.{json,md,png}``."""
    series = {"order 2, anisotropic fronts": [(sc, 2, anisotropic(sc)) for sc in (ANISO[:4] if quick else ANISO)],
              "order 1, anisotropic fronts": [(sc, 1, anisotropic(sc)) for sc in (ANISO_P1[:2] if quick else ANISO_P1)],
              # the case file as it was (P2 on its r^0.6-graded isotropic mesh): tip_grading 0.6 restored
              "order 2, isotropic r^0.6 (the case's former default)": [(1, 2, ["mesh.tip_grading=0.6"])]}
    keys = ("max_slip_error_rel", "slip_L2_rel", "slip_L2_rel_inner")
    results, variants = {}, []

    def show(name, rec):
        f = ("  field: " + " ".join(f"{100 * rec['field_' + k]:.2f}%" for k in keys)
             if rec.get("field_" + keys[0]) else "")
        print(f"{name:40s} {rec['parameter']:<5g} {rec['unknowns']:7d} unknowns  "
              + " ".join(f"{k} {100 * rec[k]:.2f}%" for k in keys + ("lambda_n_L2_rel_inner",)) + f
              + f"  {rec['seconds']:.1f} s {rec['peak_memory_mb']:.0f} MB", flush=True)

    for name, levels in series.items():
        rows = []
        for par, order, ov in levels:
            tag = "".join(c if c.isalnum() else "-" for c in name) + f"-{par}"
            rows.append(_record(run_one(order, ov, workdir, tag), par))
            show(name, rows[-1])
        n = np.array([r["unknowns"] for r in rows], float)
        rates = ({k: float(-np.polyfit(np.log(n), np.log([r[k] for r in rows]), 1)[0])
                  for k in keys + ("lambda_n_L2_rel_inner",)} if len(rows) > 1 else {})
        results[name] = {"runs": rows, "rates_per_unknown": rates}
    if not quick:
        for label, (sc, change) in ANISO_VARIANTS.items():
            rec = _record(run_one(2, anisotropic(sc, **change), workdir, f"aniso-variant-{len(variants)}"), sc)
            rec["variant"], rec["change"] = label, change
            variants.append(rec)
            show(label, rec)
    stem = "cube_slip_anisotropic"
    (out / f"{stem}.json").write_text(json.dumps({"series": results, "variants": variants}, indent=1))
    report(out, stem, 2)
    plot_anisotropic_mesh(out / f"{stem}_mesh.png")


def _limit(runs, key) -> dict | None:
    """The limit of ``key`` over a series' levels (parameter → 0): with rate 1 from the two finest
    (the crack-front cells, of size ∝ the parameter in every family here, leave an error ∝ the
    parameter in compliance-type quantities: docs/accuracy_3d.md), and with the rate fitted on the
    three finest (None if not monotone)."""
    if len(runs) < 3 or any(r.get(key) is None for r in runs):
        return None
    (s1, m1), (s2, m2) = [(r["parameter"], r[key]) for r in runs[-2:]]
    fit = richardson([r["parameter"] for r in runs[-3:]], [r[key] for r in runs[-3:]])
    return {"finest": m2, "limit_rate1": m2 + s2 / (s1 - s2) * (m2 - m1),
            "limit": fit[0] if fit else None, "rate": fit[1] if fit else None}


def report(out: Path, stem: str, order: int):
    """Limits, table and plot from ``<out>/<stem>.json`` against the current reference (``--report``
    redoes them without running anything)."""
    from polypore.cases.reference import load_reference

    data = json.loads((out / f"{stem}.json").read_text())
    results = data["series"]
    ref = load_reference("cube-slip-3d")
    # |∫_Γ [[u]]_τ| of the reference (trapezoid rule on its grid) and of each series extrapolated,
    # and the P2 maximum slip (point values) extrapolated: the limits compared directly
    ref_int = float(np.linalg.norm(np.trapezoid(np.trapezoid(ref.slip, ref.b, axis=1), ref.a, axis=0)))
    extra = {"slip_integral": {"reference": ref_int}, "p2_limit": {}}
    for name, res in results.items():
        extra["slip_integral"][name] = _limit(res["runs"], "slip_integral")
        if order == 2 and name.startswith("order 2"):
            extra["p2_limit"][name] = _limit(res["runs"], "field_max_slip")
    print("slip integrals:", extra["slip_integral"])
    keep = {k: v for k, v in data.items() if k in ("variants",)}
    (out / f"{stem}.json").write_text(json.dumps({"reference": {"max_slip": ref.max_slip, "note": ref.note},
                                                  "series": results, **extra, **keep}, indent=1))
    _table(out / f"{stem}.md", results, ref, order, extra["p2_limit"], extra["slip_integral"], stem=stem,
           variants=data.get("variants"))
    if stem == "cube_slip_anisotropic":
        compare = {}
        for source, names in (("cube_slip_p2", ("order 2, tip-graded", "order 2, r^(3/4)-graded")),
                              ("cube_slip", ("tip-graded (default)",))):
            if (out / f"{source}.json").is_file():
                # the isotropic series of docs/cube_slip_p2.md and docs/cube_slip.md (not rerun)
                old = json.loads((out / f"{source}.json").read_text())["series"]
                compare.update({f"{k}, isotropic ({source}.md)": v for k, v in old.items() if k in names})
        _plot_anisotropic(out / f"{stem}.png", results, compare)
    else:
        _plot(out / f"{stem}.png", results)
    print(f"wrote {out / stem}.json, .md, .png")


# What moves the error and what does not (one mesh family each, everything else fixed)
DIAGNOSIS = {
    "uniform h = 0.1": uniform(0.1),
    "  stabilisation × 0.1": uniform(0.1) + ["mechanics.stabilisation=0.1"],
    "  stabilisation × 3": uniform(0.1) + ["mechanics.stabilisation=3"],
    "  two-sided bubbles": uniform(0.1) + ["mechanics.bubbles=two-sided"],
    "  β × 10": uniform(0.1) + ["contact.beta=10"],
    "size 0.2, fracture_size 0.05, no tip refinement": ["mesh.size=0.2", "mesh.fracture_size=0.05",
                                                        "mesh.tip_size=1e9"],
    "  tip_size 0.01 (√r-graded fronts)": ["mesh.size=0.2", "mesh.fracture_size=0.05", "mesh.tip_size=0.01"],
    "  fracture_size 0.035 instead": ["mesh.size=0.2", "mesh.fracture_size=0.035", "mesh.tip_size=1e9"],
}


def diagnose(workdir: Path, out: Path):
    rows = []
    for name, ov in DIAGNOSIS.items():
        s = run(CASE, ov, workdir, f"diag-{len(rows)}")["summary"]
        rec = {"variant": name, "unknowns": s["mesh"]["unknowns"], **s["errors"]}
        rows.append(rec)
        print(f"{name:50s} {rec['unknowns']:7d} unknowns  max slip {rec['max_slip']:.4e}  slip L2 rim out "
              f"{100 * rec['slip_L2_rel_inner']:.1f} %  λ_n {100 * rec['lambda_n_L2_rel_inner']:.1f} %", flush=True)
    (out / "cube_slip_diagnosis.json").write_text(json.dumps(rows, indent=1))
    lines = ["Command: `.venv/bin/python benchmarks/cube_slip.py --diagnose`.", "",
             "| variant | unknowns | max slip (1e-5 m) | max-slip error | slip L2, rim out | λ_n L2, rim out | open |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['variant'].strip()} | {r['unknowns']:,} | {1e5 * r['max_slip']:.3f} | "
              f"{100 * r['max_slip_error_rel']:.1f} % | {100 * r['slip_L2_rel_inner']:.1f} % | "
              f"{100 * r['lambda_n_L2_rel_inner']:.1f} % | {r['open_faces']} |" for r in rows]
    (out / "cube_slip_diagnosis.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'cube_slip_diagnosis.md'}")


def _table(path, results, ref, order=1, limit=None, integrals=None, stem=None, variants=None):
    cmd, fig = (("", "cube_slip") if order == 1 else (" --order 2", "cube_slip_p2"))
    if stem == "cube_slip_anisotropic":
        cmd, fig = " --anisotropic", stem
    fkeys = ("max_slip_error_rel", "slip_L2_rel", "slip_L2_rel_inner")
    head = ("| mesh | parameter | unknowns | max slip (1e-5 m) | max-slip error | slip L2 | slip L2, rim out | "
            "λ_n L2, rim out | open faces | wall | peak memory |")
    if order == 2:
        head += " field: max-slip error | field: slip L2 | field: slip L2, rim out |"
    lines = [f"Command: `.venv/bin/python benchmarks/cube_slip.py{cmd}` (figures in `docs/{fig}.json`).", "",
             f"Reference: {ref.note}.", "", head, "|---" * (head.count("|") - 1) + "|"]
    pct = lambda v: "–" if v is None else f"{100 * v:.1f} %"  # noqa: E731
    for name, res in results.items():
        for r in res["runs"]:
            row = (f"| {name} | {r['parameter']:g} | {r['unknowns']:,} | {1e5 * r['max_slip']:.3f} | "
                   f"{100 * r['max_slip_error_rel']:.1f} % | {100 * r['slip_L2_rel']:.1f} % | "
                   f"{100 * r['slip_L2_rel_inner']:.1f} % | {100 * r['lambda_n_L2_rel_inner']:.1f} % | "
                   f"{r['open_faces']} | {r['seconds']:.1f} s | {r['peak_memory_mb']:.0f} MB |")
            if order == 2:
                row += "".join(f" {pct(r.get('field_' + k))} |" for k in fkeys)
            lines.append(row)
        rt = res["rates_per_unknown"]
        if rt:
            lines.append(f"| {name}: rate per unknown | | | | {rt['max_slip_error_rel']:.2f} | "
                         f"{rt['slip_L2_rel']:.2f} | {rt['slip_L2_rel_inner']:.2f} | "
                         f"{rt['lambda_n_L2_rel_inner']:.2f} | | | |"
                         + (" | | |" if order == 2 else ""))
    lines.append("")
    if stem == "cube_slip_anisotropic":
        lines.append("Parameter: the scale s of (fracture_size, tip_size) = "
                     f"({ANISO_SIZES['fracture_size']}, {ANISO_SIZES['tip_size']}) m × s with mesh.front = "
                     f"\"anisotropic\", size {ANISO_SIZES['size']} m, grading {ANISO_SIZES['grading']}, "
                     f"tip_grading {ANISO_SIZES['tip_grading']} (order 1 on the same meshes; scale 1 is the case's default "
                     "since 2026-11-24); the case's former default: order 2, size 1, fracture_size 0.8, tip_size 0.02, "
                     "grading 0.4, tip_grading 0.6, isotropic. Rates are −d log(error)/d log(unknowns). Wall: mesh, set-up and solve. \"field\": "
                     "the P2 slip at the 6 points of a face rule per fracture face (the case's own measure for "
                     "order 2) instead of the face means.")
        if variants:
            lines += ["", "Variants (order 2; one knob changed from the series' values at the scale given):", "",
                      "| variant | unknowns | field: max-slip error | field: slip L2 | field: slip L2, rim out | "
                      "λ_n L2, rim out | ∫ slip vs reference | wall | peak memory |", "|---" * 9 + "|"]
            ref_int = float(np.linalg.norm(np.trapezoid(np.trapezoid(ref.slip, ref.b, axis=1), ref.a, axis=0)))
            for r in variants:
                lines.append(f"| {r['variant']} | {r['unknowns']:,} | {pct(r.get('field_max_slip_error_rel'))} | "
                             f"{pct(r.get('field_slip_L2_rel'))} | {pct(r.get('field_slip_L2_rel_inner'))} | "
                             f"{100 * r['lambda_n_L2_rel_inner']:.1f} % | "
                             f"{100 * (r['slip_integral'] / ref_int - 1):+.1f} % | {r['seconds']:.1f} s | "
                             f"{r['peak_memory_mb']:.0f} MB |")
    elif order == 1:
        lines.append("Parameter: h (m) for the uniform meshes; the scale of (size, fracture_size, tip_size) = "
                     "(0.3, 0.08, 0.015) m for the graded ones. Rates are −d log(error)/d log(unknowns).")
    else:
        lines.append("Parameter: the scale of (size, fracture_size, tip_size) = (0.3, 0.08, 0.015) m for order 1 (the "
                     "case's family, as in docs/cube_slip.md); "
                     f"fracture_size h (m, bulk size {P2_SIZES[0]} m, no tip grading) for the fracture-refined "
                     "P2 meshes; "
                     f"the scale of (fracture_size, tip_size) = {P2_SIZES[1:]} m (bulk size {P2_SIZES[0]} m) for the "
                     "tip-graded ones (√r law, mesh.tip_grading 0.5, the generator's default); the scale of "
                     f"(fracture_size, tip_size) = {P2_34_SIZES[1:3]} m (bulk size {P2_34_SIZES[0]:g} m, never "
                     "reached) "
                     f"with mesh.tip_grading = {P2_34_SIZES[3]} for the r^(3/4)-graded ones. "
                     "Rates are −d log(error)/d log(unknowns). Wall: mesh, set-up and solve. "
                     "\"field\": the P2 slip at the 6 points of a face rule per fracture face (its maximum, and "
                     "L2 norms by that rule) instead of the face means.")
    integrals = integrals or {}
    if len(integrals) > 1:
        lines += ["", "Limits of each series (parameter → 0): with rate 1 in the parameter from the two finest "
                  "levels (the error the crack-front cells leave, docs/accuracy_3d.md), and with the rate fitted on the "
                  "three finest (noisy: every level is a new unstructured mesh)."]

    def lim_text(lim, scale, unit, refv):
        if not lim:
            return "too few levels."
        t = (f"{scale * lim['finest']:.4f}{unit} on the finest mesh; rate 1: {scale * lim['limit_rate1']:.4f}{unit} "
             f"({100 * (lim['limit_rate1'] / refv - 1):+.2f} %)")
        if lim["limit"] is not None:
            t += (f"; fitted rate {lim['rate']:.2f}: {scale * lim['limit']:.4f}{unit} "
                  f"({100 * (lim['limit'] / refv - 1):+.2f} %)")
        return t + " from the reference's " + f"{scale * refv:.4f}{unit}."

    for name, lim in integrals.items():
        if name != "reference" and (lim or stem != "cube_slip_anisotropic"):
            lines += ["", f"{name}: |∫_Γ [[u]]_τ| = " + lim_text(lim, 1e6, "e-6 m³", integrals["reference"])]
    if order == 2:
        for name, lim in (limit or {}).items():
            if lim or stem != "cube_slip_anisotropic":
                lines += ["", f"{name}: maximum slip (point values) = " + lim_text(lim, 1e5, "e-5 m", ref.max_slip)]
    path.write_text("\n".join(lines) + "\n")


def _plot(path, results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for (name, res), mk, c in zip(results.items(), ("s--", "o-", "^-", "v-"), ("C0", "C1", "C2", "C3")):
        n = [r["unknowns"] for r in res["runs"]]
        axes[0].loglog(n, [100 * r["max_slip_error_rel"] for r in res["runs"]], mk, color=c, label=name)
        axes[1].loglog(n, [100 * r["slip_L2_rel_inner"] for r in res["runs"]], mk, color=c, label=name)
        if "field_max_slip_error_rel" in res["runs"][0]:     # order 2: the slip as a field, dotted
            axes[0].loglog(n, [100 * r["field_max_slip_error_rel"] for r in res["runs"]], mk[0] + ":", color=c,
                           mfc="none", label=f"{name} (field)")
            axes[1].loglog(n, [100 * r["field_slip_L2_rel_inner"] for r in res["runs"]], mk[0] + ":", color=c,
                           mfc="none", label=f"{name} (field)")
    from matplotlib.ticker import FuncFormatter, NullFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for ax, title in zip(axes, ("maximum slip", "slip profile, rim left out (relative L2)")):
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(plain if len(results) < 3 else NullFormatter())
        _target_axes(ax, title)
        ax.legend(fontsize="small")
    fig.suptitle("cube-slip-3d: error against unknowns (dotted: 3 % at 20,000 unknowns)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def plot_anisotropic_mesh(path: Path, scale: float = 1.0):
    """The fracture faces of the scale-``scale`` anisotropic mesh (in the fracture's plane) and its ring
    (the triangulation of the plane normal to a front that every edge sweeps)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from polypore.mesh.generators.fronts import RING_RADIUS, SECTORS, polar_ring, ring_radii
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh

    fm = build_fractured_mesh(load_case(str(CASE), anisotropic(scale)))
    mesh, net = fm.mesh, fm.network
    F = mesh.face_nodes.take(net.faces).values.reshape(-1, 3)
    R = mesh.nodes - ORIGIN
    P = np.stack([R @ E1, R @ E2], axis=1)
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), gridspec_kw={"width_ratios": [1.3, 1]})
    axes[0].triplot(P[:, 0], P[:, 1], F, lw=0.5, color="C0")
    axes[0].set_aspect(1)
    axes[0].set_xlabel("x − 0.2 (m), along the fronts y = z = 0.3 and 0.7")
    axes[0].set_ylabel("distance along the plane from y = z = 0.3 (m)")
    axes[0].set_title(f"fracture faces, scale {scale:g} ({net.n_faces} faces, {mesh.n_cells} cells)")
    fsize = ANISO_SIZES["fracture_size"] * scale
    rho = RING_RADIUS * fsize
    radii = ring_radii(rho, ANISO_SIZES["tip_size"] * scale, ANISO_SIZES["tip_grading"])
    X, T = polar_ring(rho, SECTORS, radii / rho)
    axes[1].triplot(X[:, 0], X[:, 1], T, lw=0.6, color="C0")
    axes[1].plot([-rho, 0], [0, 0], "r-", lw=2, label="fracture")
    axes[1].set_aspect(1)
    axes[1].set_xlabel("o (m): in-plane distance out of the fracture")
    axes[1].set_ylabel("n (m): along the fracture normal")
    axes[1].set_title(f"ring ρ = {rho:.3g} m, radii {', '.join(f'{r:.2g}' for r in radii)} m")
    axes[1].legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def _plot_anisotropic(path, results, compare):
    """Maximum slip, slip L2 and slip L2 rim out against unknowns: the anisotropic series (the P2
    errors as fields), and the isotropic series of the other studies (grey, from their JSON)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, NullFormatter

    keys = (("max_slip_error_rel", "maximum slip"), ("slip_L2_rel", "slip profile (relative L2)"),
            ("slip_L2_rel_inner", "slip profile, rim left out"))
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.3))
    styles = [("s-", "C0"), ("o-", "C1"), ("*", "C2")]
    grey = [("x:", "0.35"), ("+:", "0.6"), ("d:", "0.75")]
    curves = [(n, r, st) for (n, r), st in zip(results.items(), styles)] + \
             [(n, r, st) for (n, r), st in zip(compare.items(), grey)]
    for name, res, (mk, c) in curves:
        n = [r["unknowns"] for r in res["runs"]]
        for ax, (k, _) in zip(axes, keys):
            # order 2: the slip as a field (the case's measure); order 1 and older P1 runs: face means
            y = [100 * r.get("field_" + k, r[k]) if r.get("field_" + k) is not None else 100 * r[k]
                 for r in res["runs"]]
            ax.loglog(n, y, mk, color=c, label=name, ms=9 if mk == "*" else 6)
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for ax, (_, title) in zip(axes, keys):
        ax.set_yticks([1, 2, 3, 5, 10, 20, 30])
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(NullFormatter())
        _target_axes(ax, title)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize="small", frameon=False)
    fig.suptitle("cube-slip-3d: anisotropic crack-front meshes against isotropic grading "
                 "(dotted lines: 3 % and 20,000 unknowns)")
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", action="store_true", help="remake the fine-mesh reference file")
    ap.add_argument("--quick", action="store_true", help="three coarsest levels of each series only")
    ap.add_argument("--diagnose", action="store_true", help="what changes the error: stabilisation, bubbles, "
                    "β, tip grading, fracture size")
    ap.add_argument("--order", type=int, choices=(1, 2), default=1,
                    help="displacement order: 2 = quadratic on tetrahedra (its own mesh series)")
    ap.add_argument("--anisotropic", action="store_true", help="anisotropic crack-front meshes (mesh.front = "
                    "\"anisotropic\"), orders 2 and 1, against the case's default mesh (~7 min)")
    ap.add_argument("--one", metavar="JSON", help="internal: one in-process run of the case, record to JSON")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="with --one: case overrides")
    ap.add_argument("--case", default=str(CASE), help="with --one: another built-in static case (e.g. penny-inclined)")
    ap.add_argument("--field", metavar="NPZ", help="with --one: also save the slip field (for a reference)")
    ap.add_argument("--out", default=str(ROOT / "docs"))
    ap.add_argument("--validate", action="store_true", help="with --reference --order 2: check the reference "
                    "against three other P2 mesh families (~10 min)")
    ap.add_argument("--report", action="store_true", help="redo the table and plot of <out>/cube_slip[_p2].json "
                    "(with --order 2) against the current reference, without running")
    ap.add_argument("--ref-out", default=str(REF), help="with --reference --order 2: where to write the reference")
    ap.add_argument("--workdir", help="keep the runs here (default: a temporary folder)")
    args = ap.parse_args()
    if args.one:
        one(Path(args.one), args.order, args.set, args.case, Path(args.field) if args.field else None)
        return
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="cube-slip-") as tmp:
        work = Path(args.workdir or tmp)
        work.mkdir(parents=True, exist_ok=True)
        if args.report:
            if args.anisotropic:
                report(out, "cube_slip_anisotropic", 2)
                plot_anisotropic_mesh(out / "cube_slip_anisotropic_mesh.png")
            else:
                report(out, "cube_slip" if args.order == 1 else "cube_slip_p2", args.order)
        elif args.anisotropic:
            anisotropic_study(work, out, args.quick)
        elif args.reference:
            if args.order == 2 and args.validate:
                validate_reference(work, out)
            elif args.order == 2:
                make_reference_p2(work, Path(args.ref_out), out)
            else:
                make_reference(work)
        elif args.diagnose:
            diagnose(work, out)
        else:
            study(work, out, args.quick, args.order)


if __name__ == "__main__":
    main()
