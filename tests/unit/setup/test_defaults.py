"""Issue 25, "Defaults below the method's best": mechanics.order = "auto" (the default) picks the
quadratic space on 3D meshes of tetrahedra with fractures and the nodal + bubble space elsewhere,
and every run says which discretisation it used and why (summary.json "choices", the log)."""

import json

import pytest

from conftest import STATIC_2D
from polypore.core.errors import InputError
from polypore.setup.casefile import load_case
from polypore.setup.mechanics import describe_choices, mechanics_setup, resolve_order
from polypore.setup.meshing import build_fractured_mesh

BOX_3D = """
name = "t3"
[mesh]
generator = "{generator}"
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
{sizes}
{fractures}
[material]
E = 1e9
nu = 0.25
[[mechanics.boundary]]
name = "zmin"
u = [0.0, 0.0, 0.0]
[[mechanics.boundary]]
name = "zmax"
u = [0.0001, 0.0, -0.0001]
[contact]
friction = 0.5
"""
FRACTURE = """[[fractures]]
name = "F"
vertices = [[0.25, 0.25, 0.5], [0.75, 0.25, 0.5], [0.75, 0.75, 0.5], [0.25, 0.75, 0.5]]"""


def _case(tmp_path, text, overrides=()):
    path = tmp_path / "c.toml"
    path.write_text(text)
    return load_case(str(path), list(overrides))


def _tets(fractures=True):
    return BOX_3D.format(generator="simplicial", sizes="size = 0.5", fractures=FRACTURE if fractures else "")


@pytest.fixture
def with_pardiso(monkeypatch):
    """The auto rule as on an install with PARDISO (order 2 is taken with PARDISO only)."""
    import polypore.solvers.linear as linear

    monkeypatch.setattr(linear, "have_pardiso", lambda: True)


def test_auto_order_is_1_without_pardiso(tmp_path, monkeypatch):
    """Without PARDISO (the default install: SciPy's SuperLU), or with another solver.linear,
    "auto" keeps order 1 on tetrahedra and says why: a quadratic 3D factorisation with SuperLU took
    minutes per Newton iteration."""
    import polypore.solvers.linear as linear

    monkeypatch.setattr(linear, "have_pardiso", lambda: False)
    case = _case(tmp_path, _tets())
    order, why = resolve_order("auto", build_fractured_mesh(case), case.spec.model, "auto")
    assert order == 1 and "no PARDISO" in why and "polypore[fast]" in why
    monkeypatch.setattr(linear, "have_pardiso", lambda: True)
    assert resolve_order("auto", build_fractured_mesh(case), None, "block-amg") == (
        1, "auto: 3D tetrahedra with fractures, but solver.linear = 'block-amg' (order 2 is taken with PARDISO)")
    assert resolve_order("auto", build_fractured_mesh(case), None, "pardiso")[0] == 2


@pytest.mark.parametrize("text,order,reason", [
    (_tets(), 2, "auto: 3D mesh of tetrahedra with fractures"),
    (_tets(fractures=False), 1, "auto: no fractures"),
    (BOX_3D.format(generator="cartesian", sizes="cells = [4, 4, 4]", fractures=FRACTURE), 1,
     "auto: polytopal mesh (P2 needs tetrahedra)"),
    (STATIC_2D, 1, "auto: 2D mesh"),
])
def test_auto_order_picks_each_value(tmp_path, with_pardiso, text, order, reason):
    case = _case(tmp_path, text)
    assert case.spec.mechanics is None or case.spec.mechanics.order == "auto"
    fm = build_fractured_mesh(case)
    assert resolve_order("auto", fm, case.spec.model) == (order, reason)
    setup = mechanics_setup(case, fm)
    assert setup.data.order == order
    assert setup.choices["order"] == order and setup.choices["order_source"] == reason


