"""Random mutations of the built-in case files and of ``--set`` overrides, run through load and
set-up (tests/unit/setup/test_fuzz_casefiles.py, benchmarks/fuzz_casefiles.py).

A mutation changes a value anywhere in the case (wrong types, out-of-range numbers, random
expressions with huge exponents and divisions by zero), deletes a key or a table, adds an
unknown key (often a near-miss of a real one) or applies a random ``--set`` override. The
set-up is everything up to the model objects: validation, the resource guards, the mesh, the
mechanics/flow/poromechanics set-up and the models' constructors; no solve. The meshes are
coarsened first (``--set`` overrides, so that they go through the schema too) and cached by
their tables, and the guards are tight, so an example takes milliseconds unless it remeshes.

The only outcomes allowed are success and an :class:`~polypore.core.errors.InputError` whose
field names a part of the case; anything else is a bug.
"""

from __future__ import annotations

import copy
import json
import math
import string
from functools import lru_cache

from hypothesis import strategies as st

from polypore.core.errors import InputError
from polypore.setup.casefile import CaseFile, apply_override, builtin_names, case_model, load_case
from polypore.setup.limits import check_limits
from polypore.setup.schema import Case

NAMES = builtin_names()
MAX_CELLS = 20_000         # the guards of the fuzz: coarse meshes (Emerald: 15,498 grid cells), short schedules
MAX_STEPS = 10_000
# the first part of a field an InputError may name: a table or key of the case, or an option
FIELD_HEADS = Case.keys() | {"--set", "--levels"}


def coarse_overrides(name: str) -> list[str]:
    """``--set`` overrides that make the case's mesh coarse (a few hundred cells)."""
    data = load_case(name).data
    m = data["mesh"]
    if m.get("generator") in ("file", "grdecl", "cornerpoint"):
        return []                 # a given grid (fault indices refer to its cells): kept as it is
    extent = max(h - lo for lo, h in zip(m["lower"], m["upper"]))
    # every polygon edge is resolved: a 64-gon as an 8-gon
    out = [f"fractures.{f['name']}.sides=8" for f in data.get("fractures", []) if f.get("sides", 0) > 8]
    if "cells" in m:
        out.append(f"mesh.cells={[min(int(c), 3) for c in m['cells']]}")
    if "size" in m:
        size = max(m["size"], extent / (4 if len(m["lower"]) == 2 else 3))
        out.append(f"mesh.size={size!r}")
        for key in ("fracture_size", "tip_size"):
            if key in m:
                # with tip grading the band around the tips scales with the fracture size: no grading
                fine = size if key == "fracture_size" and "tip_size" in m else min(size / 3, 8 * m[key])
                out.append(f"mesh.{key}={max(m[key], fine)!r}")
    return out


@lru_cache(maxsize=None)
def _base(name: str) -> CaseFile:
    return load_case(name, coarse_overrides(name))


def base_case(name: str) -> CaseFile:
    """The coarse built-in case (a fresh copy to mutate)."""
    c = _base(name)
    return CaseFile(c.name, c.source, copy.deepcopy(c.data), c.overrides)


# -- values ----------------------------------------------------------------------------------------
SPECIAL_NUMBERS = [0, -1, 1, 2, 0.5, -0.5, 0.4999, 90, 1e-12, 1e-300, 5e-324, 1e300, 1.7e308, 10**400, -10**30,
                   math.inf, -math.inf, math.nan, 9999999999]
SPECIAL_EXPRESSIONS = ["2**9999999999", "9**9**9", "1/0", "1 % 0", "10.0**400", "1e400", "0/0", "log(0)", "sqrt(-1)",
                       "x/0", "0.005/x", "exp(1000*x)", "where(x > 0, 1/x, 0)", "(" * 300 + "1" + ")" * 300,
                       "+".join(["x"] * 3000), "x" * 20000, "exact", "inf", "nan", "", " ", "sin", "sin(1, 2)",
                       "__import__('os')", "x.real", "x[0]", "lambda: 1", "'text'", "[1, 2]", "{1: 2}", "t**t**t",
                       "D", "L", "d", "d**3/12", "-1e-3", "1e-3*D", "minimum(1, 2, 3)", "heaviside(x)", "not x",
                       "x if y else z", "1 // 2", "1 @ 2", "f'{x}'", "*x", "x == y == z", "1 and 0 or 2"]
NAMES_IN_EXPRESSIONS = ["x", "y", "z", "t", "D", "L", "d", "pi", "e", "T", "sigma", "p", "a", "day", "mass_rate",
                        "foo", "sin", "exact"]


