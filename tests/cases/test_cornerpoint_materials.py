"""Mechanical properties from a corner-point grid's keywords (issue 15): E and ν per cell from a
keyword ("grdecl:KW"), by the values of an integer keyword through a table, and per region of
``region_keyword`` with [[materials]]; errors name the field, the value and what is allowed."""

import dataclasses

import numpy as np
import pytest

from polypore.core.errors import InputError
from polypore.mesh.cornerpoint import generate_grid, write_grdecl
from polypore.setup.casefile import load_case
from polypore.setup.mechanics import mechanics_setup
from polypore.setup.meshing import build_fractured_mesh, cornerpoint_of

BC = '[[mechanics.boundary]]\nname = "bottom"\nu = [0, 0, 0]\n'


@pytest.fixture
def grid_dir(tmp_path):
    """A 4 × 3 × 3 grid with FACIES (layer k -> k % 2, 2 in the corner column), YMOD (GPa × 1e9) and
    PR keywords, written to tmp_path/m.grdecl."""
    g = generate_grid(4, 3, 3, extent=(400.0, 300.0, 30.0), top=1000.0)
    k = np.broadcast_to(np.arange(3), g.dims)
    facies = (k % 2).astype(float)
    facies[3, 2, :] = 2
    props = dict(g.properties, FACIES=facies, YMOD=1e9 * (10.0 + k), PR=0.2 + 0.01 * k,
                 POROX=np.full(g.dims, 0.3))
    write_grdecl(dataclasses.replace(g, properties=props), tmp_path / "m.grdecl")
    return tmp_path


def setup(tmp_path, material, mesh_extra="", name="c.toml"):
    p = tmp_path / name
    p.write_text(f'[mesh]\ngenerator = "grdecl"\nfile = "m.grdecl"\n{mesh_extra}\n{material}\n{BC}')
    c = load_case(str(p))
    fm = build_fractured_mesh(c)
    ms = mechanics_setup(c, fm)
    _, info = cornerpoint_of(fm.mesh)
    return ms, info


def test_E_and_nu_from_keywords(grid_dir):
    ms, info = setup(grid_dir, '[material]\nE = "grdecl:YMOD"\nnu = "grdecl:PR"\n')
    k = info.cell_ijk[:, 2]
    assert np.allclose(ms.E, 1e9 * (10.0 + k)) and np.allclose(ms.nu, 0.2 + 0.01 * k)
    mu = ms.E / (2 * (1 + ms.nu))
    assert np.allclose(ms.data.mu, mu)


def test_E_and_nu_by_keyword_value(grid_dir):
    ms, info = setup(grid_dir, '[material]\nkeyword = "FACIES"\nE = { 0 = 2.0e10, 1 = 1.0e10, 2 = 5.0e9 }\n'
                               'nu = 0.25\n')
    i, j, k = info.cell_ijk.T
    expect = np.where((i == 3) & (j == 2), 5e9, np.where(k % 2 == 0, 2e10, 1e10))
    assert np.array_equal(ms.E, expect) and np.all(ms.nu == 0.25)


def test_materials_per_region_of_region_keyword(grid_dir):
    mats = "".join(f'[[materials]]\nregion = "FACIES_{v}"\nE = {e}\nnu = 0.3\n' for v, e in
                   ((0, 2e10), (1, 1e10), (2, 3e10)))
    ms, info = setup(grid_dir, mats, 'region_keyword = "FACIES"')
    i, j, k = info.cell_ijk.T
    assert np.array_equal(ms.E, np.where((i == 3) & (j == 2), 3e10, np.where(k % 2 == 0, 2e10, 1e10)))
    # a region material may itself take E from a keyword
    mats = mats.replace("E = 10000000000.0", 'E = "grdecl:YMOD"')
    ms, info = setup(grid_dir, mats, 'region_keyword = "FACIES"', name="d.toml")
    sel = (info.cell_ijk[:, 2] % 2 == 1) & ~((info.cell_ijk[:, 0] == 3) & (info.cell_ijk[:, 1] == 2))
    assert np.allclose(ms.E[sel], 11e9)


@pytest.mark.parametrize("material,field,words", [
    ('E = "grdecl:YOUNG"\nnu = 0.25', "material.E", ["no cell keyword YOUNG", "FACIES", "YMOD"]),
    ('E = "grdecl:PR"\nnu = "grdecl:YMOD"', "material.nu", ["'grdecl:YMOD'", "cell (1, 1, 1)", "(−1, 0.5)"]),
    ('keyword = "FACIES"\nE = { 0 = 2.0e10, 1 = 1.0e10 }\nnu = 0.25', "material.E",
     ["no value for FACIES = 2", "cell (4, 3, 1)", "gives FACIES = 0, 1", "have FACIES = 0, 1, 2"]),
    ('keyword = "SATNUM"\nE = { 0 = 2.0e10 }\nnu = 0.25', "material.keyword", ["no cell keyword SATNUM"]),
    ('keyword = "PR"\nE = { 0 = 2.0e10 }\nnu = 0.25', "material.keyword", ["integers", "cell (1, 1, 1)"]),
])
def test_bad_keyword_values_name_field_value_and_allowed(grid_dir, material, field, words):
    with pytest.raises(InputError) as e:
        setup(grid_dir, "[material]\n" + material)
    assert e.value.field == field, (e.value.field, str(e.value))
    assert all(w in str(e.value) for w in words), str(e.value)


@pytest.mark.parametrize("material,field,words", [
    ('E = { 0 = 2.0e10 }\nnu = 0.25', "material.keyword", ["is required"]),
    ('keyword = "FACIES"\nE = 1e10\nnu = 0.25', "material.keyword", ["applies to tables"]),
    ('keyword = "FACIES"\nE = { 0 = -2.0e10 }\nnu = 0.25', "material.E.0", ["positive"]),
    ('keyword = "FACIES"\nE = { a = 2.0e10 }\nnu = 0.25', "material.E.a", ["integer values"]),
    ('keyword = "FACIES"\nE = 1e10\nnu = { 0 = 0.7 }', "material.nu.0", ["(−1, 0.5)"]),
    ('E = "grdecl:"\nnu = 0.25', "material.E", ["grdecl:KEYWORD"]),
])
def test_schema_checks_material_tables(grid_dir, material, field, words):
    p = grid_dir / "s.toml"
    p.write_text(f'[mesh]\ngenerator = "grdecl"\nfile = "m.grdecl"\n[material]\n{material}\n')
    with pytest.raises(InputError) as e:
        load_case(str(p))
    assert e.value.field == field, (e.value.field, str(e.value))
    assert all(w in str(e.value) for w in words), str(e.value)


def test_keyword_values_need_a_cornerpoint_mesh(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[mesh]\ngenerator = "cartesian"\nlower = [0, 0, 0]\nupper = [1, 1, 1]\ncells = [1, 1, 1]\n'
                 '[material]\nE = "grdecl:YMOD"\nnu = 0.25\n')
    with pytest.raises(InputError, match="not one") as e:
        load_case(str(p))
    assert e.value.field == "material.E"
