"""Hand assignment: which hand plays each stick event.

Three algorithms (Kragtwijk, Nijholt and Zwiers 2001, section on limb
assignment; the third one proposed there and built here):

* ``simple``: the event type's preferred hand; when that hand played less than
  the event's minTimeGap ago, the other hand (alternation). The other hand also
  takes a note beyond the preferred hand's reach that it reaches
  (``HandNote.out_of_reach``) when it is free then (:func:`_single_hand`).
* ``pairwise``: a vote of the preferred hand against the pair-wise hand
  preferences with the neighbouring events, each weighted ``rho ** dt``
  (dt in seconds), then the minTimeGap alternation and reach as ``simple``.
* ``viterbi``: a shortest-path search over the whole piece. The state is the
  last event of each hand (and whether it was the bounce of a rebound double);
  a hand never plays an interval below the event's minTimeGap unless it is a
  rebound double (:mod:`common.score.rebound`): that is a hard constraint, and a
  note no hand can play is left out (``None``) at a high cost, so as few notes
  as possible. The cost of playing an event with a hand adds a rebound double,
  the speed of full strokes, a full stroke at most ``RUN_INTERVAL_S`` after the
  hand's last (so a free other hand takes every other note of a roll, a tuplet
  or a drag: ``Costs.run``), crossing the arms (pair preference violated, or the
  left stick right of the right stick when the kit says nothing), travel speed
  between hit points, leaving the preferred hand, and a hand beyond whose reach
  the note is when the other hand reaches it (``HandNote.out_of_reach``). A beam
  keeps the best states at each step.

Groups of two simultaneous stick events always use both hands; which one goes
where follows the pair preference (or the geometry), except that ``simple`` and
``pairwise`` swap the two when a hand would get a note beyond its reach that the
other hand reaches (``HandNote.out_of_reach``) and the swap leaves neither note
beyond its hand's reach.

Sticking patterns (``single`` RLRL, ``double`` RRLL, ``paradiddle`` RLRR LRLL)
apply to rolls: runs of four or more single stick events on one object faster
than twice its minTimeGap. The lead hand is the event's preferred hand. A roll
note beyond its pattern hand's reach goes to the other hand when that one
reaches it and is free then (:func:`_roll_hands`).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from common.kit import EventType, Kit, Limb
from common.score.rebound import Interval, Stroke, classify

PROGRESS_EVERY = 256
"""Notes between two calls of a progress callback (here, in the limb assignment and in the gesture planner):
under a tenth of a second of work on a long score, and a call per note would cost more than it tells."""

RUN_INTERVAL_S = 0.1
"""One hand's full strokes this close (seconds) or closer are faster than a drummer keeps up single-handed: 10 Hz is
the fastest one-hand stick tapping measured, the world's fastest drummer's, against 5-7 Hz for others (Fujii, Kudo,
Ohtsuki and Oda 2009; docs/gestures.md). The kit's minTimeGaps (70-90 ms on drums, hi-hat, ride) stand for an
isolated pair of strokes, not a run: rolls, 16th-note triplets at 100 bpm (100 ms) and drags of 32nd notes were
played one-handed between them. A free other hand takes such notes on a drum (``Costs.run``: not one keeping time on
the hi-hat or ride); time kept on a cymbal stays with one hand at any speed."""

L, R = Limb.LEFT_HAND, Limb.RIGHT_HAND
HANDS = (L, R)


class HandAlgorithm(enum.StrEnum):
    SIMPLE = "simple"
    PAIRWISE = "pairwise"
    VITERBI = "viterbi"


class Sticking(enum.StrEnum):
    NONE = "none"
    SINGLE = "single"
    DOUBLE = "double"
    PARADIDDLE = "paradiddle"


PATTERNS: dict[Sticking, str] = {Sticking.SINGLE: "RL", Sticking.DOUBLE: "RRLL", Sticking.PARADIDDLE: "RLRRLRLL"}
"""Sticking patterns, R = lead hand."""


@dataclass(frozen=True)
class HandNote:
    """A stick event to assign: score index, time (s), type, pitch, forced hand (or None), velocity in [0, 1]."""

    index: int
    time: float
    event: EventType
    pitch: int | None = None
    forced: Limb | None = None
    velocity: float = 0.7
    out_of_reach: Limb | None = None
    """The hand whose reach the hit point is beyond while the other hand reaches it (None: both or neither reach
    it): ``viterbi`` gives it to that hand only at a cost (``Costs.out_of_reach``), ``simple`` and ``pairwise``
    split a simultaneous pair by it (:func:`_within_reach`) and give a single note to the other hand when it is
    free (:func:`_single_hand`), a roll's sticking gives way (:func:`_roll_hands`)."""


