"""What the output names mean: the arrays of the VTU files, the columns of fractures.csv, the
error measures of summary.json and the contact-state codes, in one place.

Every run writes this legend into its folder, as ``summary.json``'s ``legend`` and as
``README.txt`` (issue 25: names like ``lambda_n_h12`` and an integer ``state`` appeared without
a word of what they are). docs/outputs.md is the same text for readers of the documentation;
tests/unit/io/test_legend.py checks that every name a run writes is described here.
"""

from __future__ import annotations

from pathlib import Path

from ..models.contact import STATE_NAMES
from .atomic import atomic_write_text
from .results import CSV_COLUMNS

# contact state per fracture face (the ``state`` arrays and columns)
STATES = {str(code): name for code, name in enumerate(STATE_NAMES)}
STATE_MEANING = {"open": "the faces are apart: no contact traction (λ = 0)",
                 "stick": "closed, |λ_τ| < F λ_n: no slip increment",
                 "slip": "closed, |λ_τ| = F λ_n (Coulomb) or the threshold (Tresca): the faces slide"}

BULK = {
    "region": "index of the cell's material region (0 for a single region)",
    "displacement": "displacement u (m), 3 components (z = 0 in 2D): per cell, and per node as point data "
                    "(the array ParaView's Warp By Vector uses)",
    "stress": "Cauchy stress σ (Pa); 3D: the 6 components xx yy zz xy yz xz of a symmetric tensor; 2D: a 3×3 "
              "tensor (9 components, row by row) whose z row and column are zero (σ_zz is not computed)",
    "von_mises": "von Mises stress √(3/2 s:s) of the deviator s of σ (Pa; 2D: of the in-plane tensor)",
    "effective_stress": "effective stress σ' (Pa), laid out as stress",
    "total_stress": "total stress σ' − b p I (Pa), laid out as stress",
    "pressure": "matrix pressure (Pa); poromechanics: absolute, the hydrostatic pressure added when the case has "
                "[initial_state]",
    "overpressure": "p − p⁰, the matrix pressure's change since the start of the run (Pa)",
    "darcy_velocity": "Darcy velocity −(K/η) ∇p per cell (m/s)",
    "pressure_exact": "the exact solution's pressure at the cell centroid (Pa)",
    "pressure_error": "pressure − pressure_exact (Pa)",
}
FRACTURES = {
    "fracture": "index of the face's fracture in the case's [[fractures]] order (summary.json and fractures.csv "
                "give the names)",
    "normal": "unit normal n⁺ of the face, from its + side into its − side",
    "jump": "displacement jump [[u]] = u⁺ − u⁻ across the face (m)",
    "jump_n": "normal jump [[u]]·n⁺ (m): negative where the fracture is open (the opening is −jump_n)",
    "jump_t": "|[[u]]_τ|, the length of the tangential jump (m): the slip",
    "lambda": "contact traction λ, the Lagrange multiplier of the contact conditions (Pa)",
    "lambda_n": "normal contact traction λ·n⁺ (Pa): positive in compression, zero where open",
    "lambda_t": "|λ_τ|, the length of the tangential (shear) contact traction (Pa)",
    "state": "contact state code: " + ", ".join(f"{k} {v}" for k, v in STATES.items()),
    "aperture": "hydraulic aperture d_f of the face (m)",
    "p_f": "fracture pressure (Pa); poromechanics with [initial_state]: relative to the hydrostatic pressure",
    "first_slip": "time the face first slipped (s); NaN: not yet",
    "slip_path": "slip-weakening: the slip path δ, the length of the tangential jump's increments summed over the "
                 "steps (m)",
    "friction_coefficient": "slip-weakening: the friction coefficient F(δ) at the face's slip path; rate-and-state: "
                            "μ(V, θ) at the face's slip rate and state (–)",
    "state_theta": "rate-and-state: the state variable θ of the face (s; D_c/V at steady sliding)",
    "slip_rate": "rate-and-state: the face's slip rate V over the last time step (m/s)",
    "delta_cfs": "Coulomb failure stress change since the start ΔCFS = Δτ − μ Δσ_n′ (Pa; τ = |λ_τ|, σ_n′ = λ_n, μ "
                 "the law's static coefficient: friction, f0 for rate-and-state, 0 for Tresca); > 0: towards failure",
    "slip_tendency": "slip tendency τ/σ_n′ = |λ_τ|/λ_n (–); NaN where the face is open",
    "delta_tau": "Δτ, the change of |λ_τ| since the start (Pa)",
    "delta_sigma_n": "Δσ_n′, the change of λ_n since the start (Pa; > 0: more compression)",
    "trace_plus": "matrix pressure on the face's + side (Pa)",
    "trace_minus": "matrix pressure on the face's − side (Pa)",
    "exchange": "matrix → fracture flux through both sides per unit face area (m/s)",
}
CSV = {
    "step": "output number (0: the initial state)", "time": "time (s)", "fracture": "fracture name",
    "face": "face number within the run's fracture faces", "x": "face centroid x (m)", "y": "face centroid y (m)",
    "z": "face centroid z (m; empty in 2D)", "s": "2D: arc length along the fracture from its first vertex (m)",
    "area": "face area (m², 2D: length in m)", "jump_n": FRACTURES["jump_n"], "jump_t": FRACTURES["jump_t"],
    "jump_x": "x component of [[u]] (m)", "jump_y": "y component of [[u]] (m)",
    "jump_z": "z component of [[u]] (m; empty in 2D)", "lambda_n": FRACTURES["lambda_n"],
    "lambda_t": FRACTURES["lambda_t"], "state": "contact state: open, stick or slip (empty in flow runs)",
    "aperture": FRACTURES["aperture"] + " (empty in mechanics runs)",
    "p_f": FRACTURES["p_f"] + " (empty in mechanics runs)",
    "delta_cfs": FRACTURES["delta_cfs"] + " (empty in mechanics and flow runs)",
    "slip_tendency": FRACTURES["slip_tendency"] + " (empty in mechanics and flow runs)",
}
assert set(CSV) == set(CSV_COLUMNS)
# the arrays each run driver writes besides region / fracture / normal (tests/unit/io/test_legend.py
# compares them with the files)
POROMECHANICS_ARRAYS = (("pressure", "overpressure", "displacement", "effective_stress", "total_stress"),
                        ("jump", "jump_n", "jump_t", "lambda", "lambda_n", "lambda_t", "state", "aperture", "p_f",
                         "first_slip", "delta_cfs", "slip_tendency", "delta_tau", "delta_sigma_n"))

