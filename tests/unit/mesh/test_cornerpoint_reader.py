"""GRDECL reader, writer and generator (mesh/cornerpoint): keywords, repeat counts, comments,
INCLUDE, terminators, errors naming file and keyword, round trips, the shared test grids."""

from pathlib import Path

import numpy as np
import pytest

from polypore.core.errors import InputError
from polypore.mesh.cornerpoint import FaultSpec, generate_grid, process_grid, read_grdecl, write_grdecl

DATA = Path(__file__).resolve().parents[4] / "shared" / "data" / "grdecl"
if not DATA.is_dir():                                   # the data set lives next to the repository
    DATA = Path("/work/shared/data/grdecl")

# 2 x 1 x 1 grid, unit columns, written with every syntax the reader must understand
SMALL = """-- a comment line
NOECHO
GRIDUNIT
'METRES  ' '        ' /
MAPUNITS
  'METRES' /
GDORIENT
INC INC INC DOWN LEFT /
SPECGRID
 2 1 1 1 F
/
UNKNOWN
COORD   -- pillars, i fastest
 0 0 0  0 0 10   1 0 0  1 0 10   2 0 0  2 0 10
 0 1 0  0 1 10   1 1 0  1 1 10   2 1 0  2 1 10 /
ZCORN
 8*1.0   -- tops of both cells (repeat count)
 8*2.0 /
ECHO
ACTNUM
 2*1 /
PORO
 0.1 0.2 /
PERMX
 2*150.5 /
MYPROP
 7 8 /
FAULTS
'F one' 1 1 1 1 1 1 'X' /
F2 2 2 1 1 1 1 I- /
/
"""


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def test_keywords_repeat_counts_comments_terminators(tmp_path):
    g = read_grdecl(_write(tmp_path / "small.grdecl", SMALL))
    assert g.dims == (2, 1, 1)
    assert g.coord.shape == (3, 2, 6) and g.coord[2, 1].tolist() == [2, 1, 0, 2, 1, 10]
    assert g.zcorn.shape == (4, 2, 2)
    assert np.all(g.zcorn[..., 0] == 1.0) and np.all(g.zcorn[..., 1] == 2.0)
    assert g.actnum.all()
    assert g.properties["PORO"][:, 0, 0].tolist() == [0.1, 0.2]
    assert g.properties["PERMX"][:, 0, 0].tolist() == [150.5, 150.5]
    assert g.properties["MYPROP"][:, 0, 0].tolist() == [7, 8]          # any numeric cell keyword, by name
    assert g.faults == {"F one": ((1, 1, 1, 1, 1, 1, "X"),), "F2": ((2, 2, 1, 1, 1, 1, "X-"),)}
    assert g.mapaxes is None


def test_repeat_count_errors_and_bad_tokens(tmp_path):
    bad = SMALL.replace(" 0.1 0.2 /", " 0.1 abc /")
    with pytest.raises(InputError) as exc:
        read_grdecl(_write(tmp_path / "b.grdecl", bad))
    line = SMALL.splitlines().index("PORO") + 1
    assert exc.value.field == "b.grdecl:PORO" and \
        f"value 2 (after repeat counts are expanded) is not a number (keyword on line {line})" in str(exc.value)
    assert "abc" not in str(exc.value)          # the file's text is never quoted (issue 25)
    # defaulted values (n*) are not allowed in the geometry
    bad = SMALL.replace(" 8*2.0 /", " 4* 4*2.0 /")
    with pytest.raises(InputError, match="ZCORN: has defaulted values"):
        read_grdecl(_write(tmp_path / "c.grdecl", bad))


@pytest.mark.parametrize("old,new,field,text", [
    (" 8*2.0 /", " 7*2.0 /", "ZCORN", "ZCORN has 15 values, SPECGRID 2×1×1 needs 16"),
    (" 2*1 /", " 3*1 /", "ACTNUM", "ACTNUM has 3 values, SPECGRID 2×1×1 needs 2"),
    (" 0.1 0.2 /", " 0.1 /", "PORO", "PORO has 1 values, SPECGRID 2×1×1 needs 2"),
    ("2 1 0  2 1 10 /", "2 1 0  2 1 /", "COORD", "COORD has 35 values, SPECGRID 2×1×1 needs 36"),
    ("F2 2 2 1 1 1 1 I- /", "F2 2 3 1 1 1 1 I- /", "FAULTS", "outside the grid"),
    ("F2 2 2 1 1 1 1 I- /", "F2 2 2 1 1 1 1 W /", "FAULTS", "the record on line 30: the face is not one of"),
    ("SPECGRID\n 2 1 1 1 F", "SPECGRID\n 2 1 1 1 T", "SPECGRID", "radial"),
])
def test_bad_input_names_file_and_keyword(tmp_path, old, new, field, text):
    assert old in SMALL
    src = SMALL.replace(old, new)
    with pytest.raises(InputError) as exc:
        read_grdecl(_write(tmp_path / "bad.grdecl", src))
    assert exc.value.field == f"bad.grdecl:{field}", exc.value.field
    assert text in str(exc.value)


