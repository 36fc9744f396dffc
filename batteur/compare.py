"""``batteur compare EXERCISE TAKE``: a student's take (MIDI from an e-kit, or a recording) against the exercise.

``batteur evaluate`` judges Batteur's own renders against their score; this command judges a performance it did
not make. The take is read (a MIDI file), or transcribed in-process with the recogniser ``batteur transcribe``
uses (an audio file); its notes are lined up with the exercise's (the student starts whenever they like) and
matched one to one with evaluate's matching (:func:`batteur.evaluate.match`: same kit object, within the
tolerance, the most pairs and then the least total error). The report says, per drum, what was played, missed,
played on another drum (:func:`wrong_drum_pairs`) and added (a note beyond the tolerance: played too early or
late), how early or late and how steadily, where each miss and extra is (bar and beat, as counted:
:func:`grid_label`), the bars and beats rushed or dragging (:func:`beat_feels`), and whether the written dynamics
came through (docs/evaluation.md, "A student's take against the exercise").

Alignment (:func:`align`): every pair of notes of one drum, one written and one played, proposes an offset (take
time - exercise time); the offsets most pairs agree on (within the tolerance) are tried with the full matching,
and the one matching most notes wins, set so that the median matched note is on time. Early and late are thus
measured against the student's own pulse, not against an absolute start nobody can know; ``--offset`` forces the
alignment (and then the means are against that start). A take that stops and comes back in is timed from there
against the restart (:func:`find_restarts`), its pause taken out, not as notes late by it; an entry late or early
after a written rest (:data:`REST_BEATS`) is said, its notes told late or early by it (a miscounted rest).
"""

from __future__ import annotations

import argparse
import bisect
import json
import math
import sys
from collections import Counter, defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from batteur.errors import report_error
from common.arg_types import take_negative_values
from common.kit import EventType, Kit
from common.score.events import Score
from common.score.midi_options import add_midi_arguments, drum_map, midi_read_kwargs
from common.score.position import bar_unit, pickup  # shared with the physics score player's logs
from common.score.position import counted_bar_beat as bar_and_beat

if TYPE_CHECKING:
    from batteur.evaluate import NoteRef

PROG = "batteur compare"
"""The command's name in its usage and error lines."""
DEFAULT_TOLERANCE_S = 0.050
"""A played note within this of the written one counts, seconds: a person's take is not a render's (evaluate's
10/25 ms are for the simulated drummer); 50 ms is the onset-detection convention (MIREX) and what musicians hear
as "on the beat" for a student, about the width of a loose flam, and under half a sixteenth note up to 150 bpm
(100 ms), so a note cannot match its neighbour on the grid. The transcriber's 10 ms frames also need the slack."""
TOLERANCE_RANGE_S = (0.001, 0.5)
"""Accepted ``--tolerance``, seconds."""
TEMPO_SCALE_RANGE = (0.1, 10.0)
"""Accepted ``--tempo-scale`` (as ``batteur render``'s)."""
LOOSE_S = 0.150
"""A missed note with an unmatched note of its drum this near is told as played early or late, seconds."""
CANDIDATES = 12
"""Offsets tried with the full matching (:func:`align`)."""
MAX_PAIRS = 2_000_000
"""Offset proposals per drum at most (:func:`candidate_offsets`): the written notes are thinned evenly beyond it."""
RESTART_NOTES = 4
"""Notes a restart (:func:`find_restarts`) must match beyond the take taken as one, at least: a beat of sixteenths,
a bar of quarter notes."""
RESTART_BEATS = 0.5
"""A restart's pause is this many of the exercise's beats at least (its median beat), and beyond the reach of a
note played too early or late: a bar played 200 ms late as a whole at 120 bpm (0.4 beat) is a jump, its notes
missed and extra; from half a beat on a note paired with the next eighth's would read as late or early."""
STOP_BEATS = 1.5
"""A pause with fewer than :data:`RESTART_NOTES` written notes on one side (after the first beat, before the last
one) is a restart when it is this many of the exercise's beats beyond the written gap at least (and beyond the
reach of a note played too early or late): the student really stopped (a 1 s pause at 120 bpm). A shorter one is
those few notes played early or late (a last crash held 0.35 or 0.6 s, a first downbeat 0.4 s early), told with
their error: until 7 Dec they read as a restart and the take as perfect."""
RESTART_SHARE = 0.5
"""Share of the written notes before the take came back in, and of those from there on, a restart must match
at least, each: a student who stops comes back on their pulse and plays on (a take drifting off tempo, whose tail
a shift lines up for a few bars, is no restart)."""
RESTART_CANDIDATES = 8
"""Silences (the longest pauses first) tried as restarts per round, and the rounds (restarts) at most."""
REST_BEATS = 2.0
"""A written gap (between two written onsets, any drum) of this many of the exercise's beats at least is a written
rest: a beat's rest after the beat a note takes (a quarter-note groove's notes a beat apart are none). A silence
across it is the student counting the rest, not a restart: the entry after it is said (``came in 0.5 s late after
the rest``) and its notes kept late or early (:func:`find_restarts`; until 7 Dec coming in a beat late after a
2-bar rest read as a restart and a perfect take)."""
TEMPO_GRID = (0.5, 2.0, 0.02)
"""Tempo ratios tried when most notes do not match (lowest, highest, relative step), refined by a tenth of it."""
TEMPO_NOTES = 200
"""Written notes (the first) the tempo grid is tried on (:func:`find_tempo`)."""
TEMPO_CHECK_BELOW = 0.8
"""The tempo is looked for when fewer than this share of the written notes are played."""
TEMPO_STEADY = 0.95
"""Share of the written notes a tempo found matches from which it is a steady tempo the whole take was played at
(not a tempo change in its middle, which leaves a part off at any one ratio): it need only match half the notes
the exercise's tempo leaves, not half as many again (16 bars at 0.996, 159 of 208 matched, could not be 1.5 x)."""
COUNT_IN_NOTES = 3
"""Notes a steady pulse apart before the exercise's start that make a count-in (:func:`count_in_entry`)."""
COUNT_IN_REACH = 8
"""Count-in beats from its next beat beyond which an entry is not told against it (two bars of 4/4)."""
COUNT_IN_SAME = 0.75
"""Share of a count-in's onsets that strike one same set of kit objects at least: a count-in repeats one sound
(sticks, a side-stick, the hi-hat or its pedal); a quarter left for a recording's transcriber hearing a click as
another class. A groove's onsets (hi-hat and kick, hi-hat, hi-hat and snare) are not one."""
COUNT_IN_PULSE_MATCH = 0.10
"""A count-in's pulse is the exercise's beat (or twice or half it) within this share: a count-in is counted at
the tempo to come; a tenth allows a student's count a little off (97 bpm into 105 bpm) but not a pulse of some
other subdivision (a dotted beat is 1.5, a triplet 0.67 or 1.33)."""
ACCENT_MARGIN = 10.0
"""Accents are told louder when their played mean is at least this above the rest's, MIDI velocity: a tenth of
velocity's range under 100; on an e-kit's usual velocity curve (some 40 dB over 1-127) about 3 dB, a step a
listener hears as an accent, where 1 or 2 (about 1 dB, the just-noticeable difference) is not one. Between 0 and
this: barely louder."""
FEW_LEVELS = 4
"""Written velocity levels of one drum up to which the played mean per level is said (:func:`dynamics`)."""
WRITTEN_ACCENT_GAP = 20.0
"""A drum's written accents are its notes at least this far above the rest of its written levels (MIDI velocity,
the top gap this wide between two levels): a text score's ``X`` (127) against ``x`` (89) is 38, a digit's step
14; a MIDI exercise's humanised levels a few apart (92 and 98) are no accents, and get no accent verdict."""
AUDIO_VELOCITY_SCALE = 0.25
"""How much of a velocity difference the transcriber's velocities keep: the walkthrough's b_steady (beat100's
hi-hat accents played at 120 against 90, MIDI) rendered and transcribed read 90.1 against 82.5, 7.6 of 30; a
constant 90 read with a spread of 3 to 6. An audio take's accents are told louder at :data:`ACCENT_MARGIN` times
this (2.5: above the noise of a mean over a few notes)."""
MAX_LISTED = 60
"""Misses and extras the text report lists at most (a take at the wrong tempo misses nearly everything)."""
BARS_SHOWN = 16
"""Bars the text's per-bar table shows all of; a longer take shows only the bars with something to say."""
BAR_TEMPO_NOTES = 3
"""Matched notes (at two times at least) a bar's local tempo is measured from."""
DRIFT_MIN = 0.02
"""Local tempi rising (or falling) from bar to bar by at least this share in all make a drift (2 % is 2 bpm at
100: a bar's tempo from a few notes 10 ms off is good to about 1 %)."""
WRITTEN_TEMPO_SAME = 0.005
"""Written tempi within this share of each other are one (a MIDI tempo's whole microseconds, a DAW's 0.01 bpm):
past it the exercise's tempo changes (a tempo map) and a take's tempo is said against the written one (2 % slower
than written) rather than in bpm."""
FOLLOW_ONSETS = (3, 8)
"""Onsets (written times struck, their lags averaged) the take's lag trend is fitted on, fewest and most, the last
before a note (:func:`follow_lag`): three on a line (within half the tolerance) tell a slope, as the first three
beats after a tempo change played slow do; eight, two bars of quarter notes, keep it local."""
BEAT_ONSETS = 2
"""Onsets (written times played) a beat needs before it can be told rushed or dragging (:func:`beat_feels`): one
note early is a noisy note, not a rushed beat."""
ON_GRID_BEATS = 1e-3
"""A position within this of a grid point, beats, is on it (:func:`grid_label`): a MIDI file's ticks, the take's
0.5 ms; half a millisecond at 120 bpm."""
SYLLABLES = {Fraction(0): "", Fraction(1, 4): "e", Fraction(1, 2): "&", Fraction(3, 4): "a",
             Fraction(1, 3): " trip", Fraction(2, 3): " let"}
"""How a teacher counts a beat's sixteenths (1 e & a) and eighth-note triplets (1 trip let): ``beat 3&``,
``beat 2 trip``; a position off this grid is told from its nearest point (:func:`grid_label`). The beat is the
meter's 1/D note (:func:`bar_unit`): in x/8 an eighth, its halves ``&`` (sixteenths), its thirds ``trip let``."""
FINE_GRIDS = (6, 8, 12, 16)
"""Finer subdivisions of the beat a written position is told exactly on, as a fraction (``beat 3 + 1/8``, a
thirty-second; sextuplets, sixteenth triplets, sixty-fourths)."""
DEMO = "demo"
"""EXERCISE ``demo`` (with no file of that name): the shipped demo groove, as ``batteur rig --score demo``."""


class CompareError(ValueError):
    """An input the command cannot use; the message names it (exit status 1)."""


@dataclass(frozen=True)
class Played:
    """A note of the take: time (s, the take's clock), kit object, velocity [0, 1], event name."""

    time: float
    drum: str
    velocity: float
    event: str


@dataclass
class Take:
    """The take's notes and what it is: ``kind`` ``MIDI`` or ``WAV audio`` (FLAC...); ``heard``: the kit objects the
    transcriber can name (None: a MIDI take names every drum)."""

    notes: list[Played]
    kind: str
    heard: frozenset[str] | None = None
    warnings: list[str] = field(default_factory=list)
    folded: dict[str, str] = field(default_factory=dict)
    """Per event name the transcriber has no class of its own for but files under one (a splash, a china, a
    second crash under the crash: the Groove MIDI Dataset's reduction), the kit object that class's notes are on."""


# ---------------------------------------------------------------------- reading


def read_exercise(given: str, midi: Mapping[str, Any] | None = None, kit: Kit | None = None) -> Score:
    """The exercise's :class:`~common.score.events.Score` (any score Batteur reads, or ``demo``);
    :class:`CompareError` when it cannot be used. ``midi``: keyword arguments reading a MIDI file
    (``--drum-channels``: :func:`common.score.midi_options.midi_read_kwargs`); ``kit``: ``--kit``'s, the kit a text
    score's object ids (``crash2``) name objects of (None: its ``kit`` line's, else the default; until 7 Dec
    ``--kit``'s was not passed, and an id only its kit has was refused)."""
    from common.score.events import ScoreError, audio_kind
    from common.score.text import read_score

    path = Path(given)
    if given == DEMO and not path.exists():
        from batteur.demo import DEMO_GROOVE
        from common.score.text import parse_text

        return parse_text(DEMO_GROOVE, source="demo", kit=kit)
    head = _head(path)
    if head is not None and audio_kind(head) is not None:
        raise CompareError(f"EXERCISE {path} is a recording ({audio_kind(head)}), not a score: give the score "
                           f"first and the take second ({PROG} EXERCISE TAKE)")
    try:
        score = read_score(path, kit=kit, **(midi or {}))
    except ScoreError as exc:
        raise CompareError(f"EXERCISE {exc}") from None
    if not score.events:
        raise CompareError(f"EXERCISE {path}: the score holds no drum notes")
    return score


CC4_UNUSED = "sends the hi-hat pedal (CC4), not applied"
"""The MIDI reader's notice that ``--hihat-cc4`` would open or close hi-hat notes
(:meth:`common.score.midi_notes.HiHatPedal.unused_notice`): nothing to compare, which matches open and closed
hi-hat notes alike (both the hi-hat)."""


def worth_saying(warnings: Iterable[str]) -> list[str]:
    """A score's or a take's reading warnings but the ones that do not bear on the comparison (:data:`CC4_UNUSED`:
    until 7 Dec the exercise's "would play closed with --hihat-cc4" was said, and the option changed nothing)."""
    return [text for text in warnings if CC4_UNUSED not in text]


def _head(path: Path) -> bytes | None:
    """A regular file's first bytes, else None (the reader says what is wrong with it)."""
    try:
        if not path.is_file():
            return None
        with path.open("rb") as handle:
            return handle.read(4096)
    except OSError:
        return None


def read_take(path: Path, kit: Kit, warn: Callable[[str], None], midi: Mapping[str, Any] | None = None) -> Take:
    """The take's notes with their kit objects: a MIDI file's (read with the keyword arguments ``midi``, as
    :func:`read_exercise`), or an audio file's as the recogniser hears them; :class:`CompareError` for a file it
    cannot use (a score, an unreadable file, no notes)."""
    from common.input_file import file_problem
    from common.score.events import ScoreError, audio_kind, looks_like_text, starts_as_midi
    from common.score.text import MIDI_SUFFIXES

    render = _render_folder(path)
    if render is not None:  # a Batteur render given as the take: its recording is the take, evaluate judges it
        what = "is a render folder" if render == path else f"is a render's {path.name}"
        raise CompareError(f"TAKE {path} {what}, not a take: compare its recording ({render / 'performance.wav'}), "
                           f"or judge the render against its score with batteur evaluate {render}")
    problem = file_problem(path, "a take (MIDI or audio file)")
    if problem is not None:
        raise CompareError(f"TAKE {path}: {problem}")
    head = _head(path)
    if head is None:
        raise CompareError(f"TAKE {path}: cannot read the file")
    if not head:
        raise CompareError(f"TAKE {path}: the file is empty (0 bytes)")
    if not starts_as_midi(head) and looks_like_text(head):  # also a text score named .mid
        raise CompareError(f"TAKE {path} {_text_take(path)}: give a MIDI file of the take (an e-kit's) or its audio "
                           "(WAV, FLAC...)")
    if starts_as_midi(head) or path.suffix.lower() in MIDI_SUFFIXES:  # a .mid that is not MIDI: the reader says
        from common.score.midi import read_midi

        try:
            score = read_midi(path, **(midi or {}))
        except ScoreError as exc:
            raise CompareError(f"TAKE {exc}") from None
        notes = [Played(e.time, drum_of(kit, e.event, e.pitch), e.velocity, e.event.value) for e in score.events]
        if not notes:
            raise CompareError(f"TAKE {path}: the MIDI file holds no drum notes (nothing was played)")
        return Take(notes, "MIDI", warnings=worth_saying(score.warnings))
    kind = audio_kind(head)
    if kind is not None:
        return transcribed(path, kit, kind, warn)
    raise CompareError(f"TAKE {path}: neither a MIDI file nor an audio file (WAV, FLAC, OGG, AIFF, MP3)")


