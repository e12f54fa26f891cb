"""Input fuzz (issue 25), CI tier: a small derandomised sample of each family of tests/inputfuzz.py
(GRDECL and Gmsh files, the TOML text of case files, file-system faults through the command line),
each with its expected verdict and the 60 s hang detector: no traceback, no hang, no silent
acceptance of a broken input, no false refusal of a valid one, and every message names a field
without quoting the file. benchmarks/fuzz_inputs.py runs 10,000 (docs/fuzz.md)."""

import pytest
from hypothesis import HealthCheck, Phase, given, settings

import inputfuzz


@pytest.mark.parametrize("family,n,kw", [("grdecl", 200, {}), ("msh", 100, {}), ("toml", 60, {"quick": True}),
                                         ("fs", 60, {})])
def test_inputs_are_refused_cleanly_or_accepted(family, n, kw):
    @settings(max_examples=n, derandomize=True, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(inputfuzz.STRATEGIES[family](**kw))
    def run(ex):
        v = inputfuzz.run_example(ex)
        assert not v.problems, (ex.what, ex.expect, v.outcome, v.problems, v.detail)

    run()


def test_hang_detector_stops_a_blocked_read(tmp_path):
    """The detector itself: a read of a FIFO nobody writes to is stopped (here after 1 s)."""
    import os

    os.mkfifo(tmp_path / "p")
    with pytest.raises(inputfuzz.Hang):
        with inputfuzz.guard(1.0):
            (tmp_path / "p").read_bytes()
