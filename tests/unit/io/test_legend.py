"""Issue 25: every output name is described (docs/outputs.md, summary.json's legend, README.txt in
the run folder), the contact-state codes included."""

import json
import re

import pytest

from conftest import STATIC_2D
from polypore.io.legend import BULK, CSV, FRACTURES, STATES, describe_error

FLOW = """
name = "f"
model = "flow"
[mesh]
generator = "cartesian"
lower = [0.0, 0.0]
upper = [1.0, 1.0]
cells = [4, 4]
[[fractures]]
name = "F"
vertices = [[0.25, 0.5], [0.75, 0.5]]
[flow]
permeability = 1e-12
[[flow.boundary]]
name = "xmin"
pressure = 1e5
"""


def _cell_arrays(path):
    text = path.read_text(errors="replace")
    section = text[text.index("<CellData"):text.index("</CellData>")]
    return re.findall(r'<DataArray[^>]*Name="([^"]+)"', section)


@pytest.mark.parametrize("command,text", [
    (["run", "CASE"], STATIC_2D),
    (["run", "CASE"], FLOW),
    (["run", "dfm-2d", "--set", "time.end=40", "--set", "time.output_times=[40.0]", "--set", "mesh.size=0.2"], None),
])
def test_every_array_of_a_run_is_in_its_legend(tmp_path, cli, command, text):
    if text is not None:
        (tmp_path / "c.toml").write_text(text)
        command = [str(tmp_path / "c.toml") if a == "CASE" else a for a in command]
    out = tmp_path / "o"
    code, _, err = cli(*command, "--out", str(out))
    assert code == 0, err
    legend = json.loads((out / "summary.json").read_text())["legend"]
    assert legend["state"]["0"] == "open" and legend["state"]["1"] == "stick" and legend["state"]["2"] == "slip"
    for vtu, key in (("bulk_0000.vtu", "bulk_vtu"), ("fractures_0000.vtu", "fractures_vtu")):
        names = _cell_arrays(out / vtu)
        assert names and set(names) <= set(legend[key]), (vtu, set(names) - set(legend[key]))
        assert all(legend[key][n] for n in names)
    header = (out / "fractures.csv").read_text().splitlines()[0].split(",")
    assert set(header) == set(legend["fractures_csv"])
    readme = (out / "README.txt").read_text()
    assert "0 = open, 1 = stick, 2 = slip" in readme
    assert ("state: contact state code" in readme) == ("state" in legend["fractures_vtu"])


# the error measures the cases report (cases/exact.py, flow_exact.py, reference.py, penny_exact.py)
ERRORS = ["grad_u_L2", "grad_u_L2_rel", "lambda_L2", "lambda_h12", "slip_L2_rel", "lambda_n_L2_rel",
          "lambda_n_L2_rel_away_from_tips", "lambda_n_h12", "traction_n_L2_rel", "p_cell_L2", "p_fracture_L2",
          "p_trace_L2", "grad_p_L2", "max_slip", "max_slip_error_rel", "slip_L2_rel_inner",
          "slip_vector_L2_rel_inner", "lambda_n_L2_rel_inner", "open_faces", "faces", "faces_away_from_rim",
          "faces_open", "faces_stick", "faces_slip", "faces_wrong_state", "jump_L2_rel", "exact_opening_max",
          "opening_L2_rel", "opening_L2_rel_away_from_rim", "opening_mean_rel", "opening_centre_rel",
          "exact_slip_max", "slip_L2_rel_away_from_rim", "slip_mean_rel", "slip_centre_rel",
          "slip_direction_deg_mean", "slip_direction_deg_max_away_from_rim", "exact_lambda_n",
          "lambda_n_L2_rel_away_from_rim", "lambda_n_mean_rel", "lambda_n_max_over_load"]


def test_every_error_measure_is_described():
    assert describe_error("lambda_n_h12").startswith("h^½-weighted discrete L2 norm")
    assert "normal contact traction" in describe_error("lambda_n_h12")
    assert "relative" in describe_error("slip_L2_rel_away_from_rim") and "rim" in describe_error(
        "slip_L2_rel_away_from_rim")
    assert describe_error("no_such_measure") == ""
    assert [n for n in ERRORS if not describe_error(n)] == []


def test_docs_outputs_lists_every_name():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[3] / "docs" / "outputs.md").read_text()
    for name in [*BULK, *FRACTURES, *CSV, *ERRORS]:
        assert f"`{name}`" in doc, name
    assert all(f"{k} {v}" in doc for k, v in STATES.items())
