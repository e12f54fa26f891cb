"""The case-file schema (issue 14): tables a model does not read, conflicts, finite vectors, the
error of a --set override, non-UTF-8 files, and the JSON Schema that ``polypore schema`` prints
for TOML editors (checked here with a small validator of the keywords it uses)."""

import json

import pytest

from polypore.core.errors import InputError
from polypore.setup.casefile import CaseFile, builtin_names, load_case
from polypore.setup.schema import json_schema

from conftest import STATIC_2D

MESH = {"generator": "cartesian", "lower": [0.0, 0.0], "upper": [1.0, 1.0], "cells": [2, 2]}


def _spec(**tables):
    return CaseFile("t", None, {"mesh": dict(MESH), **tables}).spec


@pytest.mark.parametrize("tables,field,fragment", [
    # tables the case's model does not read
    ({"material": {"E": 1e9, "nu": 0.2}, "time": {"end": 1.0, "step": 0.1}}, "time",
     "a mechanics case (model inferred from its tables) does not read [time]: a static case has no time loop"),
    ({"model": "flow", "monitor": {"points": {"a": [0.5, 0.5]}}}, "monitor", "a flow case (model = 'flow')"),
    ({"model": "flow", "material": {"E": 1e9, "nu": 0.2}}, "material", "does not read [material]"),
    ({"model": "mechanics", "flow": {"permeability": 1e-15}}, "flow", "set model = \"poromechanics\""),
    ({"material": {"E": 1e9, "nu": 0.2}, "initial_state": {"rock_density": 2e3, "stress_ratio": 0.7}},
     "initial_state", "poromechanics runs only"),
    ({"material": {"E": 1e9, "nu": 0.2}, "flow": {}, "exact": {"solution": "contact-2d"}}, "exact",
     "no exact solution is available for poromechanics"),
    ({"model": "flow", "exact": {"solution": "contact-2d"}}, "exact.solution", "not a solution of a flow case"),
    ({"material": {"E": 1e9, "nu": 0.2}, "solver": {"linear_tolerance": 1e-8}}, "solver.linear_tolerance",
     "applies to flow only"),
    ({"material": {"E": 1e9, "nu": 0.2}, "solver": {"predictor": "none"}}, "solver.predictor",
     "applies to poromechanics only; this is a mechanics case"),
    ({"material": {"E": 1e9, "nu": 0.2}, "flow": {}, "solver": {"predictor": "quadratic"}}, "solver.predictor",
     "allowed: linear, none"),
    # conflicts
    ({"material": {"E": 1e9, "nu": 0.2}, "materials": [{"region": "a", "E": 1e9, "nu": 0.2}]}, "materials",
     "not both"),
    ({"model": "flow", "flow": {"porosity": 0.1, "biot_modulus": 1e9, "fluid_compressibility": 1e-9}},
     "flow.porosity", "either biot_modulus or porosity"),
    ({"model": "flow", "flow": {"porosity": 0.1}}, "flow.fluid_compressibility", "is required with porosity"),
    ({"model": "flow", "flow": {"boundary": [{"name": "xmin", "pressure": 1.0}, {"name": "xmin", "flux": 0.0}]}},
     "flow.boundary.xmin.name", "'xmin' is given twice"),
    ({"model": "flow", "flow": {"boundary": [{"name": "xmin", "pressure": 1.0, "flux": 0.0}]}},
     "flow.boundary.xmin.pressure", "exactly one of pressure"),
    ({"model": "flow", "flow": {"steady": True}, "time": {"end": 1.0, "step": 0.5}}, "flow.steady",
     "has a [time] table"),
    ({"model": "flow", "flow": {"initial_pressure": 0.0}}, "flow.initial_pressure", "only applies to a transient"),
    ({"model": "flow", "time": {"end": 1.0, "step": 0.5, "output_every": 2, "output_times": [1.0]}},
     "time.output_times", "not both"),
    ({"contact": {"law": "tresca", "friction": 0.5}}, "contact.friction", "applies to law = 'coulomb' or 'slip-weakening' or 'rate-and-state' only"),
    ({"contact": {"law": "coulomb", "friction": 0.5, "a": 0.01}}, "contact.a", "applies to law = 'rate-and-state' only"),
    ({"contact": {"law": "coulomb", "friction": 0.5, "state_law": "slip"}}, "contact.state_law",
     "applies to law = 'rate-and-state' only"),
    ({"contact": {"law": "rate-and-state", "friction": 0.6, "a": 0.01, "b": 0.015, "critical_slip": 1e-3,
                  "initial_slip_rate": 1e-9}}, "contact.shear_wave_speed", "radiation_damping = false"),
    ({"contact": {"law": "rate-and-state", "state_law": "ageing"}}, "contact.state_law", "aging"),
    ({"mechanics": {"body_force": "exact"}}, "mechanics.body_force", '"exact" needs an [exact] solution'),
    ({"fractures": [{"name": "F", "vertices": [[0, 0], [1, 1]]}, {"name": "F", "vertices": [[0, 1], [1, 0]]}]},
     "fractures.F.name", "'F' is given twice"),
    ({"fractures": [{"name": "F", "vertices": [[0, 0, 0], [1, 1, 0]]}]}, "fractures.F.vertices", "must be 2D points"),
    ({"fractures": [{"name": "F", "vertices": [[0, 0], [1, 1]], "normal": [0, 0, 1]}]}, "fractures.F.normal",
     "3D meshes only"),
    ({"parameters": {"x": 1.0}}, "parameters.x", "a coordinate/time variable"),
    ({"parameters": {"sin": 1.0}}, "parameters.sin", "a function"),
    # non-finite vectors and points (TOML spells inf and nan as numbers)
    ({"fractures": [{"name": "F", "vertices": [[0, 0], [float("inf"), 1]]}]}, "fractures.F.vertices",
     "every coordinate must be a finite number, got inf"),
    ({"regions": [{"name": "r", "lower": [0, float("nan")], "upper": [1, 1]}]}, "regions.r.lower",
     "every value must be a finite number, got nan"),
    ({"model": "poromechanics", "monitor": {"points": {"a": [0.5, float("inf")]}}}, "monitor.points.a",
     "finite coordinates"),
])
def test_rules_across_tables(tables, field, fragment):
    with pytest.raises(InputError) as exc:
        _spec(**tables)
    assert exc.value.field == field and fragment in exc.value.detail, str(exc.value)


