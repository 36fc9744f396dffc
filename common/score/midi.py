"""Standard MIDI File input (types 0, 1 and 2) with mido.

Tempo changes anywhere in the file are honoured (a type 1 file's conductor
track or inline), running status is handled by mido's parser, and notes are
taken from the drum channels: channel 10 (index 9), any channel whose bank
select MSB is 120 (GM2 rhythm) or 127 (XG drums), and any channel the caller
names. A RIFF MIDI file (``.rmi``: a Standard MIDI File in a RIFF ``RMID`` form's ``data`` chunk) is read as the
file it wraps. A key signature mido cannot decode is ignored with a warning (a drum score has no key). A file that
is not a MIDI file, is truncated or is corrupt raises :class:`ScoreError` naming the file and the problem.

A long file takes seconds: 200,184 notes (2 MB) about 3 s, mido's parser most of it. ``read_midi(...,
progress=)`` is told how many of the file's bytes mido has parsed as it goes.
"""

from __future__ import annotations

import io
import math
import struct
import threading
from collections.abc import Callable, Collection, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import mido
import numpy as np
from mido.midifiles.meta import KeySignatureError, MetaSpec_key_signature, add_meta_spec

from common.gcpause import cyclic_gc_paused
from common.kit import EventType
from common.score.events import (
    MAX_SCORE_BARS,
    MAX_SCORE_BYTES,
    MAX_SCORE_NOTES,
    MAX_SCORE_SECONDS,
    DrumNote,
    Score,
    ScoreError,
    check_file,
    check_not_audio,
    hours,
    looks_like_text,
    score_from_notes,
)
from common.score.gm import DRUM_MAP
from common.score.gm_programs import GM_PROGRAM_NAMES

GM_DRUM_CHANNEL = 10
"""General MIDI's percussion channel (1-based)."""

_DRUM_BANKS = {120, 127}
MAX_BEATS = int(MAX_SCORE_SECONDS * 400 / 60)
"""The most beats kept: a whole day at 400 bpm, the fastest tempo of a text score."""
MAX_DENOMINATOR = 256
"""The largest time signature denominator read: a 256th note (the file stores its power of two, so a corrupt
byte makes a bar of 2^-255 beats); a larger one is ignored."""
REPORT_EVERY_MESSAGES = 4096
"""Messages mido parses between two progress reports: some 20 ms of parsing, a hundred reports for 2 MB."""

DEFAULT_TEMPO = 500_000
"""Microseconds per beat (a quarter note) until a file sets its tempo: 120 bpm, as the MIDI specification says."""
TEXT_SAMPLE_BYTES = 4096
"""How much of a file named as MIDI is looked at to tell a text score given that name."""

ReadProgress = Callable[[int, int], None]
"""Told (bytes parsed, bytes in the file) while a MIDI file is read."""
RIFF_MIDI_FORM = b"RMID"
"""The form type of a RIFF MIDI file (``.rmi``), whose ``data`` chunk holds a Standard MIDI File."""


class _TolerantKeySignature(MetaSpec_key_signature):
    """mido's key signature, which in a thread reading a score (:func:`_noting_bad_keys`) notes a key it cannot
    decode and leaves the message at mido's default key instead of refusing the whole file.

    mido has no option to skip a bad message (mido issue #187); a meta spec registered with ``add_meta_spec`` (its
    documented way to define meta messages) is what it offers. Every other thread, and this one outside a score
    reading, gets mido's own behaviour: its ``KeySignatureError``."""

    type = "key_signature"
    _reading = threading.local()

    def decode(self, message: Any, data: Any) -> None:
        try:
            super().decode(message, data)
        except (KeySignatureError, IndexError) as exc:  # IndexError: fewer than the key's two bytes
            problems: list[str] | None = getattr(self._reading, "problems", None)
            if problems is None:
                raise
            problems.append(str(exc) if isinstance(exc, KeySignatureError) else
                            f"{len(data)} byte{'s' * (len(data) != 1)} of the 2 a key signature holds")


add_meta_spec(_TolerantKeySignature)


