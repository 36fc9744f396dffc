"""A text score names a kit's objects by their ids (``crash2``, ``floortom2``, a designer's ``tom4``): the row names
were the 15 event types and their aliases only, so a second crash or a fourth tom, which a MIDI file plays through
the kit's ``note_objects``, could not be written. The ids are the kit's the score is played on: its ``kit`` line's
(the default kit without one), or the kit the reader is given (``read_score(kit=)``, ``python -m common.score
--kit``); an id names the event type that strikes the object and the pitch that sends it there, so planning,
physics and evaluation play and judge it on that object (tests/render/test_render_kit_objects.py renders one)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from common.kit import KITS_DIR, EventType, Limb, load_kit
from common.score.__main__ import main as inspect_main
from common.score.events import ScoreError
from common.score.text import parse_text, read_score

E = EventType


def _played(score_text: str, kit_name: str = "double_pedal") -> list[tuple[float, str]]:
    kit = load_kit(kit_name, warn=False)
    score = parse_text(score_text)
    return [(round(e.time, 3), kit.object_for(e.event, e.pitch).id) for e in score.events]


def test_rows_and_notes_name_the_kit_objects_by_id() -> None:
    text = ("kit double_pedal\ntempo 120\nCR |x...|\ncrash2 |..x.|\nFloorTom2 |.x.x|\nat 3.5 ride2 0.9 L\n"
            "at 0.5 kick_pedal\nat 1 hihat_pedal\n")
    score = parse_text(text)
    assert [(e.event, e.pitch) for e in score.events] == [
        (E.CRASH, None), (E.FLOORTOM, 41), (E.CRASH, 57), (E.FLOORTOM, 41), (E.BASS, None), (E.HIHATPEDAL, None),
        (E.RIDE, 59)]
    assert score.events[-1].limb is Limb.LEFT_HAND and score.events[-1].velocity == 0.9
    assert _played(text) == [(0.0, "crash"), (0.5, "floortom2"), (1.0, "crash2"), (1.5, "floortom2"),
                             (2.25, "kick"), (2.5, "hihat_pedal"), (3.75, "ride2")]


def test_an_object_and_its_event_s_own_at_once_are_two_drums_not_a_double() -> None:
    """``CR`` and ``crash2`` on one beat: both crashes are struck (double events are one drum's, by event type and
    the pitch choosing its object); ``CR`` and ``crash`` are one."""
    score = parse_text("kit double_pedal\nCR |x.|\ncrash2 |x.|\ncrash |x.|\n")
    assert [(e.event, e.pitch) for e in score.events] == [(E.CRASH, None), (E.CRASH, 57)]
    assert len(score.duplicates) == 1


def test_the_ids_are_the_given_kit_s_over_the_kit_line_s(tmp_path: Path) -> None:
    path = tmp_path / "s.txt"
    path.write_text("SN |x.x.|\ncrash2 |.x..|\n", encoding="utf-8")
    with pytest.raises(ScoreError) as refused:
        read_score(path)  # no kit line: the default kit's ids
    message = str(refused.value)
    assert message.startswith(f"{path}: line 2: unknown instrument 'crash2': did you mean CRASH?")
    assert "the objects of kit 'default': kick, snare, hightom" in message
    assert "crash2 is an object of kit 'double_pedal': play the score on it (a 'kit double_pedal' line)" in message
    score = read_score(path, kit=load_kit("double_pedal", warn=False))
    assert [(e.event, e.pitch) for e in score.events] == [(E.SNARE, None), (E.CRASH, 57), (E.SNARE, None)]


def test_an_unknown_name_names_the_line_and_lists_the_kit_ids() -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text("kit double_pedal\nHH |x.x.|\ncrash3 |x...|\n")
    message = str(refused.value)
    assert message.startswith("line 3: unknown instrument 'crash3': did you mean CRASH or crash2? (the names are the "
                              "event types and their aliases: docs/score-format.md, 'Row names', and the objects of "
                              "kit 'double_pedal': kick, snare, hightom, midtom, floortom, floortom2, crash, ")
    assert "crash2, splash, ride, ride2, china, cowbell, kick_pedal, hihat_pedal (hihat is struck by HIHATOPEN or " \
           "HIHATCLOSED: name the stroke)" in message
    with pytest.raises(ScoreError, match=r"^line 2: unknown instrument 'hihat': did you mean HIHATOPEN, HIHATCLOSED, "
                                         r"HIHATPEDAL .*hihat is struck by HIHATOPEN or HIHATCLOSED: name the stroke"):
        parse_text("tempo 90\nat 0 hihat\n")  # one object, two strokes: the stroke's name says which
    with pytest.raises(ScoreError, match=r"line 2: unknown instrument 'throne'.*throne is the kit's throne, which no "
                                         r"note plays alone"):
        parse_text("SN |x.|\nthrone |x.|\n")


def _kit_with_tom4(folder: Path, pitch: int | None) -> Path:
    """The default kit with a fourth tom, ``tom4``, beside the floor tom; played by ``pitch`` (None: by none)."""
    data = yaml.safe_load((KITS_DIR / "default.yaml").read_text(encoding="utf-8"))
    data["name"] = "four_toms"
    data["objects"].append({"id": "tom4", "kind": "membrane", "position": [0.50, 0.12, 0.58],
                            "rotation_deg": [5, 0, 0], "radius": 0.2, "depth": 0.4, "elasticity": 0.6})
    if pitch is not None:
        data["note_objects"] = {pitch: "tom4"}
    path = folder / "four_toms.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_a_designer_s_fourth_tom_is_written_by_its_id(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _kit_with_tom4(tmp_path, 41)
    score = tmp_path / "fill.txt"
    score.write_text("kit four_toms.yaml\ntempo 100\nFT |x.x.....|\ntom4 |....x.x.|\n", encoding="utf-8")
    read = read_score(score)  # the kit line's file, from the score's folder
    assert [(e.event, e.pitch) for e in read.events] == [(E.FLOORTOM, None), (E.FLOORTOM, None), (E.FLOORTOM, 41),
                                                         (E.FLOORTOM, 41)]
    kit = load_kit(tmp_path / "four_toms.yaml", warn=False)
    assert [kit.object_for(e.event, e.pitch).id for e in read.events] == ["floortom", "floortom", "tom4", "tom4"]
    assert inspect_main([str(score)]) == 0
    assert "FLOORTOM     4" in capsys.readouterr().out
    _kit_with_tom4(tmp_path, None)  # no pitch plays it: said what to do
    with pytest.raises(ScoreError, match=r"line 4: unknown instrument 'tom4'.*tom4 is an object of kit 'four_toms' "
                                         r"no event type or note_objects pitch strikes: give it a General MIDI pitch "
                                         r"in the kit's note_objects"):
        read_score(score)


def test_python_m_common_score_looks_the_ids_up_in_its_kit_option(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    score = tmp_path / "s.txt"
    score.write_text("tempo 100\nCR |x...|\ncrash2 |..x.|\n", encoding="utf-8")
    assert inspect_main([str(score), "--kit", "double_pedal"]) == 0
    assert "CRASH        2" in capsys.readouterr().out
    assert inspect_main([str(score)]) != 0
    assert "unknown instrument 'crash2'" in capsys.readouterr().err


def test_a_foot_object_under_a_sticking_mark_warns_as_bd_does() -> None:
    score = parse_text("kit double_pedal\nkick_pedal |xxxx|\nST |RLRL|\n")
    assert [e.limb for e in score.events] == [None] * 4
    # the id as written (it said KICK_PEDAL until 7 Dec); an alias stays upper-case, as ever
    assert score.warnings[-1] == "line 3: ST cells 1-4: kick_pedal is played by a foot; the hands there are ignored"
    score = parse_text("kit double_pedal\nKick_Pedal |x...|\nbd |.x..|\nST |RL..|\n")
    assert score.warnings[-1] == "line 4: ST cells 1-2: BD or Kick_Pedal is played by a foot; the hands there are " \
                                 "ignored"
