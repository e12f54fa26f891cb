"""VTU/PVD writers and atomic writes, checked with independent readers (VTK, meshio)."""

import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

vtk = pytest.importorskip("vtk")
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402

from polypore.core.ragged import Ragged  # noqa: E402
from polypore.io.atomic import atomic_path, atomic_write_bytes, atomic_write_text  # noqa: E402
from polypore.io.vtu import (VTK_LINE, VTK_POLYGON, VTK_POLYHEDRON, write_bulk_vtu,  # noqa: E402
                             write_fracture_vtu, write_pvd)
from polypore.mesh import (FracturedMesh, FractureSpec, mesh_from_cells, mesh_from_polygons,  # noqa: E402
                           mesh_from_polyhedra)
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates  # noqa: E402

ENCODINGS = ["base64", "raw"]


# --------------------------------------------------------------------------- meshes

def cart2d(n=4):
    return cartesian_mesh([grid_coordinates(0, 1, n, [0.5]), grid_coordinates(0, 2, n, [0.5])])


def cart3d(n=3):
    return cartesian_mesh([grid_coordinates(0, 1, n, [0.5])] * 3)


def polygons2d():
    """Triangle, quad, pentagon and a non-convex heptagon (given clockwise)."""
    X = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1], [0, 2], [1, 2], [2, 2],
                  [0.5, 0], [1.5, 1.2]], float)
    polys = Ragged.from_rows([[0, 9, 4, 3], [9, 1, 4], [1, 2, 5, 10, 4], [6, 7, 8, 5, 10, 4, 3]])
    return mesh_from_polygons(X, polys, cell_region=[0, 1, 1, 0], region_names=("a", "b"))


def mixed3d():
    """Hexahedron, wedge, pyramid and tetrahedron glued face to face."""
    X = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1],
                  [2, 0, 0], [2, 1, 0], [.5, .5, 1.5], [1.3, .5, 1.5]], float)
    return mesh_from_cells(X, {"hexahedron": [[0, 1, 2, 3, 4, 5, 6, 7]], "wedge": [[1, 8, 5, 2, 9, 6]],
                               "pyramid": [[4, 5, 6, 7, 10]], "tetra": [[5, 6, 10, 11]]})


def lshape3d():
    """A non-convex L-shaped prism (8 faces, hexagonal caps) and the cube filling its notch."""
    P = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2], [2, 2]], float)
    X = np.vstack([np.c_[P, np.zeros(7)], np.c_[P, np.ones(7)]])   # node i at z=0, i + 7 at z=1
    ring = [0, 1, 2, 3, 4, 5]
    L = [ring[::-1], [i + 7 for i in ring]] + [[a, b, b + 7, a + 7] for a, b in zip(ring, ring[1:] + ring[:1])]
    sq = [3, 2, 6, 4]
    C = [sq[::-1], [i + 7 for i in sq]] + [[a, b, b + 7, a + 7] for a, b in zip(sq, sq[1:] + sq[:1])]
    loops = Ragged.from_rows(L + C)
    return mesh_from_polyhedra(X, loops, [0] * len(L) + [1] * len(C))


MESHES_2D = {"cartesian": cart2d, "polygons": polygons2d}
MESHES_3D = {"cartesian": cart3d, "mixed": mixed3d, "lshape": lshape3d}


# --------------------------------------------------------------------------- readers

def read_vtk(path):
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    r.Update()
    assert r.GetErrorCode() == 0
    return r.GetOutput()


def cell_array(u, name):
    a = u.GetCellData().GetArray(name)
    assert a is not None, name
    return vtk_to_numpy(a)


def vtk_measures(u):
    """Per-cell area (polygons, Newell's formula) or volume (vtkPolyhedron), computed by VTK.

    Exact for non-convex cells, unlike vtkCellSizeFilter which fans from the first point.
    """
    out = np.empty(u.GetNumberOfCells())
    for c in range(out.size):
        cell = u.GetCell(c)
        if cell.GetCellType() == VTK_POLYHEDRON:
            out[c] = cell.ComputeVolume()
        else:
            out[c] = vtk.vtkPolygon.ComputeArea(cell.GetPoints(), cell.GetNumberOfPoints(), None, [0.0] * 3)
    return out


