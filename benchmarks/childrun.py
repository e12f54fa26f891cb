"""One ``polypore run`` in a child process, for the benchmark studies (defaults_study.py, penny_study.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class ChildRun:
    """The finished child: its process result, output folder (valid inside the ``with``), wall
    seconds and the 1-minute load average at its start and end."""

    proc: subprocess.CompletedProcess
    out: Path
    seconds: float
    load_average: tuple[float, float]


@contextmanager
def polypore_run(case: str, overrides) -> ChildRun:
    """``python -m polypore -q run CASE --set ...`` into a temporary folder, removed on exit."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "polypore", "-q", "run", case, "--out", str(out), "--force"]
        for ov in overrides:
            cmd += ["--set", ov]
        load0 = os.getloadavg()[0]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        yield ChildRun(proc, out, wall, (load0, os.getloadavg()[0]))
