"""Schema of the mechanics tables: ``[material]``, ``[[materials]]``, ``[mechanics]`` with its
``[[mechanics.boundary]]`` blocks, ``[contact]`` (SI units).

Values that vary in space or time are expressions of x, y, z, t (:mod:`polypore.core.expressions`),
parsed when the case is set up on its mesh; here they are checked to be a finite number or a text.
"""

from __future__ import annotations

import re
from typing import Any, Annotated

from pydantic import Field, PlainValidator, WithJsonSchema, model_validator
from pydantic_core import PydanticCustomError

from ...models.contact import PATCH_RATIO
from ...models.friction import LAW_KEYS, LAWS

# the rate-and-state keys of [contact] that are one value for the case, not per face
RATE_STATE_OPTIONS = ("state_law", "shear_wave_speed", "radiation_damping", "stick_rate", "initial_state_from",
                      "seismic_rate")
from .types import (Expr, ExprTensor, ExprVector, ExprVectorOrExact, Positive, Table, Text, choice, fail, finite,
                    is_number, number, show)

# corner-point grids: a material value from a cell keyword of the grid ("grdecl:YMODULUS")
GRDECL_KEYWORD = re.compile(r"grdecl:([A-Za-z][A-Za-z0-9_]{0,7})")
_NUMBERS = {"E": (number(gt=0), "a positive number (Pa)"), "nu": (number(gt=-1, lt=0.5), "a number in (−1, 0.5)")}


def _cell_value(name: str):
    """E or ν: a number; on corner-point grids also "grdecl:KEYWORD" (one value per cell) or a
    table `value of [material] keyword` -> number (e.g. { 0 = 2e10, 1 = 1e10 } by FACIES)."""
    number_type, what = _NUMBERS[name]
    plain = number_type.__metadata__[0].func               # the number's own check (and its messages)
    number_schema = number_type.__metadata__[1].json_schema

    def check(v):
        if isinstance(v, str):
            if GRDECL_KEYWORD.fullmatch(v.strip()):
                return v.strip()
            if not v.strip().lower().startswith("grdecl"):
                return plain(v)                            # "expected a positive number, got '1e9'"
            fail(f"must be {what}, \"grdecl:KEYWORD\" (a cell keyword of the corner-point grid, e.g. "
                 f"\"grdecl:YOUNGMOD\") or a table by the values of `keyword`; got {show(v)}")
        if isinstance(v, dict):
            if not v:
                fail(f"expected a table keyword value = {what}, got an empty table")
            out = {}
            for k, x in v.items():
                if not re.fullmatch(r"-?\d+", str(k).strip()):
                    fail(f"table keys are the integer values of `keyword` (e.g. 0, 1, 2), got {show(k)}", key=k)
                if not (is_number(x) and finite(x)):
                    fail(f"must be {what}, got {show(x)}", key=k)
                try:
                    out[int(str(k).strip())] = plain(x)
                except PydanticCustomError as exc:
                    fail(exc.context["message"], key=k)
            return out
        return plain(v)

    schema = {"anyOf": [number_schema, {"type": "string", "pattern": f"^{GRDECL_KEYWORD.pattern}$"},
                        {"type": "object", "additionalProperties": number_schema, "minProperties": 1}]}
    return Annotated[Any, PlainValidator(check), WithJsonSchema(schema)]


AUTO = "auto"
ORDER_AUTO = AUTO


def _number_or_auto(convert, number_schema: dict, words: str, short: str | None = None):
    """A case key that is a number or "auto": ``convert(v)`` returns the number (or calls
    ``fail`` naming what is allowed); ``words`` is what the key allows, for the error message
    (``short``: the same, for a string that is not "auto")."""

    def check(v):
        if isinstance(v, str):
            if v.strip() == AUTO:
                return AUTO
            fail(f"expected {short or words}, got {show(v)}")
        if isinstance(v, bool) or not is_number(v) or not finite(v):
            fail(f"expected {words}, got {show(v)}")
        return convert(v)

    schema = {"anyOf": [number_schema, {"enum": [AUTO]}]}
    return Annotated[Any, PlainValidator(check), WithJsonSchema(schema)]


