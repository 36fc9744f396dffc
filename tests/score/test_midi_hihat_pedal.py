"""The hi-hat's openness a MIDI file sends as its foot controller (CC4: 0 the pedal up, open .. 127 down, closed),
as e-kits and drum plugins do: a closed hi-hat note with the pedal clearly up plays open, an open one with the
pedal clearly down closed; half open, or before any CC4, the note says."""

from __future__ import annotations

import io
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


def events(data: bytes) -> list[tuple[E, int | None]]:
    return [(e.event, e.pitch) for e in read_midi(data).events]


def test_a_closed_note_with_the_pedal_up_plays_open() -> None:
    """The walkthrough's cc4_hihat.mid: every 4th closed hi-hat sent with CC4 0 (bow 42 and edge 22)."""
    data = pedalled([(127, 42), (127, 42), (127, 42), (0, 42), (127, 22), (0, 22)])
    assert events(data) == [(E.HIHATCLOSED, 42)] * 3 + [(E.HIHATOPEN, 46), (E.HIHATCLOSED, 22), (E.HIHATOPEN, 26)]
    assert [w for w in read_midi(data).warnings if "CC4" in w] == [
        "<bytes>: hi-hat pedal (CC4): 2 closed hi-hat notes played open (CC4 at most 31: the pedal up)"]


def test_an_open_note_with_the_pedal_down_plays_closed() -> None:
    data = pedalled([(127, 46), (HIHAT_CLOSED_MIN_CC4, 26), (0, 46)])
    assert events(data) == [(E.HIHATCLOSED, 42), (E.HIHATCLOSED, 22), (E.HIHATOPEN, 46)]
    assert "2 open hi-hat notes played closed (CC4 at least 96: the pedal down)" in read_midi(data).warnings[0]


def test_half_open_or_no_pedal_yet_the_note_says() -> None:
    half = [HIHAT_OPEN_MAX_CC4 + 1, 64, HIHAT_CLOSED_MIN_CC4 - 1]
    data = pedalled([(None, 42), (None, 46), *[(v, 42) for v in half], *[(v, 46) for v in half]])
    assert events(data) == [(E.HIHATCLOSED, 42), (E.HIHATOPEN, 46)] + [(E.HIHATCLOSED, 42)] * 3 + \
        [(E.HIHATOPEN, 46)] * 3
    assert not read_midi(data).warnings


def test_the_pedal_is_its_channels_and_moves_only_the_hats() -> None:
    """CC4 on channel 2 leaves channel 10's hats alone; the pedal chick (44), a tambourine (54, an open hi-hat
    stand-in) and the snare are not hats a pedal opens."""
    assert events(pedalled([(0, 42)], cc_channel=1)) == [(E.HIHATCLOSED, 42)]
    data = pedalled([(0, 44), (0, 38), (127, 54)])
    assert events(data) == [(E.HIHATPEDAL, 44), (E.SNARE, 38), (E.HIHATOPEN, 54)]


def test_a_note_map_applies_before_the_pedal() -> None:
    """EZdrummer-style closed hats on 25 mapped to 42: then opened by the pedal."""
    assert [(e.event, e.pitch) for e in read_midi(pedalled([(0, 25)]), note_map={25: 42}).events] == [
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
    assert not [w for w in read_midi(data).warnings if "CC4" in w]
