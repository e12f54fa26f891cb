import pytest

from polypore.cases.casefile import Section, apply_override, builtin_names, load_case
from polypore.core.errors import InputError


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
                                "mesh.generator=cartesian", "contact.friction=0.6"])
    assert case.data["mesh"]["size"] == 0.1
    assert case.data["mesh"]["generator"] == "cartesian"
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


def test_section_validation():
    s = Section({"E": -1.0, "law": "coulomb", "nu": 0.7, "typo": 1}, "material")
    with pytest.raises(InputError, match="material.E: must be positive"):
        s.number("E", positive=True)
    with pytest.raises(InputError, match="unknown value 'coulomb'; allowed: tresca, frictionless"):
        s.string("law", choices=("tresca", "frictionless"))
    with pytest.raises(InputError, match=r"material.nu: must lie in \(-1, 0.5\)"):
        s.number("nu", lo=-1, hi=0.5)
    with pytest.raises(InputError, match="material.typo: unknown key"):
        s.done()
