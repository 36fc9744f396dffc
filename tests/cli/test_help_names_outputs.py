"""Help texts name what a command writes and how to use what it sends: `batteur render`'s copy of the score,
`batteur sound --wav`'s .json beside the take, and where `batteur transcribe --live`'s hits can be watched."""

from __future__ import annotations

import pytest

from batteur import cli


def _help(command: str, capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit):
        cli.main([command, "--help"])
    return " ".join(capsys.readouterr().out.split())  # argparse's wrapping undone


def test_render_help_names_the_score_copy(capsys: pytest.CaptureFixture[str]) -> None:
    assert "DIR/score.<ext>" in _help("render", capsys)  # was four outputs; docs/render.md had the fifth


def test_sound_help_names_the_json_beside_the_take(capsys: pytest.CaptureFixture[str]) -> None:
    text = _help("sound", capsys)
    assert "take.wav.json" in text and "origin_rig_time_s" in text


def test_transcribe_help_says_how_to_receive_live_hits(capsys: pytest.CaptureFixture[str]) -> None:
    text = _help("transcribe", capsys)  # was: --to HOST:PORT, and nothing in Batteur receives there
    assert "batteur interaction --port 9900 --no-discovery --interaction-config none" in text
    assert "batteur echo --node 127.0.0.1:9900 /batteur/recogniser/hit" in text
    assert "batteur transcribe groove.wav --live --to 127.0.0.1:9900" in text
