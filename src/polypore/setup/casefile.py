"""Case files (TOML): loading, ``--set`` overrides and validation against the schema.

A case is one TOML document. Built-in cases are TOML files shipped in
``polypore/cases/data``; users pass a name or a path. ``--set key=value`` overrides are applied
to the parsed document, then the whole case is validated by the schema
(:mod:`polypore.setup.schema`): every error names the field, the bad value and what is allowed,
and an error in a value an override set also names the override.
"""

from __future__ import annotations

import codecs
import copy
import os
import tomllib
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any, Iterable

import tomli_w

from ..core.errors import InputError
from ..core.paths import not_a_file
from .schema import MODELS, Case, validate

# the largest case file read (bytes): real ones are a few kB
MAX_CASE_BYTES = 8 * 2**20
CASES = "polypore.cases"   # the package that ships the built-in case files
DATA = "data"

__all__ = ["MODELS", "CaseFile", "apply_override", "builtin_names", "case_model", "load_case"]


def builtin_names() -> list[str]:
    """Names of the built-in cases (the TOML files shipped with the package)."""
    root = resources.files(CASES) / DATA
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read_toml(raw: bytes, where: str) -> dict:
    if raw.startswith(codecs.BOM_UTF8):   # written by some editors (Windows): not part of the text
        raw = raw[len(codecs.BOM_UTF8):]
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError("case", f"{where} is not UTF-8 text (byte {exc.start}: {raw[exc.start:exc.start + 1]!r}); "
                         "save it as UTF-8") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError("case", f"{where} is not valid TOML: {exc}") from None
    except RecursionError:   # tomllib parses nested arrays and inline tables recursively
        raise InputError("case", f"{where} nests arrays or tables too deeply for the TOML reader; a case "
                         f"file needs at most {MAX_DEPTH} levels") from None
    _check_depth(data, where)
    return data


# deeper than any case file needs (a few levels), shallow enough that everything reading the data
# recursively (validation, to_toml) stays far from Python's recursion limit
MAX_DEPTH = 32