@dataclass(frozen=True)
class Costs:
    """Weights of the shortest-path search (dimensionless cost units)."""

    drop: float = 1000.0  # per note left out (times 1 + drop_velocity x velocity): only when no hand can play it
    drop_velocity: float = 1.0  # louder notes cost more to leave out
    rebound: float = 2.0  # per rebound double (a second note bounced below minTimeGap)
    fast: float = 0.3  # soft, full strokes: (minTimeGap / interval)^2
    # a full stroke on a drum at most run_interval (s) after the same hand's last while the other hand is free: above
    # not_preferred and a hand's move from a nearby drum, so the other hand takes every other note of a fast run
    # (RLRL) rather than one hand playing it all (the speed cost alone, at most 0.3, never outweighed not_preferred).
    # Free: it did not play in the run's last interval (none once both hands play: a faster roll's alternation or
    # doubles are judged as before), and its last note was on this note's object or run_idle (s) ago or more (a
    # hand keeping time on the hi-hat or ride, or playing its own part elsewhere, keeps it)
    run: float = 1.5
    run_interval: float = RUN_INTERVAL_S
    run_idle: float = 0.4
    crossing: float = 4.0  # per crossing, times |pair| (>= 0.5), decaying with the other hand's idle time
    crossing_decay: float = 0.4  # seconds
    travel: float = 0.12  # per m/s of hit-point travel speed
    not_preferred: float = 1.0
    # a hand beyond whose reach the note is, when the other reaches it: far above the rest, so the other hand plays
    # it whenever it can in time; below a drop, so a note only that hand is free for still goes to it and the
    # feasibility check flags it unreachable (not "too fast", which it is not)
    out_of_reach: float = 100.0
    beam: int = 16


@dataclass
class _Table:
    """Per-note arrays used by the algorithms."""

    time: np.ndarray
    x: np.ndarray
    pos: np.ndarray
    gap: np.ndarray
    preferred: list[Limb]
    events: list[EventType]


def _table(notes: list[HandNote], kit: Kit) -> _Table:
    cache: dict[tuple[EventType, int | None], tuple[float, float, float]] = {}
    for n in notes:
        if (n.event, n.pitch) not in cache:
            cache[(n.event, n.pitch)] = kit.hit_point(n.event, n.pitch)[0]
    pos = np.array([cache[(n.event, n.pitch)] for n in notes]).reshape(-1, 3)
    return _Table(
        time=np.array([n.time for n in notes]),
        x=pos[:, 0] if len(notes) else np.zeros(0),
        pos=pos,
        gap=np.array([kit.events[n.event].min_time_gap for n in notes]),
        preferred=[_hand(kit.spec(n.event).preferred, kit) for n in notes],
        events=[n.event for n in notes],
    )


def _hand(limb: Limb, kit: Kit) -> Limb:
    """A preferred limb as a hand (a foot-preferred event played by hand goes to the dominant hand)."""
    if limb in HANDS:
        return limb
    return R if kit.handedness == "right" else L


def _other(h: Limb) -> Limb:
    return L if h == R else R


def crossed(kit: Kit, left: EventType, right: EventType, x_left: float, x_right: float,
            left_pitch: int | None = None, right_pitch: int | None = None) -> bool:
    """True when the left stick on ``left`` and the right stick on ``right`` cross the arms.

    Uses the kit's pair preference pair(left, right) > 0 (``left`` wants the right
    hand); without one, the geometry: the left hit point (``x_left``, metres) more
    than 10 cm right of the right hit point on another object. The preference is
    between event types on their own objects: a note whose pitch strikes another
    one (``note_objects``: the double-pedal kit's second ride, out to the left) is
    judged by the geometry.
    """
    left_object, right_object = _struck_object(kit, left, left_pitch), _struck_object(kit, right, right_pitch)
    if left_object == kit.events[left].object and right_object == kit.events[right].object:
        p = kit.pair(left, right)
        if p != 0.0:
            return p > 0
    if left_object == right_object:
        return False
    return x_left - x_right > 0.10


