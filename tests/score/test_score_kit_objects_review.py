"""What a review of text scores naming kit objects (tests/score/test_score_kit_objects.py) found, fixed the day after
7 Dec: a ``kit`` line whose kit cannot be loaded was reported as an unknown instrument only; an object reached only
by ``note_objects`` pitches of two event types was called ambiguous ("name the stroke", where naming either stroke
plays another object); an object id an alias shadows was listed as nameable; doubles were merged by event and pitch
in text, by event alone in MIDI files and live notes (one rule now: same object, same stroke)."""

from __future__ import annotations

from pathlib import Path

import mido
import pytest
import yaml

from common.kit import KITS_DIR, EventType, Kit, load_kit
from common.messages.score import LiveNote
from common.score.events import ScoreError
from common.score.live import LiveNotes
from common.score.midi import read_midi
from common.score.text import parse_text, read_score

E = EventType


def _kit(folder: Path, name: str, objects: list[dict[str, object]], note_objects: dict[int, str]) -> Kit:
    """The default kit with ``objects`` added and ``note_objects``, saved in ``folder`` and loaded."""
    data = yaml.safe_load((KITS_DIR / "default.yaml").read_text(encoding="utf-8"))
    data["name"] = name
    data["objects"].extend(objects)
    data["note_objects"] = note_objects
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return load_kit(path, warn=False)


CYMBAL = {"id": "fx", "kind": "cymbal", "position": [0.3, 0.5, 1.2], "rotation_deg": [0, 0, 0], "radius": 0.2,
          "thickness": 0.002, "elasticity": 0.5}
TOM = {"id": "ft", "kind": "membrane", "position": [0.5, 0.12, 0.58], "rotation_deg": [5, 0, 0], "radius": 0.2,
       "depth": 0.4, "elasticity": 0.6}


def test_a_kit_line_that_cannot_be_loaded_says_so_beside_the_unknown_name() -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text("crash2 |x.|\nkit nosuchkit\n")
    message = str(refused.value)
    assert message.startswith("line 1: unknown instrument 'crash2'")
    assert message.endswith("; line 2: kit 'nosuchkit', whose objects a row may name, cannot be loaded: no kit file "
                            "'nosuchkit' (shipped kits: default, double_pedal, left_handed)")
    parse_text("SN |x.|\nkit nosuchkit\n")  # no object id named: the kit is not loaded (the kit's users say it)


def test_an_object_reached_only_by_pitches_of_two_events_plays_its_first_pitch(tmp_path: Path) -> None:
    kit = _kit(tmp_path, "fx_kit", [CYMBAL], {57: "fx", 52: "fx"})
    score = parse_text("fx |x.|\nat 1 FX\n", kit=kit)
    assert [(e.event, e.pitch) for e in score.events] == [(E.CHINA, 52), (E.CHINA, 52)]  # 52 Chinese Cymbal
    assert {kit.object_for(e.event, e.pitch).id for e in score.events} == {"fx"}
    with pytest.raises(ScoreError) as refused:
        parse_text("zz |x.|\n", kit=kit)
    assert "fx is struck by" not in str(refused.value) and ", fx (hihat is struck by HIHATCLOSED or HIHATOPEN: name " \
        "the stroke))" in str(refused.value)  # listed as nameable; only the hi-hat needs a stroke's name
    with pytest.raises(ScoreError, match="hihat is struck by HIHATCLOSED or HIHATOPEN: name the stroke"):
        parse_text("hihat |x.|\n", kit=kit)  # its own object's two strokes stay ambiguous


def test_an_object_id_an_alias_shadows_is_not_listed_as_nameable(tmp_path: Path) -> None:
    kit = _kit(tmp_path, "alias_kit", [TOM], {41: "ft"})
    score = parse_text("ft |x.|\n", kit=kit)
    assert [kit.object_for(e.event, e.pitch).id for e in score.events] == ["floortom"]  # FT, the alias
    with pytest.raises(ScoreError) as refused:
        parse_text("zz |x.|\n", kit=kit)
    message = str(refused.value)
    assert "cowbell, kick_pedal, hihat_pedal (hihat" in message and ", ft" not in message
    assert message.endswith("; a row 'ft' plays FLOORTOM (on floortom): a score cannot name the object ft (give it "
                            "another id in the kit))")


def _midi(path: Path, pitches: list[int]) -> Path:
    """A one-track drum file striking ``pitches`` together at tick 0."""
    mid = mido.MidiFile(ticks_per_beat=480)
    track = mido.MidiTrack()
    mid.tracks.append(track)
    for pitch in pitches:
        track.append(mido.Message("note_on", channel=9, note=pitch, velocity=100, time=0))
    for k, pitch in enumerate(pitches):
        track.append(mido.Message("note_off", channel=9, note=pitch, velocity=0, time=240 if k == 0 else 0))
    mid.save(path)
    return path


def test_doubles_are_one_object_s_in_midi_files_text_and_live_notes(tmp_path: Path) -> None:
    """49 and 57 at once: two crashes on double_pedal (57 sends CRASH to crash2), one on the default kit or without
    a kit; 42 and 22 (the TD-11's closed hi-hat) stay one on every kit, as the Groove files merge them."""
    double, default = load_kit("double_pedal", warn=False), load_kit("default", warn=False)
    crashes = _midi(tmp_path / "crashes.mid", [49, 57])
    assert [(e.event, e.pitch) for e in read_midi(crashes, kit=double).events] == [(E.CRASH, 49), (E.CRASH, 57)]
    assert len(read_score(crashes, kit=double).events) == 2  # read_score hands the kit to the MIDI reader
    for kit in (None, default):
        read = read_midi(crashes, kit=kit)
        assert [(e.event, e.pitch) for e in read.events] == [(E.CRASH, 49)] and len(read.duplicates) == 1
    hats = _midi(tmp_path / "hats.mid", [42, 22])
    for kit in (None, default, double):
        assert len(read_midi(hats, kit=kit).events) == 1
    # text, the same rule: CR and crash are one crash, crash2 twice one crash2 (the louder kept)
    score = parse_text("kit double_pedal\nCR |x.|\ncrash2 |x.|\ncrash |x.|\nCrash2 |X.|\n")
    assert [(e.event, e.pitch, e.velocity) for e in score.events] == [(E.CRASH, None, 0.7), (E.CRASH, 57, 1.0)]
    assert len(score.duplicates) == 2
    # live notes: the same rule with the kit, event types without one (as before)
    for kit, expected in ((double, [True, True, False]), (default, [True, False, False]), (None, [True, False, False])):
        live = LiveNotes(kit=kit)
        got = [live.accept(LiveNote(time=1.0, pitch=p, velocity=100, channel=10)) is not None for p in (49, 57, 57)]
        assert got == expected and live.duplicates == expected.count(False)
    live = LiveNotes(kit=double)
    assert [live.accept(LiveNote(time=1.0, pitch=p, velocity=100, channel=10)) is not None for p in (42, 22)] == [
        True, False]
