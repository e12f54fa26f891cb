"""Per-fault (per-fracture) contact and flow data in ``[[fractures]]`` (issue 15): friction,
threshold, aperture, normal permeability and conductivity replace the ``[contact]`` / ``[flow]``
values on the faces of that fault; faults not named keep the global ones."""

import numpy as np
import pytest
from conftest import CORNERPOINT_MESH, case

from polypore.core.errors import InputError
from polypore.setup.flow import flow_setup
from polypore.setup.mechanics import mechanics_setup
from polypore.setup.meshing import build_fractured_mesh

GRID = CORNERPOINT_MESH + """[[mesh.faults]]
name = "F3"
axis = "j"
index = 2
throw = 5.0
"""
REST = """
[material]
E = 1.0e10
nu = 0.25
[[mechanics.boundary]]
name = "bottom"
u = [0, 0, 0]
[flow]
permeability = 1.0e-14
porosity = 0.2
fluid_compressibility = 4.4e-10
aperture = 1.0e-4
normal_permeability = 1.0e-15
initial_pressure = 0.0
[[flow.boundary]]
name = "west"
pressure = 0.0
[time]
end = 10.0
step = 10.0
"""


FAULTS = """
[[fractures]]
name = "F1"
friction = "0.3 + 0*D"
aperture = 2.0e-4
normal_permeability = 3.0e-15
fracture_conductivity = "2*d**3"
[[fractures]]
name = "B"
fault = "F2"
friction = 0.9
[[fractures]]
name = "F3"
[contact]
friction = 0.6
"""


def test_per_fault_friction_aperture_and_flow_data(tmp_path):
    c = case(tmp_path, GRID + FAULTS + REST)
    fm = build_fractured_mesh(c)
    net = fm.network
    assert net.names == ("F1", "B", "F3")
    on = {name: net.fracture == j for j, name in enumerate(net.names)}
    assert all(v.any() for v in on.values())
    F = mechanics_setup(c, fm).data.contact.friction
    assert np.all(F[on["F1"]] == 0.3) and np.all(F[on["B"]] == 0.9) and np.all(F[on["F3"]] == 0.6)
    fs = flow_setup(c, fm)
    xf = fm.mesh.geometry.face_centroid[net.faces]
    ap = fs.data.aperture(*xf.T, 0.0)
    assert np.all(ap[on["F1"]] == 2e-4) and np.all(ap[~on["F1"]] == 1e-4)
    kfn = fs.data.normal_permeability
    assert np.all(kfn[on["F1"]] == 3e-15) and np.all(kfn[~on["F1"]] == 1e-15)
    cond = fs.data.conductivity_law(ap)
    assert np.allclose(cond[on["F1"]], 2 * 2e-4 ** 3) and np.allclose(cond[~on["F1"]], 1e-4 ** 3 / 12)


def test_every_fault_with_its_own_friction_needs_no_contact_friction(tmp_path):
    text = GRID + '[[fractures]]\nname = "F1"\nfriction = 0.4\n[[fractures]]\nname = "F2"\nfriction = 0.5\n' + REST
    c = case(tmp_path, text)
    F = mechanics_setup(c, build_fractured_mesh(c)).data.contact.friction
    assert set(np.unique(F)) == {0.4, 0.5}
    # one fault without: contact.friction is required, and the message names that fault
    c = case(tmp_path, text + '[[fractures]]\nname = "F3"\n', name="d.toml")
    with pytest.raises(InputError) as e:
        mechanics_setup(c, build_fractured_mesh(c))
    assert e.value.field == "contact.friction" and "F3" in str(e.value)


@pytest.mark.parametrize("extra,sets,field,words", [
    ('[[fractures]]\nname = "F1"\nfriction = -0.1\n[contact]\nfriction = 0.5\n', (), "fractures.F1.friction",
     ["≥ 0"]),
    ('[[fractures]]\nname = "F1"\naperture = "x - 1e9"\n[contact]\nfriction = 0.5\n', (), "fractures.F1.aperture",
     ["positive", "fracture F1"]),
    ('[[fractures]]\nname = "F1"\nnormal_permeability = "t + 1e-15"\n[contact]\nfriction = 0.5\n', (),
     "fractures.F1.normal_permeability", ["may not depend on t"]),
    ('[[fractures]]\nname = "F1"\nfriction = "q"\n[contact]\nfriction = 0.5\n', (), "fractures.F1.friction",
     ["q"]),
])
def test_bad_per_fault_values_name_the_fracture_field(tmp_path, extra, sets, field, words):
    c = case(tmp_path, GRID + extra + REST, *sets)
    fm = build_fractured_mesh(c)
    with pytest.raises(InputError) as e:
        mechanics_setup(c, fm)
        flow_setup(c, fm)
    assert e.value.field == field, (e.value.field, str(e.value))
    assert all(w in str(e.value) for w in words), str(e.value)


