"""``batteur evaluate``: how accurately the simulated drummer played a score.

Every score note is matched to at most one impact and every impact to at
most one note (optimal one-to-one matching, :func:`match`): a pair counts when
the impact is on the note's kit object (its drum event's object; pedal events
sound on the instrument the pedal drives) and within the tolerance window.
Reported per file and in aggregate (micro-averaged over all notes):

* precision, recall and F-measure at 10 ms and 25 ms;
* timing error (impact time - note time, ms) of the pairs matched at 25 ms:
  median and 95th percentile of the absolute error, and the median signed
  error (the systematic lag); the same over a loose 100 ms matching, so a
  systematic lag beyond the windows still shows;
* Spearman rank correlation between score velocity and impact velocity
  (normal approach speed, m/s) over the 25 ms pairs, pooled and per instrument,
  and within each sound (:func:`spearman_within`: a pedal chick and a stick
  stroke on the hi-hat are two sounds whose speeds are not comparable);
* spurious impacts (not matched at 25 ms);
* every missed note with a reason: the planner's feasibility issue (dropped,
  too fast, ...), or what the performance did instead (``timing``: an impact
  on the right object outside 25 ms, ``wrong_instrument``, ``no_contact``):
  no note is silently lost; the file's notes with no drum for their pitch
  (``no_drum_for_pitch``) are listed and counted (``no_drum_notes``) but, as
  ``not_in_kit`` notes, left out of the figures (docs/evaluation.md);
* real-time factor of the render.

Renders with :mod:`batteur.render` unless given an existing render directory.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
import tempfile
import textwrap
import time
from collections import Counter, defaultdict
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.stats import spearmanr

from batteur.errors import INTERRUPTED, TERMINATED, USAGE, UsageError, report_error
from batteur.interrupts import Terminated, sigterm_raises
from common.arg_types import take_negative_values
from common.kit import EventType, Kit, load_kit
from common.score.events import Score
from common.score.midi_notes import note_map_from_json, note_map_json
from common.score.midi_options import add_midi_arguments, midi_read_kwargs

WINDOWS_S: tuple[float, float] = (0.010, 0.025)
"""Tolerance windows, seconds."""
MIN_SOUND_PAIRS = 5
"""Pairs a sound (kit object and drum event) needs before its own Spearman counts in :func:`spearman_within`."""
LOOSE_WINDOW_S = 0.100
"""Window of the loose matching (systematic lag, missed-note reasons), seconds."""


@dataclass(frozen=True)
class NoteRef:
    """A score note to be played: index in ``Score.events``, time (s), expected kit object, velocity [0, 1]."""

    index: int
    time: float
    instrument: str
    velocity: float
    event: str = ""


@dataclass(frozen=True)
class Hit:
    """An impact: time (s, score clock), kit object, normal velocity (m/s), striker part."""

    time: float
    instrument: str
    velocity: float
    part: str = ""


@dataclass(frozen=True)
class Flag:
    """Why a note was not played (``source``: ``planner`` or ``performance``; ``score``: a note of the file with
    no drum for its pitch, ``index`` None, as it is none of ``Score.events``)."""

    index: int | None
    time: float
    event: str
    reason: str
    source: str
    detail: str = ""


@dataclass
class FileResult:
    """Evaluation of one performance (times in ms where named so)."""

    name: str
    notes: int
    impacts: int
    matched: dict[str, int]
    precision: dict[str, float]
    recall: dict[str, float]
    f_measure: dict[str, float]
    timing_ms: dict[str, float | None]
    timing_loose_ms: dict[str, float | None]
    spearman: float | None
    spearman_by_instrument: dict[str, float | None]
    spearman_within_sound: float | None
    spurious: int
    missed: list[Flag]
    missed_by_reason: dict[str, int]
    planner_flags: int
    real_time_factor: float | None = None
    no_drum_notes: int = 0
    """Notes of the file read with no drum for their pitch (``Score.unknown``; reason ``no_drum_for_pitch``): never
    played, listed in ``missed`` but not in ``notes``, recall or F (the drummer was not given them, as
    ``not_in_kit``); the table's ``nodrum`` column and a line under it say them."""
    music_duration_s: float = 0.0
    """The score's planned length, seconds (report.json's ``music_duration_s``)."""
    duration_s: float = 0.0
    """What was simulated: the WAV's length with the lead-in and the tail, seconds (report.json's ``duration_s``,
    what its real-time factor is computed on)."""
    wall_time_s: float = 0.0
    cpu_time_s: float = 0.0
    # raw material for aggregation and plots (not in the JSON summary)
    errors_s: list[float] = field(default_factory=list, repr=False)
    velocity_pairs: list[tuple[float, float, str]] = field(default_factory=list, repr=False)
    note_refs: list[NoteRef] = field(default_factory=list, repr=False)
    hits: list[Hit] = field(default_factory=list, repr=False)
    pairs_25: list[tuple[int, int]] = field(default_factory=list, repr=False)
    pairs_loose: list[tuple[int, int]] = field(default_factory=list, repr=False)
    render: str | None = None
    """The render folder named on the command line, whose row this is (named ``FOLDER (SCORE)``); None for a
    score rendered by the evaluation."""
    source: str = field(default="", repr=False)
    """The score or render folder as given on the command line (:func:`name_results`; not in the JSON summary)."""
    stem: str = field(default="", repr=False)
    """The plots' file name stem, unique among one run's results (:func:`name_results`; not in the JSON summary)."""

    def summary(self) -> dict[str, Any]:
        out = {k: v for k, v in asdict(self).items()
               if k not in ("errors_s", "velocity_pairs", "note_refs", "hits", "pairs_25", "pairs_loose",
                          "missed", "source", "stem")}
        out["missed"] = [asdict(f) for f in self.missed]
        # each spurious impact as missed notes are listed (until 7 Dec only counted)
        out["spurious_impacts"] = [row for row in impact_rows(self) if not row["matched"]]
        return out


# ---------------------------------------------------------------------- matching


def reach_clusters(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray,
                   window: float) -> list[tuple[list[int], list[int]]]:
    """The positions in ``a`` and in ``b`` (times, seconds) of each cluster of mutually reachable times: the
    merged times break wherever a gap exceeds ``window``, so no ``a`` and ``b`` within ``window`` of each other
    lie in two clusters (what one-to-one matching can solve cluster by cluster)."""
    events = sorted([(t, 0, i) for i, t in enumerate(a)] + [(t, 1, j) for j, t in enumerate(b)])
    clusters: list[tuple[list[int], list[int]]] = []
    last = -math.inf
    for t, side, k in events:
        if t - last > window or not clusters:
            clusters.append(([], []))
        clusters[-1][side].append(k)
        last = t
    return clusters


def _match_times(a: np.ndarray, b: np.ndarray, window: float) -> list[tuple[int, int]]:
    """Optimal one-to-one pairs (i, j) with ``|a[i] - b[j]| <= window``: the most pairs, then least total error.

    ``a`` and ``b`` sorted (seconds). Solved per cluster of mutually reachable
    times with :func:`scipy.optimize.linear_sum_assignment`.
    """
    if len(a) == 0 or len(b) == 0:
        return []
    pairs: list[tuple[int, int]] = []
    for ia, jb in reach_clusters(a, b, window):
        if not ia or not jb:
            continue
        d = np.abs(a[ia][:, None] - b[jb][None, :])
        ok = d <= window + 1e-12
        if not ok.any():
            continue
        # a valid pair is worth far more than any sum of errors: maximum cardinality, then minimum error
        big = 1.0 + window * (len(ia) + len(jb))
        cost = np.where(ok, d - big, 0.0)
        rows, cols = linear_sum_assignment(cost)
        pairs += [(ia[r], jb[c]) for r, c in zip(rows, cols, strict=True) if ok[r, c]]
    return sorted(pairs)


