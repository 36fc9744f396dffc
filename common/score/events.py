"""Drum events: what a score becomes before limbs are chosen.

A :class:`Score` is a time-sorted list of :class:`DrumEvent` (seconds, drum
event type, velocity in [0, 1]) plus what was not kept: notes with no drum
event (``unknown``) and double events (``duplicates``), so nothing is dropped
silently. Scores come from Standard MIDI Files (:mod:`common.score.midi`), the
plain-text format (:mod:`common.score.text`) or live OSC notes
(:mod:`common.score.live`).
"""

from __future__ import annotations

import codecs
from collections import Counter
from collections.abc import Callable, Hashable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from common.gesture.plan import Nuance
from common.input_file import file_problem
from common.kit import EventType, Kit, Limb
from common.score.gm import DRUM_MAP, EVENT_WORDS, GM_STAND_INS, GM_TO_EVENT, note_name, pitch_label

DUPLICATE_WINDOW = 0.010
"""Two events of the same type closer than this (seconds) are one double event."""
MAX_SCORE_SECONDS = 24 * 3600.0
"""The longest score read, seconds: a note later than a day in is a corrupt file's timing (a MIDI delta of
2^28 ticks put one 388 h in), and planning would run out of memory and time on the silence before it."""
MAX_SCORE_BARS = int(MAX_SCORE_SECONDS * 400 / 60)
"""The most bar starts a score keeps (a whole day of one-beat bars at 400 bpm): later bars are not counted (a
meter of a thousandth of a beat must not fill the memory)."""
MAX_SCORE_NOTES = 500_000
"""The most notes a score may hold (about 14 h of dense drumming at 10 notes a second): planning takes some
0.5 ms and 6 kB per note, and a text score's ``repeat 100000000`` would not fit in memory at all."""
MAX_SCORE_BYTES = 8 * 1024 * 1024
"""The largest score file read: hours of drumming are about 1 MB of MIDI, and mido holds some 300 bytes per
3-byte MIDI message in memory."""


SCORE_FILE = "a score file (MIDI or text)"
""":func:`check_file`'s words for what a score path must be (``is a folder, not a score file (MIDI or text)``)."""


def check_file(path: Path, name: str) -> None:
    """Raise :class:`ScoreError` (one line, naming ``name``) unless ``path`` is a score-sized regular file: a
    folder, a device or a pipe is said as every loader says it (:func:`common.input_file.file_problem`), and
    never opened (a pipe without a writer would wait for one for ever)."""
    problem = file_problem(path, SCORE_FILE)
    if problem is not None:
        raise ScoreError(f"{name}: {problem}")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ScoreError(f"{name}: cannot read the file ({exc.strerror or exc})") from None
    if size > MAX_SCORE_BYTES:
        raise ScoreError(f"{name}: {size / 2**20:.0f} MB is too large for a score (at most "
                         f"{MAX_SCORE_BYTES // 2**20} MB)")


def audio_kind(head: bytes) -> str | None:
    """The audio format a file's first 12 bytes start, or None: a recording given where a score is expected.

    UTF-16 or UTF-32 text (its byte order mark, :func:`unicode_bom`) is None, whoever asks (a score, a kit): UTF-16
    LE's mark FF FE is also an MPEG layer I frame's sync bits, and such text was "an audio file (MP3)"."""
    if unicode_bom(head) is not None:
        return None
    if head[:4] in (b"RIFF", b"RF64") and head[8:12] == b"WAVE":
        return "WAV"
    if head[:4] == b"FORM" and head[8:12] in (b"AIFF", b"AIFC"):
        return "AIFF"
    if head[:4] == b"fLaC":
        return "FLAC"
    if head[:4] == b"OggS":
        return "Ogg"
    if (head[:3] == b"ID3" and head[3:4] in (b"\x02", b"\x03", b"\x04")) or (
            len(head) >= 2 and head[0] == 0xFF and head[1] & 0xE6 in (0xE2, 0xE4, 0xE6)):
        return "MP3"  # an ID3 tag, or an MPEG audio layer III/II/I frame's sync bits without one
    return None