def vtk_sizes(u, key):
    """vtkCellSizeFilter's measures (convex cells only)."""
    f = vtk.vtkCellSizeFilter()
    f.SetInputData(u)
    f.Update()
    return cell_array(f.GetOutput(), key)


def cell_types(u):
    a = u.GetCellTypes() if hasattr(u, "GetCellTypes") else None
    a = a if isinstance(a, vtk.vtkDataArray) else u.GetCellTypesArray()
    return vtk_to_numpy(a)


def cell_point_lists(u):
    conn = vtk_to_numpy(u.GetCells().GetConnectivityArray())
    off = vtk_to_numpy(u.GetCells().GetOffsetsArray())
    return [conn[a:b] for a, b in zip(off[:-1], off[1:])]


def face_streams(u):
    """Per cell: list of face point-id loops, from VTK's polyhedron face stream."""
    out = []
    ids = vtk.vtkIdList()
    for c in range(u.GetNumberOfCells()):
        u.GetFaceStream(c, ids)
        s = [ids.GetId(i) for i in range(ids.GetNumberOfIds())]
        faces, k = [], 1
        for _ in range(s[0]):
            faces.append(s[k + 1:k + 1 + s[k]])
            k += 1 + s[k]
        out.append(faces)
    return out


def signed_volume(X, faces):
    """Divergence theorem with fan triangles: > 0 iff the face loops are oriented outward."""
    v = 0.0
    for f in faces:
        P = X[f]
        v += sum(np.dot(P[0], np.cross(P[i], P[i + 1])) for i in range(1, len(P) - 1))
    return v / 6


# --------------------------------------------------------------------------- bulk, 2D

@pytest.mark.parametrize("name", MESHES_2D)
@pytest.mark.parametrize("encoding", ENCODINGS)
def test_bulk_2d_polygons_roundtrip(tmp_path, name, encoding):
    mesh = MESHES_2D[name]()
    g = mesh.geometry
    vec = g.cell_centroid                     # 2-vectors: padded to 3 components
    sides = np.arange(mesh.n_nodes, dtype=np.int32)
    path = write_bulk_vtu(tmp_path / "m.vtu", mesh,
                          cell_data={"volume": g.cell_volume, "centroid": vec,
                                     "flag": g.cell_volume > np.median(g.cell_volume)},
                          point_data={"sides": sides, "x": mesh.nodes}, encoding=encoding)
    u = read_vtk(path)
    assert u.GetNumberOfPoints() == mesh.n_nodes and u.GetNumberOfCells() == mesh.n_cells
    assert np.all(cell_types(u) == VTK_POLYGON)
    X = vtk_to_numpy(u.GetPoints().GetData())
    np.testing.assert_array_equal(X[:, :2], mesh.nodes)
    assert np.all(X[:, 2] == 0)
    # one loop per cell through all of its nodes, counter-clockwise, with the mesh's area
    loops = cell_point_lists(u)
    for c, loop in enumerate(loops):
        assert sorted(loop) == list(mesh.cell_nodes.row(c))
        P = X[loop, :2]
        Q = np.roll(P, -1, axis=0)
        area = 0.5 * np.sum(P[:, 0] * Q[:, 1] - Q[:, 0] * P[:, 1])
        assert area == pytest.approx(g.cell_volume[c], rel=1e-12)
    np.testing.assert_allclose(vtk_measures(u), g.cell_volume, rtol=1e-12)
    np.testing.assert_array_equal(cell_array(u, "region"), mesh.cell_region)
    assert u.GetCellData().GetArray("region").GetDataTypeAsString() == "int"
    np.testing.assert_array_equal(cell_array(u, "volume"), g.cell_volume)
    cen = cell_array(u, "centroid")
    assert cen.shape == (mesh.n_cells, 3)
    np.testing.assert_array_equal(cen[:, :2], vec)
    assert np.all(cen[:, 2] == 0)
    np.testing.assert_array_equal(cell_array(u, "flag"), g.cell_volume > np.median(g.cell_volume))
    np.testing.assert_array_equal(vtk_to_numpy(u.GetPointData().GetArray("sides")), sides)
    np.testing.assert_array_equal(vtk_to_numpy(u.GetPointData().GetArray("x"))[:, :2], mesh.nodes)


