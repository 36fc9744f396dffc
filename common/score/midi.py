"""Standard MIDI File input (types 0, 1 and 2) with mido.

Tempo changes anywhere in the file are honoured (a type 1 file's conductor
track or inline), running status is handled by mido's parser, and notes are
taken from the drum channels: channel 10 (index 9) and any channel whose bank
select MSB is 120 (GM2 rhythm) or 127 (XG drums), or the channels the caller
names instead. A RIFF MIDI file (``.rmi``: a Standard MIDI File in a RIFF ``RMID`` form's ``data`` chunk) is read as the
file it wraps. A key signature mido cannot decode is ignored with a warning (a drum score has no key). A file that
is not a MIDI file, is truncated or is corrupt raises :class:`ScoreError` naming the file and the problem.

A long file takes seconds: 200,184 notes (2 MB) about 3 s, mido's parser most of it. ``read_midi(...,
progress=)`` is told how many of the file's bytes mido has parsed as it goes.
"""

from __future__ import annotations

import io
import math
import re
import struct
import threading
from collections import Counter
from collections.abc import Callable, Collection, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import mido
import numpy as np
from mido.midifiles.meta import KeySignatureError, MetaSpec_key_signature, add_meta_spec

from common.gcpause import cyclic_gc_paused
from common.kit import EventType, Kit
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
from common.score.midi_notes import HiHatPedal

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
PLAUSIBLE_TEMPO_BPM = (20.0, 400.0)
"""A tempo a file sets outside this range (bpm) is read as it is but warned of, with how long the file then lasts
(:func:`_tempo_warning`): a set_tempo of 1 microsecond a beat (60,000,000 bpm) played a file in 3 ms, said only as
its notes merged as doubles."""
TEXT_SAMPLE_BYTES = 4096
"""How much of a file named as MIDI is looked at to tell a text score given that name."""

_RawNote = tuple[float, int, int, int, int, int]
"""A note read: seconds, the General MIDI pitch it plays (note map and hi-hat pedal applied), velocity, channel
index (0-based), tick, and its pitch as the file writes it."""

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
    note_map: Mapping[int, int] | None = None,
    hihat_cc4: bool = False,
    kit: Kit | None = None,
) -> Score:
    """Read a Standard MIDI File into a :class:`Score`.

    Parameters
    ----------
    source : str | Path | bytes
        File path or the file's bytes.
    drum_channels : Collection[int] | None
        1-based MIDI channels holding drums (``--drum-channels``): those and no
        other. None: channel 10 and channels switched to a drum bank, notes
        elsewhere skipped with a warning; when none is on them, every channel
        but melodic ones beside others (with a warning: :func:`_chosen_notes`);
        when every channel with notes is melodic, :class:`ScoreError` (no drums).
    drum_map : Mapping[int, EventType]
        MIDI pitch -> drum event type (default: GM plus the TD-11's 22 and 26).
    progress : Callable[[int, int], None] | None
        Called with (bytes parsed, bytes in the file): ``(0, size)`` once the file is read from disk, then every
        ``REPORT_EVERY_MESSAGES`` messages mido parses, and ``(size, size)`` when the score is complete (the notes
        are turned into events after the parse: a fifth to a quarter of the time). Whatever it raises
        (``KeyboardInterrupt``) stops the reading. The score is the same with or without it.
    note_map : Mapping[int, int] | None
        The file's pitch -> the General MIDI drum pitch it plays, for a file laid out otherwise
        (:func:`common.score.midi_notes.load_drum_map`, ``--drum-map``); pitches it does not hold are read as they
        are. Applied before the hi-hat pedal (CC4, :class:`common.score.midi_notes.HiHatPedal`) and ``drum_map``;
        events and unknown notes carry the pitch it gives.
    hihat_cc4 : bool
        Apply the hi-hat pedal the file sends as CC4 to its hi-hat notes (``--hihat-cc4``,
        :class:`common.score.midi_notes.HiHatPedal`). Off: the notes play as written, and a file whose hi-hat notes,
        all closed (or all open), the pedal would change is told of the option once.
    kit : Kit | None
        The kit the file is played on, when known: double events are then those striking one object with one stroke
        (MIDI 49 and 57 at once are two crashes on a kit whose ``note_objects`` send 57 to ``crash2``:
        :func:`common.score.events.double_key`); None: those of one event type (as before 7 Dec).

    Returns
    -------
    Score
        Events in seconds, velocities in [0, 1], beats from the file's own
        ticks-per-beat and tempo map, unknown notes and removed doubles listed.
    """
    with cyclic_gc_paused():
        score, size = _read(source, drum_channels, drum_map, progress, note_map, hihat_cc4, kit)
    if progress is not None:
        progress(size, size)
    return score