UNICODE_BOMS: tuple[tuple[bytes, str, str], ...] = (
    (codecs.BOM_UTF32_LE, "utf-32", "UTF-32"),  # before UTF-16's: FF FE 00 00 starts as UTF-16 LE's FF FE
    (codecs.BOM_UTF32_BE, "utf-32", "UTF-32"),
    (codecs.BOM_UTF16_LE, "utf-16", "UTF-16"),
    (codecs.BOM_UTF16_BE, "utf-16", "UTF-16"),
)
"""Byte order marks of UTF-16 and UTF-32 text (what Windows Notepad saves as "Unicode"), the Python codec that
reads such text (it takes the order from the mark and drops it) and the encoding's name for a message."""


def unicode_bom(head: bytes) -> tuple[str, str] | None:
    """(codec, name) of the UTF-16 or UTF-32 text whose byte order mark ``head`` (a file's first bytes) starts with,
    else None. :func:`audio_kind` asks it first: UTF-16 LE's mark FF FE is also an MPEG audio frame's sync."""
    for mark, codec, name in UNICODE_BOMS:
        if head.startswith(mark):
            return codec, name
    return None


TEXT_CONTROLS = frozenset(b"\t\n\r\f\v")
"""The control characters text holds (a MIDI file's header holds NULs and other control bytes)."""


def looks_like_text(data: bytes) -> bool:
    """Whether ``data`` (a file's bytes, or its first few thousand) reads as text: UTF-16/32 after its byte order
    mark, else UTF-8 (a character cut at the end of a sample is allowed), with no control characters but
    white space. A text score named ``.mid`` is one; a MIDI, audio or other binary file is not."""
    bom = unicode_bom(data)
    try:
        if bom is not None:
            text = codecs.getincrementaldecoder(bom[0])().decode(data)
        else:
            text = codecs.getincrementaldecoder("utf-8")().decode(data)
    except UnicodeDecodeError:
        return False
    return bool(text.strip()) and not any(ord(c) < 32 and ord(c) not in TEXT_CONTROLS or ord(c) == 127
                                          for c in text)


def starts_as_midi(head: bytes) -> bool:
    """Whether a file's first 12 bytes are a Standard MIDI File's (``MThd``) or a RIFF MIDI file's (``RMID``)."""
    return head[:4] == b"MThd" or (head[:4] == b"RIFF" and head[8:12] == b"RMID")


def check_not_audio(head: bytes, name: str) -> None:
    """Raise :class:`ScoreError` saying what to do when ``head`` (a file's first bytes) is an audio file's."""
    kind = audio_kind(head)
    if kind is not None:
        raise ScoreError(f"{name}: this is an audio file ({kind}), not a score; to play it, transcribe it first: "
                         f"batteur transcribe {name} -o score.mid")


def hours(seconds: float) -> str:
    """A time for a message about the limits: ``24 h``, ``388.4 h``, ``1.389e+05 h``."""
    return f"{seconds / 3600:.4g} h"


class ScoreError(ValueError):
    """A score that cannot be read; the message names the file and the problem."""


@dataclass(frozen=True)
class DrumNote:
    """A raw note from a score source: time (s), MIDI pitch, velocity in [0, 1], MIDI channel (1-16)."""

    time: float
    pitch: int
    velocity: float
    channel: int = 10


@dataclass(frozen=True)
class DrumEvent:
    """One drum event.

    Parameters
    ----------
    time : float
        Onset, seconds from the score start.
    event : EventType
        Drum event type.
    velocity : float
        Loudness in [0, 1] (MIDI velocity / 127).
    pitch : int | None
        Source MIDI pitch (selects second objects through ``Kit.note_objects``).
    limb : Limb | None
        Forced limb (sticking written in the score), or None to let the planner choose.
    nuance : Nuance | None
        Per-note nuance, or None for the global one.
    """

    time: float
    event: EventType
    velocity: float
    pitch: int | None = None
    limb: Limb | None = None
    nuance: Nuance | None = None


@dataclass(frozen=True)
class UnknownNote:
    """A note with no drum event type: reported, not played."""

    time: float
    pitch: int
    velocity: float
    channel: int

    def describe(self) -> str:
        return f"{note_name(self.pitch)} (pitch {self.pitch}, channel {self.channel}) at {self.time:.3f} s"