def test_bulk_2d_meshio(tmp_path):
    mesh = polygons2d()
    write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={"volume": mesh.geometry.cell_volume})
    m = meshio.read(tmp_path / "m.vtu")
    assert len(m.points) == mesh.n_nodes
    assert sum(len(b.data) for b in m.cells) == mesh.n_cells
    assert {b.type for b in m.cells} == {"polygon"}
    # meshio groups polygons by size: compare as multisets
    vol = np.concatenate(m.cell_data["volume"])
    np.testing.assert_allclose(np.sort(vol), np.sort(mesh.geometry.cell_volume))
    assert sorted(np.concatenate(m.cell_data["region"]).tolist()) == sorted(mesh.cell_region.tolist())


def test_polygon_loop_independent_of_face_order(tmp_path):
    """Loops are chained from the faces, not read off the cell_faces order."""
    import dataclasses

    mesh = polygons2d()
    cf = mesh.cell_faces
    rng = np.random.default_rng(0)
    perm = np.lexsort((rng.random(cf.nnz), cf.rows_of_entries()))   # shuffle faces within each cell
    shuffled = dataclasses.replace(mesh, cell_faces=Ragged(cf.offsets, cf.values[perm]),
                                   cell_face_sign=mesh.cell_face_sign[perm])
    u = read_vtk(write_bulk_vtu(tmp_path / "m.vtu", shuffled))
    np.testing.assert_allclose(vtk_measures(u), mesh.geometry.cell_volume, rtol=1e-12)
    X = vtk_to_numpy(u.GetPoints().GetData())
    for loop in cell_point_lists(u):
        P = X[loop, :2]
        Q = np.roll(P, -1, axis=0)
        assert np.sum(P[:, 0] * Q[:, 1] - Q[:, 0] * P[:, 1]) > 0


def test_polygon_loop_rejects_broken_boundaries(tmp_path):
    """A cell bounded by two loops or by an open chain cannot be one VTK polygon."""
    import dataclasses

    mesh = cartesian_mesh([np.linspace(0, 1, 4), np.linspace(0, 1, 4)])   # 3 x 3 squares
    cf, sgn = mesh.cell_faces, mesh.cell_face_sign
    a, b = 0, 8                                        # opposite corners: no shared node
    rows = [np.r_[cf.row(a), cf.row(b)]]
    signs = [np.r_[sgn[cf.offsets[a]:cf.offsets[a + 1]], sgn[cf.offsets[b]:cf.offsets[b + 1]]]]
    two_loops = dataclasses.replace(mesh, cell_faces=Ragged.from_rows(rows), cell_face_sign=np.concatenate(signs),
                                    cell_region=np.zeros(1, np.int32))
    with pytest.raises(ValueError, match="loop"):
        write_bulk_vtu(tmp_path / "m.vtu", two_loops)
    open_chain = dataclasses.replace(mesh, cell_faces=Ragged.from_rows([cf.row(0)[:3]]),
                                     cell_face_sign=sgn[:3], cell_region=np.zeros(1, np.int32))
    with pytest.raises(ValueError, match="loop"):
        write_bulk_vtu(tmp_path / "m.vtu", open_chain)
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- bulk, 3D