def _read(source: str | Path | bytes, drum_channels: Collection[int] | None, drum_map: Mapping[int, EventType],
          progress: ReadProgress | None, note_map: Mapping[int, int] | None = None,
          hihat_cc4: bool = False, kit: Kit | None = None) -> tuple[Score, int]:
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
    drums = {GM_DRUM_CHANNEL - 1}  # and those set to a drum bank; drum_channels, when given, instead
    raw: list[_RawNote] = []
    programs: dict[int, list[int]] = {}  # channel index -> its General MIDI programs, as first set
    tempo_points: list[tuple[int, float, float]] = [(0, 0.0, per_tick)]  # tick, seconds, seconds/tick
    meters: list[tuple[int, int, int]] = [(0, 4, 4)]  # tick, numerator, denominator (4/4 until told otherwise)
    pitches = note_map or {}
    pedal = HiHatPedal()  # CC4 per channel: applied with hihat_cc4, else only told of
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
        elif msg.type == "control_change" and msg.control == 4:  # the foot controller: a hi-hat's pedal
            pedal.control(msg.channel, msg.value)
        elif msg.type == "note_on" and msg.velocity > 0:
            pitch = pedal.pitch(seconds, msg.channel, pitches.get(msg.note, msg.note), apply=hihat_cc4)
            raw.append((seconds, pitch, msg.velocity, msg.channel, tick, msg.note))
        elif msg.type == "program_change" and msg.program not in programs.setdefault(msg.channel, []):
            programs[msg.channel].append(msg.program)
    warnings = open_warnings
    chosen, told = _chosen_notes(raw, drums, drum_channels, programs, mid, name)
    end_s = seconds + max(end_tick - last_tick, 0) * per_tick
    tempo_told = _tempo_warning(tempo_points, end_tick, end_s, [n[0] for n in chosen], mid.ticks_per_beat, name)
    warnings += [tempo_told] if tempo_told else []  # first: it explains what follows (doubles merged)
    warnings += told
    _check_size(chosen, name)
    warnings += _shared_pitches(chosen, mid, drum_map, pitches, name)
    read = [(s, c, p) for s, p, _, c, _, _ in chosen]
    if hihat_cc4:
        pedalled = pedal.notice(read, name) if pedal.changed else None
    else:
        pedalled = pedal.unused_notice(read, name) if pedal.would_move else None
    if pedalled:
        warnings.append(pedalled)
    notes = [DrumNote(time=s, pitch=p, velocity=v / 127.0, channel=c + 1) for s, p, v, c, _, _ in chosen]
    beats = _beats(tempo_points, end_tick, mid.ticks_per_beat)
    score = score_from_notes(notes, drum_map=drum_map, beats=beats, source=name,
                             bar_beats=_bar_beats(meters, end_tick, mid.ticks_per_beat), kit=kit)
    score.end_beat = _end_beat(end_tick, max((n[4] for n in chosen), default=None), meters, score.bar_beats,
                               mid.ticks_per_beat)
    score.bar_units = _bar_units(meters, score.bar_beats, mid.ticks_per_beat)
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


PERCUSSIVE_PROGRAMS = range(112, 120)
"""General MIDI's Percussive family (Tinkle Bell, Agogo, Steel Drums, Woodblock, Taiko Drum, Melodic Tom, Synth
Drum, Reverse Cymbal), 0-based: a channel set to one may hold drums; any other program names a melodic
instrument."""
CLICK_NAME = re.compile(r"(?<![a-z])(clicks?|klick|metronome|count[ _-]?(in|off)|guide)(?!(?-i:[a-z]))",
                        re.IGNORECASE)