def _render_folder(path: Path) -> Path | None:
    """The render folder ``path`` is (a folder holding a render's impacts.csv and recording), or whose impacts
    file it is (its impacts.csv or report.json); else None."""
    try:
        folder = path if path.is_dir() else path.parent if path.name in ("impacts.csv", "report.json") else None
        if folder is not None and (folder / "impacts.csv").is_file() and (folder / "performance.wav").is_file():
            return folder
    except OSError:
        return None
    return None


def _text_take(path: Path) -> str:
    """What a text file given as the take is: a score (it reads as one), or other text."""
    from common.score.text import parse_text

    try:
        parse_text(path.read_text(encoding="utf-8"))
    except (ValueError, OSError):  # not a score either (or not UTF-8 text after its first bytes)
        return "is a text file, not a recording"
    return "is a score, not a recording (to compare two scores, render one first: batteur render)"


def transcribed(path: Path, kit: Kit, kind: str, warn: Callable[[str], None]) -> Take:
    """An audio take's notes as ``batteur transcribe`` hears them (its model, in-process)."""
    from common.score.gm import EVENT_PITCHES
    from services.recogniser.classes import CLASSES, class_of_pitch
    from services.recogniser.errors import RecogniserError
    from services.recogniser.transcribe import transcribe_file

    try:
        events, _ = transcribe_file(path, warn=lambda text: warn(f"TAKE {text}"))
    except RecogniserError as exc:
        raise CompareError(f"TAKE {exc}") from None
    if not events:
        raise CompareError(f"TAKE {path}: no drum strike recognised in the recording (nothing to compare)")

    def drum(event: EventType) -> str:
        return drum_of(kit, event, None)

    notes = [Played(e.time, drum(CLASSES[e.cls].event_type), e.velocity / 127, CLASSES[e.cls].event_type.value)
             for e in events]
    # the written events a class folds in (by their General MIDI pitch): a splash played is heard as a crash
    folded = {event.value: drum(CLASSES[k].event_type) for event, pitch in EVENT_PITCHES.items()
              if (k := class_of_pitch(pitch)) is not None}
    return Take(notes, f"{kind} audio", heard=frozenset(drum(c.event_type) for c in CLASSES), folded=folded)


def drum_of(kit: Kit, event: EventType, pitch: int | None) -> str:
    """The kit object a note sounds on, as evaluate matches (pedal events on the instrument the pedal drives);
    an event the kit has no object for keeps its own name (it matches only its like)."""
    from batteur.evaluate import expected_instrument

    if event not in kit.events:
        return event.value.lower()
    return expected_instrument(kit, event, pitch)


# ---------------------------------------------------------------------- alignment and matching


