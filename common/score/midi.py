"""Standard MIDI File input (types 0, 1 and 2) with mido.

Tempo changes anywhere in the file are honoured (a type 1 file's conductor
track or inline), running status is handled by mido's parser, and notes are
taken from the drum channels: channel 10 (index 9), any channel whose bank
select MSB is 120 (GM2 rhythm) or 127 (XG drums), and any channel the caller
names. A file that is not a MIDI file, is truncated or is corrupt raises
:class:`ScoreError` naming the file and the problem.
"""

from __future__ import annotations

import io
from collections.abc import Collection, Mapping
from pathlib import Path

import mido
import numpy as np

from common.kit import EventType
from common.score.events import DrumNote, Score, ScoreError, score_from_notes
from common.score.gm import DRUM_MAP

GM_DRUM_CHANNEL = 10
"""General MIDI's percussion channel (1-based)."""

_DRUM_BANKS = {120, 127}


def _open(source: str | Path | bytes) -> tuple[mido.MidiFile, str]:
    name = "<bytes>" if isinstance(source, bytes) else str(source)
    try:
        if isinstance(source, bytes):
            return mido.MidiFile(file=io.BytesIO(source), clip=False), name
        path = Path(source)
        if not path.is_file():
            raise ScoreError(f"{name}: no such file")
        return mido.MidiFile(path, clip=False), name
    except ScoreError:
        raise
    except EOFError as exc:
        raise ScoreError(f"{name}: truncated MIDI file ({str(exc) or 'the data ends early'})") from exc
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        raise ScoreError(f"{name}: not a valid Standard MIDI File ({type(exc).__name__}: {exc})") from exc


def _timeline(mid: mido.MidiFile) -> list[tuple[int, mido.Message | mido.MetaMessage]]:
    """All messages with absolute ticks, in playing order (type 2: tracks one after another)."""
    out: list[tuple[int, mido.Message | mido.MetaMessage]] = []
    if mid.type == 2:
        offset = 0
        for track in mid.tracks:
            tick = offset
            for msg in track:
                tick += msg.time
                out.append((tick, msg))
            offset = tick
        return out
    tick = 0
    for msg in mido.merge_tracks(mid.tracks):
        tick += msg.time
        out.append((tick, msg))
    return out


def read_midi(
    source: str | Path | bytes,
    drum_channels: Collection[int] | None = None,
    drum_map: Mapping[int, EventType] = DRUM_MAP,
) -> Score:
    """Read a Standard MIDI File into a :class:`Score`.

    Parameters
    ----------
    source : str | Path | bytes
        File path or the file's bytes.
    drum_channels : Collection[int] | None
        1-based MIDI channels holding drums, in addition to channel 10 and
        channels switched to a drum bank. When no note is found on any drum
        channel and none were named, every channel is read (with a warning).
    drum_map : Mapping[int, EventType]
        MIDI pitch -> drum event type (default: GM plus the TD-11's 22 and 26).

    Returns
    -------
    Score
        Events in seconds, velocities in [0, 1], beats from the file's own
        ticks-per-beat and tempo map, unknown notes and removed doubles listed.
    """
    mid, name = _open(source)
    if mid.ticks_per_beat <= 0:
        raise ScoreError(f"{name}: SMPTE time division is not supported (ticks per beat {mid.ticks_per_beat})")
    timeline = _timeline(mid)
    tempo = 500000  # microseconds per beat (120 bpm) until told otherwise
    seconds = 0.0
    last_tick = 0
    per_tick = tempo / 1e6 / mid.ticks_per_beat
    drums = {GM_DRUM_CHANNEL - 1} | {c - 1 for c in (drum_channels or ())}
    raw: list[tuple[float, int, int, int]] = []  # seconds, pitch, velocity, channel index
    tempo_points: list[tuple[int, float, float]] = [(0, 0.0, per_tick)]  # tick, seconds, seconds/tick
    for tick, msg in timeline:
        seconds += (tick - last_tick) * per_tick
        last_tick = tick
        if msg.type == "set_tempo":
            per_tick = msg.tempo / 1e6 / mid.ticks_per_beat
            tempo_points.append((tick, seconds, per_tick))
        elif msg.type == "control_change" and msg.control == 0 and msg.value in _DRUM_BANKS:
            drums.add(msg.channel)
        elif msg.type == "note_on" and msg.velocity > 0:
            raw.append((seconds, msg.note, msg.velocity, msg.channel))
    warnings: list[str] = []
    chosen = [r for r in raw if r[3] in drums]
    if not chosen and raw and not drum_channels:
        channels = sorted({r[3] + 1 for r in raw})
        warnings.append(f"{name}: no notes on a drum channel; reading channels {channels} as drums")
        chosen = raw
    notes = [DrumNote(time=s, pitch=p, velocity=v / 127.0, channel=c + 1) for s, p, v, c in chosen]
    beats = _beats(tempo_points, last_tick, mid.ticks_per_beat)
    score = score_from_notes(notes, drum_map=drum_map, beats=beats, source=name)
    score.warnings = warnings + score.warnings
    if not score.events:
        score.warnings.append(f"{name}: no drum events")
    return score


def _beats(tempo_points: list[tuple[int, float, float]], end_tick: int, ticks_per_beat: int) -> np.ndarray:
    """Beat times (seconds) from tick 0 to ``end_tick`` given (tick, seconds, seconds/tick) tempo points."""
    ticks = np.arange(0, end_tick + 1, ticks_per_beat)
    starts = np.array([p[0] for p in tempo_points])
    idx = np.searchsorted(starts, ticks, side="right") - 1
    base_sec = np.array([p[1] for p in tempo_points])[idx]
    rate = np.array([p[2] for p in tempo_points])[idx]
    return np.asarray(base_sec + (ticks - starts[idx]) * rate, dtype=float)