"""A track name saying it holds a click (Logic's German "Klick"), a metronome, a count-in or a guide (the notes
a player follows, not what is played), as a word ("ClickTrack" too; not "Clicker"): :func:`_click_channels`."""
_WORD_START = r"(?:(?<![a-z])|(?-i:(?<=[a-z])(?=[A-Z])))"
"""Where a word starts in a track name (any case): after no letter, or a capital after a small letter ("KickDrum")."""
DRUM_NAME = re.compile(_WORD_START + r"(?:drum|perc"  # Drums, Drummer, DrumKit, Percussion
                       r"|(?:kits?|kicks?|snares?|(?:hi[ _-]?)?hats?|toms?|cymbals?|rides?|crash(?:es)?)"
                       r"(?!(?-i:[a-z])))", re.IGNORECASE)
"""A track name that says drums ("Guide Drums", "HiHat guide", "KickDrum click"): never left out as a click. As
words: until 7 Dec "tom" in "Custom" or "Bottom" and "ride" in "Override" read as drums, and those clicks were
played."""
CLICK_MAX_PITCHES = 2
"""The most pitches a click plays (an accented first beat and the others; General MIDI's metronome click and
bell, 33 and 34); a channel playing more is a part, whatever its track's name."""
KICK_SNARE_PITCHES = frozenset({35, 36, 38, 40})
"""General MIDI's kicks and snares (acoustic and electric): a channel playing one of them (after ``--drum-map``'s
note map) is a part, not a click, whatever its track's name (a "Guide" kick and snare)."""
CHOOSE_CHANNELS = "choose with --drum-channels N,N (1 to 16, as a DAW shows them)"
"""How a warning about the channels read says to choose them."""


def _chosen_notes(raw: list[_RawNote], drums: set[int], named: Collection[int] | None,
                  programs: dict[int, list[int]], mid: mido.MidiFile, name: str) -> tuple[list[_RawNote], list[str]]:
    """The notes read as drums and the warnings saying which channels were left out or guessed.

    ``named`` (1-based, ``--drum-channels``): those channels and no other. Else the drum channels ``drums``
    (0-based: 10 and those set to a drum bank); notes elsewhere are skipped with a warning naming each channel
    (a Drum Rack sends on channel 1, a tambourine sits on 10: the groove was dropped without a word). With no note
    on them, every channel is read, but for the channels whose programs are all melodic (a bass, a piano) and the
    click tracks (:func:`_click_channels`) when another channel (without a program, or with a percussive one) has
    notes; said either way. A file whose every channel with notes set a melodic program holds no drums: a
    :class:`ScoreError` saying so and naming the option that reads them anyway (a drum file on channel 1 without a
    program change, as a DAW writes one, is read with the warning)."""
    counts = Counter(r[3] for r in raw)
    if named:
        wanted = {c - 1 for c in named}
        silent = sorted(wanted - counts.keys())
        warnings = []
        if silent and counts:
            others = sorted(counts.keys() - wanted)
            warnings.append(f"{name}: no notes on channel{'s' * (len(silent) > 1)} {_channel_list(silent)} "
                            f"(--drum-channels)"
                            + (f"; notes are on {_channels(others, counts, programs, mid)}" if others else ""))
        return [r for r in raw if r[3] in wanted], warnings
    chosen = [r for r in raw if r[3] in drums]
    if chosen:
        skipped = sorted(counts.keys() - drums)
        if not skipped:
            return chosen, []
        read = sorted(counts.keys() & drums)
        them = "them" if len(skipped) > 1 else "it"
        why = ": a melodic program" if all(_melodic(c, programs) for c in skipped) else ""  # a song's bass, piano
        return chosen, [f"{name}: only channel{'s' * (len(read) > 1)} {_channel_list(read)} read as drums; "
                        f"skipped {_channels(skipped, counts, programs, mid)}{why}; to read {them} too: "
                        f"--drum-channels {_channel_list(sorted(read + skipped), ',')} (every channel read, 1 to "
                        f"16 as a DAW shows them)"]
    if not raw:
        return [], []
    channels = sorted(counts)
    melodic = [c for c in channels if _melodic(c, programs)]
    others = [c for c in channels if c not in melodic]
    clicks = _click_channels(others, raw, mid)
    kept = [c for c in others if c not in clicks] or others  # a click alone is read, as any channel
    if kept != others:
        them = "them" if len(clicks) > 1 else "it"
        songs = f"skipped {_channels(melodic, counts, programs, mid)}: a melodic program; " if melodic else ""
        return [r for r in raw if r[3] in kept], [
            f"{name}: no notes on a drum channel; reading {_reading(kept, counts, programs, mid)}; {songs}skipped "
            f"{_channels(clicks, counts, programs, mid)}: {_clicks_said(clicks, raw)}; to read {them} too: "
            f"--drum-channels {_channel_list(sorted(kept + clicks), ',')} (every channel read, 1 to 16 as a DAW "
            "shows them)"]
    if melodic and kept:
        return [r for r in raw if r[3] in kept], [
            f"{name}: no notes on a drum channel; reading {_reading(kept, counts, programs, mid)}; skipped "
            f"{_channels(melodic, counts, programs, mid)}: a melodic program; {CHOOSE_CHANNELS}"]
    if melodic and not all(set(programs[c]) == {0} for c in melodic):
        # every channel with notes set a melodic program: a song without drums (a bass line, a piano); program 0
        # alone is no choice: many DAWs write it on every track, a drum track on channel 1 too
        raise ScoreError(_no_drums_said(melodic, counts, programs, mid, name))
    default = "; program 1 (Acoustic Grand Piano) set, a DAW's default, so read as drums" if melodic else ""
    return raw, [f"{name}: no notes on a drum channel; reading {_reading(channels, counts, programs, mid)}{default}; "
                 f"{CHOOSE_CHANNELS}"]


