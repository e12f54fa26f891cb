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
