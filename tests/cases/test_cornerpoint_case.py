"""Corner-point grids in case files (issue 15): the grdecl and cornerpoint generators, boundary
names, faults selected as contact surfaces, grid properties in the flow data, wells, the
built-in case cornerpoint-injection."""

import dataclasses
import json

import numpy as np
import pytest

from conftest import CORNERPOINT_MESH, case

from polypore.cli import main
from polypore.core.errors import InputError
from polypore.mesh.cornerpoint import MILLIDARCY, FaultSpec, generate_grid, write_grdecl
from polypore.setup.flow import flow_setup, well_cells
from polypore.setup.meshing import build_fractured_mesh, cornerpoint_of

MESH = CORNERPOINT_MESH
FLOW = """
[flow]
permeability = "grdecl"
porosity = "grdecl"
fluid_compressibility = 4.4e-10
initial_pressure = 0.0
[[flow.boundary]]
name = "west"
pressure = 0.0
[[flow.wells]]
name = "I1"
column = [2, 3]
layers = [2, 3]
mass_rate = 4.0
[time]
end = 10.0
step = 10.0
"""


def test_cornerpoint_generator_boundaries_and_fault_selection(tmp_path):
    fm = build_fractured_mesh(case(tmp_path, MESH + '[[fractures]]\nname = "slipper"\nfault = "F1"\n'))
    assert fm.mesh.n_cells == 72
    assert {"west", "east", "south", "north", "top", "bottom", "internal"} <= set(fm.mesh.boundary)
    assert fm.network.names == ("slipper",)              # F2 stays bonded
    grid, info = cornerpoint_of(fm.mesh)
    assert set(info.faults) == {"F1", "F2"}
    assert np.array_equal(np.sort(fm.network.faces), np.sort(info.faults["F1"]))
    # no [[fractures]]: every fault bonded
    assert build_fractured_mesh(case(tmp_path, MESH, name="d.toml")).network.n_faces == 0


@pytest.mark.parametrize("extra,field,words", [
    ('[[fractures]]\nname = "F3"\n', "fractures.F3.name", ["unknown fault 'F3'", "F1, F2"]),
    ('[[fractures]]\nname = "a"\nfault = "f1"\n', "fractures.a.fault", ["'f1'", "did you mean 'F1'"]),
    ('[[fractures]]\nname = "a"\nfault = "F_1"\n', "fractures.a.fault", ["did you mean 'F1'"]),
    ('[[fractures]]\nname = "a"\nfault = "F1"\n[[fractures]]\nname = "b"\nfault = "F1"\n', "fractures.b.fault",
     ["selected twice"]),
])
def test_unknown_or_twice_selected_fault(tmp_path, extra, field, words):
    with pytest.raises(InputError) as e:
        build_fractured_mesh(case(tmp_path, MESH + extra))
    assert e.value.field == field
    assert all(w in str(e.value) for w in words), str(e.value)


@pytest.mark.parametrize("text,field", [
    (MESH + '[[fractures]]\nname = "F1"\nvertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0]]\n', "fractures.F1.vertices"),
    (MESH.replace("index = 4", "index = 6"), "mesh.faults.F2.index"),
    (MESH.replace('cells = [6, 4, 3]', 'size = 1.0'), "mesh.size"),
    ('[mesh]\ngenerator = "grdecl"\n', "mesh.file"),
    ('[mesh]\nlower = [0, 0, 0]\nupper = [1, 1, 1]\nsize = 0.5\n[[fractures]]\nname = "a"\nfault = "F1"\n'
     'vertices = [[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5]]\n', "fractures.a.fault"),
])
def test_schema_errors_name_the_field(tmp_path, text, field):
    with pytest.raises(InputError) as e:
        case(tmp_path, text)
    assert e.value.field.startswith(field), (e.value.field, str(e.value))