@st.composite
def expressions(draw, depth: int = 3):
    """Expression texts: atoms, unary and binary operators, calls, conditionals."""
    if depth == 0 or draw(st.integers(0, 3)) == 0:
        return draw(st.one_of(st.sampled_from(NAMES_IN_EXPRESSIONS), st.sampled_from(SPECIAL_EXPRESSIONS[:14]),
                              st.integers(-10**6, 10**6).map(str), st.floats(allow_nan=False).map(repr),
                              st.sampled_from(["1e308", "1e-308", "0", "2", "10"])))
    kind = draw(st.integers(0, 4))
    a = draw(expressions(depth - 1))
    if kind == 0:
        return f"{draw(st.sampled_from(['-', '+', 'not ']))}({a})"
    if kind == 1:
        fn = draw(st.sampled_from(["sin", "exp", "log", "sqrt", "abs", "arctan", "tanh", "floor", "minimum",
                                   "where", "clip", "hypot", "open", "eval"]))
        args = [a] + [draw(expressions(depth - 1)) for _ in range(draw(st.integers(0, 2)))]
        return f"{fn}({', '.join(args)})"
    if kind == 2:
        return f"({a}) if ({draw(expressions(depth - 1))}) else ({draw(expressions(depth - 1))})"
    op = draw(st.sampled_from(["+", "-", "*", "/", "**", "%", "<", ">=", "==", " and ", " or "]))
    return f"({a}){op}({draw(expressions(depth - 1))})"


def _scalars():
    return st.one_of(st.booleans(), st.integers(-10**30, 10**30), st.floats(), st.sampled_from(SPECIAL_NUMBERS),
                     st.text(string.printable, max_size=12), expressions(), st.sampled_from(SPECIAL_EXPRESSIONS))


def values():
    """Any TOML value: scalars, lists (vectors, matrices, points) and small tables."""
    scalar = _scalars()
    return st.one_of(scalar, scalar, st.lists(scalar, max_size=4),
                     st.lists(st.lists(st.one_of(st.floats(-10, 10), scalar), min_size=1, max_size=3), max_size=4),
                     st.dictionaries(st.sampled_from(["name", "u", "E", "a", "reservoir", "xmin", "F1", "points"]),
                                     scalar, max_size=3))


def override_texts():
    """The VALUE of a --set KEY=VALUE: TOML literals and anything else (kept as text)."""
    return st.one_of(st.sampled_from(["1", "-1", "0", "1e-12", "1e400", "inf", "nan", "true", "[1, 2]", "[[0, 0]]",
                                      "[0, 0, 0]", "{a = 1}", '"text"', "[", "]]", "1979-05-27", "0x10", "'x'",
                                      "", " ", "=", "a=b", "1\nname = 'x'"]),
                     st.text(string.printable, max_size=16), expressions(2))


# -- mutations ---------------------------------------------------------------------------------------
def _containers(node, path=()):
    """(path, container) of every table and list in the case."""
    out = [(path, node)]
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        if isinstance(v, (dict, list)):
            out += _containers(v, path + (k,))
    return out


def _near_miss(draw, key: str) -> str:
    """A typo of ``key``: a letter dropped, doubled or swapped, or another case."""
    if len(key) < 2:
        return key + "x"
    i = draw(st.integers(0, len(key) - 2))
    return draw(st.sampled_from([key[:i] + key[i + 1:], key[:i] + key[i] + key[i:], key[:i] + key[i + 1] + key[i]
                                 + key[i + 2:], key.upper(), key + "s"]))


def _dotted(path, data) -> str:
    """A path as --set spells it (list elements by name where they have one)."""
    parts, node = [], data
    for k in path:
        if isinstance(node, list):
            el = node[k]
            parts.append(el["name"] if isinstance(el, dict) and isinstance(el.get("name"), str) else str(k))
        else:
            parts.append(str(k))
        node = node[k]
    return ".".join(parts)


ACTIONS = ("set", "set", "nudge", "nudge", "delete", "add", "override", "override")


