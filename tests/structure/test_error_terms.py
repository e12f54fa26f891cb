"""The layers below setup/ raise errors in their own terms (issue 27): an InputError or MeshError
of core, mesh, parallel, discretisation, assembly, solvers, models or io names the parameter of
the function that was called (``tip_size``, ``friction``, ``fracture F1``) or a file location
(``a.grdecl:ZCORN``), never a case-file key (``mesh.tip_size``). setup/ translates the lower
layers' names to case-file keys where it builds their objects (setup/translate.py)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "polypore"
LOWER = ("core", "mesh", "parallel", "discretisation", "assembly", "solvers", "models", "io")
# case-file keys that are not tables, and common words
SCALARS = {"name", "description", "model", "base_dir"}
# (module, field) raised in the module's own terms although it reads like a case-file table
ALLOWED = {
    ("mesh/cornerpoint/process.py", "regions"): "process_grid's own parameter `regions` (the name of a GRDECL cell "
                                                "keyword), not the [[regions]] table",
}


def tables() -> set[str]:
    from polypore.setup.schema.case import Case

    return set(Case.model_fields) - SCALARS


def _leading_text(node: ast.expr) -> str | None:
    """The literal start of a string or f-string argument, None for anything else."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr) and node.values and isinstance(node.values[0], ast.Constant):
        return node.values[0].value
    return None


def case_key_raises(path: Path, pattern: re.Pattern) -> list[tuple[int, str]]:
    """(line, field) of every InputError/MeshError(field, ...) whose field starts with a table name."""
    out = []
    for n in ast.walk(ast.parse(path.read_text(), str(path))):
        if not (isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in ("InputError", "MeshError")
                and n.args):
            continue
        text = _leading_text(n.args[0])
        if text is not None and pattern.match(text):
            out.append((n.lineno, ast.unparse(n.args[0])))
    return out


def test_lower_layers_raise_in_their_own_terms():
    pattern = re.compile(rf"^({'|'.join(sorted(tables(), key=len, reverse=True))})(\.|\[|$)")
    bad = []
    for layer in LOWER:
        for path in sorted((SRC / layer).rglob("*.py")):
            rel = path.relative_to(SRC).as_posix()
            for line, field in case_key_raises(path, pattern):
                if (rel, ast.literal_eval(field) if field[0] in "'\"" else field) not in ALLOWED:
                    bad.append(f"{rel}:{line}: {field}")
    assert not bad, ("errors of the lower layers name case-file keys; raise them in the function's own terms "
                     "and translate in setup/ (setup/translate.py):\n" + "\n".join(bad))


def field_arguments(path: Path, pattern: re.Pattern) -> list[tuple[int, str]]:
    """(line, text) of every string argument of a call that is a case-file key alone (a table name,
    a dot, an identifier, no spaces: a field handed to a helper that raises, such as
    ``_positive(x, "flow.viscosity")``), or a module-level FIELD constant set to one."""
    out = []
    for n in ast.walk(ast.parse(path.read_text(), str(path))):
        args = []
        if isinstance(n, ast.Call):
            args = [*n.args, *(k.value for k in n.keywords)]
        elif isinstance(n, ast.Assign) and any(isinstance(t, ast.Name) and t.id.isupper() for t in n.targets):
            args = [n.value]
        elif isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = [d for d in n.args.defaults + n.args.kw_defaults if d is not None]
        for a in args:
            text = _leading_text(a)
            if text and " " not in text and pattern.match(text) and re.match(r"^[a-z_]+\.[a-z_{]", text):
                out.append((getattr(a, "lineno", n.lineno), text))
    return out


def test_lower_layers_hand_no_case_keys_to_their_helpers():
    """The fields the lower layers pass on (to ``evaluate``, ``_positive``, …) or keep as defaults
    are their own names too: a run-time error is translated by the run (setup/translate.py,
    RUN_FLOW …), which knows the case."""
    pattern = re.compile(rf"^({'|'.join(sorted(tables(), key=len, reverse=True))})(\.|\[|$)")
    bad = [f"{path.relative_to(SRC).as_posix()}:{line}: {text}"
           for layer in LOWER for path in sorted((SRC / layer).rglob("*.py"))
           for line, text in field_arguments(path, pattern)]
    assert not bad, "case-file keys handed on by the lower layers:\n" + "\n".join(bad)


@pytest.mark.parametrize("own, keys, expected", [
    ("tip_size", "MESH", "mesh.tip_size"),
    ("fracture F1.vertices", "MESH", "fractures.F1.vertices"),
    ("fracture R:x=0.5", "MESH", "fractures.R:x=0.5"),
    ("cells.grdecl:ZCORN", "MESH", None),            # a file location stays as it is
    ("regions.R1.lower", "MESH", None),              # already a case-file key
    ("boundary.left", "FLOW", "flow.boundary.left"),
    ("displacement.left", "MECHANICS", "mechanics.boundary.left"),
    ("params.k", "POROMECHANICS", "parameters.k"),
])
def test_case_key(own, keys, expected):
    from polypore.setup import translate

    assert translate.case_key(own, getattr(translate, keys)) == expected


def test_case_keys_reraises_with_the_key():
    from polypore.core.errors import InputError, MeshError
    from polypore.setup.translate import MESH, case_keys

    with pytest.raises(MeshError, match=r"^mesh\.cells: degenerate$") as exc:
        with case_keys(MESH):
            raise MeshError("cells", "degenerate")
    assert exc.value.field == "mesh.cells" and exc.value.__cause__ is None
    with pytest.raises(InputError, match=r"^a\.grdecl:ZCORN: bad$"):
        with case_keys(MESH):
            raise InputError("a.grdecl:ZCORN", "bad")