@dataclass
class Score:
    """A drum score ready for limb distribution.

    Parameters
    ----------
    events : list[DrumEvent]
        Sorted by time.
    beats : np.ndarray, shape (B,)
        Beat times, seconds (for the head nod and tempo-aware gesture choice).
    unknown : list[UnknownNote]
        Notes with no drum event type.
    duplicates : list[DrumEvent]
        Double events removed (same type within ``DUPLICATE_WINDOW``).
    warnings : list[str]
        Other things the reader wants the user to know.
    source : str
        File name or "live"/"text".
    bar_beats : np.ndarray, shape (M,)
        Where each bar starts, in beats from the first (an index into ``beats``, fractional where a bar starts
        between two); increasing. Empty when the reader knows no bars (:mod:`common.score.position` then counts
        bars of 4 beats). A MIDI file's last start lies past its last beat: where the bar holding its end ends
        (bars after it are as long); so does a text score's ending in a rest shorter than a bar (a whole bar after
        the one starting where it ends).
    end_beat : float or None
        Where the score ends, in beats (quarter notes) from the first: a text score's last bar (or rest), a MIDI
        file's end of track when it lies on a bar line, else the end of the bar holding its last note
        (:func:`common.score.midi._end_beat`); its length, which ``python -m common.score`` reports. ``beats``
        holds the beat at the end too (the head nod's last), so it counts one beat more. None: not known (a live
        or performed score).
    bar_units : np.ndarray, shape (M,)
        Each bar's counted beat, the 1/D note of its meter N/D, in quarter notes (0.5 in 6/8 or 7/8, 1 in x/4),
        parallel to ``bar_beats`` (bars past the last start count as it); empty: quarter notes. How ``batteur
        compare`` counts beats as a DAW does (``bar 2, beat 5`` in 7/8); ``beats`` stay quarter notes.
    """

    events: list[DrumEvent]
    beats: np.ndarray = field(default_factory=lambda: np.zeros(0))
    unknown: list[UnknownNote] = field(default_factory=list)
    duplicates: list[DrumEvent] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    source: str = ""
    bar_beats: np.ndarray = field(default_factory=lambda: np.zeros(0))
    end_beat: float | None = None
    bar_units: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def duration(self) -> float:
        """Seconds from 0 to the last event (0 when empty)."""
        return self.events[-1].time if self.events else 0.0

    def unknown_summary(self) -> dict[int, int]:
        """Count of unknown notes per MIDI pitch."""
        counts: dict[int, int] = {}
        for n in self.unknown:
            counts[n.pitch] = counts.get(n.pitch, 0) + 1
        return counts


def remove_duplicates(
    events: Iterable[DrumEvent], window: float = DUPLICATE_WINDOW,
    key: Callable[[DrumEvent], Hashable] | None = None,
) -> tuple[list[DrumEvent], list[DrumEvent]]:
    """Merge double events: same event type (``key``: same key, e.g. event type and pitch where a pitch names
    another drum) within ``window`` seconds keeps the loudest.

    Returns (kept, removed), both sorted by time.
    """
    ordered = sorted(events, key=lambda e: (e.time, e.event.value))
    kept: list[DrumEvent] = []
    removed: list[DrumEvent] = []
    last: dict[Hashable, int] = {}
    for ev in ordered:
        drum = ev.event if key is None else key(ev)
        i = last.get(drum)
        if i is not None and ev.time - kept[i].time < window:
            prev = kept[i]
            if ev.velocity > prev.velocity:
                kept[i] = replace(prev, velocity=ev.velocity)
            removed.append(ev)
            continue
        last[drum] = len(kept)
        kept.append(ev)
    return kept, removed


def double_key(kit: Kit | None) -> Callable[[DrumEvent], Hashable] | None:
    """What makes two events doubles (:func:`remove_duplicates`' ``key``), one rule for text scores, MIDI files and
    live notes: they strike the same object of ``kit`` with the same stroke, the key (event type, object id: the
    kit's ``note_objects`` object for the event's pitch, else the event's own). MIDI 49 and 57 at once are two
    crashes on a kit sending 57 to ``crash2``, one on a kit that does not; 42 and 22 stay one closed hi-hat.

    None (the event type alone, as before) without a kit: a MIDI file read before its kit is known merges by event
    type (a kit it is later played on cannot split them again); the readers take the kit when they have it
    (``read_score(kit=)``)."""
    if kit is None:
        return None
    objects, events = kit.note_objects, kit.events

    def key(ev: DrumEvent) -> Hashable:
        target = objects.get(ev.pitch) if ev.pitch is not None else None
        if target is None and ev.event in events:
            target = events[ev.event].object
        return ev.event, target

    return key