# error measures (summary.json "errors", convergence.csv/json): names are built from parts
_QUANTITY = {"grad_u": "the displacement gradient ∇u", "lambda": "the contact traction λ",
             "lambda_n": "the normal contact traction λ_n", "slip": "the slip |[[u]]_τ|",
             "slip_vector": "the tangential jump [[u]]_τ (vector)", "opening": "the opening −[[u]]_n",
             "jump": "the displacement jump [[u]]", "traction_n": "the normal traction from the averaged "
             "one-sided stresses", "p_cell": "the cell pressures", "p_fracture": "the fracture pressures",
             "p_trace": "the pressure traces on both sides of the fractures", "grad_p": "the pressure gradient"}
_NORM = {"L2": "discrete L2 norm of the error (cell volumes or face areas as weights)",
         "h12": "h^½-weighted discrete L2 norm of the error on the fractures (a stand-in for the H^-½ norm)",
         "mean": "difference of the area means", "centre": "error at the centre"}
_SUFFIX = {"rel": "relative to the exact solution's norm", "away_from_tips": "faces farther than 0.1 ℓ from "
           "the crack tips", "away_from_rim": "faces away from the crack rim", "inner": "faces away from the "
           "fracture edges"}
_OTHER = {"max_slip": "largest slip |[[u]]_τ| (m)", "max_slip_error_rel": "relative error of the largest slip",
          "open_faces": "fracture faces in the open state", "faces": "fracture faces compared",
          "faces_away_from_rim": "faces away from the crack rim", "faces_open": "faces open",
          "faces_stick": "faces sticking", "faces_slip": "faces slipping",
          "faces_wrong_state": "faces whose state differs from the exact solution's",
          "exact_opening_max": "the exact largest opening (m)", "exact_slip_max": "the exact largest slip (m)",
          "exact_lambda_n": "the exact normal traction (Pa)",
          "lambda_n_max_over_load": "largest λ_n over the net opening load",
          "slip_direction_deg_mean": "mean angle between the computed and the exact slip directions (°)",
          "slip_direction_deg_max_away_from_rim": "largest angle between the computed and the exact slip "
          "directions away from the rim (°)"}


