"""``batteur render --strikes`` refuses a strike time it could not render before anything runs, and the progress
bar stays throttled (and within its total) when the work runs past the total it was given."""

from __future__ import annotations

import io
from pathlib import Path
from types import SimpleNamespace

import pytest

from batteur import progress as progress_module
from batteur import render
from batteur.progress import Progress
from batteur.strike import MAX_STRIKE_TIME_S, parse_strikes


@pytest.mark.parametrize("text", ["1e9:3", f"0.25:3,{MAX_STRIKE_TIME_S + 0.5:g}:2", "inf:3", "nan:3", "-1:3",
                                  "0.5:0", "0.5:nan"])
def test_strike_times_and_speeds_the_scene_cannot_render_are_refused_with_the_item(text: str) -> None:
    with pytest.raises(ValueError, match="strike '") as caught:
        parse_strikes(text)
    assert text.split(",")[-1] in str(caught.value)


def test_strikes_up_to_the_limit_are_kept() -> None:
    assert parse_strikes(f"0.25:3, {MAX_STRIKE_TIME_S:g}:1.5") == [(0.25, 3.0), (MAX_STRIKE_TIME_S, 1.5)]


def test_a_strike_a_billion_seconds_in_is_one_line_before_anything_runs(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """It simulated for 10 minutes and took 3.9 GB before: now refused at once, nothing created."""
    def must_not_run(*args: object, **kwargs: object) -> None:
        raise AssertionError("the strike scene ran")

    monkeypatch.setattr(render, "run_strikes", must_not_run)
    out = tmp_path / "out"
    assert render.main(["--strikes", "1e9:3", "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("batteur render: error: strike '1e9:3'") and f"at most {MAX_STRIKE_TIME_S:g} s" in err, err
    assert len(err.splitlines()) == 1
    assert not out.exists()


class _Clock:
    """A monotonic clock the test moves by hand (seconds)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


def _bar(monkeypatch: pytest.MonkeyPatch, total: float) -> tuple[Progress, io.StringIO, _Clock]:
    clock = _Clock()
    monkeypatch.setattr(progress_module, "time", SimpleNamespace(monotonic=clock.monotonic))
    stream = io.StringIO()
    return Progress("rendering x", total, stream=stream, interval_s=0.2, enabled=True), stream, clock


def _draws(stream: io.StringIO) -> list[str]:
    return [d for d in stream.getvalue().split("\r") if d]


def test_work_past_the_total_is_still_throttled_and_shown_at_the_total(monkeypatch: pytest.MonkeyPatch) -> None:
    """A render whose total was short redrew at every step past it (1,500 lines at 100 %, 127 KB)."""
    bar, stream, clock = _bar(monkeypatch, total=4.5)
    bar.update(1.0)  # the first update draws
    for k in range(1000):  # 1000 steps past the total within 0.1 s: no draw
        clock.now += 0.0001
        bar.update(4.5 + 0.001 * k)
    assert len(_draws(stream)) == 1
    clock.now += 0.5
    bar.update(5.5)  # the interval passed: drawn, clamped to the total
    bar.close()
    draws = _draws(stream)
    assert len(draws) == 3
    assert "100% 4.5 s / 4.5 s" in draws[1]
    assert "5.5" not in "".join(draws)
    assert stream.getvalue().endswith("\n")


def test_close_draws_the_full_bar_even_within_the_interval(monkeypatch: pytest.MonkeyPatch) -> None:
    bar, stream, _ = _bar(monkeypatch, total=10.0)
    bar.update(3.0)
    bar.update(9.0)  # within the interval: not drawn
    bar.close()
    draws = _draws(stream)
    assert len(draws) == 2 and "100% 10.0 s / 10.0 s" in draws[1]