@pytest.mark.parametrize("name", MESHES_3D)
@pytest.mark.parametrize("encoding", ENCODINGS)
def test_bulk_3d_polyhedra_roundtrip(tmp_path, name, encoding):
    mesh = MESHES_3D[name]()
    g = mesh.geometry
    path = write_bulk_vtu(tmp_path / "m.vtu", mesh,
                          cell_data={"volume": g.cell_volume, "centroid": g.cell_centroid,
                                     "n_faces": mesh.cell_faces.counts.astype(np.int32)},
                          point_data={"id": np.arange(mesh.n_nodes)}, encoding=encoding)
    u = read_vtk(path)
    assert u.GetNumberOfPoints() == mesh.n_nodes and u.GetNumberOfCells() == mesh.n_cells
    assert np.all(cell_types(u) == VTK_POLYHEDRON)
    X = vtk_to_numpy(u.GetPoints().GetData())
    np.testing.assert_array_equal(X, mesh.nodes)
    for c, pts in enumerate(cell_point_lists(u)):
        assert sorted(pts) == list(mesh.cell_nodes.row(c))
    streams = face_streams(u)
    for c, faces in enumerate(streams):
        assert len(faces) == mesh.cell_faces.counts[c]
        # outward loops: the divergence theorem gives +|K|
        assert signed_volume(X, faces) == pytest.approx(g.cell_volume[c], rel=1e-12)
    np.testing.assert_allclose(vtk_measures(u), g.cell_volume, rtol=1e-10)
    np.testing.assert_array_equal(cell_array(u, "region"), mesh.cell_region)
    np.testing.assert_array_equal(cell_array(u, "volume"), g.cell_volume)
    np.testing.assert_array_equal(cell_array(u, "centroid"), g.cell_centroid)
    np.testing.assert_array_equal(cell_array(u, "n_faces"), mesh.cell_faces.counts)
    np.testing.assert_array_equal(vtk_to_numpy(u.GetPointData().GetArray("id")), np.arange(mesh.n_nodes))


@pytest.mark.parametrize("name", MESHES_3D)
def test_bulk_3d_meshio(tmp_path, name):
    mesh = MESHES_3D[name]()
    write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={"volume": mesh.geometry.cell_volume})
    m = meshio.read(tmp_path / "m.vtu")
    np.testing.assert_array_equal(m.points, mesh.nodes)
    assert all(b.type.startswith("polyhedron") for b in m.cells)
    assert sum(len(b.data) for b in m.cells) == mesh.n_cells
    vol = np.concatenate(m.cell_data["volume"])
    np.testing.assert_allclose(np.sort(vol), np.sort(mesh.geometry.cell_volume))


def test_bulk_data_errors_leave_no_file(tmp_path):
    mesh = cart2d()
    with pytest.raises(ValueError, match="cell_data"):
        write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={"bad": np.zeros(mesh.n_cells + 1)})
    with pytest.raises(ValueError, match="point_data"):
        write_bulk_vtu(tmp_path / "m.vtu", mesh, point_data={"bad": np.zeros(3)})
    with pytest.raises(ValueError, match="dtype"):
        write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={"bad": np.zeros(mesh.n_cells, complex)})
    assert list(tmp_path.iterdir()) == []


def test_bulk_region_and_names(tmp_path):
    """Regions are automatic; odd array names are escaped; a given 'region' wins."""
    mesh = polygons2d()
    path = write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={'p<&>"q': np.ones(mesh.n_cells)})
    u = read_vtk(path)
    np.testing.assert_array_equal(cell_array(u, 'p<&>"q'), 1.0)
    np.testing.assert_array_equal(cell_array(u, "region"), [0, 1, 1, 0])
    u = read_vtk(write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={"region": np.full(4, 7)}))
    np.testing.assert_array_equal(cell_array(u, "region"), 7)


# --------------------------------------------------------------------------- fractures

def frac2d():
    mesh = cartesian_mesh([grid_coordinates(0, 1, 4, [0.5]), grid_coordinates(0, 1, 4, [0.5])])
    return FracturedMesh.build(mesh, [FractureSpec("F", np.array([[0.25, 0.5], [1.0, 0.5]])),
                                      FractureSpec("G", np.array([[0.5, 1.0], [0.5, 0.0]]))])