def match(notes: Sequence[NoteRef], hits: Sequence[Hit], window: float) -> list[tuple[int, int]]:
    """One-to-one pairs (note position, hit position) on the same instrument within ``window`` seconds."""
    by_inst_n: dict[str, list[int]] = defaultdict(list)
    by_inst_h: dict[str, list[int]] = defaultdict(list)
    for i, n in enumerate(notes):
        by_inst_n[n.instrument].append(i)
    for j, h in enumerate(hits):
        by_inst_h[h.instrument].append(j)
    pairs: list[tuple[int, int]] = []
    for inst, ni in by_inst_n.items():
        hj = by_inst_h.get(inst, [])
        ni_sorted = sorted(ni, key=lambda i: notes[i].time)
        hj_sorted = sorted(hj, key=lambda j: hits[j].time)
        a = np.array([notes[i].time for i in ni_sorted])
        b = np.array([hits[j].time for j in hj_sorted])
        pairs += [(ni_sorted[x], hj_sorted[y]) for x, y in _match_times(a, b, window)]
    return sorted(pairs)


def _prf(tp: int, notes: int, hits: int) -> tuple[float, float, float]:
    p = tp / hits if hits else (1.0 if notes == 0 else 0.0)
    r = tp / notes if notes else 1.0
    f = 2 * p * r / (p + r) if p + r > 0 else 0.0
    return p, r, f


def timing_stats(errors_s: Iterable[float]) -> dict[str, float | None]:
    """Median and 95th percentile of |error|, median signed error, in ms (None without pairs)."""
    e = np.asarray(list(errors_s), dtype=float) * 1000.0
    if e.size == 0:
        return {"median_abs": None, "p95_abs": None, "median_signed": None, "n": 0}
    return {"median_abs": round(float(np.median(np.abs(e))), 3),
            "p95_abs": round(float(np.percentile(np.abs(e), 95)), 3),
            "median_signed": round(float(np.median(e)), 3), "n": int(e.size)}


def spearman(pairs: Sequence[tuple[float, float, str]]) -> float | None:
    """Spearman correlation of (score velocity, impact velocity); None when undefined (< 3 pairs or constant)."""
    if len(pairs) < 3:
        return None
    x = np.array([p[0] for p in pairs])
    y = np.array([p[1] for p in pairs])
    if np.all(x == x[0]) or np.all(y == y[0]):
        return None
    rho = spearmanr(x, y).statistic
    return None if not np.isfinite(rho) else round(float(rho), 4)


def sound_pairs(notes: Sequence[NoteRef], hits: Sequence[Hit], pairs: Iterable[tuple[int, int]]
                ) -> dict[str, list[tuple[float, float, str]]]:
    """(score velocity, impact velocity, instrument) of matched pairs grouped by sound: ``"object/EVENT"``."""
    out: dict[str, list[tuple[float, float, str]]] = defaultdict(list)
    for i, j in pairs:
        note = notes[i]
        out[f"{note.instrument}/{note.event}"].append((note.velocity, hits[j].velocity, note.instrument))
    return out


def spearman_within(groups: dict[str, list[tuple[float, float, str]]]) -> float | None:
    """Spearman within each sound, averaged weighted by its pairs (sounds with >= ``MIN_SOUND_PAIRS`` and a
    defined correlation); None when no sound qualifies.

    Whether louder written notes are played louder on each sound, whatever the sounds' different gains: the
    pooled figure also asks that equal score velocities give equal approach speeds across objects and
    strikers, which a foot closing the hi-hat (plates meeting at 0.1-0.4 m/s) cannot match against sticks
    (1-8 m/s).
    """
    total, weight = 0.0, 0
    for pairs in groups.values():
        rho = spearman(pairs) if len(pairs) >= MIN_SOUND_PAIRS else None
        if rho is not None:
            total += rho * len(pairs)
            weight += len(pairs)
    return round(total / weight, 4) if weight else None


def evaluate_performance(name: str, notes: Sequence[NoteRef], hits: Sequence[Hit],
                         planner_flags: Sequence[Flag] = (), windows: Sequence[float] = WINDOWS_S) -> FileResult:
    """Score one performance (see the module docstring). ``planner_flags``: notes the planner flagged."""
    matched: dict[str, int] = {}
    precision: dict[str, float] = {}
    recall: dict[str, float] = {}
    fmeas: dict[str, float] = {}
    pairs_by: dict[float, list[tuple[int, int]]] = {}
    for w in windows:
        pairs = match(notes, hits, w)
        pairs_by[w] = pairs
        key = f"{round(w * 1000):d}ms"
        p, r, f = _prf(len(pairs), len(notes), len(hits))
        matched[key], precision[key], recall[key], fmeas[key] = len(pairs), round(p, 4), round(r, 4), round(f, 4)
    widest = max(windows)
    pairs = pairs_by[widest]
    errors = [hits[j].time - notes[i].time for i, j in pairs]
    loose = match(notes, hits, max(LOOSE_WINDOW_S, widest))
    vel_pairs = [(notes[i].velocity, hits[j].velocity, notes[i].instrument) for i, j in pairs]
    by_inst: dict[str, list[tuple[float, float, str]]] = defaultdict(list)
    for vp in vel_pairs:
        by_inst[vp[2]].append(vp)
    # missed notes and their reasons
    matched_notes = {i for i, _ in pairs}
    matched_hits = {j for _, j in pairs}
    loose_of = dict(loose)
    flagged = {f.index: f for f in planner_flags}
    missed: list[Flag] = []
    spare = [j for j in range(len(hits)) if j not in matched_hits]
    for i, n in enumerate(notes):
        if i in matched_notes:
            continue
        if n.index in flagged:
            missed.append(flagged[n.index])
            continue
        j = loose_of.get(i)
        if j is not None:
            dt = (hits[j].time - n.time) * 1000
            missed.append(Flag(n.index, n.time, n.event, "timing", "performance",
                               f"impact on {n.instrument} {dt:+.1f} ms from the note"))
            continue
        near = [j for j in spare if abs(hits[j].time - n.time) <= widest]
        if near:
            j = min(near, key=lambda j: abs(hits[j].time - n.time))
            missed.append(Flag(n.index, n.time, n.event, "wrong_instrument", "performance",
                               f"{hits[j].instrument} struck by {hits[j].part} instead of {n.instrument}"))
            continue
        missed.append(Flag(n.index, n.time, n.event, "no_contact", "performance",
                           f"no impact on {n.instrument} within {LOOSE_WINDOW_S * 1000:.0f} ms"))
    return FileResult(
        name=name, notes=len(notes), impacts=len(hits), matched=matched, precision=precision, recall=recall,
        f_measure=fmeas, timing_ms=timing_stats(errors),
        timing_loose_ms=timing_stats(hits[j].time - notes[i].time for i, j in loose),
        spearman=spearman(vel_pairs),
        spearman_by_instrument={k: spearman(v) for k, v in sorted(by_inst.items())},
        spearman_within_sound=spearman_within(sound_pairs(notes, hits, pairs)),
        spurious=len(hits) - len(pairs), missed=missed,
        missed_by_reason=dict(sorted(Counter(f.reason for f in missed).items())),
        planner_flags=len(planner_flags), errors_s=errors, velocity_pairs=vel_pairs,
        note_refs=list(notes), hits=list(hits), pairs_25=pairs, pairs_loose=loose,
    )


