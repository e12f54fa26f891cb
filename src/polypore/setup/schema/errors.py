"""From pydantic's validation errors to one :class:`~polypore.core.errors.InputError` naming the
field as a case file spells it: ``mechanics.boundary.ymax.u``, list elements by their ``name``."""

from __future__ import annotations

from pydantic import ValidationError

from ...core.errors import InputError
from .types import show


def _clip(part: str) -> str:
    # a key or name of any length may come from the file: the field names it, clipped
    return part if len(part) <= 64 else f"{part[:48]}…({len(part)} characters)"


def field_path(loc, data) -> str:
    """Dotted path of ``loc`` (keys and list indices) in the raw case ``data``; a list element
    that has a name is called by it, as ``--set`` addresses it."""
    parts, node = [], data
    for key in loc:
        if isinstance(key, int) and isinstance(node, list) and 0 <= key < len(node):
            node = node[key]
            name = node.get("name") if isinstance(node, dict) else None
            parts.append(_clip(name) if isinstance(name, str) and name else str(key))
            continue
        parts.append(_clip(str(key)))
        node = node.get(key) if isinstance(node, dict) else None
    return ".".join(parts)


def input_error(exc: ValidationError, data) -> InputError:
    """The first error of ``exc`` as an InputError: field, what is wrong, the value and what is allowed."""
    err = exc.errors(include_url=False)[0]
    loc = list(err["loc"])
    ctx = err.get("ctx") or {}
    key = ctx.get("key")
    if key is not None:
        loc += list(key) if isinstance(key, tuple) else [key]
    if err["type"] == "case":
        message = ctx["message"]
    elif err["type"] == "missing":
        message = "is required but missing"
    elif err["type"] == "list_type":
        message = f"expected a list of tables ([[{'.'.join(map(str, loc))}]] blocks), got {show(err.get('input'))}"
    else:  # a check of pydantic's own (none is expected: every type of the schema has its own message)
        message = f"{err['msg']}, got {show(err.get('input'))}"
    return InputError(field_path(loc, data) or "case", message)
