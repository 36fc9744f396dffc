"""The physics service's score player: score control messages -> gesture plans the drummer plays live.

The Pure Data panel, ``batteur send`` or any OSC tool drive it with the score
control messages (common/messages/score.py):

* :class:`~common.messages.score.ScoreLoad` reads a score (Standard MIDI File or
  Batteur text score) from the **score library** (the node's ``--score-dir``
  directories: a name or a relative path inside one of them; an absolute path
  only if it lies inside one). A missing, unreadable or corrupted score is a
  clear error (logged, counted in ``errors`` and ``PhysicsCore.rejected``); the
  previously loaded score stays loaded.
* :class:`~common.messages.score.ScoreTransport` ``play`` plans the loaded score
  from ``position`` (seconds of the score as written) with the gesture planner
  (common.gesture: limb distribution, gesture units, co-articulated Cartesian
  trajectories) and splices the plan into the drummer's tracks so that the note
  at ``position`` sounds at rig time ``time``. A ``time`` in the past (the Pd
  panel sends 0: "at once") starts as soon as the drummer can:
  :data:`START_LEAD_S` plus a planning margin after the message. ``stop``
  brings every limb to its rest posture, ``pause`` brakes every limb and holds
  it where it is; both at rig time ``time`` (or at once).
* :class:`~common.messages.score.LiveNote` adds one note to the performance: a
  note at least :attr:`ScorePlayer.preparation_s` ahead (the shortest gesture
  unit of the database plus the splice margin: the least time a stroke can be
  prepared in) is planned with the notes around it and spliced in; a later
  one is counted in ``late_notes`` and not played (never played late or wrong).
* :class:`~common.messages.score.GestureStyle` (grip, nuance, hand algorithm,
  sticking) and :class:`~common.messages.score.TempoScale` apply to live notes
  and to the next ``play``; while a score plays, its rest is re-timed and
  re-planned from ``preparation_s`` after the message (the notes before keep
  their times). The grip is also applied to the drummer's hands at once (as
  ``/batteur/physics/grip both``).
* :class:`~common.messages.score.KitSelect` is accepted only for the kit the
  physics scene was built with: a kit change rebuilds the kit bodies and must
  reach interaction and sound too, so it is rejected with a clear error
  (restart the rig with ``--kit``).

Splicing (:func:`splice_plan`) replaces each limb's track from a rig time
``t_s`` on without a jump: the track's own position and velocity at ``t_s``
become a knot, then the plan's knots follow. Where the plan already agrees
with the track at ``t_s`` (a re-plan that only adds later notes) the plan
continues at once; where it does not, its knots in the next :data:`BLEND_S`
are dropped so that the cubic Hermite segment blends into it; a plan that
starts after ``t_s`` is joined from the track's state (braked to a stop first
when there is room). Nothing is queued (no limb changes) if a knot is out of a
limb's reach or a limb's track would pass its bound (``Track.max_knots``); a
live note is refused past :data:`MAX_PERFORMANCE_NOTES` notes.

Deterministic: no wall clock, no threads; times are the rig times the core
passes in. Planning a score takes about 0.4 ms per note on this machine, in
the handler (the live node catches up afterwards, counting skipped steps).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from common.gesture.plan import GesturePlan, Grip, LimbTrajectory, Nuance, hermite
from common.kit import EventType, Limb
from common.messages import OscMessage
from common.messages.score import GestureStyle, KitSelect, LiveNote, ScoreLoad, ScoreTransport, TempoScale
from common.score.events import MAX_SCORE_NOTES, DrumEvent, Score, ScoreError
from common.score.hands import HandAlgorithm, Sticking
from common.score.limbs import HANDS
from common.score.live import LiveNotes
from services.physics.targets import TargetError, Track

if TYPE_CHECKING:
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

log = logging.getLogger("batteur.physics.score")

SCORE_MESSAGES = (ScoreLoad, ScoreTransport, LiveNote, GestureStyle, TempoScale, KitSelect)
"""The messages :meth:`ScorePlayer.handle` takes."""

SPLICE_MARGIN_S = 0.02
"""A splice happens at least this long after the rig time of the message, seconds (the step in flight)."""
BLEND_S = 0.1
"""Where a re-plan disagrees with a limb's track, its knots within this long after the splice are dropped, s."""
BRAKE_S = 0.12
"""A moving limb is braked to a stop over this long (pause, stop, or before a plan that starts later), s."""
TRANSITION_S = 0.2
"""Least time for the limbs to move from where they are to a new performance's first knot, seconds."""
START_LEAD_S = 0.5
"""A ``play`` for a rig time already past starts this long after the message (plus the planning margin), s."""
PLAN_MARGIN_PER_NOTE_S = 0.001
"""Extra start delay per note to plan for a ``play`` "at once" (planning runs about 0.4 ms per note), s."""
CONTEXT_S = 2.0
"""A re-plan (live note) includes the notes of the last this many seconds, for co-articulation, s."""
STOP_MOVE_S = 0.5
"""``stop``: time from the braked state to the rest posture, seconds."""
STOP_LIFT_M = 0.06
"""``stop``: a stick is lifted this much while braking, so it leaves the drum it is over, metres."""
AGREE_M = 1e-3
AGREE_M_S = 0.02
"""A plan agrees with a track at the splice when positions are within ``AGREE_M`` metres and velocities
within ``AGREE_M_S`` m/s."""
POSITION_TOLERANCE_S = 1e-3
"""A note this close before a ``play`` position still plays (OSC floats are 32-bit: 1.2 arrives as 1.2000000477)."""
MAX_PERFORMANCE_NOTES = MAX_SCORE_NOTES
"""Most notes a performance holds from the re-planning context on (as many as a score may have, 500,000): a live note
past it is refused (each live note is planned with every later one, so a sender streaming notes far ahead would
grow the list and the planning without end)."""
UNKNOWN_PITCHES_KEPT = 100
"""Live notes of unknown pitch are counted; only the latest this many are kept (``live.unknown``)."""