def aggregate(results: Sequence[FileResult], windows: Sequence[float] = WINDOWS_S) -> dict[str, Any]:
    """Micro-averaged figures over files (every note and impact counts once)."""
    notes = sum(r.notes for r in results)
    hits = sum(r.impacts for r in results)
    out: dict[str, Any] = {"files": len(results), "notes": notes, "impacts": hits}
    for key in ("precision", "recall", "f_measure", "matched"):
        out[key] = {}
    for w in windows:
        key = f"{round(w * 1000):d}ms"
        tp = sum(r.matched[key] for r in results)
        p, r_, f = _prf(tp, notes, hits)
        out["matched"][key], out["precision"][key], out["recall"][key], out["f_measure"][key] = (
            tp, round(p, 4), round(r_, 4), round(f, 4))
    out["timing_ms"] = timing_stats(e for r in results for e in r.errors_s)
    out["spearman"] = spearman([vp for r in results for vp in r.velocity_pairs])
    by_inst: dict[str, list[tuple[float, float, str]]] = defaultdict(list)
    for r in results:
        for vp in r.velocity_pairs:
            by_inst[vp[2]].append(vp)
    out["spearman_by_instrument"] = {k: spearman(v) for k, v in sorted(by_inst.items())}
    sounds: dict[str, list[tuple[float, float, str]]] = defaultdict(list)
    for r in results:
        for key, v in sound_pairs(r.note_refs, r.hits, r.pairs_25).items():
            sounds[key] += v
    out["spearman_within_sound"] = spearman_within(sounds)
    out["spearman_by_sound"] = {k: spearman(v) for k, v in sorted(sounds.items())}
    out["spurious"] = sum(r.spurious for r in results)
    out["missed"] = sum(len(r.missed) for r in results)
    reasons: Counter[str] = Counter()
    for r in results:
        reasons.update(r.missed_by_reason)
    out["missed_by_reason"] = dict(sorted(reasons.items()))
    out["planner_flags"] = sum(r.planner_flags for r in results)
    out["no_drum_notes"] = sum(r.no_drum_notes for r in results)
    # the real-time factors as report.json's: seconds simulated (lead-in and tail included) per wall/CPU second
    simulated = sum(r.duration_s for r in results)
    wall = sum(r.wall_time_s for r in results)
    out["music_duration_s"] = round(sum(r.music_duration_s for r in results), 3)
    out["duration_s"] = round(simulated, 3)
    out["wall_time_s"] = round(wall, 3)
    out["real_time_factor"] = round(simulated / wall, 3) if wall > 0 else None
    cpu = sum(r.cpu_time_s for r in results)
    out["cpu_time_s"] = round(cpu, 3)
    out["real_time_factor_cpu"] = round(simulated / cpu, 3) if cpu > 0 else None
    return out


# ---------------------------------------------------------------------- from a score and a render


def expected_instrument(kit: Kit, event: EventType, pitch: int | None = None) -> str:
    """The kit object a note of ``event`` must sound on (pedal events: the instrument the pedal drives; a BASS note
    routed to a footboard: the kick, BASS's object whatever its id, which physics reports the beater striking)."""
    obj = kit.object_for(event, pitch)
    if obj.kind == "pedal":
        if event == EventType.HIHATPEDAL and EventType.HIHATCLOSED in kit.events:
            return kit.object_for(EventType.HIHATCLOSED).id
        kick = kit.kick()
        if event == EventType.BASS and kick is not None and kick.kind != "pedal":
            return kick.id
    return obj.id


def note_refs(score: Score, kit: Kit) -> list[NoteRef]:
    """The score's notes the kit can play, with the object each must sound on."""
    out: list[NoteRef] = []
    for i, e in enumerate(score.events):
        if e.event not in kit.events:
            continue
        out.append(NoteRef(i, e.time, expected_instrument(kit, e.event, e.pitch), e.velocity, e.event.value))
    return out


def no_drum_flags(score: Score) -> list[Flag]:
    """The file's notes with no drum for their pitch (``Score.unknown``): read, never played (flagged, never
    silently lost)."""
    return [Flag(None, u.time, f"pitch {u.pitch}", "no_drum_for_pitch", "score",
                 f"channel {u.channel}: no drum event type for this pitch") for u in score.unknown]


def unplayable_flags(score: Score, kit: Kit) -> list[Flag]:
    """Score events the kit has no object for (flagged, never silently lost)."""
    return [Flag(i, e.time, e.event.value, "not_in_kit", "planner", f"kit {kit.name!r} does not play it")
            for i, e in enumerate(score.events) if e.event not in kit.events]


def planner_flags(issues: Any, where: Path | str = "report.json") -> list[Flag]:
    """Flags from report.json's issues: notes the planner found beyond limits (dropped, merged, moved...).

    ``ValueError`` naming ``where`` (the report) and the issue when they are not the render's issues.
    """
    if not isinstance(issues, list):
        raise ValueError(f"{where}: issues must be a list, got {type(issues).__name__}")
    out = []
    for k, issue in enumerate(issues):
        try:
            if not isinstance(issue, dict):
                raise TypeError(f"a {type(issue).__name__}, not an object")
            if issue.get("note_index") is None:
                continue
            out.append(Flag(int(issue["note_index"]), float(issue["time_s"]), issue.get("event") or "",
                            str(issue["reason"]), "planner", f"{issue['action']}: {issue.get('detail', '')}"))
        except KeyError as exc:
            raise ValueError(f"{where}: issue {k} has no {exc}") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: issue {k} is not a planner issue ({exc})") from None
    return out


def report_number(report: dict[str, Any], key: str, where: Path) -> float | None:
    """``report[key]`` as a finite float, None when missing or null; ``ValueError`` naming the file and key for
    anything else (a hand-edited or damaged report must not give figures computed from NaN)."""
    value = report.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)


def read_report(render_dir: Path) -> dict[str, Any]:
    """A render directory's report.json; ``ValueError`` naming it when it is missing or not a render report."""
    path = render_dir / "report.json"
    if not path.is_file():
        raise ValueError(f"{render_dir}: not a render directory (no report.json; `batteur render SCORE -o DIR` "
                         "makes one)")
    try:
        report = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:  # not JSON, or not UTF-8
        raise ValueError(f"{path}: not a render report ({exc})") from None
    if not isinstance(report, dict):
        raise ValueError(f"{path}: not a render report (not a JSON object)")
    return report


def render_dir_score(render_dir: Path) -> Path:
    """The score of a render directory: its copy ``score.<suffix of the score in report.json>`` (a folder
    rendered into twice may hold an earlier render's copy too), else the path in report.json (which
    :func:`evaluate_render_dir` reads and checks in any case)."""
    source = read_report(render_dir).get("score")
    if isinstance(source, str) and source:
        copy = render_dir / f"score{Path(source).suffix}"
        return copy if copy.is_file() else Path(source)
    copies = sorted(render_dir.glob("score.*"))
    if copies:
        return copies[0]
    raise ValueError(f"{render_dir}: holds no score.* and its report.json names no score")


def render_dir_kit(render_dir: Path, report: dict[str, Any]) -> str:
    """The kit a render directory's performance is judged on: the copy of its kit file the render made
    (report.json's ``kit_copy``, as the score's: the kit it played, wherever evaluate runs from), else the kit as
    report.json names it (a shipped kit's name; the file's absolute path ``kit_file``, or as typed: a render made
    before 7 Dec). A warning on stderr when the kit file has been edited since the render: the copy is judged on.
    ``ValueError`` naming report.json for a kit entry that is not a name."""
    where = render_dir / "report.json"
    name = report.get("kit", "default")
    if not isinstance(name, str):
        raise ValueError(f"{where}: kit must be a kit name or file, got {name!r}")
    source, copy = report.get("kit_file"), report.get("kit_copy")
    if source is not None and not isinstance(source, str):
        raise ValueError(f"{where}: kit_file must be a kit file's path, got {source!r}")
    if isinstance(copy, str) and Path(copy).name == copy and (render_dir / copy).is_file():
        kept = render_dir / copy
        if source is not None and Path(source).resolve() != kept.resolve() and edited(Path(source), kept):
            print(f"{PROG}: warning: {source} has changed since {render_dir} was rendered; judged on the kit it "
                  f"played, its copy {kept}", file=sys.stderr)
        return str(kept)
    return source if source is not None else name


def load_render_dir_kit(kit: str, where: Path) -> Kit:
    """:func:`render_dir_kit`'s kit loaded (no load warnings: its render gave them); a relative kit file that is not
    there: ``FileNotFoundError`` saying why (a render before 7 Dec kept no copy and named it as typed)."""
    try:
        return load_kit(kit, warn=False)
    except FileNotFoundError:
        if not Path(kit).suffix or Path(kit).is_absolute() or Path(kit).exists():
            raise
        raise FileNotFoundError(f"{where}: no kit file {kit!r} from here: a render made before 7 Dec kept no copy "
                                "of its kit and names the file as it was given, relative to where the render ran; "
                                "run batteur evaluate from there (or render again)") from None


