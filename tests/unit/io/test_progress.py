"""Progress estimates of long loops: elapsed time and time left, in log lines and on a bar."""

import pytest

from polypore.io.progress import Progress, clock


def test_clock_formats():
    assert clock(42.4) == "42 s"
    assert clock(185) == "3 min 05 s"
    assert clock(2 * 3600 + 7 * 60) == "2 h 07 min"


def test_equal_cost_items_extrapolate_linearly(monkeypatch):
    now = [0.0]
    monkeypatch.setattr("polypore.io.progress.time.perf_counter", lambda: now[0])
    p = Progress(10, "steps", bar=False)
    assert p.remaining() is None and p.text() == "elapsed 0 s"
    for k in range(4):
        now[0] += 3.0
        text = p.advance()
    assert p.remaining() == pytest.approx(18.0)           # 6 steps left at 3 s each
    assert text == "elapsed 12 s, about 18 s left"
    for k in range(6):
        now[0] += 3.0
        text = p.advance()
    assert text == "elapsed 30 s"                        # finished: no estimate left


def test_growing_cost_uses_the_measured_ratio(monkeypatch):
    now = [0.0]
    monkeypatch.setattr("polypore.io.progress.time.perf_counter", lambda: now[0])
    p = Progress(4, "levels", growth=4.0, bar=False)
    p.advance(1.0)
    assert p.remaining() == pytest.approx(4 + 16 + 64)    # the assumed growth before two levels are known
    p.advance(8.0)
    assert p.remaining() == pytest.approx(64 + 512)       # measured growth 8: 8·8 and 8·64


def test_bar_runs_without_a_terminal():
    with Progress(3, "steps", bar=True) as p:
        for _ in range(3):
            p.advance(0.01)
    assert p.done == 3


# -- the live status line (issue 25, docs/live_progress.md) ----------------------------------------

import io
import logging

from polypore.core import live
from polypore.io.progress import LiveStatus


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def _status(terminal, **kw):
    clk = FakeClock()
    out = io.StringIO()
    st = LiveStatus(out, clock=clk, terminal=terminal, **{"width": 400, **kw})
    return st, clk, out


def test_estimate_before_the_first_step_completes():
    st, clk, out = _status(True, seconds_per_unknown=1e-4, iterations_per_step=6)
    st.update(steps=10, unit="step", step=1)
    st.update(newton_start="poromechanics Newton", unknowns=100_000)
    clk.t = 2.0
    st.update(newton=0, residual=1.0)
    # no iteration finished: 1e-4 s × 1e5 unknowns = 10 s per iteration, 6 per step (a guess)
    step_left, run_left, rough = st.estimate()
    assert rough and step_left == pytest.approx(60.0) and run_left == pytest.approx(60.0 + 9 * 60.0)
    st.enter("factorising (SuperLU)")
    clk.t = 32.0                      # the first iteration is slower than guessed: it takes ≥ 30 s
    step_left, _, _ = st.estimate()
    assert step_left == pytest.approx(5 * 30.0)
    st.poll()
    line = out.getvalue()
    assert line.startswith("\r\x1b[K") and "\n" not in line
    assert line == ("\r\x1b[Kstep 1/10 · poromechanics Newton it 0, residual 1.0e+00 · factorising (SuperLU) 30 s"
                    " · step 32 s, ~2 min 30 s left · run 32 s, ~29 min 30 s left (rough estimate)")
    st.leave("factorising (SuperLU)")
    clk.t = 42.0                      # iteration 1 after 40 s: measured from now on
    st.update(newton=1, residual=1e-3)
    step_left, run_left, rough = st.estimate()
    assert step_left == pytest.approx(5 * 40.0)       # still 6 iterations per step assumed
    assert run_left == pytest.approx(200.0 + 9 * 6 * 40.0) and rough


