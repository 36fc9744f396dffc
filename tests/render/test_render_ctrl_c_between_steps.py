"""A Ctrl-C during a one-process render is acted on between steps, never inside one: landing inside a numba kernel
of the physics step it became a ``SystemError`` with a traceback (exit 1) instead of the one-line interruption."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest

from batteur import render
from batteur.interrupts import DeferredCtrlC
from services.interaction.core import InteractionCore

TINY = "tempo 120\nmeter 4/4\nSN |x.x.|\n"


def test_a_ctrl_c_inside_a_step_is_acted_on_after_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    steps = {"count": 0, "finished_the_interrupted_one": False}
    original = InteractionCore.step

    def step(self: InteractionCore, now: float) -> Any:
        steps["count"] += 1
        if steps["count"] == 200:
            os.kill(os.getpid(), signal.SIGINT)  # as a terminal's Ctrl-C, in the middle of a step
            out = original(self, now)
            steps["finished_the_interrupted_one"] = True
            return out
        return original(self, now)

    monkeypatch.setattr(InteractionCore, "step", step)
    score = tmp_path / "tiny.txt"
    score.write_text(TINY)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "Traceback" not in err and "interrupted; nothing written" in err
    assert steps["finished_the_interrupted_one"]
    assert not out.exists()


def test_deferred_ctrl_c_raises_at_the_check_or_at_the_end() -> None:
    before = signal.getsignal(signal.SIGINT)  # Python's default, or ignored (a suite run in the background)
    with DeferredCtrlC() as ctrl_c:
        os.kill(os.getpid(), signal.SIGINT)
        assert ctrl_c.noted  # noted, not raised here
        with pytest.raises(KeyboardInterrupt):
            ctrl_c.check()
        ctrl_c.check()  # acted on once
    with pytest.raises(KeyboardInterrupt), DeferredCtrlC():
        os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) == before  # put back as it was