def _order():
    """``mechanics.order``: 1, 2 or "auto" (resolved on the mesh: setup/mechanics.py, ``resolve_order``)."""
    words = "1 (nodal + bubble space), 2 (quadratic, simplicial meshes) or \"auto\""

    def convert(v):
        if int(v) != v or int(v) not in (1, 2):
            fail(f"expected {words}, got {show(v)}")
        return int(v)

    return _number_or_auto(convert, {"type": "integer", "minimum": 1, "maximum": 2}, words, "1, 2 or \"auto\"")


class Material(Table):
    """``[material]``: isotropic elasticity, E and ν or the Lamé parameters μ and λ.

    On corner-point grids E and ν may vary per cell: ``"grdecl:KEYWORD"`` takes them from a cell
    keyword of the grid (Pa for E), and a table ``{ 0 = ..., 1 = ... }`` gives them per value of
    the integer cell keyword ``keyword`` (FACIES, SATNUM, FIPNUM, ...).
    """

    E: _cell_value("E") | None = Field(None, description="Young's modulus (Pa); corner-point grids: "
                                       "\"grdecl:KEYWORD\" or a table by the values of `keyword`")
    nu: _cell_value("nu") | None = Field(None, description="Poisson's ratio in (−1, 0.5); corner-point grids: "
                                         "\"grdecl:KEYWORD\" or a table by the values of `keyword`")
    keyword: Text | None = Field(None, description="corner-point grids: the integer cell keyword (e.g. FACIES) "
                                 "whose values key the E and nu tables")
    mu: Positive | None = Field(None, description="shear modulus μ (Pa), with lambda")
    lam: number() | None = Field(None, alias="lambda", description="Lamé's first parameter λ (Pa) > −2μ/3, with mu")

    @model_validator(mode="after")
    def _one_pair(self):
        given = self.given()
        tables = [k for k in ("E", "nu") if isinstance(getattr(self, k), dict)]
        if tables and self.keyword is None:
            fail(f"is required with a table of {tables[0]} by keyword value: the integer cell keyword of the "
                 "grid (e.g. keyword = \"FACIES\")", key="keyword")
        if self.keyword is not None and not tables:
            fail("applies to tables of E or nu by keyword value (E = { 0 = 2e10, 1 = 1e10 }); neither is one",
                 key="keyword")
        young, lame = given & {"E", "nu"}, given & {"mu", "lambda"}
        if young and lame:
            fail(f"give E and nu, or mu and lambda, not both pairs; got {', '.join(sorted(given))}",
                 key=sorted(lame)[0])
        pair = ("mu", "lambda") if lame else ("E", "nu")
        for key in pair:
            if key not in given:
                fail(f"is required: give {pair[0]} and {pair[1]}" + (" (Pa)" if lame else " (Pa and Poisson's "
                     "ratio)"), key=key)
        if lame and not self.lam > -2 * self.mu / 3:
            fail(f"must exceed −2μ/3 = {-2 * self.mu / 3:g} Pa (a positive bulk modulus), got {self.lam!r}",
                 key="lambda")
        return self


class RegionMaterial(Material):
    """``[[materials]]``: the material of one region (``[[regions]]``)."""

    region: Text = Field(description="the region ([[regions]] name) this material fills")
    name: Text | None = Field(None, description="a label (optional)")


class MechanicsBoundary(Table):
    """``[[mechanics.boundary]]``: the condition on one boundary part (no block: traction-free)."""

    name: Text = Field(description="boundary part: xmin ... zmax, a mesh group or a [[boundaries]] part")
    u: ExprVectorOrExact | None = Field(None, description="displacement, all components (m), or \"exact\"")
    ux: Expr | None = Field(None, description="x displacement (m) (a roller)")
    uy: Expr | None = Field(None, description="y displacement (m)")
    uz: Expr | None = Field(None, description="z displacement (m)")
    traction: ExprVector | None = Field(None, description="σ n on the part (Pa); 0 in the components a "
                                        "displacement holds")

    @model_validator(mode="after")
    def _conditions(self):
        given = self.given()
        rollers = sorted(given & {"ux", "uy", "uz"})
        if "u" in given and rollers:
            fail("conflicts with `u` on the same boundary part (u holds every component)", key=rollers[0])
        if not given - {"name"}:
            fail("gives no condition: give u, ux, uy, uz or traction (a part without a block is "
                 "traction-free)", key="name")
        if self.traction is not None and (self.u is not None or rollers):
            held = range(len(self.traction)) if self.u is not None else ["xyz".index(k[1]) for k in rollers]
            bad = [i for i in held if i >= len(self.traction) or not _zero(self.traction[i])]
            if bad:
                given_u = "u" if self.u is not None else ", ".join(rollers)
                fail(f"{self.traction!r} conflicts with the displacement condition {given_u} on the same part: its "
                     f"{'xyz'[bad[0]]} component would be ignored; give the traction only in the free components "
                     f"(0 in {', '.join('xyz'[i] for i in held)}) or drop {given_u}", key="traction")
        return self


