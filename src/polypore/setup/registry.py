"""The built-in cases and their one-line descriptions."""

from __future__ import annotations

from .casefile import builtin_names, load_case


def describe_cases() -> list[tuple[str, str]]:
    """(name, description) of every built-in case, sorted by name."""
    return [(n, load_case(n).data.get("description", "")) for n in builtin_names()]
