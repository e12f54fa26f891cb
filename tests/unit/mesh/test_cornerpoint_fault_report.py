"""Per-fault report (issue 24): faces, cells on each side, area, dip and dip azimuth / strike of
every fault of a corner-point grid, checked on a generated grid whose fault attitude is known."""

import numpy as np
import pytest

from polypore.mesh.cornerpoint import (CornerPointGrid, FaultSpec, fault_report, fault_table, generate_grid,
                                       process_grid)


def inclined_fault_grid(dip: float, rotate: float, inactive=None):
    """6×4×4 grid (100 m columns, 10 m layers) with one fault on the pillar line i = 3 (throw
    15 m, the east side down); all pillars lean east so that the fault dips ``dip`` degrees
    towards +x, then the map is rotated ``rotate`` degrees anticlockwise."""
    g = generate_grid(6, 4, 4, (600.0, 400.0, 40.0), faults=(FaultSpec("i", 3, 15.0, name="F"),),
                      inactive=np.zeros((6, 4, 4), bool) if inactive is None else inactive)
    c = g.coord.copy()
    c[..., 3] = c[..., 0] + (c[..., 5] - c[..., 2]) / np.tan(np.radians(dip))
    r = np.radians(rotate)
    R = np.array([[np.cos(r), -np.sin(r)], [np.sin(r), np.cos(r)]])
    c[..., 0:2] = c[..., 0:2] @ R.T
    c[..., 3:5] = c[..., 3:5] @ R.T
    return CornerPointGrid(g.dims, c, g.zcorn, g.actnum, None, g.faults)


@pytest.mark.parametrize("dip, rotate", [(60.0, 30.0), (35.0, -120.0), (89.0, 0.0)])
def test_report_of_an_inclined_fault(dip, rotate):
    off = np.zeros((6, 4, 4), bool)
    off[3, 0, 1] = True                                   # one hanging-wall cell on the fault inactive
    mesh, info = process_grid(inclined_fault_grid(dip, rotate, off), nonplanar="keep")
    r = fault_report(mesh, info)["F"]
    assert r["dip_deg"] == pytest.approx(dip, abs=1e-9)
    az = (90.0 - rotate) % 360.0                           # +x is east; anticlockwise turns it north
    assert r["dip_azimuth_deg"] == pytest.approx(az, abs=1e-9)
    assert r["strike_deg"] == pytest.approx((az - 90.0) % 360.0, abs=1e-9)
    # the columns overlap over 25 m of depth (40 m stack, 15 m throw) on the 400 m long line,
    # less the inactive cell's 10 m; along the plane a depth d is d / sin(dip)
    assert r["area_m2"] == pytest.approx(400.0 * 25.0 / np.sin(np.radians(dip)) - 100.0 * 10.0 / np.sin(np.radians(dip)),
                                         rel=1e-12)
    # layers 1..3 of the footwall (west) and 0..2 of the hanging wall (east, above the plane)
    assert r["cells"] == {"hanging_wall": 4 * 3 - 1, "footwall": 4 * 3}
    assert r["faces"] == info.faults["F"].size and r["planarity"] == pytest.approx(1.0, abs=1e-12)
    lines = fault_table(fault_report(mesh, info), {"F": "F1"})
    assert len(lines) == 2 and lines[1].split()[:4] == ["F", "F1", str(r["faces"]), "11/12"]


def test_report_does_not_depend_on_face_options():
    g = inclined_fault_grid(50.0, 10.0)
    reps = [fault_report(*process_grid(g, nonplanar=o)) for o in ("keep", "centre", "diagonal")]
    for rep in reps[1:]:
        for k in ("area_m2", "dip_deg", "dip_azimuth_deg", "strike_deg"):
            assert rep["F"][k] == pytest.approx(reps[0]["F"][k], rel=1e-12)
        assert rep["F"]["cells"] == reps[0]["F"]["cells"]