@contextmanager
def _noting_bad_keys() -> Iterator[list[str]]:
    """While mido parses in this thread, a key signature it cannot decode is listed (why) instead of raised."""
    problems: list[str] = []
    _TolerantKeySignature._reading.problems = problems
    try:
        yield problems
    finally:
        _TolerantKeySignature._reading.problems = None


class _ReportingBytes(io.BytesIO):
    """The file's bytes for mido, telling ``progress`` how far its parser has come: mido asks for the position once a
    message (``tell``, to find the track's end), so a report every ``REPORT_EVERY_MESSAGES`` of those costs one
    counter (about 5 % of the reading) and no change to what is parsed."""

    def __init__(self, data: bytes, progress: ReadProgress) -> None:
        super().__init__(data)
        self._progress = progress
        self._size = len(data)
        self._asked = 0

    def tell(self) -> int:
        position = super().tell()
        self._asked += 1
        if self._asked >= REPORT_EVERY_MESSAGES:
            self._asked = 0
            self._progress(position, self._size)
        return position


def _open(source: str | Path | bytes,
          progress: ReadProgress | None = None) -> tuple[mido.MidiFile, str, int, list[str]]:
    """The parsed file, its name for messages, its size in bytes (of the Standard MIDI File) and warnings;
    :class:`ScoreError` if it cannot be."""
    name = "<bytes>" if isinstance(source, bytes) else str(source)
    if isinstance(source, bytes):
        data = source
    else:
        check_file(Path(source), name)
        try:
            data = Path(source).read_bytes()
        except OSError as exc:  # not "not a valid MIDI file": the file could not be read at all
            raise ScoreError(f"{name}: cannot read the file ({exc.strerror or exc})") from None
    if len(data) > MAX_SCORE_BYTES:
        raise ScoreError(f"{name}: {len(data) / 2**20:.0f} MB is too large for a score (at most "
                         f"{MAX_SCORE_BYTES // 2**20} MB)")
    if not data:  # mido's EOFError would read "truncated MIDI file"
        raise ScoreError(f"{name}: the file is empty (0 bytes), not a MIDI file")
    if data[:4] not in (b"MThd", b"RIFF") and looks_like_text(data[:TEXT_SAMPLE_BYTES]):  # was "MThd not found"
        raise ScoreError(f"{name}: this looks like a text score, not a MIDI file; rename it .txt "
                         f"(a .mid name is read as MIDI whatever it holds)")
    check_not_audio(data[:12], name)
    data = _without_alien_chunks(_unwrapped_riff(data, name))
    if progress is not None:
        progress(0, len(data))
    stream = io.BytesIO(data) if progress is None else _ReportingBytes(data, progress)
    try:
        with _noting_bad_keys() as bad_keys:
            mid = mido.MidiFile(file=stream, clip=False)
    except EOFError as exc:
        raise ScoreError(f"{name}: truncated MIDI file ({str(exc) or 'the data ends early'})") from exc
    except (OSError, ValueError, KeyError, IndexError, TypeError, KeySignatureError) as exc:
        # KeySignatureError (no ValueError) only if another module replaced the tolerant key signature spec
        # mido's words without Python's class name ("OSError: MThd not found ..." said nothing to a user)
        raise ScoreError(f"{name}: not a valid Standard MIDI File ({str(exc) or type(exc).__name__})") from exc
    warnings = []
    if bad_keys:
        count = f"{len(bad_keys)} key signatures" if len(bad_keys) > 1 else "a key signature"
        warnings.append(f"{name}: {count} that cannot be read ignored (a drum score needs no key; "
                        f"{bad_keys[0]})")
    return mid, name, len(data), warnings