def test_mesh_keys_of_another_generator_and_a_missing_size():
    with pytest.raises(InputError, match=r"^mesh.rounds: does not apply to generator = 'cartesian' \(only to "
                       "agglomerated\\)"):
        CaseFile("t", None, {"mesh": {**MESH, "rounds": 3}}).spec
    with pytest.raises(InputError, match="^mesh.size: is required with generator = 'simplicial'"):
        CaseFile("t", None, {"mesh": {"lower": [0, 0], "upper": [1, 1]}}).spec
    with pytest.raises(InputError, match=r"^mesh.lower: expected a list of 2 or 3 coordinates \(m\), got \[0\]"):
        CaseFile("t", None, {"mesh": {"lower": [0], "upper": [1], "size": 1}}).spec


def test_a_set_override_is_named_in_the_error(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text(STATIC_2D)
    with pytest.raises(InputError, match=r"^material.E: must be positive, got -5 \(set by --set material.E=-5\)$"):
        load_case(str(path), ["mesh.cells=[4, 4]", "material.E=-5"])
    with pytest.raises(InputError, match=r"^fractures.F.vertices: .*\(set by --set fractures.F.vertices=\[1\]\)"):
        load_case(str(path), ["fractures.F.vertices=[1]"])


def test_non_utf8_and_unreadable_case_files(tmp_path, cli):
    path = tmp_path / "latin.toml"
    path.write_bytes(STATIC_2D.replace('name = "t"', 'name = "t"\ndescription = "d\xe9j\xe0"').encode("latin-1"))
    code, _, err = cli("run", str(path), "--out", str(tmp_path / "o"))
    assert code == 2 and "is not UTF-8 text" in err and "Traceback" not in err, err
    assert not (tmp_path / "o").exists()


# -- the JSON Schema --------------------------------------------------------------------------------
def _resolve(schema, root):
    while "$ref" in schema:
        schema = root["$defs"][schema["$ref"].rsplit("/", 1)[1]]
    return schema


def _errors(value, schema, root, path="") -> list[str]:
    """What a JSON Schema validator would report, for the keywords ``polypore schema`` uses."""
    schema = _resolve(schema, root)
    if "anyOf" in schema:
        branches = [_errors(value, b, root, path) for b in schema["anyOf"]]
        return [] if any(not b for b in branches) else [f"{path}: matches no branch ({branches})"]
    if "enum" in schema and value not in schema["enum"] or "const" in schema and value != schema["const"]:
        return [f"{path}: {value!r} not allowed"]
    kind = schema.get("type")
    types = {"number": (int, float), "integer": int, "string": str, "boolean": bool, "array": list, "object": dict}
    if kind and (not isinstance(value, types[kind]) or isinstance(value, bool) and kind != "boolean"):
        return [f"{path}: not a {kind}"]
    out = []
    for key, ok in (("minimum", lambda b: value >= b), ("exclusiveMinimum", lambda b: value > b),
                    ("maximum", lambda b: value <= b), ("exclusiveMaximum", lambda b: value < b),
                    ("minItems", lambda b: len(value) >= b), ("maxItems", lambda b: len(value) <= b),
                    ("minLength", lambda b: len(value) >= b)):
        if key in schema and not ok(schema[key]):
            out.append(f"{path}: {key} {schema[key]}")
    if isinstance(value, dict):
        for k, v in value.items():
            sub = schema.get("properties", {}).get(k, schema.get("additionalProperties", True))
            out += [f"{path}.{k}: not allowed"] if sub is False else _errors(v, sub, root, f"{path}.{k}") \
                if sub is not True else []
        out += [f"{path}.{k}: required" for k in schema.get("required", []) if k not in value]
    if isinstance(value, list) and "items" in schema:
        for i, v in enumerate(value):
            out += _errors(v, schema["items"], root, f"{path}[{i}]")
    return out


def test_json_schema_accepts_every_builtin_and_rejects_what_the_schema_rejects(tmp_path, cli):
    code, text, _ = cli("schema")
    schema = json.loads(text)
    assert code == 0 and schema == json_schema() and schema["$schema"].startswith("http://json-schema.org/")
    assert "null" not in text                     # TOML has no null: absent keys are not offered as null
    for name in builtin_names():
        data = load_case(name).data
        assert _errors(data, schema, schema) == [], name
    good = {"mesh": dict(MESH), "material": {"E": 1e9, "nu": 0.2}, "mechanics": {"biot": 0.5}}
    assert _errors(good, schema, schema) == []
    for path, bad in ((("material", "E"), -1.0), (("material", "nu"), 0.5), (("mechanics", "biot"), 2),
                      (("mechanics", "bubbels"), "two-sided"), (("solvr",), {}), (("mesh", "generator"), "hex"),
                      (("mesh", "seed"), 1.5), (("mesh", "lower"), [0.0])):
        doc = json.loads(json.dumps(good))
        node = doc
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = bad
        assert _errors(doc, schema, schema), path
        with pytest.raises(InputError, match=f"^{'.'.join(path)}: "):
            CaseFile("t", None, doc).spec
    out = tmp_path / "case.schema.json"
    code, text, _ = cli("schema", "--out", str(out))
    assert code == 0 and json.loads(out.read_text()) == schema and f"wrote {out}" in text


def test_schema_constants_match_the_layers_they_stand_for():
    from polypore.mesh.generators.mirror import MODES
    from polypore.setup.limits import TIP_RADIUS
    from polypore.mesh.generators.simplicial import TIP_RADIUS as MESH_TIP_RADIUS
    from polypore.setup.schema.geometry import MIRROR_MODES

    assert MIRROR_MODES == MODES and TIP_RADIUS == MESH_TIP_RADIUS


def test_order_and_petsc_options_reach_the_model_data(tmp_path):
    from polypore.setup.mechanics import mechanics_setup
    from polypore.setup.meshing import build_fractured_mesh

    path = tmp_path / "t.toml"
    path.write_text(STATIC_2D)
    case = load_case(str(path), ["mechanics.order=2"])
    assert mechanics_setup(case, build_fractured_mesh(case)).data.order == 2
    # the PETSc backends need petsc4py (not in every install): the options as the solver gets them
    case = load_case(str(path), ["solver.linear=petsc", "solver.petsc.pc_type=gamg", "solver.petsc.ksp_rtol=1e-9"])
    assert case.spec.solver.backend_options() == {"petsc_options": {"pc_type": "gamg", "ksp_rtol": 1e-9}}
    with pytest.raises(InputError, match=r"^mechanics.order: expected 1 \(nodal \+ bubble space\), 2 .* or \"auto\", got 3"):
        load_case(str(path), ["mechanics.order=3"])
    with pytest.raises(InputError, match=r"^solver.petsc: applies to linear = \"petsc\" or \"block-petsc\" only"):
        load_case(str(path), ["solver.petsc.pc_type=gamg"])
    with pytest.raises(InputError, match=r"^solver.petsc.pc_gamg_threshold: expected a text, a finite number"):
        load_case(str(path), ["solver.linear=petsc", "solver.petsc.pc_gamg_threshold=[0.1]"])


def test_cornerpoint_pillar_angle_is_checked_and_reaches_the_grid():
    from polypore.mesh.cornerpoint import pillar_angles
    from polypore.setup.meshing import _cornerpoint_grid

    with pytest.raises(InputError) as exc:
        load_case("cornerpoint-injection", ["mesh.pillar_angle=85"])
    assert exc.value.field == "mesh.pillar_angle" and "85" in str(exc.value), str(exc.value)
    with pytest.raises(InputError, match=r"^mesh.pillar_angle: does not apply to generator = 'cartesian' "
                       r"\(only to cornerpoint\)"):
        CaseFile("t", None, {"mesh": {**MESH, "pillar_angle": 10.0}}).spec
    spec = load_case("cornerpoint-injection", ["mesh.pillar_angle=60"]).spec
    a = pillar_angles(_cornerpoint_grid(spec))
    assert a[0].max() == pytest.approx(60.0) and a[-1].max() == pytest.approx(60.0)     # x = 0 and x = Lx
    assert a[10].max() == pytest.approx(0.0, abs=1e-9)                                 # x = Lx/2: vertical
    assert pillar_angles(_cornerpoint_grid(load_case("cornerpoint-injection").spec)).max() == 0.0