def describe_error(name: str) -> str:
    """What an error measure ``name`` is (``lambda_n_h12``: "h^½-weighted discrete L2 norm of the
    error on the fractures ... of the normal contact traction λ_n"); "" if the name is unknown."""
    if name in _OTHER:
        return _OTHER[name]
    for quantity in sorted(_QUANTITY, key=len, reverse=True):
        if not name.startswith(quantity + "_"):
            continue
        rest = name[len(quantity) + 1:]
        norm = next((n for n in _NORM if rest == n or rest.startswith(n + "_")), None)
        if norm is None:
            continue
        rest = rest[len(norm):].lstrip("_")
        extra = []
        while rest:
            part = next((s for s in _SUFFIX if rest == s or rest.startswith(s + "_")), None)
            if part is None:
                break
            extra.append(_SUFFIX[part])
            rest = rest[len(part):].lstrip("_")
        if rest:
            continue
        return f"{_NORM[norm]} of {_QUANTITY[quantity]}" + "".join(f"; {e}" for e in extra)
    return ""


def run_legend(bulk=(), fractures=(), errors=()) -> dict:
    """The legend of one run: the meaning of its bulk and fracture VTU arrays, of fractures.csv's
    columns, of its error measures and of the contact-state codes (summary.json's ``legend``)."""
    out = {"documentation": "docs/outputs.md",
           "state": {**STATES, "meaning": STATE_MEANING}}
    if bulk:
        out["bulk_vtu"] = {k: BULK.get(k, "") for k in ("region", *bulk)}
    if fractures:
        out["fractures_vtu"] = {k: FRACTURES.get(k, "") for k in ("fracture", "normal", *fractures)}
        out["fractures_csv"] = dict(CSV)
    if errors:
        out["errors"] = {k: describe_error(k) for k in errors}
    return out


def write_legend(stage: Path, summary: dict, bulk=(), fractures=()) -> None:
    """Put the run's legend into ``summary`` (its ``legend``) and write it as README.txt."""
    legend = run_legend(bulk, fractures, summary.get("errors") or ())
    summary["legend"] = legend
    lines = ["What the files of this run hold (all names: docs/outputs.md in polypore's sources).", "",
             "Contact state codes (the state arrays and column): " +
             ", ".join(f"{k} = {v}" for k, v in STATES.items()) + "."]
    lines += [f"  {v}: {STATE_MEANING[v]}" for v in STATES.values()]
    for key, title in (("bulk_vtu", "bulk_NNNN.vtu (cell data)"), ("fractures_vtu", "fractures_NNNN.vtu (cell data, "
                                                                                    "one cell per fracture face)"),
                       ("fractures_csv", "fractures.csv (one row per fracture face and output time)"),
                       ("errors", "summary.json errors (against the exact or reference solution)")):
        if key in legend:
            lines += ["", title + ":"] + [f"  {k}: {v}" for k, v in legend[key].items()]
    atomic_write_text(Path(stage) / "README.txt", "\n".join(lines) + "\n")
