"""Corner-point refinement (issue 24, mesh/cornerpoint/refine.py): every cell split along its
pillars into a corner-point grid again; volumes, faults, cell keywords and wells follow."""

import dataclasses

import numpy as np
import pytest

from conftest import CORNERPOINT_MESH, case
from polypore.core.errors import InputError
from polypore.mesh.cornerpoint import FaultSpec, generate_grid, process_grid, read_grdecl, write_grdecl
from polypore.mesh.cornerpoint.refine import refine_grid
from test_cornerpoint import DATA

AB = (FaultSpec("i", 3, 25.0, name="A"), FaultSpec("j", 4, -12.0, start=1, stop=5, name="B"))
GENERATED = {
    "two-faults": dict(faults=AB),
    "pinch-inactive": dict(faults=AB, pinchout=[1], inactive=0.1, dip=4.0),
    "left-handed": dict(faults=AB, pinchout=[1, 2], dip=5.0, left_handed=True),
    "parallel-tilted": dict(faults=AB, dip=3.0, mapaxes=[[0.0, 100.0], [0.0, 0.0], [100.0, 0.0]]),
}
# the shared grids with parallel pillars (with skew pillars a child follows the interpolated
# pillars, not its parent's trilinear cell: the sum differs by 2e-7 (sixcells_lefthanded), 2e-3
# (sixcells2), 2% (concave; Emerald: 1.5% at most per parent, 1e-5 in total)
SHARED = ["b.grdecl", "banal6.grdecl", "simpleb8.grdecl", "dual_distorted1.grdecl"]


def grid_of(name):
    if name in GENERATED:
        return generate_grid(6, 8, 4, (600.0, 800.0, 40.0), **GENERATED[name])
    return read_grdecl(DATA / name)


