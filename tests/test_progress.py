"""Progress through tqdm: silent when quiet, off a terminal or for short work; drawn otherwise.
The command line's --quiet and a stderr that is not a terminal silence it too."""

import io
import sys

import pytest

from twoscale.cli.main import main
from twoscale.progress import Progress, StatusLine, track


class _Tty(io.StringIO):
    def isatty(self):
        return True


@pytest.fixture
def clock(monkeypatch):
    """tqdm's clock, set by hand (tqdm reads ``tqdm.std.time`` when a bar is made)."""
    import tqdm.std

    t = [0.0]
    monkeypatch.setattr(tqdm.std, "time", lambda: t[0])
    return t


def test_draws_on_a_terminal_after_the_delay(clock):
    s = _Tty()
    with Progress(4, label="loads", stream=s) as bar:
        bar.update()
        assert s.getvalue() == ""  # 0 s < 2 s delay: nothing yet
        clock[0] = 3.0
        bar.update(note="S1")
    text = s.getvalue()
    assert "loads" in text and "2/4" in text and "S1" in text
    assert text.endswith("\n")


def test_silent_when_quiet_or_not_a_terminal_or_quick(clock):
    for stream, quiet, t in ((_Tty(), True, 5.0), (io.StringIO(), False, 5.0), (_Tty(), False, 1.0)):
        clock[0] = 0.0
        with Progress(2, stream=stream, quiet=quiet) as bar:
            clock[0] = t
            bar.update()
            bar.update()
        assert stream.getvalue() == ""


def test_track_yields_everything():
    assert list(track(range(5), quiet=True)) == [0, 1, 2, 3, 4]


def test_status_line_draws_late_and_only_on_a_terminal(clock):
    stream = _Tty()
    with StatusLine(stream=stream, delay=3.0, interval=0.5) as status:
        status("macro step")  # too early: nothing
        clock[0] = 3.5
        status("micro step, sweep 2, residual 1.0e-03")  # drawn, with the elapsed time
        clock[0] = 3.6
        status("micro step, sweep 3")  # too soon after the last: skipped
    text = stream.getvalue()
    assert "macro" not in text and "solving: micro step, sweep 2, residual 1.0e-03  00:03" in text
    assert "sweep 3" not in text
    assert text.endswith("\r")  # cleared at the end
    for stream, quiet in ((io.StringIO(), False), (_Tty(), True)):
        clock[0] = 0.0
        with StatusLine(stream=stream, quiet=quiet) as status:
            clock[0] = 10.0
            status("anything")
        assert stream.getvalue() == ""  # not a terminal, or quiet: silent


@pytest.mark.parametrize("quiet", [False, True])
def test_solve_status_on_a_terminal_unless_quiet(scene, monkeypatch, quiet):
    # a clock that runs 1 s per reading makes every solve "long"; stderr a terminal
    import tqdm.std

    t = [0.0]

    def tick():
        t[0] += 1.0
        return t[0]

    monkeypatch.setattr(tqdm.std, "time", tick)
    err = _Tty()
    monkeypatch.setattr(sys, "stderr", err)
    # the two-scale solver itself (one sphere's default route is its full grid's one CG,
    # whose single stage is named before it starts)
    argv = ["solve", str(scene), "--iteration", "union-cg"]
    assert main(argv + (["--quiet"] if quiet else [])) == 0
    if quiet:
        assert err.getvalue() == ""
    else:
        assert "solving: " in err.getvalue() and "step" in err.getvalue()
