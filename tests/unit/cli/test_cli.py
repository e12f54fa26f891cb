"""The command line: listing cases, building meshes, exit statuses and messages for bad input."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import STATIC_2D

from polypore.cli import main


def test_help_and_cases(capsys, cli):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "mesh" in capsys.readouterr().out
    code, out, _ = cli("cases")
    assert code == 0
    assert "frictionless-3d" in out and "dfm-2d" in out and "poromechanics" in out


def test_console_script_entry_point():
    proc = subprocess.run([sys.executable, "-m", "polypore", "cases"], capture_output=True, text=True)
    assert proc.returncode == 0 and "dfm-3d" in proc.stdout


def test_mesh_cartesian_case(tmp_path, cli):
    case = tmp_path / "t.toml"
    case.write_text("""
name = "t"
description = "test"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [2.0, 1.0]
cells = [8, 4]
[[fractures]]
name = "F"
vertices = [[0.5, 0.5], [1.5, 0.5]]
[[regions]]
name = "left"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
[[regions]]
name = "right"
lower = [1.0, 0.0]
upper = [2.0, 1.0]
""")
    out = tmp_path / "out"
    code, text, err = cli("mesh", str(case), "--out", str(out))
    assert code == 0, err
    assert "fracture F: 4 faces" in text
    rep = json.loads((out / "mesh.json").read_text())
    assert rep["mesh"]["cells"] == 32 and rep["mesh"]["regions"] == {"left": 16, "right": 16}
    assert rep["fractures"]["F"]["tips"] == 2
    assert (out / "mesh.vtu").stat().st_size > 0 and (out / "fractures.vtu").exists()
    assert (out / "case.toml").exists()
    # refuses a non-empty directory without --force
    code, _, err = cli("mesh", str(case), "--out", str(out))
    assert code == 2 and "not empty" in err
    code, _, err = cli("mesh", str(case), "--out", str(out), "--force", "--set", "mesh.cells=[4, 2]")
    assert code == 0, err


BAD = [
    # (overrides on the cartesian test case, expected fragment of the message)
    (["fractures.F.vertices=[[0.5, 0.5], [1.5, 0.75]]"], "does not conform"),
    (["fractures.F.vertices=[[0.5, 0.5], [0.5, 0.5]]"], "coincide"),
    (["fractures.F.vertices=[[0.5, 0.5], [2.5, 0.5]]"], "outside the domain"),
    (["mesh.generator=hexagonal"], "allowed: cartesian"),
    (["mesh.cells=[0, 4]"], "positive integers"),
    (["mesh.sise=3"], "mesh.sise: unknown key"),
    (["regions.right.lower=[1.5, 0.0]"], "do not cover the domain"),
]


@pytest.mark.parametrize("overrides,msg", BAD)
def test_bad_input_exit_2(tmp_path, cli, overrides, msg):
    case = tmp_path / "t.toml"
    case.write_text("""
name = "t"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [2.0, 1.0]
cells = [8, 4]
[[fractures]]
name = "F"
vertices = [[0.5, 0.5], [1.5, 0.5]]
[[regions]]
name = "left"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
[[regions]]
name = "right"
lower = [1.0, 0.0]
upper = [2.0, 1.0]
""")
    argv = ["mesh", str(case), "--out", str(tmp_path / "o")]
    for o in overrides:
        argv += ["--set", o]
    code, _, err = cli(*argv)
    assert code == 2, err
    assert msg in err
    assert "Traceback" not in err
    assert not (tmp_path / "o" / "mesh.json").exists()


def test_degenerate_polygon_3d(tmp_path, cli):
    case = tmp_path / "p.toml"
    case.write_text("""