def parent_volumes(grid, r):
    """(nx, ny, nz) volumes of the processed cells (snap = 0) of ``grid`` refined by ``r``, summed
    over each parent."""
    mesh, info = process_grid(refine_grid(grid, r), snap=0)
    v = np.zeros(grid.dims)
    np.add.at(v, tuple((info.cell_ijk // np.array(r)).T), mesh.geometry.cell_volume)
    return v, mesh, info


@pytest.mark.parametrize("name", list(GENERATED) + SHARED)
def test_children_volumes_sum_to_the_parent(name):
    g = grid_of(name)
    mesh, info = process_grid(g, snap=0)
    v0 = np.zeros(g.dims)
    v0[tuple(info.cell_ijk.T)] = mesh.geometry.cell_volume
    for r in ((2, 2, 2), (3, 1, 2)):
        v, rm, ri = parent_volumes(g, r)
        assert np.abs(v - v0).max() <= 1e-12 * np.abs(v0).max(), (r, np.abs(v - v0).max() / v0.max())
        assert np.all((v > 0) == (v0 > 0))         # inactive and collapsed parents have no children


def test_refined_grid_is_a_corner_point_grid_with_its_data():
    g = grid_of("pinch-inactive")
    props = dict(g.properties)
    props["MULTX"] = np.arange(g.n_cells, dtype=float).reshape(g.dims)
    g = dataclasses.replace(g, properties=props)
    r = refine_grid(g, (2, 3, 2))
    assert r.dims == (12, 24, 8)
    assert sorted(r.properties) == sorted(g.properties)
    I, J, K = np.meshgrid(*(np.arange(n) for n in r.dims), indexing="ij")
    P = (I // 2, J // 3, K // 2)
    for k, v in g.properties.items():
        assert np.array_equal(r.properties[k], v[P]), k
    assert np.array_equal(r.actnum, g.actnum[P])
    # old pillars are kept, every corner of a parent's corner stays where it was
    assert np.array_equal(r.coord[::2, ::3], g.coord)
    Zr, Z = r.cell_corners(), g.cell_corners()
    assert np.array_equal(Zr[::2, ::3, ::2, 0, 0, 0], Z[..., 0, 0, 0])
    assert np.array_equal(Zr[1::2, 2::3, 1::2, 1, 1, 1], Z[..., 1, 1, 1])
    # FAULTS: A on the +X faces of i = 3 -> i = 6; B on the +Y faces of j = 4 (i 2...5) -> j = 12 (i 3...10)
    assert g.faults == {"A": ((3, 3, 1, 8, 1, 4, "X"),), "B": ((2, 5, 4, 4, 1, 4, "Y"),)}
    assert r.faults == {"A": ((6, 6, 1, 24, 1, 8, "X"),), "B": ((3, 10, 12, 12, 1, 8, "Y"),)}
    assert refine_grid(g, [1, 1, 1]) is g
    # a record over several cells across its face is split: one record per old face line
    g2 = dataclasses.replace(g, faults={"W": ((2, 3, 1, 2, 1, 1, "X-"), (1, 1, 1, 1, 4, 4, "Z"))})
    assert refine_grid(g2, (2, 2, 3)).faults == {"W": ((3, 3, 1, 4, 1, 3, "X-"), (5, 5, 1, 4, 1, 3, "X-"),
                                                       (1, 2, 1, 2, 12, 12, "Z"))}


@pytest.mark.parametrize("name", ["two-faults", "left-handed"])
def test_faults_keep_names_and_area(name):
    """2 × 2 × 2 with the faults named by FAULTS; found from the geometry, with 2 × 2 × 3 (A's
    throw of 2.5 layers would be 5 refined layers by 2 × 2 × 2: then the cells across A match
    corner for corner, and a fault found from the geometry alone does not see it; FAULTS does)."""
    g = grid_of(name)
    for grid, r in ((g, (2, 2, 2)), (dataclasses.replace(g, faults={}), (2, 2, 3))):
        m0, i0 = process_grid(grid, snap=0)
        m1, i1 = process_grid(refine_grid(grid, r), snap=0)
        assert sorted(i1.faults) == sorted(i0.faults) and len(i0.faults) == 2
        for k, f in i0.faults.items():
            a0, a1 = m0.geometry.face_area[f].sum(), m1.geometry.face_area[i1.faults[k]].sum()
            assert a1 == pytest.approx(a0, rel=1e-12), k
            assert i1.faults[k].size > f.size


def test_emerald_refined():
    """The shipped Emerald grid (skew pillars): 2 × 2 × 1 keeps its faults and their areas (to
    5e-5), its volume to 1e-5 (the interpolated pillars are not the parents' trilinear cells).
    Its faults are named from the geometry, by their first face: the names are the same, the
    areas are compared as sets (the order of the names could follow the face numbering)."""
    from test_cornerpoint_slivers import EMERALD

    g = read_grdecl(EMERALD)
    m0, i0 = process_grid(g, snap=0)
    m1, i1 = process_grid(refine_grid(g, (2, 2, 1)), snap=0)
    assert sorted(i1.faults) == sorted(i0.faults) and len(i0.faults) == 5
    assert m1.volume == pytest.approx(m0.volume, rel=2e-5)
    a0 = np.sort([m0.geometry.face_area[f].sum() for f in i0.faults.values()])
    a1 = np.sort([m1.geometry.face_area[f].sum() for f in i1.faults.values()])
    assert np.allclose(a1, a0, rtol=1e-4, atol=0)


def test_refinement_of_a_refinement():
    """Trilinear corner depths and bilinear pillars are reproduced by interpolation: refining by a
    then by b is refining by a·b (an affine grid, and a faulted one with tilted pillars)."""
    for g in (generate_grid(3, 4, 2, (300.0, 400.0, 20.0), dip=5.0),
              generate_grid(4, 5, 3, (400.0, 500.0, 30.0), faults=AB[:1], pillar_tilt=0.05, dip=3.0)):
        once = refine_grid(g, (6, 2, 3))
        twice = refine_grid(refine_grid(g, (2, 1, 3)), (3, 2, 1))
        assert twice.dims == once.dims and twice.faults == once.faults
        assert np.allclose(twice.coord, once.coord, rtol=0, atol=1e-12 * np.abs(g.coord).max())
        assert np.allclose(twice.zcorn, once.zcorn, rtol=0, atol=1e-12 * np.abs(g.zcorn).max())
        assert np.array_equal(twice.actnum, once.actnum)


@pytest.mark.parametrize("value", ["[0, 1, 1]", "[2, -1, 1]", "[1.5, 1, 1]", "[2, 2]", "2"])
def test_bad_refine_names_the_key(tmp_path, value):
    with pytest.raises(InputError) as e:
        case(tmp_path, CORNERPOINT_MESH.replace("top = 1500.0", f"top = 1500.0\nrefine = {value}"))
    assert e.value.field == "mesh.refine", str(e.value)
    with pytest.raises(InputError) as e:
        refine_grid(grid_of("two-faults"), [0, 1, 1])
    assert e.value.field == "refine" and "positive integers" in str(e.value)


def test_refine_too_many_cells(tmp_path):
    """The size guard estimates the refined grid (from mesh.cells or the GRDECL header)."""
    from polypore.setup.limits import check_limits, estimate_cells

    c = case(tmp_path, CORNERPOINT_MESH.replace("top = 1500.0", "top = 1500.0\nrefine = [1000, 1000, 100]"))
    assert estimate_cells(c.spec) == (72e8, "mesh.refine")
    with pytest.raises(InputError, match="about 7.2e[+]09 cells") as e:
        check_limits(c.spec)
    assert e.value.field == "mesh.refine"
    write_grdecl(grid_of("two-faults"), tmp_path / "m.grdecl")
    c = case(tmp_path, '[mesh]\ngenerator = "grdecl"\nfile = "m.grdecl"\nrefine = [100, 100, 100]\n', name="g.toml")
    assert estimate_cells(c.spec) == (192e6, "mesh.refine")
    with pytest.raises(InputError) as e:
        check_limits(c.spec, memory=1e9)
    assert e.value.field == "mesh.refine"
    c = case(tmp_path, '[mesh]\ngenerator = "grdecl"\nfile = "m.grdecl"\n', name="h.toml")
    assert estimate_cells(c.spec) == (192.0, "mesh.file")
    with pytest.raises(InputError, match="at most 2,147,483,647 cells") as e:      # the guard without --no-limits
        refine_grid(grid_of("two-faults"), (1000, 1000, 100))
    assert e.value.field == "refine"              # the library call names its parameter


def test_refine_in_a_case_with_a_well(tmp_path):
    """mesh.refine in a grdecl case: faults named, keywords copied, the well [2, 3] layers [2, 3]
    of the file's grid is the children's columns around the old column's centre line (the middle
    child for an odd factor, the two middle ones for an even factor): the well does not move."""
    from polypore.setup.flow import flow_setup, well_cells
    from polypore.setup.meshing import build_fractured_mesh, cornerpoint_of
    from test_cornerpoint_case import FLOW

    g = generate_grid(6, 4, 3, extent=(600.0, 400.0, 60.0), top=1500.0, faults=[FaultSpec("i", 3, 20.0, name="FA")])
    write_grdecl(g, tmp_path / "m.grdecl")
    text = '[mesh]\ngenerator = "grdecl"\nfile = "m.grdecl"\nnonplanar = "keep"\n[[fractures]]\nname = "FA"\n' + FLOW
    base = case(tmp_path, text)
    fm0 = build_fractured_mesh(base)
    c = case(tmp_path, text, "mesh.refine=[3, 2, 2]", name="r.toml")
    fm = build_fractured_mesh(c)
    assert fm.network.names == ("FA",) and fm.mesh.n_cells == 12 * fm0.mesh.n_cells
    assert fm.mesh.volume == pytest.approx(fm0.mesh.volume, rel=1e-12)
    a0, a1 = (f.mesh.geometry.face_area[f.network.faces].sum() for f in (fm0, fm))
    assert a1 == pytest.approx(a0, rel=1e-12)
    grid, info = cornerpoint_of(fm.mesh)
    assert grid.dims == (18, 8, 6)
    cells = well_cells(fm.mesh, c.spec.flow.wells[0], "flow.wells.I1")
    # old column (1, 2) (0-based) -> children i 3...5, j 4...5: middle i 4, both j; layers 2, 3 -> 3 ... 6
    assert set(map(tuple, info.cell_ijk[cells])) == {(4, j, k) for j in (4, 5) for k in range(2, 6)}
    fs = flow_setup(c, fm)
    geo = fm.mesh.geometry
    h = fs.cell_source(*geo.cell_centroid.T, 0.0)
    assert np.isclose(np.sum(h * geo.cell_volume), 4.0 / 1000.0) and np.count_nonzero(h) == 8
    # the source's centre in the map is the old well column's centre
    old = well_cells(fm0.mesh, base.spec.flow.wells[0], "flow.wells.I1")
    g0 = fm0.mesh.geometry
    c0 = np.average(g0.cell_centroid[old, :2], axis=0, weights=g0.cell_volume[old])
    c1 = np.average(geo.cell_centroid[:, :2], axis=0, weights=h * geo.cell_volume)
    assert np.allclose(c1, c0, atol=1e-9 * 600.0)
    c = case(tmp_path, text, "mesh.refine=[3, 2, 2]", "flow.wells.I1.column=[7, 1]", name="s.toml")
    with pytest.raises(InputError, match=r"i in 1 \.\.\. 6") as e:     # the file's indices
        flow_setup(c, build_fractured_mesh(c))
    assert e.value.field == "flow.wells.I1.column"