def frac3d():
    mesh = cartesian_mesh([grid_coordinates(0, 1, 4, [0.5])] * 3)
    sq = np.array([[0.25, 0.25, 0.5], [0.75, 0.25, 0.5], [0.75, 0.75, 0.5], [0.25, 0.75, 0.5]])
    return FracturedMesh.build(mesh, [FractureSpec("F", sq),
                                      FractureSpec("G", sq[:, [2, 0, 1]], normal=np.array([-1.0, 0, 0]))])


@pytest.mark.parametrize("build", [frac2d, frac3d])
def test_fracture_vtu(tmp_path, build):
    fm = build()
    mesh, net = fm.mesh, fm.network
    g = mesh.geometry
    area = g.face_area[net.faces]
    path = write_fracture_vtu(tmp_path / "f.vtu", fm, cell_data={"area": area},
                              point_data={"sides": fm.side_counts()})
    u = read_vtk(path)
    used = np.unique(mesh.face_nodes.take(net.faces).values)
    assert u.GetNumberOfCells() == net.n_faces and u.GetNumberOfPoints() == used.size
    want_type = VTK_LINE if mesh.dim == 2 else VTK_POLYGON
    assert np.all(cell_types(u) == want_type)
    X = vtk_to_numpy(u.GetPoints().GetData())
    np.testing.assert_array_equal(X[:, :mesh.dim], mesh.nodes[used])
    np.testing.assert_array_equal(cell_array(u, "fracture"), net.fracture)
    assert u.GetCellData().GetArray("fracture").GetDataTypeAsString() == "int"
    normal = cell_array(u, "normal")
    assert normal.shape == (net.n_faces, 3)
    np.testing.assert_array_equal(normal[:, :mesh.dim], net.normal)
    np.testing.assert_array_equal(cell_array(u, "area"), area)
    np.testing.assert_array_equal(vtk_to_numpy(u.GetPointData().GetArray("sides")), fm.side_counts()[used])
    # each cell is its mesh face (same nodes), oriented so that its right-hand normal is n⁺
    for k, pts in enumerate(cell_point_lists(u)):
        assert sorted(used[pts]) == sorted(mesh.face_nodes.row(net.faces[k]))
        P = X[pts]
        if mesh.dim == 2:
            t = P[1, :2] - P[0, :2]
            n = np.array([t[1], -t[0]])                 # tangent turned clockwise
        else:
            n = 0.5 * np.sum(np.cross(P, np.roll(P, -1, axis=0)), axis=0)
        assert np.linalg.norm(n) == pytest.approx(area[k], rel=1e-12)
        np.testing.assert_allclose(n / area[k], normal[k, :mesh.dim], atol=1e-12)
    sizes = vtk_sizes(u, "Length" if mesh.dim == 2 else "Area")
    np.testing.assert_allclose(sizes, area, rtol=1e-12)
    m = meshio.read(path)
    assert len(m.points) == used.size and sum(len(b.data) for b in m.cells) == net.n_faces


def test_fracture_vtu_has_both_fractures():
    fm = frac3d()
    assert set(np.unique(fm.network.fracture)) == {0, 1}


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("encoding", ENCODINGS)
def test_fracture_vtu_without_fractures(tmp_path, dim, encoding):
    """No fractures: a valid empty grid (the files of ``polypore mesh`` always exist)."""
    fm = FracturedMesh.build(cartesian_mesh([grid_coordinates(0, 1, 2)] * dim), [])
    path = write_fracture_vtu(tmp_path / "f.vtu", fm, cell_data={"area": np.zeros(0)},
                              point_data={"sides": fm.side_counts()}, encoding=encoding)
    u = read_vtk(path)
    assert u.GetNumberOfPoints() == 0 and u.GetNumberOfCells() == 0
    assert u.GetCellData().GetArray("normal").GetNumberOfComponents() == 3


# --------------------------------------------------------------------------- pvd