def test_missing_keywords_and_terminator(tmp_path):
    src = SMALL
    cut = src[:src.index("ZCORN")] + src[src.index("\nECHO\n") + 1:]
    with pytest.raises(InputError, match="ZCORN: missing"):
        read_grdecl(_write(tmp_path / "m.grdecl", cut))
    nospec = src.replace("SPECGRID\n 2 1 1 1 F\n/\n", "")
    with pytest.raises(InputError, match="SPECGRID: missing"):
        read_grdecl(_write(tmp_path / "n.grdecl", nospec))
    with pytest.raises(InputError, match="no terminating"):
        read_grdecl(_write(tmp_path / "t.grdecl", "SPECGRID\n 1 1 1 1 F /\nCOORD\n 1 2 3\n"))
    with pytest.raises(InputError, match="cannot read the file"):
        read_grdecl(tmp_path / "nowhere.grdecl")


def test_include_relative_to_the_including_file(tmp_path):
    src = SMALL
    zc = src[src.index("ZCORN"):src.index("\nECHO\n") + 1]
    main = src.replace(zc, "INCLUDE\n  'inc/zcorn.inc' /\n")
    _write(tmp_path / "model" / "inc" / "zcorn.inc", "-- nested include, relative to inc/\nINCLUDE\n'more.inc' /\n")
    _write(tmp_path / "model" / "inc" / "more.inc", zc)
    g = read_grdecl(_write(tmp_path / "model" / "main.grdecl", main))
    assert np.all(g.zcorn[..., 1] == 2.0)
    with pytest.raises(InputError, match="cannot read"):
        read_grdecl(_write(tmp_path / "model" / "bad.grdecl", main.replace("inc/zcorn.inc", "none.inc")))


def test_gridunit_feet_is_converted(tmp_path):
    src = SMALL.replace("'METRES  ' '        ' /", "'FEET' /")
    g = read_grdecl(_write(tmp_path / "f.grdecl", src))
    assert g.zcorn[0, 0, 1] == pytest.approx(2.0 * 0.3048)
    assert g.coord[1, 0, 0] == pytest.approx(0.3048)


EXPECTED = {  # (dims, active cells) of the shared test grids (README of the data set)
    "eme_small_w_hole_grid_params.grdecl": ((21, 41, 18), 7157),
    "SPE9.GRDECL": ((24, 25, 15), 9000),
    "b.grdecl": ((20, 15, 8), None),
    "simpleb8.grdecl": ((4, 2, 3), None),
    "twocell.grdecl": ((1, 2, 1), 2),
    "sixcells_lefthanded_hdr1.grdecl": ((1, 2, 3), 5),
}


@pytest.mark.parametrize("name", sorted(p.name for p in DATA.iterdir() if p.suffix.lower() == ".grdecl"))
def test_reads_every_shared_grid(name):
    g = read_grdecl(DATA / name)
    nx, ny, nz = g.dims
    assert g.zcorn.shape == (2 * nx, 2 * ny, 2 * nz) and np.isfinite(g.zcorn).all()
    if name in EXPECTED:
        dims, active = EXPECTED[name]
        assert g.dims == dims
        if active is not None:
            assert int(g.actnum.sum()) == active
    if name.startswith("eme"):
        assert g.mapaxes.tolist() == [[460090.936, 5936451.383], [460090.936, 5931903.401], [463948.429, 5931903.401]]
        assert {"PORO", "FACIES"} <= set(g.properties)
        assert 0 < g.properties["PORO"][g.actnum].mean() < 1


def test_generated_grid_round_trip(tmp_path):
    faults = [FaultSpec("i", 2, 12.5, name="A"), FaultSpec("j", 3, -7.25, start=1, stop=4, name="B")]
    g = generate_grid(5, 6, 3, (500, 600, 30), dip=3.0, faults=faults, pinchout=[1], inactive=0.1, seed=4,
                      mapaxes=[[0.0, 1.0], [100.0, 50.0], [101.0, 50.0]])
    path = write_grdecl(g, tmp_path / "gen.grdecl")
    r = read_grdecl(path)
    assert r.dims == g.dims
    for a in ("coord", "zcorn", "actnum", "mapaxes"):
        assert np.array_equal(getattr(r, a), getattr(g, a)), a
    assert dict(r.faults) == dict(g.faults) and set(r.faults) == {"A", "B"}
    assert set(r.properties) == set(g.properties)
    for k in g.properties:
        assert np.array_equal(r.properties[k], g.properties[k]), k
    m1, i1 = process_grid(g)
    m2, i2 = process_grid(r)
    assert (m1.n_cells, m1.n_faces, m1.n_nodes) == (m2.n_cells, m2.n_faces, m2.n_nodes)
    assert np.array_equal(m1.nodes, m2.nodes)
    assert {k: v.tolist() for k, v in i1.faults.items()} == {k: v.tolist() for k, v in i2.faults.items()}