def test_a_given_order_is_kept(tmp_path):
    for given in (1, 2):
        case = _case(tmp_path, _tets(), [f"mechanics.order={given}"])
        setup = mechanics_setup(case, build_fractured_mesh(case))
        assert setup.data.order == given and setup.choices["order_source"] == "given"
    # anything else is refused, naming the allowed values
    with pytest.raises(InputError, match=r"^mechanics.order: expected 1 .*, 2 .* or \"auto\", got 3"):
        load_case("cube-slip-3d", ["mechanics.order=3"])
    with pytest.raises(InputError, match=r"^mechanics.order: expected 1, 2 or \"auto\", got 'quadratic'"):
        load_case("cube-slip-3d", ["mechanics.order=quadratic"])


def test_the_built_in_cases_that_set_the_order_keep_it():
    # cube-slip-3d's anisotropic fronts were tuned for P2 (docs/cube_slip_anisotropic.md)
    assert load_case("cube-slip-3d").spec.mechanics.order == 2


def test_the_summary_and_the_log_report_the_choices(tmp_path, cli, caplog, monkeypatch):
    import polypore.solvers.linear as linear_solvers

    # the order rule as with PARDISO; this tiny system is solved by whatever is installed
    monkeypatch.setattr(linear_solvers, "pardiso_solves", lambda linear: True)
    (tmp_path / "c.toml").write_text(_tets())
    out = tmp_path / "o"
    with caplog.at_level("INFO", logger="polypore"):
        code, _, err = cli("run", str(tmp_path / "c.toml"), "--out", str(out))
    assert code == 0, err
    c = json.loads((out / "summary.json").read_text())["choices"]
    assert c == {"order": 2, "order_source": "auto: 3D mesh of tetrahedra with fractures",
                 "bubbles": "one-sided", "bubbles_source": "default", "mirror": "none", "mirror_source": "default",
                 "front": "isotropic", "front_source": "default"}
    line = ("discretisation: order 2 (auto: 3D mesh of tetrahedra with fractures), one-sided bubbles (default), "
            "isotropic crack-front cells (default), mirror none (default)")
    assert describe_choices(c) == line[len("discretisation: "):]
    assert line in caplog.text or line in err
    # given values are reported as given
    code, _, err = cli("run", str(tmp_path / "c.toml"), "--out", str(out), "--force", "--set", "mechanics.order=1",
                       "--set", "mechanics.bubbles=two-sided")
    assert code == 0, err
    c = json.loads((out / "summary.json").read_text())["choices"]
    assert (c["order"], c["order_source"], c["bubbles"], c["bubbles_source"]) == (1, "given", "two-sided", "given")


def test_the_resource_guard_foresees_the_quadratic_space(tmp_path, with_pardiso):
    from polypore.setup.limits import estimate

    auto = estimate(_case(tmp_path, _tets()).spec)
    p1 = estimate(_case(tmp_path, _tets(), ["mechanics.order=1"]).spec)
    assert auto.cells == p1.cells and auto.unknowns > 3 * p1.unknowns and auto.memory > p1.memory
    # no fractures: "auto" is order 1, the estimate that of order 1
    assert estimate(_case(tmp_path, _tets(fractures=False)).spec).unknowns == pytest.approx(
        estimate(_case(tmp_path, _tets(fractures=False), ["mechanics.order=1"]).spec).unknowns)


def test_nodal_stabilisation_auto_is_thickness_on_corner_point_grids_only():
    """mechanics.nodal_stabilisation = "auto": the thickness weight on corner-point grids (flat
    cells), the scheme's diameter weight elsewhere; a given value is kept."""
    from polypore.setup.mechanics import resolve_nodal_stabilisation

    assert resolve_nodal_stabilisation("auto", "grdecl")[0] == "thickness"
    assert resolve_nodal_stabilisation("auto", "cornerpoint")[0] == "thickness"
    for gen in ("simplicial", "voronoi", "cartesian", "file"):
        assert resolve_nodal_stabilisation("auto", gen)[0] == "diameter"
    assert resolve_nodal_stabilisation("diameter", "grdecl") == ("diameter", "given")