def edited(kit: Path, copy: Path) -> bool:
    """Whether the kit file ``kit`` differs from a render's ``copy`` of it (a file gone or unreadable: not edited,
    nothing to compare)."""
    try:
        return kit.read_bytes() != copy.read_bytes()
    except OSError:
        return False


def report_midi_kwargs(report: dict[str, Any], where: Path) -> dict[str, Any]:
    """How the render of ``report`` read its MIDI score (``--drum-channels``: its ``drum_channels``), as keyword
    arguments of ``read_score``: the score is judged as it was played. A report without them: the reader's
    defaults (a render made before they were recorded, or without the option). ``--drum-map``: its ``drum_map``;
    ``--hihat-cc4``: its ``hihat_cc4``."""
    mapped = note_map_from_json(report.get("drum_map"), str(where))  # a DrumMapError is a ValueError
    kwargs: dict[str, Any] = {} if mapped is None else {"note_map": mapped}
    pedal = report.get("hihat_cc4", False)
    if not isinstance(pedal, bool):
        raise ValueError(f"{where}: hihat_cc4 must be true or false, got {pedal!r}")
    if pedal:
        kwargs["hihat_cc4"] = True
    channels = report.get("drum_channels")
    if channels is None:
        return kwargs
    if not (isinstance(channels, list) and channels
            and all(isinstance(c, int) and not isinstance(c, bool) and 1 <= c <= 16 for c in channels)):
        raise ValueError(f"{where}: drum_channels must be a list of MIDI channels 1 to 16, got {channels!r}")
    return {**kwargs, "drum_channels": tuple(channels)}


def report_part(score: Score, report: dict[str, Any], where: Path) -> Score:
    """``score`` cut to the bars a render of part of it played (report.json's ``bars``: ``batteur render --bars``),
    on the part's clock as the render's impacts are; the whole score for a whole render. ValueError naming ``where``
    for an entry that is not a render's."""
    from batteur.score_part import bar_part

    part = report.get("bars")
    if part is None:
        return score
    first = part.get("first") if isinstance(part, dict) else None
    last = part.get("last") if isinstance(part, dict) else None
    if not isinstance(first, int) or not isinstance(last, int):
        raise ValueError(f"{where}: bars must be null or hold the first and last bar rendered, got {part!r}")
    return bar_part(score, (first, last), Path(str(report.get("score") or where)).name)[0]


def evaluate_render_dir(score_path: Path, render_dir: Path, kit: Kit | None = None) -> FileResult:
    """Evaluate an existing render directory (impacts.csv + report.json) against its score."""
    from batteur.impact_log import read_impacts_csv
    from batteur.render import scale_tempo
    from common.score.text import read_score

    report = read_report(render_dir)
    where = render_dir / "report.json"
    if report.get("scene") != "drummer":
        raise ValueError(f"{render_dir}: not a score render (scene {report.get('scene')!r})")
    offset = report_number(report, "score_offset_s", where)
    if offset is None:
        raise ValueError(f"{where}: not a render report (no score_offset_s)")
    kit_name = render_dir_kit(render_dir, report) if kit is None else ""  # the copy the render made, if any
    tempo_scale = report_number(report, "tempo_scale", where)
    if tempo_scale is not None and tempo_scale <= 0:
        raise ValueError(f"{where}: tempo_scale must be positive, got {tempo_scale:g}")
    flags = planner_flags(report.get("issues", []), where)
    timing = {key: report_number(report, key, where) for key in ("real_time_factor", "duration_s", "music_duration_s",
                                                                   "wall_time_s", "cpu_time_s")}
    if kit is None:
        kit = load_render_dir_kit(kit_name, where)
    # a text score's kit object ids (crash2) in the kit played, as render read it (until 7 Dec its kit line's)
    score = scale_tempo(read_score(score_path, kit=kit, **report_midi_kwargs(report, where)),
                        1.0 if tempo_scale is None else tempo_scale)
    score = report_part(score, report, where)  # --bars: the part rendered, on its clock
    if not (render_dir / "impacts.csv").is_file():
        raise ValueError(f"{render_dir}: no impacts.csv (not a whole render)")
    impacts = read_impacts_csv(render_dir / "impacts.csv")
    hits = [Hit(i.time - offset, i.instrument, i.velocity, i.part) for i in impacts]
    source = report.get("score")
    name = Path(source if isinstance(source, str) and source else score_path).name
    result = evaluate_performance(name, note_refs(score, kit), hits, flags)
    result.missed += unplayable_flags(score, kit)
    unknown = no_drum_flags(score)
    result.missed += unknown
    result.no_drum_notes = len(unknown)
    result.missed_by_reason = dict(sorted(Counter(f.reason for f in result.missed).items()))
    result.real_time_factor = timing["real_time_factor"]
    result.music_duration_s = timing["music_duration_s"] or 0.0
    result.duration_s = timing["duration_s"] or 0.0
    result.wall_time_s = timing["wall_time_s"] or 0.0
    result.cpu_time_s = timing["cpu_time_s"] or 0.0
    return result


# ---------------------------------------------------------------------- plots


def plot_stem(result: FileResult) -> str:
    """The plots' file name stem: the one :func:`name_results` gave, unique in the run; else the render folder's
    name for a folder named on the command line (two renders of one score must not overwrite each other's plots),
    else the score's stem."""
    if result.stem:
        return result.stem
    return folder_name(Path(result.render)) if result.render else Path(result.name).stem


ROW_PAD = 0.6
"""Rows of space above the top row and below the bottom one in the piano roll: an impact is drawn 0.15 of a row above
its note, and the default margin clipped the top row's crosses at the border (until 8 Dec)."""


def pianoroll_figure(result: FileResult) -> Any:
    """The piano roll of ``result`` (a matplotlib Figure): score notes as circles (green played, red missed) and
    impacts as crosses (blue matched, orange spurious), one row per kit object, each row padded (:data:`ROW_PAD`) so
    no marker is clipped, the legend outside the axes on the right (inside, it covered the notes at the right end:
    until 8 Dec)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    instruments = sorted({n.instrument for n in result.note_refs} | {h.instrument for h in result.hits})
    row = {name: k for k, name in enumerate(instruments)}
    matched_n = {i for i, _ in result.pairs_25}
    matched_h = {j for _, j in result.pairs_25}
    fig, ax = plt.subplots(figsize=(14, max(2.0, 1.0 + 0.5 * len(instruments))))  # 2 in: the legend's height
    for ok, colour, label in ((True, "tab:green", "note played"), (False, "tab:red", "note missed")):
        xs = [n.time for i, n in enumerate(result.note_refs) if (i in matched_n) == ok]
        ys = [float(row[n.instrument]) for i, n in enumerate(result.note_refs) if (i in matched_n) == ok]
        if xs:
            ax.scatter(xs, ys, s=60, facecolors="none", edgecolors=colour, label=label)
    for ok, colour, label in ((True, "tab:blue", "impact (matched)"), (False, "tab:orange", "impact (spurious)")):
        xs = [h.time for j, h in enumerate(result.hits) if (j in matched_h) == ok]
        ys = [row[h.instrument] + 0.15 for j, h in enumerate(result.hits) if (j in matched_h) == ok]
        if xs:
            ax.scatter(xs, ys, s=12, c=colour, marker="x", label=label)
    ax.set_yticks(range(len(instruments)), instruments)
    ax.set_ylim(-ROW_PAD, max(len(instruments) - 1, 0) + ROW_PAD)
    ax.set_xlabel("score time (s)")
    ax.set_title(f"{result.name}: score vs impacts (25 ms matching)")
    if ax.get_legend_handles_labels()[0]:  # nothing drawn: no empty legend box
        ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0, fontsize=8)
    fig.tight_layout()
    return fig


def plot_result(result: FileResult, directory: Path) -> list[Path]:
    """Piano roll (score vs impacts, :func:`pianoroll_figure`) and timing-error histogram as PNG files in
    ``directory``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    stem = plot_stem(result)
    fig = pianoroll_figure(result)
    roll = directory / f"{stem}_pianoroll.png"
    fig.savefig(roll, dpi=100)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    errors = np.asarray(result.errors_s) * 1000
    ax.hist(errors, bins=[float(b) for b in range(-25, 26)], color="tab:blue")
    ax.set_xlabel("impact time - note time (ms)")
    ax.set_ylabel("notes")
    ax.set_title(f"{result.name}: timing error (n={len(errors)})")
    fig.tight_layout()
    hist = directory / f"{stem}_timing.png"
    fig.savefig(hist, dpi=100)
    plt.close(fig)
    return [roll, hist]