def _struck_object(kit: Kit, event: EventType, pitch: int | None) -> str:
    """Id of the object ``event`` of ``pitch`` strikes (:meth:`Kit.object_for`'s, without looking the object up)."""
    if pitch is not None and pitch in kit.note_objects:
        return kit.note_objects[pitch]
    return kit.events[event].object


def _pair_split(a: int, b: int, t: _Table, kit: Kit, notes: list[HandNote]) -> tuple[Limb, Limb]:
    """Hands for two simultaneous notes a, b (forced hands first, then reach, then pair preference, then
    geometry)."""
    fa, fb = notes[a].forced, notes[b].forced
    if fa is not None and fb != fa:
        return fa, _other(fa)
    if fb is not None and fa is None:
        return _other(fb), fb
    return _within_reach(a, b, *_preferred_split(a, b, t, kit, notes), notes)


def _preferred_split(a: int, b: int, t: _Table, kit: Kit, notes: list[HandNote]) -> tuple[Limb, Limb]:
    """Hands for two simultaneous notes a, b by pair preference, then preferred hands, then geometry."""
    own = all(_struck_object(kit, notes[i].event, notes[i].pitch) == kit.events[notes[i].event].object
              for i in (a, b))
    p = kit.pair(t.events[a], t.events[b]) if own else 0.0  # as crossed(): another object, the geometry
    if p > 0:
        return R, L
    if p < 0:
        return L, R
    if t.preferred[a] != t.preferred[b]:
        return t.preferred[a], t.preferred[b]
    return (R, L) if t.x[a] >= t.x[b] else (L, R)


def _within_reach(a: int, b: int, ha: Limb, hb: Limb, notes: list[HandNote]) -> tuple[Limb, Limb]:
    """The split ``ha``, ``hb`` of notes a, b, swapped when a hand is given a note beyond its reach that the other
    hand reaches (``HandNote.out_of_reach``) and the swap puts neither note beyond its hand's reach: the hand that
    reaches plays it rather than the feasibility check dropping it (the other hand busy with the pair's other
    note). Where both hands reach both notes, the split is kept."""
    far_a, far_b = notes[a].out_of_reach, notes[b].out_of_reach
    if (far_a == ha or far_b == hb) and far_a != hb and far_b != ha:
        return hb, ha
    return ha, hb


def _groups(notes: list[HandNote], window: float) -> list[list[int]]:
    groups: list[list[int]] = []
    for i, n in enumerate(notes):
        if groups and n.time - notes[groups[-1][0]].time <= window and len(groups[-1]) < 2:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def apply_sticking(notes: list[HandNote], kit: Kit, sticking: Sticking, window: float = 0.015) -> list[HandNote]:
    """Force hands on rolls (runs of >= 4 single notes on one object faster than 2 x minTimeGap).

    A roll note beyond its pattern hand's reach goes to the other hand when that one reaches it and is free
    (:func:`_roll_hands`); a note the score forces keeps its hand."""
    if sticking == Sticking.NONE or not notes:
        return notes
    pattern = PATTERNS[sticking]
    groups = _groups(notes, window)
    out = list(notes)
    run: list[int] = []

    def close_run() -> None:
        if len(run) >= 4:
            lead = _hand(kit.spec(notes[run[0]].event).preferred, kit)
            hands = _roll_hands([notes[i] for i in run], kit, lead, pattern)
            for i, hand in zip(run, hands, strict=True):
                if out[i].forced is None:
                    out[i] = replace(notes[i], forced=hand)
        run.clear()

    for g in groups:
        if len(g) != 1:
            close_run()
            continue
        i = g[0]
        n = notes[i]
        if run:
            prev = notes[run[-1]]
            same = kit.object_for(prev.event, prev.pitch).id == kit.object_for(n.event, n.pitch).id
            if not (same and n.time - prev.time < 2 * kit.spec(n.event).min_time_gap):
                close_run()
        run.append(i)
    close_run()
    return out


