"""The hi-hat's openness a MIDI file sends as its foot controller (CC4: 0 the pedal up, open .. 127 down, closed),
as e-kits and drum plugins do, with ``--hihat-cc4`` (``hihat_cc4``): a closed hi-hat note with the pedal clearly up
plays open, an open one with the pedal clearly down closed; half open, or before any CC4, the note says. Without
it the notes play as written (a Roland TD-11 chooses open or closed itself), and a file whose hats the pedal would
move is told of the option once."""

from __future__ import annotations

import io
import json
from pathlib import Path

import mido
import pytest

from common.kit import EventType as E
from common.score.midi import read_midi
from common.score.midi_notes import HIHAT_CLOSED_MIN_CC4, HIHAT_OPEN_MAX_CC4

DATA = Path(__file__).resolve().parents[1] / "data"


def pedalled(steps: list[tuple[int | None, int]], channel: int = 9, cc_channel: int | None = None) -> bytes:
    """A type 0 file: for each (CC4 or None, pitch) a CC4 (on ``cc_channel``, default ``channel``) then the note,
    a quarter note apart."""
    track = mido.MidiTrack()
    for k, (cc4, pitch) in enumerate(steps):
        delta = 480 if k else 0
        if cc4 is not None:
            track.append(mido.Message("control_change", control=4, value=cc4, time=delta,
                                      channel=channel if cc_channel is None else cc_channel))
            delta = 0
        track.append(mido.Message("note_on", note=pitch, velocity=90, channel=channel, time=delta))
        track.append(mido.Message("note_off", note=pitch, velocity=0, channel=channel, time=0))
    mid = mido.MidiFile(type=0, ticks_per_beat=480)
    mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    return buf.getvalue()


def events(data: bytes, hihat_cc4: bool = True) -> list[tuple[E, int | None]]:
    return [(e.event, e.pitch) for e in read_midi(data, hihat_cc4=hihat_cc4).events]


def test_a_closed_note_with_the_pedal_up_plays_open() -> None:
    """The walkthrough's cc4_hihat.mid: every 4th closed hi-hat sent with CC4 0 (bow 42 and edge 22)."""
    data = pedalled([(127, 42), (127, 42), (127, 42), (0, 42), (127, 22), (0, 22)])
    assert events(data) == [(E.HIHATCLOSED, 42)] * 3 + [(E.HIHATOPEN, 46), (E.HIHATCLOSED, 22), (E.HIHATOPEN, 26)]
    assert [w for w in read_midi(data, hihat_cc4=True).warnings if "CC4" in w] == [
        "<bytes>: hi-hat pedal (CC4): 2 closed hi-hat notes played open (CC4 at most 31: the pedal up)"]


def test_an_open_note_with_the_pedal_down_plays_closed() -> None:
    data = pedalled([(127, 46), (HIHAT_CLOSED_MIN_CC4, 26), (0, 46)])
    assert events(data) == [(E.HIHATCLOSED, 42), (E.HIHATCLOSED, 22), (E.HIHATOPEN, 46)]
    assert "2 open hi-hat notes played closed (CC4 at least 96: the pedal down)" in read_midi(
        data, hihat_cc4=True).warnings[0]


def test_half_open_or_no_pedal_yet_the_note_says() -> None:
    half = [HIHAT_OPEN_MAX_CC4 + 1, 64, HIHAT_CLOSED_MIN_CC4 - 1]
    data = pedalled([(None, 42), (None, 46), *[(v, 42) for v in half], *[(v, 46) for v in half]])
    assert events(data) == [(E.HIHATCLOSED, 42), (E.HIHATOPEN, 46)] + [(E.HIHATCLOSED, 42)] * 3 + \
        [(E.HIHATOPEN, 46)] * 3
    assert not read_midi(data, hihat_cc4=True).warnings


def test_the_pedal_is_its_channels_and_moves_only_the_hats() -> None:
    """CC4 on channel 2 leaves channel 10's hats alone; the pedal chick (44), a tambourine (54, an open hi-hat
    stand-in) and the snare are not hats a pedal opens."""
    assert events(pedalled([(0, 42)], cc_channel=1)) == [(E.HIHATCLOSED, 42)]
    data = pedalled([(0, 44), (0, 38), (127, 54)])
    assert events(data) == [(E.HIHATPEDAL, 44), (E.SNARE, 38), (E.HIHATOPEN, 54)]


def test_a_note_map_applies_before_the_pedal() -> None:
    """EZdrummer-style closed hats on 25 mapped to 42: then opened by the pedal."""
    assert [(e.event, e.pitch) for e in read_midi(pedalled([(0, 25)]), note_map={25: 42}, hihat_cc4=True).events] == [
        (E.HIHATOPEN, 46)]


@pytest.mark.parametrize("name", ["groove_drummer1_s2_1_latin-chacarera_157_beat_3-4.mid",
                                  "groove_drummer6_s3_1_rock_90_beat_4-4.mid"])