# ---------------------------------------------------------------------- command line


LABEL_WIDTH = 28
"""The label column's width when every label fits, characters."""
MAX_LABEL_WIDTH = 60
"""Widest the label column grows to for longer labels, characters (a Groove MIDI file's name is about 52)."""


def fit_label(label: str, width: int) -> str:
    """``label`` in at most ``width`` characters: as it is if it fits, else cut in the middle ("...") so that
    its start and its end stay (Groove MIDI names of one session differ only at their end: ``..._beat_3-4``)."""
    if len(label) <= width:
        return label
    kept = width - 3
    head = kept // 2
    return f"{label[:head]}...{label[len(label) - (kept - head):]}"


def format_table(rows: Sequence[tuple[str, dict[str, Any]]]) -> str:
    """A plain-text table of aggregate (or per-file) figures, one row per label (timing columns in milliseconds,
    ``rho``: Spearman pooled, ``rho_s``: within each sound, ``RTF``: real-time factor); the label column as wide as the
    longest label, from :data:`LABEL_WIDTH` to :data:`MAX_LABEL_WIDTH` characters (longer ones :func:`fit_label`)."""
    width = min(MAX_LABEL_WIDTH, max([LABEL_WIDTH, *(len(label) for label, _ in rows)]))
    head = (f"{'':<{width}} {'notes':>6} {'F@10':>6} {'F@25':>6} {'P@25':>6} {'R@25':>6} "
            f"{'med|e| ms':>10} {'p95|e| ms':>10} {'bias ms':>7} "
            f"{'rho':>6} {'rho_s':>6} {'spur':>5} {'miss':>5} {'nodrum':>6} {'flag':>5} {'RTF':>5}")
    lines = [head]
    for label, a in rows:
        t = a["timing_ms"]
        missed = len(a["missed"]) if isinstance(a["missed"], list) else a["missed"]

        def num(v: Any, fmt: str) -> str:  # a missing figure keeps its column's width
            return format(v, fmt) if v is not None else "-".rjust(int(fmt.lstrip("+").split(".")[0]))

        lines.append(
            f"{fit_label(label, width):<{width}} {a['notes']:>6} {a['f_measure']['10ms']:>6.3f} "
            f"{a['f_measure']['25ms']:>6.3f} {a['precision']['25ms']:>6.3f} {a['recall']['25ms']:>6.3f} "
            f"{num(t['median_abs'], '10.2f')} {num(t['p95_abs'], '10.2f')} {num(t['median_signed'], '+7.2f')} "
            f"{num(a['spearman'], '6.3f')} {num(a.get('spearman_within_sound'), '6.3f')} {a['spurious']:>5} "
            f"{missed:>5} {a.get('no_drum_notes', 0):>6} {a['planner_flags']:>5} "
            f"{num(a['real_time_factor'], '5.2f')}")
    return "\n".join(lines)


TABLE_LEGEND: tuple[tuple[str, str], ...] = (
    ("notes", "notes given to the drummer"),
    ("F@10, F@25", "F-measure, impacts within 10, 25 ms"),
    ("P@25, R@25", "precision, recall"),
    ("med|e|, p95|e|", "median, 95th percentile timing error"),
    ("bias", "median signed error (+: late)"),
    ("rho", "velocity rank correlation (Spearman)"),
    ("rho_s", "the same within each sound"),
    ("spur", "impacts matching no note"),
    ("miss", "notes missed"),
    ("nodrum", "notes with no drum for their pitch"),
    ("flag", "notes the planner flagged"),
    ("RTF", "real-time factor, seconds of audio rendered per wall-clock second (below 1: slower than real time)"),
)
"""What each column of :func:`format_table` holds, said under the table (until 8 Dec ``rho_s``, ``nodrum``, ``flag``
and ``RTF`` were explained nowhere on screen)."""
LEGEND_WIDTH = 118
"""The legend's lines are wrapped to this many characters (about the table's width)."""


def table_legend() -> str:
    """:data:`TABLE_LEGEND` as indented lines of at most :data:`LEGEND_WIDTH` characters, starting ``  columns:``."""
    words = "; ".join(f"{column}: {meaning}" for column, meaning in TABLE_LEGEND)
    return textwrap.fill(f"columns: {words}", LEGEND_WIDTH, initial_indent="  ", subsequent_indent="  ",
                         break_on_hyphens=False)


def evaluate_scores(paths: Sequence[Path], opts: Any, renders: Path | None, quiet: bool = True,
                    reuse: bool = False) -> list[FileResult]:
    """Render (or reuse) each score and evaluate it. ``opts``: :class:`batteur.render.RenderOptions`."""
    from batteur.render import render_score

    results = []
    created = created_folders(renders) if renders is not None else []
    with tempfile.TemporaryDirectory(prefix="batteur-evaluate-") as tmp, remove_if_empty(created):
        base = renders if renders is not None else Path(tmp)
        for number, path in enumerate(paths):
            if path.is_dir():
                result = evaluate_render_dir(render_dir_score(path), path)
                result.render = str(path)
            else:  # a temporary render each: two scores of one name must not share a folder
                out = base / path.stem if renders is not None else base / f"{number}-{path.stem}"
                if not (reuse and reusable(out, path, opts)):
                    render_score(path, out, opts, quiet=quiet, prog=PROG)  # its warnings name this command
                result = evaluate_render_dir(path, out)
            result.source = str(path)
            results.append(result)
    name_results(results)
    return results


def created_folders(folder: Path) -> list[Path]:
    """The folders a render into ``folder`` would create: ``folder`` and its missing parents, deepest first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing


@contextlib.contextmanager
def remove_if_empty(folders: Sequence[Path]) -> Iterator[None]:
    """On the way out (Ctrl-C or an error before any render was written, e.g. ``--renders DIR`` that held
    nothing), remove those of ``folders`` (deepest first; ones this run created) left empty. A folder holding a
    finished render is kept, for ``--reuse``."""
    try:
        yield
    finally:
        for folder in folders:
            try:
                folder.rmdir()  # only an empty folder: never a render, nor a file another program put there
            except OSError:
                break


def folder_name(path: Path) -> str:
    """A folder's name as its row shows it: its last part (of the folder it resolves to for ``.`` and ``..``)."""
    return path.name if path.name not in ("", "..") else (path.resolve().name or str(path))


def distinguishing_tails(paths: Sequence[Path]) -> list[Path]:
    """Each path's shortest end (its name, then with its parent, ...) that none of the others ends with, of the
    absolute paths (``.`` and ``..`` folded): ``a/groove.txt`` and ``b/groove.txt`` for those two, ``x/r1`` and
    ``y/r1`` for two folders ``r1``."""
    full = [Path(os.path.abspath(path)).parts for path in paths]
    tails = []
    for k, parts in enumerate(full):
        others = [other for m, other in enumerate(full) if m != k]
        n = 1
        while n < len(parts) and any(other[-n:] == parts[-n:] for other in others):
            n += 1
        tails.append(Path(*parts[-n:]))
    return tails


def _tails_where_shared(keys: Sequence[str], paths: Sequence[Path]) -> list[Path | None]:
    """For the entries whose key another entry shares, their :func:`distinguishing_tails` among those; None for
    an entry whose key is its own."""
    groups: dict[str, list[int]] = defaultdict(list)
    for k, key in enumerate(keys):
        groups[key].append(k)
    out: list[Path | None] = [None] * len(keys)
    for members in groups.values():
        if len(members) > 1:
            for k, tail in zip(members, distinguishing_tails([paths[k] for k in members]), strict=True):
                out[k] = tail
    return out


