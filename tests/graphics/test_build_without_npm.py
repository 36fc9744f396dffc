"""`batteur graphics build` on a machine without npm: the convention's one line and status 1 (README, "Exit
status"): npm is a missing tool, not a command line that cannot run."""

from __future__ import annotations

import pytest

from services.graphics import node


def test_build_without_npm_says_so_in_one_error_line_and_exits_1(monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(node.shutil, "which", lambda name: None)
    monkeypatch.setattr(node.subprocess, "run", lambda *a, **k: pytest.fail("ran a command without npm"))
    assert node.build_assets() == 1
    assert capsys.readouterr().err == ("batteur graphics build: error: npm is not installed "
                                       "(Debian: apt-get install npm)\n")
