"""``python -m common.score`` plays a text score's ``kit`` line as ``batteur render`` and ``batteur evaluate`` do
(``--kit`` wins; a kit file relative to the score's folder; a kit it cannot load names the line); it used the
default kit whatever the score said."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from common.kit import KITS_DIR
from common.score.__main__ import main

ONE_BAR = "tempo 120\nmeter 4/4\nSN |x.x.|\nBD |x...|\n"


def _score(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "score.txt"
    path.write_text(text)
    return path


def _kit_said(out: str) -> str:
    return next(line for line in out.splitlines() if line.startswith("kit: "))


def test_the_score_s_kit_line_is_played_unless_kit_is_given(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    path = _score(tmp_path, "kit double_pedal\n" + ONE_BAR)
    assert main([str(path)]) == 0
    assert _kit_said(capsys.readouterr().out) == "kit: double_pedal (the score's kit line)"
    assert main([str(path), "--kit", "left_handed"]) == 0
    assert _kit_said(capsys.readouterr().out) == "kit: left_handed"
    assert main([str(_score(tmp_path, ONE_BAR))]) == 0  # no kit line, no --kit: the default, as before
    assert _kit_said(capsys.readouterr().out) == "kit: default"


def test_a_kit_file_named_in_a_score_is_found_beside_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "kits").mkdir()
    data = yaml.safe_load((KITS_DIR / "default.yaml").read_text())
    data["name"] = "mine"
    (tmp_path / "kits" / "mine.yaml").write_text(yaml.safe_dump(data))
    assert main([str(_score(tmp_path, "kit kits/mine.yaml\n" + ONE_BAR))]) == 0
    assert _kit_said(capsys.readouterr().out) == f"kit: {tmp_path / 'kits' / 'mine.yaml'} (the score's kit line)"


def test_an_unknown_kit_in_a_score_names_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _score(tmp_path, "tempo 120\nkit nosuchkit\n" + ONE_BAR)
    assert main([str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path}: line 2: kit 'nosuchkit': " in err[0] and "shipped kits: " in err[0], err
    assert main([str(path), "--kit", "nosuchkit"]) == 1  # the option's own kit: no score line to name
    err = capsys.readouterr().err.strip()
    assert "line 2" not in err and "nosuchkit" in err, err