def _roll_hands(roll: list[HandNote], kit: Kit, lead: Limb, pattern: str) -> list[Limb]:
    """Hands of a roll's notes (time order): the score's where it forces one, else the pattern's (``R``: ``lead``),
    except that a note beyond its pattern hand's reach (``HandNote.out_of_reach``) goes to the other hand when that
    one is free: its interval from the other hand's previous roll note and to its next one (as the pattern gives
    them) are full strokes or rebound doubles (:func:`common.score.rebound.classify`, the rule the hand
    assignment and the feasibility check keep). Otherwise it stays, and the feasibility check flags it
    ``unreachable``. The notes around the roll are not assigned yet: the check judges those intervals."""
    hands = [n.forced if n.forced is not None else lead if pattern[k % len(pattern)] == "R" else _other(lead)
             for k, n in enumerate(roll)]
    last: dict[Limb, tuple[Stroke, bool]] = {}  # each hand's previous roll stroke, whether it was a bounce
    for k, n in enumerate(roll):
        h = hands[k]
        if n.forced is None and n.out_of_reach == h:
            other = _other(h)
            after = next((roll[j] for j in range(k + 1, len(roll)) if hands[j] == other), None)
            if _free(kit, last.get(other), n, after):
                h = hands[k] = other
        last[h] = (_stroke(n), _interval(kit, last.get(h), n) == Interval.REBOUND)
    return hands


def _free(kit: Kit, before: tuple[Stroke, bool] | None, n: HandNote, after: HandNote | None) -> bool:
    """Whether a hand whose previous stroke is ``before`` (and whether it was a bounce) and whose next note is
    ``after`` can play ``n`` between them: neither interval too fast."""
    kind = _interval(kit, before, n)
    if kind == Interval.TOO_FAST:
        return False
    return after is None or classify(kit, _stroke(n), kind == Interval.REBOUND, _stroke(after)) != Interval.TOO_FAST


def _interval(kit: Kit, before: tuple[Stroke, bool] | None, n: HandNote) -> Interval:
    """How a hand whose previous stroke is ``before`` (and whether it was a bounce) plays ``n``."""
    if before is None:
        return Interval.FIRST
    return classify(kit, before[0], before[1], _stroke(n))


def _stroke(n: HandNote) -> Stroke:
    return Stroke(n.time, n.event, n.pitch, n.velocity)


