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
    ("contact", {"law": "coulomb", "critical_slip": 1e-3},
     "contact.critical_slip: applies to law = 'slip-weakening' or 'rate-and-state' only"),
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


def test_base_dir_is_not_a_case_file_key(tmp_path, cli):
    """Issue 25: ``base_dir = "/etc"`` in a case file made ``mesh.file = "passwd"`` read
    /etc/passwd. It is set by polypore (the case file's folder), never by the file or --set."""
    case = tmp_path / "c.toml"
    case.write_text('base_dir = "/etc"\n[mesh]\ngenerator = "grdecl"\nfile = "passwd"\n')
    with pytest.raises(InputError) as exc:
        load_case(str(case))
    assert exc.value.field == "base_dir" and "not a case-file key" in str(exc.value)
    case.write_text('[mesh]\ngenerator = "grdecl"\nfile = "passwd"\n')
    with pytest.raises(InputError) as exc:
        load_case(str(case), ["base_dir=/etc"])
    assert exc.value.field == "--set" and "cannot be set" in str(exc.value)
    code, _, err = cli("mesh", str(case), "--set", "base_dir=/etc", "--out", str(tmp_path / "o"))
    assert code == 2 and "root" not in err and not (tmp_path / "o").exists()
    from polypore.setup.schema import json_schema
    assert "base_dir" not in json_schema()["properties"]


def test_case_toml_has_no_base_dir_and_an_absolute_mesh_file(tmp_path):
    """The copy written into a run folder (case.toml) loads again from there: no base_dir, and a
    relative mesh.file made absolute against the case file's folder."""
    from polypore.mesh.cornerpoint import generate_grid, write_grdecl

    (tmp_path / "case").mkdir()
    write_grdecl(generate_grid(2, 2, 1), tmp_path / "case" / "g.grdecl")
    src = tmp_path / "case" / "c.toml"
    src.write_text('[mesh]\ngenerator = "grdecl"\nfile = "g.grdecl"\n')
    case = load_case(str(src))
    assert case.spec.base_dir == str((tmp_path / "case").resolve())
    copy = tmp_path / "run" / "case.toml"
    copy.parent.mkdir()
    copy.write_text(case.to_toml())
    import tomllib
    assert "base_dir" not in tomllib.loads(copy.read_text())
    again = load_case(str(copy))
    assert again.spec.mesh.file == str((tmp_path / "case" / "g.grdecl").resolve())


# -- found by the input fuzz (issue 25, tests/inputfuzz.py) ---------------------------------------------
def test_oversized_case_file_is_refused_unread(tmp_path):
    """A 50 MB case file (comments) was parsed, for seconds, and accepted; a sparse 200 MB one was
    read whole. Refused by its size, before it is read."""
    import time

    from conftest import STATIC_2D

    from polypore.setup.casefile import MAX_CASE_BYTES

    p = tmp_path / "big.toml"
    p.write_text(STATIC_2D)
    with open(p, "r+b") as f:
        f.truncate(200 * 2**20)
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"has 200\.0 MiB; a case file may have at most 8 MiB") as exc:
        load_case(str(p))
    assert exc.value.field == "case" and time.perf_counter() - t0 < 1.0
    p.write_text(STATIC_2D + "#" * (MAX_CASE_BYTES - len(STATIC_2D) - 1) + "\n")   # the limit itself: read
    assert load_case(str(p)).name == "t"


def test_byte_order_mark_is_accepted(tmp_path):
    """A UTF-8 byte-order mark (some Windows editors) made the file "not valid TOML" at line 1."""
    from conftest import STATIC_2D

    p = tmp_path / "bom.toml"
    p.write_bytes(b"\xef\xbb\xbf" + STATIC_2D.replace("\n", "\r\n").encode())
    assert load_case(str(p)).spec.material.E == 1e9


def test_long_unknown_key_is_clipped_in_the_error(tmp_path):
    """An unknown key of 10^6 characters was quoted whole (twice) in the error."""
    from conftest import STATIC_2D

    p = tmp_path / "k.toml"
    p.write_text(STATIC_2D.replace("[material]\n", "[material]\n" + "k" * 10**6 + " = 1\n"))
    with pytest.raises(InputError, match="unknown key") as exc:
        load_case(str(p))
    assert exc.value.field == "material." + "k" * 48 + "…(1000000 characters)"
    assert len(str(exc.value)) < 1000
