"""Bad corner-point grids through the command line (issue 15): ``polypore mesh`` / ``polypore run``
on a case whose GRDECL file is broken exit with status 2 and one error line naming the file's
keyword and, where a cell is at fault, the cell (i, j, k) 1-based as in the file; no traceback."""

import dataclasses
import re

import numpy as np
import pytest

from polypore.cli import main
from polypore.mesh.cornerpoint import generate_grid, write_grdecl

CASE = """
[mesh]
generator = "grdecl"
file = "bad.grdecl"
"""
RUN = CASE + """
[material]
E = 1.0e10
nu = 0.25
[[mechanics.boundary]]
name = "bottom"
u = [0, 0, 0]
"""


def good():
    return generate_grid(3, 2, 2, extent=(300.0, 200.0, 20.0), top=1000.0, properties=False)


def grid_text(grid, tmp_path) -> str:
    return write_grdecl(grid, tmp_path / "good.grdecl").read_text()


def keyword_block(text: str, kw: str) -> tuple[int, int]:
    """(start, end) of keyword kw's block (from its name to its terminating '/')."""
    m = re.search(rf"^{kw}\b", text, re.M)
    return m.start(), text.index("/", m.end()) + 1


def drop_last_value(text: str, kw: str) -> str:
    a, b = keyword_block(text, kw)
    block = text[a:b].rstrip("/").split()
    return text[:a] + "\n".join([block[0], " ".join(block[1:-1]), "/"]) + text[b:]


def run_cli(tmp_path, capsys, grid_source: str, command="mesh", case=CASE):
    (tmp_path / "bad.grdecl").write_text(grid_source)
    (tmp_path / "case.toml").write_text(case)
    args = [command, str(tmp_path / "case.toml"), "--out", str(tmp_path / "out")]
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and err.startswith("polypore: error:"), err
    assert len(err.strip().splitlines()) == 1, err
    return err


def test_missing_keyword(tmp_path, capsys):
    text = grid_text(good(), tmp_path)
    a, b = keyword_block(text, "ZCORN")
    err = run_cli(tmp_path, capsys, text[:a] + text[b:])
    assert "bad.grdecl:ZCORN" in err and "missing" in err


def test_missing_specgrid(tmp_path, capsys):
    text = grid_text(good(), tmp_path)
    a, b = keyword_block(text, "SPECGRID")
    err = run_cli(tmp_path, capsys, text[:a] + text[b:])
    assert "bad.grdecl:SPECGRID" in err and "missing" in err


@pytest.mark.parametrize("kw,need", [("ZCORN", 96), ("COORD", 72), ("ACTNUM", 12)])
def test_short_keyword(tmp_path, capsys, kw, need):
    grid = good()
    if kw == "ACTNUM":
        # write ACTNUM explicitly (a grid with all cells active may omit it)
        act = grid.actnum.copy()
        act[0, 0, 0] = False
        grid = dataclasses.replace(grid, actnum=act)
    text = grid_text(grid, tmp_path)
    err = run_cli(tmp_path, capsys, drop_last_value(text, kw))
    m = re.search(rf"bad.grdecl:{kw}: {kw} has (\d+) values, SPECGRID 3×2×2 needs {need}", err)
    assert m and int(m.group(1)) < need, err


def test_inverted_cell(tmp_path, capsys):
    g = good()
    z = g.zcorn.copy()
    # cell (2, 1, 2), 1-based: the bottom of its first corner above its top
    z[2, 0, 2], z[2, 0, 3] = z[2, 0, 3] + 5.0, z[2, 0, 2]
    err = run_cli(tmp_path, capsys, grid_text(dataclasses.replace(g, zcorn=z), tmp_path), command="run", case=RUN)
    assert "bad.grdecl:ZCORN" in err and "cell (2, 1, 2) is inverted" in err


