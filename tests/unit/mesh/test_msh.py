"""Reading Gmsh .msh files: regions, boundary groups, fracture groups, errors, the CLI."""

import json
import re

import numpy as np
import pytest

from polypore.cli import main
from polypore.core.errors import InputError
from polypore.mesh import FracturedMesh
from polypore.mesh.msh import read_msh

gmsh = pytest.importorskip("gmsh")


def _session():
    gmsh.initialize([], readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)


def write_2d(path, version=4.1, save_all=False, mixed=False, quads=False, twice=False):
    """Unit square, interface x = 0.5 (regions left/right), fracture y = 0.3 for 0.2 <= x <= 0.8.

    ``twice``: the left surfaces are also in a second physical group "again" (MSH 2 then
    writes their elements twice).
    """
    _session()
    try:
        occ = gmsh.model.occ
        sq = occ.addRectangle(0, 0, 0, 1, 1)
        itf = occ.addLine(occ.addPoint(0.5, 0, 0), occ.addPoint(0.5, 1, 0))
        fr = occ.addLine(occ.addPoint(0.2, 0.3, 0), occ.addPoint(0.8, 0.3, 0))
        _, omap = occ.fragment([(2, sq)], [(1, itf), (1, fr)])
        occ.synchronize()
        frac = [t for _, t in omap[2]]
        surfs = gmsh.model.getEntities(2)
        left = [t for d, t in surfs if occ.getCenterOfMass(d, t)[0] < 0.5]
        right = [t for d, t in surfs if occ.getCenterOfMass(d, t)[0] > 0.5]
        bottom = [t for d, t in gmsh.model.getEntities(1)
                  if np.allclose(np.reshape(gmsh.model.getBoundingBox(d, t), (2, 3))[:, 1], 0, atol=1e-5)]
        gmsh.model.addPhysicalGroup(2, left, name="left")
        if twice:
            gmsh.model.addPhysicalGroup(2, left, name="again")
        if not save_all:
            gmsh.model.addPhysicalGroup(2, right, name="right")
        gmsh.model.addPhysicalGroup(1, frac + (bottom if mixed else []), name="frac")
        gmsh.model.addPhysicalGroup(1, bottom, name="bottom")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.1)
        gmsh.option.setNumber("Mesh.SaveAll", int(save_all))
        gmsh.option.setNumber("Mesh.RecombineAll", int(quads))
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


def write_3d(path, version=4.1, binary=False):
    """Unit cube (tets), square fracture z = 0.5 on [0.2, 0.8]^2, boundary group top (z = 1)."""
    _session()
    try:
        occ = gmsh.model.occ
        box = occ.addBox(0, 0, 0, 1, 1, 1)
        sq = occ.addRectangle(0.2, 0.2, 0.5, 0.6, 0.6)
        _, omap = occ.fragment([(3, box)], [(2, sq)])
        occ.synchronize()
        top = [t for d, t in gmsh.model.getEntities(2)
               if np.allclose(np.reshape(gmsh.model.getBoundingBox(d, t), (2, 3))[:, 2], 1, atol=1e-5)]
        gmsh.model.addPhysicalGroup(3, [t for _, t in gmsh.model.getEntities(3)], name="rock")
        gmsh.model.addPhysicalGroup(2, [t for _, t in omap[1]], name="F")
        gmsh.model.addPhysicalGroup(2, top, name="top")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.25)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


@pytest.mark.parametrize("version", [2.2, 4.1])
def test_read_2d(tmp_path, version, exact_geometry):
    mesh, groups = read_msh(str(write_2d(tmp_path / "sq.msh", version)))
    assert mesh.dim == 2 and mesh.nodes.shape[1] == 2
    exact_geometry(mesh, volume=1.0)
    assert sorted(mesh.region_names) == ["left", "right"]
    vol = np.bincount(mesh.cell_region, weights=mesh.geometry.cell_volume)
    np.testing.assert_allclose(vol, [0.5, 0.5], rtol=1e-12)
    assert np.all((mesh.geometry.cell_centroid[:, 0] < 0.5) == (mesh.cell_region == mesh.region_names.index("left")))
    # boundary group next to the built-in box names
    b = mesh.boundary["bottom"]
    assert abs(mesh.geometry.face_area[b].sum() - 1.0) < 1e-12
    assert set(b) == set(mesh.boundary["ymin"])
    assert list(groups) == ["frac"]
    f = groups["frac"]
    assert f.dtype == np.int32 and np.all(np.diff(f) > 0)
    assert abs(mesh.geometry.face_area[f].sum() - 0.6) < 1e-12
    assert np.allclose(mesh.geometry.face_centroid[f, 1], 0.3)
    fm = FracturedMesh.from_faces(mesh, groups)
    sides = fm.side_counts()
    X = mesh.nodes
    on = np.isclose(X[:, 1], 0.3) & (X[:, 0] > 0.2 + 1e-9) & (X[:, 0] < 0.8 - 1e-9)
    np.testing.assert_array_equal(sides, 1 + on)
    assert fm.report()["frac"]["tips"] == 2


