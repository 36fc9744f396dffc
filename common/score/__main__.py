"""Inspect a score: ``python -m common.score FILE [--kit NAME] [--algorithm viterbi] [--sticking none] [--plan]``.

Prints the events per type, the kit (``--kit``, else a text score's ``kit``
line, as ``batteur render`` plays it, else the default), unknown notes, removed
doubles, the limb assignment and every feasibility issue (and, with ``--plan``,
the gesture plan's size and planning time).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from collections.abc import Sequence

from common.exit_status import FAILED, report_error
from common.gesture.plan import FeasibilityIssue
from common.output_paths import point_at_devnull
from common.score.events import MAX_SCORE_BARS, Score, ScoreError
from common.score.hands import HandAlgorithm, Sticking
from common.score.limbs import distribute
from common.score.midi_options import add_midi_arguments, midi_read_kwargs
from common.score.position import counted_bar_beat
from common.score.summary import beat_seconds, last_bar_end, meter_line, score_length, tempo_line
from common.score.text import DEFAULT_KIT, load_score_kit, read_score, score_kit

PROG = "python -m common.score"
"""The command's name in its usage and error lines."""


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless the count is 1 ("1 event", "3 events")."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def length(score: Score) -> str:
    """How long ``score`` is, as a musician counts it: beats (quarter notes, to a hundredth: 3.5 for a bar of 7/8)
    and bars up to its end (:attr:`Score.end_beat`), "4 beats, 1 bar" for a bar of 4/4. Not the number of
    ``score.beats``: that holds the beat at the end as well (a one-note bar of 1/4 was "2 beats")."""
    known = score_length(score)
    if known is None:  # a reader that does not know its end: the beats before the last
        return counted(max(len(score.beats) - 1, 0), "beat")
    end, bars = known
    beats = f"{end:.2f}".rstrip("0").rstrip(".")  # not :g, whose 6 digits drop the hundredths past 10,000 beats
    at_least = "at least " if len(score.bar_beats) >= MAX_SCORE_BARS else ""  # the readers stop counting there
    return f"{beats} beat{'' if end == 1 else 's'}, {at_least}{counted(bars, 'bar')}"


def bar_end_words(score: Score) -> str:
    """``; 2.000 s to the end of the last bar`` (:func:`common.score.summary.last_bar_end`: a MIDI file's end of
    track inside a bar counts to that bar's end), "" when the score's end or tempo is not known."""
    end = last_bar_end(score)
    seconds = None if end is None else beat_seconds(score, end)
    return "" if seconds is None else f"; {seconds:.3f} s to the end of the last bar"


MAX_LISTED_BARS = 8
"""The most bars a line of repeated issues lists one by one (more: the first ones, the last and their count)."""


def bars_words(bars: Sequence[int]) -> str:
    """Bars as a musician lists them: ``bar 8``, ``bars 3 to 6``, ``every 8 bars from bar 8 to bar 296``, ``bars 2,
    5, 11``; more than :data:`MAX_LISTED_BARS` irregular ones: ``bars 2, 5, ..., 290 (37 bars)``."""
    bars = sorted(set(bars))
    if len(bars) == 1:
        return f"bar {bars[0]}"
    steps = {b - a for a, b in zip(bars, bars[1:], strict=False)}
    if len(bars) >= 3 and len(steps) == 1:
        step = steps.pop()
        if step == 1:
            return f"bars {bars[0]} to {bars[-1]}"
        return f"every {step} bars from bar {bars[0]} to bar {bars[-1]}"
    if len(bars) <= MAX_LISTED_BARS:
        return "bars " + ", ".join(str(b) for b in bars)
    return "bars " + ", ".join(str(b) for b in bars[:MAX_LISTED_BARS - 1]) + f", ..., {bars[-1]} ({len(bars)} bars)"