def test_self_intersecting_cells(tmp_path, capsys):
    g = generate_grid(3, 3, 2, extent=(300.0, 300.0, 20.0), top=1000.0, properties=False)
    c = g.coord.copy()
    # two pillars swapped: the cells between them fold over themselves
    c[1, 1, [0, 3]], c[2, 1, [0, 3]] = c[2, 1, [0, 3]].copy(), c[1, 1, [0, 3]].copy()
    err = run_cli(tmp_path, capsys, grid_text(dataclasses.replace(g, coord=c), tmp_path))
    assert "bad.grdecl:COORD/ZCORN" in err and re.search(r"cell \(\d, \d, \d\) has a non-positive volume", err)


def test_all_cells_inactive(tmp_path, capsys):
    g = good()
    err = run_cli(tmp_path, capsys, grid_text(dataclasses.replace(g, actnum=np.zeros(g.dims, bool)), tmp_path))
    assert "ACTNUM" in err and "all cells are inactive" in err


def test_fault_record_outside_the_grid(tmp_path, capsys):
    text = grid_text(good(), tmp_path) + "\nFAULTS\n 'FX' 2 2 1 3 1 2 I /\n/\n"     # j2 = 3 > ny = 2
    err = run_cli(tmp_path, capsys, text)
    assert "bad.grdecl:FAULTS" in err and "'FX'" in err and "outside the grid" in err


def test_good_grid_passes(tmp_path):
    (tmp_path / "bad.grdecl").write_text(grid_text(good(), tmp_path))
    (tmp_path / "case.toml").write_text(CASE)
    assert main(["mesh", str(tmp_path / "case.toml"), "--out", str(tmp_path / "out")]) == 0


# -- found by the input fuzz (issue 25, tests/inputfuzz.py) ---------------------------------------------
def replace_value(text: str, kw: str, k: int, new: str) -> str:
    """The k-th value (0-based) of keyword kw's block replaced by ``new``."""
    a, b = keyword_block(text, kw)
    head, _, rest = text[a:b].partition("\n")
    vals = rest.rstrip("/").split()
    vals[k] = new
    return text[:a] + head + "\n" + " ".join(vals) + "\n/" + text[b:]


@pytest.mark.parametrize("kw", ["COORD", "ZCORN"])
@pytest.mark.parametrize("bad,says", [("inf", "not a finite number"), ("-Inf", "not a finite number"),
                                      ("nan", "not a finite number"), ("1e999", "overflows"),
                                      ("-1e300", "within ±1e+09 m"), ("1e300", "within ±1e+09 m")])
def test_non_finite_or_huge_values(tmp_path, capsys, kw, bad, says):
    """inf in COORD was accepted; nan was called a defaulted value; -1e300 in ZCORN ended in a
    ValueError traceback (overflow in the node merging)."""
    err = run_cli(tmp_path, capsys, replace_value(grid_text(good(), tmp_path), kw, 5, bad))
    assert f"bad.grdecl:{kw}" in err and "value 6" in err and says in err, err


@pytest.mark.parametrize("kind", ["fifo", "dev_zero", "directory"])
def test_include_of_a_fifo_device_or_folder_is_refused(tmp_path, capsys, kind):
    """INCLUDE of a FIFO blocked forever (and /dev/zero would never end): regular files only."""
    import os

    target = {"fifo": str(tmp_path / "pipe.grdecl"), "dev_zero": "/dev/zero", "directory": str(tmp_path)}[kind]
    if kind == "fifo":
        os.mkfifo(target)
    text = grid_text(good(), tmp_path)
    err = run_cli(tmp_path, capsys, f"INCLUDE\n '{target}' /\n\n" + text)
    assert "is not a regular file" in err and target in err


@pytest.mark.parametrize("kw", ["SPECGRID", "DIMENS"])
def test_specgrid_without_its_slash_is_refused(tmp_path, capsys, kw):
    """SPECGRID without its '/' silently swallowed the next keyword (GDORIENT, MAPAXES)."""
    text = grid_text(good(), tmp_path).replace("SPECGRID\n 3 2 2 1 F /", f"{kw}\n 3 2 2 1 F\n\nMAPAXES\n0 1 0 0 1 0 /")
    err = run_cli(tmp_path, capsys, text)
    assert f"bad.grdecl:{kw}" in err and "items" in err
