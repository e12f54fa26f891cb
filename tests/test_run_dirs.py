"""Run directories (issue 14): a finished run leaves a complete result; a failure, SIGINT or
SIGTERM leaves only failed.json with the reason; --force starts from a clean folder and never
wipes a folder that is not a polypore result; staging folders of killed runs are removed."""

import json
import os
import signal
import socket
import subprocess
import sys
import time
import tomllib

import pytest
from conftest import STATIC_2D

# the conftest case on 8 × 8 cells, sheared so that the fracture slips
TINY = (STATIC_2D.replace('name = "t"', 'name = "tiny"').replace("cells = [4, 4]", "cells = [8, 8]")
        .replace("u = [0.0, -0.001]", 'u = ["0.01", "-0.001"]')
        .replace("friction = 0.5", 'law = "coulomb"\nfriction = 0.1'))


@pytest.fixture
def tiny(tmp_path):
    """A static contact case that runs in about a second (two Newton iterations, slip)."""
    case = tmp_path / "tiny.toml"
    case.write_text(TINY)
    return case


def _old_result(out):
    """A previous run's complete result, as far as anyone looking at the folder can tell."""
    out.mkdir()
    (out / "summary.json").write_text("{}")
    (out / "case.toml").write_text('name = "old"\n')
    (out / "bulk_0000.vtu").write_text("old")