class ScorePlayerError(ValueError):
    """A score control message the player cannot act on (the message says why)."""


def shortest_unit_period() -> float:
    """The shortest captured gesture unit's inter-onset interval, seconds (the fastest a stroke is prepared)."""
    from common.gesture.database import default_database

    return min(u.period for u in default_database().units)


def splice_plan(scene: DrummerScene, plan: GesturePlan, t_s: float, limbs: set[Limb] | None = None,
                blend_s: float = BLEND_S, brake_s: float = BRAKE_S) -> None:
    """Replace the drummer's tracks with ``plan`` from rig time ``t_s`` on, without a jump (module docstring).

    ``plan`` times are rig seconds. ``limbs``: only these limbs (default: every limb of the plan).
    Raises :class:`TargetError` (nothing queued, no track changed) when a knot after ``t_s`` is out of a limb's
    reach or a limb's track would hold more knots than its bound (``Track.max_knots``).
    """
    chosen = [(limb, traj) for limb, traj in plan.trajectories.items() if limbs is None or limb in limbs]
    for limb, traj in chosen:
        if limb.value not in scene.limb_tracks:
            raise TargetError(f"plan has unknown limb {limb.value!r}")
        later = traj.positions[traj.times > t_s]
        if len(later):  # the scene's reach check (check_cartesian), for every knot at once
            root, reach = scene.reach[limb.value]
            far = np.flatnonzero(np.linalg.norm(later - root, axis=1) > reach)
            if far.size:
                scene.check_cartesian(limb.value, later[far[0]])  # raises, with the scene's own message
    first_stroke: dict[Limb, float] = {}
    for stroke in plan.strokes:
        if stroke.time > t_s and stroke.limb not in first_stroke:
            first_stroke[stroke.limb] = stroke.time
    here: dict[str, np.ndarray] | None = None
    splices: list[_Splice] = []
    for limb, traj in chosen:  # every limb's splice worked out and checked before any track changes
        track = scene.limb_tracks[limb.value]
        if len(track):
            p0, v0 = (np.array(a, dtype=float) for a in track.sample(t_s))
        else:
            if here is None:
                here = scene.current_targets()
            p0, v0 = here[limb.value].copy(), np.zeros(3)
        splice = _splice(traj, t_s, p0, v0, first_stroke.get(limb, math.inf) - t_s, blend_s, brake_s)
        track.check_room(t_s, 1 + len(splice.bridge) + int(np.count_nonzero(splice.keep)))
        splices.append(splice)
    for (limb, traj), splice in zip(chosen, splices, strict=True):
        track = scene.limb_tracks[limb.value]
        track.add(t_s, splice.p0, splice.v0)  # cuts the track's knots at and after t_s
        for t, p in splice.bridge:
            track.add(t, p, np.zeros(3))
        keep = splice.keep
        if np.any(keep):
            _append(track, traj.times[keep], traj.positions[keep], traj.velocities[keep])
            track.add_strokes(plan.strokes_of(limb), 0.0, after=splice.cut)
    if plan.head is not None:
        scene.head = (plan.head, 0.0)