def test_estimate_from_finished_steps_and_krylov_counts():
    st, clk, out = _status(True)
    st.update(steps=4, unit="step", step=1)
    for k in range(1, 3):                      # two steps of 2 iterations of 10 s (+ 5 s outputs)
        st.update(newton_start="Newton", unknowns=1000)
        st.update(newton=0, residual=1.0)
        for it in (1, 2):
            for _ in range(7):
                st.krylov_iteration()
            st.update(krylov_solved=7)
            clk.t += 10.0
            st.update(newton=it, residual=10.0 ** -it)
        st.update(newton_end=True)
        clk.t += 5.0
        st.update(step_done=True, step=k + 1)
    assert "14 Krylov its" not in st.status()          # counts restart with the step
    st.update(newton_start="Newton", unknowns=1000)
    st.update(newton=0, residual=1.0)
    st.enter("GMRES")
    for _ in range(3):
        st.krylov_iteration()
    clk.t += 4.0
    step_left, run_left, rough = st.estimate()
    assert not rough
    assert step_left == pytest.approx(10.0 + 6.0)    # 2 iterations per step: this one 6 s more, then one
    assert run_left == pytest.approx(16.0 + 25.0)    # and one step of 25 s after this one
    st.poll()
    text = out.getvalue()
    assert text.endswith("step 3/4 · Newton it 0, residual 1.0e+00 · GMRES 4 s · 3 Krylov its · "
                         "step 4 s, ~16 s left · run 54 s, ~41 s left")


def test_static_solve_without_steps_and_growing_levels():
    st, clk, _ = _status(False)
    st.update(newton_start="contact Newton", unknowns=10)
    st.update(newton=0, residual=1.0)
    clk.t = 3.0
    st.update(newton=1, residual=0.1)
    step_left, run_left, rough = st.estimate()
    assert step_left == pytest.approx(5 * 3.0) and run_left == step_left and rough
    assert "step" not in st.status()
    # levels each 4× the one before: after levels of 1 and 4 s, level 3 of 4 costs 16 s, level 4 64 s
    st, clk, _ = _status(False)
    st.update(steps=4, unit="level", growth=4.0, step=1)
    clk.t = 1.0
    st.update(step_done=True, step=2)
    clk.t = 5.0
    st.update(step_done=True, step=3)
    clk.t = 6.0
    step_left, run_left, _ = st.estimate()
    assert step_left == pytest.approx(15.0) and run_left == pytest.approx(15.0 + 64.0)


def test_plain_lines_are_throttled_and_log_records_count_as_output():
    st, clk, out = _status(False, interval=30.0)
    st.update(newton_start="Newton", unknowns=10)
    st.update(newton=0, residual=1.0)
    for t in range(0, 100, 1):       # polled every second for 100 s
        clk.t = float(t)
        st.poll()
    lines = out.getvalue().splitlines()
    assert len(lines) == 3 and all(l.startswith("[polypore] still running: Newton it 0") for l in lines)
    assert "run 30 s" in lines[0] and "run 1 min 30 s" in lines[2]
    # a log record resets the quiet time: no status line within 30 s of it
    handler = logging.StreamHandler(out)
    logger = logging.getLogger("polypore.test-live")
    logger.addHandler(handler)
    logger.propagate = False
    try:
        st.guard(handler)
        clk.t = 100.0
        logger.warning("something logged")
        for t in range(101, 129):
            clk.t = float(t)
            st.poll()
        assert out.getvalue().splitlines()[-1] == "something logged"
        clk.t = 130.0
        st.poll()
        assert out.getvalue().splitlines()[-1].startswith("[polypore] still running:")
    finally:
        logger.removeHandler(handler)
    assert "\r" not in out.getvalue() and "\x1b" not in out.getvalue()


def test_terminal_line_is_throttled_and_cleared_before_log_records_and_at_the_end():
    st, clk, out = _status(True, tick=1.0)
    handler = logging.StreamHandler(out)
    logger = logging.getLogger("polypore.test-live-tty")
    logger.addHandler(handler)
    logger.propagate = False
    try:
        st.guard(handler)
        st.enter("meshing")
        clk.t = 1.0
        st.poll()
        clk.t = 1.5
        st.poll()                        # within the tick: not redrawn
        assert out.getvalue() == "\r\x1b[Kmeshing 1 s · run 1 s"
        logger.warning("mesh built")
        assert out.getvalue().endswith("meshing 1 s · run 1 s\r\x1b[Kmesh built\n")
        clk.t = 1.6
        st.poll()                        # redrawn at once after a record
        assert out.getvalue().endswith("mesh built\n\r\x1b[Kmeshing 2 s · run 2 s")
    finally:
        logger.removeHandler(handler)
    st.leave("meshing")
    st.erase()
    assert out.getvalue().endswith("\r\x1b[K")
    st2, _, out2 = _status(True, width=20)
    st2.enter("factorising (SuperLU)")
    st2.poll()
    assert len(out2.getvalue()) == len("\r\x1b[K") + 20 and out2.getvalue().endswith("…")


