"""The progress bar says the time left once it means something (``video [...] 98% 459 frames / 466 frames (35.5 s)``
said only the time spent), and off a terminal (a log, CI) prints a plain line now and then instead of nothing;
quiet stays quiet. A hand-moved clock and a fake stream."""

from __future__ import annotations

import io
from types import SimpleNamespace

import pytest

from batteur import progress as progress_module
from batteur.progress import Progress, duration_words


class _Clock:
    """A monotonic clock the test moves by hand (seconds)."""

    def __init__(self) -> None:
        self.now = 500.0

    def monotonic(self) -> float:
        return self.now


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> _Clock:
    moved = _Clock()
    monkeypatch.setattr(progress_module, "time", SimpleNamespace(monotonic=moved.monotonic))
    return moved


def _draws(stream: io.StringIO) -> list[str]:
    return [d for d in stream.getvalue().split("\r") if d]


def test_the_bar_says_the_time_left_once_it_means_something(clock: _Clock) -> None:
    stream = _Terminal()
    bar = Progress("video", 466, unit="frames", decimals=0, stream=stream)
    clock.now += 1.0
    bar.update(100)  # 21 % but 1 s in: no estimate yet
    clock.now += 1.0
    bar.update(5)  # 2 s in but 1 %: none either
    clock.now += 33.5
    bar.update(459)  # 98 % in 35.5 s: 0.54 s left, said as 1 s
    clock.now += 0.5
    bar.close()
    draws = _draws(stream)
    assert "left" not in draws[0] and "left" not in draws[1], draws
    assert draws[2].startswith("video [") and "98% 459 frames / 466 frames (35.5 s, about 1 s left)" in draws[2]
    assert "100% 466 frames / 466 frames (36.0 s)" in draws[3] and "left" not in draws[3]  # done: no estimate
    assert len(draws[3]) >= len(draws[2].rstrip())  # padded over the longer line before: no "left)" left behind
    assert stream.getvalue().endswith("\n")


def test_the_estimate_holds_the_rate_so_far(clock: _Clock) -> None:
    stream = _Terminal()
    bar = Progress("rendering x", 100.0, stream=stream)
    clock.now += 60.0
    bar.update(20.0)  # a fifth in a minute: four minutes left
    clock.now += 60.0
    bar.update(90.0)  # 90 % in two minutes: 13 s left
    draws = _draws(stream)
    assert "(60.0 s, about 4 min left)" in draws[0] and "(120.0 s, about 13 s left)" in draws[1], draws


def test_duration_words() -> None:
    assert [duration_words(s) for s in (0.2, 1.4, 42.0, 99.0, 100.0, 3599.0, 3600.0, 7500.0)] == [
        "1 s", "1 s", "42 s", "99 s", "2 min", "1 h 00 min", "1 h 00 min", "2 h 05 min"]


def test_off_a_terminal_a_plain_line_now_and_then(clock: _Clock) -> None:
    """Every 30 s or 10 %, whichever comes first, none in the first 30 s; a last line at the end once any was
    printed (not a second one at 100 %)."""
    log = io.StringIO()
    bar = Progress("rendering groove.mid", 200.0, stream=log)
    done = 0.0
    for _ in range(400):  # 0.5 s of rig time per 0.25 s: 100 s for the whole, 10 % every 10 s
        clock.now += 0.25
        done += 0.5
        bar.update(done)
    bar.close()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert lines == [f"rendering groove.mid: {p}% {2.0 * p:.1f} s / 200.0 s ({p} s, about {100 - p} s left)"
                     for p in (30, 40, 50, 60, 70, 80, 90)] + [
                     "rendering groove.mid: 100% 200.0 s / 200.0 s (100 s)"], lines


def test_off_a_terminal_a_slow_run_says_it_is_alive_every_30_s(clock: _Clock) -> None:
    """A render slower than 10 % in 30 s (a 10-minute piece rendering for 17 minutes) prints a line with the time
    left every 30 s of wall time: until 8 Dec only every 10 %, here 100 s apart, and minutes apart on longer ones."""
    log = io.StringIO()
    bar = Progress("video", 1000, unit="frames", decimals=0, stream=log)
    for frame in range(1, 1001):  # one frame a second: 10 % every 100 s
        clock.now += 1.0
        bar.update(frame)
    bar.close(finished=True)
    lines = log.getvalue().splitlines()
    seconds = range(30, 1000, 30)
    assert lines[:-1] == [f"video: {s // 10}% {s} frames / 1000 frames ({s} s, about {duration_words(1000 - s)} left)"
                          for s in seconds], lines
    assert lines[-1] == "video: 100% 1000 frames / 1000 frames (1000 s)"


def test_off_a_terminal_a_short_run_or_a_given_up_one_prints_nothing(clock: _Clock) -> None:
    log = io.StringIO()
    bar = Progress("rendering x", 10.0, stream=log)
    for k in range(10):  # all of it within 29 s
        clock.now += 2.9
        bar.update(k + 1.0)
    bar.close()
    assert log.getvalue() == ""
    bar = Progress("rendering x", 10.0, stream=log)
    clock.now += 40.0
    bar.update(5.0)
    bar.close(finished=False)  # given up: its error says so, no "100 %"
    assert log.getvalue().splitlines() == ["rendering x: 50% 5.0 s / 10.0 s (40 s, about 40 s left)"]


@pytest.mark.parametrize("stream", [io.StringIO(), _Terminal()])
def test_quiet_stays_quiet(clock: _Clock, stream: io.StringIO) -> None:
    bar = Progress("rendering x", 10.0, stream=stream, enabled=False)
    for k in range(10):
        clock.now += 40.0
        bar.update(k + 1.0)
    bar.close()
    assert stream.getvalue() == ""


class _ClosedPipe(io.StringIO):
    """A stream whose reader has gone (``batteur render ... 2>&1 | head``): every write raises."""

    def __init__(self, terminal: bool) -> None:
        super().__init__()
        self.terminal = terminal
        self.writes = 0

    def isatty(self) -> bool:
        return self.terminal

    def write(self, text: str) -> int:
        self.writes += 1
        raise BrokenPipeError(32, "Broken pipe")


@pytest.mark.parametrize("terminal", [True, False])
def test_a_stream_that_breaks_silences_the_progress_not_the_work(clock: _Clock, terminal: bool) -> None:
    """A closed pipe stopped the render whose progress it showed (off a terminal progress now writes lines)."""
    stream = _ClosedPipe(terminal)
    bar = Progress("render", 100.0, stream=stream)
    for done in range(0, 101, 5):
        clock.now += 10.0
        bar.update(float(done))
    bar.close()
    assert stream.writes == 1  # the first write failed, nothing was tried after it


def test_no_stderr_at_all_is_quiet(monkeypatch: pytest.MonkeyPatch, clock: _Clock) -> None:
    """``2>&-`` leaves sys.stderr None: the progress says nothing instead of failing on it."""
    monkeypatch.setattr(progress_module.sys, "stderr", None)
    bar = Progress("render", 10.0)
    clock.now += 60.0
    bar.update(5.0)
    bar.close()
    assert not bar.enabled and not bar.logging


def test_off_a_terminal_100_percent_is_said_once_when_done(clock: _Clock) -> None:
    """A line printed at 99.6 % says 99 %, and the last line at the end says 100 % (until 8 Dec both said 100 %)."""
    log = io.StringIO()
    bar = Progress("rendering x", 10.0, stream=log)
    clock.now += 40.0
    bar.update(9.96)
    bar.close()
    lines = log.getvalue().splitlines()
    assert [line.split(": ")[1].split()[0] for line in lines] == ["99%", "100%"], lines
