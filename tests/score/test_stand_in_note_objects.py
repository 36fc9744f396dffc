"""A General MIDI stand-in pitch the kit's ``note_objects`` sends to an object of its own is said to be played there:
the warning said ``pitch 76 (Hi Wood Block, E4) played as cowbell`` for a kit whose ``woodblock`` plays 76."""

from __future__ import annotations

from pathlib import Path

from common.kit import Kit, KitObject, load_kit
from common.score.midi import read_midi
from tests.score.test_midi_note_maps import drum_file


def _woodblock_kit() -> Kit:
    """The default kit with a wood block (kind bell) beside the cowbell, GM 76 and 77 sent to it."""
    kit = load_kit("default")
    block = KitObject(id="woodblock", kind="bell", position=(0.18, 0.70, 0.95), rotation_deg=(30.0, 0.0, 0.0),
                      radius=0.035, depth=0.18)
    return Kit.model_validate({**kit.model_dump(), "objects": [*kit.model_dump()["objects"], block.model_dump()],
                               "note_objects": {76: "woodblock", 77: "woodblock"}})


def test_a_pitch_the_kit_sends_to_its_own_object_is_said_to_play_there(tmp_path: Path) -> None:
    mid = drum_file(tmp_path / "wb.mid", [76, 76, 77, 36])
    [warning] = read_midi(mid, kit=_woodblock_kit()).warnings
    assert ("is played on the kit's own object for it: pitch 76 (Hi Wood Block, E4) played on woodblock (the kit's "
            "note_objects) x2, pitch 77 (Low Wood Block, F4) played on woodblock (the kit's note_objects) x1;"
            ) in warning
    assert "cowbell" not in warning


def test_the_others_are_still_played_as_the_piece_struck_alike(tmp_path: Path) -> None:
    mid = drum_file(tmp_path / "mixed.mid", [60, 60, 76, 36])
    [warning] = read_midi(mid, kit=_woodblock_kit()).warnings
    assert ("is played on the kit's own object for it, else on the kit piece struck alike: pitch 60 (Hi Bongo, C3) "
            "played as high tom x2, pitch 76 (Hi Wood Block, E4) played on woodblock (the kit's note_objects) x1;"
            ) in warning


def test_without_the_kit_or_on_a_kit_without_the_route_the_warning_is_as_before(tmp_path: Path) -> None:
    mid = drum_file(tmp_path / "wb.mid", [76, 36])
    for kit in (None, load_kit("default")):
        [warning] = read_midi(mid, kit=kit).warnings
        assert ("is played on the kit piece struck alike: pitch 76 (Hi Wood Block, E4) played as cowbell x1;"
                in warning)
