import pytest

from polypore.core.errors import InputError
from polypore.setup.casefile import CaseFile, apply_override, builtin_names, load_case


def test_builtin_cases_load():
    names = builtin_names()
    for required in ("frictionless-3d", "dfm-2d", "dfm-3d", "single-crack", "fault-injection",
                     "six-fractures-static"):
        assert required in names
    for n in names:
        case = load_case(n)
        assert case.name == n and case.data["description"]


def test_overrides():
    case = load_case("dfm-2d", ["mesh.size=0.1", "fractures.F1.vertices=[[0.2, 0.7], [0.8, 0.7]]",
                                "mesh.generator=agglomerated", "contact.friction=0.6"])
    assert case.data["mesh"]["size"] == 0.1 and case.spec.mesh.size == 0.1
    assert case.data["mesh"]["generator"] == "agglomerated"
    assert case.data["fractures"][0]["vertices"] == [[0.2, 0.7], [0.8, 0.7]]
    assert case.data["contact"]["friction"] == 0.6
    assert "size = 0.1" in case.to_toml()
    with pytest.raises(InputError, match="no element named 'F9'"):
        load_case("dfm-2d", ["fractures.F9.vertices=[]"])
    with pytest.raises(InputError, match="KEY=VALUE"):
        apply_override({}, "mesh.size")


def test_unknown_case_and_bad_file(tmp_path):
    with pytest.raises(InputError, match="unknown case"):
        load_case("nope")
    with pytest.raises(InputError, match="does not exist"):
        load_case(str(tmp_path / "missing.toml"))
    bad = tmp_path / "bad.toml"
    bad.write_text("a = [1,")
    with pytest.raises(InputError, match="not valid TOML"):
        load_case(str(bad))


def _table(table: str, values: dict) -> CaseFile:
    mesh = {"generator": "cartesian", "lower": [0, 0], "upper": [1, 1], "cells": [2, 2]}
    return CaseFile("t", None, {"mesh": mesh, table: values})


@pytest.mark.parametrize("table,values,message", [
    ("material", {"E": -1.0, "nu": 0.25}, "material.E: must be positive, got -1.0"),
    ("material", {"E": 1e9, "nu": 0.7}, r"material.nu: must be in \(−1, 0.5\), got 0.7"),
    ("material", {"E": "1e9", "nu": 0.2}, "material.E: expected a positive number, got '1e9'"),
    ("material", {"E": 1e9, "nu": 0.2, "typo": 1}, "material.typo: unknown key"),
    ("material", {"E": 1e9, "nu": 0.2, "mu": 1e9}, "material.mu: give E and nu, or mu and lambda, not both"),
    ("material", {"E": 1e9}, r"material.nu: is required: give E and nu"),
    ("material", {"mu": 1e9, "lambda": -1e9}, "material.lambda: must exceed −2μ/3"),
    ("contact", {"law": "coulomb", "threshold": 1.0}, "contact.threshold: applies to law = 'tresca' only"),
    ("contact", {"law": "sticky"}, "contact.law: unknown value 'sticky'; allowed: frictionless, tresca, coulomb"),
    ("mechanics", {"biot": True}, "mechanics.biot: expected a number in \\[0, 1\\], got True"),
    ("mechanics", {"boundary": [{"name": "xmin", "u": [0, 0], "ux": 0}]},
     "mechanics.boundary.xmin.ux: conflicts with `u`"),
    ("mechanics", {"boundary": [{"name": "xmin"}]}, "mechanics.boundary.xmin.name: gives no condition"),
    ("mechanics", {"boundary": {"name": "xmin"}}, "mechanics.boundary: expected a list of tables"),
    ("mechanics", {"initial_stress": [[0, 0], [0]]}, "mechanics.initial_stress: expected a square matrix"),
])
def test_schema_names_field_value_and_what_is_allowed(table, values, message):
    with pytest.raises(InputError, match=f"^{message}"):
        _table(table, values).spec


def test_schema_accepts_every_builtin_and_fills_defaults():
    for n in builtin_names():
        spec = load_case(n).spec
        assert spec.mesh.perturb == 0.0 and spec.mesh.seed == load_case(n).data["mesh"].get("seed", 0)
    spec = load_case("dfm-2d").spec
    assert spec.physics == "poromechanics" and spec.mechanics.bubbles == "one-sided" and spec.contact.beta == 1.0
    assert spec.flow.viscosity == 1e-3 and spec.time.max_cuts == 4 and spec.flow.boundary[0].pressure == 1e5