def _no_drums_said(melodic: list[int], counts: Counter[int], programs: dict[int, list[int]], mid: mido.MidiFile,
                   name: str) -> str:
    """The error for a file whose notes are all on channels (0-based) that set a melodic program: no drums in it
    (until 8 Dec its bass line was read as drums with a warning, and played on the snare), and the option that
    reads them as drums anyway."""
    them = "it" if len(melodic) == 1 else "them"
    return (f"{name}: no drums: no notes on a drum channel (10, or one set to a drum bank), and the notes are on "
            f"{_channels(melodic, counts, programs, mid)}, set to a melodic program; to read {them} as drums anyway: "
            f"--drum-channels {_channel_list(melodic, ',')}")


def _click_channels(channels: list[int], raw: list[_RawNote], mid: mido.MidiFile) -> list[int]:
    """Those of ``channels`` (0-based) that hold a click, not drums: every track with notes on the channel is named
    so (:data:`CLICK_NAME`: Click, Metronome, Count-in, Guide; a name saying drums too, "Guide Drums", is not) and
    holds notes on that channel only, and its notes are on at most :data:`CLICK_MAX_PITCHES` pitches as the file
    writes them, none a kick or a snare (:data:`KICK_SNARE_PITCHES`, as ``--drum-map`` maps them). A DAW's click
    or count-in has no program change, so it looked like drums; until 7 Dec it played as cowbells beside the
    groove. A name alone leaves nothing out (a "Click" track playing a beat is read), nor does a pitch count alone
    (a drum machine's kick and snare on a channel of their own). A track on several channels is a part whatever
    its name: a type 0 file's one track, named "Guide", holds every channel (until 7 Dec its kick and snare
    channel was dropped as a click); so is a "Click" or "Guide" track playing a kick and a snare."""
    pitches: dict[int, set[int]] = {}
    wanted = set(channels)
    for r in raw:
        if r[3] in wanted:
            pitches.setdefault(r[3], set()).add(r[5])
    drums = {r[3] for r in raw if r[3] in wanted and r[1] in KICK_SNARE_PITCHES}
    few = {c for c in channels if len(pitches.get(c, ())) <= CLICK_MAX_PITCHES and c not in drums}
    if not few:  # the usual file: no pass over the tracks
        return []
    titles: dict[int, list[tuple[str, bool]]] = {}  # channel -> (name, the track's only channel) of its tracks
    for track in mid.tracks:
        played = {m.channel for m in track if m.type == "note_on" and m.velocity > 0}
        for channel in played & few:
            titles.setdefault(channel, []).append((track.name.strip(), len(played) == 1))
    return [c for c in channels if c in titles
            and all(alone and CLICK_NAME.search(t) and not DRUM_NAME.search(t) for t, alone in titles[c])]