def _numbered(keys: Sequence[str], separator: str) -> list[str]:
    """``keys`` with a second and later use of a key numbered (``groove``, ``groove-2``), never into another key."""
    taken = set(keys)
    seen: set[str] = set()
    out = []
    for key in keys:
        unique, n = key, 1
        while unique in seen or (unique != key and unique in taken):
            n += 1
            unique = f"{key}{separator}{n}"
        seen.add(unique)
        taken.add(unique)
        out.append(unique)
    return out


def name_results(results: Sequence[FileResult]) -> None:
    """Name each row (``name``) and its plots (``stem``), apart from every other of the run: a score by its file
    name (plots: its stem), a render folder by its name and its score's, ``o10 (fill6.mid)`` (plots: the folder's
    name). Rows that would share a name, and plots a stem, take the shortest end of their paths (``source``) that
    tells them apart: ``a/groove.txt`` and ``b/groove.txt`` (plots ``a_groove``, ``b_groove``), ``x/r1 (groove.txt)``
    (plots ``x_r1``); a stem still shared (``groove.txt`` and ``groove.mid``) is numbered, ``groove-2``: a plot
    never replaces another of the same run."""
    paths = [Path(r.source or r.render or r.name) for r in results]

    def label(r: FileResult, where: str) -> str:  # a render folder's row names its score too
        return f"{where} ({r.name})" if r.render is not None else where

    names = [label(r, folder_name(path) if r.render is not None else path.name) for r, path in zip(results, paths,
                                                                                                     strict=True)]
    tails = _tails_where_shared(names, paths)
    names = [name if tail is None else label(r, str(tail)) for r, name, tail in zip(results, names, tails,
                                                                                     strict=True)]
    stems = [folder_name(path) if r.render is not None else path.stem for r, path in zip(results, paths, strict=True)]
    tails = _tails_where_shared(stems, paths)
    stems = [stem if tail is None else _tail_stem(tail, r.render is None)
             for r, stem, tail in zip(results, stems, tails, strict=True)]
    for r, name, stem in zip(results, _numbered(names, " #"), _numbered(stems, "-"), strict=True):
        r.name, r.stem = name, stem


def _tail_stem(tail: Path, is_score: bool) -> str:
    """A path's end as a file name stem: ``a/groove.txt`` -> ``a_groove`` (a score: without its suffix),
    ``x/r1`` -> ``x_r1``."""
    parts = [part for part in tail.parts if part != tail.anchor]
    if is_score and parts:
        parts[-1] = Path(parts[-1]).stem
    return "_".join(parts) or "plots"


def distinct_inputs(paths: Sequence[Path]) -> list[Path]:
    """``paths`` without a second mention of one score or render folder (by any spelling: ``r1`` and ``./r1/``),
    each dropped one named in a warning: evaluated twice, it counted twice in ALL (and in a fit)."""
    kept: dict[Path, Path] = {}
    for path in paths:
        try:
            key = path.resolve()
        except (OSError, RuntimeError):  # a symbolic link loop: its spelling, then
            key = Path(os.path.abspath(path))
        if key in kept:
            again = "twice" if str(kept[key]) == str(path) else f"again as {path}"
            print(f"{PROG}: warning: {kept[key]} is given {again}: evaluated once", file=sys.stderr)
            continue
        kept[key] = path
    return list(kept.values())


from batteur.render_outputs import RENDER_OUTPUTS  # noqa: E402 (render's own list; render itself is heavy)


def check_not_render_output(path: Path) -> None:
    """``ValueError`` when ``path`` is a render's output, not a score: one of :data:`RENDER_OUTPUTS` in a render
    folder, or an impact log by its header line whatever its name (read as a text score, impacts.csv gave
    ``line 1: unknown directive 'seq,time,instrument,...'``). Says to give the render folder instead."""
    from batteur.impact_log import COLUMNS

    if not path.is_file():
        return  # a folder, or a file missing: told where it is read
    in_render = (path.parent / "report.json").is_file()
    if path.name in RENDER_OUTPUTS and in_render:
        what = f"a render's {path.name}"
    else:
        try:
            with path.open("rb") as handle:
                head = handle.readline(4096)
        except OSError:
            return  # told where the score is read
        if head.strip() != ",".join(COLUMNS).encode("ascii"):
            return
        what = "a render's impact log"
    folder = f"its render folder: {PROG} {path.parent}" if in_render else "the render folder it came from"
    raise ValueError(f"{path}: {what}, not a score; give {folder}")


def reusable(render_dir: Path, score: Path, opts: Any) -> bool:
    """Whether ``render_dir`` is a render of this very score with these options (``--reuse``): a render of
    another score of the same name, or with another kit, tempo, grip, nuance, sticking or drummer, would be evaluated
    against the wrong notes or be another performance. The grip and nuance compared are those a render would
    play (the options', else the score's directives: ``RenderOptions.styled``); a render in segments is another
    performance than one in one process (:func:`same_segments`)."""
    from batteur.render import DEFAULT_MASS_KG, DEFAULT_NUANCE, file_kit, file_style
    from common.score.events import ScoreError
    from common.score.limbs import STATURE_M

    try:
        report = read_report(render_dir)
        copy = render_dir / f"score{score.suffix}"
        same_score = copy.is_file() and copy.read_bytes() == score.read_bytes()
        if not same_score:
            return False
        style = opts.with_style(*file_style(score)).with_kit(file_kit(score))
    except (ValueError, OSError, ScoreError):  # a score it cannot read: rendered, so that the error is told
        return False
    wanted = {"grip": style.grip, "nuance": (style.nuance or DEFAULT_NUANCE).value,
              "tempo_scale": opts.tempo_scale, "control": opts.control,
              "drum_channels": (None if opts.midi.get("drum_channels") is None
                                else list(opts.midi["drum_channels"])),
              "drum_map": note_map_json(opts.midi.get("note_map")),
              "calibration": str(opts.calibration) if opts.calibration else None}
    body = {"height_m": (opts.height_m, STATURE_M), "mass_kg": (opts.mass_kg, DEFAULT_MASS_KG),
            "hihat_cc4": (bool(opts.midi.get("hihat_cc4", False)), False),  # before 7 Dec: CC4 read as written
            "sticking": (opts.sticking.value, "none")}  # before 8 Dec: no --sticking
    return (all(report.get(key) == value for key, value in wanted.items())
            and all(report.get(key, before) == value for key, (value, before) in body.items())
            and same_segments(report, opts) and same_kit(report, style.kit)
            and same_kit_file(render_dir, report, style.kit))


def same_kit(report: dict[str, Any], kit: str | None) -> bool:
    """Whether ``kit`` (a name or a file, as typed) names the kit of the render of ``report``: the same file
    (``kit_file``: ``./kits/my.yaml`` and ``kits/my.yaml`` are one kit), else the same name as report.json's
    ``kit`` (a shipped kit, the default, a render made before 7 Dec)."""
    from common.kit import kit_file

    source = report.get("kit_file")
    if isinstance(source, str) and kit is not None and Path(kit).suffix:
        return str(kit_file(kit)) == source
    return bool(report.get("kit") == kit)


def same_kit_file(render_dir: Path, report: dict[str, Any], kit: str | None) -> bool:
    """Whether the kit file ``kit`` is the one the render of ``report`` played, as it was: the same file
    (``kit_file``: a relative path given from another folder is another file) and the same contents as the render's
    copy (``kit_copy``: a kit edited since is another kit). True for a shipped kit's name, and for a render made
    before 7 Dec (no copy: nothing to compare)."""
    from common.kit import kit_file

    source, copy = report.get("kit_file"), report.get("kit_copy")
    if kit is None or not Path(kit).suffix or not isinstance(source, str) or not isinstance(copy, str):
        return True
    path = kit_file(kit)
    if str(path) != source:
        return False
    try:
        return path.read_bytes() == (render_dir / Path(copy).name).read_bytes()
    except OSError:
        return False