@dataclasses.dataclass(frozen=True)
class _Splice:
    """How one limb's trajectory joins its track at the splice time (see :func:`splice_plan`)."""

    p0: np.ndarray
    """The track's position (3,) m at the splice, the first knot queued."""
    v0: np.ndarray
    """... and its velocity (3,) m/s."""
    bridge: list[tuple[float, np.ndarray]]
    """Knots (rig time s, position m, at rest) between the splice and the plan: a brake before a later start."""
    keep: np.ndarray
    """Which of the trajectory's knots are queued, (N,) bool."""
    cut: float
    """Rig time (s) after which the plan's knots and strokes are queued."""


def _splice(traj: LimbTrajectory, t_s: float, p0: np.ndarray, v0: np.ndarray, room: float, blend_s: float,
            brake_s: float) -> _Splice:
    """One limb's splice at rig time ``t_s`` from the track state ``p0``, ``v0``; ``room``: seconds from ``t_s``
    to the limb's first stroke after it."""
    times, pos, vel = traj.times, traj.positions, traj.velocities
    bridge: list[tuple[float, np.ndarray]] = []
    if times[0] > t_s + 1e-6:  # the plan starts later: join its first knot, braking first when there is room
        keep = np.ones(len(times), dtype=bool)
        cut = t_s
        if times[0] - t_s > 2 * brake_s and float(np.linalg.norm(v0)) > 1e-6:
            bridge.append((t_s + brake_s, _brake_point(p0, v0, brake_s, 0.0)))
    else:
        p1, v1 = hermite(times, pos, vel, np.array([t_s]))
        agree = float(np.max(np.abs(p1[0] - p0))) <= AGREE_M and float(np.max(np.abs(v1[0] - v0))) <= AGREE_M_S
        cut = t_s + 1e-4 if agree else t_s + min(blend_s, 0.5 * room)
        keep = times > cut
    return _Splice(p0, v0, bridge, keep, cut)


def _append(track: Track, times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> None:
    """``Track.extend`` for a plan's knots in one go (checked once: finite, increasing, after the track's end; the
    caller has checked the track's room, ``Track.check_room``)."""
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(values)) and np.all(np.isfinite(velocities))):
        raise TargetError("plan knots must be finite")
    if np.any(np.diff(times) <= 0) or times[0] <= track.end_time:
        raise TargetError("plan knot times must increase and follow the splice")
    track.times.extend(float(t) for t in times)
    track.values.extend(np.array(values, dtype=float))
    track.velocities.extend(np.array(velocities, dtype=float))