def _zero(v) -> bool:
    try:
        return float(v) == 0
    except (TypeError, ValueError):
        return False


def _stabilisation():
    """``mechanics.stabilisation``: a positive scale or "auto" (setup/mechanics.py, ``resolve_stabilisation``)."""
    words = "a positive number (the scale of the stabilisation) or \"auto\""

    def convert(v):
        if float(v) <= 0:
            fail(f"expected {words}, got {show(v)}")
        return float(v)

    return _number_or_auto(convert, {"type": "number", "exclusiveMinimum": 0}, words)


class Mechanics(Table):
    """``[mechanics]``: discretisation options, loads, the Biot coefficient and boundary conditions."""

    order: _order() = Field("auto", description="displacement space: 1 nodal + face bubbles (any polytopal mesh), "
                            "2 quadratic (triangles / tetrahedra only), or \"auto\": 2 on a 3D mesh of tetrahedra "
                            "with fractures, else 1 (docs/defaults.md)")
    bubbles: choice("one-sided", "two-sided") = Field("one-sided", description="face bubbles on one or both "
                                                       "sides of each fracture")
    bubble_side: choice("regular", "plus") = Field(
        "regular", description="cell holding a one-sided bubble (order 1): regular (the cell of which the face is "
        "the more regular face: the − cell where its cross-section normal to the face is less than half the + "
        "cell's; docs/contact_patches.md, \"The bubble's cell\") or plus (the fault's + side, the scheme's)")
    stabilisation: _stabilisation() = Field(
        "auto", description="scale of the stabilisation (× the scheme's weights), or auto: 0.3 on corner-point "
        "grids, 1 elsewhere (docs/contact_patches.md, \"The stabilisation's reaction\")")
    bubble_stabilisation: choice("face", "cell") = Field(
        "face", description="weight of the bubbles' stabilisation: face ((2μ + λ) |σ|²/|K|, robust on flat cells "
        "and fault slivers) or cell (h_K (2μ + λ), the scheme's; docs/contact_patches.md)")
    nodal_stabilisation: choice("auto", "diameter", "thickness") = Field(
        "auto", description="length in the weight of the nodal stabilisation: diameter (h_K, the scheme's), "
        "thickness (h_K min(1, 4 t_K/h_K), t_K = |K|/largest face: softer on flat cells) or auto (thickness on "
        "corner-point grids, diameter elsewhere; docs/contact_patches.md)")
    body_force: ExprVectorOrExact | None = Field(None, description="body force (N/m³), per component, or "
                                                 "\"exact\"")
    matrix_pressure: Expr | None = Field(None, description="p_m (Pa) of the Biot term −b p_m I")
    biot: number(ge=0, le=1) = Field(1.0, description="Biot coefficient b in [0, 1] (0: no coupling)")
    fracture_pressure: Expr | None = Field(None, description="p_f (Pa) on the fracture faces")
    initial_stress: ExprTensor | None = Field(None, description="σ0 (Pa), d×d: total stress = σ0 + σ(u)")
    boundary: list[MechanicsBoundary] = Field(default_factory=list, description="one block per boundary part")

    @model_validator(mode="after")
    def _one_block_per_part(self):
        seen = set()
        for i, b in enumerate(self.boundary):
            if b.name in seen:
                # the model would apply both: later displacements overwrite earlier ones, tractions add up
                fail(f"boundary {b.name!r} is given twice; one [[mechanics.boundary]] block per part (put its "
                     "u/ux/uy/uz and traction together)", key=("boundary", i, "name"))
            seen.add(b.name)
        return self