@pytest.mark.parametrize("text,field,words", [
    (GRID + '[[fractures]]\nname = "F1"\nfriction = 0.4\n[contact]\nlaw = "tresca"\nthreshold = 1e6\n' + REST,
     "fractures.F1.friction", ["'coulomb'", "'tresca'"]),
    (GRID + '[[fractures]]\nname = "F1"\nthreshold = 1e6\n' + REST, "fractures.F1.threshold", ["'tresca'"]),
    (GRID + '[[fractures]]\nname = "F1"\naperture = 1e-4\n[material]\nE = 1e10\nnu = 0.25\n',
     "fractures.F1.aperture", ["mechanics case"]),
    (GRID + '[[fractures]]\nname = "F1"\nfriction = 0.5\n[flow]\npermeability = 1e-14\n[[flow.boundary]]\n'
     'name = "west"\npressure = 0.0\n', "fractures.F1.friction", ["flow case"]),
])
def test_schema_checks_per_fault_data_against_the_case(tmp_path, text, field, words):
    with pytest.raises(InputError) as e:
        case(tmp_path, text)
    assert e.value.field == field, (e.value.field, str(e.value))
    assert all(w in str(e.value) for w in words), str(e.value)


def test_per_fracture_data_on_a_generated_mesh_too(tmp_path):
    text = """
[mesh]
generator = "cartesian"
lower = [0, 0, 0]
upper = [1, 1, 1]
cells = [2, 2, 2]
[[fractures]]
name = "a"
vertices = [[0.5, 0, 0], [0.5, 1, 0], [0.5, 1, 1], [0.5, 0, 1]]
friction = 0.2
[material]
E = 1.0e10
nu = 0.25
[[mechanics.boundary]]
name = "xmin"
u = [0, 0, 0]
"""
    c = case(tmp_path, text)
    F = mechanics_setup(c, build_fractured_mesh(c)).data.contact.friction
    assert F.size == 4 and np.all(F == 0.2)


def test_slip_weakening_coefficients_per_fault(tmp_path):
    """slip-weakening reads friction, dynamic_friction and critical_slip from [contact] or a fault's
    own block; a missing one names the key and the faults, and a dynamic friction above the static
    one is refused when the law is built."""
    sw = '[contact]\nlaw = "slip-weakening"\nfriction = 0.6\ndynamic_friction = 0.4\ncritical_slip = 1e-3\n'
    text = GRID + '[[fractures]]\nname = "F1"\ndynamic_friction = 0.2\n[[fractures]]\nname = "F2"\n' + \
        REST.replace("[contact]\nfriction = 0.6\n", "") + sw
    c = case(tmp_path, text)
    fm = build_fractured_mesh(c)
    spec = mechanics_setup(c, fm).data.contact
    on = fm.network.fracture == fm.network.names.index("F1")
    co = spec.coefficients
    assert spec.law == "slip-weakening" and np.all(spec.friction == 0.6) and np.all(co["critical_slip"] == 1e-3)
    assert np.all(co["dynamic_friction"][on] == 0.2) and np.all(co["dynamic_friction"][~on] == 0.4)
    c = case(tmp_path, text.replace("critical_slip = 1e-3\n", ""), name="d.toml")
    with pytest.raises(InputError) as e:
        mechanics_setup(c, build_fractured_mesh(c))
    assert e.value.field == "contact.critical_slip" and "slip-weakening" in str(e.value)
    c = case(tmp_path, text.replace("dynamic_friction = 0.4", "dynamic_friction = 0.7"), name="e.toml")
    fm = build_fractured_mesh(c)
    with pytest.raises(InputError) as e:
        mechanics_setup(c, fm).problem(fm)
    assert e.value.field == "contact.dynamic_friction" and "must not exceed the static friction" in str(e.value)