def _unwrapped_riff(data: bytes, name: str) -> bytes:
    """The Standard MIDI File a RIFF MIDI file (``RIFF`` size ``RMID``, then chunks) holds in its ``data`` chunk;
    any other bytes as they are. A RIFF file of another form (a WAV) or a broken one raises :class:`ScoreError`.

    The RIFF size is not trusted (writers get it wrong); the chunks are followed to the first ``data`` one, each
    a 4-byte type, a little-endian 32-bit size and its bytes, padded to an even length."""
    if data[:4] != b"RIFF":
        return data
    if len(data) < 12:
        raise ScoreError(f"{name}: truncated RIFF file ({len(data)} bytes, shorter than its 12-byte header)")
    form = data[8:12]
    if form != RIFF_MIDI_FORM:
        raise ScoreError(f"{name}: not a valid Standard MIDI File (a RIFF {form.decode('latin-1')!r} file, not "
                         f"RIFF MIDI {RIFF_MIDI_FORM.decode()!r})")
    offset = 12
    while offset + 8 <= len(data):
        kind, size = data[offset : offset + 4], struct.unpack("<I", data[offset + 4 : offset + 8])[0]
        start = offset + 8
        if kind == b"data":
            if start + size > len(data):
                raise ScoreError(f"{name}: truncated RIFF MIDI file (its 'data' chunk holds {size} bytes, "
                                 f"{len(data) - start} are in the file)")
            return data[start : start + size]
        offset = start + size + size % 2
    if offset < len(data):  # a chunk header cut short
        raise ScoreError(f"{name}: truncated RIFF MIDI file (a chunk header at byte {offset} is cut short)")
    raise ScoreError(f"{name}: RIFF MIDI file without a 'data' chunk (the Standard MIDI File it should hold)")


def _without_alien_chunks(data: bytes) -> bytes:
    """The file without chunks other than ``MThd`` and ``MTrk`` among its tracks: the Standard MIDI File
    specification tells readers to skip such "alien" chunks (Yamaha's XF files have some), and mido reads
    whatever chunk follows a track as the next track. A file without any comes back as it is, and so does one
    whose chunks cannot be followed (mido then names the problem)."""
    if data[:4] != b"MThd" or len(data) < 14:
        return data
    tracks = int.from_bytes(data[10:12], "big")
    offset = 8 + int.from_bytes(data[4:8], "big")
    kept = [data[:offset]]
    alien = False
    while tracks > 0 and offset + 8 <= len(data):
        name, end = data[offset : offset + 4], offset + 8 + int.from_bytes(data[offset + 4 : offset + 8], "big")
        if name == b"MTrk":
            kept.append(data[offset:end])
            tracks -= 1
        elif all(0x20 <= c < 0x7F for c in name) and end <= len(data):  # a chunk type is four ASCII letters
            alien = True
        else:
            return data
        offset = end
    return b"".join(kept) + data[offset:] if alien else data


def _timeline(mid: mido.MidiFile) -> tuple[list[tuple[int, mido.Message | mido.MetaMessage]], int]:
    """All messages with absolute ticks, in playing order (type 2: tracks one after another), and the end tick.

    Types 0 and 1: every track's messages sorted by tick (ties in track order) without their end-of-track
    markers, as ``mido.merge_tracks`` gives them, but without its two copies of every message (a million
    notes took 80 s and a gigabyte more).

    Type 2: each track is a sequence of its own, starting where the one before ended, at 120 bpm and in 4/4 (a
    tempo and a time signature put where it starts) unless it sets its own, as a file's start is: a track
    without a tempo played at the one the track before it left.
    """
    out: list[tuple[int, mido.Message | mido.MetaMessage]] = []
    if mid.type == 2:
        offset = 0
        for k, track in enumerate(mid.tracks):
            tick = offset
            if k:  # tick 0 already starts at them; its own at its tick 0 come after these, and win
                out.append((tick, mido.MetaMessage("set_tempo", tempo=DEFAULT_TEMPO)))
                out.append((tick, mido.MetaMessage("time_signature", numerator=4, denominator=4)))
            for msg in track:
                tick += msg.time
                out.append((tick, msg))
            offset = tick
        return out, (out[-1][0] if out else 0)
    end = 0
    for track in mid.tracks:
        tick = 0
        for msg in track:
            tick += msg.time
            if msg.type != "end_of_track":
                out.append((tick, msg))
        end = max(end, tick)
    out.sort(key=lambda tm: tm[0])
    return out, end