def test_read_2d_default_region_and_mixed_group(tmp_path):
    mesh, _ = read_msh(str(write_2d(tmp_path / "d.msh", save_all=True)))
    assert sorted(mesh.region_names) == ["default", "left"]
    right = mesh.cell_region == mesh.region_names.index("default")
    assert np.all(mesh.geometry.cell_centroid[right, 0] > 0.5)
    with pytest.raises(InputError, match="'frac'.*mixes .* boundary and .* interior") as exc:
        read_msh(str(write_2d(tmp_path / "m.msh", mixed=True)))
    assert exc.value.field == "path"


@pytest.mark.parametrize("version", [2.2, 4.1])
def test_read_2d_quads_and_duplicated_groups(tmp_path, version, exact_geometry):
    mesh, groups = read_msh(str(write_2d(tmp_path / "q.msh", version, quads=True, twice=True)))
    assert mesh.cell_faces.counts.max() == 4
    exact_geometry(mesh, volume=1.0)
    # a cell in two groups belongs to the first; no cell is read twice
    assert mesh.region_names == ("left", "again", "right")
    vol = np.bincount(mesh.cell_region, weights=mesh.geometry.cell_volume, minlength=3)
    np.testing.assert_allclose(vol, [0.5, 0.0, 0.5], rtol=1e-12, atol=1e-14)
    assert abs(mesh.geometry.face_area[groups["frac"]].sum() - 0.6) < 1e-12


@pytest.mark.parametrize("version,binary", [(2.2, False), (4.1, False), (4.1, True)])
def test_read_3d(tmp_path, version, binary, exact_geometry):
    mesh, groups = read_msh(str(write_3d(tmp_path / "cube.msh", version, binary)))
    assert mesh.dim == 3 and mesh.region_names == ("rock",)
    exact_geometry(mesh, volume=1.0)
    assert abs(mesh.geometry.face_area[mesh.boundary["top"]].sum() - 1.0) < 1e-12
    f = groups["F"]
    assert abs(mesh.geometry.face_area[f].sum() - 0.36) < 1e-12
    fm = FracturedMesh.from_faces(mesh, groups, {"F": [0, 0, 1]})
    X = mesh.nodes
    inner = np.isclose(X[:, 2], 0.5) & np.all((X[:, :2] > 0.2 + 1e-9) & (X[:, :2] < 0.8 - 1e-9), axis=1)
    np.testing.assert_array_equal(fm.side_counts(), 1 + inner)
    assert np.all(fm.network.normal[:, 2] > 0.999)


HEX_MSH = """$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
3
2 1 "mid"
2 3 "west"
3 2 "block"
$EndPhysicalNames
$Nodes
13
1 0 0 0
2 1 0 0
3 2 0 0
4 0 1 0
5 1 1 0
6 2 1 0
7 0 0 1
8 1 0 1
9 2 0 1
10 0 1 1
11 1 1 1
12 2 1 1
13 9 9 9
$EndNodes
$Elements
4
1 5 2 2 1 1 2 5 4 7 8 11 10
2 5 2 2 1 2 3 6 5 8 9 12 11
3 3 2 1 5 2 5 11 8
4 3 2 3 6 1 4 10 7
$EndElements
"""