def assign_hands(
    notes: list[HandNote],
    kit: Kit,
    algorithm: HandAlgorithm | str = HandAlgorithm.VITERBI,
    sticking: Sticking | str = Sticking.NONE,
    window: float = 0.015,
    rho: float = 0.02,
    default_weight: float = 0.5,
    costs: Costs | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[Limb | None]:
    """Assign a hand to each stick note (sorted by time; at most two within ``window`` seconds).

    Parameters
    ----------
    notes : list[HandNote]
        Stick events sorted by time.
    kit : Kit
        Hit points, preferred hands, minTimeGaps, pair preferences.
    algorithm : HandAlgorithm
        ``simple``, ``pairwise`` or ``viterbi``.
    sticking : Sticking
        Pattern forced on rolls.
    window : float
        Seconds within which notes are simultaneous.
    rho : float
        Pair-wise algorithm: weight of a neighbour ``dt`` seconds away is ``rho ** dt``.
    default_weight : float
        Pair-wise algorithm: weight of the preferred hand's vote.
    costs : Costs | None
        Shortest-path weights.
    progress : Callable[[int, int], None] | None
        ``viterbi`` (the slow one: most of a long score's limb assignment): called with (notes searched,
        notes) every ``PROGRESS_EVERY`` notes or so; what it raises stops the search. The hands are the
        same with or without it.

    Returns
    -------
    list[Limb | None]
        ``left_hand`` or ``right_hand`` per note; ``None``: the shortest-path search left the
        note out (no hand can play it within the minimum intervals). ``simple`` and ``pairwise``
        give every note a hand (too fast ones are flagged by :func:`common.score.limbs.check_feasibility`).
    """
    algorithm = HandAlgorithm(algorithm)
    notes = apply_sticking(notes, kit, Sticking(sticking), window)
    if not notes:
        return []
    t = _table(notes, kit)
    groups = _groups(notes, window)
    if algorithm == HandAlgorithm.VITERBI:
        return _viterbi(notes, groups, t, kit, costs or Costs(), progress)
    hands: list[Limb | None] = [None] * len(notes)
    last: dict[Limb, float] = {L: -math.inf, R: -math.inf}
    for gi, g in enumerate(groups):
        if len(g) == 2:
            ha, hb = _pair_split(g[0], g[1], t, kit, notes)
            hands[g[0]], hands[g[1]] = ha, hb
            last[L] = last[R] = t.time[g[0]]
            continue
        i = g[0]
        if notes[i].forced is not None:
            h = notes[i].forced
        else:
            h = t.preferred[i]
            if algorithm == HandAlgorithm.PAIRWISE:
                score = default_weight * (1.0 if h == R else -1.0)
                for gj in range(max(0, gi - 4), min(len(groups), gi + 5)):
                    if gj == gi:
                        continue
                    for j in groups[gj]:
                        dt = abs(t.time[j] - t.time[i])
                        if dt <= 1.0:
                            score += rho**dt * kit.pair(t.events[i], t.events[j])
                h = R if score > 0 else L if score < 0 else h
            h = _single_hand(h, notes[i].out_of_reach, t.time[i] - last[h], t.time[i] - last[_other(h)], t.gap[i])
        assert h is not None
        hands[i] = h
        last[h] = t.time[i]
    return [h if h is not None else R for h in hands]


def _single_hand(h: Limb, far: Limb | None, since_h_s: float, since_other_s: float, gap_s: float) -> Limb:
    """``simple`` and ``pairwise``: the hand for a single note the method prefers for hand ``h``. The other hand
    takes it when it is free (its last stroke ``since_other_s`` seconds ago, at least the note's minTimeGap
    ``gap_s``) and ``h`` is not (the minTimeGap alternation) or ``h`` is beyond the note's reach while the other
    reaches it (``far``: ``HandNote.out_of_reach``), rather than the feasibility check moving or dropping it. Where
    ``h`` reaches the note, only the alternation."""
    other = _other(h)
    if since_other_s >= gap_s and (since_h_s < gap_s or far == h):
        return other
    return h


def _viterbi(notes: list[HandNote], groups: list[list[int]], t: _Table, kit: Kit, c: Costs,
             progress: Callable[[int, int], None] | None = None) -> list[Limb | None]:
    """Beam-pruned Viterbi over states (last note of each hand, whether it was a rebound bounce).

    A hand never plays an interval that :func:`common.score.rebound.classify` calls too fast: such
    placements are not allowed; dropping a note (cost ``c.drop`` x (1 + ``c.drop_velocity`` x velocity))
    always is, so the search always finds a path. Dropped notes get ``None``.
    """
    Key = tuple[int, int, bool, bool]
    Option = tuple[tuple[int, Limb | None], ...]
    beam: dict[Key, float] = {(-1, -1, False, False): 0.0}
    history: list[dict[Key, tuple[Key, Option]]] = []

    pair_cache: dict[tuple[EventType, EventType], float] = {}

    def pair(a: EventType, b: EventType) -> float:
        value = pair_cache.get((a, b))
        if value is None:
            value = pair_cache[(a, b)] = kit.pair(a, b)
        return value

    xs = t.x.tolist()
    objects = [_struck_object(kit, n.event, n.pitch) for n in notes]
    # the pair preference is between event types on their own objects; a note struck on another (note_objects)
    # is judged by the geometry, as crossed() judges it
    own = [objects[i] == kit.events[e].object for i, e in enumerate(t.events)]
    # a fast run on a drum (a roll, a tuplet, a drag, a fill) goes hand to hand; one on a cymbal is time kept by one
    # hand (the Groove drummers' hi-hat and ride: given to the other hand, its strokes came late or not at all)
    kinds = {o: kit.object(o).kind for o in set(objects)}
    drum = [kinds[o] == "membrane" for o in objects]
    times = t.time.tolist()
    gaps = t.gap.tolist()
    pos = t.pos.tolist()
    strokes = [Stroke(n.time, n.event, n.pitch, n.velocity) for n in notes]
    far = [n.out_of_reach for n in notes]
    interval_cache: dict[tuple[int, bool, int], Interval] = {}

    def interval(prev: int, prev_rebound: bool, i: int) -> Interval:
        key = (prev, prev_rebound, i)
        kind = interval_cache.get(key)
        if kind is None:
            kind = interval_cache[key] = classify(kit, strokes[prev], prev_rebound, strokes[i])
        return kind

    def place(i: int, h: Limb, state: Key) -> tuple[float, bool]:
        """Cost of playing note i with hand h from ``state`` (inf: not allowed) and whether it is a bounce."""
        prev, other = (state[0], state[1]) if h == L else (state[1], state[0])
        prev_rebound = state[2] if h == L else state[3]
        cost = c.not_preferred if h != t.preferred[i] else 0.0
        if far[i] == h:
            cost += c.out_of_reach
        bounce = False
        if prev >= 0:
            dt = times[i] - times[prev]
            gap = gaps[i]
            if dt < gap - 1e-9:
                kind = interval(prev, prev_rebound, i)
                if kind != Interval.REBOUND:
                    return math.inf, False
                bounce = True
                cost += c.rebound
            else:
                cost += c.fast * (gap / dt) ** 2
                if dt <= c.run_interval + 1e-9 and drum[i] and (other < 0 or free(other, i)):
                    cost += c.run
            a, b = pos[i], pos[prev]
            dist = math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + (a[2] - b[2]) ** 2)
            cost += c.travel * dist / max(dt, 0.02)
        if other >= 0:
            idle = times[i] - times[other]
            if idle < 5 * c.crossing_decay:
                left, right = (i, other) if h == L else (other, i)
                p = pair(t.events[left], t.events[right]) if own[left] and own[right] else 0.0
                if p != 0.0:
                    crossing = p > 0
                else:
                    crossing = objects[left] != objects[right] and xs[left] - xs[right] > 0.10
                if crossing:
                    cost += c.crossing * max(abs(p), 0.5) * math.exp(-idle / c.crossing_decay)
        return cost, bounce

    def free(other: int, i: int) -> bool:
        """Whether the hand whose last note is ``other`` is free to take note i of a fast run (``Costs.run``)."""
        idle = times[i] - times[other]
        return idle > c.run_interval + 1e-9 and (objects[other] == objects[i] or idle >= c.run_idle - 1e-9)

    def allowed(i: int, h: Limb) -> bool:
        f = notes[i].forced
        return f is None or f == h

    next_report = PROGRESS_EVERY
    for g in groups:
        if progress is not None and g[0] >= next_report:
            progress(g[0], len(notes))
            next_report = g[0] + PROGRESS_EVERY
        options: list[Option]
        if len(g) == 1:
            i = g[0]
            options = [((i, h),) for h in HANDS if allowed(i, h)]
            options.append(((i, None),))
        else:
            a, b = g
            options = []
            for ha in HANDS:
                hb = _other(ha)
                if allowed(a, ha) and allowed(b, hb):
                    options.append(((a, ha), (b, hb)))
            if not options:  # contradictory forced hands: both forced to one hand
                options = [((a, L), (b, R))]
            # dropping one of the two (the other on either hand) or both
            options += [((a, None), (b, h)) for h in HANDS if allowed(b, h)]
            options += [((a, h), (b, None)) for h in HANDS if allowed(a, h)]
            options.append(((a, None), (b, None)))
        new: dict[Key, tuple[float, Key, Option]] = {}
        for state, base in beam.items():
            for opt in options:
                cost = base
                s = state
                for i, h in opt:
                    if h is None:
                        cost += c.drop * (1.0 + c.drop_velocity * notes[i].velocity)
                        continue
                    added, bounce = place(i, h, s)
                    cost += added
                    if cost == math.inf:
                        break
                    s = (i, s[1], bounce, s[3]) if h == L else (s[0], i, s[2], bounce)
                if cost == math.inf:
                    continue
                if s not in new or cost < new[s][0]:
                    new[s] = (cost, state, opt)
        best = sorted(new.items(), key=lambda kv: kv[1][0])[: c.beam]
        beam = {k: v[0] for k, v in best}
        history.append({k: (v[1], v[2]) for k, v in best})
    hands: list[Limb | None] = [None] * len(notes)
    key = min(beam, key=lambda k: beam[k])
    for step in reversed(history):
        parent, opt = step[key]
        for i, h in opt:
            hands[i] = h
        key = parent
    return hands
