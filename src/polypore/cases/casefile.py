"""Case files (TOML): loading, ``--set`` overrides and field-by-field validation.

A case is one TOML document. Built-in cases are TOML files shipped in
``polypore/cases/data``; users pass a name or a path. Every value is read through
:class:`Section`, which knows the dotted path of each key, so that every error
names the field, the bad value and what is allowed, and unknown keys (typos) are
reported instead of silently ignored.
"""

from __future__ import annotations

import copy
import difflib
import math
import re
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Iterable

import tomli_w

from ..core.errors import InputError

DATA = "data"
_MISSING = object()

# Every top-level key or table a case may have (read by casefile, meshing, mechanics_setup,
# flow_setup, schedule, insitu, poro_run, run); anything else is a typo, reported at load time
# because no table reader would see it. base_dir is added by load_case for case files.
TOP_LEVEL = ("name", "description", "model", "base_dir", "parameters", "mesh", "fractures", "regions",
             "boundaries", "material", "materials", "mechanics", "contact", "exact", "flow", "time", "solver",
             "initial_state", "monitor")
# a case name becomes a folder name (results/<name>): no path separators, no "..", no spaces
_NAME = re.compile(r"[\w.-]+")


def unknown_key(key: str, allowed: Iterable[str], what: str = "unknown key") -> str:
    """Message for an unknown key: a did-you-mean suggestion and the accepted keys."""
    allowed = sorted(allowed)
    close = difflib.get_close_matches(str(key), allowed, n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"{what}{hint}; accepted: {', '.join(allowed) or 'nothing'}"


def check_top_level(data: dict, where: str = "") -> None:
    """InputError for a top-level key or table no part of polypore reads (``[solvr]``)."""
    for key in data:
        if key not in TOP_LEVEL:
            what = "table" if isinstance(data[key], (dict, list)) else "key"
            raise InputError(key, unknown_key(key, TOP_LEVEL, f"unknown top-level {what}{where}"))


def check_name(name, from_file: bool) -> None:
    """InputError unless ``name`` can be a folder name under results/."""
    if isinstance(name, str) and _NAME.fullmatch(name) and name != "." and ".." not in name:
        return
    origin = " (taken from the file name; set name = \"...\" in the case file)" if from_file else ""
    raise InputError("name", f"the case name names its results folder (results/<name>), so it may hold only "
                     f"letters, digits, '-', '_' and '.', with no path separator and no '..'; got {name!r}{origin}")


def _finite(v) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer beyond the float range
        return False


def builtin_names() -> list[str]:
    """Names of the built-in cases (the TOML files shipped with the package)."""
    root = resources.files(__package__) / DATA
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read_toml(text: str, where: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError("case", f"{where} is not valid TOML: {exc}") from None


@dataclass
class CaseFile:
    """A loaded case: its name, where it came from and its (overridden) data."""

    name: str
    source: str
    data: dict

    def to_toml(self) -> str:
        """The fully resolved case as TOML text (written as ``case.toml``)."""
        return tomli_w.dumps(self.data)

    def root(self) -> "Section":
        return Section(self.data, "")


def load_case(name_or_path: str, overrides: Iterable[str] = ()) -> CaseFile:
    """Load a built-in case by name or a TOML file by path, then apply ``KEY=VALUE`` overrides."""
    path = Path(name_or_path)
    if name_or_path in builtin_names():
        text = (resources.files(__package__) / DATA / f"{name_or_path}.toml").read_text()
        data = _read_toml(text, f"built-in case {name_or_path!r}")
        source = f"builtin:{name_or_path}"
        stem_name = None
    elif path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise InputError("case", f"case file {str(path)!r} does not exist; give a built-in case name "
                             f"({', '.join(builtin_names())}) or the path of a TOML case file")
        data = _read_toml(path.read_text(), f"case file {str(path)!r}")
        source = str(path.resolve())
        check_top_level(data, f" in {str(path)!r}")
        stem_name = None if "name" in data else path.stem
        data.setdefault("name", path.stem)
        data.setdefault("base_dir", str(path.resolve().parent))
    else:
        raise InputError("case", f"unknown case {name_or_path!r}; built-in cases are {', '.join(builtin_names())}, "
                         "or give the path of a .toml case file")
    data = copy.deepcopy(data)
    for item in overrides:
        top = item.partition("=")[0].strip().split(".")[0]
        if "=" in item and top and top not in TOP_LEVEL:
            raise InputError(f"--set {item}", unknown_key(top, TOP_LEVEL, f"unknown top-level key or table {top!r}"))
        apply_override(data, item)
    check_top_level(data)
    name = data.get("name", path.stem)
    check_name(name, from_file=stem_name is not None and name == stem_name)
    return CaseFile(name, source, data)


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare word or an expression: keep it as a string


def apply_override(data: dict, item: str) -> None:
    """Apply one ``dotted.key=value`` override in place.

    List elements are addressed by index or, for lists of tables with a ``name``,
    by that name (``fractures.F1.normal=[0, 0, 1]``). The value is read as a TOML
    value when it parses as one, otherwise kept as a string.
    """
    if "=" not in item:
        raise InputError("--set", f"expected KEY=VALUE, got {item!r}")
    key, _, text = item.partition("=")
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise InputError("--set", f"empty key in {item!r}")
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        where = ".".join(parts[:i + 1])
        if isinstance(node, list):
            node = _list_item(node, part, where)
        elif isinstance(node, dict):
            node = node.setdefault(part, {})
        else:
            raise InputError(key, f"cannot set {where!r}: {'.'.join(parts[:i])!r} is a value, not a table")
    last = parts[-1]
    value = _parse_value(text.strip())
    if isinstance(node, list):
        idx = _list_index(node, last, key)
        node[idx] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise InputError(key, "cannot set a key inside a value")


def _list_index(lst: list, part: str, where: str) -> int:
    if part.lstrip("-").isdigit():
        idx = int(part)
        if -len(lst) <= idx < len(lst):
            return idx
        raise InputError(where, f"index {idx} out of range for a list of {len(lst)}")
    for i, el in enumerate(lst):
        if isinstance(el, dict) and el.get("name") == part:
            return i
    names = [el.get("name") for el in lst if isinstance(el, dict)]
    raise InputError(where, f"no element named {part!r}; known: {names}")


def _list_item(lst: list, part: str, where: str):
    return lst[_list_index(lst, part, where)]


class Section:
    """Typed, path-aware reader of one table of a case file.

    Call :meth:`done` after reading to reject unknown keys.
    """

    def __init__(self, data: dict, path: str):
        if not isinstance(data, dict):
            raise InputError(path or "case", f"expected a table, got {data!r}")
        self.data = data
        self.path = path
        self._read: set[str] = set()

    def field(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default=_MISSING):
        self._read.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise InputError(self.field(key), "is required but missing")
            return default
        return self.data[key]

    def number(self, key: str, default=_MISSING, *, positive=False, nonneg=False, lo=None, hi=None,
               integer=False) -> float:
        v = self.raw(key, default)
        if v is None:
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(self.field(key), f"expected a number, got {v!r}")
        if key in self.data and not _finite(v):
            # TOML spells inf and nan as numbers; no value read as a number may be either
            # (a default from the code may be inf on purpose)
            raise InputError(self.field(key), f"must be a finite number, got {v!r}")
        if integer and int(v) != v:
            raise InputError(self.field(key), f"expected an integer, got {v!r}")
        if positive and not v > 0:
            raise InputError(self.field(key), f"must be positive, got {v!r}")
        if nonneg and not v >= 0:
            raise InputError(self.field(key), f"must be non-negative, got {v!r}")
        if lo is not None and not v > lo or hi is not None and not v < hi:
            raise InputError(self.field(key), f"must lie in ({lo}, {hi}), got {v!r}")
        return int(v) if integer else float(v)

    def string(self, key: str, default=_MISSING, choices: Iterable[str] | None = None) -> str:
        v = self.raw(key, default)
        if v is None:
            return v
        if not isinstance(v, str):
            raise InputError(self.field(key), f"expected a string, got {v!r}")
        if choices is not None and v not in choices:
            raise InputError(self.field(key), f"unknown value {v!r}; allowed: {', '.join(choices)}")
        return v

    def boolean(self, key: str, default=_MISSING) -> bool:
        v = self.raw(key, default)
        if not isinstance(v, bool):
            raise InputError(self.field(key), f"expected true or false, got {v!r}")
        return v

    def vector(self, key: str, length: int | None = None, default=_MISSING) -> list[float]:
        v = self.raw(key, default)
        if v is None:
            return v
        ok = isinstance(v, list) and all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in v)
        if not ok or (length is not None and len(v) != length):
            want = f"a list of {length} numbers" if length else "a list of numbers"
            raise InputError(self.field(key), f"expected {want}, got {v!r}")
        return [float(a) for a in v]

    def points(self, key: str, dim: int) -> list[list[float]]:
        v = self.raw(key)
        if not (isinstance(v, list) and v and all(isinstance(p, list) and len(p) == dim and all(
                isinstance(a, (int, float)) and not isinstance(a, bool) for a in p) for p in v)):
            raise InputError(self.field(key), f"expected a list of {dim}D points [[x, y{', z' if dim == 3 else ''}], "
                             f"...], got {v!r}")
        return [[float(a) for a in p] for p in v]

    def section(self, key: str, default=_MISSING) -> "Section":
        v = self.raw(key, {} if default is _MISSING else default)
        if v is None:
            v = {}
        return Section(v, self.field(key))

    def sections(self, key: str) -> list["Section"]:
        v = self.raw(key, [])
        if not isinstance(v, list) or not all(isinstance(el, dict) for el in v):
            raise InputError(self.field(key), f"expected a list of tables ([[{key}]] blocks), got {v!r}")
        out = []
        for i, el in enumerate(v):
            label = el.get("name", i)
            out.append(Section(el, f"{self.field(key)}.{label}"))
        return out

    def done(self, ignore: Iterable[str] = ()) -> None:
        """Reject keys that were not read (misspelt or unsupported options)."""
        extra = set(self.data) - self._read - set(ignore)
        if extra:
            k = sorted(extra)[0]
            raise InputError(self.field(k), unknown_key(k, self._read | set(ignore), "unknown key"))

    def check(self, key: str, ok: Callable[[Any], bool], message: str):
        v = self.raw(key)
        if not ok(v):
            raise InputError(self.field(key), f"{message}, got {v!r}")
        return v
