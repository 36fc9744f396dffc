"""Planning benchmark on the Groove MIDI Dataset (CC BY 4.0, Gillick et al. 2019).

For each hand-assignment algorithm (simple, pairwise, viterbi), over a subset of
../shared/data/groove (``--all`` for every file), limb distribution + hand
assignment + gesture plan, then counted **on the gesture plan** (what physics
will play), stick strokes only:

* ``preferred``: share of stick strokes on their event's preferred hand;
* ``cross/min``: arm crossings per minute (a stick stroke played while the other
  hand's last stroke, within 0.25 s, makes a crossed pair: the kit's pair
  preference violated, or the left stick more than 10 cm right of the right one);
* ``<full``: same-hand intervals below the event's minTimeGap (the full-stroke
  minimum), whatever they are;
* ``bounce``: of those, the ones that are honest rebound doubles: the plan
  plays the second stroke as a bounce (``PlannedStroke.rebound_double``) AND the
  pair meets the rebound-double rules of ``common.score.rebound.classify``,
  re-checked here from the planned strokes (same object within 5 cm, the first a
  full stroke, the second not louder by more than the kit's margin, interval at
  least the rebound minimum);
* ``illegal``: ``<full`` minus ``bounce``: intervals below the minimum that are
  not a planned rebound double (goal for viterbi: 0);
* ``<rebound``: of those, intervals even below the rebound minimum;
* ``flagged``: notes with any feasibility issue; ``left out``: notes not played
  (dropped or merged into a nearby stroke on the same drum) by the limb rules
  (hi-hat conflicts, feet), the hand assignment or the feasibility check;
  ``too fast``: of those, stick notes left out because no hand can play them in
  time; printed below for viterbi next to the fewest any hand choice must leave
  out so that no interval is illegal (the shortest-path search with the
  leave-out cost only, beam 64, on the same stick notes);
* ``plan s/min``: planning time per minute of music (goal: under 1 s).

Goal for the shortest-path search: no same-hand interval below the minimum
(``illegal`` = 0) and the fewest crossings. Figures only, no asserts.

Usage: python bench/planning_bench.py [--all] [--limit N] [--kit default] [--groove DIR]
(the default 40 files: about 35 s; --all: about 1,000 files, a quarter of an hour)
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from common.arg_types import count  # noqa: E402
from common.gesture.database import default_database  # noqa: E402
from common.gesture.plan import GesturePlan, IssueAction, IssueReason  # noqa: E402
from common.gesture.planner import plan_gestures  # noqa: E402
from common.kit import Kit, Limb, load_kit  # noqa: E402
from common.score.events import Score, ScoreError  # noqa: E402
from common.score.hands import Costs, HandNote, assign_hands, crossed  # noqa: E402
from common.score.limbs import HANDS, Assignment, distribute  # noqa: E402
from common.score.midi import read_midi  # noqa: E402
from common.score.rebound import Interval, Stroke, classify, rebound_gap  # noqa: E402

ALGORITHMS = ("simple", "pairwise", "viterbi")
GROOVE = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "groove"
LEFT_OUT = (IssueAction.DROPPED, IssueAction.MERGED)


def metrics(plan: GesturePlan, a: Assignment, score: Score, kit: Kit) -> Counter[str]:
    """Counts over one plan (stick strokes) and its assignment's issues."""
    c: Counter[str] = Counter()
    last: dict[Limb, tuple[Stroke, bool, float]] = {}  # hand -> (stroke, was a bounce, x of the hit point)
    for s in plan.strokes:
        if s.limb not in HANDS:
            continue
        c["stick_notes"] += 1
        spec = kit.spec(s.event)
        preferred = spec.preferred if spec.preferred in HANDS else Limb.RIGHT_HAND
        c["on_preferred"] += s.limb == preferred
        x = float(s.hit_point[0])
        cur = Stroke(s.time, s.event, score.events[s.note_index].pitch, s.note_velocity)
        prev = last.get(s.limb)
        bounce = False
        if prev is not None:
            kind = classify(kit, prev[0], prev[1], cur)
            if s.time - prev[0].time < spec.min_time_gap - 1e-9:
                c["below_full"] += 1
                if kind == Interval.REBOUND and s.rebound_double:
                    c["bounce"] += 1
                    bounce = True
                else:
                    c["illegal"] += 1
                    c["below_rebound"] += s.time - prev[0].time < rebound_gap(kit, s.event, s.note_velocity) - 1e-9
        other = last.get(Limb.LEFT_HAND if s.limb == Limb.RIGHT_HAND else Limb.RIGHT_HAND)
        if other is not None and s.time - other[0].time <= 0.25:
            if s.limb == Limb.LEFT_HAND:
                c["crossings"] += crossed(kit, s.event, other[0].event, x, other[2])
            else:
                c["crossings"] += crossed(kit, other[0].event, s.event, other[2], x)
        last[s.limb] = (cur, bounce, x)
    c["flagged"] = len({i.note_index for i in a.issues})
    c["left_out"] = len({i.note_index for i in a.issues if i.action in LEFT_OUT})
    c["hands_left_out"] = len({
        i.note_index for i in a.issues
        if i.action in LEFT_OUT and i.reason == IssueReason.TOO_FAST and i.event is not None
        and kit.spec(i.event).pedal is None
    })
    return c