def _clicks_said(clicks: list[int], raw: list[_RawNote]) -> str:
    """"a click (so named, on 2 pitches)"; for several channels (0-based) each one's pitches as the file writes
    them: "clicks (so named, on 2 pitches each)", "clicks (so named; channel 15 on 2 pitches, channel 16 on 1
    pitch)" (until 7 Dec the pitches of all were counted together: a Click on 76 and 77 and a Count-in on 33 and
    34 were "on 4 pitches")."""
    counts = {c: len({r[5] for r in raw if r[3] == c}) for c in clicks}
    if len(set(counts.values())) == 1:
        n = counts[clicks[0]]
        each = " each" * (len(clicks) > 1)
        return f"{'clicks' if each else 'a click'} (so named, on {n} pitch{'es' * (n != 1)}{each})"
    return "clicks (so named; " + ", ".join(f"channel {c + 1} on {n} pitch{'es' * (n != 1)}"
                                            for c, n in counts.items()) + ")"


def _melodic(channel: int, programs: dict[int, list[int]]) -> bool:
    """Whether the channel (0-based) set programs, all of them melodic instruments (not General MIDI's Percussive
    family): not drums, unless named."""
    return bool(programs.get(channel)) and not any(p in PERCUSSIVE_PROGRAMS for p in programs[channel])


def _reading(channels: list[int], counts: Counter[int], programs: dict[int, list[int]], mid: mido.MidiFile) -> str:
    """"channels [3] (Violin) as drums" for one channel (0-based) read as drums; for several, each with its notes,
    programs and tracks (:func:`_channels`): the user picks among them."""
    if len(channels) == 1:
        return f"channels {[channels[0] + 1]}{_instruments(channels, programs)} as drums"
    return f"channels {[c + 1 for c in channels]} as drums: {_channels(channels, counts, programs, mid)}"


def _channel_list(channels: list[int], sep: str = ", ") -> str:
    """0-based channel indices as a DAW shows them: "1, 10" (``sep`` "," for an option's value: "1,10")."""
    return sep.join(str(c + 1) for c in channels)


def _channels(channels: list[int], counts: Counter[int], programs: dict[int, list[int]], mid: mido.MidiFile) -> str:
    """"channel 1 (24 notes, track Drums); channel 2 (8 notes, Electric Bass (finger), track Bass)": each channel
    (0-based), its notes, its General MIDI programs and the tracks its notes are in, for the user to choose."""
    tracks = _channel_tracks(mid)
    out = []
    for c in channels:
        parts = [f"{counts[c]} note{'s' * (counts[c] != 1)}"]
        parts += [GM_PROGRAM_NAMES[p] for p in programs.get(c, [])]
        names = tracks.get(c, [])
        if names:
            parts.append(f"track{'s' * (len(names) > 1)} {', '.join(names)}")
        out.append(f"channel {c + 1} ({', '.join(parts)})")
    return "; ".join(out)


def _channel_tracks(mid: mido.MidiFile) -> dict[int, list[str]]:
    """The names of the tracks holding each channel's (0-based) notes, in file order; unnamed tracks left out."""
    out: dict[int, list[str]] = {}
    for track in mid.tracks:
        title = track.name.strip()
        if not title:
            continue
        for channel in sorted({m.channel for m in track if m.type == "note_on" and m.velocity > 0}):
            if title not in out.setdefault(channel, []):
                out[channel].append(title)
    return out