class Contact(Table):
    """``[contact]``: the contact law on the fractures (not needed without fractures)."""

    law: choice(*LAWS) = Field("coulomb", description="contact law")
    friction: Expr | None = Field(None, description="coulomb, slip-weakening: (static) friction coefficient "
                                  "F ≥ 0; rate-and-state: the reference coefficient f₀ at reference_rate; an "
                                  "expression of x, y, z and D (distance to the fracture's nearest tip, m)")
    threshold: Expr | None = Field(None, description="tresca: threshold g ≥ 0 (Pa), same variables")
    dynamic_friction: Expr | None = Field(None, description="slip-weakening: dynamic friction coefficient F_d, "
                                          "0 ≤ F_d ≤ friction, reached after critical_slip of slip; same variables")
    critical_slip: Expr | None = Field(None, description="slip-weakening: slip D_c > 0 (m) over which the friction "
                                       "falls linearly from friction to dynamic_friction; rate-and-state: the "
                                       "characteristic slip D_c > 0 (m) of the state evolution; same variables")
    a: Expr | None = Field(None, description="rate-and-state: direct effect a > 0 (μ = f₀ + a ln(V/V₀) + "
                           "b ln(V₀θ/D_c), regularised); same variables")
    b: Expr | None = Field(None, description="rate-and-state: evolution effect b ≥ 0 (a < b: velocity weakening, "
                           "earthquakes possible); same variables")
    reference_rate: Expr | None = Field(None, description="rate-and-state: reference slip rate V₀ > 0 (m/s) of "
                                        "f₀ (default 1e-6); same variables")
    initial_slip_rate: Expr | None = Field(None, description="rate-and-state: slip rate V_i > 0 (m/s) at the start; "
                                           "each face's initial state θ₀ follows from its initial traction "
                                           "(τ = σ′ μ(V_i, θ₀) + η V_i); same variables")
    state_law: choice("aging", "slip") = Field("aging", description="rate-and-state: state evolution, aging "
                                               "(θ̇ = 1 − Vθ/D_c) or slip (θ̇ = −(Vθ/D_c) ln(Vθ/D_c))")
    shear_wave_speed: Positive | None = Field(None, description="rate-and-state: shear-wave speed c_s (m/s) of the "
                                              "radiation damping η V, η = μ/(2c_s) with μ the shear modulus next "
                                              "to each face (quasi-dynamic slip); required unless "
                                              "radiation_damping = false")
    radiation_damping: bool = Field(True, description="rate-and-state: the radiation-damping term η V (false: "
                                    "fully quasi-static, slip rates unbounded in an instability)")
    initial_state_from: choice("traction", "steady") = Field(
        "traction", description="rate-and-state: each face's initial state θ₀ such that its initial traction slides "
        "at initial_slip_rate (\"traction\"), or the steady state θ₀ = critical_slip/initial_slip_rate "
        "(\"steady\"; the face's slip rate then follows from its traction)")
    seismic_rate: Positive = Field(1e-3, description="rate-and-state: slip rate (m/s) above which a fault's "
                                   "slip is an event of events.csv (onset, hypocentre, area, slip, M0, Mw)")
    stick_rate: Positive = Field(1e-9, description="rate-and-state: slip rate (m/s) below which a face is reported "
                                 "as stick (every closed face creeps; this only sorts the outputs)")
    beta: Positive = Field(1.0, description="c in β = c (2μ + λ)/h of the augmented multipliers")
    initial: choice("closed", "open") = Field("closed", description="first Newton iterate: closed (bonded) or "
                                              "open (λ = 0)")
    patch_ratio: number(ge=0, le=1) = Field(
        PATCH_RATIO, description="multiplier patches: fracture faces smaller than this fraction of their cells' "
        "cross-section, or narrower than this fraction of the thicker cell's thickness, share their multiplier "
        "with neighbours (slivers and wedge faces of corner-point faults); 0: one per face")

    @model_validator(mode="after")
    def _law_keys(self):
        given = self.given()
        for key, laws in {**LAW_KEYS, **{k: ("rate-and-state",) for k in RATE_STATE_OPTIONS}}.items():
            if key in given and self.law not in laws:
                fail(f"applies to law = {' or '.join(map(repr, laws))} only; this case has law = {self.law!r}",
                     key=key)
        if self.law == "rate-and-state" and self.radiation_damping and self.shear_wave_speed is None:
            fail("is required by law = 'rate-and-state' (the radiation damping η = μ/(2c_s), m/s, e.g. 3464); "
                 "or set radiation_damping = false", key="shear_wave_speed")
        return self
