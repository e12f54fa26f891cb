"""The case-file schema: one declarative description (pydantic) of every table and key of a case
file, their types, ranges, defaults and conflicts.

:func:`validate` turns a case's data (the parsed TOML with ``--set`` overrides applied) into a
:class:`Case` or raises one InputError naming the field; :func:`json_schema` is the JSON Schema
``polypore schema`` prints for TOML editors.
"""

from __future__ import annotations

from pydantic import ValidationError

from .case import MODELS, Case
from .errors import input_error

__all__ = ["Case", "MODELS", "json_schema", "validate"]


def validate(data: dict) -> Case:
    """The validated case; InputError naming the first bad field."""
    try:
        return Case.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, data) from None


def json_schema() -> dict:
    """JSON Schema (draft 7) of a case file, without the nulls that stand for absent keys
    (TOML has no null)."""
    schema = Case.model_json_schema(by_alias=True)
    schema["properties"].pop("base_dir", None)      # set by polypore, not a case-file key
    schema["$schema"] = "http://json-schema.org/draft-07/schema#"   # what Taplo and most editors read
    schema["title"] = "polypore case file"
    return _without_null(schema)


def _without_null(node):
    if isinstance(node, dict):
        out = {}
        for k, v in node.items():
            if k == "default" and v is None:
                continue
            if k == "anyOf" and isinstance(v, list):
                v = [b for b in v if b != {"type": "null"}]
                if len(v) == 1:
                    out.update(_without_null(v[0]))
                    continue
            out[k] = _without_null(v)
        return out
    if isinstance(node, list):
        return [_without_null(v) for v in node]
    return node
