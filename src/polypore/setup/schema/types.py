"""Value types of the case-file schema: numbers with ranges, integers, expressions, vectors, choices.

Each type validates with its own message (what is allowed and the value given) and carries its
JSON Schema, so that ``polypore schema`` tells an editor the same rules. :func:`fail` raises the
error every validator of the schema raises; ``key`` names a sub-field of the table being checked
(a conflict found by a table's validator belongs to one of its keys).
"""

from __future__ import annotations

import difflib
import math
from typing import Annotated, Any, Iterable

from pydantic import BaseModel, ConfigDict, PlainValidator, WithJsonSchema, model_validator
from pydantic_core import PydanticCustomError

EXPRESSION = "a number or an expression of x, y, z, t (text)"


def fail(message: str, key: str | tuple | None = None):
    """Raise the schema's validation error; ``key`` is a key (or a path of keys and list indices)
    inside the table being validated."""
    raise PydanticCustomError("case", "{message}", {"message": message, "key": key})


def unknown_key(key: str, allowed: Iterable[str], what: str = "unknown key") -> str:
    """Message for an unknown key: a did-you-mean suggestion and the accepted keys."""
    allowed = sorted(allowed)
    close = difflib.get_close_matches(str(key), allowed, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"{what}{hint}; accepted: {', '.join(allowed) or 'nothing'}"


def show(v: Any) -> str:
    """A value as quoted in messages (long values clipped)."""
    r = repr(v)
    return r if len(r) <= 80 else f"{r[:60]} … {r[-12:]}"


def is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def finite(v) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer beyond the float range
        return False


class Table(BaseModel):
    """A table of a case file: known keys only (a typo gets a did-you-mean), nothing else."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data):
        cls._check_keys(data)
        return data

    @classmethod
    def _check_keys(cls, data) -> None:
        """Checks of the raw table before its values are validated: a table, known keys."""
        if not isinstance(data, dict):
            fail(f"expected a table (key = value pairs), got {show(data)}")
        allowed = cls.keys()
        for key in data:
            if key not in allowed:
                fail(unknown_key(key, allowed, cls._unknown_what(data[key])), key=key)

    @classmethod
    def _unknown_what(cls, value) -> str:
        return "unknown key"

    @classmethod
    def keys(cls) -> set[str]:
        """The keys the table accepts, as spelt in a case file."""
        return {f.alias or name for name, f in cls.model_fields.items()}

    def given(self) -> set[str]:
        """The keys the case file gave (as spelt there)."""
        fields = type(self).model_fields
        return {fields[n].alias or n for n in self.model_fields_set}


def _g(v) -> str:
    return f"{v:g}".replace("-", "−")


def _range_text(gt, ge, lt, le) -> str:
    lo = gt if gt is not None else ge
    hi = lt if lt is not None else le
    if lo is not None and hi is not None:
        return f"in {'(' if gt is not None else '['}{_g(lo)}, {_g(hi)}{')' if lt is not None else ']'}"
    if gt == 0:
        return "positive"
    if ge == 0:
        return "≥ 0"
    if lo is not None:
        return f"{'>' if gt is not None else '≥'} {_g(lo)}"
    return f"{'<' if lt is not None else '≤'} {_g(hi)}"


def number(*, gt=None, ge=None, lt=None, le=None, unit: str = "", integer: bool = False):
    """A finite number (an integer if ``integer``: TOML's 4.0 counts) in the given range; ``unit``
    is quoted in messages."""
    ranged = any(b is not None for b in (gt, ge, lt, le))
    what = "an integer" if integer else "a number"
    rng = _range_text(gt, ge, lt, le) if ranged else ""
    allowed = f"a positive {what[2:]}" if rng == "positive" else f"{what} {rng}".rstrip()
    allowed += f" ({unit})" if unit else ""

    def check(v):
        if not is_number(v):
            fail(f"expected {allowed}, got {show(v)}")
        if not finite(v):
            fail(f"must be a finite number, got {show(v)}")
        if integer and int(v) != v:
            fail(f"expected {allowed}, got {show(v)}")
        if (gt is not None and not v > gt or ge is not None and not v >= ge or lt is not None and not v < lt
                or le is not None and not v <= le):
            fail(f"must be {_range_text(gt, ge, lt, le)}{f' ({unit})' if unit else ''}, got {show(v)}")
        return int(v) if integer else float(v)

    schema = {"type": "integer" if integer else "number"}
    for key, b in (("exclusiveMinimum", gt), ("minimum", ge), ("exclusiveMaximum", lt), ("maximum", le)):
        if b is not None:
            schema[key] = b
    return Annotated[int if integer else float, PlainValidator(check), WithJsonSchema(schema)]


def _text(v):
    if not isinstance(v, str) or not v.strip():
        fail(f"expected a non-empty text, got {show(v)}")
    return v


def _boolean(v):
    if not isinstance(v, bool):
        fail(f"expected true or false, got {show(v)}")
    return v


def _expression(v):
    if isinstance(v, str):
        if not v.strip():
            fail(f"expected {EXPRESSION}, got an empty text")
        return v
    if not is_number(v):
        fail(f"expected {EXPRESSION}, got {show(v)}")
    if not finite(v):
        fail(f"must be a finite number, got {show(v)}")
    return float(v)


def choice(*options: str):
    """One of ``options`` (text)."""

    def check(v):
        if not isinstance(v, str) or v not in options:
            fail(f"unknown value {show(v)}; allowed: {', '.join(options)}")
        return v

    return Annotated[str, PlainValidator(check), WithJsonSchema({"enum": list(options)})]


def vector(length: int | tuple[int, ...] | None = None, what: str = "numbers"):
    """A list of finite numbers; ``length`` one length or the allowed lengths."""
    lengths = (length,) if isinstance(length, int) else length
    want = (f"a list of {' or '.join(map(str, lengths))} {what}" if lengths else f"a list of {what}")

    def check(v):
        if not (isinstance(v, list) and all(is_number(a) for a in v)) or lengths and len(v) not in lengths:
            fail(f"expected {want}, got {show(v)}")
        bad = [a for a in v if not finite(a)]
        if bad:
            fail(f"every value must be a finite number, got {show(bad[0])} in {show(v)}")
        return [float(a) for a in v]

    schema = {"type": "array", "items": {"type": "number"}}
    if lengths:
        schema.update(minItems=min(lengths), maxItems=max(lengths))
    return Annotated[list[float], PlainValidator(check), WithJsonSchema(schema)]


def points(what: str = "points [x, y] or [x, y, z]", minimum: int = 1):
    """A list of at least ``minimum`` points of 2 or 3 finite coordinates, all of one dimension."""

    def check(v):
        ok = isinstance(v, list) and len(v) >= minimum and all(
            isinstance(p, list) and len(p) in (2, 3) and all(is_number(a) for a in p) for p in v)
        if not ok or len({len(p) for p in v}) > 1:
            fail(f"expected a list of at least {minimum} {what} (one dimension for all), got {show(v)}")
        bad = [a for p in v for a in p if not finite(a)]
        if bad:
            fail(f"every coordinate must be a finite number, got {show(bad[0])} in {show(v)}")
        return [[float(a) for a in p] for p in v]

    schema = {"type": "array", "minItems": minimum,
              "items": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 3}}
    return Annotated[list[list[float]], PlainValidator(check), WithJsonSchema(schema)]


def _expressions(v):
    if not isinstance(v, list) or not v:
        fail(f"expected a list of {EXPRESSION}s, one per component, got {show(v)}")
    return [_expression(a) for a in v]


def _tensor(v):
    if not (isinstance(v, list) and v and all(isinstance(r, list) for r in v)):
        fail(f"expected a list of rows (lists) of {EXPRESSION}s, got {show(v)}")
    if any(len(r) != len(v) for r in v):
        fail(f"expected a square matrix (d rows of d values), got {show(v)}")
    return [[_expression(a) for a in r] for r in v]


_EXPR_SCHEMA = {"anyOf": [{"type": "number"}, {"type": "string"}]}
Text = Annotated[str, PlainValidator(_text), WithJsonSchema({"type": "string", "minLength": 1})]
Boolean = Annotated[bool, PlainValidator(_boolean), WithJsonSchema({"type": "boolean"})]
Expr = Annotated[float | str, PlainValidator(_expression), WithJsonSchema(_EXPR_SCHEMA)]
ExprVector = Annotated[list[float | str], PlainValidator(_expressions),
                       WithJsonSchema({"type": "array", "items": _EXPR_SCHEMA, "minItems": 1})]
ExprTensor = Annotated[list[list[float | str]], PlainValidator(_tensor),
                       WithJsonSchema({"type": "array", "items": {"type": "array", "items": _EXPR_SCHEMA}})]
Number = number()
Positive = number(gt=0)
NonNegative = number(ge=0)


def exact_or(inner_check, inner_schema: dict):
    """The text "exact" (the case's [exact] solution gives the value) or a value of another type."""

    def check(v):
        return v if v == "exact" else inner_check(v)

    return Annotated[Any, PlainValidator(check),
                     WithJsonSchema({"anyOf": [{"const": "exact"}, inner_schema]})]


ExprOrExact = exact_or(_expression, _EXPR_SCHEMA)
ExprVectorOrExact = exact_or(_expressions, {"type": "array", "items": _EXPR_SCHEMA})