def test_stabilisation_auto_is_reduced_on_corner_point_grids_only(tmp_path):
    """mechanics.stabilisation = "auto": 0.3 on corner-point grids, the scheme's 1 elsewhere; a given
    number is kept; the run says which (log line and summary.json choices); bad values are refused
    naming the key."""
    from polypore.core.errors import InputError
    from polypore.setup.casefile import load_case
    from polypore.setup.mechanics import STAB_CORNERPOINT, mechanics_setup, resolve_stabilisation
    from polypore.setup.meshing import build_fractured_mesh

    assert resolve_stabilisation("auto", "grdecl") == (STAB_CORNERPOINT, "auto: corner-point grid")
    assert resolve_stabilisation("auto", "cornerpoint")[0] == 0.3
    for gen in ("simplicial", "voronoi", "cartesian", "file"):
        assert resolve_stabilisation("auto", gen)[0] == 1.0
    assert resolve_stabilisation(2.0, "grdecl") == (2.0, "given")
    case = load_case("cornerpoint-injection", ["mesh.cells=[20, 10, 2]"])
    ms = mechanics_setup(case, build_fractured_mesh(case))
    assert ms.data.stabilisation == 0.3 and ms.choices["stabilisation"] == 0.3
    for bad in ("0", "-1", '"huge"'):
        with pytest.raises(InputError) as e:
            load_case("cornerpoint-injection", [f"mechanics.stabilisation={bad}"])
        assert e.value.field == "mechanics.stabilisation"


def test_auto_linear_solver_by_size_and_install():
    """solver.linear = "auto" on coupled systems (setup/poromechanics.resolve_linear): direct up
    to the measured sizes, then block-direct (PARDISO) or block-amg (default install); 2D and P2
    stay direct; a given backend is kept."""
    from types import SimpleNamespace

    from polypore.setup.poromechanics import BLOCK_DIRECT_MIN, SUPERLU_MAX, resolve_linear

    def fm(n, dim=3):          # d × nodes + cells + faces = n (nodes only)
        return SimpleNamespace(mesh=SimpleNamespace(dim=dim, n_nodes=n // dim, n_cells=0, n_faces=0))

    assert resolve_linear("auto", fm(BLOCK_DIRECT_MIN - 3), 1, True)[0] == "pardiso"
    assert resolve_linear("auto", fm(BLOCK_DIRECT_MIN + 3), 1, True)[0] == "block-direct"
    assert resolve_linear("auto", fm(SUPERLU_MAX), 1, False)[0] == "superlu"
    choice, why = resolve_linear("auto", fm(60_000), 1, False)
    assert choice == "block-amg" and "60,000" in why and "polypore[fast]" in why
    assert resolve_linear("auto", fm(10**6), 2, True)[0] == "pardiso"        # P2: direct
    assert resolve_linear("auto", fm(10**6, dim=2), 1, False)[0] == "superlu"
    assert resolve_linear("superlu", fm(10**6), 1, True) == ("superlu", "given")


def test_auto_avoids_block_factors_that_would_not_fit(monkeypatch):
    """With PARDISO "auto" keeps the displacement block's factors while they need at most half of the
    machine's memory and takes AMG beyond, and says so."""
    from types import SimpleNamespace

    import polypore.setup.poromechanics as pm

    fm = SimpleNamespace(mesh=SimpleNamespace(dim=3, n_nodes=50_000, n_cells=0, n_faces=0))   # 150,000
    need = pm.block_direct_bytes(150_000)
    assert 0.8e9 < need < 1.6e9          # 8–10 kB per unknown (measured, setup/poromechanics.py)
    monkeypatch.setattr(pm, "machine_memory", lambda: 2.5 * need)
    assert pm.resolve_linear("auto", fm, 1, True)[0] == "block-direct"
    monkeypatch.setattr(pm, "machine_memory", lambda: 1.5 * need)
    choice, why = pm.resolve_linear("auto", fm, 1, True)
    assert choice == "block-amg" and "would need about" in why and "GB" in why