def test_grdecl_file_properties_and_well(tmp_path):
    grid = generate_grid(6, 4, 3, extent=(600.0, 400.0, 60.0), top=1500.0,
                         faults=[FaultSpec("i", 3, 20.0, name="FA")])
    props = dict(grid.properties)
    props["NTG"] = np.full(grid.dims, 0.5)
    props["PERMX"] = np.full(grid.dims, 200.0)
    import dataclasses
    (tmp_path / "sub").mkdir()
    write_grdecl(dataclasses.replace(grid, properties=props), tmp_path / "sub" / "m.grdecl")
    text = ('[mesh]\ngenerator = "grdecl"\nfile = "sub/m.grdecl"\nnonplanar = "keep"\n[[fractures]]\nname = "FA"\n'
            + FLOW)
    c = case(tmp_path, text)
    fm = build_fractured_mesh(c)
    assert fm.network.names == ("FA",)
    fs = flow_setup(c, fm)
    K = fs.data.permeability
    assert np.allclose(K[:, 0, 0], 100.0 * MILLIDARCY) and np.allclose(K[:, 2, 2], 10.0 * MILLIDARCY)
    # porosity PORO × NTG = 0.1 -> M = 1/(φ c_w)
    assert np.allclose(fs.data.biot_modulus, 1.0 / (0.1 * 4.4e-10))
    cells = well_cells(fm.mesh, c.spec.flow.wells[0], "flow.wells.I1")
    grid2, info = cornerpoint_of(fm.mesh)
    assert cells.size == 2 and set(map(tuple, info.cell_ijk[cells])) == {(1, 2, 1), (1, 2, 2)}
    g = fm.mesh.geometry
    h = fs.cell_source(*g.cell_centroid.T, 0.0)
    assert np.isclose(np.sum(h * g.cell_volume), 4.0 / 1000.0)      # m³/s injected
    assert np.count_nonzero(h) == 2
    # a missing file, a well outside the grid
    with pytest.raises(InputError, match="does not exist") as e:
        build_fractured_mesh(case(tmp_path, text.replace("sub/m", "nope"), name="e.toml"))
    assert e.value.field == "mesh.file"
    c = case(tmp_path, text, "flow.wells.I1.column=[7, 1]", name="f.toml")
    with pytest.raises(InputError, match="outside the grid") as e:
        flow_setup(c, build_fractured_mesh(c))
    assert e.value.field == "flow.wells.I1.column"


def test_grdecl_values_need_a_cornerpoint_mesh(tmp_path):
    text = ('[mesh]\ngenerator = "cartesian"\nlower = [0, 0, 0]\nupper = [1, 1, 1]\ncells = [2, 2, 2]\n[flow]\n'
            'permeability = "grdecl"\n[[flow.boundary]]\nname = "xmin"\npressure = 0.0\n')
    c = case(tmp_path, text)
    with pytest.raises(InputError, match="not one") as e:
        flow_setup(c, build_fractured_mesh(c))
    assert e.value.field == "flow.permeability"


def test_builtin_case_runs(tmp_path):
    out = tmp_path / "o"
    assert main(["run", "cornerpoint-injection", "--out", str(out), "--set", "time.end=86400"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["case"] == "cornerpoint-injection" and set(summary["monitor"]) >= {"well", "fault"} or \
        summary["monitor"]
    assert (out / "solution.pvd").is_file() and (out / "fractures_0001.vtu").is_file()
    # unknowns per block (issue 26): they add up to the run's unknowns; one pressure per cell,
    # HFV face pressures, the fault's traces and faces, nodal displacements and one bubble per
    # fault face (one-sided), 3 multipliers per patch
    m = summary["mesh"]
    b = m["blocks"]
    assert sum(v for k, v in b.items() if k != "per_cell") == m["unknowns"]
    assert b["pressure_cells"] == m["cells"] and b["multipliers"] == 3 * m["multiplier_patches"]["patches"]
    assert 0 < b["displacement_bubbles"] <= 3 * m["fracture_faces"] and b["pressure_fractures"] == m["fracture_faces"]
    assert b["per_cell"] == pytest.approx(m["unknowns"] / m["cells"], abs=1e-3)
    # the linear solver "auto" chose, and why (a small grid: direct)
    assert summary["choices"]["linear_solver"] in ("pardiso", "superlu")
    assert summary["choices"]["linear_solver_source"].startswith("auto: about")


def test_generated_layer_permeability(tmp_path):
    """mesh.layer_permeability: PERMX = PERMY per layer from the top, repeated down the stack,
    PERMZ a tenth; a bad value names the key."""
    from polypore.mesh.cornerpoint import generate_grid

    g = generate_grid(2, 2, 5, layer_permeability=[1000.0, 0.001])
    assert g.properties["PERMX"][0, 0].tolist() == [1000.0, 0.001, 1000.0, 0.001, 1000.0]
    assert np.array_equal(g.properties["PERMZ"], 0.1 * g.properties["PERMY"])
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh

    case = load_case("cornerpoint-injection", ["mesh.layer_permeability=[1000.0, 1e-3]"])
    fm = build_fractured_mesh(case)
    assert fm.mesh.n_cells == 1600
    with pytest.raises(Exception) as e:
        load_case("cornerpoint-injection", ["mesh.layer_permeability=[100.0, -1.0]"])
    assert "layer_permeability" in str(e.value) and "-1.0" in str(e.value)
