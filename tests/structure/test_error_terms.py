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