def read_midi(
    source: str | Path | bytes,
    drum_channels: Collection[int] | None = None,
    drum_map: Mapping[int, EventType] = DRUM_MAP,
    progress: ReadProgress | None = None,
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
    progress : Callable[[int, int], None] | None
        Called with (bytes parsed, bytes in the file): ``(0, size)`` once the file is read from disk, then every
        ``REPORT_EVERY_MESSAGES`` messages mido parses, and ``(size, size)`` when the score is complete (the notes
        are turned into events after the parse: a fifth to a quarter of the time). Whatever it raises
        (``KeyboardInterrupt``) stops the reading. The score is the same with or without it.

    Returns
    -------
    Score
        Events in seconds, velocities in [0, 1], beats from the file's own
        ticks-per-beat and tempo map, unknown notes and removed doubles listed.
    """
    with cyclic_gc_paused():
        score, size = _read(source, drum_channels, drum_map, progress)
    if progress is not None:
        progress(size, size)
    return score


def _read(source: str | Path | bytes, drum_channels: Collection[int] | None, drum_map: Mapping[int, EventType],
          progress: ReadProgress | None) -> tuple[Score, int]:
    """:func:`read_midi`'s work; also returns the file's size in bytes."""
    mid, name, size, open_warnings = _open(source, progress)
    if mid.ticks_per_beat < 0:  # the division's top bit: frames a second and ticks a frame
        raise ScoreError(f"{name}: SMPTE time division ({-(mid.ticks_per_beat >> 8)} frames a second, "
                         f"{mid.ticks_per_beat & 0xFF} ticks a frame) is not supported; save it with ticks per beat")
    if mid.ticks_per_beat == 0:
        raise ScoreError(f"{name}: 0 ticks per beat in the header (a corrupt file?)")
    timeline, end_tick = _timeline(mid)
    tempo = DEFAULT_TEMPO  # until told otherwise
    seconds = 0.0
    last_tick = 0
    per_tick = tempo / 1e6 / mid.ticks_per_beat
    drums = {GM_DRUM_CHANNEL - 1} | {c - 1 for c in (drum_channels or ())}
    raw: list[tuple[float, int, int, int, int]] = []  # seconds, pitch, velocity, channel index, tick
    programs: dict[int, list[int]] = {}  # channel index -> its General MIDI programs, as first set
    tempo_points: list[tuple[int, float, float]] = [(0, 0.0, per_tick)]  # tick, seconds, seconds/tick
    meters: list[tuple[int, int, int]] = [(0, 4, 4)]  # tick, numerator, denominator (4/4 until told otherwise)
    for tick, msg in timeline:
        seconds += (tick - last_tick) * per_tick
        last_tick = tick
        if msg.type == "set_tempo":
            if msg.tempo <= 0:  # every later note would sound at once, each reported as a double of the first
                raise ScoreError(f"{name}: tempo 0 at tick {tick} (a tempo is microseconds per beat, at least 1)")
            per_tick = msg.tempo / 1e6 / mid.ticks_per_beat
            tempo_points.append((tick, seconds, per_tick))
        elif msg.type == "time_signature" and msg.numerator > 0 and 0 < msg.denominator <= MAX_DENOMINATOR:
            # 0/x has no bars; x/2^40 (a corrupt byte) had bars of 1e-11 beats, half a million of them
            meters.append((tick, msg.numerator, msg.denominator))
        elif msg.type == "control_change" and msg.control == 0 and msg.value in _DRUM_BANKS:
            drums.add(msg.channel)
        elif msg.type == "note_on" and msg.velocity > 0:
            raw.append((seconds, msg.note, msg.velocity, msg.channel, tick))
        elif msg.type == "program_change" and msg.program not in programs.setdefault(msg.channel, []):
            programs[msg.channel].append(msg.program)
    warnings = open_warnings
    chosen = [r for r in raw if r[3] in drums]
    if not chosen and raw and not drum_channels:
        channels = sorted({r[3] for r in raw})
        warnings.append(f"{name}: no notes on a drum channel; reading channels {[c + 1 for c in channels]}"
                        f"{_instruments(channels, programs)} as drums")
        chosen = raw
    _check_size(chosen, name)
    notes = [DrumNote(time=s, pitch=p, velocity=v / 127.0, channel=c + 1) for s, p, v, c, _ in chosen]
    beats = _beats(tempo_points, end_tick, mid.ticks_per_beat)
    score = score_from_notes(notes, drum_map=drum_map, beats=beats, source=name,
                             bar_beats=_bar_beats(meters, end_tick, mid.ticks_per_beat))
    score.end_beat = end_tick / mid.ticks_per_beat
    score.warnings = warnings + score.warnings
    if not score.events:
        score.warnings.append(f"{name}: no drum events")
    return score, size


def _instruments(channels: list[int], programs: dict[int, list[int]]) -> str:
    """`` (Violin)`` for one channel (0-based) read as drums that set a General MIDI program, `` (3: Violin;
    5: Flute, Piccolo)`` for several (each channel's programs in the order it set them): a melody file read as
    drums says what it is; "" when none set one."""
    named = {c: ", ".join(GM_PROGRAM_NAMES[p] for p in programs[c]) for c in channels if programs.get(c)}
    if not named:
        return ""
    if len(channels) == 1:
        return f" ({named[channels[0]]})"
    return " (" + "; ".join(f"{c + 1}: {names}" for c, names in named.items()) + ")"


def _check_size(notes: list[tuple[float, int, int, int, int]], name: str) -> None:
    """Refuse more notes than a score may hold, or a note later than a score may last (a corrupt delta time)."""
    if len(notes) > MAX_SCORE_NOTES:
        raise ScoreError(f"{name}: {len(notes)} notes, more than the {MAX_SCORE_NOTES} a score may hold")
    late = next((n for n in notes if n[0] > MAX_SCORE_SECONDS), None)
    if late is not None:
        raise ScoreError(f"{name}: a note at tick {late[4]} sounds {hours(late[0])} in, later than the "
                         f"{hours(MAX_SCORE_SECONDS)} a score may last (a corrupt delta time or tempo?)")


def _bar_beats(meters: list[tuple[int, int, int]], end_tick: int, ticks_per_beat: int) -> np.ndarray:
    """Where bars start (beats from tick 0) given (tick, numerator, denominator) time signatures in tick order: a
    signature starts a bar where it stands (the one before is cut short there). The last start is where the bar
    holding ``end_tick`` ends, so that bars past the file's end go on as long as its last signature's
    (:func:`common.score.position.bar_beat` counts on from the last two starts; the file usually ends inside a bar,
    whose part before the end made them a beat or so long). At most :data:`MAX_SCORE_BARS`."""
    starts: list[np.ndarray] = []
    count = 0
    for k, (tick, numerator, denominator) in enumerate(meters):
        last = k + 1 == len(meters)
        until = end_tick if last else meters[k + 1][0]
        if until <= tick and not last:  # replaced at the same tick
            continue
        bar_ticks = numerator * ticks_per_beat * 4 / denominator
        whole = math.floor((until - tick) / bar_ticks) + 2 if last else math.ceil((until - tick) / bar_ticks)
        n = min(whole, MAX_SCORE_BARS - count)
        starts.append(tick + bar_ticks * np.arange(max(n, 0)))
        count += max(n, 0)
    return np.concatenate(starts) / ticks_per_beat if starts else np.zeros(0)


def _beats(tempo_points: list[tuple[int, float, float]], end_tick: int, ticks_per_beat: int) -> np.ndarray:
    """Beat times (seconds) from tick 0 to ``end_tick`` given (tick, seconds, seconds/tick) tempo points.

    At most ``MAX_BEATS``: a file's end can lie far beyond its notes (2^28 ticks of silence made a terabyte
    array); the beats past its last note only nod the head, and no plan reaches that far.
    """
    ticks = np.arange(0, min(end_tick, (MAX_BEATS - 1) * ticks_per_beat) + 1, ticks_per_beat)
    starts = np.array([p[0] for p in tempo_points])
    idx = np.searchsorted(starts, ticks, side="right") - 1
    base_sec = np.array([p[1] for p in tempo_points])[idx]
    rate = np.array([p[2] for p in tempo_points])[idx]
    return np.asarray(base_sec + (ticks - starts[idx]) * rate, dtype=float)