def test_left_handed_generation_mirrors_the_numbering():
    faults = [FaultSpec("i", 2, 12.0, name="A"), FaultSpec("j", 2, 9.0, start=1, stop=3, name="B")]
    r = generate_grid(4, 4, 2, faults=faults)
    l_ = generate_grid(4, 4, 2, faults=faults, left_handed=True)
    assert np.array_equal(l_.zcorn, r.zcorn[:, ::-1]) and np.array_equal(l_.coord, r.coord[:, ::-1])
    assert l_.faults["B"] == ((2, 3, 3, 3, 1, 2, "Y-"),) and r.faults["B"] == ((2, 3, 2, 2, 1, 2, "Y"),)
    assert l_.faults["A"] == r.faults["A"]


def test_generator_rejects_bad_faults():
    with pytest.raises(InputError, match="index 4 must be in 1..3"):
        generate_grid(4, 4, 2, faults=[FaultSpec("i", 4, 1.0)])
    with pytest.raises(InputError, match="axis"):
        generate_grid(4, 4, 2, faults=[FaultSpec("k", 1, 1.0)])
    with pytest.raises(InputError, match="start"):
        generate_grid(4, 4, 2, faults=[FaultSpec("i", 1, 1.0, start=3, stop=2)])


@pytest.mark.parametrize("old,new,kw", [
    (" 0.1 0.2 /", " 1000000000000*0.2 /", "PORO"),             # issue 25: was a MemoryError
    (" 8*2.0 /", " 999999999999*2.0 /", "ZCORN"),
    (" 7 8 /", " 1000000000000*7 /", None),                        # unknown keyword: dropped, not expanded
])
def test_huge_repeat_counts_are_refused_before_expanding(tmp_path, old, new, kw):
    assert old in SMALL
    path = _write(tmp_path / "huge.grdecl", SMALL.replace(old, new))
    if kw is None:
        assert "MYPROP" not in read_grdecl(path).properties
        return
    with pytest.raises(InputError) as exc:
        read_grdecl(path)
    line = SMALL.splitlines().index(kw) + 1
    assert exc.value.field == f"huge.grdecl:{kw}"
    assert "SPECGRID 2×1×1 needs" in str(exc.value) and f"keyword on line {line})" in str(exc.value)


def test_huge_repeat_count_before_specgrid_hits_the_reader_limit(tmp_path):
    path = _write(tmp_path / "h.grdecl", "PORO\n 1000000000000*0.2 /\n" + SMALL)
    with pytest.raises(InputError, match=r"h.grdecl:PORO: PORO has 1000000000000 values, more than the "
                                         r"100000000 the reader takes per keyword \(repeat counts expanded; "
                                         r"keyword on line 1\)"):
        read_grdecl(path)


@pytest.mark.parametrize("actnum,value,cell", [(" 1 7 /", "7", "(2, 1, 1)"), (" -1 1 /", "-1", "(1, 1, 1)"),
                                               (" 0.5 1 /", "0.5", "(1, 1, 1)")])
def test_actnum_other_than_0_or_1_is_an_error(tmp_path, actnum, value, cell):
    with pytest.raises(InputError) as exc:
        read_grdecl(_write(tmp_path / "a.grdecl", SMALL.replace(" 2*1 /", actnum)))
    assert exc.value.field == "a.grdecl:ACTNUM"
    assert f"value {value} at cell (i, j, k) = {cell}" in str(exc.value) and "0 (inactive) or 1" in str(exc.value)
    g = read_grdecl(_write(tmp_path / "ok.grdecl", SMALL.replace(" 2*1 /", " 0 1 /")))
    assert g.actnum[:, 0, 0].tolist() == [False, True]


SECRET = "root:x:0:0:root:/root:/bin/bash"


@pytest.mark.parametrize("text,message", [
    (SECRET + "\ndaemon:x:1:1\n", "unexpected text on line 1 after the last keyword"),
    ("SPECGRID\n 1 1 1 1 F /\n" + SECRET + "\nCOORD\n", "unexpected text on line 3, before the keyword on line 4"),
    ("SECRET\n" + SECRET + " /\n", "keyword on line 1: value 1 (after repeat counts are expanded) is not a number"),
    ("GRIDUNIT\n 'root:x' /\n", "unknown unit (line 1)"),
    ("FAULTS\n 'root' 1 1 1 1 1 1 root:x /\n/\n", "the record on line 2: the face is not one of"),
    ("FAULTS\n root x 0 /\n/\n", "the record on line 2 has 3 items"),
    ("SPECGRID\n root x 0 /\n", "nx ny nz must be integers (line 1)"),
    ("INCLUDE\n root x /\n", "expected one file name, got 2 items (line 1)"),
    ("SECRET\n 1 2 3\n", "keyword on line 1: has no terminating"),
])
def test_errors_never_quote_the_files_text(tmp_path, text, message):
    """Issue 25: mesh.file may name any readable file (a system file); the reader's errors said
    "unexpected text 'root:x:0:0:root:/root:/bin/bash...'". They name lines, not text."""
    with pytest.raises(InputError) as exc:
        read_grdecl(_write(tmp_path / "passwd", text))
    assert message in str(exc.value), str(exc.value)
    assert "root" not in str(exc.value) and "SECRET" not in str(exc.value) and "daemon" not in str(exc.value)