def fewest_left_out(score: Score, a: Assignment, kit: Kit) -> int:
    """Fewest stick notes any hand choice must leave out: the viterbi assignment's stick notes (kept and left out
    by the hand assignment) searched again with the leave-out cost only."""
    notes = [(n.time, n.event, n.pitch, n.velocity) for n in a.notes if n.limb in HANDS]
    for i in a.issues:
        e = score.events[i.note_index]
        if (i.reason == IssueReason.TOO_FAST and i.action in LEFT_OUT and i.event is not None
                and kit.spec(i.event).pedal is None):
            notes.append((e.time, i.event, e.pitch, e.velocity))
    notes.sort(key=lambda n: (n[0], n[1].value))
    hand_notes = [HandNote(k, t, ev, p, None, v) for k, (t, ev, p, v) in enumerate(notes)]
    only_drops = Costs(drop=1.0, drop_velocity=0.0, rebound=0.0, fast=0.0, crossing=0.0, travel=0.0,
                       not_preferred=0.0, beam=64)
    return sum(h is None for h in assign_hands(hand_notes, kit, "viterbi", costs=only_drops))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--all", action="store_true", help="every file (slow: about 1,000 files)")
    parser.add_argument("--limit", type=count, default=40,
                        help="files in the default subset (every k-th file; default 40)")
    parser.add_argument("--kit", default="default", help="kit name or kit file (default: default)")
    parser.add_argument("--groove", type=Path, default=GROOVE,
                        help=f"folder searched for .mid files (default {GROOVE})")
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        kit = load_kit(args.kit)
    except (OSError, ValueError) as exc:
        parser.error(f"--kit {args.kit}: {exc}")
    files = sorted(args.groove.rglob("*.mid"))
    if not files:
        parser.error(f"--groove {args.groove}: no MIDI files under it")
    if not args.all:
        step = max(1, len(files) // args.limit)
        files = files[::step][: args.limit]
    default_database()  # load the gesture units once, outside the timings
    totals: dict[str, Counter[str]] = {alg: Counter() for alg in ALGORITHMS}
    seconds = {alg: 0.0 for alg in ALGORITHMS}
    music_minutes = 0.0
    fewest = 0
    errors = 0
    unknown: Counter[int] = Counter()
    for done, path in enumerate(files, 1):
        print(f"\r  planning {done}/{len(files)}", end="", file=sys.stderr, flush=True)
        try:
            score = read_midi(path)
        except ScoreError as exc:
            errors += 1
            print(f"skip: {exc}")
            continue
        if not score.events:
            continue
        unknown.update(n.pitch for n in score.unknown)
        music_minutes += max(score.duration, 1.0) / 60.0
        for alg in ALGORITHMS:
            t0 = time.perf_counter()
            a = distribute(score, kit, alg)
            plan = plan_gestures(a, kit, score)
            seconds[alg] += time.perf_counter() - t0
            totals[alg] += metrics(plan, a, score, kit)
            if alg == "viterbi":
                fewest += fewest_left_out(score, a, kit)
    print(file=sys.stderr)
    print(f"Groove MIDI Dataset (CC BY 4.0): {len(files)} files, {music_minutes:.1f} min of music, kit {kit.name!r}")
    if errors:
        print(f"unreadable files: {errors}")
    if unknown:
        print(f"unknown drum pitches: {dict(unknown)}")
    header = (
        f"{'algorithm':<10} {'preferred':>9} {'cross/min':>9} {'<full':>6} {'bounce':>6} {'illegal':>7} "
        f"{'<rebound':>8} {'flagged':>7} {'left out':>8} {'too fast':>8} {'plan s/min':>10}"
    )
    print(header)
    for alg in ALGORITHMS:
        c = totals[alg]
        n = max(c["stick_notes"], 1)
        print(
            f"{alg:<10} {c['on_preferred'] / n:>9.1%} {c['crossings'] / music_minutes:>9.2f} {c['below_full']:>6d} "
            f"{c['bounce']:>6d} {c['illegal']:>7d} {c['below_rebound']:>8d} {c['flagged']:>7d} {c['left_out']:>8d} "
            f"{c['hands_left_out']:>8d} "
            f"{seconds[alg] / music_minutes:>10.3f}"
        )
    v = totals["viterbi"]
    print(f"stick strokes planned (viterbi): {v['stick_notes']}; stick notes no hand can play in time: viterbi leaves "
          f"out {v['hands_left_out']}, the fewest any hand choice can is {fewest}")
    best = min(ALGORITHMS, key=lambda alg: totals[alg]["crossings"])
    print(f"goal illegal = 0 for viterbi: {'met' if v['illegal'] == 0 else 'NOT met'}; fewest crossings: {best}; "
          f"plan s/min < 1: {'met' if seconds['viterbi'] / music_minutes < 1 else 'NOT met'}")

if __name__ == "__main__":
    main()
