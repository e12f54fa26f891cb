"""``polypore run``: pick the run driver of a case's model."""

from __future__ import annotations

from pathlib import Path

from ..setup.casefile import CaseFile, case_model
from .coupled import run_poromechanics
from .flow import run_flow
from .static import run_static


def run_case(case: CaseFile, out: Path) -> dict:
    """Run ``case`` with the driver of its model and write its files into ``out``; return
    summary.json's content."""
    model = case_model(case)
    if model == "flow":
        return run_flow(case, out)
    if model == "poromechanics":
        return run_poromechanics(case, out)
    return run_static(case, out)