def same_segments(report: dict[str, Any], opts: Any) -> bool:
    """Whether the render of ``report`` (its report.json) was made as ``opts`` would make it: in one process
    (``jobs`` 1), or in segments of ``opts.segment_s`` seconds (``jobs`` above 1: the same files for any number
    of processes, batteur/segments.py, but not a one-process render's). A segmented render records its segments
    in ``physics``; a report without them is a one-process render's."""
    physics = report.get("physics")
    segments = physics.get("segments") if isinstance(physics, dict) else None
    if opts.jobs <= 1:
        return segments is None
    return isinstance(segments, dict) and segments.get("segment_s") == opts.segment_s


def check_render_names(paths: Sequence[Path], renders: Path) -> None:
    """:class:`UsageError` when two scores would be rendered into the same ``renders/<stem>`` (the second would
    replace the first's render)."""
    seen: dict[str, Path] = {}
    for path in paths:
        if path.is_dir():
            continue
        if path.stem in seen and seen[path.stem].resolve() != path.resolve():
            raise UsageError(f"--renders {renders}: {seen[path.stem]} and {path} would both render into "
                             f"{renders / path.stem}; rename one")
        seen.setdefault(path.stem, path)


PROG = "batteur evaluate"
"""The command's name in its usage and error lines."""


