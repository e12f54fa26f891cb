"""Issue 14: input that used to be accepted silently or validated late, runs without fractures,
and the outputs a user reads (the one-line summary, point displacement, named stress components)."""

import json

import numpy as np
import pytest

from polypore.core.errors import InputError
from polypore.models.materials import lame
from polypore.models.mechanics import MechanicsData
from polypore.setup.casefile import load_case
from polypore.setup.mechanics import mechanics_setup
from polypore.setup.meshing import build_fractured_mesh

from conftest import STATIC_2D as STATIC  # noqa: E402

# 2D poromechanics without fractures and without a [contact] table
POROUS = """
name = "porous"
model = "poromechanics"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [4, 4]
[material]
E = 1.0e10
nu = 0.2
[mechanics]
biot = 0.5
[[mechanics.boundary]]
name = "ymax"
u = [0.0, "-0.001 * t"]
[[mechanics.boundary]]
name = "ymin"
u = [0.0, 0.0]
[flow]
permeability = 1e-15
viscosity = 1.0e-3
biot_modulus = 1.0e10
initial_pressure = 1.0e5
[[flow.boundary]]
name = "xmin"
pressure = 1.0e5
[time]
end = 2.0
step = 1.0
"""


def _case(tmp_path, text=STATIC, name="t.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _setup(tmp_path, *overrides, text=STATIC):
    case = load_case(str(_case(tmp_path, text)), overrides)
    return mechanics_setup(case, build_fractured_mesh(case))


# -- silently accepted input -----------------------------------------------------------------------
BAD = [
    # (--set overrides on STATIC, fragments the message must hold)
    (["solvr.linear=auto"], ["solvr: unknown top-level table", "did you mean 'solver'", "--set solvr.linear=auto"]),
    (["mechanics.biot=2"], ["mechanics.biot", "[0, 1]", "got 2 (set by --set mechanics.biot=2)"]),
    (["mechanics.biot=-0.5"], ["mechanics.biot", "[0, 1]"]),
    (["name=../escape"], ["name:", "'../escape'", "no '..'"]),
    (["name=a/b"], ["name:", "'a/b'", "no path separator"]),
    (["mechanics.boundary.ymax.traction=[0, -1e6]"],
     ["mechanics.boundary.ymax.traction", "[0.0, -1000000.0]", "conflicts with the displacement condition u"]),
    (["mechanics.boundary.ymax.name=ymin"], ["mechanics.boundary.ymin.name", "'ymin' is given twice"]),
    (["mesh.sise=3"], ["mesh.sise: unknown key", "did you mean 'size'"]),
]


@pytest.mark.parametrize("overrides,fragments", BAD)
def test_bad_input_exit_2(tmp_path, cli, overrides, fragments):
    argv = ["run", str(_case(tmp_path)), "--out", str(tmp_path / "o")]
    for o in overrides:
        argv += ["--set", o]
    code, _, err = cli(*argv)
    assert code == 2, err
    for f in fragments:
        assert f in err, (f, err)
    assert "Traceback" not in err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_unknown_top_level_in_the_file(tmp_path):
    path = _case(tmp_path, STATIC + '[solvr]\nlinear = "auto"\n')
    with pytest.raises(InputError, match=r"^solvr: unknown top-level table .*did you mean 'solver'") as exc:
        load_case(str(path))
    assert "accepted:" in str(exc.value) and "mechanics" in str(exc.value)
    path = _case(tmp_path, 'descripton = "x"\n' + STATIC)
    with pytest.raises(InputError, match="descripton: unknown top-level key .*did you mean 'description'"):
        load_case(str(path))


def test_schema_suggests_a_key(tmp_path):
    with pytest.raises(InputError, match=r"^contact.frction: unknown key \(did you mean 'friction'\?\)"):
        load_case(str(_case(tmp_path)), ["contact.frction=0.5"])


def test_case_names(tmp_path):
    assert load_case(str(_case(tmp_path)), ["name=run-2_b.v1"]).name == "run-2_b.v1"
    path = _case(tmp_path, STATIC.replace('name = "t"\n', ""), name="my case.toml")
    with pytest.raises(InputError, match=r"got 'my case' \(taken from the file name"):
        load_case(str(path))
    for bad in ("..", ".", "x/../../y", "a\\\\b"):
        with pytest.raises(InputError, match="^name: "):
            load_case(str(_case(tmp_path)), [f'name="{bad}"'])


def test_boundary_and_biot_rules_accept_what_is_meaningful(tmp_path):
    # a roller with a traction in its free component, and b = 0 (a decoupled problem)
    setup = _setup(tmp_path, "mechanics.boundary.ymax.u=[0, 0]", "mechanics.biot=0")
    assert setup.data.biot == 0.0
    roller = STATIC.replace('u = [0.0, -0.001]', 'uy = 0.0\ntraction = ["1e6", -1e6]')
    with pytest.raises(InputError, match=r"ymax.traction: .*y component would be ignored"):
        _setup(tmp_path, text=roller)
    setup = _setup(tmp_path, text=roller.replace('traction = ["1e6", -1e6]', 'traction = ["1e6", "0.0"]'))
    assert len(setup.data.traction) == 1 and len(setup.data.displacement) == 2


# -- the Python API validates where data are built -------------------------------------------------
def test_api_materials():
    with pytest.raises(InputError, match=r"^elastic.nu: .*\(−1, 0.5\), got 0.7"):
        lame(25e9, 0.7)
    with pytest.raises(InputError, match=r"^elastic.E: .*positive.*got -1"):
        lame(-1e9, 0.2)
    mu, lam = lame(np.array([1e9, 2e9]), 0.25)
    assert np.all(mu > 0) and np.all(lam > 0)
    n = 3
    with pytest.raises(InputError, match=r"^mu: the shear modulus must be positive.*got -1000000000.0"):
        MechanicsData(mu=np.full(n, -1e9), lam=np.full(n, 1e9))
    with pytest.raises(InputError, match=r"^mu: .*got 0.0"):
        MechanicsData(mu=0.0, lam=1e9)
    with pytest.raises(InputError, match=r"^lam: .*−2μ/3.*got -1000000000.0"):
        MechanicsData(mu=np.full(n, 1e9), lam=np.full(n, -1e9))
    with pytest.raises(InputError, match=r"^biot: .*\[0, 1\], got 2.0"):
        MechanicsData(mu=1e9, lam=1e9, biot=2.0)
    MechanicsData(mu=np.full(n, 1e9), lam=np.full(n, -0.5e9), biot=0.0)   # ν ≈ −0.5: allowed


# -- runs without fractures; what the user reads --------------------------------------------------
def _vtk(path):
    import vtk

    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    r.Update()
    return r.GetOutput()


def _names(arr):
    return [arr.GetComponentName(i) for i in range(arr.GetNumberOfComponents())]


def test_poromechanics_without_fractures(tmp_path, cli):
    """No [contact] table needed, no fracture plots, point displacement and named stresses in
    the VTU, and the summary line counts every Newton iteration."""
    from vtk.util.numpy_support import vtk_to_numpy

    out = tmp_path / "o"
    code, text, err = cli("run", str(_case(tmp_path, POROUS, "porous.toml")), "--out", str(out))
    assert code == 0, err
    assert "Traceback" not in err and "Warning" not in err
    steps = json.loads((out / "summary.json").read_text())["steps"]
    total = sum(s["newton_iterations"] for s in steps)
    assert total != steps[-1]["newton_iterations"]          # the test tells the total from the last
    assert f"{len(steps)} time steps; {total} Newton iterations; at the end residual" in text
    assert (out / "overpressure.png").exists()
    assert not list(out.glob("contact_t*.png")) and not (out / "slip_profiles.png").exists()
    g = _vtk(out / f"bulk_{len(steps):04d}.vtu")
    u = vtk_to_numpy(g.GetPointData().GetArray("displacement"))
    assert u.shape == (25, 3)
    top = vtk_to_numpy(g.GetPoints().GetData())[:, 1] == 1.0
    assert np.allclose(u[top], [0.0, -0.001 * steps[-1]["time"], 0.0])
    for name in ("effective_stress", "total_stress"):
        assert _names(g.GetCellData().GetArray(name)) == ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"]
    assert _vtk(out / "fractures_0000.vtu").GetNumberOfCells() == 0


def test_static_stress_components(tmp_path, cli):
    from vtk.util.numpy_support import vtk_to_numpy

    from polypore.runs.static import solve_static

    out = tmp_path / "o"
    path = _case(tmp_path)
    code, text, err = cli("run", str(path), "--out", str(out))
    assert code == 0, err
    assert "time steps" not in text                         # one static solve
    rows = (out / "fractures.csv").read_text().splitlines()
    col = rows[0].split(",").index("state")
    assert {r.split(",")[col] for r in rows[1:]} <= {"open", "stick", "slip"}
    g = _vtk(out / "bulk_0000.vtu")
    arr = g.GetCellData().GetArray("stress")
    # issue 25: 3 components (xx, yy, xy) were what ParaView takes for a vector; a 3x3 tensor now
    assert _names(arr) == ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"]
    problem, st, *_ = solve_static(load_case(str(path)))
    S = problem.stress(st)
    full = np.zeros((len(S), 3, 3))
    full[:, :2, :2] = 0.5 * (S + S.transpose(0, 2, 1))
    assert np.allclose(vtk_to_numpy(arr), full.reshape(-1, 9), rtol=1e-9, atol=1e-9 * np.abs(S).max())


def test_3d_tensor_is_vtk_symmetric_order(tmp_path):
    from vtk.util.numpy_support import vtk_to_numpy

    from polypore.io.vtu import symmetric_tensor, write_unstructured_vtu

    S = np.array([[[11.0, 12.0, 13.0], [12.0, 22.0, 23.0], [13.0, 23.0, 33.0]]])
    vals, names = symmetric_tensor(S)
    assert names == ("xx", "yy", "zz", "xy", "yz", "xz")
    assert vals.tolist() == [[11.0, 22.0, 33.0, 12.0, 23.0, 13.0]]
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    path = write_unstructured_vtu(tmp_path / "t.vtu", pts, np.arange(4), np.array([4]), np.array([10]),
                                  cell_data={"stress": vals}, component_names={"stress": names})
    arr = _vtk(path).GetCellData().GetArray("stress")
    assert _names(arr) == list(names) and vtk_to_numpy(arr).tolist() == vals.tolist()
    with pytest.raises(ValueError, match="3 names for an array of shape"):
        write_unstructured_vtu(tmp_path / "u.vtu", pts, np.arange(4), np.array([4]), np.array([10]),
                               cell_data={"stress": vals}, component_names={"stress": names[:3]})


@pytest.mark.parametrize("case,override,fragment", [
    # issue 25: a 3D bow-tie (edges crossing) and 2D polylines crossing, touching or folding back
    ("dfm-3d", None, "the polygon intersects itself: the edge from vertex 2 to vertex 3 and the edge from vertex 4 "
     "to vertex 1 (vertices numbered from 1) cross or touch"),
    ("single-crack", "[[0.2, 0.2], [0.8, 0.8], [0.8, 0.2], [0.2, 0.8]]",
     "the polyline intersects itself: the edge from vertex 1 to vertex 2 and the edge from vertex 3 to vertex 4"),
    ("single-crack", "[[0.2, 0.5], [0.8, 0.5], [0.8, 0.7], [0.5, 0.5]]", "cross or touch"),
    ("single-crack", "[[0.2, 0.5], [0.8, 0.5], [0.5, 0.5]]", "fold back onto each other"),
])
def test_self_intersecting_fracture_is_refused_at_input(tmp_path, cli, case, override, fragment):
    spec = load_case(case).spec
    name = spec.fractures[0].name
    if override is None:       # the case's first fracture, its vertices 3 and 4 swapped: a bow-tie
        v = [list(p) for p in spec.fractures[0].vertices]
        assert len(v) == 4
        override = str([v[0], v[1], v[3], v[2]])
    with pytest.raises(InputError) as exc:
        load_case(case, [f"fractures.{name}.vertices={override}"])
    assert exc.value.field == f"fractures.{name}.vertices" and fragment in str(exc.value), str(exc.value)
    code, _, err = cli("mesh", case, "--set", f"fractures.{name}.vertices={override}", "--out", str(tmp_path / "o"))
    assert code == 2 and f"polypore: error: fractures.{name}.vertices: the poly" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()
