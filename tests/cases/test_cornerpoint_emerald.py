"""The built-in case emerald-injection (issue 15): the real Emerald grid shipped as package data
with its licence, two of its faults as contact surfaces with their own friction, materials and
flow data per facies, a well; set up on the grid (the full run needs PARDISO to stay short)."""

import json
from importlib import resources

import numpy as np
import pytest

from polypore.cli import main
from polypore.setup.casefile import load_case
from polypore.setup.flow import well_cells
from polypore.setup.meshing import build_fractured_mesh, cornerpoint_of
from polypore.setup.poromechanics import poro_setup
from polypore.solvers.linear import have_pardiso


def test_grid_and_licence_are_package_data():
    data = resources.files("polypore.cases") / "data"
    text = (data / "emerald.grdecl").read_text()
    assert "equinor/xtgeo-testdata" in text[:400] and "LGPL" in text[:400]
    assert "GNU LESSER GENERAL PUBLIC LICENSE" in (data / "LICENSE-xtgeo-testdata.md").read_text()
    assert "emerald.grdecl" in (data / "GRIDS.md").read_text()


def test_emerald_case_sets_up():
    case = load_case("emerald-injection")
    fm = build_fractured_mesh(case)
    grid, info = cornerpoint_of(fm.mesh)
    assert grid.dims == (21, 41, 18) and fm.mesh.n_cells == 7157
    assert set(info.faults) == {f"fault_{k}" for k in range(1, 6)}
    net = fm.network
    assert net.names == ("west", "north")
    assert np.array_equal(np.sort(net.faces[net.fracture == 0]), np.sort(info.faults["fault_1"]))
    assert list(fm.mesh.region_names) == ["FACIES_0", "FACIES_1"]
    model, fs, ms = poro_setup(case, fm)
    F = ms.data.contact.friction
    assert np.all(F[net.fracture == 0] == 0.55) and np.all(F[net.fracture == 1] == 0.71)
    sand = fm.mesh.cell_region == list(fm.mesh.region_names).index("FACIES_1")
    assert np.all(ms.E[sand] == 1e10) and np.all(ms.E[~sand] == 2e10)
    facies = info.cell_values(grid.properties["FACIES"])
    assert np.array_equal(sand, facies == 1)
    assert np.allclose(fs.data.permeability[sand, 0, 0], 1e-13)
    cells = well_cells(fm.mesh, case.spec.flow.wells[0], "flow.wells.I1")
    assert cells.size == 4 and np.all(facies[cells] == 1)                # the well is in the lower sand
    # the in-situ state keeps both faults below their friction (no slip before injection)
    lam0 = model.reference.traction(fm)                                   # λ⁰ = −(σ⁰ + p_h I) n⁺
    n = net.normal
    ln = np.einsum("fi,fi->f", lam0, n)                                   # > 0: compression
    lt = np.linalg.norm(lam0 - ln[:, None] * n, axis=1)
    assert np.all(ln > 0) and np.all(lt < F * ln)
    assert np.all(lt > 0.8 * F * ln)                                      # but close to it: within 20%


def test_results_copy_of_the_case_finds_the_shipped_grid(tmp_path):
    assert main(["mesh", "emerald-injection", "--out", str(tmp_path / "m")]) == 0
    # the resolved case.toml has no folder of its own grid: the shipped grid is found
    assert main(["mesh", str(tmp_path / "m" / "case.toml"), "--out", str(tmp_path / "m2")]) == 0
    report = json.loads((tmp_path / "m2" / "mesh.json").read_text())
    assert report["mesh"]["cells"] == 7157
    # the per-fault report of summary.json, also without a run (issue 25): names, faces and which
    # [[fractures]] entry uses each fault
    faults = report["faults"]
    assert sorted(faults) == [f"fault_{i}" for i in range(1, 6)]
    used = {f["fracture"]: f["faces"] for f in faults.values() if f["fracture"]}
    assert used == {"west": 147, "north": 132}
    assert sum(used.values()) == report["mesh"]["fracture_faces"] == 279


@pytest.mark.skipif(not have_pardiso(), reason="PARDISO not installed: SuperLU takes minutes per step here")
def test_emerald_case_runs_one_step(tmp_path):
    out = tmp_path / "o"
    assert main(["run", "emerald-injection", "--out", str(out), "--set", "time.end=86400"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["mesh"]["fracture_faces"] == 279 and len(s["steps"]) == 1        # 281 without snapping, 249 unbounded
    assert (out / "solution.pvd").is_file() and (out / "fractures_0001.vtu").is_file()
    # the poroelastic bound of docs/contact_patches.md: no fault traction moves by more than 3x the
    # largest overpressure (13.6x on a 5 m² face over the run, 4.7x after its first day, before the
    # multiplier patches and the face-scaled bubbles)
    import csv

    rows = list(csv.DictReader(open(out / "fractures.csv", newline="")))
    ln = {}
    for r in rows:
        ln.setdefault(int(r["step"]), []).append(float(r["lambda_n"]))
    steps = sorted(ln)
    change = np.abs(np.array(ln[steps[-1]]) - np.array(ln[steps[0]]))
    assert change.max() < 3.0 * max(s["monitor"]["max_overpressure"])