name = "p"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
cells = [2, 2, 2]
[[fractures]]
name = "P"
vertices = [[0.0, 0.0, 0.5], [0.5, 0.5, 0.5], [1.0, 1.0, 0.5]]
""")
    code, _, err = cli("mesh", str(case), "--out", str(tmp_path / "o"))
    assert code == 2 and "fractures.P" in err and "collinear" in err


def test_missing_files(tmp_path, cli):
    code, _, err = cli("mesh", str(tmp_path / "nope.toml"))
    assert code == 2 and "nope.toml" in err and "does not exist" in err
    code, _, err = cli("mesh", "no-such-case")
    assert code == 2 and "unknown case" in err
    case = tmp_path / "f.toml"
    case.write_text('name = "f"\n[mesh]\ngenerator = "file"\nfile = "absent.msh"\n')
    code, _, err = cli("mesh", str(case), "--out", str(tmp_path / "o"))
    assert code == 2 and "absent.msh" in err


@pytest.mark.parametrize("override,field", [
    ("material.E=inf", "material.E"),
    ("material.nu=nan", "material.nu"),
    ("contact.beta=1e400", "contact.beta"),
])
def test_non_finite_numbers_name_the_field(tmp_path, cli, override, field):
    """TOML spells inf and nan as numbers: rejected where the number is read, before any solve."""
    case = tmp_path / "t.toml"
    case.write_text(STATIC_2D)
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "o"), "--set", override)
    assert code == 2 and f"{field}: must be a finite number" in err, err
    assert "Traceback" not in err


@pytest.mark.parametrize("command", [["cases"], ["schema"]])
def test_closed_pipe_exits_quietly(command):
    """issue 25: `polypore cases | head -1` (or `| grep -q`) ended in a BrokenPipeError traceback."""
    import os

    r, w = os.pipe()
    os.close(r)                       # the reader is gone before polypore writes a byte
    try:
        proc = subprocess.run([sys.executable, "-m", "polypore", *command], stdout=w, stderr=subprocess.PIPE,
                              text=True, timeout=60)
    finally:
        os.close(w)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr


def _nested(depth):
    return "[" * depth + "]" * depth


@pytest.mark.parametrize("body,where", [
    (f"x = {_nested(100_000)}\n", "too deeply for the TOML reader"),        # RecursionError in tomllib
    ("x = " + "{a = " * 5000 + "1" + "}" * 5000 + "\n", "too deeply for the TOML reader"),
    ("[" + ".".join(["a"] * 3000) + "]\nv = 1\n", "33 or more levels deep"),  # parsed, too deep to use
])
def test_nested_toml_bomb_is_refused(tmp_path, cli, body, where):
    case = tmp_path / "bomb.toml"
    case.write_text('name = "bomb"\n' + body)
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "o"))
    assert code == 2 and "case:" in err and str(case) in err and where in err, err
    assert "Traceback" not in err and not (tmp_path / "o").exists()


def test_nested_override_is_refused(tmp_path, cli):
    case = tmp_path / "t.toml"
    case.write_text(STATIC_2D)
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "o"), "--set", f"x={_nested(100_000)}")
    assert code == 2 and "--set:" in err and "too deeply" in err, err
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "o"), "--set", f"x={_nested(40)}")
    assert code == 2 and "--set overrides nests" in err, err


def test_case_path_too_long(tmp_path, cli):
    code, _, err = cli("run", str(tmp_path / ("c" * 300)))
    assert code == 2 and "case: case file" in err and "File name too long" in err, err
    code, _, err = cli("run", str(tmp_path / ("c" * 300 + ".toml")))
    assert code == 2 and "File name too long" in err, err


FLOW_2D = """
name = "f"
model = "flow"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [2, 2]
[flow]
permeability = 1e-12
[[flow.boundary]]
name = "xmin"
pressure = 1e5
"""


@pytest.mark.parametrize("text,old,new,field,commands", [
    (STATIC_2D, 'name = "ymax"', 'name = "ymaxx"', "mechanics.boundary.ymaxx.name", ("mesh", "run")),
    # a geometry-first case (no [material] yet, which run requires first): its boundary names are checked
    (STATIC_2D.replace("[material]\nE = 1e9\nnu = 0.25\n", ""), 'name = "ymax"', 'name = "top"',
     "mechanics.boundary.top.name", ("mesh",)),
    (FLOW_2D, 'name = "xmin"', 'name = "left"', "flow.boundary.left.name", ("mesh", "run")),
])
def test_mesh_makes_the_case_checks_of_run(tmp_path, cli, text, old, new, field, commands):
    """Issue 25: `polypore mesh` wrote a mesh for a case whose boundary names `polypore run` refused.
    Both now refuse it, naming the same field, and write nothing."""
    assert old in text
    case = tmp_path / "c.toml"
    case.write_text(text.replace(old, new))
    for command in commands:
        out = tmp_path / command
        code, _, err = cli(command, str(case), "--out", str(out))
        assert code == 2 and f"polypore: error: {field}: unknown boundary" in err, (command, err)
        assert [p.name for p in out.iterdir() if not p.name.startswith(".")] == ["failed.json"]   # no mesh
    case.write_text(text)
    code, _, err = cli("mesh", str(case), "--out", str(tmp_path / "ok"))
    assert code == 0, err


@pytest.mark.parametrize("kind,says", [("folder", "is a folder, not a file"),
                                       ("fifo", "is not a regular file (a pipe, a socket or a device)"),
                                       ("loop", "cannot be read: Too many levels of symbolic links"),
                                       ("device", "is not a regular file")])
@pytest.mark.parametrize("where", ["case", "mesh.file"])
def test_input_path_that_is_not_a_file(tmp_path, cli, kind, says, where):
    """A case file or GRDECL file that is a folder, a FIFO, a symbolic-link loop or a device was
    reported as "does not exist" (found by the input fuzz, issue 25); none is read (a FIFO would
    block)."""
    import os

    p = {"folder": tmp_path / "x.toml", "fifo": tmp_path / "x.toml", "loop": tmp_path / "x.toml",
         "device": Path("/dev/zero")}[kind]
    if kind == "folder":
        p.mkdir()
    elif kind == "fifo":
        os.mkfifo(p)
    elif kind == "loop":
        p.symlink_to(p)
    case = p
    if where == "mesh.file":
        case = tmp_path / "case.toml"
        case.write_text(f'name = "g"\n[mesh]\ngenerator = "grdecl"\nfile = "{p}"\n')
    code, _, err = cli("mesh", str(case), "--out", str(tmp_path / "o"))
    assert code == 2 and f"error: {where}: " in err and says in err and str(p) in err, err
