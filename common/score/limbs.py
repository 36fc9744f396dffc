"""Limb distribution: drum events -> hands, left foot, right foot.

Rules (Kragtwijk, Nijholt and Zwiers 2001):

* at most one stick hi-hat event (HIHATOPEN, HIHATCLOSED) and one HIHATPEDAL at
  a time, the louder of each kind kept; a pedal under a stick hi-hat is played by the
  hi-hat foot (a human drummer's chick under the stick, as in the Groove MIDI
  performances);
* when three or more non-bass events coincide, the hi-hat pedal substitutes
  for a stick hi-hat (the left foot closes the hi-hat instead of a hand);
* at most two stick events at once (the quietest extra ones are dropped);
* BASS goes to the kit's bass foot; with a double pedal, a bass note too soon
  after the previous one goes to the other foot when it is free;
* stick events go to the hands by one of the algorithms of
  :mod:`common.score.hands`; notes the shortest-path search leaves out (no
  hand can play them, even as a rebound double) are merged into a stroke on the
  same object nearby or dropped, and reported.

Every note that cannot be played as written gets a :class:`FeasibilityIssue`
(reason and what was done); see :func:`check_feasibility`.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from common.gcpause import cyclic_gc_paused
from common.gesture.plan import FeasibilityIssue, IssueAction, IssueReason, Nuance
from common.kit import DEFAULT_SEAT_M, STRUCK_KINDS, EventType, Kit, Limb, Vec3
from common.score.events import DrumEvent, Score
from common.score.hands import PROGRESS_EVERY, HandAlgorithm, HandNote, Sticking, assign_hands, crossed
from common.score.rebound import Interval, Stroke, classify, rebound_gap, why_too_fast

STICK_HIHAT = {EventType.HIHATOPEN, EventType.HIHATCLOSED}
FEET = {Limb.LEFT_FOOT, Limb.RIGHT_FOOT}
HANDS = {Limb.LEFT_HAND, Limb.RIGHT_HAND}
SIMULTANEITY = 0.015
"""Events closer than this (seconds) are played at the same time."""
HARD_MIN_INTERVAL = 0.03
"""A limb cannot repeat a stroke faster than this (seconds): such notes are dropped."""
SHOULDERS: dict[Limb, Vec3] = {Limb.LEFT_HAND: (-0.19, 0.05, 1.30), Limb.RIGHT_HAND: (0.19, 0.05, 1.30)}
"""Shoulders (metres) of the drummer seated at :data:`common.kit.DEFAULT_SEAT_M` (the shipped kits' throne); on
another kit they move with its throne (:func:`shoulders`)."""
REACH = 1.15
"""Shoulder-to-stick-tip reach (metres): arm, stick and some lean of the trunk."""
HIPS: dict[Limb, Vec3] = {Limb.LEFT_FOOT: (-0.09, 0.05, 0.61), Limb.RIGHT_FOOT: (0.09, 0.05, 0.61)}
"""Hip joint centres (metres) of a 1.75 m drummer seated at :data:`common.kit.DEFAULT_SEAT_M`, where physics bases
the legs (services/physics/character.py: half the hip width, 0.105 x stature, to each side, 0.05 m forward and
0.09 m above the seat point); on another kit they move with its throne (:func:`hips`)."""
FOOT_REACH = 1.036
"""Hip-to-ball-of-the-foot reach (metres) of a 1.75 m drummer, leg straight and toes pointed: thigh 0.424 m + shank
0.436 m (de Leva's table scaled, services/physics/anthropometry.py) + ankle to the ball of the foot 0.163 m
(services/physics/character.py), 1.023 m, + 0.013 m the body gives on its seat. Measured on renders of a bar of
kicks and snares with the default kit's kick and pedal moved forward (7 Dec): every kick sounds with the pedal
1.0355 m from the hip, one of two at 1.040 m, none from 1.044 m (nor at 1.05-1.12 m). Physics rests the foot on the
pedal by the same reach (:func:`pedals_out_of_reach`); until 7 Dec it used thigh + shank + foot, 1.12 m, and the
planner 1.02 m, dropping notes physics played."""
STATURE_M = 1.75
"""The drummer's height (metres) :data:`SHOULDERS`, :data:`REACH`, :data:`HIPS` and :data:`FOOT_REACH` are given for;
another height scales them (:func:`shoulders`, :func:`hips`, :func:`hand_reach`, :func:`foot_reach`)."""
ARM_M = 0.640
"""Of :data:`REACH`, the arm of a 1.75 m drummer: upper arm + forearm + hand, 0.282 + 0.270 + 0.087 m (de Leva's
table scaled, services/physics/anthropometry.py). It scales with the height; the stick and the lean of the trunk
(the other 0.51 m) do not, as in physics' own reach (services/physics/drummer.py ``_reach``)."""
LEG_M = 0.860
"""Of :data:`FOOT_REACH`, the thigh and shank of a 1.75 m drummer, 0.424 + 0.436 m (the rest, to the ball of the
foot, scales with the height)."""
PROGRESS_SHARES = (0.08, 0.86)
"""Shares of :func:`distribute`'s progress for its limb rules and its hand assignment (the feasibility check has
the rest): their shares of its time on a 200,000-note Groove score (8 %, 86 %, 6 %)."""

ProgressCallback = Callable[[int, int], None]
"""Told (notes done, notes total) while a long score is worked on."""


@dataclass(frozen=True)
class LimbLengths:
    """A drummer's arm and leg (metres) where they are not de Leva's table scaled to its height: a skeleton's
    (``batteur render --skeleton-bvh``: physics builds the body from its segments). The planner's reach follows
    them (:func:`hand_reach`, :func:`foot_reach`); the shoulders and hips stay where the height puts them."""

    arm_m: float
    """Upper arm + forearm + hand."""
    leg_m: float
    """Thigh + shank."""

    @classmethod
    def of_segments(cls, lengths_m: Mapping[str, float]) -> LimbLengths:
        """A body's arm and leg from its segment lengths (metres, by the names of
        services/physics/anthropometry.py: ``upper_arm``, ``forearm``, ``hand``, ``thigh``, ``shank``)."""
        return cls(arm_m=lengths_m["upper_arm"] + lengths_m["forearm"] + lengths_m["hand"],
                   leg_m=lengths_m["thigh"] + lengths_m["shank"])


@dataclass(frozen=True)
class Note:
    """A drum event with its limb.

    ``index`` is the event's index in ``Score.events``; ``event`` may differ from
    the score's when the hi-hat pedal substituted for a stick hi-hat.
    """

    index: int
    time: float
    event: EventType
    velocity: float
    limb: Limb
    pitch: int | None = None
    nuance: Nuance | None = None
    rebound: bool = False
    """True for the second note of a rebound double (a bounce after the hand's previous stroke, played with the
    fingers below the event's minTimeGap; :mod:`common.score.rebound`); set by :func:`check_feasibility`."""


@dataclass
class Assignment:
    """Notes with limbs, sorted by time, and the issues found."""

    notes: list[Note]
    issues: list[FeasibilityIssue] = field(default_factory=list)
    algorithm: HandAlgorithm = HandAlgorithm.VITERBI
    kit_name: str = ""
    pedals_out_of_reach: frozenset[tuple[Limb, str]] = frozenset()
    """(foot, pedal object id) of each pedal beyond that foot's reach for the drummer distributed for: its notes
    are dropped, and the planner does not rest the foot there (stretched for it, the leg pulled the body and the
    hands off their notes)."""

    def of(self, limb: Limb) -> list[Note]:
        return [n for n in self.notes if n.limb == limb]


def _groups(times: list[float], window: float) -> list[list[int]]:
    groups: list[list[int]] = []
    for i, t in enumerate(times):
        if groups and t - times[groups[-1][0]] <= window:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def _keep_rank(e: DrumEvent, pedal_sounding: bool) -> tuple[bool, bool, float]:
    """Rank of a stick event among too many at once (higher is kept): a forced hand, not a stick hi-hat
    the pedal already sounds, then loudness."""
    return (e.limb is not None, not (pedal_sounding and e.event in STICK_HIHAT), e.velocity)


def bass_feet(kit: Kit) -> set[Limb]:
    """The feet :func:`distribute` may give a BASS note: the kit's bass-drum foot and, with a double pedal, the other
    foot too (a kick too soon after the first foot's last one)."""
    if EventType.BASS not in kit.events:
        return set()
    foot = kit.spec(EventType.BASS).preferred
    other = Limb.LEFT_FOOT if foot == Limb.RIGHT_FOOT else Limb.RIGHT_FOOT
    return {foot, other} & FEET if kit.double_pedal else {foot} & FEET


def distribute(
    score: Score,
    kit: Kit,
    algorithm: HandAlgorithm | str = HandAlgorithm.VITERBI,
    sticking: Sticking | str = Sticking.NONE,
    window: float = SIMULTANEITY,
    progress: ProgressCallback | None = None,
    height_m: float = STATURE_M,
    lengths: LimbLengths | None = None,
) -> Assignment:
    """Distribute a score's events over the limbs and check feasibility.

    Parameters
    ----------
    score : Score
        Events sorted by time.
    kit : Kit
        The kit played (preferred limbs, minTimeGaps, pair preferences, double pedal).
    algorithm : HandAlgorithm
        Hand-assignment algorithm.
    sticking : Sticking
        Sticking pattern forced on rolls.
    window : float
        Simultaneity window, seconds.
    progress : Callable[[int, int], None] | None
        Called with (notes done, notes total), ``total`` the score's events: ``(0, total)`` first,
        ``(total, total)`` last, and between once every ``PROGRESS_EVERY`` notes a pass goes through.
        ``done`` is the work done counted in notes: the limb rules move it over their share of ``total``
        (``PROGRESS_SHARES``), the hand assignment over its share (the ``viterbi`` search as it goes, the others
        at once when they end), the feasibility check over the rest. Whatever it raises (``KeyboardInterrupt``)
        stops the distribution. The assignment is the same with or without it.
    height_m : float
        The drummer's height, metres: its reach for the ``unreachable`` check (:func:`check_feasibility`) and the
        hand assignment (a hand is given a note beyond its reach only when the other hand cannot play it).
    lengths : LimbLengths | None
        The drummer's arm and leg when they are not the height's (a skeleton's), metres; None: the height's.
    """
    with cyclic_gc_paused():  # many small objects, no cycles: collections only walked them (common/gcpause.py)
        return _distribute(score, kit, algorithm, sticking, window, progress, height_m, lengths)


def _distribute(score: Score, kit: Kit, algorithm: HandAlgorithm | str, sticking: Sticking | str, window: float,
                progress: ProgressCallback | None, height_m: float = STATURE_M,
                lengths: LimbLengths | None = None) -> Assignment:
    """:func:`distribute`'s work."""
    algorithm = HandAlgorithm(algorithm)
    report = _Shares(progress, len(score.events))
    report.at(0.0)
    events = [e for e in score.events if e.event in kit.events]
    index_of = {id(e): i for i, e in enumerate(score.events)}
    issues: list[FeasibilityIssue] = []
    for e in score.events:
        if e.event not in kit.events:
            issues.append(
                FeasibilityIssue(
                    index_of[id(e)],
                    e.time,
                    e.event,
                    IssueReason.UNKNOWN_NOTE,
                    IssueAction.DROPPED,
                    f"kit {kit.name!r} has no {e.event.value}",
                )
            )
    foot_of = {
        EventType.BASS: kit.spec(EventType.BASS).preferred if EventType.BASS in kit.events else Limb.RIGHT_FOOT,
        EventType.HIHATPEDAL: kit.spec(EventType.HIHATPEDAL).preferred
        if EventType.HIHATPEDAL in kit.events
        else Limb.LEFT_FOOT,
    }
    hihat_foot = foot_of[EventType.HIHATPEDAL]
    bass_foot = foot_of[EventType.BASS]
    other_foot = Limb.LEFT_FOOT if bass_foot == Limb.RIGHT_FOOT else Limb.RIGHT_FOOT
    feet: list[Note] = []
    hand_notes: list[HandNote] = []
    hand_meta: list[tuple[int, float, int | None, Nuance | None, EventType]] = []
    last_foot: dict[Limb, float] = {Limb.LEFT_FOOT: -math.inf, Limb.RIGHT_FOOT: -math.inf}

    def issue(idx: int, reason: IssueReason, action: IssueAction, detail: str) -> None:
        e = score.events[idx]
        issues.append(FeasibilityIssue(idx, e.time, e.event, reason, action, detail))

    out_of_reach = _OutOfReach(kit, height_m, lengths)
    rules, hands_share = PROGRESS_SHARES
    next_report = PROGRESS_EVERY
    for g in _groups([e.time for e in events], window):
        if progress is not None and g[0] >= next_report:
            report.at(rules * g[0] / len(events))
            next_report = g[0] + PROGRESS_EVERY
        group = [(index_of[id(events[i])], events[i]) for i in g]
        # one stick hi-hat and one pedal at a time: drummers often close the hi-hat with the foot as a hand
        # strikes it (a chick under the stick, or a splash beside an open hit), so the two are kept together
        for kind in (STICK_HIHAT, {EventType.HIHATPEDAL}):
            hats = [(i, e) for i, e in group if e.event in kind]
            if len(hats) < 2:
                continue
            keep = max(hats, key=lambda ie: (ie[1].velocity, ie[1].event.value))
            for i, e in hats:
                if i != keep[0]:
                    issue(
                        i,
                        IssueReason.HIHAT_CONFLICT,
                        IssueAction.DROPPED,
                        f"{e.event.value} with {keep[1].event.value} at the same time",
                    )
            group = [(i, e) for i, e in group if e.event not in kind or i == keep[0]]
        # pedal substitution when three or more non-bass events coincide
        non_bass = [(i, e) for i, e in group if e.event != EventType.BASS]
        stick = [(i, e) for i, e in group if e.event not in (EventType.BASS, EventType.HIHATPEDAL)]
        pedal_ok = EventType.HIHATPEDAL in kit.events and not any(e.event == EventType.HIHATPEDAL for _, e in group)
        if len(non_bass) >= 3 and pedal_ok:
            for i, e in stick:
                if e.event in STICK_HIHAT and e.limb not in HANDS:
                    issue(
                        i,
                        IssueReason.TOO_MANY_HANDS,
                        IssueAction.SUBSTITUTED_PEDAL,
                        f"{len(non_bass)} non-bass events at once: hi-hat pedal instead of a stick",
                    )
                    group = [(j, replace(f, event=EventType.HIHATPEDAL) if j == i else f) for j, f in group]
                    break
        stick = [(i, e) for i, e in group if e.event not in (EventType.BASS, EventType.HIHATPEDAL)]
        if len(stick) > 2:
            # with the pedal sounding the hi-hat, a stick hi-hat is the note to give up, then the quietest
            pedal = any(e.event == EventType.HIHATPEDAL for _, e in group)
            ranked = sorted(stick, key=lambda ie: _keep_rank(ie[1], pedal), reverse=True)
            for i, _e in ranked[2:]:
                issue(
                    i, IssueReason.TOO_MANY_HANDS, IssueAction.DROPPED, f"{len(stick)} stick events at once, two hands"
                )
            dropped = {i for i, _ in ranked[2:]}
            group = [(i, e) for i, e in group if i not in dropped]
        for i, e in group:
            if e.event == EventType.BASS:
                foot = bass_foot
                gap = kit.spec(EventType.BASS).min_time_gap
                busy_other = any(f.event == EventType.HIHATPEDAL for _, f in group)
                if (
                    kit.double_pedal
                    and e.time - last_foot[foot] < gap
                    and not busy_other
                    and e.time - last_foot[other_foot] >= gap
                ):
                    foot = other_foot
                feet.append(Note(i, e.time, e.event, e.velocity, foot, e.pitch, e.nuance))
                last_foot[foot] = e.time
            elif e.event == EventType.HIHATPEDAL:
                if (
                    any(f.event == EventType.BASS for _, f in group)
                    and hihat_foot == other_foot
                    and _foot_busy(feet, hihat_foot, e.time, window)
                ):
                    issue(i, IssueReason.LIMB_BUSY, IssueAction.DROPPED, "hi-hat foot is playing the bass drum")
                    continue
                feet.append(Note(i, e.time, e.event, e.velocity, hihat_foot, e.pitch, e.nuance))
                last_foot[hihat_foot] = e.time
            else:
                forced = e.limb if e.limb in HANDS else None
                hand_notes.append(HandNote(len(hand_notes), e.time, e.event, e.pitch, forced, e.velocity,
                                           out_of_reach(e.event, e.pitch)))
                hand_meta.append((i, e.velocity, e.pitch, e.nuance, e.event))
    report.at(rules)
    hands = assign_hands(hand_notes, kit, algorithm, sticking, window, progress=None if progress is None else
                         lambda k, n: report.at(rules + hands_share * k / max(n, 1)))
    report.at(rules + hands_share)
    notes = list(feet)
    left_out: list[Note] = []
    for hn, h, (i, vel, pitch, nuance, ev) in zip(hand_notes, hands, hand_meta, strict=True):
        if h is None:
            left_out.append(Note(i, hn.time, ev, vel, Limb.RIGHT_HAND, pitch, nuance))
        else:
            notes.append(Note(i, hn.time, ev, vel, h, pitch, nuance))
    notes = _merge_or_drop(left_out, notes, kit, issues)
    notes.sort(key=lambda n: (n.time, n.limb.value))
    far = frozenset((foot, pedal) for pedal, feet in pedals_out_of_reach(kit, height_m, lengths).items()
                    for foot in feet)
    assignment = Assignment(notes=notes, issues=issues, algorithm=algorithm, kit_name=kit.name,
                            pedals_out_of_reach=far)
    checked_from = rules + hands_share
    check_feasibility(assignment, kit, window, None if progress is None else
                      lambda k, n: report.at(checked_from + (1.0 - checked_from) * k / max(n, 1)), height_m, lengths)
    report.at(1.0)
    return assignment


def _distance_m(a: Vec3, b: Vec3) -> float:
    """Metres between two points: one rule for the hand assignment's reach (:class:`_OutOfReach`) and the
    feasibility check's, so they never disagree on a note at the edge."""
    return float(np.linalg.norm(np.array(a) - np.array(b)))


class _OutOfReach:
    """The hand beyond whose reach a stick event's hit point is while the other hand reaches it (None: both or
    neither reach it), for a drummer ``height_m`` tall (metres) on ``kit``'s throne: the hand assignment gives the
    note to the other hand when it can (:class:`common.score.hands.HandNote`)."""

    def __init__(self, kit: Kit, height_m: float, lengths: LimbLengths | None = None) -> None:
        self.kit = kit
        self.shoulders = shoulders(kit, height_m)
        self.reach = hand_reach(height_m, lengths)
        self.known: dict[tuple[EventType, int | None], Limb | None] = {}

    def __call__(self, event: EventType, pitch: int | None) -> Limb | None:
        if (event, pitch) not in self.known:
            point = self.kit.hit_point(event, pitch)[0]
            beyond = [h for h in (Limb.LEFT_HAND, Limb.RIGHT_HAND)
                      if _distance_m(point, self.shoulders[h]) > self.reach]
            self.known[(event, pitch)] = beyond[0] if len(beyond) == 1 else None
        return self.known[(event, pitch)]


class _Shares:
    """Reports a fraction of the work as (notes done, notes total) to a progress callback (none: nothing)."""

    def __init__(self, progress: ProgressCallback | None, total: int) -> None:
        self.progress = progress
        self.total = total

    def at(self, fraction: float) -> None:
        if self.progress is not None:
            self.progress(min(self.total, int(fraction * self.total)), self.total)


def _foot_busy(feet: list[Note], foot: Limb, time: float, window: float) -> bool:
    """Whether ``foot`` plays a note within ``window`` of ``time``; ``feet`` is in time order.

    Only the notes at the end of the list can be that close: scanning them all for every hi-hat pedal under a
    bass note made a long score quadratic (20,000 such pairs took 36 s).
    """
    for n in reversed(feet):
        if time - n.time > window:  # this one and all before it are too early
            return False
        if n.limb == foot and abs(n.time - time) <= window:
            return True
    return False


def _limb_words(limb: Limb) -> str:
    """``left hand`` for :attr:`Limb.LEFT_HAND`: a limb as a drummer says it."""
    return limb.value.replace("_", " ")


def _strokes_around(time: float, before: float | None, after: float | None) -> str:
    """A hand's strokes around a note at ``time`` (s) as a drummer reads them: ``its previous stroke 1180 ms before,
    its next 20 ms after`` (until 8 Dec ``1180 ms after and 20 ms before its strokes``, which read backwards); ""
    with neither."""
    said = []
    if before is not None:
        gap_ms = 1000 * (time - before)
        said.append("a stroke at the same time" if gap_ms < 0.5 else f"its previous stroke {gap_ms:.0f} ms before")
    if after is not None:
        next_ms = f"{1000 * (after - time):.0f} ms after"
        said.append(f"its next {next_ms}" if before is not None else f"its next stroke {next_ms}")
    return ", ".join(said)


def _merge_or_drop(left_out: list[Note], notes: list[Note], kit: Kit, issues: list[FeasibilityIssue]) -> list[Note]:
    """Report the stick notes the hand assignment left out (no hand can play them in time).

    A left-out note with a kept stick note on the same object less than its
    minTimeGap away is *merged* into that note (the two sound as one stroke;
    its velocity is kept, so the hand assignment's intervals stay valid);
    otherwise it is *dropped*. The detail gives each hand's intervals.
    """
    if not left_out:
        return notes
    out = list(notes)
    hands_sorted = sorted((n for n in out if n.limb in HANDS), key=lambda n: n.time)
    times = [n.time for n in hands_sorted]
    for d in left_out:
        gap = kit.spec(d.event).min_time_gap
        obj = kit.object_for(d.event, d.pitch).id
        k = bisect.bisect_left(times, d.time)
        near = [n for n in hands_sorted[max(0, k - 4) : k + 4] if abs(n.time - d.time) < gap]
        around = hands_sorted[max(0, k - 8) : k + 8]
        parts = []
        for h in (Limb.LEFT_HAND, Limb.RIGHT_HAND):
            before = max((n.time for n in around if n.limb == h and n.time <= d.time), default=None)
            after = min((n.time for n in around if n.limb == h and n.time > d.time), default=None)
            said = _strokes_around(d.time, before, after)
            if said:
                parts.append(f"{_limb_words(h)}: {said}")
        why = (f"no hand can play it in time ({'; '.join(parts) or 'both hands busy'}; minTimeGap "
               f"{gap * 1000:.0f} ms, rebound minimum {rebound_gap(kit, d.event, d.velocity) * 1000:.0f} ms)")
        same = [n for n in near if kit.object_for(n.event, n.pitch).id == obj]
        if same:
            into = min(same, key=lambda n: abs(n.time - d.time))
            issues.append(FeasibilityIssue(d.index, d.time, d.event, IssueReason.TOO_FAST, IssueAction.MERGED,
                                           f"{why}, so it sounds as one stroke with the {_limb_words(into.limb)}'s "
                                           f"{into.event.value} at {into.time:.3f} s"))
        else:
            issues.append(FeasibilityIssue(d.index, d.time, d.event, IssueReason.TOO_FAST, IssueAction.DROPPED, why))
    return out


def shoulders(kit: Kit, height_m: float = STATURE_M) -> dict[Limb, Vec3]:
    """The shoulders (metres) of a drummer ``height_m`` tall seated on ``kit``'s throne: :data:`SHOULDERS` moved as
    far as the throne is from :data:`common.kit.DEFAULT_SEAT_M` (the same numbers on the shipped kits, mirrored or
    not), their offsets from the seat scaled with the height (:func:`_scaled`)."""
    return _from_seat(_scaled(SHOULDERS, height_m), kit)


def hips(kit: Kit, height_m: float = STATURE_M) -> dict[Limb, Vec3]:
    """The hip joint centres (metres) of a drummer ``height_m`` tall seated on ``kit``'s throne (:data:`HIPS`
    scaled and moved with it, as :func:`shoulders`)."""
    return _from_seat(_scaled(HIPS, height_m), kit)


def hand_reach(height_m: float = STATURE_M, lengths: LimbLengths | None = None) -> float:
    """Shoulder-to-stick-tip reach (metres) of a drummer ``height_m`` tall: :data:`REACH`, its arm
    (:data:`ARM_M`) scaled with the height, or ``lengths.arm_m`` when given (the stick and the lean stay)."""
    if lengths is not None:
        return REACH - ARM_M + lengths.arm_m
    if height_m == STATURE_M:  # exactly REACH: plans of the default drummer do not change
        return REACH
    return REACH + ARM_M * (height_m / STATURE_M - 1.0)


def foot_reach(height_m: float = STATURE_M, lengths: LimbLengths | None = None) -> float:
    """Hip-to-ball-of-the-foot reach (metres) of a drummer ``height_m`` tall: :data:`FOOT_REACH` scaled (every
    part of it is a body segment), its thigh and shank (:data:`LEG_M`) ``lengths.leg_m`` when given."""
    if lengths is not None:
        return (FOOT_REACH - LEG_M) * height_m / STATURE_M + lengths.leg_m
    if height_m == STATURE_M:
        return FOOT_REACH
    return FOOT_REACH * height_m / STATURE_M


def _scaled(at_stature: dict[Limb, Vec3], height_m: float) -> dict[Limb, Vec3]:
    """Points of the body (metres) given for a :data:`STATURE_M` drummer on the default seat, for one ``height_m``
    tall on the same seat: physics builds the body from segments scaled with the height and seats it on the
    throne, so each point's offset from the seat point scales (the hips 0.09 m above it at 1.75 m are 0.072 m above
    it at 1.40 m). The default height leaves them exactly as given."""
    if height_m == STATURE_M:
        return at_stature
    k = height_m / STATURE_M
    sx, sy, sz = DEFAULT_SEAT_M
    return {limb: (sx + k * (x - sx), sy + k * (y - sy), sz + k * (z - sz)) for limb, (x, y, z) in at_stature.items()}


def _from_seat(at_default: dict[Limb, Vec3], kit: Kit) -> dict[Limb, Vec3]:
    """Points of the body (metres) given for the default seat, moved to ``kit``'s: the body only translates with
    its throne (physics seats it facing +y whatever the throne's rotation). On the default seat the offsets are 0.0
    (or -0.0), which leaves every coordinate exactly as given."""
    dx, dy, dz = (seat - default for seat, default in zip(kit.seat_position(), DEFAULT_SEAT_M, strict=True))
    return {limb: (x + dx, y + dy, z + dz) for limb, (x, y, z) in at_default.items()}


def check_feasibility(assignment: Assignment, kit: Kit, window: float = SIMULTANEITY,
                      progress: ProgressCallback | None = None, height_m: float = STATURE_M,
                      lengths: LimbLengths | None = None) -> None:
    """Flag notes beyond human limits; drop strokes a limb cannot repeat at all; mark rebound doubles.

    Adds to ``assignment.issues``: ``too_fast`` (same limb closer than the
    event's minTimeGap and not a rebound double (:mod:`common.score.rebound`):
    played anyway, or dropped below ``HARD_MIN_INTERVAL``), ``crossing`` (arms
    crossed for simultaneous stick events: :func:`common.score.hands.crossed`, by
    the notes' objects) and ``unreachable`` (hit point beyond
    :data:`REACH` of the hand's shoulder, or pedal beyond :data:`FOOT_REACH` of the foot's hip, both where the kit's
    throne seats the drummer: :func:`shoulders`, :func:`hips`; for a drummer ``height_m`` tall (metres) the points
    and reaches scale: :func:`hand_reach`, :func:`foot_reach`; ``lengths``: a skeleton's arm and leg). A hand's
    note beyond its hand's reach goes to the other hand when that one reaches it and is free then (:func:`_busy`;
    ``moved_to_other_hand``), else it is dropped: its hand does not travel to it and plays its other notes as if
    it were not written (a hand held at the edge of its reach spoiled them). A foot's note on a pedal beyond its
    reach is dropped too (until 7 Dec played anyway: the foot pulled the body, and with it the hands, off their
    notes). A hand's note that is the bounce of a rebound double gets ``Note.rebound = True`` and no issue.
    ``progress``: called with (notes checked, notes total) every ``PROGRESS_EVERY`` notes (not at the end); what
    it raises stops the check. Run again on its own result it changes nothing and adds no issue twice.
    """
    kept: list[Note] = []
    last: dict[Limb, Note] = {}
    points: dict[tuple[EventType, int | None], tuple[float, float, float]] = {}
    shoulder_at = shoulders(kit, height_m)
    hip_at = hips(kit, height_m)
    arm_reach, leg_reach = hand_reach(height_m, lengths), foot_reach(height_m, lengths)
    foot_distances: dict[tuple[EventType, Limb], float] = {}
    known = set(assignment.issues)  # issues of an earlier check of these notes: not added twice

    def add(issue: FeasibilityIssue) -> None:
        if issue not in known:
            assignment.issues.append(issue)

    def from_hip(event: EventType, foot: Limb) -> float:
        """Metres from the foot's hip to where it presses the pedal (the planner's target)."""
        if (event, foot) not in foot_distances:
            foot_distances[(event, foot)] = math.dist(kit.effector_target(event, foot)[0], hip_at[foot])
        return foot_distances[(event, foot)]

    def point(event: EventType, pitch: int | None) -> tuple[float, float, float]:
        if (event, pitch) not in points:
            points[(event, pitch)] = kit.hit_point(event, pitch)[0]
        return points[(event, pitch)]

    shoulder_distances: dict[tuple[EventType, int | None, Limb], float] = {}

    def from_shoulder(n: Note, hand: Limb) -> float:
        """Metres from ``hand``'s shoulder to the note's hit point (asked for every hand note: kept by sound)."""
        key = (n.event, n.pitch, hand)
        if key not in shoulder_distances:
            shoulder_distances[key] = _distance_m(point(n.event, n.pitch), shoulder_at[hand])
        return shoulder_distances[key]

    later = _Later(assignment.notes)

    def other_hand_for(k: int, n: Note) -> tuple[Limb | None, str]:
        """The other hand when it reaches note ``k``, ``n``, beyond its own hand's reach, and is free then (None:
        it is not), and what the issue says."""
        other = _other_hand(n.limb)
        where = (f"{from_shoulder(n, n.limb):.2f} m from the {n.limb.value.removesuffix('_hand')} shoulder, "
                 f"{from_shoulder(n, other):.2f} m from the {other.value.removesuffix('_hand')} (reach "
                 f"{arm_reach:.2f} m)")
        if from_shoulder(n, other) > arm_reach:
            return None, where
        busy = _busy(kit, n, other, last.get(other), later.after(k, other), window)
        return (None if busy else other), f"{where}; the {other.value.replace('_', ' ')} {busy or 'plays it'}"

    total = len(assignment.notes)
    moved = False
    for k, n in enumerate(assignment.notes):
        if progress is not None and k % PROGRESS_EVERY == 0:
            progress(k, total)
        if n.limb in HANDS and from_shoulder(n, n.limb) > arm_reach:
            taker, why = other_hand_for(k, n)
            action = IssueAction.DROPPED if taker is None else IssueAction.MOVED_TO_OTHER_HAND
            add(FeasibilityIssue(n.index, n.time, n.event, IssueReason.UNREACHABLE, action, why))
            if taker is None:  # no knots of its own: its hand goes on between its other notes
                continue
            n = replace(n, limb=taker)
            moved = True
        if n.limb in FEET and from_hip(n.event, n.limb) > leg_reach:
            # dropped as a hand's is: played anyway, the foot stretched for it pulled the whole body off its seat and
            # every stick stopped above its heads (a kit with its kick pedal out of reach played no note at all)
            add(FeasibilityIssue(n.index, n.time, n.event, IssueReason.UNREACHABLE, IssueAction.DROPPED,
                                 f"{from_hip(n.event, n.limb):.2f} m from the {n.limb.value.replace('_', ' ')}'s hip "
                                 f"(reach {leg_reach:.2f} m)"))
            continue
        prev = last.get(n.limb)
        if n.limb in HANDS:
            kind = Interval.FIRST
            if prev is not None:
                kind = classify(kit, _stroke(prev), prev.rebound, _stroke(n))
            if n.rebound != (kind == Interval.REBOUND):
                n = replace(n, rebound=kind == Interval.REBOUND)
            if kind == Interval.TOO_FAST:
                assert prev is not None
                detail = f"{n.limb.value} " + why_too_fast(kit, _stroke(prev), prev.rebound, _stroke(n))
                dt = n.time - prev.time
                action = IssueAction.DROPPED if dt < HARD_MIN_INTERVAL else IssueAction.PLAYED_ANYWAY
                add(FeasibilityIssue(n.index, n.time, n.event, IssueReason.TOO_FAST, action, detail))
                if action == IssueAction.DROPPED:
                    continue
        elif prev is not None:
            dt = n.time - prev.time
            gap = kit.spec(n.event).min_time_gap
            if dt < HARD_MIN_INTERVAL:
                add(
                    FeasibilityIssue(
                        n.index,
                        n.time,
                        n.event,
                        IssueReason.TOO_FAST,
                        IssueAction.DROPPED,
                        f"{n.limb.value} {dt * 1000:.0f} ms after its last stroke",
                    )
                )
                continue
            if dt < gap:
                add(
                    FeasibilityIssue(
                        n.index,
                        n.time,
                        n.event,
                        IssueReason.TOO_FAST,
                        IssueAction.PLAYED_ANYWAY,
                        f"{n.limb.value} {dt * 1000:.0f} ms after its last stroke (minTimeGap {gap * 1000:.0f} ms)",
                    )
                )
        if n.limb in HANDS:
            other = last.get(Limb.LEFT_HAND if n.limb == Limb.RIGHT_HAND else Limb.RIGHT_HAND)
            if other is not None and n.time - other.time <= window:
                left, right = (n, other) if n.limb == Limb.LEFT_HAND else (other, n)
                xl = point(left.event, left.pitch)[0]
                xr = point(right.event, right.pitch)[0]
                if crossed(kit, left.event, right.event, xl, xr, left.pitch, right.pitch):
                    add(
                        FeasibilityIssue(
                            n.index,
                            n.time,
                            n.event,
                            IssueReason.CROSSING,
                            IssueAction.PLAYED_ANYWAY,
                            f"left hand on {left.event.value}, right hand on {right.event.value} at once",
                        )
                    )
        last[n.limb] = n
        kept.append(n)
    if moved:  # in distribute's order again (time, then limb), which a second check walks in
        kept.sort(key=lambda n: (n.time, n.limb.value))
    assignment.notes = kept
    assignment.issues.sort(key=lambda i: (i.time, i.note_index))


def _stroke(n: Note) -> Stroke:
    return Stroke(n.time, n.event, n.pitch, n.velocity)


def _other_hand(hand: Limb) -> Limb:
    return Limb.LEFT_HAND if hand == Limb.RIGHT_HAND else Limb.RIGHT_HAND


class _Later:
    """Each hand's next note after a position of a time-ordered note list, by the hands the list came with (a later
    note the check then drops or moves is seen where it was: the hand may be judged busy when it would not be). The
    index is built on the first question: only a note beyond its hand's reach asks."""

    def __init__(self, notes: list[Note]) -> None:
        self.notes = notes
        self.at: dict[Limb, list[int]] | None = None

    def after(self, k: int, hand: Limb) -> Note | None:
        if self.at is None:
            self.at = {h: [] for h in HANDS}
            for j, n in enumerate(self.notes):
                if n.limb in HANDS:
                    self.at[n.limb].append(j)
        where = self.at[hand]
        i = bisect.bisect_right(where, k)
        return self.notes[where[i]] if i < len(where) else None


def _busy(kit: Kit, n: Note, hand: Limb, before: Note | None, after: Note | None, window: float) -> str:
    """Why ``hand`` cannot take ``n`` from its own hand ("" when it is free): a note of its own within ``window``
    seconds (two strokes at once), or an interval to its note ``before`` or ``after`` that
    :func:`common.score.rebound.classify` calls too fast (the rules the hand assignment keeps)."""
    bounce = False
    if before is not None:
        if n.time - before.time <= window:
            return f"plays {before.event.value} at the same time"
        kind = classify(kit, _stroke(before), before.rebound, _stroke(n))
        if kind == Interval.TOO_FAST:
            return "is busy: " + why_too_fast(kit, _stroke(before), before.rebound, _stroke(n))
        bounce = kind == Interval.REBOUND
    if after is not None:
        if after.time - n.time <= window:
            return f"plays {after.event.value} at the same time"
        if classify(kit, _stroke(n), bounce, _stroke(after)) == Interval.TOO_FAST:
            return (f"is busy: its {after.event.value} at {after.time:.3f} s would be "
                    + why_too_fast(kit, _stroke(n), bounce, _stroke(after)))
    return ""


def unplayable_instruments(kit: Kit, height_m: float = STATURE_M, lengths: LimbLengths | None = None) -> list[str]:
    """The kit's instruments the drummer cannot play, one line each naming the object and why (for a warning as
    the kit is loaded: a kit file may place an object anywhere).

    An instrument is unplayable when no event type or ``note_objects`` pitch strikes it, when a stick event strikes
    an object of a kind no stick strikes (a stand), when a stick event's hit point is beyond a hand's
    :data:`REACH` from both shoulders, or when a pedal is beyond :data:`FOOT_REACH` from the hip of the foot that
    presses it (what :func:`check_feasibility` flags ``unreachable`` on every such note). Shoulders and hips are
    where the kit's throne seats the drummer (:func:`shoulders`, :func:`hips`); mirroring the kit for a left-hander
    mirrors the throne and swaps the feet, so the same instruments are named. ``height_m``: the drummer's height,
    metres (its reach scales: :func:`check_feasibility`; a line names a drummer of another height than
    :data:`STATURE_M`: "a 1.4 m drummer's hand reaching 1.02 m"). ``lengths``: a skeleton's arm and leg, metres
    (its reach, :func:`hand_reach`; a line names it: "a skeleton's hand reaching 0.977 m"). The physics' own reach
    (``services/physics/drummer.py``, from the body's measures) is longer, so every target it refuses is among
    these.
    """
    from common.score.gm import DRUM_MAP

    strokes: dict[str, list[tuple[str, EventType, int | None]]] = {}  # object id -> (what, event, pitch) of sticks
    struck: set[str] = set()
    for event, spec in kit.events.items():
        struck.add(spec.object)
        if spec.pedal is None:
            strokes.setdefault(spec.object, []).append((event.value, event, None))
    for pitch, object_id in sorted(kit.note_objects.items()):
        mapped = DRUM_MAP.get(pitch)
        if mapped is None or mapped not in kit.events:  # no score note of this pitch reaches the object
            continue
        struck.add(object_id)
        if kit.events[mapped].pedal is None:
            strokes.setdefault(object_id, []).append((f"{mapped.value} (pitch {pitch})", mapped, pitch))
    shoulder_at = shoulders(kit, height_m)
    arm_reach = hand_reach(height_m, lengths)
    pedals_far = pedals_out_of_reach(kit, height_m, lengths)
    whose = _whose(height_m, lengths)
    lines: list[str] = []
    for obj in kit.objects:
        for foot, far_ones in pedals_far.get(obj.id, {}).items():
            lines.append(f"{obj.id}: out of the {foot.value.replace('_', ' ')}'s reach ({', '.join(far_ones)} from the "
                         f"hip, a {whose}leg reaching {foot_reach(height_m, lengths):.4g} m): the planner drops its "
                         "notes (unreachable)")
        if obj.id not in struck:
            if obj.kind in STRUCK_KINDS:
                lines.append(f"{obj.id} ({obj.kind}): no event type or note_objects pitch strikes it")
            continue
        ways = strokes.get(obj.id, [])
        if ways and obj.kind not in STRUCK_KINDS:
            lines.append(f"{obj.id}: {', '.join(w for w, _, _ in ways)} strike{'s' * (len(ways) == 1)} it, but it "
                         f"is a {obj.kind}, which no stick strikes")
            continue
        far = []
        for what, struck_event, struck_pitch in ways:
            point = kit.hit_point(struck_event, struck_pitch)[0]
            nearer = min(_distance_m(point, s) for s in shoulder_at.values())
            if nearer > arm_reach:
                far.append(f"{what} {nearer:.2f} m")
        if far:
            lines.append(f"{obj.id}: out of both hands' reach ({', '.join(far)} from the nearer shoulder, a "
                         f"{whose}hand reaching {arm_reach:.3g} m): the planner flags its notes unreachable")
    return lines


def _whose(height_m: float, lengths: LimbLengths | None) -> str:
    """Whose reach a line of :func:`unplayable_instruments` gives: a skeleton's, a drummer's of another height than
    :data:`STATURE_M` (metres), or "" (the default drummer's reads as it always did)."""
    if lengths is not None:
        return "skeleton's "
    return "" if height_m == STATURE_M else f"{height_m:g} m drummer's "


def pedals_out_of_reach(kit: Kit, height_m: float = STATURE_M,
                        lengths: LimbLengths | None = None) -> dict[str, dict[Limb, list[str]]]:
    """Pedal object id -> foot -> its foot events there beyond :func:`foot_reach` from that foot's hip ("EVENT d m"),
    for a drummer ``height_m`` tall (``lengths``: a skeleton's legs).

    The feet are :func:`distribute`'s: each foot event's preferred foot, and with a double pedal the other foot on
    BASS, which presses the left bass pedal (:meth:`common.kit.Kit.pedal_for`)."""
    hip_at = hips(kit, height_m)
    leg_reach = foot_reach(height_m, lengths)
    out: dict[str, dict[Limb, list[str]]] = {}
    for event, spec in kit.events.items():
        if spec.pedal is None:
            continue
        feet = [spec.preferred]
        if event == EventType.BASS and kit.double_pedal:
            feet.append(Limb.LEFT_FOOT if spec.preferred == Limb.RIGHT_FOOT else Limb.RIGHT_FOOT)
        for foot in feet:
            if foot not in hip_at:  # a kit may give a foot event a hand: no leg to measure
                continue
            dist = math.dist(kit.effector_target(event, foot)[0], hip_at[foot])
            if dist > leg_reach:
                far = out.setdefault(kit.pedal_for(event, foot), {}).setdefault(foot, [])
                far.append(f"{event.value} {dist:.2f} m")
    return out