def _check_room(scene: DrummerScene, t_s: float, count: int) -> None:
    """Raise :class:`TargetError` (before any track changes) if a limb's track with knots has no room for ``count``
    knots from rig time ``t_s`` seconds on (``Track.check_room``)."""
    for track in scene.limb_tracks.values():
        if len(track):
            track.check_room(t_s, count)


def _brake_point(p0: np.ndarray, v0: np.ndarray, brake_s: float, lift: float) -> np.ndarray:
    """Where a limb moving at ``v0`` from ``p0`` stops when braked evenly over ``brake_s`` (never lower), m."""
    p = p0 + v0 * brake_s / 2
    p[2] = max(p[2], p0[2]) + lift
    return p


class ScorePlayer:
    """Plays scores and live notes on a :class:`PhysicsCore`'s drummer scene (see the module docstring).

    Parameters
    ----------
    core : PhysicsCore
        The core whose scene plays (``scene="drummer"``; with the strike scene every message that would
        move the drummer is rejected).
    library : sequence of str or Path
        Score library directories: where ScoreLoad names are looked up.
    """

    def __init__(self, core: PhysicsCore, library: tuple[str | Path, ...] = ()) -> None:
        self.core = core
        self.library: list[Path] = [Path(d) for d in library]
        grip = core.settings.grip
        self.grip = Grip(grip) if grip in (g.value for g in Grip) else Grip.GERMAN
        self.nuance = Nuance.TENUTO
        self.algorithm = HandAlgorithm.VITERBI
        self.sticking = Sticking.NONE
        self.tempo = 1.0
        self.score: Score | None = None
        self.score_path: Path | None = None
        self.state: Literal["idle", "playing", "paused"] = "idle"
        self.end_time = -math.inf
        """Rig time the current performance's plan ends, seconds."""
        self.events: list[DrumEvent] = []
        """The current performance's notes in rig seconds (hands once assigned are kept: ``DrumEvent.limb``)."""
        self.mapping: tuple[float, float, float] | None = None
        """The playing score's clock: (rig time s, score position s as written, tempo factor) of one instant."""
        self._live_keys: set[tuple[float, str]] = set()
        """(rig time, event) of the live notes in ``events`` (a score re-timing leaves them where they are)."""
        self.live = LiveNotes()
        self.unknown_pitches = 0
        """Live notes whose pitch has no drum event type (not played), counted; ``live.unknown`` keeps the latest
        :data:`UNKNOWN_PITCHES_KEPT`."""
        self.late_notes = 0
        """Notes (score or live) that arrived too late to be prepared: counted and not played."""
        self.errors: Counter[str] = Counter()
        """Rejected messages per kind of problem (also logged and in ``PhysicsCore.rejected``)."""
        self.flagged = 0
        """Notes the planner flagged (dropped, moved or substituted; see the plan's issues)."""
        self.plans = 0
        """Plans spliced so far."""
        self.last_plan: GesturePlan | None = None
        self._preparation_s: float | None = None

    @property
    def preparation_s(self) -> float:
        """Least time (s) between a live note's arrival and its rig time for it to be played: the shortest
        gesture unit's period plus the splice margin (the gesture database is loaded on first use)."""
        if self._preparation_s is None:
            self._preparation_s = shortest_unit_period() + SPLICE_MARGIN_S
        return self._preparation_s

    @preparation_s.setter
    def preparation_s(self, value: float) -> None:
        self._preparation_s = float(value)

    # ------------------------------------------------------------------ messages

    def handle(self, message: OscMessage, now: float) -> None:
        """Act on one score control message at rig time ``now``; raises :class:`ScorePlayerError`
        (a ``ValueError``: the core logs and counts it) for what it cannot do."""
        try:
            self._dispatch(message, now)
        except ScoreError as exc:
            self.errors["score"] += 1
            raise ScorePlayerError(str(exc)) from None
        except ValueError as exc:
            self.errors[type(message).__name__] += 1
            raise ScorePlayerError(str(exc)) from None
        except OSError as exc:
            self.errors["score"] += 1
            raise ScorePlayerError(f"cannot read the score: {exc.strerror or exc}") from None

    def _dispatch(self, message: OscMessage, now: float) -> None:
        if isinstance(message, ScoreLoad):
            self.load(message.path)
        elif isinstance(message, ScoreTransport):
            if message.action == "play":
                self.play(message.time, message.position, now)
            elif message.action == "stop":
                self.stop(message.time, now)
            else:
                self.pause(message.time, now)
        elif isinstance(message, LiveNote):
            self.live_note(message, now)
        elif isinstance(message, GestureStyle):
            self.set_style(message.grip, message.nuance, message.algorithm, message.sticking)
            self.replan(now)
        elif isinstance(message, TempoScale):
            self.tempo = float(message.factor)
            log.info("tempo factor %g", self.tempo)
            self.replan(now)
        elif isinstance(message, KitSelect):
            self.select_kit(message.kit)

    # ------------------------------------------------------------------ score and settings

    def resolve(self, name: str) -> Path:
        """The score file ``name`` stands for, inside the score library; raises :class:`ScorePlayerError`.

        Nothing outside the library directories is opened (names are resolved, symbolic links
        included, before anything is read).
        """
        if not self.library:
            raise ScorePlayerError(f"score {name!r}: no score library on this node (start it with --score-dir DIR)")
        for root in self.library:
            base = root.expanduser().resolve()
            candidate = (base / name).resolve()
            if candidate != base and base in candidate.parents and candidate.is_file():
                return candidate
        dirs = ", ".join(str(d) for d in self.library)
        raise ScorePlayerError(f"score {name!r}: no such file in the score library ({dirs})")

    def load(self, name: str | Path, trusted: bool = False) -> Score:
        """Read a score (by library name; ``trusted``: any local path, for the command line) and keep it."""
        from common.score.text import read_score

        path = Path(name).expanduser() if trusted else self.resolve(str(name))
        if trusted and not path.is_file():
            raise ScorePlayerError(f"score {str(name)!r}: no such file")
        try:
            score = read_score(path)
        except ScoreError:
            raise
        except (OSError, ValueError, EOFError, IndexError, KeyError) as exc:  # a reader's own failure
            raise ScoreError(f"{path}: cannot read the score ({type(exc).__name__}: {exc})") from None
        if not score.events:
            raise ScoreError(f"{path}: no drum events to play")
        self.score, self.score_path = score, path
        log.info("score %s loaded: %d notes, %.2f s%s", path.name, len(score.events), score.duration,
                 f" ({'; '.join(score.warnings)})" if score.warnings else "")
        return score

    def set_style(self, grip: str, nuance: str, algorithm: str, sticking: str) -> None:
        """Planner style (and the drummer's grip, at once)."""
        self.grip, self.nuance = Grip(grip), Nuance(nuance)
        self.algorithm, self.sticking = HandAlgorithm(algorithm), Sticking(sticking)
        scene = self._maybe_drummer()
        if scene is not None:
            scene.set_grip("both", self.grip.value)
        log.info("gesture style: %s grip, %s, %s hands, sticking %s", grip, nuance, algorithm,
                 sticking)

    def select_kit(self, kit: str) -> None:
        """Accept the scene's own kit; reject any other (see the module docstring)."""
        current = {self.core.kit.name, self.core.settings.kit}
        if kit in current:
            return
        raise ScorePlayerError(f"kit {kit!r}: the physics scene was built with kit {self.core.kit.name!r}; a kit "
                               "change rebuilds the kit bodies and must reach interaction and sound too: restart the "
                               f"rig with --kit {kit}")

    # ------------------------------------------------------------------ transport

    def play(self, at: float, position: float, now: float) -> GesturePlan:
        """Play the loaded score from ``position`` (score seconds as written) with that note at rig time ``at``."""
        scene = self._drummer()
        if self.score is None:
            raise ScorePlayerError("play: no score loaded (send /batteur/score/load first)")
        score = self.score
        base = self._base(now)
        tempo = self.tempo
        remaining = [e for e in score.events if e.time >= position - POSITION_TOLERANCE_S]
        if not remaining:
            raise ScorePlayerError(f"play: nothing to play after {position:g} s (the score ends at "
                                   f"{score.duration:.3f} s)")
        if at <= base:  # "at once"
            asked = at
            at = base + START_LEAD_S + PLAN_MARGIN_PER_NOTE_S * len(remaining)
            if asked > 0.0:  # a time that has passed (0 is the panel's "at once"): say how late it starts
                log.warning("play at rig time %.3f s asked at %.3f s, already past: the score starts at %.3f s "
                            "instead (%.3f s late)", asked, base, at, at - asked)
        t_s = base + SPLICE_MARGIN_S
        earliest = t_s + TRANSITION_S + self.preparation_s - SPLICE_MARGIN_S
        events = [dataclasses.replace(e, time=at + (e.time - position) / tempo) for e in remaining]
        late = [e for e in events if e.time < earliest]
        if late:
            self.late_notes += len(late)
            log.warning("play at %.3f s: %d notes before %.3f s cannot be prepared in time; not played",
                        at, len(late), earliest)
        events = [e for e in events if e.time >= earliest]
        if not events:
            raise ScorePlayerError(f"play at {at:.3f} s: every note is too close to now ({base:.3f} s) to prepare")
        beats = np.asarray(score.beats, dtype=float)
        beats = at + (beats[beats >= position - POSITION_TOLERANCE_S] - position) / tempo
        lead_in = min(1.0, events[0].time - t_s - TRANSITION_S)
        plan = self._plan(events, beats, lead_in)
        splice_plan(scene, plan, t_s)
        self.events = self._assigned(events, plan)
        self.mapping = (at, position, tempo)
        self.state = "playing"
        self.end_time = plan.end_time
        log.info("playing %s from %.3f s at rig time %.3f s (tempo x%g): %d notes until %.3f s",
                 self.score_path.name if self.score_path else "score", position, at, tempo, len(events),
                 plan.end_time)
        return plan

    def stop(self, at: float, now: float) -> None:
        """From rig time ``at`` (or at once), brake every limb and bring it to its rest posture."""
        scene = self._drummer()
        t_s = max(at, self._base(now) + SPLICE_MARGIN_S)
        _check_room(scene, t_s, 3)
        for limb, track in scene.limb_tracks.items():
            if not len(track):
                continue
            p0, v0 = (np.array(a, dtype=float) for a in track.sample(t_s))
            hand = limb.endswith("hand")
            track.add(t_s, p0, v0)
            track.add(t_s + BRAKE_S, _brake_point(p0, v0, BRAKE_S, STOP_LIFT_M if hand else 0.0), np.zeros(3))
            if limb in scene.rest_targets:
                track.add(t_s + BRAKE_S + STOP_MOVE_S, scene.rest_targets[limb] - scene.target_offset[limb],
                          np.zeros(3))
        self._forget(t_s)
        self.state = "idle"
        self.mapping = None
        log.info("stop at %.3f s", t_s)

    def pause(self, at: float, now: float) -> None:
        """From rig time ``at`` (or at once), brake every limb and hold it there."""
        scene = self._drummer()
        t_s = max(at, self._base(now) + SPLICE_MARGIN_S)
        _check_room(scene, t_s, 2)
        for track in scene.limb_tracks.values():
            if not len(track):
                continue
            p0, v0 = (np.array(a, dtype=float) for a in track.sample(t_s))
            track.add(t_s, p0, v0)
            track.add(t_s + BRAKE_S, _brake_point(p0, v0, BRAKE_S, 0.0), np.zeros(3))
        self._forget(t_s)
        self.state = "paused"
        self.mapping = None
        log.info("pause at %.3f s", t_s)

    def replan(self, now: float) -> GesturePlan | None:
        """A playing score follows a new tempo or style from ``preparation_s`` after ``now`` on.

        The notes before that keep their times (they may already be under way); the rest of the score is
        re-timed so that the score position there stays put, re-planned with the notes around it and
        spliced in. Nothing happens when no score is playing (the settings apply to the next play).
        """
        scene = self._maybe_drummer()
        if scene is None or self.mapping is None or self.score is None or self.state != "playing":
            return None
        t_s = self._base(now) + SPLICE_MARGIN_S
        if t_s >= self.end_time:
            return None
        t_c = t_s + self.preparation_s - SPLICE_MARGIN_S
        at, position, old_tempo = self.mapping
        p_c = position + (t_c - at) * old_tempo
        tempo = self.tempo
        kept = [e for e in self.events if t_s - CONTEXT_S <= e.time < t_c]
        # split the score where the old clock reaches t_c (the same formula that timed ``events``: no note in both)
        ahead = [dataclasses.replace(e, time=t_c + (e.time - p_c) / tempo) for e in self.score.events
                 if at + (e.time - position) / old_tempo >= t_c and e.time >= position - POSITION_TOLERANCE_S]
        if not ahead:
            return None
        beats = np.asarray(self.score.beats, dtype=float)
        beats = t_c + (beats[beats >= p_c] - p_c) / tempo
        live = [e for e in self.events if e.time >= t_c and (e.time, e.event.value) in self._live_keys]
        events = sorted(kept + ahead + live, key=lambda e: e.time)
        plan = self._plan(events, beats, 1.0)
        splice_plan(scene, plan, t_s, limbs={s.limb for s in plan.strokes if s.time > t_s})
        self.events = self._assigned(events, plan)
        self.mapping = (t_c, p_c, tempo)
        self.end_time = plan.end_time
        log.info("re-planned from %.3f s (score %.3f s): tempo x%g, %s grip, %s", t_c, p_c, tempo, self.grip.value,
                 self.nuance.value)
        return plan

    def live_note(self, note: LiveNote, now: float) -> GesturePlan | None:
        """Plan one live note with the notes around it and splice it in; a late note is counted, not played."""
        scene = self._drummer()
        unknown = len(self.live.unknown)
        event = self.live.accept(note)
        if event is None:
            if len(self.live.unknown) > unknown:
                self.errors["unknown_pitch"] += 1
                self.unknown_pitches += 1
                del self.live.unknown[:-UNKNOWN_PITCHES_KEPT]  # a stream of them must not grow the list
                log.warning("live note: pitch %d has no drum event type; not played", note.pitch)
            return None
        t_s = self._base(now) + SPLICE_MARGIN_S
        if event.time - t_s < self.preparation_s - SPLICE_MARGIN_S:
            self.late_notes += 1
            if self.late_notes <= 10 or self.late_notes % 100 == 0:
                log.warning("live note %s at %.3f s arrived at %.3f s: less than %.0f ms to prepare it; not played "
                            "(%d late so far)", event.event.value, event.time, now, self.preparation_s * 1000,
                            self.late_notes)
            return None
        events = sorted([e for e in self.events if e.time >= t_s - CONTEXT_S] + [event], key=lambda e: e.time)
        if len(events) > MAX_PERFORMANCE_NOTES:
            raise ScorePlayerError(f"live note {event.event.value} at {event.time:.3f} s: the performance already "
                                   f"holds {len(events) - 1} notes, the limit of {MAX_PERFORMANCE_NOTES} "
                                   "(MAX_PERFORMANCE_NOTES); refused, the queued notes are kept")
        plan = self._plan(events, np.zeros(0), 1.0)
        moving = {s.limb for s in plan.strokes if s.time > t_s}
        if any(s.event == EventType.HIHATOPEN and s.time > t_s for s in plan.strokes) \
                and EventType.HIHATPEDAL in self.core.kit.events:
            moving.add(self.core.kit.spec(EventType.HIHATPEDAL).preferred)
        splice_plan(scene, plan, t_s, limbs=moving)
        self.events = self._assigned(events, plan)
        self._live_keys = {k for k in self._live_keys if k[0] >= t_s - CONTEXT_S} | {(event.time, event.event.value)}
        self.state = "playing"
        self.end_time = max(self.end_time, plan.end_time)
        return plan

    # ------------------------------------------------------------------ helpers

    def _drummer(self) -> DrummerScene:
        scene = self._maybe_drummer()
        if scene is None:
            raise ScorePlayerError("scores need the drummer scene (this physics node runs the strike scene)")
        return scene

    def _maybe_drummer(self) -> DrummerScene | None:
        from services.physics.drummer import DrummerScene

        scene = self.core.scene
        return scene if isinstance(scene, DrummerScene) else None

    def _base(self, now: float) -> float:
        """The later of the message's rig time and the simulation's (a splice is never in the simulated past)."""
        return max(float(now), self.core.time)

    def _plan(self, events: list[DrumEvent], beats: np.ndarray, lead_in: float) -> GesturePlan:
        """Distribute and plan rig-timed events (the planner's times are rig seconds)."""
        from common.gesture.planner import PlannerConfig, plan_gestures
        from common.score.limbs import distribute

        score = Score(events=events, beats=beats, source="performance")
        assignment = distribute(score, self.core.kit, self.algorithm, self.sticking)
        if not assignment.notes:
            raise ScorePlayerError("nothing to play: the kit has none of these notes' instruments")
        config = PlannerConfig(grip=self.grip, nuance=self.nuance, lead_in=max(lead_in, 0.05))
        try:
            plan = plan_gestures(assignment, self.core.kit, score, config)
        except Exception as exc:  # a planner failure rejects this message; it never stops the service
            log.exception("the gesture planner failed")
            raise ScorePlayerError(f"the gesture planner failed: {type(exc).__name__}: {exc}") from None
        self.flagged += len(plan.issues)
        for issue in plan.issues:
            log.info("planner: note at %.3f s (%s): %s, %s (%s)", issue.time, issue.event.value if issue.event else "-",
                     issue.reason.value, issue.action.value, issue.detail)
        self.plans += 1
        self.last_plan = plan
        return plan

    @staticmethod
    def _assigned(events: list[DrumEvent], plan: GesturePlan) -> list[DrumEvent]:
        """The events with the hand each was planned on (so a re-plan keeps it)."""
        out = list(events)
        for stroke in plan.strokes:
            if stroke.limb in HANDS and 0 <= stroke.note_index < len(out):
                out[stroke.note_index] = dataclasses.replace(out[stroke.note_index], limb=stroke.limb)
        return out

    def _forget(self, t_s: float) -> None:
        """Drop the performance's notes from ``t_s`` on (they are no longer in the tracks)."""
        self.events = [e for e in self.events if e.time < t_s]
        self.end_time = min(self.end_time, t_s)

    def reset(self) -> None:
        """The scene was reset (tracks cleared): nothing is playing any more."""
        self.events = []
        self.state = "idle"
        self.mapping = None
        self.end_time = -math.inf

    def status(self) -> dict[str, object]:
        """Counters and state, for logs and tests (a performance whose plan has ended is ``idle``)."""
        state = "idle" if self.state == "playing" and self.core.time > self.end_time else self.state
        return {"state": state, "score": str(self.score_path) if self.score_path else None,
                "late_notes": self.late_notes, "errors": dict(self.errors), "flagged": self.flagged,
                "plans": self.plans, "unknown_live_pitches": self.unknown_pitches,
                "live_duplicates": self.live.duplicates}
