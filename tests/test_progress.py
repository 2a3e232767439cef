"""The progress bar: silent when quiet, off a terminal or for short work; drawn otherwise."""
import io

from twoscale.progress import Progress, track


class _Tty(io.StringIO):
    def isatty(self):
        return True


class _Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_draws_on_a_terminal_after_the_delay():
    s, clock = _Tty(), _Clock()
    with Progress(4, label="loads", stream=s, clock=clock, width=8) as bar:
        bar.update()
        assert s.getvalue() == ""            # 0 s < 2 s delay: nothing yet
        clock.t = 3.0
        bar.update(note="S1")
    text = s.getvalue()
    assert "loads [####    ] 2/4  3.0 s  S1" in text
    assert text.endswith("\n")


def test_silent_when_quiet_or_not_a_terminal_or_quick():
    for stream, quiet, t in ((_Tty(), True, 5.0), (io.StringIO(), False, 5.0), (_Tty(), False, 1.0)):
        clock = _Clock()
        with Progress(2, stream=stream, quiet=quiet, clock=clock) as bar:
            clock.t = t
            bar.update()
            bar.update()
        assert stream.getvalue() == ""


def test_track_yields_everything():
    assert list(track(range(5), quiet=True)) == [0, 1, 2, 3, 4]
