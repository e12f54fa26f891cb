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