def _start(case, out, *extra):
    # SIGINT reset to its default: a test runner may ignore it, and the child inherits that
    return subprocess.Popen([sys.executable, "-m", "polypore", "-q", "run", str(case), "--out", str(out), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for_stage(proc, parent, timeout=60.0):
    """Poll until the run's hidden staging folder exists next to its output folder."""
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        stages = list(parent.glob(".partial-*"))
        if stages:
            return stages
        if proc.poll() is not None:
            break
        time.sleep(0.005)
    proc.kill()
    out, err = proc.communicate()
    pytest.fail(f"no staging folder appeared in {parent} (exit {proc.returncode}): {err[-2000:]}")


@pytest.mark.parametrize("sig,status,reason", [
    (signal.SIGTERM, 143, "terminated by SIGTERM"),
    (signal.SIGINT, 130, "interrupted by the user (SIGINT)"),
])
def test_signal_leaves_only_failed_json(tmp_path, tiny, sig, status, reason):
    out = tmp_path / "out"
    _old_result(out)
    proc = _start(tiny, out, "--force")
    _wait_for_stage(proc, tmp_path)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == status, err
    assert "Traceback" not in err
    assert err.strip().splitlines() == [f"polypore: {reason}; wrote {out / 'failed.json'}"]
    assert sorted(p.name for p in out.iterdir()) == ["failed.json"]
    failed = json.loads((out / "failed.json").read_text())
    assert failed["error"] == reason and failed["signal"] == sig.name
    assert not list(tmp_path.glob(".partial-*"))


def test_stage_of_killed_run_is_removed_by_the_next_run(tmp_path, tiny, cli):
    proc = _start(tiny, tmp_path / "killed")
    stage, = _wait_for_stage(proc, tmp_path)
    proc.kill()                                  # SIGKILL: no handler runs, the stage stays behind
    proc.wait()
    assert stage.is_dir()
    # staging folders of a live process and of another host (a shared file system) are kept
    live = tmp_path / f".partial-busy@{socket.gethostname()}.{os.getppid()}.0123456789ab"
    other = tmp_path / f".partial-busy@elsewhere.example.{proc.pid}.0123456789ab"
    live.mkdir()
    other.mkdir()
    code, _, err = cli("mesh", str(tiny), "--out", str(tmp_path / "next"))
    assert code == 0, err
    assert not stage.exists()
    assert live.is_dir() and other.is_dir()


def test_failed_force_rerun_leaves_only_failed_json(tmp_path, tiny, cli):
    out = tmp_path / "out"
    code, _, err = cli("run", str(tiny), "--out", str(out))
    assert code == 0, err
    assert (out / "summary.json").exists()
    code, _, err = cli("run", str(tiny), "--out", str(out), "--force", "--set", "solver.max_iterations=1")
    assert code == 1 and "did not converge" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["failed.json"]
    assert "did not converge" in json.loads((out / "failed.json").read_text())["error"]
    # a folder holding only a failed run's failed.json takes a new result without --force
    code, _, err = cli("mesh", str(tiny), "--out", str(out))
    assert code == 0, err
    assert (out / "mesh.json").exists() and not (out / "failed.json").exists()
    assert not list(tmp_path.glob(".partial-*")) and not list(out.glob(".partial-*"))


def test_input_error_during_run_replaces_the_old_result(tmp_path, tiny, cli):
    out = tmp_path / "out"
    _old_result(out)
    code, _, err = cli("run", str(tiny), "--out", str(out), "--force",
                       "--set", 'mechanics.boundary.ymax.u=[0.0, "0.005/x"]')
    assert code == 2 and "mechanics.boundary.ymax.u[1]" in err and "(x, y) = (0, 1)" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["failed.json"]
    failed = json.loads((out / "failed.json").read_text())
    assert failed["field"] == "mechanics.boundary.ymax.u[1]" and "not finite" in failed["error"]


def test_force_into_another_result_leaves_no_foreign_files(tmp_path, tiny, cli):
    out = tmp_path / "out"
    code, _, err = cli("mesh", str(tiny), "--out", str(out))
    assert code == 0, err
    (out / "notes.txt").write_text("kept by nobody: --force starts from a clean folder")
    code, _, err = cli("run", str(tiny), "--out", str(out), "--set", "mesh.cells=[4, 4]")
    assert code == 2 and "not empty" in err and "--force" in err
    code, _, err = cli("run", str(tiny), "--out", str(out), "--force", "--set", "mesh.cells=[4, 4]")
    assert code == 0, err
    names = {p.name for p in out.iterdir()}
    assert "summary.json" in names and "case.toml" in names
    assert not names & {"mesh.json", "mesh.vtu", "fractures.vtu", "notes.txt"}, names
    assert tomllib.loads((out / "case.toml").read_text())["mesh"]["cells"] == [4, 4]


def test_force_refuses_a_folder_that_is_not_a_result(tmp_path, tiny, cli):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("precious")
    code, _, err = cli("run", str(tiny), "--out", str(mine), "--force")
    assert code == 2 and "--out" in err and "not hold a polypore result" in err, err
    assert sorted(p.name for p in mine.iterdir()) == ["thesis.tex"]
    assert not list(tmp_path.glob(".partial-*"))
    (tmp_path / "file").write_text("x")
    code, _, err = cli("run", str(tiny), "--out", str(tmp_path / "file"))
    assert code == 2 and "not a directory" in err
    # a case file named case.toml makes its folder look like a result: --force must not delete it
    proj = tmp_path / "proj"
    proj.mkdir()
    (proj / "case.toml").write_text(tiny.read_text())
    code, _, err = cli("run", str(proj / "case.toml"), "--out", str(proj), "--force")
    assert code == 2 and "holds the case file" in err, err
    assert (proj / "case.toml").read_text() == tiny.read_text()


@pytest.mark.parametrize("where", ["remove_stale_stages", "_host"])
def test_interrupt_while_the_stage_is_being_made_leaves_failed_json(tmp_path, monkeypatch, where):
    """A signal that lands while run_directory claims its stage (before the run starts) still
    ends with failed.json in place of the old result and no stage left behind."""
    from polypore.io import atomic

    out = tmp_path / "res"
    _old_result(out)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic, where, interrupted)
    with pytest.raises(KeyboardInterrupt):
        with atomic.run_directory(out, force=True):
            pass
    assert sorted(p.name for p in out.iterdir()) == ["failed.json"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(atomic.STAGE_PREFIX)]
