"""Planning benchmark on the Groove MIDI Dataset (CC BY 4.0, Gillick et al. 2019).

For each hand-assignment algorithm (simple, pairwise, viterbi), over a subset of
../shared/data/groove (``--all`` for every file), prints:

* share of stick notes on their preferred hand,
* arm crossings per minute (a stick note played while the other hand's last note,
  within 0.25 s, makes a crossed pair: the kit's pair preference violated, or
  the left stick more than 10 cm right of the right stick),
* same-hand intervals below the event's minTimeGap (count, and per minute), next
  to the fewest any hand choice reaches for the same notes ("fewest": the
  shortest-path search with the speed cost only; drags and ruffs in the data
  are faster than two hands can alternate),
* notes flagged infeasible (any feasibility issue, and the dropped ones),
* planning time per minute of music (limb distribution + hand assignment +
  gesture plan; goal: under 1 s).

Goal for the shortest-path search: no same-hand interval below the minimum
and the fewest crossings. Figures only, no asserts.

Usage: python bench/planning_bench.py [--all] [--limit N] [--kit default] [--groove DIR]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from common.gesture.database import default_database  # noqa: E402
from common.gesture.plan import IssueAction  # noqa: E402
from common.gesture.planner import plan_gestures  # noqa: E402
from common.kit import Kit, Limb, load_kit  # noqa: E402
from common.score.events import ScoreError  # noqa: E402
from common.score.hands import Costs, HandNote, assign_hands, crossed  # noqa: E402
from common.score.limbs import HANDS, Assignment, distribute  # noqa: E402
from common.score.midi import read_midi  # noqa: E402

ALGORITHMS = ("simple", "pairwise", "viterbi")
GROOVE = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "groove"


def metrics(a: Assignment, kit: Kit) -> Counter[str]:
    c: Counter[str] = Counter()
    sticks = [n for n in a.notes if n.limb in HANDS]
    last: dict[Limb, tuple[float, object, float]] = {}
    for n in a.notes:
        if n.limb not in HANDS:
            continue
        c["stick_notes"] += 1
        spec = kit.spec(n.event)
        preferred = spec.preferred if spec.preferred in HANDS else Limb.RIGHT_HAND
        c["on_preferred"] += n.limb == preferred
        x = kit.hit_point(n.event, n.pitch)[0][0]
        prev = last.get(n.limb)
        if prev is not None and n.time - prev[0] < spec.min_time_gap - 1e-9:
            c["below_min"] += 1
        other = last.get(Limb.LEFT_HAND if n.limb == Limb.RIGHT_HAND else Limb.RIGHT_HAND)
        if other is not None and n.time - other[0] <= 0.25:
            if n.limb == Limb.LEFT_HAND:
                cross = crossed(kit, n.event, other[1], x, other[2])  # type: ignore[arg-type]
            else:
                cross = crossed(kit, other[1], n.event, other[2], x)  # type: ignore[arg-type]
            c["crossings"] += cross
        last[n.limb] = (n.time, n.event, x)
    # reference: the fewest intervals below the minimum any hand choice reaches for these notes
    # (the shortest-path search with the speed cost only and a wide beam)
    stick_notes = [HandNote(k, n.time, n.event, n.pitch) for k, n in enumerate(sticks)]
    speed_only = Costs(too_fast=1.0, fast=0.0, crossing=0.0, travel=0.0, not_preferred=0.0, beam=64)
    hands = assign_hands(stick_notes, kit, "viterbi", costs=speed_only)
    last_t: dict[Limb, tuple[float, float]] = {}
    for n, h in zip(sticks, hands, strict=True):
        prev_t = last_t.get(h)
        if prev_t is not None and n.time - prev_t[0] < kit.spec(n.event).min_time_gap - 1e-9:
            c["unavoidable"] += 1
        last_t[h] = (n.time, 0.0)
    c["flagged"] = len({i.note_index for i in a.issues})
    c["dropped"] = len({i.note_index for i in a.issues if i.action == IssueAction.DROPPED})
    return c


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--all", action="store_true", help="every file (slow: about 1,000 files)")
    parser.add_argument("--limit", type=int, default=40, help="files in the default subset (every k-th file)")
    parser.add_argument("--kit", default="default")
    parser.add_argument("--groove", type=Path, default=GROOVE)
    parser.add_argument("--no-plan", action="store_true", help="time the limb assignment only")
    args = parser.parse_args()
    files = sorted(args.groove.rglob("*.mid"))
    if not files:
        sys.exit(f"no MIDI files under {args.groove}")
    if not args.all:
        step = max(1, len(files) // args.limit)
        files = files[::step][: args.limit]
    kit = load_kit(args.kit)
    default_database()  # load the gesture units once, outside the timings
    totals: dict[str, Counter[str]] = {alg: Counter() for alg in ALGORITHMS}
    seconds = {alg: 0.0 for alg in ALGORITHMS}
    music_minutes = 0.0
    errors = 0
    unknown: Counter[int] = Counter()
    for path in files:
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
            if not args.no_plan:
                plan_gestures(a, kit, score)
            seconds[alg] += time.perf_counter() - t0
            totals[alg] += metrics(a, kit)
    print(f"Groove MIDI Dataset (CC BY 4.0): {len(files)} files, {music_minutes:.1f} min of music, kit {kit.name!r}")
    if errors:
        print(f"unreadable files: {errors}")
    if unknown:
        print(f"unknown drum pitches: {dict(unknown)}")
    header = (
        f"{'algorithm':<10} {'preferred':>9} {'cross/min':>9} {'<minGap':>8} {'fewest':>8} {'<min/min':>8} "
        f"{'flagged':>8} {'dropped':>8} {'plan s/min':>10}"
    )
    print(header)
    for alg in ALGORITHMS:
        c = totals[alg]
        n = max(c["stick_notes"], 1)
        print(
            f"{alg:<10} {c['on_preferred'] / n:>9.1%} {c['crossings'] / music_minutes:>9.2f} {c['below_min']:>8d} "
            f"{c['unavoidable']:>8d} "
            f"{c['below_min'] / music_minutes:>8.2f} {c['flagged']:>8d} {c['dropped']:>8d} "
            f"{seconds[alg] / music_minutes:>10.3f}"
        )
    print(f"stick notes per algorithm: {totals[ALGORITHMS[0]]['stick_notes']}; goal: plan s/min < 1")


if __name__ == "__main__":
    main()