def test_pvd(tmp_path):
    entries = [(0.0, "bulk_000.vtu"), (0.5, "bulk_001.vtu"), (1e-7, "sub/frac_001.vtu", 1)]
    path = write_pvd(tmp_path / "out" / "series.pvd", entries)
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.attrib["type"] == "Collection"
    ds = root.find("Collection").findall("DataSet")
    assert [(float(d.attrib["timestep"]), d.attrib["file"], int(d.attrib["part"])) for d in ds] == \
        [(0.0, "bulk_000.vtu", 0), (0.5, "bulk_001.vtu", 0), (1e-7, "sub/frac_001.vtu", 1)]
    with pytest.raises(ValueError):
        write_pvd(tmp_path / "bad.pvd", [(0.0,)])
    assert not (tmp_path / "bad.pvd").exists()


def test_pvd_files_resolve(tmp_path):
    """The collection's relative names point at readable VTU files next to the .pvd."""
    mesh = cart2d(2)
    write_bulk_vtu(tmp_path / "run" / "a.vtu", mesh, cell_data={"t": np.zeros(mesh.n_cells)})
    write_bulk_vtu(tmp_path / "run" / "b.vtu", mesh, cell_data={"t": np.ones(mesh.n_cells)})
    path = write_pvd(tmp_path / "run" / "s.pvd", [(0.0, "a.vtu"), (2.0, "b.vtu")])
    for d, t in zip(ET.parse(path).getroot().iter("DataSet"), (0.0, 1.0)):
        u = read_vtk(path.parent / d.attrib["file"])
        np.testing.assert_array_equal(cell_array(u, "t"), t)


# --------------------------------------------------------------------------- atomic writes

def test_atomic_path_failure_leaves_nothing(tmp_path):
    target = tmp_path / "a" / "b" / "x.txt"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            assert tmp.parent == target.parent and tmp != target
            tmp.write_text("partial")
            raise RuntimeError("boom")
    assert not target.exists()
    assert list(target.parent.iterdir()) == []


def test_atomic_path_failure_keeps_old_file(tmp_path):
    target = tmp_path / "x.txt"
    atomic_write_text(target, "old")
    with pytest.raises(KeyError):
        with atomic_path(target) as tmp:
            tmp.write_text("new but incomplete")
            raise KeyError("boom")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.txt"]


def test_atomic_writes_replace(tmp_path):
    target = tmp_path / "deep" / "x.bin"
    atomic_write_bytes(target, b"\x00\x01")
    assert target.read_bytes() == b"\x00\x01"
    atomic_write_text(target, "héllo")
    assert target.read_text(encoding="utf-8") == "héllo"
    with atomic_path(target) as tmp:
        assert not tmp.exists()
        tmp.write_bytes(b"z")
        assert target.read_text(encoding="utf-8") == "héllo"   # untouched until the block ends
    assert target.read_bytes() == b"z"
    assert sorted(p.name for p in target.parent.iterdir()) == ["x.bin"]


def test_atomic_path_nothing_written_is_an_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        with atomic_path(tmp_path / "x"):
            pass
    assert list(tmp_path.iterdir()) == []


def test_failed_vtu_write_keeps_old_file(tmp_path, monkeypatch):
    """A crash while writing the data leaves the previous complete file in place."""
    from polypore.io import vtu

    mesh = cart2d(2)
    path = write_bulk_vtu(tmp_path / "m.vtu", mesh)
    before = path.read_bytes()

    def boom(self, f):
        raise OSError("disk full")
    monkeypatch.setattr(vtu._DataWriter, "write_appended", boom)
    with pytest.raises(OSError):
        write_bulk_vtu(path, mesh, cell_data={"x": np.ones(mesh.n_cells)})
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.vtu"]


# --------------------------------------------------------------------------- size

def test_large_mesh_is_fast(tmp_path):
    import time

    mesh = cartesian_mesh([grid_coordinates(0, 1, 30)] * 3)   # 27 000 hexahedra
    t = time.perf_counter()
    write_bulk_vtu(tmp_path / "m.vtu", mesh, cell_data={"volume": mesh.geometry.cell_volume})
    assert time.perf_counter() - t < 5.0
    u = read_vtk(tmp_path / "m.vtu")
    assert u.GetNumberOfCells() == mesh.n_cells
    np.testing.assert_allclose(vtk_sizes(u, "Volume"), mesh.geometry.cell_volume, rtol=1e-10)