def _check_depth(data, where: str) -> None:
    """InputError if ``data`` nests tables or arrays more than MAX_DEPTH levels (checked without
    recursion: the data may be as deep as the parser allows)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise InputError("case", f"{where} nests tables or arrays {MAX_DEPTH + 1} or more levels deep; "
                             f"a case file needs at most {MAX_DEPTH}")
        children = value.values() if isinstance(value, dict) else value
        stack.extend((v, depth + 1) for v in children if isinstance(v, (dict, list)))


@dataclass
class CaseFile:
    """A loaded case: its name, where it came from and its (overridden) data.

    ``spec`` is the data validated by the schema (computed on first use, so a CaseFile built
    from data in code is validated too); the set-up reads it.
    """

    name: str
    source: str | None
    data: dict
    overrides: tuple = field(default=(), repr=False)

    def to_toml(self) -> str:
        """The fully resolved case as TOML text (written as ``case.toml``): without ``base_dir``,
        which is not a case-file key, and with a relative ``mesh.file`` made absolute against it,
        so that the copy runs from another folder."""
        data = {k: v for k, v in self.data.items() if k != "base_dir"}
        base = self.data.get("base_dir")
        mesh = data.get("mesh")
        if base and isinstance(mesh, dict) and isinstance(mesh.get("file"), str) \
                and not Path(mesh["file"]).is_absolute() and (Path(base) / mesh["file"]).is_file():
            data["mesh"] = {**mesh, "file": str(Path(base) / mesh["file"])}
        return tomli_w.dumps(data)

    @cached_property
    def spec(self) -> Case:
        """The validated case (:class:`polypore.setup.schema.Case`); InputError naming the field."""
        try:
            return validate(self.data)
        except InputError as exc:
            raise _with_override(exc, self.overrides) from None


def _with_override(exc: InputError, overrides) -> InputError:
    """The error, naming the ``--set`` override that set the field (or a table around it)."""
    for item in overrides:
        key = ".".join(p for p in item.partition("=")[0].strip().split(".") if p)
        if key and (exc.field == key or exc.field.startswith(key + ".") or key.startswith(exc.field + ".")):
            return InputError(exc.field, f"{exc.detail} (set by --set {item})")
    return exc


def _exists(path: Path, file: bool = False) -> bool:
    """Path.exists / is_file, but a name the system cannot look up (over 255 bytes) is an InputError."""
    try:
        return path.is_file() if file else path.exists()
    except OSError as exc:
        raise InputError("case", f"case file {str(path)!r} cannot be read: {exc.strerror or exc}") from None


def load_case(name_or_path: str, overrides: Iterable[str] = ()) -> CaseFile:
    """Load a built-in case by name or a TOML file by path, apply ``KEY=VALUE`` overrides and
    validate the result (InputError naming the field)."""
    path = Path(name_or_path)
    overrides = tuple(overrides)
    stem_name = None
    if name_or_path in builtin_names():
        raw = (resources.files(CASES) / DATA / f"{name_or_path}.toml").read_bytes()
        data = _read_toml(raw, f"built-in case {name_or_path!r}")
        source = f"builtin:{name_or_path}"
    elif path.suffix == ".toml" or _exists(path):
        if not _exists(path, file=True):
            raise InputError("case", f"case file {str(path)!r} {not_a_file(path) or 'does not exist'}; give a "
                             f"built-in case name ({', '.join(builtin_names())}) or the path of a TOML case file")
        try:
            with open(path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                # refused before it is read: a case file is a few kB, a huge file is a mistake (a mesh?)
                raw = f.read(MAX_CASE_BYTES + 1) if size <= MAX_CASE_BYTES else b""
        except OSError as exc:
            raise InputError("case", f"case file {str(path)!r} cannot be read: {exc.strerror or exc}") from None
        if max(size, len(raw)) > MAX_CASE_BYTES:
            raise InputError("case", f"case file {str(path)!r} has {max(size, len(raw)) / 2**20:.1f} MiB; a case "
                             f"file may have at most {MAX_CASE_BYTES >> 20} MiB (meshes and grids go in their own "
                             "files: mesh.file)")
        data = _read_toml(raw, f"case file {str(path)!r}")
        source = str(path.resolve())
        if "name" not in data:
            stem_name = path.stem
        data.setdefault("name", path.stem)
    else:
        raise InputError("case", f"unknown case {name_or_path!r}; built-in cases are {', '.join(builtin_names())}, "
                         "or give the path of a .toml case file")
    if "base_dir" in data:
        raise InputError("base_dir", "is not a case-file key: polypore sets it to the case file's folder, where "
                         "relative mesh files are found; remove it (mesh.file may be an absolute path)")
    data = copy.deepcopy(data)
    for item in overrides:
        if item.partition("=")[0].strip().split(".")[0] == "base_dir":
            raise InputError("--set", f"{item.partition('=')[0].strip()!r} cannot be set: base_dir is the case "
                             "file's folder, set by polypore")
        apply_override(data, item)
    if source is not None and not source.startswith("builtin:"):
        data["base_dir"] = str(path.resolve().parent)
    if overrides:
        _check_depth(data, "the case with its --set overrides")
    case = CaseFile(str(data.get("name", path.stem)), source, data, overrides)
    try:
        case.spec
    except InputError as exc:
        if exc.field == "name" and stem_name is not None and data.get("name") == stem_name:
            raise InputError("name", f"{exc.detail} (taken from the file name; set name = \"...\" in the case "
                             "file)") from None
        raise
    return case


def case_model(case: CaseFile) -> str:
    """The physics a case asks for (one of MODELS): its ``model`` key, else "poromechanics" for a
    case with a [flow] table and mechanics tables, "flow" for a [flow] table alone, else
    "mechanics"."""
    return case.spec.physics


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare word or an expression: keep it as a string
    except RecursionError:
        raise InputError("--set", f"the value {text[:40]!r}... nests arrays or tables too deeply "
                         f"(at most {MAX_DEPTH} levels)") from None


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
