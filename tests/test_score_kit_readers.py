"""Every reader of a score reads it with the kit it is played on (a text score's object ids, doubles by object):
the sound demo and the graphics preview read it without, so a score naming ``crash2`` with no ``kit`` line was
refused on the ``double_pedal`` kit they were given (a review of 4bc4c37)."""

from __future__ import annotations

from pathlib import Path

from common.kit import load_kit

SCORE = "tempo 120\nCR |x...|\ncrash2 |..x.|\n"


def test_the_sound_demo_reads_a_score_with_its_kit(tmp_path: Path) -> None:
    from services.sound.demo import impacts_from_midi

    score = tmp_path / "crashes.txt"
    score.write_text(SCORE, encoding="utf-8")
    impacts = impacts_from_midi(score, load_kit("double_pedal", warn=False))
    assert [i.instrument for i in impacts] == ["crash", "crash2"]


def test_the_graphics_preview_reads_a_score_with_its_kit(tmp_path: Path) -> None:
    from services.graphics.preview import score_preview

    score = tmp_path / "crashes.txt"
    score.write_text(SCORE, encoding="utf-8")
    preview = score_preview(score, load_kit("double_pedal", warn=False))
    assert preview is not None