def mutate(draw, case: CaseFile, actions=ACTIONS) -> list[str]:
    """Apply 1–3 random mutations to ``case.data`` in place; returns what was done (for reports)."""
    done = []
    for _ in range(draw(st.integers(1, 3))):
        data = case.data
        action = draw(st.sampled_from(actions))
        path, node = draw(st.sampled_from(_containers(data)))
        keys = list(node) if isinstance(node, dict) else list(range(len(node)))
        if action == "override":
            if keys and draw(st.booleans()):
                key = draw(st.sampled_from(keys))
                target = _dotted(path + (key,), data)
            else:
                target = ".".join([_dotted(path, data), draw(st.sampled_from(["typo", "x", "0", "F1", "size"]))])
            item = f"{target.strip('.')}={draw(override_texts())}"
            done.append(f"--set {item}")
            try:
                apply_override(data, item)
            except InputError as exc:
                done.append(f"(--set refused: {exc})")
                raise
            continue
        if action == "add" and isinstance(node, dict):
            key = _near_miss(draw, draw(st.sampled_from(keys))) if keys and draw(st.booleans()) else draw(
                st.sampled_from(["typo", "solvr", "Size", "frction", "extra"]))
            node[key] = draw(values())
            done.append(f"add {_dotted(path, data)}.{key} = {node[key]!r:.80}")
            continue
        if not keys:
            continue
        key = draw(st.sampled_from(keys))
        if action == "nudge":   # a plausible value nearby: valid often, so the set-up runs further
            old = node[key]
            if isinstance(old, list) and old and all(isinstance(v, (int, float)) for v in old):
                i = draw(st.integers(0, len(old) - 1))
                node[key] = old[:i] + [_nudge(draw, old[i])] + old[i + 1:]
            elif isinstance(old, (int, float)) and not isinstance(old, bool):
                node[key] = _nudge(draw, old)
            elif isinstance(old, str):
                node[key] = draw(st.sampled_from([f"({old}) * 2", f"-({old})", f"{old} + x", f"({old}) / (x - 0.5)",
                                                  f"({old}) * t", f"{old}_", "exact", old.upper()]))
            done.append(f"nudge {_dotted(path, data)}[{key!r}] = {node[key]!r:.80}")
            continue
        if action == "delete":
            del node[key]
            done.append(f"delete {_dotted(path, data)}[{key!r}]")
        else:
            node[key] = draw(values())
            done.append(f"set {_dotted(path, data)}[{key!r}] = {node[key]!r:.80}")
    return done


def _nudge(draw, v):
    f = draw(st.sampled_from([0, -1, 0.5, 2, 10, 1e-3, 1e3, 1 + 1e-9, 1 - 1e-9]))
    out = v * f if not (isinstance(v, int) and abs(v) > 2**53) else v
    return int(out) if isinstance(v, int) and not isinstance(v, bool) and f in (0, -1, 2, 10) else out


@st.composite
def mutated_cases(draw, actions=ACTIONS):
    """(case, description): a coarse built-in case with random mutations (the InputError instead of
    the case if a --set was refused by apply_override itself)."""
    name = draw(st.sampled_from(NAMES))
    case = base_case(name)
    try:
        what = mutate(draw, case, actions)
    except InputError as exc:
        return exc, [name, "--set refused"]
    return case, [name] + what


# -- set-up ------------------------------------------------------------------------------------------
_MESHES: dict = {}


def _mesh(case: CaseFile):
    """The case's mesh, cached by the tables that make it (or the InputError they raise)."""
    from polypore.setup.meshing import build_fractured_mesh

    spec = case.spec
    key = json.dumps([spec.mesh.model_dump(), [f.model_dump() for f in spec.fractures],
                      [r.model_dump() for r in spec.regions], [b.model_dump() for b in spec.boundaries],
                      spec.base_dir], sort_keys=True, default=repr)
    if key not in _MESHES:
        if len(_MESHES) > 200:
            _MESHES.clear()
        try:
            _MESHES[key] = build_fractured_mesh(case)
        except InputError as exc:
            _MESHES[key] = exc
    fm = _MESHES[key]
    if isinstance(fm, InputError):
        raise fm
    return fm


def set_up(case: CaseFile) -> None:
    """Validate, guard, mesh and set the case up to its model objects (no solve)."""
    from polypore.setup.flow import flow_setup
    from polypore.setup.mechanics import mechanics_setup
    from polypore.setup.poromechanics import monitor_points, poro_setup

    check_limits(case.spec, max_cells=MAX_CELLS, max_steps=MAX_STEPS, memory=math.inf)
    case.to_toml()                       # a run writes case.toml first
    fm = _mesh(case)
    model = case_model(case)
    if model == "mechanics":
        mechanics_setup(case, fm).problem(fm)          # as runs/static.py
    elif model == "flow":
        flow_setup(case, fm).model()
    else:
        poro_setup(case, fm)
        monitor_points(case, fm.mesh)


def outcome(case) -> tuple[str, str | None]:
    """("ok", None) or ("input", field); any other exception propagates (a bug)."""
    if isinstance(case, InputError):
        return "input", case.field
    try:
        set_up(case)
    except InputError as exc:
        return "input", exc.field
    return "ok", None


def names_a_field(field: str | None, case) -> bool:
    """Whether an InputError's field names a part of the case: a table or key of the schema, a key
    the case gave (an unknown one is named as given) or an option."""
    if not field:
        return False
    head = field.split(".")[0].split("[")[0]
    given = set(case.data) if isinstance(case, CaseFile) else set()
    return head in FIELD_HEADS or head in given or field.startswith("--set")