def test_context_installs_the_observer_and_the_thread_draws(monkeypatch):
    out = io.StringIO()
    assert live.current() is None
    with LiveStatus(out, terminal=True, tick=0.01, width=200) as st:
        assert live.current() is st
        with live.phase("meshing"):
            import time
            deadline = time.time() + 5
            while "meshing" not in out.getvalue() and time.time() < deadline:
                time.sleep(0.01)
    assert live.current() is None
    assert "meshing" in out.getvalue() and out.getvalue().endswith("\r\x1b[K")
    live.update(newton=1)              # nobody listens: nothing happens
    with live.phase("x"):
        live.krylov_iteration()


def test_progress_reports_its_steps_to_the_live_status():
    st, clk, _ = _status(False)
    previous = live.install(st)
    try:
        with Progress(3, "steps", bar=None) as p:
            assert p._bar is None            # the live line replaces the rich bar
            assert "step 1/3" in st.status()
            clk.t = 2.0
            p.advance()
            assert "step 2/3" in st.status()
            assert st.estimate()[1] == pytest.approx(4.0)
    finally:
        live.install(previous)
    assert "step" not in st.status()


def _run_cli(args, env_extra, tty):
    """Run ``polypore`` in a subprocess, stderr a pseudo-terminal (tty) or a pipe; returns (status, stderr)."""
    import os
    import subprocess
    import sys

    env = {**os.environ, **env_extra, "COLUMNS": "300"}
    env["PYTHONPATH"] = os.pathsep.join([str(__import__("pathlib").Path(__file__).parents[3] / "src"),
                                         env.get("PYTHONPATH", "")])
    cmd = [sys.executable, "-m", "polypore", *args]
    if not tty:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
        return proc.returncode, proc.stderr
    import pty

    master, slave = pty.openpty()
    proc = subprocess.Popen(cmd, env=env, stdin=subprocess.DEVNULL, stdout=slave, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    return proc.wait(timeout=600), b"".join(chunks).decode(errors="replace")


SHORT_DFM = ["run", "dfm-2d", "--set", "time.end=200", "--set", "time.output_times=[200.0]", "--force"]


def test_cli_plain_lines_in_a_log(tmp_path):
    code, err = _run_cli(SHORT_DFM + ["--out", str(tmp_path / "r")], {"POLYPORE_LIVE_INTERVAL": "0.5"}, tty=False)
    assert code == 0, err
    still = [l for l in err.splitlines() if "still running:" in l]
    assert still and all(l.startswith("[polypore] still running: ") for l in still)
    assert "\r" not in err and "\x1b[K" not in err
    assert any("step 10/10" in l for l in err.splitlines())        # the per-step lines are kept


@pytest.mark.slow
def test_cli_terminal_line_is_cleared(tmp_path):
    code, out = _run_cli(SHORT_DFM + ["--out", str(tmp_path / "r")], {}, tty=True)
    assert code == 0, out
    assert "\r\x1b[Kstep " in out                        # the live line was drawn ...
    tail = out[out.rindex("\r\x1b[K"):]
    assert "· run " not in tail and "case dfm-2d:" in tail    # ... and cleared at the end, before the summary
    code, out = _run_cli(["-q"] + SHORT_DFM + ["--out", str(tmp_path / "q")], {}, tty=True)
    assert code == 0 and "\x1b[K" not in out            # --quiet: no live line


def test_cli_live_status_only_on_rank_0_and_not_quiet(monkeypatch):
    import polypore.cli as cli

    monkeypatch.setattr(cli, "_is_root", lambda: False)
    with cli._live_status():
        assert live.current() is None                  # MPI ranks other than 0: no line
    monkeypatch.setattr(cli, "_is_root", lambda: True)
    monkeypatch.setenv("POLYPORE_LIVE", "0")
    with cli._live_status():
        assert live.current() is None
    monkeypatch.delenv("POLYPORE_LIVE")
    level = cli.log.level
    try:
        cli.log.setLevel(logging.INFO)
        with cli._live_status():
            assert isinstance(live.current(), LiveStatus)
        assert live.current() is None
        cli.log.setLevel(logging.WARNING)              # --quiet
        with cli._live_status():
            assert live.current() is None
    finally:
        cli.log.setLevel(level)