def candidate_offsets(written: Sequence[NoteRef], played: Sequence[Played], tolerance: float,
                      limit: int = CANDIDATES) -> list[float]:
    """Offsets (take time - exercise time, s) that line most pairs of notes of one drum up within ``tolerance``,
    the best first, at least ``tolerance`` apart: every (written, played) pair of one drum proposes one, and an
    offset's support is the proposals within ``tolerance`` above it (their median is the candidate)."""
    by_drum: dict[str, list[float]] = defaultdict(list)
    for p in played:
        by_drum[p.drum].append(p.time)
    proposals = []
    for drum, times in _times_by_drum(written).items():
        if drum not in by_drum:
            continue
        a, b = np.asarray(times), np.asarray(by_drum[drum])
        if len(a) * len(b) > MAX_PAIRS:  # a long piece: written notes thinned evenly (a repeated figure stays)
            a = a[np.linspace(0, len(a) - 1, max(1, MAX_PAIRS // len(b))).astype(int)]
        proposals.append((b[None, :] - a[:, None]).ravel())
    if not proposals:
        return []
    d = np.sort(np.concatenate(proposals))
    ends = np.searchsorted(d, d + tolerance, side="right")
    support = ends - np.arange(len(d))
    chosen: list[float] = []
    for i in np.argsort(-support, kind="stable"):
        centre = float(np.median(d[i:ends[i]]))
        if all(abs(centre - c) > tolerance for c in chosen):
            chosen.append(centre)
            if len(chosen) >= limit:
                break
    return chosen


def _times_by_drum(written: Sequence[NoteRef]) -> dict[str, list[float]]:
    out: dict[str, list[float]] = defaultdict(list)
    for n in written:
        out[n.instrument].append(n.time)
    return out


def matched(written: Sequence[NoteRef], played: Sequence[Played], offset: float, tolerance: float
            ) -> list[tuple[int, int]]:
    """Evaluate's one-to-one pairs (written position, played position) with the take moved back by ``offset``."""
    from batteur.evaluate import Hit, match

    if not written:
        return []
    # only the played notes the written span can reach (the tempo search matches a head of a long take many times)
    low = min(n.time for n in written) + offset - tolerance
    high = max(n.time for n in written) + offset + tolerance
    near = [j for j, p in enumerate(played) if low <= p.time <= high]
    pairs = match(written, [Hit(played[j].time - offset, played[j].drum, played[j].velocity) for j in near],
                  tolerance)
    return [(i, near[k]) for i, k in pairs]


def align(written: Sequence[NoteRef], played: Sequence[Played], tolerance: float, limit: int = CANDIDATES
          ) -> tuple[float, list[tuple[int, int]]]:
    """The offset (s) lining the take up with the exercise, and the pairs it gives: of the
    :func:`candidate_offsets`, the one matching most notes (then: least total error; then: the take starting
    earliest in the exercise), moved so that the median matched note is on time. (0.0, []) when nothing
    matches."""
    best: tuple[tuple[int, float, float], float, list[tuple[int, int]]] | None = None
    for start in candidate_offsets(written, played, tolerance, limit):
        offset, pairs = start, matched(written, played, start, tolerance)
        for _ in range(3):  # the median moves the pairs a little; settles in one or two rounds
            if not pairs:
                break
            moved = offset + float(np.median([played[j].time - offset - written[i].time for i, j in pairs]))
            if abs(moved - offset) < 1e-9:
                break
            again = matched(written, played, moved, tolerance)
            if len(again) < len(pairs):
                break
            offset, pairs = moved, again
        if not pairs:
            continue
        error = sum(abs(played[j].time - offset - written[i].time) for i, j in pairs)
        key = (len(pairs), -round(error, 9), -min(written[i].time for i, _ in pairs))
        if best is None or key > best[0]:
            best = (key, offset, pairs)
    return (0.0, []) if best is None else (best[1], best[2])


def leading_count_in(played: Sequence[Played], tolerance: float) -> list[int]:
    """The take's indices of the notes that may be a count-in at its very start: its first onsets (notes within the
    tolerance one) a steady pulse apart (as :func:`count_in_entry` has it), at least :data:`COUNT_IN_NOTES`, each
    striking the first one's kit objects; [] when the take does not start so."""
    order = sorted(range(len(played)), key=lambda j: played[j].time)
    onsets: list[list[int]] = []
    for j in order:
        if onsets and played[j].time - played[onsets[-1][0]].time <= tolerance:
            onsets[-1].append(j)
        else:
            onsets.append([j])
    sound = {played[j].drum for j in onsets[0]} if onsets else set()
    run = 1
    while run < len(onsets) and {played[j].drum for j in onsets[run]} == sound:
        gaps = np.diff([played[o[0]].time for o in onsets[:run + 1]])
        pulse = float(np.median(gaps))
        if not pulse > 0 or np.max(np.abs(gaps - pulse)) > max(tolerance, 0.1 * pulse):
            break
        run += 1
    return [] if run < COUNT_IN_NOTES else [j for onset in onsets[:run] for j in onset]


def align_past_count_in(written: Sequence[NoteRef], played: Sequence[Played], tolerance: float,
                        beat_s: float | None) -> tuple[float, list[tuple[int, int]]]:
    """:func:`align`, a count-in at the take's start (:func:`leading_count_in`) not lined up with the exercise's
    first notes: a count-in of four hi-hats matches a groove's first bar of quarter hi-hats, and the take lined up
    a bar early won by those notes (its first bar "missed", its last bar's fill "after the exercise", until 7 Dec).
    The take is lined up again without those notes; that offset is kept when it matches (with them) at least as
    many notes as the first less the count-in's, and they make a count-in before it (:func:`count_in_entry`)."""
    offset, pairs = align(written, played, tolerance)
    head = set(leading_count_in(played, tolerance))
    if not head or len(head) == len(played):
        return offset, pairs
    rest = [j for j in range(len(played)) if j not in head]
    at, _ = align(written, [played[j] for j in rest], tolerance)
    if abs(at - offset) <= tolerance:
        return offset, pairs
    again = matched(written, played, at, tolerance)
    before = [(played[j].time, played[j].drum) for j in head if played[j].time - at < -max(LOOSE_S, 2 * tolerance)]
    if (len(again) + len(head) < len(pairs) or len(before) < len(head)
            or count_in_entry(before, at, tolerance, beat_s) is None):
        return offset, pairs
    return at, again


@dataclass(frozen=True)
class Restart:
    """The take stopped and came back in (:func:`find_restarts`): from take time ``cut`` (s, the take's own clock:
    the first note after the silence) its notes are ``late_s`` later than the pulse before the silence puts them
    (the pause beyond the written gap); ``silence_s``: the take's time without a note there."""

    cut: float
    late_s: float
    silence_s: float
    rest: bool = False
    """An entry after a written rest (:data:`REST_BEATS`), late or early (``late_s`` < 0): its notes are lined up
    by it to be paired, then kept as played (late or early by it), not re-timed (:func:`_compare_at`)."""


def restarted(played: Sequence[Played], restarts: Sequence[Restart]) -> list[Played]:
    """The take with each restart's pause taken out: every note from a restart's ``cut`` on moved earlier by its
    ``late_s`` (the notes keep their order and positions: index j is the take's note j)."""
    if not restarts:
        return list(played)
    return [replace(p, time=p.time - sum(r.late_s for r in restarts if p.time >= r.cut - 1e-9)) for p in played]


def find_restarts(written: Sequence[NoteRef], played: Sequence[Played], offset: float,
                  pairs: Sequence[tuple[int, int]], tolerance: float, forced: bool, beat_s: float | None = None
                  ) -> tuple[list[Restart], float, list[tuple[int, int]], dict[int, int]]:
    """The places the student stopped and came back in, and the offset and pairs with their pauses taken out
    (:func:`restarted`). A student who stops and restarts plays on their pulse again, later by the pause: taken as
    one, the take's notes after it are all late by it, or, a pause of a beat and a bit, paired with the next beat's
    notes and read "dragging, +100 ms" (until 7 Dec).

    Each silence of the take (between two onsets: notes within the tolerance one) whose length exceeds the written
    gap between the notes on either side of it (the written note the onset before it was matched to and the next
    one; else the onset after it and the one before) by more than the reach of a note played too early or late
    (:data:`LOOSE_S`, 2 tolerances if more) and :data:`RESTART_BEATS` (``beat_s``: the exercise's beat on the
    compared clock, s) is a candidate, the :data:`RESTART_CANDIDATES` longest tried: the notes
    after it moved earlier by that excess, matched at the offset (the notes after the silence then line up) and,
    but for a forced ``--offset``, at the offset less it (the notes before it do: the offset had lined up the part
    after it). The one matching most is a restart when it matches :data:`RESTART_NOTES` more than before (or, a
    pause after the take's first notes or before its last ones, all the fewer written there: until 7 Dec they were
    missed and the notes played for them silently before or after the exercise; such a pause must be
    :data:`STOP_BEATS` beyond the written gap, else those notes were played early or late: returned last, written
    index -> take index, told with their error), and :data:`RESTART_SHARE` of the
    written notes before the restart and of those from it on; then the take is lined up again and the next is
    looked for. ``pairs``: the take's at ``offset`` as one.

    A silence across a written rest (a written gap of :data:`REST_BEATS` at least) is no restart but an entry
    after the rest (:attr:`Restart.rest`), found the same way, late or early (a silence shorter than the rest by
    more than :data:`LOOSE_S`, 2 tolerances if more): the student miscounted the rest, and the notes after it
    are told late or early by it, not timed from it. It is also tried with the entry after the next written rest
    back on the pulse before (the part between the two rests off alone: one move could not line both up)."""
    reach = max(LOOSE_S, 2 * tolerance, RESTART_BEATS * (beat_s or 0.0))
    # the few notes of a take's first or last beats played early or late as one (past the 150 ms a note is claimed
    # within): no eighth to mistake them for on the side nothing is played
    edge_reach = max(LOOSE_S, 2 * tolerance)
    rest_gap = None if beat_s is None else REST_BEATS * beat_s - tolerance
    times = sorted({round(n.time, 6) for n in written})
    note_times = sorted(n.time for n in written)
    # a pause with few notes on one side: a real stop (a beat beyond a restart's half beat), else those notes are off
    stop = max(reach, STOP_BEATS * (beat_s or 0.0))
    found: list[Restart] = []
    strays: dict[int, int] = {}  # written index: take index, the few notes of a pause too short to be a stop
    refused: set[int] = set()  # take indices after such a pause: not tried again
    pairs = list(pairs)
    for _ in range(RESTART_CANDIDATES):
        moved = restarted(played, found)
        order = sorted(range(len(moved)), key=lambda j: moved[j].time)
        onsets: list[list[int]] = []  # take indices, in time order, notes within the tolerance one onset
        for j in order:
            if onsets and moved[j].time - moved[onsets[-1][-1]].time <= tolerance:
                onsets[-1].append(j)
            else:
                onsets.append([j])
        written_of = {j: written[i].time for i, j in pairs}
        head = next((k for k, onset in enumerate(onsets) if any(j in written_of for j in onset)), 0)
        head_of: dict[int, float] = {}
        head_at = offset
        if not forced and sum(map(len, onsets[:head])) >= RESTART_NOTES:
            # the notes before the first one lined up, lined up alone: a groove repeated bar after bar lines its
            # bars after a pause up with its first ones (the notes before the pause then lie before its start)
            notes = [j for onset in onsets[:head] for j in onset]
            head_at, its = align(written, [moved[j] for j in notes], tolerance)
            head_of = {notes[k]: written[i].time for i, k in its}
        tried: list[tuple[float, int, float, float, bool]] = []  # (excess s, first take index after it, silence s,
        # offset, across a written rest)
        rests: list[tuple[int, float]] = []  # (first take index after it, silence s) per silence across a written
        # rest, in time order
        for index, (before, after) in enumerate(zip(onsets, onsets[1:], strict=False)):
            a, b = moved[before[-1]].time, moved[after[0]].time
            anchors = head_of if index + 1 == head and head_of else written_of
            wa = next((anchors[j] for j in before if j in anchors), None)
            wb = next((written_of[j] for j in after if j in written_of), None)
            if wa is not None:  # on the pulse before: the next written onset is where it came back in
                k = bisect.bisect_right(times, wa + tolerance)
                if k == len(times):
                    continue  # after the exercise's last note: a stray note, no restart
                gap = times[k] - wa
            elif wb is not None:  # on the pulse after (the offset lined that part up): the onset before it
                k = bisect.bisect_left(times, wb - tolerance) - 1
                if k < 0:
                    continue  # the exercise's first note: a late entry after a count-in, no restart
                gap = wb - times[k]
            else:
                continue
            if wb is not None and wa is not None and rest_gap is not None:
                # the written gap before the note it came back in on, as paired: a part lined up a beat off (a
                # groove's hi-hat eighths match so) hides a rest from the note before, not from this one
                k = bisect.bisect_left(times, wb - tolerance) - 1
                if k >= 0 and wb - times[k] >= rest_gap:
                    gap = max(gap, wb - times[k])
            rest = rest_gap is not None and gap >= rest_gap
            if rest:
                rests.append((after[0], b - a))
            # an entry's notes are kept as played: an entry off beyond the tolerance is one (its notes are not on
            # time); a pause with few written notes on one side (the take's first or last beat) is tried from the
            # 150 ms reach on (those notes 0.25 s late read as missed and extra until 8 Dec)
            came = wb if wb is not None else times[k]  # the written onset it came back in on
            ahead = bisect.bisect_left(note_times, came - tolerance)
            edge = min(ahead, len(note_times) - ahead) < RESTART_NOTES
            if (abs(b - a - gap) > tolerance) if rest else (b - a - gap > (edge_reach if edge else reach)):
                tried.append((b - a - gap, after[0], b - a, head_at if anchors is head_of else offset, rest))
        best: tuple[list[Restart], float, list[tuple[int, int]], int] | None = None
        tried = [c for c in tried if c[1] not in refused]
        for excess, j, silence, start, rest in sorted(tried, key=lambda c: -abs(c[0]))[:RESTART_CANDIDATES]:
            moves = [[Restart(played[j].time, excess, silence, rest)]]
            later = [(k, quiet) for k, quiet in rests if moved[k].time > moved[j].time]
            if rest and later:  # the part up to the next rest off alone: the entry after it back on the pulse
                k, quiet = later[0]
                moves.append([*moves[0], Restart(played[k].time, -excess, quiet, True)])
            for move in moves:
                shifted = restarted(played, [*found, *move])
                for at in (start,) if forced or start != offset else (offset, offset - excess):
                    again = matched(written, shifted, at, tolerance)
                    if best is None or len(again) > len(best[2]):
                        best = (move, at, again, j)
        if best is None or len(best[2]) <= len(pairs):
            break
        move, at, again, j = best
        # the written notes before the note it came back in on (less the tolerance) and from it on: each half played
        split = restarted(played, [*found, *move])[j].time - at - tolerance
        earlier = [n.time < split for n in written]
        before_n, before_m = sum(earlier), sum(earlier[i] for i, _ in again)
        few = min(before_n, len(written) - before_n)
        side = before_n == few  # the side of the few notes: True, before it
        if few < RESTART_NOTES:
            # all of those matched, and more in all: the take as one may have paired one of them with a neighbour
            # (a first beat 0.3 s early: its 1& 50 ms early for the 1), so it need not gain each
            gained = (len(again) > len(pairs)
                      and sum(earlier[i] == side for i, _ in again) == (before_n if side else len(written) - before_n))
        else:
            gained = len(again) >= len(pairs) + RESTART_NOTES and (move[0].rest or move[0].late_s > reach)
        if not gained or before_m < RESTART_SHARE * before_n \
                or len(again) - before_m < RESTART_SHARE * (len(written) - before_n):
            if move[0].rest or move[0].late_s > reach:
                break
            refused.add(j)  # a candidate only the first or last beats' reach let in: the next is tried
            continue
        if few < RESTART_NOTES and not move[0].rest and move[0].late_s < stop:
            # no real stop: the few notes on that side (a last crash held on, a first downbeat early) were played
            # early or late, paired as the move lined them up (the take's pairs of them let go: a neighbour's),
            # told with their error against the take as one; the next candidate is tried
            now = restarted(played, found)
            theirs = {i: k for i, k in again if earlier[i] == side}
            pairs = sorted([(i, k) for i, k in pairs if earlier[i] != side and k not in theirs.values()]
                           + [(i, k) for i, k in theirs.items()
                              if abs(now[k].time - offset - written[i].time) <= tolerance])
            paired = {i for i, _ in pairs}
            strays.update({i: k for i, k in theirs.items() if i not in paired})
            refused.add(j)
            continue
        found.extend(move)
        if forced:
            pairs = again
        else:
            offset, pairs = align(written, restarted(played, found), tolerance)
    return sorted(found, key=lambda r: r.cut), offset, pairs, strays


def follow_lag(written: Sequence[NoteRef], played: Sequence[Played], offset: float, tolerance: float,
               pairs: Mapping[int, int], claimed: Mapping[int, int], missed: Sequence[int],
               loose: Mapping[str, Sequence[int]]) -> tuple[dict[int, int], dict[int, int]]:
    """The pairs and the notes played too early or late (``claimed``: written index -> played index, the nearest
    within the 150 ms reach) redone along the take's lag where it falls behind (runs ahead) bar after bar: a tempo
    change played at 110 where 120 is written is 45 ms more behind each beat, its notes leave the reach (they were
    "missed", with as many "extras" an eighth-triplet off), and once more than half a note behind, the nearest
    written note of a strike is the next one (a note 290 ms late read as 210 ms early for the note after), or a
    sixteenth's neighbour within the tolerance (a pair: "dragging, +32 ms" in a take running 5 % ahead, until
    7 Dec).

    The written notes are walked in time order. At each, the lag (played - written, s, ``offset`` taken off) is
    fitted as a line through the last :data:`FOLLOW_ONSETS` onsets struck before it (the pairs and the notes
    decided so far; its own onset's other notes not: they are walked next), the most of them within half the
    tolerance of it; where the last onset is beyond the tolerance on the side the line heads to, the note of its
    drum nearest the line's lag at it, within the tolerance of it, is the one played for it: a note no written
    note has (``loose``: per drum the played indices not in ``pairs``, and those a pair here let go), or one
    paired or claimed for a later written note (which is walked again, without it). A pair stays unless the line
    is beyond the tolerance from its lag. No line is extrapolated further than the onsets it is fitted on span,
    nor steeper than :data:`TEMPO_GRID`'s tempi; where there is none, or no note near it, the note keeps what it
    had. Returns the pairs (a pair redone is one when within the tolerance) and the written index -> played index
    of every note played too early or late.

    On a take on tempo the last onset is within the tolerance (or a lone note off is no line) and everything
    stays."""
    decided = {**pairs, **claimed}
    paired = set(pairs)  # written notes whose note (a pair's or a redone pair's) counts as a pair when within it
    redone: set[int] = set()
    owner = {j: i for i, j in decided.items()}
    onsets: dict[float, list[float]] = defaultdict(list)  # written time (s, rounded): lags s

    def lag_of(i: int, j: int) -> float:
        return played[j].time - offset - written[i].time

    for i, j in decided.items():
        onsets[round(written[i].time, 6)].append(lag_of(i, j))
    keys = sorted(onsets)
    slopes = (1.0 / TEMPO_GRID[1] - 1.0, 1.0 / TEMPO_GRID[0] - 1.0)  # lag s per written s
    pool: dict[str, list[tuple[float, int]]] = defaultdict(list)  # per drum (time s, played index): loose or paired
    for drum, js in loose.items():
        pool[drum].extend((played[j].time - offset, j) for j in js)
    for j in pairs.values():
        pool[played[j].drum].append((played[j].time - offset, j))
    for notes in pool.values():
        notes.sort()
    pool_times = {drum: [at for at, _ in notes] for drum, notes in pool.items()}
    todo = sorted({*decided, *missed}, key=lambda k: (written[k].time, k))
    while todo:
        i = todo.pop(0)
        t, key = written[i].time, round(written[i].time, 6)
        old = decided.get(i)
        recent: list[float] = []  # the last onsets before it, struck (a note taken back leaves its time empty)
        for k in reversed(keys[:bisect.bisect_left(keys, key)]):  # its own onset not: its other notes are walked next
            if onsets[k]:
                recent.append(k)
                if len(recent) == FOLLOW_ONSETS[1]:
                    break
        lag = _lag_line(recent[::-1], onsets, t, tolerance, slopes)
        if lag is None or (old is not None and i in pairs and abs(lag_of(i, old) - lag) <= tolerance):
            continue  # no trend to follow, or a pair on it: it stays
        best = None
        drum = written[i].instrument
        if drum in pool:
            at = pool_times[drum]
            near = [(abs(pool[drum][k][0] - t - lag), pool[drum][k][1])
                    for k in range(bisect.bisect_left(at, t + lag - tolerance),
                                   bisect.bisect_right(at, t + lag + tolerance))]
            near = [(d, j) for d, j in near if j == old or owner.get(j) is None
                    or (written[owner[j]].time, owner[j]) > (t, i)]  # free, its own, or a later note's
            best = min(near)[1] if near else None
        if best is None or best == old:
            continue
        if old is not None:
            onsets[key].remove(lag_of(i, old))
            del owner[old]
        other = owner.get(best)
        if other is not None:  # taken from a later note: that one is walked again, without it
            onsets[round(written[other].time, 6)].remove(lag_of(other, best))
            del decided[other]
            if other not in todo:
                todo.append(other)
                todo.sort(key=lambda k: (written[k].time, k))
        decided[i], owner[best] = best, i
        if i in paired:
            redone.add(i)
        if key not in onsets:
            bisect.insort(keys, key)
        onsets[key].append(lag_of(i, best))
    new_pairs = {i: j for i, j in decided.items() if i in paired
                 and (i not in redone or abs(lag_of(i, j)) <= tolerance)}
    return new_pairs, {i: j for i, j in decided.items() if i not in new_pairs}


def _lag_line(times: Sequence[float], onsets: Mapping[float, Sequence[float]], t: float, tolerance: float,
              slopes: tuple[float, float]) -> float | None:
    """The lag (s) at written time ``t`` on the line through the most of the onsets ``times`` (the last first, at
    least :data:`FOLLOW_ONSETS`'s fewest) that lie within half the tolerance of it, when the last onset is beyond
    the tolerance on the side the line heads to, ``t`` is no further from it than the onsets span and the slope
    (lag s per written s) is within ``slopes``; else None (:func:`follow_lag`)."""
    x = np.asarray(times, dtype=float)
    if len(x) < FOLLOW_ONSETS[0]:
        return None
    y = np.array([float(np.mean(onsets[k])) for k in times])
    if abs(y[-1]) <= tolerance:  # not yet off: a note there is the matching's or the 150 ms reach's
        return None
    for k in range(len(x), FOLLOW_ONSETS[0] - 1, -1):
        xs, ys = x[-k:], y[-k:]
        span = float(xs[-1] - xs[0])
        if span <= 0 or t - xs[-1] > span:
            continue
        slope, intercept = (float(v) for v in np.polyfit(xs, ys, 1))
        if np.max(np.abs(ys - (slope * xs + intercept))) > tolerance / 2:
            continue
        if not slopes[0] <= slope <= slopes[1]:
            return None
        lag = slope * t + intercept
        return lag if lag * y[-1] > 0 and abs(lag) >= abs(y[-1]) - tolerance / 2 else None
    return None


def wrong_drum_pairs(written: Sequence[tuple[float, str]], played: Sequence[tuple[float, str]], tolerance: float,
                     family: Callable[[str], str]) -> list[tuple[int, int]]:
    """One-to-one pairs (written position, played position) of notes on different drums within ``tolerance`` of
    each other: the most pairs, then the fewest pairing a cymbal with a drum (:func:`drum_family`: a ride played
    for the hi-hat rather than for the snare written with it), then the least total error; as evaluate's
    matching, solved per cluster of times within reach (:func:`scipy.optimize.linear_sum_assignment`).
    ``written``/``played``: (time s on one clock, kit object)."""
    from scipy.optimize import linear_sum_assignment

    from batteur.evaluate import reach_clusters

    pairs: list[tuple[int, int]] = []
    for ia, jb in reach_clusters([t for t, _ in written], [t for t, _ in played], tolerance):
        if not ia or not jb:
            continue
        d = np.abs(np.array([written[i][0] for i in ia])[:, None] - np.array([played[j][0] for j in jb])[None, :])
        other = np.array([[written[i][1] != played[j][1] for j in jb] for i in ia])
        ok = (d <= tolerance + 1e-12) & other
        if not ok.any():
            continue
        apart = np.array([[family(written[i][1]) != family(played[j][1]) for j in jb] for i in ia])
        # a pair is worth more than any sum of errors and family penalties (each under 2 tolerances)
        big = 1.0 + 2 * tolerance * (len(ia) + len(jb))
        cost = np.where(ok, d + tolerance * apart - big, 0.0)
        rows, cols = linear_sum_assignment(cost)
        pairs += [(ia[r], jb[c]) for r, c in zip(rows, cols, strict=True) if ok[r, c]]
    return sorted(pairs)


def drum_family(kit: Kit, drum: str) -> str:
    """``cymbal`` (cymbals and the hi-hat), ``drum`` (membranes), else the object's kind, or the name of an object
    the kit does not have: what may stand for what in :func:`wrong_drum_pairs`."""
    try:
        kind = kit.object(drum).kind
    except KeyError:
        return drum
    return "cymbal" if kind in ("cymbal", "hihat") else "drum" if kind == "membrane" else kind


def scaled(written: Sequence[NoteRef], scale: float) -> list[NoteRef]:
    """The written notes played ``scale`` times faster (times divided by it)."""
    return [replace(n, time=n.time / scale) for n in written]


def find_tempo(written: Sequence[NoteRef], played: Sequence[Played], tolerance: float, offset: float | None
               ) -> tuple[float, int]:
    """The tempo ratio (take / exercise) matching most notes, and how many it matches.

    Over :data:`TEMPO_GRID` (a coarse geometric grid, then a finer one around its best, the least total error
    among equals) on the exercise's first :data:`TEMPO_NOTES` notes (quick on a long piece); then refined
    (:func:`refine_tempo`) over windows doubling from the first matched note, since a ratio off by a grid step
    drifts out of the tolerance over a long piece (0.1 % is 0.1 s over 100 s). ``offset`` forced, else aligned at
    each grid ratio."""

    def pairs_at(scale: float, notes: Sequence[NoteRef], limit: int = 3) -> tuple[float, list[tuple[int, int]]]:
        moved = scaled(notes, scale)
        if offset is not None:
            return offset, matched(moved, played, offset, tolerance)
        return align(moved, played, tolerance, limit=limit)

    def error(scale: float, at: tuple[float, list[tuple[int, int]]]) -> float:
        return sum(abs(played[j].time - at[0] - head[i].time / scale) for i, j in at[1])

    head = sorted(written, key=lambda n: n.time)[:TEMPO_NOTES]
    low, high, step = TEMPO_GRID
    grid = np.exp(np.arange(math.log(low), math.log(high) + 1e-9, math.log1p(step)))
    best = float(max(grid, key=lambda s: (len(pairs_at(float(s), head)[1]), -abs(math.log(s)))))
    fine = best * np.exp(np.linspace(-math.log1p(step), math.log1p(step), 21))
    tried = {float(s): pairs_at(float(s), head) for s in fine}
    scale = max(tried, key=lambda s: (len(tried[s][1]), -error(s, tried[s])))
    start, pairs = tried[scale]
    if not pairs:
        return scale, 0
    first = min(head[i].time for i, _ in pairs)
    return refine_tempo(written, played, tolerance, scale, start, offset is not None, first,
                        span=tolerance / (math.log1p(step) / 10))


def refine_tempo(written: Sequence[NoteRef], played: Sequence[Played], tolerance: float, scale: float,
                 offset: float, forced: bool, first: float, span: float) -> tuple[float, int]:
    """The ratio ``scale`` (and ``offset``, unless ``forced``) refined as the line take time = exercise time /
    scale + offset through the pairs of the written notes from ``first`` to ``first + span`` s, the span doubled
    each round until it holds the whole exercise. Each round matches at the line so far and fits the line through
    the pairs within half the tolerance of a first fit (a note paired with its neighbour an eighth off does not
    pull the line), kept when it matches at least as many notes. ``span``: where the grid's ratio is good to
    the tolerance. The ratio and how many notes it matches over the whole exercise (aligned there again, as
    ``batteur compare --tempo-scale`` with that ratio does, unless ``forced``)."""
    notes = sorted(written, key=lambda n: n.time)
    times = np.array([n.time for n in notes])
    while True:
        window = notes[:int(np.searchsorted(times, first + span, side="right"))]
        pairs = matched(scaled(window, scale), played, offset, tolerance)
        line = _fit_line(window, played, pairs, tolerance, offset if forced else None)
        if line is not None:
            again = matched(scaled(window, line[0]), played, line[1], tolerance)
            if len(again) >= len(pairs):
                scale, offset = line
        if len(window) == len(notes):
            break
        span *= 2
    if forced:
        return scale, len(matched(scaled(notes, scale), played, offset, tolerance))
    # aligned again over the whole exercise: a repeated groove lines its first notes up as well a bar or two on,
    # which the head cannot tell but the last notes can (they have nothing to pair with)
    return scale, len(align(scaled(notes, scale), played, tolerance)[1])


def _fit_line(written: Sequence[NoteRef], played: Sequence[Played], pairs: Sequence[tuple[int, int]],
              tolerance: float, offset: float | None) -> tuple[float, float] | None:
    """(scale, offset) of the least-squares line take time = exercise time / scale + offset through ``pairs``,
    refitted on the pairs within half the tolerance of it; through ``offset`` when given. None when it cannot be
    fitted (fewer than two pairs, one time, a slope not positive)."""
    x = np.array([written[i].time for i, _ in pairs])
    y = np.array([played[j].time for _, j in pairs])
    keep = np.ones(len(x), dtype=bool)
    fit: tuple[float, float] | None = None
    for _ in range(2):
        if keep.sum() < 2 or np.ptp(x[keep]) <= 0:
            break
        if offset is None:
            slope, intercept = (float(v) for v in np.polyfit(x[keep], y[keep], 1))
        else:
            slope, intercept = float(np.dot(x[keep], y[keep] - offset) / np.dot(x[keep], x[keep])), offset
        if not slope > 0:
            break
        fit = (1.0 / slope, intercept)
        keep = np.abs(y - (slope * x + intercept)) <= tolerance / 2
    return fit


def ratio_digits(ratio: float, duration: float, tolerance: float) -> float:
    """``ratio`` rounded to the fewest decimals (3 to 6) that drift less than a quarter of the tolerance over
    ``duration`` s: the --tempo-scale said for a long take must match as the ratio found does."""
    for decimals in range(3, 7):
        rounded = round(ratio, decimals)
        if abs(math.log(rounded / ratio)) * duration <= tolerance / 4:
            break
    return rounded


# ---------------------------------------------------------------------- the report


def position(score: Score, written_time: float, scale: float = 1.0) -> dict[str, Any]:
    """Bar and beat (both from 1, the beat fractional) of a time on the exercise's written clock, and ``where``,
    the position as a teacher says it (:func:`grid_label`; ``scale``: the tempo ratio compared at, for its ms on
    the take's clock); before its first beat (but for a strike just before it, :func:`grid_point`), none. The bar
    is that of the nearest grid point, as ``where`` says it: a strike 20 ms before bar 3 is bar 3's, its beat just
    under 1 (0.96). After a pick-up (:func:`pickup`) the first full bar is bar 1, as printed music numbers it, and
    the pick-up bar 0, its beats counted as the end of a full bar (a one-beat pick-up before 4/4 is beat 4). A time
    whose nearest point is the exercise's end (:func:`last_bar`) is the last bar's: ``end of bar 4 (20 ms early)``,
    beat 4.96."""
    point = grid_point(score, written_time)
    if point is None:
        return {"bar": None, "beat": None, "where": "before bar 1"}
    last = last_bar(score)
    if last is not None and point.bar > last[0] and point.time >= last[3] - 1e-6:
        # the exercise's end is its nearest point (a strike within the tolerance of it, which compare keeps): no bar
        # after the last, told in the last bar as its end (until 7 Dec "bar 5, beat 1 (20 ms early)"
        # and a row of its own in the bar table, 0 written, after a 4-bar exercise)
        bar, beat_at, spacing, end = last
        late_ms = (written_time - end) * 1000 / scale
        where = f"end of bar {bar}" + (f" ({abs(late_ms):.0f} ms {'late' if late_ms > 0 else 'early'})"
                                       if round(abs(late_ms)) >= 1 else "")
        return {"bar": bar, "beat": _r(beat_at + (written_time - end) / spacing, 3), "where": where}
    beat = point.beat + float(point.grid) + (written_time - point.time) / point.spacing
    return {"bar": point.bar, "beat": _r(beat, 3), "where": grid_label(score, written_time, scale)}


def last_bar(score: Score) -> tuple[int, float, float, float] | None:
    """(the exercise's last bar, numbered as :func:`position` says, the counted beat its end falls on (5 in 4/4,
    7 in 6/8), that bar's beat length s, the end on the written clock s: :func:`exercise_end`) when the exercise
    ends on a bar line after its last note (a text score's last bar, a MIDI file's); None when a note lies at the
    end (its bar is the last) or the score has no beats."""
    end = exercise_end(score)
    if not score.events or score.events[-1].time >= end - 1e-6:
        return None
    at = bar_and_beat(score, end - 1e-6)  # just before the end: in the last bar (float-safe)
    if at is None:
        return None
    bar, beat, spacing = at
    return bar, beat + 1e-6 / spacing, spacing, end


@dataclass(frozen=True)
class GridPoint:
    """The counting grid's point nearest a time (:func:`grid_point`): its ``bar`` and counted ``beat`` (from 1,
    numbered as :func:`position` says), ``grid`` where in that beat (0 on it, 1/2 its &), ``exact`` when the time
    is on it (within :data:`ON_GRID_BEATS`, or on a :data:`FINE_GRIDS` subdivision: then ``grid`` is that), ``time``
    the point on the written clock (s) and ``spacing`` the length (s) of the counted beat the point is in: for a
    time just before the next beat, that beat's (until 7 Dec this one's: 20 ms before a 6/8 bar
    after a 4/4 one at 120 bpm was beat 0.96 there, 0.92 before the next 6/8 bar)."""

    bar: int
    beat: int
    grid: Fraction
    exact: bool
    time: float
    spacing: float


def grid_point(score: Score, written_time: float) -> GridPoint | None:
    """The grid point a time is counted at: the coarsest subdivision it lies on, else the nearest sixteenth or
    triplet point (:data:`SYLLABLES`), the next beat's (or bar's) first point included, so a strike just before a
    downbeat is that bar's, in its label and its bar alike. Before the first beat, the first beat when the time is
    nearer it than the grid point before it (an eighth of a beat: a strike just ahead of bar 1, a sixteenth of a
    count-in being the point before); else None."""
    at = bar_and_beat(score, written_time)
    if at is None:
        first = float(score.beats[0]) if len(score.beats) >= 2 else None
        start = None if first is None else bar_and_beat(score, first)
        if first is None or start is None or first - written_time > start[2] / 8:
            return None
        return GridPoint(start[0], math.floor(start[1] + 1e-6), Fraction(0),
                         first - written_time <= ON_GRID_BEATS * start[2], first, start[2])
    bar, beat, spacing = at
    whole = math.floor(beat + 1e-6)
    frac = beat - whole
    grid: Fraction | None = None
    for n in (1, 2, 3, 4, *FINE_GRIDS):  # the coarsest subdivision it lies on
        k = round(frac * n)
        if abs(frac - k / n) <= ON_GRID_BEATS:
            grid = Fraction(k, n)
            break
    exact = grid is not None
    if grid is None:
        grid = min((*SYLLABLES, Fraction(1)), key=lambda g: (abs(frac - float(g)), g))
    point = written_time + (float(grid) - frac) * spacing  # s, the grid point on the written clock
    if grid == 1:  # the next beat's first point: maybe the next bar's (looked up just after it, float-safe)
        again = bar_and_beat(score, point + 1e-6)
        # measured in that beat's length: at a meter change (4/4 -> 6/8) the next bar's eighth, not this quarter
        bar, whole, grid, spacing = (bar, whole + 1, Fraction(0), spacing) if again is None else (
            again[0], math.floor(again[1] + 1e-6), Fraction(0), again[2])
    return GridPoint(bar, whole, grid, exact, point, spacing)


def grid_label(score: Score, written_time: float, scale: float = 1.0) -> str:
    """``bar 3, beat 2&``: a position on the beat's grid (:func:`grid_point`), counted as :data:`SYLLABLES`
    (``beat 2``, ``2e``, ``2&``, ``2a``, ``2 trip``, ``2 let``) or, on a :data:`FINE_GRIDS` subdivision, as a
    fraction (``beat 2 + 1/8``); off those (a strike, a humanised MIDI exercise), the nearest sixteenth or triplet
    point and how far from it on the take's clock (``beat 2& (12 ms late)``; ``scale``: the tempo ratio, take /
    exercise), the next beat's (or bar's) first point included (``bar 4, beat 1 (20 ms early)``)."""
    point = grid_point(score, written_time)
    if point is None:
        return "before bar 1"
    late_ms = (written_time - point.time) * 1000 / scale
    text = f"bar {point.bar}, beat {point.beat}{SYLLABLES.get(point.grid, f' + {point.grid}')}"
    if not point.exact and round(abs(late_ms)) >= 1:
        text += f" ({abs(late_ms):.0f} ms {'late' if late_ms > 0 else 'early'})"
    return text


def where_text(entry: dict[str, Any]) -> str:
    """``bar 3, beat 2&`` (:func:`grid_label`; ``before bar 1`` ahead of the first beat)."""
    if "where" in entry:
        return str(entry["where"])
    if entry["bar"] is None:
        return "before bar 1"
    return f"bar {entry['bar']}, beat {entry['beat']:g}"


def timing(errors_s: Sequence[float]) -> dict[str, float | int | None]:
    """Mean and standard deviation of played - written times, ms (positive: late), and how many."""
    if not errors_s:
        return {"mean_ms": None, "sd_ms": None, "n": 0}
    e = np.asarray(errors_s) * 1000.0
    # + 0.0: no "-0.0 ms" for a mean rounded to zero
    return {"mean_ms": round(float(e.mean()), 1) + 0.0, "sd_ms": round(float(e.std()), 1) + 0.0, "n": int(e.size)}


def normal_level(velocities: Iterable[float]) -> int | None:
    """The most common written level (MIDI velocity, from ``velocities`` in [0, 1]; a tie, the one nearest their
    median, then the lower): a text score's plain ``x``. None without notes."""
    counts = Counter(round(v * 127) for v in velocities)
    if not counts:
        return None
    middle = float(np.median(list(counts.elements())))
    return max(counts, key=lambda k: (counts[k], -abs(k - middle), -k))


def dynamics(pairs: Sequence[tuple[float, float]], margin: float = ACCENT_MARGIN, normal: int | None = None
             ) -> dict[str, Any] | None:
    """Written against played velocities of one drum's matched notes, MIDI 0-127 (``pairs``: (written, played)
    in [0, 1]): the played mean and spread, the rank agreement of written and played (evaluate's Spearman; None
    when either side is flat), for a score of a few written levels (a text score's ghost, plain and accent: at
    most :data:`FEW_LEVELS`) the played mean per level, and where the score writes accents (its levels from the
    top gap of :data:`WRITTEN_ACCENT_GAP` up) whether they were played louder on average than the rest, by
    ``margin`` (:data:`ACCENT_MARGIN`; an audio take's less, :data:`AUDIO_VELOCITY_SCALE`). A drum without
    written accents gets no accent verdict (a MIDI exercise's toms at 92 and 98 read "ACCENTS NOT LOUDER" until
    7 Dec). Levels at or below ``normal`` (the exercise's normal level, :func:`normal_level`; else this drum's) are
    no accents: a split between them and lower ones is normal notes against ghost notes, whether the ghosts were
    played softer by ``margin`` (a snare of ``x`` and ``g`` read its backbeats as accents, ghosts played as loud
    "ACCENTS NOT LOUDER: 89 against 89" with no accent written, until 7 Dec). None without pairs."""
    from batteur.evaluate import spearman

    if not pairs:
        return None
    played = [p * 127 for _, p in pairs]
    out: dict[str, Any] = {"played_mean": round(float(np.mean(played)), 1),
                           "played_sd": round(float(np.std(played)), 1),
                           "spearman": spearman([(w, p, "") for w, p in pairs])}
    levels: dict[int, list[float]] = defaultdict(list)
    for w, p in pairs:
        levels[round(w * 127)].append(p * 127)
    if 1 < len(levels) <= FEW_LEVELS:
        out["levels"] = {str(k): {"n": len(v), "played_mean": round(float(np.mean(v)), 1)}
                         for k, v in sorted(levels.items())}
    ranked = sorted(levels, reverse=True)
    split = next((k for k in range(len(ranked) - 1) if ranked[k] - ranked[k + 1] >= WRITTEN_ACCENT_GAP), None)
    if normal is None:
        normal = normal_level(w for w, _ in pairs)
    if split is not None and normal is not None and ranked[split] <= normal:
        # the louder side holds the normal level: no accents; the softer one is ghost notes
        loud = float(np.mean([p for k in ranked[:split + 1] for p in levels[k]]))
        ghosts = float(np.mean([p for k in ranked[split + 1:] for p in levels[k]]))
        out["ghosts_softer"] = loud - ghosts >= margin
        out["ghosts_barely_softer"] = 0 < loud - ghosts < margin
        out["ghost_margin"] = round(loud - ghosts, 1) + 0.0
        out["ghost_margin_needed"] = round(margin, 1)
        out["ghost_mean"], out["others_mean"] = round(ghosts, 1), round(loud, 1)
    elif split is not None:
        top = set(ranked[:split + 1])
        accents = float(np.mean([p for k in top for p in levels[k]]))
        rest = float(np.mean([p for k, v in levels.items() if k not in top for p in v]))
        out["accents_louder"] = accents - rest >= margin
        out["accents_barely_louder"] = 0 < accents - rest < margin
        out["accent_margin"] = round(accents - rest, 1) + 0.0
        out["accent_margin_needed"] = round(margin, 1)
        out["accent_mean"], out["others_mean"] = round(accents, 1), round(rest, 1)
    return out


def bar_rows(score: Score, written: Sequence[tuple[float, float]], pairs: Sequence[tuple[int, float, float]],
             missed: Sequence[int], off: Sequence[int], wrong: Sequence[int], extra_bars: Sequence[int | None],
             tolerance: float, late: Sequence[tuple[int, float, float]] = (), entered: Mapping[int, float] | None = None
             ) -> list[dict[str, Any]]:
    """One row per bar of the exercise (its first bar to the bar of its last written note, as :func:`position`
    numbers them): written, played, missed, too early/late, played on another drum (``wrong_drum``) and extra
    notes, the mean timing (ms, + late) of the notes played on their drum, within the tolerance or beyond it, and
    ``feel`` (``rushed``/``dragging`` when that mean is beyond half the tolerance, else None), and the bar's local
    tempo (``bpm``, quarter notes a minute as the exercise's tempo; None under :data:`BAR_TEMPO_NOTES` such notes):
    the slope of the take's times against the notes' written positions in quarter notes (least squares,
    :func:`quarters`), beside ``written_bpm``, the same slope of their written times: the bar's own written tempo
    (its tempo map's), which the played one is measured against. Until 7 Dec the notes too early or
    late were left out of the mean, the feel and the tempo: a bar whose second half was 90 to 140 ms late read
    +11 ms, neither dragging, from its first half's notes alone.

    ``written``: each written note's (exercise clock, compared clock) time, s; ``pairs``: (written index, take
    time s, played - written s) within the tolerance (``played``), ``late`` the same beyond it;
    ``missed``/``off``/``wrong``: written indices; ``extra_bars``: each extra's bar (its nearest grid point's, as
    :func:`position` says it); ``entered``: per written index, the lag (s) of the entry after a written rest its
    note came in with (:func:`rest_entry`): the feel is judged against it (a bar entered a beat late and played
    steadily on is no "dragging, +500 ms", as until 8 Dec; its mean stays the notes' own)."""
    entered = entered or {}
    # each note's bar as its position says it (grid_point: a humanised note just before a downbeat is that bar's)
    labels: list[Any] = [None if (at := grid_point(score, t)) is None else at.bar for t, _ in written]
    known = [b for b in labels if b is not None]
    if not known:
        return []
    first = 0 if pickup(score) is not None else 1
    # an extra's bar too (a strike just before the bar after the last written note: a row of its own)
    last = max(known + [b for b in extra_bars if b is not None])
    rows: dict[int, dict[str, Any]] = {
        b: {"bar": b, "written": 0, "played": 0, "missed": 0, "off_tolerance": 0, "wrong_drum": 0, "extra": 0,
            "mean_ms": None, "feel": None, "entry_ms": None, "bpm": None, "written_bpm": None}
        for b in range(min(first, min(known)), last + 1)}
    for b in known:
        rows[b]["written"] += 1
    for key, indices in (("missed", missed), ("off_tolerance", off), ("wrong_drum", wrong)):
        for i in indices:
            if labels[i] is not None:
                rows[labels[i]][key] += 1
    for b in extra_bars:
        if b in rows:
            rows[b]["extra"] += 1
    by_bar: dict[int, list[tuple[float, float, float, float]]] = defaultdict(list)  # (written s, take s, error s,
    # error against the entry s)
    for i, take_time, error in [*pairs, *late]:
        if labels[i] is not None:
            by_bar[labels[i]].append((written[i][0], take_time, error, error - entered.get(i, 0.0)))
    for i, _, _ in pairs:
        if labels[i] is not None:
            rows[labels[i]]["played"] += 1
    for b, notes in by_bar.items():
        row = rows[b]
        mean = float(np.mean([e for _, _, e, _ in notes])) * 1000
        row["mean_ms"] = _r(mean, 1)
        feel = float(np.mean([e for _, _, _, e in notes])) * 1000
        if abs(feel) > tolerance * 1000 / 2:
            row["feel"] = "rushed" if feel < 0 else "dragging"
        if any(e != f for _, _, e, f in notes):  # the lag its feel is judged against: an entry's after a rest
            row["entry_ms"] = _r(mean - feel, 1)
        x = np.array([w for w, _, _, _ in notes])
        y = np.array([t for _, t, _, _ in notes])
        if len(score.beats) >= 2 and len(notes) >= BAR_TEMPO_NOTES and np.ptp(x) > 0:
            q = quarters(score, x)
            played_s = float(np.polyfit(q, y, 1)[0])  # take seconds per written quarter note
            written_s = float(np.polyfit(q, x, 1)[0])  # written seconds per quarter note: the bar's tempo map
            if played_s > 0 and written_s > 0:
                row["bpm"], row["written_bpm"] = round(60.0 / played_s, 1), round(60.0 / written_s, 1)
    return list(rows.values())


def quarters(score: Score, times: np.ndarray) -> np.ndarray:
    """Written times (s, the exercise's clock) as quarter notes from its first beat through its tempo map (the
    score's beats; the first and last spacings go on beyond them). The score has two beats at least."""
    beats = np.asarray(score.beats, dtype=float)
    t = np.asarray(times, dtype=float)
    out = np.interp(t, beats, np.arange(len(beats), dtype=float))
    before, after = t < beats[0], t > beats[-1]
    out[before] = (t[before] - beats[0]) / (beats[1] - beats[0])
    out[after] = len(beats) - 1 + (t[after] - beats[-1]) / (beats[-1] - beats[-2])
    return out


def same_tempo(low: float, high: float) -> bool:
    """Whether two written tempi (bpm) are one (within :data:`WRITTEN_TEMPO_SAME`)."""
    return high <= low * (1 + WRITTEN_TEMPO_SAME)


def written_tempi(score: Score) -> tuple[float, float] | None:
    """The slowest and fastest written tempo (bpm) of the exercise's beats up to its end (its tempo map); None
    without two beats."""
    beats = np.asarray(score.beats, dtype=float)
    if len(beats) < 2:
        return None
    gaps = np.diff(beats)[beats[:-1] < exercise_end(score) - 1e-9]
    gaps = gaps[gaps > 0]
    return None if not len(gaps) else (60.0 / float(gaps.max()), 60.0 / float(gaps.min()))


def against_written(percent: float) -> str:
    """``2 % slower than written`` (``percent``: played over written tempo, - 1, in %)."""
    if round(abs(percent)) < 1:
        return "as written"
    return f"{abs(percent):.0f} % {'faster' if percent > 0 else 'slower'} than written"


def drift(bars: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    """``{"direction": "speeding up" | "slowing down", "from_bpm", "to_bpm", ...}`` when the bars' local tempi
    (three bars at least), each against its written tempo (a tempo map's 120 then 140 bpm played as written is no
    drift), rise, or fall, from each bar to the next and by :data:`DRIFT_MIN` in all; else None. ``from_percent``
    and ``to_percent``: the first and last bar's tempo against the written one (+ faster), ``from_bar``/``to_bar``
    and their written tempi."""
    rows = [b for b in bars if b["bpm"] is not None and b.get("written_bpm")]
    if len(rows) < 3:
        return None
    ratios = [b["bpm"] / b["written_bpm"] for b in rows]
    steps = np.diff(ratios)
    if abs(math.log(ratios[-1] / ratios[0])) < math.log1p(DRIFT_MIN):
        return None
    if not (np.all(steps > 0) or np.all(steps < 0)):
        return None
    return {"direction": "speeding up" if ratios[-1] > ratios[0] else "slowing down",
            "from_bpm": rows[0]["bpm"], "to_bpm": rows[-1]["bpm"],
            "from_percent": _r((ratios[0] - 1) * 100, 1), "to_percent": _r((ratios[-1] - 1) * 100, 1),
            "from_bar": rows[0]["bar"], "to_bar": rows[-1]["bar"],
            "written_from_bpm": rows[0]["written_bpm"], "written_to_bpm": rows[-1]["written_bpm"]}


def off_tempo(score: Score, bars: Sequence[dict[str, Any]], notes: Sequence[tuple[float, float, float]],
              tolerance: float, scale: float = 1.0) -> list[dict[str, Any]]:
    """The runs of bars the take falls behind (runs ahead) in: consecutive bars each played by :data:`DRIFT_MIN`
    or more slower (faster) than its written tempo, over which the notes' lag grows by more than the tolerance to
    beyond it: a tempo change played 8 % slow, bar after bar (no drift: the tempo does not keep moving, it stays
    off). Each: ``direction`` (``behind``/``ahead``), ``from_bar``/``to_bar``, ``bpm`` the take's tempo over the
    run's notes and ``written_bpm`` theirs (the slopes of the take's and the written times against the notes'
    quarter notes, as a bar's), ``percent`` (+ faster), ``lag_ms`` the last onset's lag (+ late) and ``where``
    it is, ``notes`` how many, ``tempo_change`` whether the written tempo changes as the run starts (the bar
    before's written tempo another: an exercise's 90 then 120 bpm) with ``written_before_bpm``. The run's onsets
    (notes at one time, lags averaged) lie within the tolerance of a line: a lag jumping about is no tempo kept;
    and its lag grows over a bar's worth of beats at least (:func:`grows_over_a_bar`): not in a fill's last beat.

    ``notes``: (written time on the exercise's clock s, take time s, played - written s) of every written note
    played on its drum, within the tolerance or beyond it; ``scale``: the tempo ratio compared at (a bar is off
    against the written tempo times it; the tempi said are the exercise's, as the bar table's)."""
    from common.score.position import bar_beat

    if len(score.beats) < 2 or not notes:
        return []
    sign_of: dict[int, int] = {}
    for b in bars:
        if b["bpm"] is not None and b.get("written_bpm"):
            ratio = b["bpm"] / (b["written_bpm"] * scale)  # against the tempo compared at
            sign_of[b["bar"]] = 1 if ratio <= 1 - DRIFT_MIN else -1 if ratio >= 1 + DRIFT_MIN else 0
    runs: list[list[int]] = []
    for b in bars:  # consecutive bars off the same way (1: slower, behind)
        sign = sign_of.get(b["bar"], 0)
        if sign and runs and runs[-1][-1] == b["bar"] - 1 and sign_of[runs[-1][0]] == sign:
            runs[-1].append(b["bar"])
        elif sign:
            runs.append([b["bar"]])
    bar_of = [None if (at := grid_point(score, t)) is None else at.bar for t, _, _ in notes]
    out = []
    for run in runs:
        sign = sign_of[run[0]]
        its = sorted(n for n, b in zip(notes, bar_of, strict=True) if b in run)
        onsets: dict[float, list[float]] = defaultdict(list)
        for t, _, error in its:
            onsets[round(t, 6)].append(error)
        lags = [float(np.mean(v)) for _, v in sorted(onsets.items())]
        if len(its) < BAR_TEMPO_NOTES or len(onsets) < 2:
            continue
        if not (sign * (lags[-1] - lags[0]) > tolerance and sign * lags[-1] > tolerance):
            continue
        when = np.array(sorted(onsets))
        if np.max(np.abs(np.polyval(np.polyfit(when, lags, 1), when) - lags)) > tolerance:
            continue  # not a lag growing steadily (notes paired across a jump): no tempo kept
        if not grows_over_a_bar(score, when, np.array(lags) * sign, tolerance):
            continue  # a fill played early, its last beat's notes alone off: notes off, no tempo kept
        x = np.array([t for t, _, _ in its])
        q = quarters(score, x)
        played_s = float(np.polyfit(q, np.array([p for _, p, _ in its]), 1)[0])
        written_s = float(np.polyfit(q, x, 1)[0])  # the exercise's written tempo, as the bar table's
        if not (played_s > 0 and written_s > 0):
            continue
        bpm, written_bpm = 60.0 / played_s, 60.0 / written_s
        first = bar_beat(score, x[0])
        before = [t for t, _, _ in notes if t < x[0] - 1e-9]  # the last note played before the run
        then = None if not before else bar_beat(score, max(before))
        change = (first is not None and then is not None
                  and not same_tempo(*sorted((first.tempo_bpm, then.tempo_bpm))))
        last = max(onsets)
        out.append({"direction": "behind" if sign > 0 else "ahead", "from_bar": run[0], "to_bar": run[-1],
                    "bpm": round(bpm, 1), "written_bpm": round(written_bpm, 1),
                    "percent": _r((bpm / written_bpm - 1) * 100, 1), "lag_ms": _r(lags[-1] * 1000, 1),
                    "where": grid_label(score, last, scale), "notes": len(its), "tempo_change": change,
                    "written_before_bpm": None if not change or then is None else round(then.tempo_bpm, 1)})
    return out


def grows_over_a_bar(score: Score, when: np.ndarray, lags: np.ndarray, tolerance: float) -> bool:
    """Whether a run's lag (s, its sign the run's: growing) grows over a bar's worth of beats at least: the onsets
    (written times ``when``, s) whose lag has grown by more than a quarter of the tolerance since the run's first
    lie on as many of the score's beats as the bar the first of them is in has (4 in 4/4). Until the day after 7
    Dec a lag growing in a bar's last beat alone was a tempo too: two snare notes of a fill 60 and 120 ms early,
    the bar's others on time, read "running ahead in bar 2: played at about 127 bpm"."""
    from common.score.position import DEFAULT_BEATS_PER_BAR, bar_beat

    grown = when[lags - lags[0] > tolerance / 4]
    if not len(grown):
        return False
    beats = np.asarray(score.beats, dtype=float)
    struck = {int(np.searchsorted(beats, t + 1e-9, side="right")) - 1 for t in grown}  # beat index (-1: before)
    at = bar_beat(score, float(grown[0]))
    lengths = np.diff(np.asarray(score.bar_beats, dtype=float))
    if at is None or not len(lengths):
        length = float(DEFAULT_BEATS_PER_BAR)
    else:
        length = float(lengths[min(max(at.bar, 0), len(lengths) - 1)])
    return len(struck) >= round(length)


def beat_feels(score: Score, notes: Sequence[tuple[float, float]], tolerance: float) -> list[dict[str, Any]]:
    """The beats rushed or dragging, in order: a bar's mean hides a one-beat fill (4 notes 40 ms early among a
    bar's 14 are -11 ms). A beat's onsets are its written times played (notes at one time are one onset, their
    timings averaged); a beat of :data:`BEAT_ONSETS` onsets or more is ``rushed`` (``dragging``) when its median
    onset is more than half the tolerance early (late), the bar's mark, and more than half its onsets are more
    than a quarter of the tolerance early (late): one note far off among steady ones (a median of two is their
    mean) is no rushed beat. ``mean_ms`` is the onsets' mean.

    The beat judged is the felt one (:func:`felt_beat`): in 6/8, 9/8 and 12/8 a dotted quarter, three counted
    eighths (an eighth of 6/8 seldom has two onsets: a beat per eighth was never judged); ``beat`` and
    ``last_beat`` are its first and last counted beats (4 and 6: the second dotted quarter of 6/8; one beat:
    equal; in a pick-up, from its first counted beat: 5 and 6 for a 2/8 pick-up before 6/8).

    ``notes``: (written time on the exercise's clock s, played - written s) of every written note played."""
    beats: dict[tuple[int, int], dict[float, list[float]]] = defaultdict(lambda: defaultdict(list))
    groups: dict[int, int] = {}  # bar: counted beats per felt beat
    for t, error in notes:
        at = grid_point(score, t)
        if at is not None:
            group = groups.setdefault(at.bar, felt_beat(score, at.bar))
            beats[(at.bar, (at.beat - 1) // group * group + 1)][round(t, 6)].append(error)
    short = pickup(score)
    # the pick-up's first counted beat (5 for a 2/8 pick-up before 6/8): its felt beat starts there, not before
    first = None if short is None else math.floor(1 + (short[1] - short[0]) / bar_unit(score, 1) + 1e-6)
    out = []
    for (bar, beat), onsets in sorted(beats.items()):
        errors = np.array([np.mean(v) for v in onsets.values()])
        median = float(np.median(errors))
        if len(errors) < BEAT_ONSETS or abs(median) <= tolerance / 2:
            continue
        if 2 * np.sum(errors * np.sign(median) > tolerance / 4) <= len(errors):
            continue
        last = beat + groups[bar] - 1
        if bar == 0 and first is not None:  # until 7 Dec "beats 4-6" for a pick-up of 5 and 6
            beat = min(max(beat, first), last)
        out.append({"bar": bar, "beat": beat, "last_beat": last, "onsets": len(errors),
                    "notes": sum(len(v) for v in onsets.values()),
                    "mean_ms": _r(float(np.mean(errors)) * 1000, 1), "median_ms": _r(median * 1000, 1),
                    "feel": "rushed" if median < 0 else "dragging"})
    return out


def felt_beat(score: Score, bar: int) -> int:
    """Counted beats (:func:`bar_unit`) per felt beat in bar ``bar`` (numbered as :func:`position` says; a pick-up
    as the bar after it): 3 in a compound meter (6, 9 or 12 eighths or sixteenths: the dotted quarter a player
    feels and a teacher points at), else 1: x/4 and x/2, and 3/8, 5/8 and 7/8, whose grouping (2+3 or 3+2, 2+2+3
    or 3+2+2) the score does not give. For rushed and dragging beats only: positions keep counting eighths."""
    # Score.bar_beats' bar: bar 1 is its first bar, or its second after a pick-up (bar 0 counted as bar 1)
    index = max(bar, 1) if pickup(score) is not None else max(bar - 1, 0)
    unit = bar_unit(score, index)
    starts = np.asarray(score.bar_beats, dtype=float)
    if unit > 0.5 or not len(starts):
        return 1
    k = min(index, len(starts) - 1)
    # the bar's length in quarter notes, as common.score.position.bar_beat measures it (the last: to the last beat)
    length = float(starts[k + 1] - starts[k]) if k + 1 < len(starts) else len(score.beats) - 1 - float(starts[k])
    if length <= 0 and k > 0:
        length = float(starts[k] - starts[k - 1])
    count = round(length / unit)
    return 3 if count >= 6 and count % 3 == 0 and abs(count * unit - length) < 1e-6 else 1


def bar_lines(report: dict[str, Any]) -> list[str]:
    """The per-bar table (all bars up to :data:`BARS_SHOWN`, else the bars with something to say), the bars
    rushed or dragging, the beats rushed or dragging in a bar not told so as a whole, and the drift."""
    bars = report.get("bars") or []
    if not bars:
        return []
    feel = {b["bar"]: b["feel"] for b in bars}
    beats = [b for b in report.get("beats_rushed_dragging") or [] if feel.get(b["bar"]) != b["feel"]]
    beat_bars = {b["bar"] for b in beats}

    def notable(b: dict[str, Any]) -> bool:
        return bool(b["missed"] or b["off_tolerance"] or b.get("wrong_drum") or b["extra"] or b["feel"]
                    or b["bar"] in beat_bars)

    shown = bars if len(bars) <= BARS_SHOWN else [b for b in bars if notable(b)]
    # a tempo map: each bar's written tempo beside the played one (a steady exercise's is the table's one tempo)
    written = [b["written_bpm"] for b in bars if b.get("written_bpm")]
    mapped = bool(written) and not same_tempo(min(written), max(written))
    means = [_ms(b["mean_ms"]) for b in shown]
    width = _width("mean ms", means)
    lines = ["", f"{'bar':>4} {'written':>7} {'played':>6} {'missed':>6} {'too early/late':>14} {'extra':>5} "
             f"{'other drum':>10} {'mean ms':>{width}} {'tempo bpm':>9}" + (f" {'written bpm':>11}" if mapped else "")]
    for b, mean in zip(shown, means, strict=True):
        lines.append(f"{b['bar']:>4} {b['written']:>7} {b['played']:>6} {b['missed']:>6} {b['off_tolerance']:>14} "
                     f"{b['extra']:>5} {b.get('wrong_drum', 0):>10} {mean:>{width}} "
                     f"{'-' if b['bpm'] is None else format(b['bpm'], '.1f'):>9}"
                     + (f" {'-' if not b.get('written_bpm') else format(b['written_bpm'], '.1f'):>11}"
                        if mapped else ""))
    if len(shown) < len(bars):
        fine = len(bars) - len(shown)
        lines.append(f"... {fine} other bar{'' if fine == 1 else 's'} fine (--json lists every bar)")
    told = sorted([(b["bar"], 0, f"bar {b['bar']}: {b['feel']}, {b['mean_ms']:+.0f} ms on average"
                    if b.get("entry_ms") is None else f"bar {b['bar']}: {b['feel']}, "
                    f"{b['mean_ms'] - b['entry_ms']:+.0f} ms on average against the entry after the rest "
                    f"({b['entry_ms']:+.0f} ms)")
                   for b in bars if b["feel"]]
                  # a beat is told by its median onset (one note far off does not make it), and said so: its mean
                  # (the label from the median, the number from the mean read "rushed, +8 ms" until 7 Dec)
                  + [(b["bar"], b["beat"], f"bar {b['bar']}, {_beats_text(b)}: {b['feel']}, "
                      f"{b.get('median_ms', b['mean_ms']):+.0f} ms median ({b['notes']} notes)") for b in beats])
    lines.extend(text for _, _, text in told)
    d = report.get("drift")
    if d and same_tempo(*sorted((d.get("written_from_bpm") or 1.0, d.get("written_to_bpm") or 1.0))):
        lines.append(f"{d['direction']}: {d['from_bpm']:.0f} -> {d['to_bpm']:.0f} bpm")
    elif d:  # the written tempo changes between them: the drift is against it
        lines.append(f"{d['direction']} against the written tempo: bar {d['from_bar']} "
                     f"{against_written(d['from_percent'])} ({d['from_bpm']:.0f} bpm, written "
                     f"{d['written_from_bpm']:.0f}), bar {d['to_bar']} {against_written(d['to_percent'])} "
                     f"({d['to_bpm']:.0f} bpm, written {d['written_to_bpm']:.0f})")
    lines.extend(off_tempo_text(run) for run in report.get("off_tempo") or [])
    return lines


def off_tempo_text(run: dict[str, Any]) -> str:
    """``falling behind in bars 3-4 after the tempo change (90 -> 120 bpm): played at about 110 bpm where 120 is
    written (8 % slower than written); 310 ms late by bar 4, beat 4`` (:func:`off_tempo`)."""
    scope = f"bar {run['from_bar']}" if run["from_bar"] == run["to_bar"] else \
        f"bars {run['from_bar']}-{run['to_bar']}"
    change = (f" after the tempo change ({run['written_before_bpm']:g} -> {run['written_bpm']:g} bpm)"
              if run.get("tempo_change") and run.get("written_before_bpm") else "")
    lag = run["lag_ms"]
    return (f"{'falling behind' if run['direction'] == 'behind' else 'running ahead'} in {scope}{change}: played at "
            f"about {run['bpm']:.0f} bpm where {run['written_bpm']:g} is written ({against_written(run['percent'])}); "
            f"{abs(lag):.0f} ms {'late' if lag > 0 else 'early'} by {run['where']}")


def _beats_text(beat: dict[str, Any]) -> str:
    """``beat 4``, or a felt beat of several counted ones ``beats 4-6`` (:func:`felt_beat`)."""
    last = beat.get("last_beat", beat["beat"])
    return f"beat {beat['beat']}" if last == beat["beat"] else f"beats {beat['beat']}-{last}"


def tempo_bpm(score: Score) -> float | None:
    """The exercise's written tempo (median beat), beats per minute; None without beats."""
    beats = np.asarray(score.beats, dtype=float)
    if len(beats) < 2:
        return None
    spacing = float(np.median(np.diff(beats)))
    return 60.0 / spacing if spacing > 0 else None


def start_beat_s(score: Score, scale: float) -> float | None:
    """The exercise's beat where it starts (its first note), s on the take's clock: what a count-in counts (a
    tempo map's first tempo, not its median); None without beats."""
    from common.score.position import bar_beat

    where = bar_beat(score, score.events[0].time if score.events else 0.0)
    return None if where is None else 60.0 / where.tempo_bpm / scale


def exercise_end(score: Score) -> float:
    """Where the exercise ends on its written clock, s: its last beat (a text score's end) or last note."""
    last = score.events[-1].time if score.events else 0.0
    return max(last, float(score.beats[-1])) if len(score.beats) and score.end_beat is not None else last


def compare(score: Score, take: Take, kit: Kit, tolerance: float, scale: float | None = None,
            offset: float | None = None) -> dict[str, Any]:
    """The whole comparison as a JSON-ready dict (see the module docstring; times on the exercise's clock).

    ``scale`` None (no ``--tempo-scale``): compared at the exercise's tempo, and when the tempo check finds a ratio
    matching clearly more notes (``tempo`` set), compared again at that ratio (a take 2 % slow is not half
    missed); ``tempo_scale_found`` says so. A ``scale`` given is kept as given (no search)."""
    report = _compare_at(score, take, kit, tolerance, 1.0 if scale is None else scale, offset)
    report["tempo_scale_found"] = False
    tempo = report["tempo"]
    if scale is None and tempo is not None:
        again = _compare_at(score, take, kit, tolerance, tempo["ratio"], offset)
        if again["played"] > report["played"]:
            # the exercise's own tempo kept in "tempo" (the second run's would be the take's)
            tempo["played_at_exercise_tempo"] = report["played"]
            report = {**again, "tempo": tempo, "tempo_scale_found": True}
    return report


def _compare_at(score: Score, take: Take, kit: Kit, tolerance: float, scale: float,
                offset: float | None) -> dict[str, Any]:
    """The comparison at the tempo ratio ``scale`` (take / exercise)."""
    from batteur.evaluate import note_refs

    refs = note_refs(score, kit)
    written_all = [replace(n, time=n.time / scale) for n in refs]
    not_heard: Counter[str] = Counter()
    compared_as: dict[str, dict[str, Any]] = {}
    written = []
    for n in written_all:
        if take.heard is not None and n.instrument not in take.heard:
            heard_as = take.folded.get(n.event)
            if heard_as is None:
                not_heard[n.instrument] += 1
                continue
            # the transcriber files it under another class: compared as that drum (its strikes no extras there)
            entry = compared_as.setdefault(n.instrument, {"as": heard_as, "notes": 0})
            entry["notes"] += 1
            n = replace(n, instrument=heard_as)
        written.append(n)
    if not written:
        raise CompareError("the exercise has no note on a drum the transcriber can hear (it knows kick, snare, "
                           "hi-hat, toms, crash and ride)")
    forced = offset is not None
    bpm = tempo_bpm(score)
    if offset is None:
        offset, pairs = align_past_count_in(written, take.notes, tolerance, start_beat_s(score, scale))
    else:
        pairs = matched(written, take.notes, offset, tolerance)
    # a student who stopped and came back in: timed from there on against the restart (its pause taken out)
    restarts, offset, pairs, strays = find_restarts(written, take.notes, offset, pairs, tolerance, forced,
                                                    None if bpm is None else 60.0 / bpm / scale)
    # an entry after a written rest lined its notes up to pair them; they are kept late or early as played
    entries = [r for r in restarts if r.rest]
    restarts = [r for r in restarts if not r.rest]
    played = restarted(take.notes, restarts)
    entered: dict[int, int] = {}  # written index: its note, paired after an entry and beyond the tolerance
    # each entry's note's written time (s, compared clock), as paired: the entry's bar and its rest's are that
    # note's (an entry note a few ms early was placed in the rest's last bar, "after the rest (bar 3)", until 7 Dec)
    entry_at = {r.cut: written[i].time for r in entries for i, j in pairs if abs(take.notes[j].time - r.cut) < 1e-9}
    if entries:
        entered = {i: j for i, j in pairs if abs(played[j].time - offset - written[i].time) > tolerance}
        pairs = [(i, j) for i, j in pairs if i not in entered]
    # the take's notes before the exercise starts or after it ends (a count-in, a last crash held on): not extras
    start, end = -tolerance, exercise_end(score) / scale + tolerance
    inside = [j for j, p in enumerate(played) if start <= p.time - offset <= end]
    outside = len(played) - len(inside)
    done_written = {i for i, _ in pairs}
    done_played = {j for _, j in pairs}
    extras_j = [j for j in inside if j not in done_played]
    missed_i = [i for i in range(len(written)) if i not in done_written]

    def written_clock(seconds: float) -> float:
        return seconds * scale

    # a miss with an unmatched note of its drum near is told early or late; that note may lie just before the
    # exercise's start or after its end (a first note early, a last one late): it is still the written note's.
    # That note is the written one played too early or late, not also an extra: each is claimed by one miss
    loose: dict[str, list[int]] = defaultdict(list)
    for j, p in enumerate(played):
        if j not in done_played and j not in entered.values():
            loose[p.drum].append(j)
    claimed: dict[int, int] = dict(entered)  # written index: the note of its drum played too early or late for it
    taken: set[int] = set(entered.values())
    for i, j in strays.items():  # the few notes of a pause too short to be a stop: off by it, beyond the reach
        if i in missed_i and i not in claimed and j not in done_played and j not in taken:
            claimed[i] = j
            taken.add(j)
    reach = max(LOOSE_S, 2 * tolerance)
    candidates = sorted((abs(played[j].time - offset - written[i].time), i, j) for i in missed_i
                        for j in loose.get(written[i].instrument, [])
                        if abs(played[j].time - offset - written[i].time) <= reach)
    for _, i, j in candidates:  # the closest pairs first: a note early for the next beat is that beat's
        if i not in claimed and j not in taken:
            claimed[i] = j
            taken.add(j)
    # a take falling behind (running ahead) bar after bar: its notes beyond the reach are followed along its lag
    # (until 7 Dec a tempo change played 8 % slow read as bars all missed, with as many extras)
    near = dict(claimed)  # the entry's notes and those within the reach: not followed along the lag
    followed, claimed = follow_lag(written, played, offset, tolerance, dict(pairs), claimed,
                                   [i for i in missed_i if i not in claimed], loose)
    if followed != dict(pairs):  # pairs redone along the lag: the notes they let go are extras unless claimed
        pairs = sorted(followed.items())
        done_written, done_played = set(followed), set(followed.values())
        extras_j = [j for j in inside if j not in done_played]
        missed_i = [i for i in range(len(written)) if i not in done_written]
    taken = set(claimed.values())
    extras_j = [j for j in extras_j if j not in taken]
    # a note told early or late is not also one before or after the exercise (a first note early)
    inside_set = set(inside)
    outside -= sum(j not in inside_set for j in taken)
    # a miss with an extra on another drum within the tolerance (no note of its own drum near: claimed above) was
    # played on that drum: a wrong drum, not a miss and an extra
    lost = [i for i in missed_i if i not in claimed]
    swaps = [(lost[a], extras_j[b]) for a, b in wrong_drum_pairs(
        [(written[i].time, written[i].instrument) for i in lost],
        [(played[j].time - offset, played[j].drum) for j in extras_j], tolerance, lambda d: drum_family(kit, d))]
    wrong_of = dict(swaps)
    stood_in = set(wrong_of.values())
    extras_j = [j for j in extras_j if j not in stood_in]
    off_i = set(claimed)
    lost_i = [i for i in lost if i not in wrong_of]
    misses = []
    for i in missed_i:
        if i in wrong_of:
            continue
        n = written[i]
        entry = {**position(score, written_clock(n.time), scale), "time_s": _r(written_clock(n.time), 4),
                 "drum": n.instrument, "event": n.event, "velocity": round(n.velocity * 127)}
        if i in claimed:
            j = claimed[i]
            entry["played_off_by_ms"] = round((played[j].time - offset - n.time) * 1000, 1) + 0.0
            entry["played_take_time_s"] = _r(take.notes[j].time, 4)  # the take's own clock (a pause in)
        misses.append(entry)
    wrong = []
    for i, j in sorted(swaps, key=lambda s: written[s[0]].time):
        n, p = written[i], played[j]
        wrong.append({**position(score, written_clock(n.time), scale), "time_s": _r(written_clock(n.time), 4),
                      "drum": n.instrument, "event": n.event, "velocity": round(n.velocity * 127),
                      "played_drum": p.drum, "played_event": p.event, "played_velocity": round(p.velocity * 127),
                      "played_take_time_s": _r(take.notes[j].time, 4),
                      "timing_ms": _r((p.time - offset - n.time) * 1000, 1)})
    extras = []
    for j in extras_j:
        p = played[j]
        extras.append({**position(score, written_clock(p.time - offset), scale),
                       "time_s": _r(written_clock(p.time - offset), 4), "take_time_s": _r(take.notes[j].time, 4),
                       "drum": p.drum, "event": p.event, "velocity": round(p.velocity * 127)})
    drums: dict[str, Any] = {}
    normal = normal_level(n.velocity for n in written)  # the exercise's plain level: its accents are above it
    names = sorted({n.instrument for n in written} | {played[j].drum for j in inside})
    for drum in names:
        its_pairs = [(i, j) for i, j in pairs if written[i].instrument == drum]
        drums[drum] = {
            "written": sum(n.instrument == drum for n in written), "played": len(its_pairs),
            "missed": sum(written[i].instrument == drum for i in lost_i),
            "off_tolerance": sum(written[i].instrument == drum for i in off_i),
            "wrong_drum": sum(written[i].instrument == drum for i in wrong_of),
            "played_instead": dict(sorted(Counter(played[j].drum for i, j in swaps
                                                  if written[i].instrument == drum).items())),
            "played_for_other": sum(played[j].drum == drum for _, j in swaps),
            "extra": sum(played[j].drum == drum for j in extras_j),
            "timing": timing([played[j].time - offset - written[i].time for i, j in its_pairs]),
            "dynamics": dynamics([(written[i].velocity, played[j].velocity) for i, j in its_pairs],
                                 ACCENT_MARGIN * (1.0 if take.heard is None else AUDIO_VELOCITY_SCALE), normal),
        }
    short = pickup(score)
    # every written note the take played, on its drum (within the tolerance or beyond it) or on another one
    struck = [*pairs, *claimed.items(), *swaps]
    # the lag an entry after a written rest (said: beyond the tolerance) put each note after it at, s: its bars and
    # beats are rushed or dragging against it, not against the take's start
    lag_at = [(r.cut, sum(e.late_s for e in entries if e.cut <= r.cut + 1e-9)) for r in entries]
    entry_lag = {i: lag for i, j in struck
                 if abs(lag := max([(cut, lag) for cut, lag in lag_at if cut <= take.notes[j].time + 1e-9],
                                   default=(0.0, 0.0))[1]) > tolerance}
    bars = bar_rows(score, [(written_clock(n.time), n.time) for n in written],
                    [(i, played[j].time, played[j].time - offset - written[i].time) for i, j in pairs],
                    lost_i, sorted(off_i), sorted(wrong_of), [e["bar"] for e in extras], tolerance,
                    [(i, played[j].time, played[j].time - offset - written[i].time) for i, j in claimed.items()],
                    entry_lag)
    report: dict[str, Any] = {
        "take_kind": take.kind, "tolerance_ms": round(tolerance * 1000, 3), "tempo_scale": scale,
        "offset_s": _r(offset, 4), "offset_forced": forced,
        "written": len(written), "played": len(pairs), "missed": len(lost_i),
        "off_tolerance": len(off_i), "wrong_drum": len(swaps), "extra": len(extras_j),
        "outside": outside,
        "timing": timing([played[j].time - offset - written[i].time for i, j in pairs]),
        "drums": drums, "misses": misses, "wrong_drums": wrong, "extras": extras,
        "not_heard": dict(sorted(not_heard.items())), "compared_as": dict(sorted(compared_as.items())),
        "tempo": None, "take_stops": None,
        # the count-in: notes before the start, but for a first note early (told as such above)
        "entry": None if forced else count_in_entry(
            [(p.time, p.drum) for p in played if p.time - offset < -max(LOOSE_S, 2 * tolerance)], offset, tolerance,
            start_beat_s(score, scale)),
        # where each came back in, on the written clock: every earlier move taken out (an entry's too)
        "restarts": [restart_entry(score, r, [*restarts, *entries], offset, scale) for r in restarts],
        # each entry late or early against the take's start (the pulse before the rest may have been off already)
        "rest_entries": [rest_entry(score, r, [*restarts, *entries], offset, scale, lag, entry_at.get(r.cut))
                         for r in entries if abs(lag := sum(e.late_s for e in entries if e.cut <= r.cut + 1e-9))
                         > tolerance],
        "pickup_beats": None if short is None else _r(short[0] / bar_unit(score, 1), 3),  # counted as bar 1's
        "pickup_in_bar_1": pickup_in_bar_1(score),
        "bars": bars, "drift": drift(bars), "off_tempo": [],
        "beats_rushed_dragging": beat_feels(
            score, [(written_clock(written[i].time), played[j].time - offset - written[i].time - entry_lag.get(i, 0.0))
                    for i, j in struck], tolerance),
        "warnings": list(take.warnings),
    }
    # the take's last note from the start on (one just after the end too: a last note late is no early stop)
    later = [(p.time - offset, j) for j, p in enumerate(played) if p.time - offset >= start]
    last, last_j = max(later) if later else (None, None)
    early_for = [i for i, j in claimed.items() if j == last_j]
    if last is not None and early_for:
        # the last note played early for a later written note (a take running ahead) stops there, not before it
        last = max(last, written[early_for[0]].time)
    if last is not None and bpm is not None:
        # within a beat (a quarter note where the exercise ends, through its tempo map) of the end: it played to the
        # end, its misses are listed. The median tempo judged it before: 90 bpm's beat read a take stopping a beat
        # and a half before the end of a last bar at 140 as played to the end
        # (its last written note, not the end of its last bar: a take missing only a quiet pedal chick 70 ms after
        # the last strike read "the take stops" until 7 Dec)
        end_q, last_q = quarters(score, np.array([written_clock(max(n.time for n in written)),
                                                  written_clock(last + tolerance)]))
        if end_q - last_q <= 1 + 1e-9:
            last = None
    for entry in misses:  # a take stopped before the end: its missed notes after the take are told as one
        entry["after_take"] = (last is not None and "played_off_by_ms" not in entry
                               and entry["time_s"] > written_clock(last + tolerance))
    after = sum(bool(entry["after_take"]) for entry in misses)
    if last is not None and after:
        # where the written note it was played for is (its bar, as the table counts it), else the strike's own
        i_of = {j: i for i, j in struck}
        at = written_clock(last if last_j not in i_of else written[i_of[last_j]].time)
        report["take_stops"] = {**position(score, at, scale), "missed_after": after}
    # a take a little off tempo lined up bars in (a repeated groove: its first bars before the start, not a count-in,
    # and the exercise's last ones after its end, missed): most notes match, the tempo is looked for all the same
    # (16 bars at 1.004 lined up three bars in, 39 missed and the take "stopping" at bar 13, until 8 Dec)
    early = sum(p.time - offset < start for j, p in enumerate(played) if j not in taken)
    shifted = (not forced and report["take_stops"] is not None and report["entry"] is None
               and min(early, report["take_stops"]["missed_after"]) >= RESTART_NOTES)
    if len(pairs) < TEMPO_CHECK_BELOW * len(written) or shifted:
        ratio, count = find_tempo(written, played, tolerance, offset if forced else None)
        length = exercise_end(score) / scale  # s, as the take plays it: a small ratio still drifts over a long take
        # and more notes than those here on time or followed along the take's lag (a tempo change in the middle of
        # a take: the whole take compared at the later tempo put its first bars off, until 7 Dec), not those only
        # near their written time: a take 7 % slow has many (with an entry 0.5 s late after a rest, 56 too early
        # or late outnumbered the 66 the tempo matched, no tempo said, until 7 Dec)
        along = sum(near.get(i) != j for i, j in claimed.items())
        # (more than those and an entry's notes, after an entry off after a rest: the take steady, 0.2 s late after
        # a 2-bar rest, matched as many at 117 bpm, the tie said the tempo)
        by_entry = sum(near.get(i) == j for i, j in claimed.items() if i in entered)
        # clearly more: half as many again and a fifth of the notes; or, lined up bars in or matching nearly every
        # note (a steady tempo, not a change in the middle), half the notes left (16 bars at 0.996: 159 of 208 at
        # the exercise's tempo, 208 at the take's, no tempo said until 8 Dec: 1.5 x 159 > 208); and
        # more than those followed or moved by an entry
        relaxed = shifted or count >= TEMPO_STEADY * len(written)
        if (count >= max(len(pairs) + 0.5 * (len(written) - len(pairs)) if relaxed else
                         max(1.5 * len(pairs), len(pairs) + 0.2 * len(written)),
                         len(pairs) + along + (by_entry + 1 if entered else 0))
                and abs(math.log(ratio)) * length > tolerance / 2):
            said = ratio_digits(ratio * scale, length / ratio, tolerance)
            tempi = written_tempi(score)
            # a tempo map: no one tempo to say the take's in bpm against; said as a share of the written tempo
            mapped = tempi is not None and not same_tempo(*tempi)
            report["tempo"] = {"ratio": said, "played": count,
                               "exercise_bpm": None if bpm is None else round(bpm * scale, 1),
                               "take_bpm": None if bpm is None else round(bpm * scale * ratio, 1),
                               "percent": _r((said - 1) * 100, 1),
                               "written_bpm_range": None if not mapped or tempi is None else
                               [round(tempi[0], 1), round(tempi[1], 1)]}
    if report["tempo"] is None:  # else the TEMPO line says the take's tempo (a drift may come with a run: a bar 2 %
        # fast by chance before a tempo change played slow makes the bars' tempi fall from each to the next)
        report["off_tempo"] = off_tempo(
            score, bars, [(written_clock(written[i].time), played[j].time, played[j].time - offset - written[i].time)
                          for i, j in [*pairs, *claimed.items()]], tolerance, scale)
    return report


def pickup_in_bar_1(score: Score) -> dict[str, Any] | None:
    """``{"first_beat": 3, "beats": 3}`` when the exercise's first bar (a full bar: no pick-up of its own meter,
    :func:`pickup`) has no note in its first half and the exercise goes on past it: a pick-up written as a full bar
    of rests first (a DAW's MIDI file: its bar 1 holds the pick-up; a MIDI file of one time signature knows no
    shorter bar), which the report counts as the file does (the pick-up ``bar 1, beat 3``, printed music's bar 1
    ``bar 2``); ``beats``: the bar's counted beats. Else None. Said, not renumbered: the file's own numbering is what
    a DAW shows (until 8 Dec nothing said why a 3/4 exercise's bars were one more than the part's)."""
    from common.score.position import DEFAULT_BEATS_PER_BAR

    if pickup(score) is not None or not score.events:
        return None
    first = bar_and_beat(score, score.events[0].time)
    last = bar_and_beat(score, score.events[-1].time)
    if first is None or last is None or first[0] != 1 or last[0] < 2:
        return None
    starts = np.asarray(score.bar_beats, dtype=float)
    length = (float(starts[1] - starts[0]) / bar_unit(score, 0) if len(starts) >= 2
              else float(DEFAULT_BEATS_PER_BAR))  # counted beats of bar 1
    beat = first[1]
    if beat - 1 < length / 2 - 1e-6:
        return None
    return {"first_beat": _r(beat, 3), "beats": _r(length, 3)}


def pickup_in_bar_1_text(hint: dict[str, Any]) -> str:
    """``bar 1 has no note before beat 3 (of 3): ...`` (:func:`pickup_in_bar_1`)."""
    return (f"bar 1 has no note before beat {hint['first_beat']:g} (of {hint['beats']:g}): if that is a pick-up, "
            "bars are counted as the exercise writes it, the pick-up in bar 1 and the first full bar bar 2 (give the "
            "pick-up a meter of its own, a MIDI time signature or a text score's meter line, to count it as bar 0)")


def restart_entry(score: Score, restart: Restart, restarts: Sequence[Restart], offset: float, scale: float
                  ) -> dict[str, Any]:
    """A restart as the report says it: where the take came back in (the bar and beat of its first note after the
    silence, :func:`position`), ``take_time_s`` that note's time on the take's clock, ``late_s`` how much later than
    its pulse before the silence, ``silence_s`` the silence."""
    moved = restart.cut - sum(r.late_s for r in restarts if r.cut <= restart.cut + 1e-9)
    return {**position(score, (moved - offset) * scale, scale), "take_time_s": _r(restart.cut, 4),
            "late_s": _r(restart.late_s, 3), "silence_s": _r(restart.silence_s, 3)}


def rest_entry(score: Score, entry: Restart, moves: Sequence[Restart], offset: float, scale: float, lag: float,
               paired_at: float | None = None) -> dict[str, Any]:
    """An entry after a written rest as the report says it (:func:`restart_entry`'s fields, ``late_s`` the entry
    note's lag against the take's start, s, < 0 early; ``moves``: every restart and entry, to place it), with
    ``rest``, the rest's bars (``bars 3-4``: the bars without a written note; a rest within or across bars, those
    bars: ``bar 2``) and ``late_beats``, in the exercise's beats there. ``paired_at``: the written time (s, on the
    compared clock) of the note the entry note was paired with, where the entry is (else where its move puts it:
    a few ms early there is still in the rest)."""
    said = {**restart_entry(score, entry, moves, offset, scale), "late_s": _r(lag, 3)}
    if paired_at is None:
        at = (entry.cut - sum(r.late_s for r in moves if r.cut <= entry.cut + 1e-9) - offset) * scale
    else:
        at = paired_at * scale
        said.update(position(score, at, scale))
    onsets = sorted({e.time for e in score.events})
    before = onsets[max(0, bisect.bisect_left(onsets, at - 1e-6) - 1)]  # the last written onset before the rest
    first, where = bar_and_beat(score, before), bar_and_beat(score, at)
    rest = ""
    if first is not None and where is not None:
        # the bars wholly without a written note (the entry's has its own), else those the rest lies in
        a, b = (first[0] + 1, where[0] - 1) if where[0] - first[0] >= 2 else (first[0], where[0])
        rest = f"bar {a}" if a == b else f"bars {a}-{b}"
    beat = where[2] / scale if where is not None else None
    return {**said, "rest": rest, "late_beats": None if beat is None else _r(lag / beat, 2)}


def rest_entry_text(entry: dict[str, Any]) -> str:
    """``bar 5: came in 0.5 s late (1 beat) after the rest (bars 3-4), 10.800 s into the take: ...``
    (:func:`rest_entry`)."""
    how = "late" if entry["late_s"] > 0 else "early"
    beats = entry.get("late_beats")
    said = None if beats is None else round(abs(beats), 1)  # a beat late with a few ms of jitter: "1 beat"
    count = "" if said is None else f" ({said:g} beat{'' if said == 1 else 's'})"
    bar = f"bar {entry['bar']}" if entry.get("bar") is not None else where_text(entry)
    # 0.08 s, not "0.1 s": an entry is said from the tolerance on
    late = f"{abs(entry['late_s']):.1f}" if abs(entry["late_s"]) >= 0.095 else f"{abs(entry['late_s']):.2f}"
    return (f"{bar}: came in {late} s {how}{count} after the rest ({entry['rest']}), "
            f"{entry['take_time_s']:.3f} s into the take: its notes told {how} by it")


def restart_text(entry: dict[str, Any]) -> str:
    """``came back in 0.6 s late at bar 3, beat 1 after a pause ...`` (:func:`restart_entry`)."""
    return (f"came back in {entry['late_s']:.1f} s late at {where_text(entry)} "
            f"after a pause ({entry['silence_s']:.2f} s without a note, {entry['take_time_s']:.3f} s into the take): "
            "timed from there on against the restart")


def _r(value: float, digits: int) -> float:
    """``value`` rounded, a negative zero made positive (no ``-0.0`` in the JSON, no ``-0.000 s`` said)."""
    return round(value, digits) + 0.0


def count_in_entry(before: Sequence[tuple[float, str]], offset: float, tolerance: float,
                   beat_s: float | None = None) -> dict[str, Any] | None:
    """Where the take entered against its count-in, given the take's notes (time s, kit object) before the
    exercise's start (``offset``; a first note early left out): the last :data:`COUNT_IN_NOTES` or more of them
    (notes within the tolerance one onset) a steady pulse apart (each gap within the tolerance, or a tenth of the
    pulse, of their median), the exercise is due one pulse after the last; ``late_beats`` is how far after that
    it started, in the count-in's beats (- early). None when there is no such count-in, or the entry is more
    than :data:`COUNT_IN_REACH` beats from it (those notes were not counting the exercise in), or (``beat_s``: the
    exercise's beat on the take's clock, s) the pulse is not that beat, twice it or half it within
    :data:`COUNT_IN_PULSE_MATCH` (a transcriber's ghost notes a steady 0.26 s apart are no count-in at 100 bpm),
    or those onsets do not repeat one sound (:data:`COUNT_IN_SAME`): a groove's hi-hat, kick and snare before the
    start are the exercise's own notes (a long take at 1.004 of the tempo lined up three bars in read "entered 0.2
    beat early after the count-in" until 7 Dec, a take without one)."""
    onsets: list[float] = []
    sounds: list[set[str]] = []  # the kit objects each onset strikes
    for t, drum in sorted(before):
        if not onsets or t - onsets[-1] > tolerance:
            onsets.append(t)
            sounds.append(set())
        sounds[-1].add(drum)
    run = 1  # onsets in the steady run ending at the last
    while run < len(onsets):
        gaps = np.diff(onsets[-run - 1:])
        pulse = float(np.median(gaps))
        if not pulse > 0 or np.max(np.abs(gaps - pulse)) > max(tolerance, 0.1 * pulse):
            break
        run += 1
    if run < COUNT_IN_NOTES:
        return None
    pulse = float(np.median(np.diff(onsets[-run:])))
    struck = Counter(frozenset(its) for its in sounds[-run:])
    if struck.most_common(1)[0][1] < COUNT_IN_SAME * run:
        return None
    if beat_s is not None and not any(abs(pulse / (beat_s * k) - 1) <= COUNT_IN_PULSE_MATCH for k in (0.5, 1, 2)):
        return None
    due = onsets[-1] + pulse
    late = offset - due
    if abs(late) > COUNT_IN_REACH * pulse:
        return None
    return {"count_in_notes": run, "count_in_beat_s": _r(pulse, 4), "due_s": _r(due, 4),
            "late_s": _r(late, 4), "late_beats": _r(late / pulse, 2), "on_time": abs(late) <= tolerance}


def entry_text(entry: dict[str, Any]) -> str:
    """``entered 1 beat late after the count-in (...)``."""
    how = (f"{entry['count_in_notes']} notes {entry['count_in_beat_s']:.3g} s apart; the exercise due at "
           f"{entry['due_s']:.3f} s")
    if entry["on_time"]:
        return f"entered on the beat after the count-in ({how})"
    beats = abs(entry["late_beats"])
    count = f"{round(beats)}" if abs(beats - round(beats)) < 0.05 else f"{beats:.1f}"
    return (f"entered {count} beat{'' if float(count) <= 1 else 's'} {'late' if entry['late_s'] > 0 else 'early'} "
            f"after the count-in ({how})")


def summary_lines(report: dict[str, Any], exercise: str, take: str) -> list[str]:
    """The report as a teacher reads it."""
    lines = [f"{take} ({report['take_kind']}) against {exercise}"]
    how = "forced (--offset)" if report["offset_forced"] else "found by lining up the notes"
    lines.append(f"the exercise starts {_r(report['offset_s'], 3):.3f} s into the take ({how}); tolerance "
                 f"{report['tolerance_ms']:g} ms" + (f"; tempo scale {report['tempo_scale']:g}"
                                                       if report["tempo_scale"] != 1 else ""))
    if report.get("entry"):
        lines.append(entry_text(report["entry"]))
    lines.extend(restart_text(entry) for entry in report.get("restarts") or [])
    lines.extend(rest_entry_text(entry) for entry in report.get("rest_entries") or [])
    if report.get("pickup_beats"):
        lines.append(f"bar 0 is the pick-up ({report['pickup_beats']:g} beat{'s' if report['pickup_beats'] > 1 else ''}"
                     "), bar 1 the first full bar")
    if report.get("pickup_in_bar_1"):
        lines.append(pickup_in_bar_1_text(report["pickup_in_bar_1"]))
    t = report["timing"]
    off = (f"{report['off_tolerance']} played too early or late (beyond the tolerance), "
           if report["off_tolerance"] else "")
    wrong = (f"{report['wrong_drum']} played on another drum, " if report.get("wrong_drum") else "")
    lines.append(f"{report['played']} of {report['written']} written notes played, {off}{wrong}{report['missed']} "
                 f"missed, {report['extra']} extra" + (f" ({report['outside']} before or after the exercise not "
                                                       "counted)" if report["outside"] else ""))
    if t["n"]:
        lines.append(f"timing: {_ms(t['mean_ms'])} on average (+ late, - early), spread {t['sd_ms']:.1f} ms "
                     "(standard deviation), against the take's own pulse" if not report["offset_forced"] else
                     f"timing: {_ms(t['mean_ms'])} on average (+ late, - early), spread {t['sd_ms']:.1f} ms "
                     "(standard deviation)")
    stops = report.get("take_stops")
    if stops:
        n = stops["missed_after"]
        lines.append(f"the take stops at {where_text(stops)} (its last note): {n} written note{'' if n == 1 else 's'} "
                     f"after it {'is' if n == 1 else 'are'} missed (not listed below)")
    tempo = report.get("tempo")
    changes = tempo.get("written_bpm_range") if tempo else None
    if changes:  # a tempo map has no one tempo to say the take's against
        changes = (f"the written tempo changes, {changes[0]:g} to {changes[1]:g} bpm")
    if tempo and report.get("tempo_scale_found"):
        bpm = (f"played {against_written(tempo['percent'])} ({changes})" if changes else
               f"played at about {tempo['take_bpm']:g} bpm, the exercise is at {tempo['exercise_bpm']:g}"
               if tempo["exercise_bpm"] else f"played at about {tempo['ratio']} times the exercise's tempo")
        # until 7 Dec "68 of 68 played (at the exercise's tempo 26)", which read as a tempo of 26
        lines.insert(1, f"{bpm}: compared at the take's tempo (--tempo-scale {tempo['ratio']}); at that tempo "
                     f"{report['played']} of the {report['written']} written notes are on time, at the exercise's "
                     f"tempo only {tempo['played_at_exercise_tempo']} would be")
    elif tempo:
        bpm = (f" ({against_written(tempo['percent'])}; {changes})" if changes else
               f" (the exercise at {tempo['exercise_bpm']:g} bpm, the take at about {tempo['take_bpm']:g})"
               if tempo["exercise_bpm"] else "")
        lines.append(f"TEMPO: most notes do not match at the exercise's tempo; the take is played at about "
                     f"{tempo['ratio']} times it{bpm}: --tempo-scale {tempo['ratio']} compares at the "
                     f"take's tempo ({tempo['played']} notes then match)")
    lines.append("")
    means = {drum: _ms(d["timing"]["mean_ms"]) if d["timing"]["n"] else "-" for drum, d in report["drums"].items()}
    # a recording's velocities are the transcriber's guess from loudness (compressed), not an e-kit's
    velocity = "velocity as transcribed" if "audio" in report["take_kind"] else "MIDI velocity"
    width = _width("mean ms", means.values())
    lines.append(f"{'drum':<10} {'written':>7} {'played':>6} {'too early/late':>14} {'missed':>6} {'extra':>5} "
                 f"{'other drum':>10} {'mean ms':>{width}} {'spread ms':>9}  dynamics ({velocity})")
    for drum, d in report["drums"].items():
        lines.append(f"{drum:<10} {d['written']:>7} {d['played']:>6} {d['off_tolerance']:>14} {d['missed']:>6} "
                     f"{d['extra']:>5} {d.get('wrong_drum', 0):>10} {means[drum]:>{width}} "
                     f"{_spread(d['timing']):>9}  {_dynamics_text(d['dynamics'])}")
    for drum, d in report["drums"].items():  # the other drum column said: which drum, how often
        for other, n in d.get("played_instead", {}).items():
            lines.append(f"played {other} instead of {drum}: {n} note{'' if n == 1 else 's'}")
    if report["not_heard"]:
        drums = ", ".join(f"{k} {v}" for k, v in report["not_heard"].items())
        lines.append(f"not compared (the transcriber has no class for them): {drums}")
    if report.get("compared_as"):
        drums = ", ".join(f"{k} {v['notes']} as {v['as']}" for k, v in report["compared_as"].items())
        lines.append(f"compared as the drum the transcriber hears them as (it has no class of their own): {drums}")
    lines.extend(bar_lines(report))
    listed = sorted([*(m for m in report["misses"] if not m.get("after_take")), *report.get("wrong_drums", []),
                     *report["extras"]], key=lambda e: e["time_s"])
    # the notes a take falling behind (running ahead) played late (early) are one line, the run's (said above)
    runs = report.get("off_tempo") or []

    def run_of(entry: dict[str, Any]) -> int | None:
        off = entry.get("played_off_by_ms")
        for k, run in enumerate(runs):
            if (off is not None and run["from_bar"] <= (entry["bar"] if entry["bar"] is not None else -1)
                    <= run["to_bar"] and (off > 0) == (run["direction"] == "behind")):
                return k
        return None

    grouped: dict[int, list[dict[str, Any]]] = defaultdict(list)
    keyed = [(run_of(entry), entry) for entry in listed]
    for k, entry in keyed:
        if k is not None:
            grouped[k].append(entry)
    keyed = [(k, e) for k, e in keyed if k is None or grouped[k][0] is e]  # a run's line where its first note is
    if keyed:
        lines.append("")
    for k, entry in keyed[:MAX_LISTED]:
        if k is not None:
            group = grouped[k]
            offs = sorted(abs(e["played_off_by_ms"]) for e in group)
            late = runs[k]["direction"] == "behind"
            lines.append(f"{where_text(group[0])} to {where_text(group[-1])}: {len(group)} notes played "
                         f"{offs[0]:.0f} to {offs[-1]:.0f} ms {'late' if late else 'early'} "
                         f"({'falling behind' if late else 'running ahead'}, above)")
            continue
        if "played_drum" in entry:
            lines.append(f"{where_text(entry)}: played {entry['played_drum']} instead of {entry['drum']}")
            continue
        off = entry.get("played_off_by_ms")
        what = ("extra" if "take_time_s" in entry else "missed" if off is None else
                f"played {abs(off):.0f} ms {'late' if off > 0 else 'early'} (beyond the tolerance)")
        lines.append(f"{where_text(entry)}: {entry['drum']} {what}")
    if len(keyed) > MAX_LISTED:
        lines.append(f"... {len(keyed) - MAX_LISTED} more misses, extras and wrong drums (--json lists them all)")
    return lines


def _spread(t: dict[str, Any]) -> str:
    return f"{t['sd_ms']:.1f}" if t["n"] else "-"


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:+.1f} ms"


def _width(header: str, cells: Iterable[str], least: int = 8) -> int:
    """A table column's width: its header's and its widest cell's (``+100.0 ms`` is 9 characters: until 7 Dec the
    mean column was 8 wide, and a mean of 100 ms or more pushed the row's later columns one to the right)."""
    return max(least, len(header), *(len(cell) for cell in cells))


def _dynamics_text(d: dict[str, Any] | None) -> str:
    if d is None:
        return "-"
    text = f"{d['played_mean']:.0f} +- {d['played_sd']:.0f}"
    if "accents_louder" in d:
        verdict = ("accents louder" if d["accents_louder"] else
                   f"accents barely louder (+{d['accent_margin']:.0f})" if d.get("accents_barely_louder") else
                   "ACCENTS NOT LOUDER")
        text += f"; {verdict}: {d['accent_mean']:.0f} against {d['others_mean']:.0f}"
    elif "ghosts_softer" in d:
        verdict = ("ghost notes softer" if d["ghosts_softer"] else
                   f"ghost notes barely softer (-{d['ghost_margin']:.0f})" if d.get("ghosts_barely_softer") else
                   "GHOST NOTES NOT SOFTER")
        text += f"; {verdict}: {d['ghost_mean']:.0f} against {d['others_mean']:.0f}"
    elif d["spearman"] is not None:
        text += f"; written and played ranks agree {d['spearman']:+.2f} (Spearman)"
    return text


# ---------------------------------------------------------------------- the command


DESCRIPTION = """\
Compare a student's take with the exercise: which written notes were played,
missed, played on another drum or added, per drum, how early or late and how
steady, where each is (bar and beat), and whether accents were played as
accents; then bar by bar: the counts, the mean timing and the bar's tempo, the
bars rushed or dragged, the beats rushed or dragged (a short fill), and
whether the take sped up or slowed down.

EXERCISE: any score Batteur reads (a text score, a MIDI file; `demo`: the
shipped demo groove). TAKE: a MIDI file (an e-kit's recording) or an audio
file (WAV, FLAC, OGG, AIFF, MP3), transcribed as `batteur transcribe` does.

The student may start whenever they like: the take is lined up with the
exercise by the offset that matches most notes (every pair of notes of one
drum proposes one), set so that the median note is on time: early and late
are against the student's own pulse (--offset forces the start instead). Notes
before the exercise starts or after it ends (a count-in) are not extras; a
steady count-in (one sound repeated) says where the take entered against it
("entered 1 beat late after the count-in"). A take that stops and comes back
in is timed from there against the restart ("came back in 0.6 s late at bar
3, beat 1 after a pause"), not as late notes; an entry late or early after a
written rest is said ("bar 5: came in 0.5 s late (1 beat) after the rest
(bars 3-4)") and its notes told late or early (its bars rushed or dragging
only against it). After a pick-up bar (a first bar shorter than the next),
bar 1 is the first full bar and the pick-up bar 0, as printed; a pick-up
written in a full bar, rests first (a DAW's), is counted as written, and said.
A written note counts as played when the take has one on the same drum (kit
object: open and closed hi-hat, and the hi-hat pedal, are the hi-hat) within
--tolerance; else as played too early or late when one of its drum is within
150 ms (2 tolerances if more), or, where the take falls behind (runs ahead)
bar after bar, one of its drum where that lag is heading; else as played on
another drum ("played ride instead of hihat": not a miss and an extra) when a
strike on another drum is left within --tolerance (a cymbal for a cymbal, a
drum for a drum, first); else missed. Extras are the strikes left over. A beat is told rushed
(dragging) when its notes are: two onsets at least, more than half of them
over a quarter of --tolerance early (late) and their median over half of it;
one note off among steady ones is not. The beat judged so is the felt one:
in 6/8, 9/8 and 12/8 the dotted quarter ("bar 2, beats 4-6: rushed"), else
the counted beat (5/8 and 7/8 in eighths: their grouping is not written).
Positions are counted as a teacher does: beat 3, 3e, 3&, 3a (sixteenths),
3 trip, 3 let (triplets), 3 + 1/8 (a finer written note); off that grid, the
nearest point and how far from it on the take's clock ("beat 3& (12 ms
late)"), in that point's bar (a strike 20 ms before bar 4 is bar 4's, "bar 4,
beat 1 (20 ms early)", in the bar table too). The beat is the meter's note
value, as a DAW counts: eighths in x/8, 6/8 and 12/8 too (1 to 6, 1 to 12;
beat 4& is a sixteenth after the fourth eighth), quarters in x/4. Each bar's
tempo (quarter notes a minute) and mean timing, from its notes played on
their drum (too early or late ones too), is measured against its own written
tempo (a tempo map's); a drift is a tempo rising or falling against it; bars
played slower (faster) than written in a row, the lag growing over a bar's
worth of beats at least (not a fill's last beat played early), are said as
falling behind (running ahead: "falling behind in bars 3-4 after the tempo
change (90 -> 120 bpm)"); a take at another tempo than a tempo map is said in
% of the written one. An audio
take is compared on the drums the transcriber knows (kick, snare, hi-hat,
three toms, crash, ride); the others are listed apart. When most notes do not match, the tempo the take
is played at is looked for; when it matches clearly more, the take is
compared at it (said first) unless --tempo-scale is given (then it is only
reported). Timing is played minus written, in ms: + late, - early; the spread
is the standard deviation.
Velocities are MIDI's 0-127 (a transcription's are the recogniser's own).
"""

EPILOG = """\
examples:
  batteur compare exercise.txt take.mid
  batteur compare exercise.txt take.wav --json
  batteur compare demo take.flac --tempo-scale 0.8 --tolerance 0.03

exit status: 0 when the comparison ran, whatever it found; 1 for a file it
cannot use (missing, unreadable, a score given as the take, no notes); 2 for
a command line that cannot be run (an option's value out of range).
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION, epilog=EPILOG,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    take_negative_values(parser)  # --offset -0.5: the start of a take cut after the exercise began
    parser.add_argument("exercise", metavar="EXERCISE", help="the score (text or MIDI; demo: the demo groove)")
    parser.add_argument("take", metavar="TAKE", type=Path, help="the take: a MIDI file or an audio file")
    parser.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE_S, metavar="SECONDS",
                        help=f"a played note within this of the written one counts, seconds (default "
                        f"{DEFAULT_TOLERANCE_S:g}: 50 ms, what a listener hears as on the beat; lower it for "
                        f"fast sixteenths)")
    parser.add_argument("--offset", type=float, default=None, metavar="SECONDS",
                        help="the exercise starts this far into the take, seconds (default: found by lining up "
                        "the notes)")
    parser.add_argument("--tempo-scale", type=float, default=None, metavar="X",
                        help="the take is played X times faster than written, 0.1 to 10 (0.8: at 80 %% of the "
                        "tempo), as render's; default: the exercise's tempo, or the take's when most notes "
                        "match only at it (then said first)")
    parser.add_argument("--kit", default=None, metavar="NAME",
                        help="the kit whose objects the drums are (default: the exercise's kit line, else "
                        "default); it groups the notes, as evaluate does")
    parser.add_argument("--json", action="store_true", help="print the comparison as JSON")
    add_midi_arguments(parser)  # one --drum-channels for the exercise and a MIDI take
    parser.add_argument("--take-drum-map", type=drum_map, default=None, metavar="NAME|FILE",
                        help="the MIDI take's note layout when it is not the exercise's (an e-kit's: roland-td), "
                        "as --drum-map (default: --drum-map's)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``batteur compare``; the exit status (README, "Exit status")."""
    parser = build_parser()
    args = parser.parse_args(argv)
    low, high = TOLERANCE_RANGE_S
    if not low <= args.tolerance <= high:  # NaN fails too
        hint = (f" ({args.tolerance:g} ms is --tolerance {args.tolerance / 1000:g})"
                if 1 <= args.tolerance <= 500 else "")
        parser.error(f"--tolerance {args.tolerance:g}: {low:g} to {high:g} seconds{hint}")
    if args.tempo_scale is not None and not TEMPO_SCALE_RANGE[0] <= args.tempo_scale <= TEMPO_SCALE_RANGE[1]:
        hint = f" ({args.tempo_scale:g} % is {args.tempo_scale / 100:g})" if 10 <= args.tempo_scale <= 1000 else ""
        parser.error(f"--tempo-scale {args.tempo_scale:g}: {TEMPO_SCALE_RANGE[0]:g} to {TEMPO_SCALE_RANGE[1]:g} "
                     f"(times faster){hint}")
    if args.offset is not None and not math.isfinite(args.offset):
        parser.error(f"--offset {args.offset:g}: a number of seconds")

    def warn(text: str) -> None:
        print(f"{PROG}: warning: {text}", file=sys.stderr)

    from common.score.text import load_score_kit

    try:
        given = None
        if args.kit is not None:  # loaded first: the exercise's object ids are its kit's, as render reads them
            try:
                given = load_score_kit(None, args.kit)
            except (FileNotFoundError, ValueError) as exc:
                raise CompareError(f"--kit {args.kit}: {exc}") from None
        score = read_exercise(args.exercise, midi_read_kwargs(args), given)
        for text in worth_saying(score.warnings):
            warn(text)
        try:
            kit = given or load_score_kit(score, None)
        except (FileNotFoundError, ValueError) as exc:  # a ScoreError naming the score's kit line
            raise CompareError(str(exc)) from None
        take = read_take(args.take, kit, warn, {**midi_read_kwargs(args), **(
            {} if args.take_drum_map is None else {"note_map": args.take_drum_map})})
        for text in take.warnings:
            warn(f"TAKE {text}")
        report = compare(score, take, kit, args.tolerance, args.tempo_scale, args.offset)
    except (CompareError, OSError) as exc:
        return report_error(PROG, exc)
    if args.json:
        print(json.dumps({"exercise": args.exercise, "take": str(args.take), **report}, indent=2))
    else:
        print("\n".join(summary_lines(report, args.exercise, str(args.take))))
    return 0