def _shared_pitches(chosen: list[_RawNote], mid: mido.MidiFile, drum_map: Mapping[int, EventType],
                    note_map: Mapping[int, int], name: str) -> list[str]:
    """A warning for each pitch that several tracks or channels play at the same ticks: one drum per track, each
    on the same pitch (a DAW's default note, 60), is one drum here, read by pitch, and their notes at once one
    note. Tracks are not mapped by their names (a name says little of what a note is, and a wrong guess plays
    the wrong drum): the warning names the tracks so the user can give each drum its pitch.

    Pitches as the file writes them (the user's DAW shows those), the drum named the one ``note_map`` plays: until
    7 Dec the notes were compared after the map but looked up in the tracks before it, so a map moving the shared
    pitch (60 -> 38) hid the warning and one swapping two pitches named the wrong drum. Two pitches a map plays on
    one drum (a tom's head and rim) are not one pitch shared."""
    seen = Counter((r[4], r[5]) for r in chosen)
    doubled = {key for key, n in seen.items() if n > 1}
    if not doubled:  # the usual file: no pass over the tracks
        return []
    wanted = {r[3] for r in chosen}
    players: dict[tuple[int, int], set[tuple[int, int]]] = {}  # (tick, pitch) -> {(track, channel)}
    offset = 0
    for k, track in enumerate(mid.tracks):
        tick = offset
        for msg in track:
            tick += msg.time
            if (msg.type == "note_on" and msg.velocity > 0 and msg.channel in wanted
                    and (tick, msg.note) in doubled):
                players.setdefault((tick, msg.note), set()).add((k, msg.channel))
        offset = tick if mid.type == 2 else 0  # type 2: tracks one after another, as _timeline reads them
    shared: dict[int, tuple[set[tuple[int, int]], int]] = {}  # pitch -> its players, times played together
    for (_, pitch), who in players.items():
        if len(who) > 1:
            group, times = shared.get(pitch, (set(), 0))
            shared[pitch] = (group | who, times + 1)
    warnings = []
    for pitch, (who, times) in sorted(shared.items()):
        names = [f"{mid.tracks[k].name.strip() or f'track {k + 1}'} (channel {c + 1})" for k, c in sorted(who)]
        event = drum_map.get(note_map.get(pitch, pitch))
        drum = f"one drum here ({event.value})" if event is not None else "one pitch (unknown: not played)"
        warnings.append(f"{name}: pitch {pitch} is played by {len(who)} tracks, {', '.join(names)}, {times} "
                        f"time{'s' * (times != 1)} at the same tick: drums are read by pitch, not by track, so "
                        f"they are {drum} and notes played together one note; give each drum its own pitch in "
                        f"the DAW (General MIDI: kick 36, snare 38, closed hi-hat 42)")
    return warnings


