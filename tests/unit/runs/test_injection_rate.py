"""The injected volume rate of a poromechanics model (Poromechanics.injection_rate), the ΔV of
McGarr's bound in seismicity.csv: the case's mass rate through a boundary part over the fluid
density, sources included, pressure boundaries left out."""

import pytest

from polypore.runs.coupled import set_up
from polypore.setup.casefile import load_case


@pytest.mark.parametrize("rate", [0.02, 0.05])
def test_injection_rate_of_a_mass_rate_boundary(rate):
    case = load_case("fault-injection", overrides=["mesh.size=400", f"parameters.mass_rate={rate}"])
    run, _, _ = set_up(case)
    # kg/s per metre / 1000 kg/m³; the drained top (a pressure boundary) is not injection
    assert run.model.injection_rate(43200.0) == pytest.approx(rate / 1000.0, rel=1e-12)


@pytest.mark.parametrize("key", ["matrix_pressure", "fracture_pressure"])
def test_a_prescribed_pressure_in_a_coupled_run_names_its_key(key):
    """The coupled model computes the pressures; a mechanics pressure given anyway is refused under
    the case key the user wrote (it was reported as a non-existent mechanics.pressure)."""
    from polypore.core.errors import InputError
    from polypore.setup.translate import RUN_POROMECHANICS, case_keys

    case = load_case("fault-injection", overrides=["mesh.size=400", f"mechanics.{key}=1e6"])
    with pytest.raises(InputError) as err, case_keys(RUN_POROMECHANICS):
        set_up(case)
    assert str(err.value).startswith(f"mechanics.{key}:")
