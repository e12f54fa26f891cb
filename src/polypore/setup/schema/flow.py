"""Schema of the flow tables: ``[flow]`` with ``[[flow.regions]]``, ``[[flow.boundary]]`` and
``[[flow.fracture_boundary]]`` (SI units).

Fracture expressions may use ``D`` (distance to the nearest tip of the same fracture, m) and
``L`` (the fracture's length in 2D, square root of its area in 3D, m) besides x, y, z, t.
"""

from __future__ import annotations

from typing import Any, Annotated

from pydantic import Field, PlainValidator, WithJsonSchema, model_validator

from ...discretisation.hfv import CELL_POINTS
from .types import (choice, EXPRESSION, Boolean, Expr, ExprOrExact, NonNegative, Positive, Table, Text, _expression,
                    _tensor, fail, finite, is_number, number, show, vector)

GRDECL = "grdecl"   # a value taken from the cell keywords of a corner-point grid
_EXPR = {"anyOf": [{"type": "number"}, {"type": "string"}]}
_MATRIX = {"type": "array", "items": {"type": "array", "items": _EXPR}}


def _by_region(check, what: str):
    """A value, or a table region name -> value (every region of the mesh then needs one)."""

    def by_region(v):
        if isinstance(v, dict):
            if not v:
                fail(f"expected {what} or a table by region (region = value), got an empty table")
            return {k: _checked(check, x, k) for k, x in v.items()}
        return check(v)

    return by_region


def _checked(check, v, key):
    # an error in one region's value names that region (flow.porosity.reservoir)
    from pydantic_core import PydanticCustomError

    try:
        return check(v)
    except PydanticCustomError as exc:
        fail(exc.context["message"], key=key)


def _permeability_value(v):
    return _tensor(v) if isinstance(v, list) else _expression(v)


def _modulus(v):
    if isinstance(v, str) and v.strip().lower() in ("inf", "infinity"):
        return float("inf")
    if not is_number(v) or not finite(v) or not v > 0:
        fail(f"must be a positive number (Pa) or \"inf\" (no storage), got {show(v)}")
    return float(v)


def _porosity(v):
    if v == GRDECL:
        return v
    if not is_number(v) or not 0 < v <= 1:
        fail(f"must be a number in (0, 1] or \"grdecl\" (PORO × NTG × MULTPV of a corner-point grid), got {show(v)}")
    return float(v)


def _region_table(schema: dict) -> dict:
    return {"anyOf": [schema, {"type": "object", "additionalProperties": schema, "minProperties": 1}]}


Permeability = Annotated[Any, PlainValidator(_by_region(_permeability_value, "a number, an expression or a matrix")),
                         WithJsonSchema(_region_table({"anyOf": [_EXPR, _MATRIX]}))]
Modulus = Annotated[Any, PlainValidator(_by_region(_modulus, "a positive number or \"inf\"")),
                    WithJsonSchema(_region_table({"anyOf": [{"type": "number", "exclusiveMinimum": 0},
                                                            {"enum": ["inf", "infinity"]}]}))]
Porosity = Annotated[Any, PlainValidator(_by_region(_porosity, "a number in (0, 1] or \"grdecl\"")),
                     WithJsonSchema(_region_table({"anyOf": [{"type": "number", "exclusiveMinimum": 0, "maximum": 1},
                                                             {"enum": [GRDECL]}]}))]


class FlowRegion(Table):
    """``[[flow.regions]]``: the permeability of one region (overrides ``permeability`` there)."""

    name: Text = Field(description="region name ([[regions]])")
    permeability: Permeability = Field(description=f"K_m (m²): {EXPRESSION} or a d×d matrix")


class FlowBoundary(Table):
    """``[[flow.boundary]]``: one condition on one boundary part (parts without a block: no flow)."""

    name: Text = Field(description="boundary part: xmin ... zmax, a mesh group or a [[boundaries]] part")
    pressure: ExprOrExact | None = Field(None, description="pressure (Pa), expression of x, y, z, t, or \"exact\"")
    flux: Expr | None = Field(None, description="outward flux density (m/s); < 0 injects")
    rate: Expr | None = Field(None, description="injected volume rate through the part (m³/s; m²/s per metre in "
                              "2D), an expression of t")
    mass_rate: Expr | None = Field(None, description="injected mass rate (kg/s; kg/s per metre in 2D), divided "
                                   "by flow.fluid_density")

    @model_validator(mode="after")
    def _exactly_one(self):
        given = self.given() & {"pressure", "flux", "rate", "mass_rate"}
        if len(given) != 1:
            fail("give exactly one of pressure (Pa), flux (outward, m/s), rate (injected, m³/s; m²/s per metre in "
                 "2D) or mass_rate (injected, kg/s; kg/s per metre in 2D) for this boundary part"
                 + (f"; got {', '.join(sorted(given))}" if given else ""),
                 key=sorted(given)[1] if len(given) > 1 else "pressure")
        if self.flux == "exact" or self.rate == "exact" or self.mass_rate == "exact":
            fail('"exact" is only available for pressure conditions', key=sorted(given)[0])
        return self


class FractureBoundary(Table):
    """``[[flow.fracture_boundary]]``: the fracture ends on a boundary part where the matrix has no
    pressure condition: a pressure or no flow."""

    name: Text = Field(description="boundary part")
    pressure: Expr | None = Field(None, description="pressure (Pa) at the fracture ends")
    no_flow: Boolean | None = Field(None, description="true: no flow through the fracture ends")

    @model_validator(mode="after")
    def _exactly_one(self):
        given = self.given()
        if ("pressure" in given) == ("no_flow" in given):
            fail("give exactly one of pressure (Pa) or no_flow = true", key="pressure")
        if self.no_flow is False:
            fail("only no_flow = true is meaningful (omit the block otherwise)", key="no_flow")
        return self