def test_a_td11_recording_plays_as_its_notes_say(name: str) -> None:
    """The Groove MIDI Dataset's TD-11 sends CC4 0 to 90 and chooses open or closed notes itself (some open notes
    come with 90, one closed edge with 48): the thresholds leave its hats as recorded."""
    data = (DATA / name).read_bytes()
    mid = mido.MidiFile(file=io.BytesIO(data))
    assert any(m.type == "control_change" and m.control == 4 for t in mid.tracks for m in t)
    for track in mid.tracks:
        for k, message in enumerate(track):
            if message.type == "control_change" and message.control == 4:
                track[k] = mido.MetaMessage("text", text="", time=message.time)  # the same timing, no CC4
    buf = io.BytesIO()
    mid.save(file=buf)
    assert events(data) == events(buf.getvalue())
    assert not [w for w in read_midi(data, hihat_cc4=True).warnings if "CC4" in w]


def test_by_default_the_notes_play_as_written_and_the_option_is_told_once() -> None:
    """The walkthrough's cc4_hihat.mid read without ``--hihat-cc4``: its closed hats stay closed, and one warning
    says the file sends CC4 and what the option does."""
    data = pedalled([(127, 42), (127, 42), (127, 42), (0, 42), (127, 22), (0, 22)])
    assert events(data, hihat_cc4=False) == [(E.HIHATCLOSED, 42)] * 4 + [(E.HIHATCLOSED, 22)] * 2
    assert [w for w in read_midi(data).warnings if "CC4" in w] == [
        "<bytes>: sends the hi-hat pedal (CC4), not applied: 2 of its 6 closed hi-hat notes would play open with "
        "--hihat-cc4 (a closed note with CC4 at most 31, the pedal up, plays open; an open one with at least 96 "
        "closed)"]
    assert "1 of its 2 open hi-hat notes would play closed" in read_midi(pedalled([(127, 46), (64, 46)])).warnings[0]
    for quiet in ([(0, 38), (0, 36)], [(64, 42), (127, 42)], [(0, 46)]):  # no hats, or none the pedal would move
        assert not [w for w in read_midi(pedalled(quiet)).warnings if "CC4" in w]
    assert not [w for w in read_midi(pedalled([(0, 42)], cc_channel=1)).warnings if "CC4" in w]  # another's pedal


def test_a_td11_closed_note_with_the_pedal_up_stays_closed_by_default() -> None:
    """The Groove MIDI Dataset's drummer8/session1/16_afrobeat_90_beat_4-4.mid (a Roland TD-11) around 6 s: an open
    edge (26) with CC4 90, then the pedal chick (44), a rim (40) and a closed hat (42) with CC4 16. Its notes say
    open and closed, so the option is not advised; with it the closed hat would open (95 of the dataset's 1,021
    files read differently so)."""
    data = pedalled([(90, 26), (16, 44), (None, 40), (None, 42)])
    assert events(data, hihat_cc4=False) == [(E.HIHATOPEN, 26), (E.HIHATPEDAL, 44), (E.SNARE, 40),
                                             (E.HIHATCLOSED, 42)]
    assert not [w for w in read_midi(data).warnings if "CC4" in w]
    assert events(data)[-1] == (E.HIHATOPEN, 46)  # what --hihat-cc4 makes of it


def test_the_option_reaches_the_reader_and_a_render_records_it(tmp_path: Path) -> None:
    """``--hihat-cc4`` in the shared MIDI options, off unless given; report.json's ``hihat_cc4`` read back by
    ``batteur evaluate DIR`` (and a render's reuse) as the score was rendered."""
    import argparse

    from batteur import evaluate, render
    from common.score.midi_options import add_midi_arguments, midi_read_kwargs

    parser = argparse.ArgumentParser()
    add_midi_arguments(parser)
    assert midi_read_kwargs(parser.parse_args([])) == {}
    assert midi_read_kwargs(parser.parse_args(["--hihat-cc4"])) == {"hihat_cc4": True}
    opts = render.options_from(render.build_parser().parse_args(["x.mid", "-o", str(tmp_path), "--hihat-cc4"]))
    assert opts.midi == {"hihat_cc4": True}
    where = tmp_path / "report.json"
    assert evaluate.report_midi_kwargs({"hihat_cc4": True}, where) == {"hihat_cc4": True}
    assert evaluate.report_midi_kwargs({"hihat_cc4": False}, where) == {}
    assert evaluate.report_midi_kwargs({}, where) == {}
    with pytest.raises(ValueError, match="hihat_cc4 must be true or false"):
        evaluate.report_midi_kwargs({"hihat_cc4": "yes"}, where)
    score = tmp_path / "hats.mid"
    score.write_bytes(pedalled([(0, 42)]))
    for name, pedal in (("pedal", True), ("written", False), ("before", None)):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "score.mid").write_bytes(score.read_bytes())
        report = {"kit": "default", "grip": "german", "nuance": "tenuto", "tempo_scale": 1.0, "control": "cartesian",
                  "drum_channels": None, "drum_map": None, "calibration": None}
        (folder / "report.json").write_text(json.dumps(report if pedal is None else {**report, "hihat_cc4": pedal}))
    with_pedal = render.RenderOptions(midi={"hihat_cc4": True})
    assert evaluate.reusable(tmp_path / "pedal", score, with_pedal)
    assert not evaluate.reusable(tmp_path / "pedal", score, render.RenderOptions())
    assert not evaluate.reusable(tmp_path / "written", score, with_pedal)
    assert evaluate.reusable(tmp_path / "written", score, render.RenderOptions())
    assert evaluate.reusable(tmp_path / "before", score, render.RenderOptions())  # a render before the option
