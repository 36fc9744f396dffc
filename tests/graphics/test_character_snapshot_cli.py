"""``python -m tests.graphics.character_snapshot``: --help explains and writes nothing (until 7 Dec it ignored its
arguments and rewrote services/graphics/character.json, which on some machines differs in the 6th decimal of a few
values: --help dirtied the tree); --check compares without writing, telling rounding from a change."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from services.graphics.poser import SNAPSHOT

from . import character_snapshot


def _shipped() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(SNAPSHOT.read_text(encoding="utf-8"))
    return data


def test_help_explains_and_builds_or_writes_nothing(monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    before = SNAPSHOT.read_bytes()
    monkeypatch.setattr(character_snapshot, "build_snapshot", lambda: pytest.fail("built on --help"))
    with pytest.raises(SystemExit) as done:
        character_snapshot.main(["--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "usage:" in out and "--check" in out and "character.json" in out
    assert SNAPSHOT.read_bytes() == before


@pytest.mark.parametrize(("change", "code", "said"), [(0.0, 0, "is what physics builds"),
                                                      (1e-6, 0, "(rounding)"),
                                                      (2e-4, 1, "rest: largest difference 0.0002")])
def test_check_compares_without_writing(change: float, code: int, said: str, monkeypatch: pytest.MonkeyPatch,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    fresh = copy.deepcopy(_shipped())
    fresh["rest"][3][0] += change
    monkeypatch.setattr(character_snapshot, "build_snapshot", lambda: fresh)
    before = SNAPSHOT.read_bytes()
    assert character_snapshot.main(["--check"]) == code
    assert said in capsys.readouterr().out
    assert SNAPSHOT.read_bytes() == before


def test_check_says_a_changed_body_and_writing_goes_where_asked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    fresh = copy.deepcopy(_shipped())
    fresh["names"] = fresh["names"][:-1]
    fresh["effectors"]["right_hand"]["link"] = "left_stick"
    monkeypatch.setattr(character_snapshot, "build_snapshot", lambda: fresh)
    assert character_snapshot.main(["--check"]) == 1
    out = capsys.readouterr().out
    assert "names: differs" in out and "effectors: another link" in out
    target = tmp_path / "character.json"
    before = SNAPSHOT.read_bytes()
    assert character_snapshot.main(["-o", str(target)]) == 0
    assert json.loads(target.read_text(encoding="utf-8")) == fresh
    assert SNAPSHOT.read_bytes() == before