def test_read_hexahedra_msh22_by_hand(tmp_path, exact_geometry):
    p = tmp_path / "hex.msh"
    p.write_text(HEX_MSH)
    mesh, groups = read_msh(str(p))
    assert mesh.n_cells == 2 and mesh.n_nodes == 12  # the unused node 13 is dropped
    exact_geometry(mesh, volume=2.0)
    assert mesh.region_names == ("block",)
    assert mesh.boundary["west"].size == 1 and set(mesh.boundary["west"]) == set(mesh.boundary["xmin"])
    assert list(groups) == ["mid"] and np.allclose(mesh.geometry.face_centroid[groups["mid"]], [1, 0.5, 0.5])


def test_errors(tmp_path):
    with pytest.raises(InputError, match="does not exist") as exc:
        read_msh(str(tmp_path / "absent.msh"))
    assert exc.value.field == "path"
    bad = tmp_path / "bad.msh"
    bad.write_text("Point(1) = {0, 0, 0};\n")
    with pytest.raises(InputError, match="not a Gmsh mesh file") as exc:
        read_msh(str(bad))
    assert exc.value.field == "path"
    # a valid header with a truncated body
    good = write_2d(tmp_path / "good.msh").read_text()
    cut = tmp_path / "cut.msh"
    cut.write_text(good[: len(good) // 2])
    with pytest.raises(InputError) as exc:
        read_msh(str(cut))
    assert exc.value.field == "path"
    # only lines: no cells
    lines = tmp_path / "lines.msh"
    lines.write_text(HEX_MSH.replace("4\n1 5 2 2 1 1 2 5 4 7 8 11 10\n2 5 2 2 1 2 3 6 5 8 9 12 11\n3 3 2 1 5 2 5 11 8\n"
                                     "4 3 2 3 6 1 4 10 7\n", "1\n1 1 2 1 1 1 2\n"))
    with pytest.raises(InputError, match="no 2D or 3D cells") as exc:
        read_msh(str(lines))
    # a group element that is no cell face (a diagonal quad through the first hexahedron)
    diag = tmp_path / "diag.msh"
    diag.write_text(HEX_MSH.replace("3 3 2 1 5 2 5 11 8", "3 3 2 1 5 1 2 11 10"))
    with pytest.raises(InputError, match="'mid'.*not faces") as exc:
        read_msh(str(diag))
    # triangles off the plane z = 0 are a surface in 3D, not a 2D mesh
    surf = tmp_path / "surf.msh"
    surf.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 1\n2 1 0 1\n3 0 1 1.5\n"
                    "$EndNodes\n$Elements\n1\n1 2 2 0 1 1 2 3\n$EndElements\n")
    with pytest.raises(InputError, match="plane z = 0"):
        read_msh(str(surf))
    assert not gmsh.isInitialized()


def _case(tmp_path, group):
    write_2d(tmp_path / "x.msh")
    case = tmp_path / "c.toml"
    case.write_text(f'name = "c"\n[mesh]\ngenerator = "file"\nfile = "x.msh"\n'
                    f'[[fractures]]\nname = "F"\ngroup = "{group}"\n')
    return case


def test_cli_missing_group(tmp_path, capsys):
    case = _case(tmp_path, "nope")
    code = main(["mesh", str(case), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "fractures.F.group" in err and "'nope'" in err and "['frac']" in err
    assert "Traceback" not in err


def test_cli_file_mesh(tmp_path, capsys):
    pytest.importorskip("polypore.io.vtu")
    case = _case(tmp_path, "frac")
    out = tmp_path / "o"
    code = main(["mesh", str(case), "--out", str(out)])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    assert "fracture F:" in cap.out
    rep = json.loads((out / "mesh.json").read_text())
    assert rep["fractures"]["F"]["tips"] == 2
    assert set(rep["mesh"]["regions"]) == {"left", "right"}



def test_file_mesh_arc_length_and_static_run(tmp_path, cli):
    """A 2D fracture read from a file has no vertex list: its arc length comes from its faces,
    and a static run writes the profiles along it (this used to crash in the plots)."""
    import csv

    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh
    from polypore.models.fracture_geometry import arc_length

    case = _case(tmp_path, "frac")
    fm = build_fractured_mesh(load_case(str(case)))
    s = arc_length(fm)
    x = fm.mesh.geometry.face_centroid[fm.network.faces, 0]
    np.testing.assert_allclose(s, x - 0.2, atol=1e-12)  # fracture y = 0.3 from x = 0.2 (its smallest end)
    # clamped bottom (the file's only boundary group), loaded by gravity-like body force
    case.write_text(case.read_text() + """
[material]
E = 1e9
nu = 0.25
[mechanics]
body_force = [1e5, -1e6]
[[mechanics.boundary]]
name = "bottom"
ux = 0.0
uy = 0.0
[contact]
law = "coulomb"
friction = 0.3
""")
    code, _, err = cli("run", str(case), "--out", str(tmp_path / "r"))
    assert code == 0, err
    rows = list(csv.DictReader((tmp_path / "r" / "fractures.csv").open()))
    assert len(rows) == fm.network.n_faces
    np.testing.assert_allclose(sorted(float(r["s"]) for r in rows), np.sort(s), atol=1e-9)
    assert (tmp_path / "r" / "profiles.png").stat().st_size > 0


def test_file_that_crashes_gmsh_is_an_input_error(tmp_path):
    """gmsh dies of SIGSEGV on some malformed MSH 2.2 files (triangle 102 of the fuzz's square
    given the type of a pyramid, 7, or triangle 63 that of a point, 15: found by the input fuzz,
    issue 25), which ended polypore itself without a word; the file is read in a forked child,
    whose crash is an InputError naming mesh.file."""
    from inputfuzz import msh_bases

    text = msh_bases()["2d-v2.2.msh"][0].decode()
    for tag, new_type in (("102", "7"), ("63", "15")):
        lines = text.split("\n")
        at = next(i for i, ln in enumerate(lines) if ln.split()[:2] == [tag, "2"] and len(ln.split()) == 8)
        parts = lines[at].split()
        parts[1] = new_type
        lines[at] = " ".join(parts)
        bad = tmp_path / f"bad{tag}.msh"
        bad.write_text("\n".join(lines))
        with pytest.raises(InputError, match=r"gmsh crashed on it \(SIGSEGV\); the file is malformed") as exc:
            read_msh(str(bad))
        assert exc.value.field == "path"


def test_reading_after_a_superlu_factorisation_is_quiet(tmp_path, capfd):
    """A factorisation on core/interruptible.py's worker thread, then a .msh read (forked child):
    the child printed "SystemError: ... returned a result with an exception set" (the live worker
    that had run SuperLU was torn down in it); the idle worker is now ended before the fork."""
    import signal

    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from polypore.core.interruptible import interruptible

    old = signal.signal(signal.SIGTERM, lambda *a: None)     # a Python handler: the worker is used
    try:
        lu = interruptible(spla.splu, (sp.random(30, 30, density=0.2, random_state=1) + sp.eye(30)).tocsc())
        assert lu.shape == (30, 30)
        mesh, _ = read_msh(str(write_2d(tmp_path / "sq.msh")))
    finally:
        signal.signal(signal.SIGTERM, old)
    assert mesh.n_cells > 0
    err = capfd.readouterr().err
    assert "SystemError" not in err and "Exception ignored" not in err, err


@pytest.mark.parametrize("version", [2.2, 4.1])
@pytest.mark.parametrize("bad", ["1e", "0.5x", "1..2"])
def test_corrupted_number_is_refused(tmp_path, version, bad):
    """gmsh reads a prefix of a corrupted number ("1e" as 1, "0.5x" as 0.5): a node moved
    silently (found by the input fuzz, issue 25). The $Nodes and $Elements of an ASCII file are
    checked first; the error names the line and the token."""
    text = write_2d(tmp_path / "sq.msh", version).read_text()
    a = text.index("$Nodes\n")
    lines = text[a:].split("\n")
    i = next(k for k, ln in enumerate(lines) if len(ln.split()) == (4 if version == 2.2 else 3) and k > 3)
    parts = lines[i].split()
    parts[-2] = bad
    lines[i] = " ".join(parts)
    (tmp_path / "bad.msh").write_text(text[:a] + "\n".join(lines))
    with pytest.raises(InputError, match=rf"line {text[:a].count(chr(10)) + i + 1}: '{re.escape(bad)}' in \$Nodes "
                       "is not a number") as exc:
        read_msh(str(tmp_path / "bad.msh"))
    assert exc.value.field == "path"