class Well(Table):
    """``[[flow.wells]]``: injection into the cells of one column of a corner-point grid (a vertical well)."""

    name: Text = Field(description="well name")
    column: vector(2, "cell indices") = Field(description="[i, j] of the column (1-based, as in the GRDECL file; "
                                              "with mesh.refine the file's indices still)")
    layers: vector(2, "layer numbers") | None = Field(None, description="[k1, k2], the perforated layers "
                                                      "(1-based, inclusive; default: all)")
    rate: Expr | None = Field(None, description="injected volume rate (m³/s; < 0 produces), an expression of t")
    mass_rate: Expr | None = Field(None, description="injected mass rate (kg/s), divided by flow.fluid_density")

    @model_validator(mode="after")
    def _checks(self):
        given = self.given() & {"rate", "mass_rate"}
        if len(given) != 1:
            fail("give exactly one of rate (m³/s) or mass_rate (kg/s)" + (
                f"; got {', '.join(sorted(given))}" if given else ""), key="mass_rate" if given else "rate")
        for key in ("column", "layers"):
            v = getattr(self, key)
            if v is not None and any(int(a) != a or a < 1 for a in v):
                fail(f"must be positive integers (1-based), got {v}", key=key)
        if self.layers is not None and self.layers[1] < self.layers[0]:
            fail(f"must be [first, last] with first ≤ last, got {self.layers}", key="layers")
        return self


class Flow(Table):
    """``[flow]``: mixed-dimensional Darcy flow data."""

    permeability: Permeability | None = Field(None, description="K_m (m²): a number or expression of x, y, z "
                                              "(isotropic), a d×d matrix, or a table by region")
    viscosity: Positive = Field(1e-3, description="η (Pa·s)")
    biot_modulus: Modulus | None = Field(None, description="M (Pa) > 0, \"inf\" (no matrix storage; the "
                                         "default), or a table by region")
    porosity: Porosity | None = Field(None, description="φ in (0, 1] (or a table by region), instead of "
                                      "biot_modulus: 1/M = φ c_w")
    fluid_compressibility: Positive | None = Field(None, description="c_w (1/Pa), with porosity")
    fracture_compressibility: NonNegative = Field(0.0, description="c_f (1/Pa)")
    dilatancy_angle: number(ge=0, lt=90) = Field(0.0, description="ψ (degrees) of the aperture's dilatancy "
                                                 "(poromechanics)")
    pressure_stabilisation: NonNegative | None = Field(None, description="δ of the poromechanics pressure-jump "
                                                       "stabilisation; 0 switches it off")
    aperture: Expr = Field(1e-4, description="d_f (m) > 0: expression of x, y, z, t, D, L")
    normal_permeability: Expr = Field(1e-15, description="K_fn (m²) > 0: expression of x, y, z, D, L")
    fracture_conductivity: Expr | None = Field(None, description="C_f (m³): expression of the aperture d (and x, "
                                               "y, z, D, L); default d³/12")
    source: ExprOrExact = Field(0.0, description="h_m (1/s): expression of x, y, z, t, or \"exact\"")
    fracture_source: ExprOrExact = Field(0.0, description="h_f (m/s): expression of x, y, z, t, D, L, or \"exact\"")
    initial_pressure: Expr | None = Field(None, description="p⁰ (Pa) of a transient run: expression of x, y, z")
    steady: Boolean | None = Field(None, description="default: true unless the case has a [time] table")
    alpha: Positive | None = Field(None, description="HFV stabilisation α (default √d)")
    fracture_alpha: Positive | None = Field(None, description="HFV stabilisation on the fractures (default "
                                            "√(d−1))")
    cell_point: choice(*CELL_POINTS) = Field("auto", description="HFV cell points x_K: \"centroid\", or "
                                              "\"auto\" (the centroid, except on wedge slivers whose HFV "
                                              "matrix it leaves near-singular: the face-area mean there)")
    fluid_density: Positive = Field(1000.0, description="ρ_w (kg/m³), converts mass rates")
    regions: list[FlowRegion] = Field(default_factory=list, description="per-region permeability")
    boundary: list[FlowBoundary] = Field(default_factory=list, description="one block per boundary part")
    fracture_boundary: list[FractureBoundary] = Field(default_factory=list, description="fracture ends on "
                                                      "boundary parts")
    wells: list[Well] = Field(default_factory=list, description="corner-point grids: injection into columns of "
                              "cells")

    @model_validator(mode="after")
    def _conflicts(self):
        given = self.given()
        if "porosity" in given and "biot_modulus" in given:
            fail("give either biot_modulus or porosity (with fluid_compressibility), not both", key="porosity")
        if ("porosity" in given) != ("fluid_compressibility" in given):
            key = "fluid_compressibility" if "porosity" in given else "porosity"
            fail("is required with " + ("porosity (1/Pa)" if "porosity" in given else
                                        "fluid_compressibility: 1/M = φ c_w"), key=key)
        for key in ("boundary", "fracture_boundary", "wells"):
            seen = set()
            for i, b in enumerate(getattr(self, key)):
                if b.name in seen:
                    fail(f"{'well' if key == 'wells' else 'boundary'} {b.name!r} is given twice; one [[flow.{key}]] "
                         "block per " + ("well" if key == "wells" else "part"),
                         key=(key, i, "name"))
                seen.add(b.name)
        return self