def build_parser() -> argparse.ArgumentParser:
    from batteur.render import add_body_options, add_performance_options

    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Render scores (or read render directories) and measure the performance against the score: "
        "precision/recall/F at 10 and 25 ms, timing error, velocity Spearman, spurious and missed notes.")
    take_negative_values(parser)
    parser.add_argument("scores", nargs="+", type=Path, help="scores (.mid or text), or render directories")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument("--plots", type=Path, default=None, metavar="DIR",
                        help="write <stem>_pianoroll.png and <stem>_timing.png here (default: no plots)")
    parser.add_argument("--renders", type=Path, default=None, metavar="DIR",
                        help="keep the renders in DIR/<score stem> (default: a temporary folder, removed)")
    parser.add_argument("--reuse", action="store_true",
                        help="with --renders: reuse a render already there when it is of the same score with the "
                        "same options")
    add_performance_options(parser, kit_default=None)  # a score's kit line, as render
    add_midi_arguments(parser)
    add_body_options(parser)
    parser.add_argument("--calibration", type=Path, default=None, metavar="FILE",
                        help="calibration JSON applied to the plans (default: none)")
    parser.add_argument("--fit-calibration", type=Path, default=None, metavar="FILE",
                        help="fit a calibration (timing offsets, velocity map) from these performances; write JSON")
    parser.add_argument("--list", action="store_true",
                        help="list every impact: matched or spurious, striker part, velocity, nearest note "
                        "(with --json: each file's impact_list)")
    parser.add_argument("--jobs", type=int, default=1, metavar="N",
                        help="render each score on N processes in time segments, as `batteur render --jobs` "
                        "(0: one per CPU; default 1: in one piece)")
    parser.add_argument("--segment", type=float, default=30.0, metavar="SECONDS",
                        help="segment length with --jobs above 1, seconds (default 30)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def nearest_note(result: FileResult, hit: Hit) -> NoteRef | None:
    """The note nearest ``hit`` in time: on the same object when it has one, else on any; None without notes."""
    same = [n for n in result.note_refs if n.instrument == hit.instrument] or result.note_refs
    return min(same, key=lambda n: abs(n.time - hit.time), default=None)


def impact_rows(result: FileResult) -> list[dict[str, Any]]:
    """Every impact as ``--list`` shows it, for the JSON (``--json --list``: ``impact_list``): ``matched`` at 25 ms
    (else spurious), score time (s), object, striker part, normal velocity (m/s), the :func:`nearest_note` (its
    index in the score, event, object, time in s) and the impact's offset from it (ms)."""
    matched = {j for _, j in result.pairs_25}
    rows = []
    for j, h in enumerate(result.hits):
        near = nearest_note(result, h)
        rows.append({"matched": j in matched, "time_s": round(h.time, 6), "instrument": h.instrument,
                     "part": h.part, "velocity_m_s": round(h.velocity, 4),
                     "nearest_note": None if near is None else {
                         "index": near.index, "event": near.event, "instrument": near.instrument,
                         "time_s": round(near.time, 6), "offset_ms": round((h.time - near.time) * 1000, 3)}})
    return rows


MAX_DETAIL_LINES = 20
"""Missed notes, and spurious impacts, listed per file under the table; the rest is counted (all: ``--json``)."""


def spurious_lines(result: FileResult) -> list[str]:
    """One line per spurious impact (not matched at 25 ms), as a missed note's: score time, object, striker,
    velocity, the :func:`nearest_note` and, when on another object, the note nearest in time (``impact at 2.922 s
    on crash2 spurious: right_stick_tip 1.70 m/s, nearest note 8 CRASH on crash2 at 2.400 s (+522.0 ms); nearest
    in time: note 9 RIDE on ride at 2.950 s (-28.0 ms)``)."""
    matched = {j for _, j in result.pairs_25}
    lines = []
    for j, h in enumerate(result.hits):
        if j in matched:
            continue
        near = nearest_note(result, h)
        where = "no note" if near is None else f"nearest note {_note_words(near, h)}"
        # the note played nearest in time, on another object: what the stick was on its way to, or came from
        when = min(result.note_refs, key=lambda n: abs(n.time - h.time), default=None)
        if when is not None and near is not None and when.instrument != near.instrument:
            where += f"; nearest in time: note {_note_words(when, h)}"
        lines.append(f"impact at {h.time:.3f} s on {h.instrument} spurious: {h.part or 'striker unknown'} "
                     f"{h.velocity:.2f} m/s, {where}")
    return lines


def _note_words(note: NoteRef, hit: Hit) -> str:
    """``12 RIDE on ride at 4.400 s (+20.0 ms)``: a note and ``hit``'s offset from it."""
    return (f"{note.index} {note.event} on {note.instrument} at {note.time:.3f} s "
            f"({(hit.time - note.time) * 1000:+.1f} ms)")


def impact_listing(result: FileResult) -> list[str]:
    """One line per impact: M(atched)/S(purious), score time, object, striker, velocity, nearest note and offset."""
    matched = {j for _, j in result.pairs_25}
    lines = []
    for j, h in enumerate(result.hits):
        near = nearest_note(result, h)
        where = "" if near is None else (f"nearest {near.event} on {near.instrument} at {near.time:.3f} s "
                                         f"({(h.time - near.time) * 1000:+.1f} ms)")
        lines.append(f"  {'M' if j in matched else 'S'} {h.time:+9.3f} s {h.instrument:<10} {h.part:<18} "
                     f"{h.velocity:6.2f} m/s  {where}")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``batteur evaluate``; the exit status (batteur/errors.py)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.reuse and args.renders is None:  # it reuses renders kept in --renders DIR; without one there are none
        # one line, exit 2, as render's options that exclude each other (not argparse's usage before it)
        return report_error(PROG, "--reuse needs --renders DIR (the folder whose renders it reuses)", USAGE)
    args.scores = distinct_inputs(args.scores)
    warn_unused_options(args, parser)
    try:
        with sigterm_raises():  # SIGTERM (timeout, systemd) cleans up as Ctrl-C does
            return _main(args)
    except Terminated:  # before KeyboardInterrupt, which it is
        print(f"{PROG}: terminated (SIGTERM)", file=sys.stderr)
        return TERMINATED
    except KeyboardInterrupt:  # Ctrl-C: a render in progress is staged, so nothing of it was written
        print(f"{PROG}: interrupted", file=sys.stderr)
        return INTERRUPTED


RENDER_OPTIONS = ("kit", "grip", "nuance", "height", "mass", "tempo_scale", "control", "calibration", "jobs",
                  "segment", "drum_channels", "drum_map", "hihat_cc4", "sticking")
"""The options that change a render: a render directory given to evaluate was made with its own."""


def warn_unused_options(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """Say which render options given do not apply to the render directories among the inputs (they were
    ignored in silence); the fit's kit and base calibration apply to them."""
    folders = [str(path) for path in args.scores if path.is_dir()]
    used = ("kit", "calibration") if args.fit_calibration is not None else ()
    given = [f"--{name.replace('_', '-')}" for name in RENDER_OPTIONS
             if name not in used and getattr(args, name) != parser.get_default(name)]
    if folders and given:
        one = len(folders) == 1
        print(f"{PROG}: warning: {_and(folders)} {'is a render' if one else 'are renders'}: {_and(given)} "
              f"{'does' if len(given) == 1 else 'do'} not apply to {'it' if one else 'them'} "
              f"({'it was' if one else 'each was'} rendered with the options in its report.json)", file=sys.stderr)


def fit_kit_name(inputs: Sequence[Path], kit: str | None) -> str:
    """The kit a calibration fitted from ``inputs`` is for: ``kit`` (``--kit``: every score is rendered on it) when
    given, else the one kit they all play: a score's ``kit`` line (else the default kit, as ``batteur render``), a
    render directory's (its report.json). :class:`UsageError` when they play several: a calibration's offsets and
    velocity maps are per kit object, and one fit cannot serve kits whose objects differ."""
    from batteur.render import DEFAULT_KIT
    from common.kit import kit_file
    from common.score.text import MIDI_SUFFIXES, load_score_kit, read_score, score_kit

    if kit is not None:
        return kit
    played: dict[str, tuple[str, list[str]]] = {}  # the kit's file -> its name as written, the inputs playing it
    for path in inputs:
        if path.is_dir():
            report = read_report(path)
            name = report.get("kit_file") or report.get("kit", DEFAULT_KIT)  # the file wherever this runs from
            if not isinstance(name, str):  # said by the evaluation of that render
                continue
            copy = report.get("kit_copy")
            if isinstance(copy, str) and Path(copy).name == copy and (path / copy).is_file():
                # one kit with the file it was copied from; fitted on the copy: the kit the render played
                played.setdefault(str(kit_file(name)), (str(path / copy), []))[1].append(path.name)
                continue
        else:  # a MIDI file names no kit (and is not read here)
            score = None if path.suffix.lower() in MIDI_SUFFIXES else read_score(path)
            name = score_kit(score) or DEFAULT_KIT
            if name != DEFAULT_KIT:  # one it cannot load: a ScoreError naming the line, before the renders
                load_score_kit(score, None, path, lambda kit: load_kit(kit, warn=False))
        same = str(kit_file(name))  # a name and its file's path are one kit
        played.setdefault(same, (name, []))[1].append(path.name)
    if len(played) > 1:
        kits = "; ".join(f"{name} ({_and(paths)})" for name, paths in played.values())
        raise UsageError(f"--fit-calibration: these inputs play {len(played)} kits, {kits}; a calibration is for one "
                         "kit (its offsets and velocity maps are per kit object): fit each kit's apart, or give --kit "
                         "to render every score on one")
    return next(iter(played.values()))[0] if played else DEFAULT_KIT


def _and(words: Sequence[str]) -> str:
    """'a, b and c'."""
    return f"{', '.join(words[:-1])} and {words[-1]}" if len(words) > 1 else words[0]


def _main(args: argparse.Namespace) -> int:
    from batteur.calibration import Calibration
    from batteur.render import RenderError, RenderOptions, height_of, resolve_jobs, style_from
    from common.output_paths import check_output_dir, check_output_file
    from common.score.events import ScoreError
    from common.score.hands import Sticking

    started = time.perf_counter()
    base_calibration, fit_kit = None, None
    try:
        for path in args.scores:  # before the renders: one input read wrong must not cost them
            check_not_render_output(path)
        for option, folder in (("--plots", args.plots), ("--renders", args.renders)):
            if folder is not None:  # before the renders: a typo must not cost them
                check_output_dir(folder, option)
        if args.renders is not None:
            check_render_names(args.scores, args.renders)
        if args.fit_calibration is not None:
            check_output_file(args.fit_calibration, "--fit-calibration")
            # read now, as the base of the fit: a bad file must not cost the renders
            fit_kit = load_kit(fit_kit_name(args.scores, args.kit))
            if args.calibration is not None:
                base_calibration = Calibration.load(args.calibration)
        grip, nuance = style_from(args)
        opts = RenderOptions(kit=args.kit, grip=grip, nuance=nuance, tempo_scale=args.tempo_scale,
                             control=args.control, sticking=Sticking(args.sticking),
                             calibration=args.calibration, jobs=resolve_jobs(args.jobs),
                             segment_s=args.segment, height_m=height_of(args), mass_kg=args.mass,
                             midi=midi_read_kwargs(args))
        results = evaluate_scores(args.scores, opts, args.renders, quiet=args.quiet, reuse=args.reuse)
    except (ScoreError, RenderError, ValueError, OSError, KeyError) as exc:  # UsageError: 2, a file or a render: 1
        return report_error(PROG, exc)
    agg = aggregate(results)
    if args.json:
        # --list: every impact in each file's figures (a table's listing would not be JSON)
        files = [{**r.summary(), "impact_list": impact_rows(r)} if args.list else r.summary() for r in results]
        print(json.dumps({"files": files, "aggregate": agg,
                          "elapsed_s": round(time.perf_counter() - started, 3)}, indent=2))
    else:
        rows = [(r.name, r.summary()) for r in results] + ([("ALL", agg)] if len(results) > 1 else [])
        print(format_table(rows))
        print(table_legend())
        for r in results:
            if r.no_drum_notes:  # the figures are over the notes given to the drummer: these must not go unseen
                print(f"  {r.name}: {r.no_drum_notes} note{'s' * (r.no_drum_notes > 1)} of the file not played: no "
                      f"drum for {'their' if r.no_drum_notes > 1 else 'its'} pitch (nodrum; F, P and R count the "
                      f"{r.notes} the drummer was given)")
            for f in r.missed[:MAX_DETAIL_LINES]:
                note = f"note {f.index} {f.event}" if f.index is not None else f"a note of {f.event}"
                print(f"  {r.name}: {note} at {f.time:.3f} s missed: {f.reason} ({f.detail})")
            if len(r.missed) > MAX_DETAIL_LINES:
                print(f"  {r.name}: ... {len(r.missed) - MAX_DETAIL_LINES} more missed notes (see --json)")
            spurious = spurious_lines(r)
            for line in spurious[:MAX_DETAIL_LINES]:
                print(f"  {r.name}: {line}")
            if len(spurious) > MAX_DETAIL_LINES:
                print(f"  {r.name}: ... {len(spurious) - MAX_DETAIL_LINES} more spurious impacts (see --json, "
                      "--list)")
            if args.list:
                print(f"{r.name}: impacts")
                print("\n".join(impact_listing(r)))
    if args.plots is not None:
        try:  # after the figures are shown (a failed write must not lose them): a full disk, a folder made
            # read-only since the check, is one line, not a traceback
            for r in results:
                for p in plot_result(r, args.plots):
                    print(f"wrote {p}", file=sys.stderr)
        except OSError as exc:
            return report_error(PROG, f"--plots {args.plots}: cannot write {exc.filename or 'a plot'} "
                                      f"({exc.strerror or exc})")
    if args.fit_calibration is not None and fit_kit is not None:
        from batteur.calibration import fit_calibration

        cal = fit_calibration(results, fit_kit, base=base_calibration)
        try:
            cal.save(args.fit_calibration)
        except OSError as exc:  # e.g. a full disk
            return report_error(PROG, f"--fit-calibration {args.fit_calibration}: cannot write it "
                                      f"({exc.strerror or exc})")
        objects = sum("/" not in key for key in cal.timing)  # an object's offset, and its events' own
        print(f"wrote {args.fit_calibration} (timing offsets for {objects} kit objects and "
              f"{len(cal.timing) - objects} of their sounds, velocity maps for {len(cal.velocity)})", file=sys.stderr)
    return 0