def _tempo_warning(tempo_points: list[tuple[int, float, float]], end_tick: int, end_s: float, note_s: list[float],
                   ticks_per_beat: int, name: str) -> str | None:
    """A warning for the tempos the file sets outside :data:`PLAUSIBLE_TEMPO_BPM` that hold for some of it, saying
    how long the file and its notes then last (read as they are, not refused); None when there is none.

    ``tempo_points``: (tick, seconds, seconds per tick), the first the default tempo; ``end_tick``, ``end_s``: the
    file's end; ``note_s``: the times of the notes read as drums, seconds."""
    low, high = PLAUSIBLE_TEMPO_BPM
    odd = []
    for k, (tick, _, per_tick) in enumerate(tempo_points[1:], start=1):
        until = tempo_points[k + 1][0] if k + 1 < len(tempo_points) else end_tick
        bpm = 60.0 / (per_tick * ticks_per_beat)
        if until > tick and not low <= bpm <= high:  # one replaced at its own tick or set at the end holds nothing
            odd.append((tick, bpm, round(per_tick * ticks_per_beat * 1e6)))
    if not odd:
        return None
    tick, bpm, micros = odd[0]
    first = f"tempo {_bpm(bpm)} bpm at tick {tick} (a set_tempo of {micros:,} microsecond{'s' * (micros != 1)} a beat)"
    if len(odd) == 1:
        which = f"{first}, outside the {low:g} to {high:g} bpm music is played at"
    else:
        bpms = [b for _, b, _ in odd]
        which = (f"{len(odd)} tempos outside the {low:g} to {high:g} bpm music is played at, from {_bpm(min(bpms))} to "
                 f"{_bpm(max(bpms))} bpm, the first {first}")
    notes = ""
    if note_s:
        count = f"{len(note_s)} note{'s' * (len(note_s) != 1)}"
        notes = (f", its {count} at {_seconds(note_s[0])}" if len(note_s) == 1 else
                 f", its {count} between {_seconds(min(note_s))} and {_seconds(max(note_s))}")
    return (f"{name}: {which}: read as {'it is' if len(odd) == 1 else 'they are'}, the whole file lasts "
            f"{_seconds(end_s)}{notes} (a corrupt tempo? set the tempo in the DAW and export again)")


def _bpm(bpm: float) -> str:
    """A tempo for :func:`_tempo_warning`: ``60,000,000``, ``412.5``, ``0.5``."""
    return f"{bpm:,.0f}" if bpm >= 1000 else f"{bpm:.4g}"


def _seconds(seconds: float) -> str:
    """A time for :func:`_tempo_warning`: ``0 s``, ``0.03 ms``, ``0.003 s``, ``12.5 s``, ``1.5 h``."""
    if 0 < seconds < 1e-3:
        return f"{seconds * 1e3:.2g} ms"
    return hours(seconds) if seconds >= 3600 else f"{seconds:.3g} s"


def _check_size(notes: list[_RawNote], name: str) -> None:
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


def _end_beat(end_tick: int, last_note_tick: int | None, meters: list[tuple[int, int, int]], bar_beats: np.ndarray,
              ticks_per_beat: int) -> float:
    """Where the score ends, beats (:attr:`Score.end_beat`): the file's end of track when it lies on a bar line (a
    DAW's song end set on a bar, empty bars before it counted), else the end of the bar holding the last note: a DAW
    writes its end of track a little after the last note or bar line (8 bars of 4/4 ending at beat 32.62 were "9
    bars (32.62 beats)" until 8 Dec). A file without notes, or whose last note lies past the bars counted
    (:data:`MAX_SCORE_BARS`), ends at its end of track. ``meters``: (tick, numerator, denominator) in tick order;
    ``bar_beats``: :func:`_bar_beats`'s."""
    end = end_tick / ticks_per_beat
    tick, numerator, denominator = meters[-1]  # in force at the end: the end of track is the file's last tick
    bar_ticks = numerator * ticks_per_beat * 4 / denominator
    into_bar = math.fmod(end_tick - tick, bar_ticks)
    on_bar_line = min(into_bar, bar_ticks - into_bar) < 0.5  # within half a tick
    if last_note_tick is None:
        return end
    starts = np.asarray(bar_beats, dtype=float)
    after = int(np.searchsorted(starts, last_note_tick / ticks_per_beat + 1e-9, side="right"))
    if after >= len(starts):  # past the bars counted
        return end
    note_bar_end = float(starts[after])
    return max(end, note_bar_end) if on_bar_line else note_bar_end


def _bar_units(meters: list[tuple[int, int, int]], bar_beats: np.ndarray, ticks_per_beat: int) -> np.ndarray:
    """Each bar's counted beat in quarter notes (4 / the denominator of the time signature in force where it
    starts; the last of several at one tick), parallel to ``bar_beats`` (:func:`_bar_beats`)."""
    ticks = np.array([tick for tick, _, _ in meters], dtype=float)
    which = np.searchsorted(ticks, np.asarray(bar_beats, dtype=float) * ticks_per_beat + 1e-6, side="right") - 1
    return np.array([4.0 / meters[max(k, 0)][2] for k in which], dtype=float)


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