def issue_lines(score: Score, issues: Sequence[FeasibilityIssue]) -> list[str]:
    """One line per feasibility issue, ``note 3 at 0.580 s SNARE: too_fast -> merged (...)``; issues alike (reason,
    action, event and detail) on several notes are one line with their count and bars (:func:`bars_words`), in the
    order of the first: ``37 notes HIHATCLOSED, every 8 bars from bar 8 to bar 296 (the first: note 98 at 15.500 s):
    too_many_hands -> substituted_pedal (...)`` (until 8 Dec a 10-minute file printed 37 identical lines)."""
    groups: dict[tuple[str, str, str, str], list[FeasibilityIssue]] = {}
    for issue in issues:
        event = issue.event.value if issue.event else "-"
        groups.setdefault((issue.reason.value, issue.action.value, event, issue.detail), []).append(issue)
    lines = []
    for (reason, action, event, detail), alike in groups.items():
        first = alike[0]
        what = f"{reason} -> {action} ({detail})"
        if len(alike) == 1:
            lines.append(f"  note {first.note_index} at {first.time:.3f} s {event}: {what}")
            continue
        where = [counted_bar_beat(score, i.time) for i in alike]
        bars = f", {bars_words([w[0] for w in where if w is not None])}" if all(where) else ""
        lines.append(f"  {len(alike)} notes {event}{bars} (the first: note {first.note_index} at {first.time:.3f} s): "
                     f"{what}")
    return lines


def main(argv: list[str] | None = None) -> int:
    """Print what the command line asks for; the exit status (README, "Exit status": 2 a bad option, 1 a score
    or kit it cannot use). A reader that goes away (``| head -1``) is a quiet stop, exit 0, as for the batteur
    tools (``batteur.tools.nodes.run_tool``), not a BrokenPipeError traceback."""
    try:
        status = _inspect(argv)
        sys.stdout.flush()  # here, not at exit: a reader gone by the last flush is a quiet stop too
        return status
    except BrokenPipeError:
        point_at_devnull(sys.stdout)  # the interpreter's own flush at exit stays quiet
        return 0


def _inspect(argv: list[str] | None) -> int:
    """:func:`main`'s work."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__)
    parser.add_argument("score", help="a .mid file or a Batteur text score")
    parser.add_argument("--kit", default=None, help="kit name or YAML/JSON path (default: a text score's `kit` "
                        f"line, as batteur render plays it, else {DEFAULT_KIT})")
    parser.add_argument("--algorithm", default="viterbi", choices=[a.value for a in HandAlgorithm])
    parser.add_argument("--sticking", default="none", choices=[s.value for s in Sticking])
    parser.add_argument("--plan", action="store_true", help="also plan the gestures")
    add_midi_arguments(parser)
    args = parser.parse_args(argv)
    try:
        given = load_score_kit(None, args.kit) if args.kit else None  # a text score's object ids are its objects
        score = read_score(args.score, kit=given, **midi_read_kwargs(args))
        kit = given or load_score_kit(score, None)  # a kit line's kit it cannot load: an error naming the line
    except (ScoreError, FileNotFoundError, ValueError) as exc:  # a score or kit it cannot use
        return report_error(PROG, exc, FAILED)
    last = f" (the last at {score.duration:.2f} s)" if score.events else ""  # none: "(the last at 0.00 s)"
    print(f"{score.source}: {counted(len(score.events), 'event')}{last}, {length(score)}{bar_end_words(score)}")
    for line in (tempo_line(score), meter_line(score)):
        if line is not None:
            print(line)
    asked = score_kit(score)
    print(f"kit: {args.kit or asked or DEFAULT_KIT}" + (" (the score's kit line)" if args.kit is None and asked
                                                         else ""))
    for event, count in sorted(Counter(e.event.value for e in score.events).items()):
        print(f"  {event:<12} {count}")
    for warning in score.warnings:
        print(f"warning: {warning}")
    if score.duplicates:
        print(f"double events removed: {len(score.duplicates)}")
    assignment = distribute(score, kit, args.algorithm, args.sticking)
    limbs = Counter(n.limb.value for n in assignment.notes)
    print("limbs: " + (", ".join(f"{k} {v}" for k, v in sorted(limbs.items())) or "none"))  # none: no note
    bounces = sum(n.rebound for n in assignment.notes)
    if bounces:
        print(f"rebound doubles (second note a bounce, below minTimeGap): {bounces}")
    for line in issue_lines(score, assignment.issues):
        print(line)
    if args.plan:
        from common.gesture.planner import plan_gestures

        t0 = time.perf_counter()
        plan = plan_gestures(assignment, kit, score)
        elapsed = time.perf_counter() - t0
        knots = sum(len(t.times) for t in plan.trajectories.values())
        print(
            f"plan: {counted(len(plan.strokes), 'stroke')}, {counted(knots, 'knot')}, "
            f"{plan.start_time:.2f}..{plan.end_time:.2f} s, "
            f"planned in {elapsed:.3f} s"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