def score_from_notes(
    notes: Iterable[DrumNote],
    drum_map: Mapping[int, EventType] = DRUM_MAP,
    beats: np.ndarray | None = None,
    source: str = "",
    duplicate_window: float = DUPLICATE_WINDOW,
    bar_beats: np.ndarray | None = None,
    kit: Kit | None = None,
) -> Score:
    """Turn raw notes into a :class:`Score`: map pitches, clamp velocities to [0, 1], remove doubles (those of one
    object of ``kit`` when given, :func:`double_key`; else of one event type)."""
    events: list[DrumEvent] = []
    unknown: list[UnknownNote] = []
    for n in notes:
        vel = float(min(max(n.velocity, 0.0), 1.0))
        ev = drum_map.get(n.pitch)
        if ev is None:
            unknown.append(UnknownNote(n.time, n.pitch, vel, n.channel))
        else:
            events.append(DrumEvent(time=n.time, event=ev, velocity=vel, pitch=n.pitch))
    kept, removed = remove_duplicates(events, duplicate_window, key=double_key(kit))
    named = f"{source}: " if source else ""
    warnings = []
    if unknown:
        counts = sorted(_count(unknown).items(), key=lambda pc: (-pc[1], pc[0]))  # the most played first
        pitches = [f"{pitch_label(p)} x{c}" for p, c in counts]
        said = f"{len(unknown)} notes have no drum event type and are" if len(unknown) != 1 else \
            "1 note has no drum event type and is"
        warnings.append(f"{named}{said} not played: "
                        f"{capped(pitches)} (note names with middle C = C3); {MAP_HINT}")
    stand_ins = Counter(e.pitch for e in events
                        if e.pitch in GM_STAND_INS and GM_TO_EVENT.get(e.pitch) is e.event)
    if stand_ins:
        # a pitch the kit's note_objects sends to an object of its own (a woodblock) plays there, as Kit.object_for
        routed = {p: kit.note_objects[p] for p in stand_ins
                  if kit is not None and p in kit.note_objects and GM_TO_EVENT[p] in kit.events}
        played = [f"{pitch_label(p)} played on {routed[p]} (the kit's note_objects) x{c}" if p in routed else
                  f"{pitch_label(p)} played as {EVENT_WORDS[GM_TO_EVENT[p]]} x{c}"
                  for p, c in sorted(stand_ins.items(), key=lambda pc: (-pc[1], pc[0]))]
        alike, own = "on the kit piece struck alike", "on the kit's own object for it"
        where = alike if not routed else own if len(routed) == len(stand_ins) else f"{own}, else {alike}"
        warnings.append(f"{named}General MIDI percussion a drum kit does not have is played {where}: "
                        f"{capped(played)}; if the file means other drums by these notes, {MAP_HINT}")
    return Score(
        events=kept,
        beats=np.zeros(0) if beats is None else beats,
        bar_beats=np.zeros(0) if bar_beats is None else bar_beats,
        unknown=unknown,
        duplicates=removed,
        warnings=warnings,
        source=source,
    )


MAP_HINT = "give --drum-map a note map (a .json or .toml file, or roland-td; docs/score-format.md, \"Note maps\")"
"""How a note that is not General MIDI's is given its drum (the MIDI reading option of the command lines)."""
LISTED_PITCHES = 8
"""The most pitches a warning lists (the most played): a keyboard-mapped sample kit has dozens."""


def capped(items: list[str], most: int = LISTED_PITCHES) -> str:
    """``items`` joined with commas, the first ``most`` of them and ``... and 61 more pitches`` for the rest."""
    if len(items) <= most:
        return ", ".join(items)
    rest = len(items) - most
    return ", ".join(items[:most]) + f", ... and {rest} more pitch{'es' * (rest != 1)}"


def _count(unknown: list[UnknownNote]) -> dict[int, int]:
    counts: dict[int, int] = {}
    for n in unknown:
        counts[n.pitch] = counts.get(n.pitch, 0) + 1
    return counts
