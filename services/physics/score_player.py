"""The physics service's score player: score control messages -> gesture plans the drummer plays live.

The Pure Data panel, ``batteur send`` or any OSC tool drive it with the score
control messages (common/messages/score.py):

* :class:`~common.messages.score.ScoreLoad` reads a score (Standard MIDI File or
  Batteur text score) from the **score library** (the node's ``--score-dir``
  directories: a name or a relative path inside one of them; an absolute path
  only if it lies inside one). A missing, unreadable or corrupted score is a
  clear error (logged, counted in ``errors`` and ``PhysicsCore.rejected``); the
  previously loaded score stays loaded. Loaded while another score plays, it is
  for the next ``play``: the playing score plays on (said in the log; its loop
  ends as ``loop 0 0`` ends it: the pass in progress, then the rest), and a
  tempo, style or dynamics change meanwhile re-plans the playing one (a loop
  asked then is the new score's, for its play). Each score loaded plays at its
  own tempo and dynamics: the factors go back to 1 for its play, said in the
  log when they were not (the playing one keeps its own: :meth:`ScorePlayer._reset_factors`).
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
  and to the next ``play``, :class:`~common.messages.score.ScoreDynamics` (every
  score note's velocity times a factor, clipped to 1: louder or softer strokes;
  live notes keep theirs) to the next ``play``; while a score plays, its rest is
  re-timed and re-planned from ``preparation_s`` after the message (the notes
  before keep their times and velocities). The grip is also applied to the drummer's hands at once (as
  ``/batteur/physics/grip both``).
* :class:`~common.messages.score.KitSelect` is accepted only for the kit the
  physics scene was built with: a kit change rebuilds the kit bodies and must
  reach interaction and sound too, so it is rejected with a clear error
  (restart the rig with ``--kit``). For the same reason a loaded text score's
  ``kit`` line naming another kit is not applied: the score plays on the
  node's kit, and a warning in the log says so (:meth:`ScorePlayer._check_score_kit`;
  an accepted ``ScoreLoad`` gets no answer to carry it).

The **planned grip** (:attr:`ScorePlayer.grip`) starts as the hands' grip
(``PhysicsSettings.grip``) where the gesture database has it (french, german),
else german, as ``batteur render`` plans; ``GestureStyle`` changes it, and so
does loading a text score with a ``grip`` directive (its ``nuance`` directive
sets the nuance): the hands take that grip too, as with a ``GestureStyle``,
and a later ``GestureStyle`` wins.
``/batteur/physics/grip`` changes only how the hands hold the sticks (at once,
the plan in the tracks is kept, nothing is re-planned). A plan made while the
hands hold another grip than the planned one (american, traditional, or a
``/batteur/physics/grip`` since) logs a warning naming both, once (again only
after either grip changes: :meth:`ScorePlayer._check_grip`).

Splicing (services/physics/splice.py: :func:`splice_plan`) replaces each limb's track from a rig time
``t_s`` on without a jump: the track's own position and velocity at ``t_s``
become a knot, then the plan's knots follow. Where the plan already agrees
with the track at ``t_s`` (a re-plan that only adds later notes) the plan
continues at once; where it does not, its knots in the next :data:`BLEND_S`
are dropped so that the cubic Hermite segment blends into it; a plan that
starts after ``t_s`` is joined from the track's state (braked to a stop first
when there is room). Nothing is queued (no limb changes) if a knot is out of a
limb's reach or a limb's track would pass its bound (``Track.max_knots``); a
live note is refused past :data:`MAX_PERFORMANCE_NOTES` notes. Before its
splice every plan's knots beyond the body's reach (an instrument too far for
the drummer: the planner, given the node's ``height_m``, flags its notes
``unreachable``) are brought just within it (:meth:`ScorePlayer._reachable`):
those notes are missed, the rest plays, and the knots are counted
(``pulled_into_reach``) and logged once per plan.

A live note during a performance re-plans a **window** around it, not the
rest of the performance: the notes from :data:`CONTEXT_S` before the splice
to a little after the note (:meth:`ScorePlayer._window_end`). The planner is
causal per limb and keeps the hands already assigned, so each limb's window
plan meets its queued plan again (the limb that plays the note after its
next stroke); :func:`splice_window` replaces each moving limb's knots only
from ``t_s`` to that join time (:func:`join_time`: from there every knot of
both agrees, as ``splice_plan``'s "agrees" rule) and keeps the queued knots
and strikes after it. The hi-hat foot also moves when the window changes its
open-hi-hat lifts (the one part of a limb's plan made from other limbs' notes:
an open hi-hat dropped for the new note, a chain of them cut at the context's
start or at the window's end). The tracks are those a plan of the whole rest would give. A window
that does not re-join is planned again (counted in ``window_misses``): with
the window widened to the hi-hat foot's next note when only the foot's lifts
changed, else with the whole rest.

Deterministic by default: no wall clock, no threads; times are the rig times
the core passes in, and planning runs in the handler (about 0.4 ms per note).
The live node (services/physics/node.py) turns on **background plans**
(:meth:`ScorePlayer.start_background`): ``play``, style and tempo re-plans and
live notes are planned in a worker (a process of its own in the node) and
spliced in at the first step after the plan is ready, so the physics loop
never waits for the planner (docs/physics.md, "Background plans"). Every
message then takes effect in arrival order: while a plan is in flight the
messages after it wait in a FIFO (:meth:`ScorePlayer.submit`, :meth:`ScorePlayer.pump`),
and live notes waiting together are planned together; a ``/batteur/physics/reset``
does not wait: it drops the plan in flight (:meth:`ScorePlayer._drop_for_reset`) and
the next plan starts at once (its process terminated, a spare planning process takes over; a thread finishes the
dropped plan alone while a new one plans: services/physics/plan_worker.py ``PlanWorkers``); nor does a ``stop`` or
``pause`` for at once: it drops the plans it makes pointless, said in the log (:meth:`ScorePlayer._stop_at_once`).

The log says where the score is (its seconds as written, and bar and beat
counted in its own meter: :func:`common.score.position.counted_bar_beat`, as
``batteur compare`` counts) at a stop, pause or re-plan, and once a play ends
(its plan's end passed, or a stop, pause, new ``play`` or reset) how much of it
played: the notes played of those from its position on (a play that looped: the
notes played and the passes it reached), those not played by reason, and where it
ended (:meth:`ScorePlayer.say_ended`).

A ``pause`` when nothing plays and no limb moves then, or a ``stop`` of a
drummer that never moved, is refused (a :class:`ScorePlayerError`, answered to
its sender by the core); tempo and style are kept for the next ``play``.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import logging
import math
import os
import statistics
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future
from concurrent.futures import wait as wait_futures
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np

from common.gesture.plan import GesturePlan, Grip, IssueAction, IssueReason, Nuance, planned_grip
from common.gesture.planner import kick_feet
from common.gesture.reach import pull_into_reach
from common.kit import EventType, Limb, kit_file
from common.messages import OscMessage
from common.messages.physics import PhysicsReset
from common.messages.score import (
    GestureStyle,
    KitSelect,
    LiveNote,
    ScoreDynamics,
    ScoreLoad,
    ScoreLoop,
    ScoreTransport,
    TempoScale,
)
from common.score.bars import Timeline, counted_bars, loop_notes, loop_passes, looped
from common.score.events import MAX_SCORE_NOTES, DrumEvent, Score, ScoreError
from common.score.hands import HandAlgorithm, Sticking
from common.score.limbs import FEET, HANDS, LimbLengths, bass_feet
from common.score.live import LiveNotes
from common.score.position import counted_bar_beat
from services.physics.plan_worker import PlanWorker, PlanWorkers, plan_events
from services.physics.splice import (
    BLEND_S,
    BRAKE_S,
    KNOT_TIME_S,
    agrees,
    brake_point,
    check_room,
    join_time,
    plan_splices,
    splice_plan,
    splice_window,
)

if TYPE_CHECKING:
    from common.core import Outgoing
    from services.physics.core import PhysicsCore
    from services.physics.drummer import DrummerScene

log = logging.getLogger("batteur.physics.score")

SCORE_MESSAGES = (ScoreLoad, ScoreTransport, LiveNote, GestureStyle, TempoScale, ScoreDynamics, ScoreLoop, KitSelect)
"""The messages :meth:`ScorePlayer.handle` takes."""
SETTINGS_MESSAGES = (GestureStyle, TempoScale, ScoreDynamics, ScoreLoop)
"""The messages that change how the score is planned (a playing score is re-planned from shortly after them)."""

SPLICE_MARGIN_S = 0.02
"""A splice happens at least this long after the rig time of the message, seconds (the step in flight)."""
TRANSITION_S = 0.2
"""Least time for the limbs to move from where they are to a new performance's first knot, seconds."""
START_LEAD_S = 0.5
"""A ``play`` "at once" (rig time 0, the Pd panel's) starts this long after the message (plus a planning margin), s."""
LATE_START_S = 1.5
"""A ``play`` for a rig time already past starts this long after the message (plus the planning margin), s: the
transition and the whole 1 s lead-in before its first note, as on time, and room for a node's loop to start
(``batteur physics --play-at`` plans before the first step, which came 0.6 s later on a loaded machine: with
START_LEAD_S the first note was due before the simulation started, and lost)."""
PLAN_MARGIN_PER_NOTE_S = 0.001
"""Extra start delay per note to plan for a ``play`` "at once" (planning runs about 0.4 ms per note), s."""
CONTEXT_S = 2.0
"""A re-plan (live note) includes the notes of the last this many seconds, for co-articulation, s."""
WINDOW_AFTER_S = 1.0
"""A live note's plan (its window) takes the performance's notes until at least this long after the (last) new
note, and each limb's first note after the splice and after the new notes, s."""
WINDOW_MAX_S = 8.0
"""A limb's next note is looked for at most this long after the new note (a limb idle for longer keeps its
track), seconds."""
FOOT_NOTES_AFTER = 3
"""A live note's window holds this many of the bass-drum foot's notes after the new ones (other limbs': one): its
stroke after a new one is planned from the new one's speed, so it and the way to the next differ from the queued
plan's; the foot re-joins after the second (:meth:`ScorePlayer._window_end`)."""
JOIN_GUARD_S = 0.5
"""Notes past a live note's window can change a limb's plan up to this long before them (an open hi-hat lifts the
pedal 0.18 s early, a foot's cycle, a merged opening): the window's plan re-joins the queued one no later than this
long before the window's end, s."""
STOP_MOVE_S = 0.5
"""``stop``: time from the braked state to the rest posture, seconds."""
STOP_LIFT_M = 0.06
"""``stop``: a stick is lifted this much while braking, so it leaves the drum it is over, metres."""
POSITION_TOLERANCE_S = 1e-3
"""A note this close before a ``play`` position still plays (OSC floats are 32-bit: 1.2 arrives as 1.2000000477)."""
MAX_PERFORMANCE_NOTES = MAX_SCORE_NOTES
"""Most notes a performance holds from the re-planning context on (as many as a score may have, 500,000): a live note
past it is refused (a sender streaming notes far ahead would grow the list without end; a live note whose window
does not re-join is planned with all of them)."""
UNKNOWN_PITCHES_KEPT = 100
"""Live notes of unknown pitch are counted; only the latest this many are kept (``live.unknown``)."""
PLAN_OVERHEAD_S = 0.01
"""Background plans: planning time estimated for any plan on top of its notes' share, seconds."""
PLAN_PER_NOTE_S = 0.001
"""Background plans: planning time per note assumed until plans of at least :data:`PLAN_MEASURED_NOTES` notes
have been timed (about 0.4 ms alone, more while the physics loop shares the core), seconds."""
START_TEMPO = 1.0
"""The tempo factor (``/batteur/score/tempo``) a score player starts with, and each score loaded: as written."""
START_DYNAMICS = 1.0
"""The velocity factor (``/batteur/score/dynamics``) a score player starts with, and each score loaded: as
written."""
LOOP_AHEAD_S = 60.0
"""``/batteur/score/loop``: a loop's passes are planned this far ahead (rig seconds at the tempo then), then more
(:data:`LOOP_EXTEND_S`)."""
LOOP_EXTEND_S = 20.0
"""... once the passes planned end less than this long (rig seconds) after the play's position, more passes are
planned (a re-plan at the end of the pass in progress: :meth:`ScorePlayer.pump`); a third of the passes laid at once
when fewer than LOOP_AHEAD_S are (:func:`common.score.bars.loop_passes`: a tiny loop at a fast tempo)."""
START_NUANCE = Nuance.TENUTO
START_ALGORITHM = HandAlgorithm.VITERBI
START_STICKING = Sticking.NONE
"""The nuance, hand assignment and sticking a score player plans with until ``/batteur/score/style`` (or a score's
own nuance) changes them; its grip starts from the node's (``planned_grip``)."""
PLAN_MEASURED_NOTES = 20
"""Background plans: plans of at least this many notes give the per-note planning time (smaller ones are mostly
overhead: their time is kept whole, see :meth:`ScorePlayer._estimate`)."""
PLAN_SAFETY = 1.5
"""Background plans: the splice is put this many estimated planning times after the message."""
PLAN_HISTORY = 8
"""Background plans: the per-note planning time is the median of this many latest timed plans ..."""
PLAN_MIN_TIMED = 3
"""... once at least this many have been timed (the median of one or two is one of them: a single plan slowed on a
loaded core became every next plan's estimate): until then :data:`PLAN_PER_NOTE_S` (and no least time for short
plans, :meth:`ScorePlayer._estimate`)."""
CLOCKS_KEPT_S = 2.0
"""A re-plan keeps the score clocks in force from this long before the targets' clock on (:attr:`ScorePlayer._clocks`):
a stop or pause is never placed before it (the targets' clock goes back only when they fall behind, by at most
``MAX_TARGET_LAG_S``, 0.5 s), seconds."""
MAX_PLAN_RETRIES = 3
"""Background plans: a ``play`` or re-plan whose plan is ready after its splice time is planned again from the
state then, at most this many times (each with the larger estimate it measured)."""
MAX_WAITING_MESSAGES = 10_000
"""Background plans: most messages waiting behind a plan in flight; more are refused (counted in
``PhysicsCore.rejected``)."""


class ScorePlayerError(ValueError):
    """A score control message the player cannot act on (the message says why)."""


class _NothingPlaying(ScorePlayerError):
    """A stop or pause with nothing to act on (:meth:`ScorePlayer._check_playing`)."""


class _LiveOrigin(NamedTuple):
    """Where a live note of the performance came from (:attr:`ScorePlayer._live_keys`)."""

    source: str
    """Its sender, "host:port" (told if the note is dropped: :meth:`ScorePlayer.drop_skipped`)."""
    rig_time: float
    """The rig time it was sent for, seconds."""


@dataclasses.dataclass
class _Run:
    """A score's play, from its ``play`` until it ends (:meth:`ScorePlayer.say_ended`), for its summary."""

    name: str
    score: Score
    notes: int
    """Score notes from the play's position on (the planned ones and the ``late`` ones)."""
    late: int
    """... of which too close to prepare when it started (not planned)."""
    skipped: int = 0
    """Score notes the live core's targets jumped over (:meth:`ScorePlayer.drop_skipped`)."""
    cut: int = 0
    """Score notes after a stop, pause, new ``play`` or reset."""
    live: set[tuple[float, str]] = dataclasses.field(default_factory=set)
    """Keys (time on the targets' clock s, event) of the live notes played with it (not the score's)."""
    ending: str = ""
    """How it ended, when a stop, pause, new play or reset ended it (``stopped at rig 97.115 s: score ...``)."""
    cause: str = ""
    """... which of them."""
    ended_at: float = math.inf
    """... at this time on the targets' clock, s."""
    played_end: float = math.inf
    """... at this played time (s: a loop's passes laid end to end; :attr:`ScorePlayer.mapping`'s)."""
    timeline: Timeline | None = None
    """Its score as played, the latest laid (a loop's passes: the summary counts those reached)."""


def _floor1(value: float) -> str:
    """One decimal, rounded down (beat 4.96 of a 4/4 bar is ``4.9``, not the next bar's ``5.0``)."""
    return f"{math.floor(value * 10 + 1e-6) / 10:.1f}"


def score_words(score: Score, seconds: float) -> str:
    """``score 2.893 s, bar 2 beat 1.8``: score time ``seconds`` (as written, what ``/batteur/score/transport play``
    takes as its position) and its bar and beat from 1, counted in the score's own meter
    (:func:`common.score.position.counted_bar_beat`, as ``batteur compare`` counts: eighths in 6/8; beat to a tenth,
    rounded down); the seconds alone before the first beat."""
    where = counted_bar_beat(score, seconds)
    text = f"score {seconds:.3f} s"
    if where is None:
        return text
    return f"{text}, bar {where[0]} beat {_floor1(where[1])}"


class _WindowMissed(Exception):
    """A live note's window plan does not re-join the queued plan (nothing was changed): plan the window widened to
    the hi-hat foot's next note (``widen``: the window changed only the foot's open-hi-hat lifts, and the foot has
    no note in it to re-join after), else the whole rest."""

    def __init__(self, widen: bool) -> None:
        super().__init__("the window's plan does not re-join the queued plan")
        self.widen = widen


def shortest_unit_period() -> float:
    """The shortest captured gesture unit's inter-onset interval, seconds (the fastest a stroke is prepared)."""
    from common.gesture.database import default_database

    return min(u.period for u in default_database().units)


@dataclasses.dataclass(frozen=True)
class _Waiting:
    """A message waiting its turn behind a background plan (applied in arrival order)."""

    message: OscMessage
    now: float
    """Rig time it arrived, seconds."""
    source: str
    """Its sender, "host:port" (for a rejection)."""
    event: DrumEvent | None = None
    """A live note already accepted, waiting to be planned again (its first plan was ready too late for another
    note of the same plan)."""
    tries: int = 0
    """Plans of it ready too late so far (``play``, re-plans)."""
    whole: bool = False
    """A live note whose window did not re-join the queued plan: planned again with the rest of the performance."""
    widen: bool = False
    """... or with its window widened to the hi-hat foot's next note (``_WindowMissed.widen``)."""
    behind: str = ""
    """The plan in flight when it arrived (``a tempo re-plan``: :meth:`ScorePlayer._kind`), said if it waited too
    long behind it; "": none."""
    took: float = 0.0
    """A ``play`` or re-plan planned again: seconds its latest plan took (the least its next one is given)."""


@dataclasses.dataclass(frozen=True)
class _Prepared:
    """A plan's inputs, worked out from the player's state, and what to do with the plan."""

    t_s: float
    """Splice rig time, seconds."""
    events: list[DrumEvent]
    beats: np.ndarray
    lead_in: float
    commit: Callable[[GesturePlan, float], GesturePlan]
    """Splice the plan at the given rig time (s) and update the performance."""
    announce: Callable[[], None] = lambda: None
    """Count and log what the plan leaves out (run once, before ``commit``)."""
    hold: tuple[float, float] | None = None
    """(lag s, targets' clock s): placed while the live core's targets trailed the rig clock by that lag, its notes
    play until then; while its plan is in flight the targets keep that lag (:meth:`ScorePlayer.lag_floor`; dropped
    with the plan if it fails or is replaced)."""
    last_strokes: dict[Limb, float] = dataclasses.field(default_factory=dict)
    """Each foot's last note played before the plan (targets' clock, s; :meth:`ScorePlayer._last_strokes`)."""


@dataclasses.dataclass
class _Job:
    """A plan being computed in the worker."""

    requests: list[_Waiting]
    """The messages it answers (several live notes are planned together)."""
    prepared: _Prepared
    future: Future[GesturePlan]
    started: float
    """``time.perf_counter()`` at submission, seconds."""
    generation: int
    """The player's reset count then: a plan for a performance since reset is dropped."""
    finish: Callable[[_Job, GesturePlan, float], None]
    """Splice the ready plan (or plan again) at rig time ``now``, s."""
    notes: tuple[DrumEvent, ...] = ()
    """Live notes: the note of each request, in the same order."""
    pulled: dict[str, int] = dataclasses.field(default_factory=dict)
    """Once ready: its plan's knots brought within the body's reach, per limb (:meth:`ScorePlayer._reachable`)."""
    behind: Future[GesturePlan] | None = None
    """A plan dropped unread that the worker still computed when this one was submitted (:meth:`ScorePlayer._drop_job`):
    this one was computed after it, so it is timed from that one's end (:meth:`ScorePlayer._took`)."""


def _under(base: Path, path: Path) -> bool:
    """Whether resolved ``path`` is the library directory ``base`` or inside it."""
    return path == base or base in path.parents


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
        self.live = LiveNotes(kit=core.kit)  # doubles: two notes on one object of the node's kit
        self._midi: dict[str, Any] = {}
        self.grip = planned_grip(core.settings.grip)
        """The grip the gestures are planned with (see the module docstring)."""
        self._grip_warned: tuple[str, str, Grip] | None = None
        """(left hand's grip, right hand's grip, planned grip) last warned about (:meth:`_check_grip`)."""
        self.nuance = START_NUANCE
        self.algorithm = START_ALGORITHM
        self.sticking = START_STICKING
        self.tempo = START_TEMPO
        """The tempo factor the next ``play`` plans with: :data:`START_TEMPO` again at each load (:meth:`load`)."""
        self.dynamics = START_DYNAMICS
        """Every score note's velocity is this many times its written one when planned (clipped to 1), from the
        next ``play`` on: :data:`START_DYNAMICS` again at each load."""
        self._play_factors = (START_TEMPO, START_DYNAMICS)
        """(tempo, dynamics) the score playing was planned with, what its re-plans (a style change, a loop's more
        passes) keep: a score loaded since resets :attr:`tempo` and :attr:`dynamics` for its own play, not the
        playing one's (a tempo or dynamics message sets both)."""
        self.score: Score | None = None
        self.score_path: Path | None = None
        self._playing: tuple[Score, str] | None = None
        """(score, file name) of the latest ``play``: what a tempo, style, dynamics or loop re-plan re-plans while
        it plays (:meth:`load` while it plays keeps the new :attr:`score` for the next ``play``)."""
        self.loop: tuple[int, int] | None = None
        """``/batteur/score/loop``: the bars (counted from 1, first and last) looped, None: no loop."""
        self._loop_changed = False
        """The loop was changed since the playing score was last planned (its next re-plan lays the new one)."""
        self._unloop = False
        """A score was loaded while the playing one looped: the playing one's loop ends as ``loop 0 0`` ends it (the
        pass in progress, then the rest of that score), by a re-plan the load starts (:meth:`_end_playing_loop`; a
        re-plan before it lays it too). Until 7 Dec the log said the loop ended, but the passes laid played on
        (~60 s) and the play stopped at the last of them: the rest of the score never played."""
        self._timeline: Timeline | None = None
        """The play's score as played (:class:`common.score.bars.Timeline`: its loop's passes laid end to end);
        :attr:`mapping`'s score positions are its played seconds. None: the score as written."""
        self._loop_said = -math.inf
        """Played time (s) of the latest loop start, wrap or end said in the log (:meth:`_say_loop`)."""
        self._extending: Timeline | None = None
        """The timeline whose loop more passes were asked for (asked once: :meth:`_extend_loop`)."""
        self._extend_threshold: tuple[Timeline, float, float] | None = None
        """(timeline, tempo, rig seconds) of :meth:`_extend_within`, found once per timeline."""
        self.state: Literal["idle", "playing", "paused"] = "idle"
        self.end_time = -math.inf
        """Rig time the current performance's plan ends, seconds."""
        self.events: list[DrumEvent] = []
        """The current performance's notes in rig seconds (hands once assigned are kept: ``DrumEvent.limb``)."""
        self.mapping: tuple[float, float, float] | None = None
        """The playing score's clock: (rig time s, score position s as written, tempo factor) of one instant."""
        self._clocks: list[tuple[float, float, float]] = []
        """The play's clocks in force one after another (as :attr:`mapping`): the play's, then each re-plan's from its
        anchor on; a stop or pause before the latest anchor (laid ahead by the planning time) is said with the one
        sounding then (:meth:`_sounding`); those no longer in force :data:`CLOCKS_KEPT_S` before the targets' clock
        are dropped (:meth:`_clocks_since`)."""
        self._stopping: tuple[tuple[float, float, float], float] | None = None
        """A stop or pause sent ahead of its time: the score's clock before it and the rig time (s) it plays
        until (the score plays on until then, and its position is shown: :meth:`clock`)."""
        self._bass_feet: dict[float, Limb] = {}
        """A double pedal's kicks: the foot each queued BASS note is planned on (its time on the targets' clock, s,
        from :attr:`CONTEXT_S` before the last splice on), for a live window's count of each foot's notes
        (:meth:`_limbs_of`; ``DrumEvent.limb`` keeps hands only)."""
        self._live_keys: dict[tuple[float, str], _LiveOrigin] = {}
        """(time on the targets' clock s, event) of the live notes in ``events`` (a score re-timing leaves them where
        they are) -> their sender and rig time (a note the live core's targets jump over is refused to it)."""
        self.unknown_pitches = 0
        """Live notes whose pitch has no drum event type (not played), counted; ``live.unknown`` keeps the latest
        :data:`UNKNOWN_PITCHES_KEPT`."""
        self.late_notes = 0
        """Notes (score or live) not played for being late: they arrived too late to be prepared, the live core's
        targets jumped over them (``skipped_notes``), or a stop or pause acting at once dropped them before their
        plan was spliced (:meth:`_drop_live`); counted (Health's ``late``)."""
        self.skipped_notes: Counter[str] = Counter()
        """Notes ("live", "score") of the performance the live core's targets jumped over when they trailed the rig
        clock too far (:meth:`drop_skipped`): not played; also in ``late_notes``."""
        self.errors: Counter[str] = Counter()
        """Rejected messages per kind of problem (also logged and in ``PhysicsCore.rejected``)."""
        self.flagged = 0
        """Notes the planner flagged (dropped, moved or substituted; see the plan's issues)."""
        self.plans = 0
        """Plans spliced so far."""
        self.pulled_into_reach: Counter[str] = Counter()
        """Knots of the spliced plans brought within the body's reach, per limb (:meth:`_reachable`: an instrument
        too far for the drummer; its notes missed, the rest played)."""
        self.last_plan: GesturePlan | None = None
        self._preparation_s: float | None = None
        self._worker: PlanWorkers | None = None
        """Background plans: the planning worker (None: plans are computed in the handler)."""
        self._direct: Callable[[OscMessage, float, str], list[Outgoing]] | None = None
        """Background plans: the core's own handler, for the other messages that waited in the FIFO."""
        self._waiting: deque[_Waiting] = deque()
        self._job: _Job | None = None
        self._generation = 0
        self._plan_times: deque[float] = deque(maxlen=PLAN_HISTORY)
        """Seconds per note of the latest timed background plans (of at least PLAN_MEASURED_NOTES notes)."""
        self._short_plan_times: deque[tuple[int, float]] = deque(maxlen=PLAN_HISTORY)
        """(notes, seconds) of the latest timed background plans of fewer notes."""
        self._orphan: Future[GesturePlan] | None = None
        """The latest plan dropped unread that the worker goes on computing (:meth:`_drop_job`), None: none."""
        self._orphan_done = 0.0
        """``time.perf_counter()`` (s) when the latest such plan finished: the plans queued behind it started then."""
        self.replanned_late = 0
        """Background plans ready after their splice time (spliced later, planned again or counted late)."""
        self.window_misses = 0
        """Live-note windows whose plan did not re-join the queued plan: the notes planned again, with the window
        widened to the hi-hat foot's next note (only the foot's open-hi-hat lifts changed) or the whole rest."""
        self._run: _Run | None = None
        """The score's play in progress, for its summary when it ends (:meth:`say_ended`)."""
        self._dropped: dict[tuple[float, str], str] = {}
        """(time on the targets' clock s, event) -> reason, of the performance's notes the plans in the tracks do
        not play (the planner dropped or merged them, or they are out of reach), for the play's summary."""
        self._held: tuple[float, float] | None = None
        """(lag s, targets' clock s): a plan spliced while the live core's targets trailed the rig clock by that lag
        plays until then; the targets keep at least that lag until it ends (:meth:`lag_floor`; a stop, pause or
        ``play`` brings the end to what still plays: :meth:`_hold`)."""

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

    def _in_time(self, event: DrumEvent, t_s: float, slack_s: float = 0.0) -> bool:
        """True if a note spliced at rig time ``t_s`` (s) still has the time a stroke needs to be prepared: at
        least ``preparation_s`` less the splice margin (less ``slack_s``) between the splice and the note."""
        return event.time - t_s >= self.preparation_s - SPLICE_MARGIN_S - slack_s

    # ------------------------------------------------------------------ messages

    def handle(self, message: OscMessage, now: float, source: str = "") -> None:
        """Act on one score control message from ``source`` at rig time ``now``; raises :class:`ScorePlayerError`
        (a ``ValueError``: the core logs, counts and answers it) for what it cannot do."""
        try:
            self._dispatch(message, now, source)
        except (ValueError, OSError) as exc:
            raise self._counted(message, exc) from None

    def _counted(self, message: OscMessage, exc: ValueError | OSError) -> ScorePlayerError:
        """Count a failure in ``errors`` (by kind) and return the error to reject the message with."""
        if isinstance(exc, ScoreError):
            self.errors["score"] += 1
            return ScorePlayerError(str(exc))
        if isinstance(exc, ValueError):
            self.errors[type(message).__name__] += 1
            return ScorePlayerError(str(exc))
        self.errors["score"] += 1
        return ScorePlayerError(f"cannot read the score: {exc.strerror or exc}")

    def _dispatch(self, message: OscMessage, now: float, source: str = "") -> None:
        if isinstance(message, ScoreLoad):
            self.load(message.path)
            self._end_playing_loop(now)
        elif isinstance(message, ScoreTransport):
            if message.action == "play":
                self.play(message.time, message.position, now)
            elif message.action == "stop":
                self.stop(message.time, now)
            else:
                self.pause(message.time, now)
        elif isinstance(message, LiveNote):
            self.live_note(message, now, source)
        elif isinstance(message, SETTINGS_MESSAGES):
            self._apply_settings(message)
            if self._replans(message) and self.replan(now) is None:
                self._say_unplanned(message)
        elif isinstance(message, KitSelect):
            self.select_kit(message.kit)

    def _apply_settings(self, message: GestureStyle | TempoScale | ScoreDynamics | ScoreLoop) -> None:
        """A style, tempo or dynamics message's settings (the re-plan of a playing score follows)."""
        if isinstance(message, GestureStyle):
            self.set_style(message.grip, message.nuance, message.algorithm, message.sticking)
        elif isinstance(message, ScoreLoop):
            self._set_loop(message.first, message.last)
        elif isinstance(message, ScoreDynamics):
            self.dynamics = float(message.factor)
            self._play_factors = (self._play_factors[0], self.dynamics)
            log.info("dynamics: velocity factor %g (%s)", self.dynamics,
                     "as written" if self.dynamics == 1.0 else "louder" if self.dynamics > 1.0 else "softer")
        else:
            self.tempo = float(message.factor)
            self._play_factors = (self.tempo, self._play_factors[1])
            log.info("tempo factor %g", self.tempo)

    def _set_loop(self, first: int, last: int) -> None:
        """Loop counted bars ``first``..``last`` (``0 0``: off); refused without a score, for bars the score does
        not have (or its pick-up) or a first bar after the last."""
        if self.score is None:
            raise ScorePlayerError(f"loop {first} {last}: no score loaded (send /batteur/score/load first)")
        name = self.score_path.name if self.score_path else "the score"
        if first == last == 0:
            bars = None
        else:
            low, high = counted_bars(self.score)
            if first > last:
                raise ScorePlayerError(f"loop {first} {last}: the first bar is after the last (0 0 turns looping "
                                       "off)")
            if first < max(low, 1) or last > high:
                pick = " (bar 0, its pick-up, is not looped)" if low == 0 else ""
                raise ScorePlayerError(f"loop {first} {last}: bars outside the score: {name} has bars 1..{high}"
                                       f"{pick}; 0 0 turns looping off")
            bars = (first, last)
        if bars == self.loop:
            return
        was, self.loop = self.loop, bars
        self._loop_changed = True
        playing = self._plays_loaded()
        if bars is not None:
            log.info("loop bars %d-%d of %s asked%s", first, last, name,
                     "" if playing else ": it starts with the next play")
        elif was is not None:
            log.info("loop bars %d-%d off asked%s", *was, ": the pass in progress ends, then the rest of the score"
                     if playing else "")

    @property
    def playing_score(self) -> Score | None:
        """The score :meth:`clock`'s positions are in: the latest ``play``'s (a score loaded since is for the next
        one), else the loaded one."""
        return self._playing[0] if self._playing is not None else self.score

    def _plays_loaded(self) -> bool:
        """A play of the loaded score is in progress (not one of a score loaded before it: :meth:`load`)."""
        return self.state == "playing" and self._playing is not None and self._playing[0] is self.score

    def _replans(self, message: OscMessage) -> bool:
        """Whether a settings message re-plans what plays: a loop only the loaded score's play (a loop asked
        after another score was loaded is that score's, for its next ``play``)."""
        return not isinstance(message, ScoreLoop) or self._plays_loaded()

    def _clear_loop(self, why: str) -> None:
        """A stop, reset or new score ends the loop (said once)."""
        if self.loop is not None:
            log.info("loop bars %d-%d ended by the %s", *self.loop, why)
        self.loop = None
        self._loop_changed = False
        self._unloop = False
        self._loop_said = -math.inf

    def _end_playing_loop(self, now: float) -> None:
        """After a load at rig time ``now`` (s) while the playing score looped (:attr:`_unloop`): re-plan that score
        with its loop off, in the handler (background plans: :meth:`_start`). Its failure is logged, not the
        load's (the score is loaded): the passes laid play on."""
        if not self._unloop:
            return
        try:
            self.replan(now)
        except ValueError as exc:
            log.warning("the playing score's loop could not be ended: %s; its passes laid play on", exc)

    def _played(self, score: Score, timeline: Timeline | None) -> Score:
        """The score to plan: ``timeline``'s (its loop's passes laid) or ``score`` as written."""
        return timeline.played if timeline is not None else score

    def _words(self, score: Score, played: float) -> str:
        """:func:`score_words` at played time ``played`` (s: a loop's passes laid end to end), said in the written
        score."""
        timeline = self._timeline
        if timeline is not None and timeline.score is score:
            played = timeline.written(played)
        return score_words(score, played)

    @staticmethod
    def _loudness(velocity: float, factor: float) -> float:
        """A score note's velocity (0..1) played at velocity factor ``factor``: scaled, clipped to 1."""
        return velocity if factor == 1.0 else min(1.0, velocity * factor)

    # ------------------------------------------------------------------ score and settings

    def resolve(self, name: str) -> Path:
        """The score file ``name`` stands for, inside the score library; raises :class:`ScorePlayerError`.

        Nothing outside the library directories is opened (names are resolved, symbolic links
        included, before anything is read).
        """
        if not self.library:
            raise ScorePlayerError(f"score {name!r}: no score library on this node (start it with --score-dir DIR)")
        dirs = ", ".join(str(d) for d in self.library)
        if self._outside(name):  # said before looking: the refusal must not tell whether a file outside exists
            raise ScorePlayerError(f"score {name!r}: outside the score library ({dirs}): only files inside it are "
                                   "read")
        for base in self._bases():  # in library order: the first folder holding the name wins
            candidate = (base / name).resolve()
            if _under(base, candidate) and candidate.is_file():
                return candidate
            if Path(name).suffix:
                continue
            found = self._by_stem(base, name)  # "groove" for groove.txt: the file of that name, whatever its extension
            if len(found) == 1:
                return found[0]
            if found:
                names = ", ".join(sorted(p.name for p in found))
                raise ScorePlayerError(f"score {name!r}: several files in the score library match ({names}): "
                                       "give the extension")
        raise ScorePlayerError(f"score {name!r}: no such file in the score library ({dirs})")

    def _outside(self, name: str) -> bool:
        """True when ``name`` (absolute, or relative to a library directory) is outside every library directory,
        as written (``../x``: against the directory as written, or as its links lead, so ``--score-dir`` may be a
        link and an absolute name may spell either) or once resolved (a link in the library to elsewhere: against
        the directory its links lead to); whether it exists plays no part."""
        for root in self.library:
            written, base = Path(os.path.abspath(root.expanduser())), root.expanduser().resolve()
            as_written = (_under(written, Path(os.path.normpath(written / name)))
                          or _under(base, Path(os.path.normpath(base / name))))
            if as_written and _under(base, (base / name).resolve()):
                return False
        return True

    def _bases(self) -> list[Path]:
        """The library directories, links followed (what every name is judged inside)."""
        return [root.expanduser().resolve() for root in self.library]

    @staticmethod
    def _by_stem(base: Path, name: str) -> list[Path]:
        """The regular files of library directory ``base`` (resolved) named ``name`` plus any extension (listed,
        not globbed: a name may hold glob characters), resolved and still inside it."""
        folder = (base / name).parent.resolve()
        if not _under(base, folder):
            return []
        try:
            entries = list(folder.iterdir())
        except OSError:  # no such folder in this library
            return []
        found: list[Path] = []
        for entry in entries:
            target = entry.resolve()
            if (entry.stem == Path(name).name and entry.suffix and target.is_file() and _under(base, target)
                    and target not in found):
                found.append(target)
        return found

    @property
    def midi(self) -> dict[str, Any]:
        """How MIDI scores are read: :func:`common.score.midi.read_midi`'s keyword arguments (the node's
        ``--drum-channels``, ``--drum-map``, ``--hihat-cc4``: :func:`common.score.midi_options.midi_setting_kwargs`);
        a text score ignores them. Setting them gives live notes the note map too (``/batteur/score/note``'s pitches
        are read as a MIDI file's, :class:`common.score.live.LiveNotes`: until 7 Dec as General MIDI's
        whatever ``--drum-map`` said); the other two are a file's (its channels, its CC4)."""
        return self._midi

    @midi.setter
    def midi(self, kwargs: dict[str, Any]) -> None:
        self._midi = dict(kwargs)
        self.live.note_map = dict(self._midi.get("note_map") or {})

    def load(self, name: str | Path, trusted: bool = False) -> Score:
        """Read a score (by library name; ``trusted``: any local path, for the command line) and keep it."""
        from common.score.text import read_score

        path = Path(name).expanduser() if trusted else self.resolve(str(name))
        if trusted and not path.is_file():
            raise ScorePlayerError(f"score {str(name)!r}: no such file")
        try:
            score = read_score(path, kit=self.core.kit, **self.midi)  # ids and doubles: the node's kit's objects
        except ScoreError:
            raise
        except (OSError, ValueError, EOFError, IndexError, KeyError) as exc:  # a reader's own failure
            raise ScoreError(f"{path}: cannot read the score ({type(exc).__name__}: {exc})") from None
        if not score.events:
            raise ScoreError(f"{path}: no drum events to play")
        unloop = self.loop is not None and self._plays_loaded()  # the playing score's loop: it ends (said next)
        self._clear_loop("new score")
        self._unloop = self._unloop or unloop
        self.score, self.score_path = score, path
        # the score playing now plays on (a stop or pause sent ahead: until then, its clock kept for the view and
        # the log, :attr:`playing_score`; until 7 Dec that clock was dropped here, read in the loaded score's bars)
        playing = self._playing if self._mapping_at(self.core.time - self.core.target_lag) is not None else None
        log.info("score %s loaded: %d notes, %.2f s%s%s", path.name, len(score.events), score.duration,
                 f" ({'; '.join(score.warnings)})" if score.warnings else "",
                 f"; {playing[1]} plays on, {path.name} plays from the next play" if playing is not None else "")
        self._reset_factors(path.name, playing[1] if playing is not None else None)
        self._take_score_style(score, path.name)
        self._check_score_kit(score, path.name)
        return score

    def _reset_factors(self, name: str, plays_on: str | None) -> None:
        """A score loaded (file ``name``) plays at its own tempo and dynamics: the factors set before (for another
        score, or this one's previous load) go back to as written, said when they were not (``plays_on``: the score
        still playing, which keeps them). Until 8 Dec they carried over: a groove slowed to x0.5 for practice made
        the next piece loaded play at half its tempo, and the node said nothing."""
        was = [f"{what} x{value:g}" for what, value, start in (("tempo", self.tempo, START_TEMPO),
                                                                 ("dynamics", self.dynamics, START_DYNAMICS))
               if value != start]
        self.tempo, self.dynamics = START_TEMPO, START_DYNAMICS
        if was:
            kept = f"; {plays_on} plays on with them" if plays_on is not None else ""
            log.info("%s plays at its own tempo and dynamics: %s reset to x1 (as written) for its play%s; send "
                     "/batteur/score/tempo or /batteur/score/dynamics after the load to change them", name,
                     " and ".join(was), kept)

    def _take_score_style(self, score: Score, name: str) -> None:
        """A text score's ``grip`` and ``nuance`` directives become the planner's style, the grip the hands' too
        (as a ``/batteur/score/style`` would; a later one wins); what the score does not name stays."""
        grip, nuance = getattr(score, "grip", None), getattr(score, "nuance", None)
        if grip is None and nuance is None:
            return
        self.grip = grip if grip is not None else self.grip
        self.nuance = nuance if nuance is not None else self.nuance
        scene = self._maybe_drummer()
        if grip is not None and scene is not None:
            scene.set_grip("both", self.grip.value)
        log.info("score %s asks for %s: planning with the %s grip, %s", name,
                 " and ".join(f"{what} {value.value}" for what, value in (("grip", grip), ("nuance", nuance))
                              if value is not None), self.grip.value, self.nuance.value)

    def set_style(self, grip: str, nuance: str, algorithm: str, sticking: str) -> None:
        """Planner style (and the drummer's grip, at once)."""
        self.grip, self.nuance = Grip(grip), Nuance(nuance)
        self.algorithm, self.sticking = HandAlgorithm(algorithm), Sticking(sticking)
        scene = self._maybe_drummer()
        if scene is not None:
            scene.set_grip("both", self.grip.value)
        log.info("gesture style: %s grip, %s, %s hands, sticking %s", grip, nuance, algorithm,
                 sticking)

    def _check_score_kit(self, score: Score, name: str) -> None:
        """Warn when a text score's ``kit`` line names another kit than the node's: the node's kit is fixed at
        start (a kit change rebuilds the kit bodies and must reach interaction and sound too, as for
        :meth:`select_kit`), so the score plays on the node's kit, which the log says. Kits are compared as the
        files they stand for (a shipped kit's name is its file in common/kits; a relative path in the score is
        taken from the score's folder, as ``batteur render`` reads it, the node's from its working directory)."""
        from common.score.text import score_kit

        asked = score_kit(score)
        if asked is None or asked == self.core.settings.kit or kit_file(asked) == kit_file(self.core.settings.kit):
            return
        line = getattr(score, "kit_line", None)
        log.warning("score %s: %sasks for kit %r: played on this node's kit %r (the kit is fixed when the node "
                    "starts: a kit change rebuilds the kit bodies and must reach interaction and sound too); restart "
                    "the rig with --kit %s to play it on its own", name, f"line {line} " if line else "", asked,
                    self.core.settings.kit, asked)

    def select_kit(self, kit: str) -> None:
        """Accept the scene's own kit; reject any other (see the module docstring)."""
        current = {self.core.kit.name, self.core.settings.kit}
        if kit in current:
            return
        raise ScorePlayerError(f"kit {kit!r}: the physics scene was built with kit {self.core.kit.name!r}; a kit "
                               "change rebuilds the kit bodies and must reach interaction and sound too: restart the "
                               f"rig with --kit {kit}")

    # ------------------------------------------------------------------ transport

    def play(self, at: float, position: float, now: float, whole: bool = False, start_up: bool = False
             ) -> GesturePlan:
        """Play the loaded score from ``position`` (score seconds as written) with that note at rig time ``at``;
        ``whole``: if that note can no longer be prepared by then, the whole score later rather than the notes too
        close left out (a node's ``--play-at``); ``start_up``: the node's own ``--play-at``, whose time is often past
        once its scene is ready (seconds to build): a later start is said at INFO, not as a warning."""
        prepared = self._prepare_play(at, position, now, 0.0, whole, start_up)
        prepared.announce()
        return prepared.commit(self._plan(prepared.events, prepared.beats, prepared.lead_in, prepared.last_strokes),
                               prepared.t_s)

    def _prepare_play(self, at: float, position: float, now: float, delay_s: float, whole: bool = False,
                      start_up: bool = False) -> _Prepared:
        """``play``'s plan inputs; ``delay_s``: seconds the splice (and an "at once" start) moves later, the time a
        background plan is expected to take; ``whole``: a first note too close to prepare starts the whole score
        as a time already past does, instead of the notes too close being left out."""
        scene = self._drummer()
        if self.score is None:
            raise ScorePlayerError("play: no score loaded (send /batteur/score/load first)")
        score = self.score
        base = self._base(now)
        lag = self.core.target_lag
        rig_at, at = at, (at - lag if at > 0.0 else at)  # on the targets' clock (0: the panel's "at once")
        tempo, dynamics = self.tempo, self.dynamics
        bars = self.loop
        timeline = looped(Timeline.plain(score), position, bars, LOOP_AHEAD_S * tempo) if bars else None
        played = self._played(score, timeline)
        remaining = [e for e in played.events if e.time >= position - POSITION_TOLERANCE_S]
        if not remaining:
            raise ScorePlayerError(f"play: nothing to play after {position:g} s (the score ends at "
                                   f"{score.duration:.3f} s)")
        asked = None
        t_s = base + SPLICE_MARGIN_S + delay_s
        earliest = t_s + TRANSITION_S + self.preparation_s - SPLICE_MARGIN_S
        # notes that only the expected planning time (``delay_s``) would leave out: the whole score starts later
        # instead (until 7 Dec an estimate swollen by a slow plan dropped a minute of music)
        planning = delay_s > 0.0 and at > base and any(earliest - delay_s <= at + (e.time - position) / tempo
                                                       < earliest for e in remaining)
        too_close = (whole or planning) and at + (min(e.time for e in remaining) - position) / tempo < earliest
        if at <= base or too_close:  # "at once"; a time that has passed: with its whole lead-in
            asked = at
            at = (base + delay_s + (LATE_START_S if rig_at > 0.0 else START_LEAD_S)
                  + PLAN_MARGIN_PER_NOTE_S * len(remaining))
        events = [dataclasses.replace(e, time=at + (e.time - position) / tempo,
                                      velocity=self._loudness(e.velocity, dynamics)) for e in remaining]
        late = [e for e in events if e.time < earliest]

        start_level = logging.INFO if start_up else logging.WARNING  # how a later start than asked is said

        def announce() -> None:  # rig times (the targets' clock plus the lag)
            if asked is not None and asked > base:  # ``whole``: the first note too close to prepare
                log.log(start_level, "play at rig time %.3f s asked at %.3f s, too close to prepare its first note%s: "
                        "the whole score starts at %.3f s instead (%.3f s late)", rig_at, base + lag,
                        f" once planned (its plan is expected to take {delay_s:.3f} s)" if planning else "", at + lag,
                        at - asked)
            elif asked is not None and rig_at <= 0.0 and delay_s > START_LEAD_S:  # "at once", seconds later
                log.log(start_level, "play at once asked at %.3f s: its plan is expected to take %.3f s: the score "
                        "starts at %.3f s (%.3f s after the message)", base + lag, delay_s, at + lag, at - base)
            elif asked is not None and rig_at > 0.0:  # a time that has passed (0 is the panel's "at once"): how late
                log.log(start_level, "play at rig time %.3f s asked at %.3f s, already past: the score starts at "
                        "%.3f s instead (%.3f s late)", rig_at, base + lag, at + lag, at + lag - rig_at)
            if late:
                self.late_notes += len(late)
                log.warning("play at %.3f s: %d notes before %.3f s cannot be prepared in time; not played",
                            at + lag, len(late), earliest + lag)

        events = [e for e in events if e.time >= earliest]
        if not events:
            announce()
            raise ScorePlayerError(f"play at {at + lag:.3f} s: every note is too close to now ({base + lag:.3f} s) to "
                                   "prepare")
        beats = np.asarray(played.beats, dtype=float)
        beats = at + (beats[beats >= position - POSITION_TOLERANCE_S] - position) / tempo

        def commit(plan: GesturePlan, t_s: float) -> GesturePlan:
            splice_plan(scene, plan, t_s)
            self._end_run(t_s, "new play", self._said_at("replaced by a new play", t_s), at_once=True)
            self._hold(lag, plan.end_time, replace=True)  # every limb's track from t_s on is this plan's
            self._bass_feet.clear()
            self._keep_bass_feet(plan, t_s)
            self.events = self._assigned(events, plan)
            self._dropped = {}
            self._note_dropped(plan, t_s)
            self.mapping = (at, position, tempo)
            self._play_factors = (tempo, dynamics)
            self._clocks = [self.mapping]
            self._stopping = None
            self.state = "playing"
            self.end_time = plan.end_time
            name = self.score_path.name if self.score_path else "score"
            self._playing = (score, name)
            self._run = _Run(name, score, len(events) + len(late), len(late))
            louder = f", dynamics x{dynamics:g}" if dynamics != 1.0 else ""
            log.info("playing %s from %.3f s at rig time %.3f s (tempo x%g%s): %d notes until %.3f s", name, position,
                     at + lag, tempo, louder, len(events), plan.end_time + lag)
            self._lay(timeline, None, position, (at, position, tempo), lag)
            return plan

        return _Prepared(t_s, events, beats, min(1.0, events[0].time - t_s - TRANSITION_S), commit, announce,
                         self._pending(lag, events[-1].time), self._last_strokes(t_s))

    def stop(self, at: float, now: float) -> None:
        """From rig time ``at`` (or at once), brake every limb and bring it to its rest posture; refused
        (:class:`ScorePlayerError`) when nothing plays then, nothing is paused and no limb ever moved (no target
        since the start or the last reset: the drummer is at rest)."""
        scene = self._drummer()
        lag = self.core.target_lag
        t_s = max(at - lag, self._base(now) + SPLICE_MARGIN_S)  # on the targets' clock
        if self.state != "paused" and not any(len(track) for track in scene.limb_tracks.values()):
            self._check_playing("stop", t_s)  # a drummer that never moved (or was reset): nothing to bring to rest
        check_room(scene, t_s, 3)
        for limb, track in scene.limb_tracks.items():
            if not len(track):
                continue
            p0, v0 = (np.array(a, dtype=float) for a in track.sample(t_s))
            hand = limb.endswith("hand")
            track.add(t_s, p0, v0)
            track.add(t_s + BRAKE_S, brake_point(p0, v0, BRAKE_S, STOP_LIFT_M if hand else 0.0), np.zeros(3))
            if limb in scene.rest_targets:
                track.add(t_s + BRAKE_S + STOP_MOVE_S, scene.rest_targets[limb] - scene.target_offset[limb],
                          np.zeros(3))
        self._hold(lag, t_s + BRAKE_S + STOP_MOVE_S, replace=True)  # nothing of the plans plays after it
        said = self._said_at("stop", t_s)
        self._end_run(t_s, "stop", said.replace("stop at", "stopped at", 1))
        self._clear_loop("stop")
        self._forget(t_s)
        self._stop_clock()
        self.state = "idle"
        log.info("%s", said)

    def pause(self, at: float, now: float) -> None:
        """From rig time ``at`` (or at once), brake every limb and hold it there; refused
        (:class:`ScorePlayerError`) when nothing plays then and no limb moves then (streamed targets move them
        too; the state is left as it was)."""
        scene = self._drummer()
        lag = self.core.target_lag
        t_s = max(at - lag, self._base(now) + SPLICE_MARGIN_S)  # on the targets' clock
        if not any(track.end_time > t_s for track in scene.limb_tracks.values() if len(track)):
            self._check_playing("pause", t_s)  # no limb moves then, not even by streamed targets
        check_room(scene, t_s, 2)
        for track in scene.limb_tracks.values():
            if not len(track):
                continue
            p0, v0 = (np.array(a, dtype=float) for a in track.sample(t_s))
            track.add(t_s, p0, v0)
            track.add(t_s + BRAKE_S, brake_point(p0, v0, BRAKE_S, 0.0), np.zeros(3))
        self._hold(lag, t_s + BRAKE_S, replace=True)  # nothing of the plans plays after it
        said = self._said_at("pause", t_s)
        self._end_run(t_s, "pause", said.replace("pause at", "paused at", 1))
        self._forget(t_s)
        self._stop_clock()
        self.state = "paused"
        log.info("%s", said)

    def _said_at(self, action: str, t_s: float) -> str:
        """``pause at rig 74.814 s: score 2.893 s, bar 2 beat 1.8``: an action at ``t_s`` (s, the targets' clock)
        in rig time and, while a score plays then (or has a stop or pause ahead), where in the score
        (:func:`score_words`: what a ``play`` from there takes, and its bar and beat)."""
        text = f"{action} at rig {t_s + self.core.target_lag:.3f} s"
        mapping = self._mapping_at(t_s)
        if mapping is None:
            return text
        score = self.playing_score
        if score is None:
            return text
        at, position, tempo = self._sounding(t_s, mapping)
        if t_s < at:  # before the play's first note: it was to start there
            return f"{text}, before the score started (from {score_words(score, position)})"
        return f"{text}: {self._words(score, position + (t_s - at) * tempo)}"

    def where(self, t_from: float, t_to: float | None = None) -> str:
        """Where in the playing score the drummer is at ``t_from`` (s, the targets' clock), counted as a musician
        counts (:func:`common.score.position.counted_bar_beat`): ``groove.mid bar 12 beat 3.4``; with ``t_to``, the
        stretch from one to the other: ``groove.mid bar 12 beat 3.4 to bar 13 beat 1.2`` (``... to its end``: the
        play's plan ends before ``t_to``). "" while no score plays at ``t_from`` (live notes alone, idle). For the live
        warnings of physics falling behind: until 8 Dec they gave step counts alone, and a teacher could not tell
        which bars the students heard played late or skipped."""
        start = self._bar_words(t_from)
        if not start:
            return ""
        assert self._playing is not None  # a score plays: _bar_words said where
        text = f"{self._playing[1]} {start}"
        if t_to is None:
            return text
        end = self._bar_words(t_to)
        return f"{text} to {end or 'its end'}" if end != start else text

    def _bar_words(self, t_s: float) -> str:
        """``bar 12 beat 3.4`` (beat to a tenth, rounded down) of the playing score at ``t_s`` (s, the targets'
        clock), said in the written score (a loop's passes: the bars looped); ``before bar 1 beat 1.0`` before its
        play's first note; ``at score 0.120 s`` before its first beat; "" while none plays then."""
        mapping = self._mapping_at(t_s)
        score = self.playing_score
        if mapping is None or score is None or self._playing is None:
            return ""
        at, position, tempo = self._sounding(t_s, mapping)
        played = position + max(t_s - at, 0.0) * tempo
        timeline = self._timeline
        written = timeline.written(played) if timeline is not None and timeline.score is score else played
        counted = counted_bar_beat(score, written)
        if counted is None:
            return f"at score {written:.3f} s"
        words = f"bar {counted[0]} beat {_floor1(counted[1])}"
        return f"before {words}" if t_s < at else words

    def _sounding(self, t_s: float, mapping: tuple[float, float, float]) -> tuple[float, float, float]:
        """The clock of the score sounding at ``t_s`` (s, the targets' clock): ``mapping`` (the latest, as
        :meth:`_mapping_at`) from its rig time on; before it (a re-plan's anchor, laid the planning time ahead) the
        one in force then (:attr:`_clocks`: an earlier re-plan's or the play's, whose start a time before is
        before). Until 7 Dec a stop before a re-plan's anchor was said "before the score started", from the
        anchor's position."""
        if t_s >= mapping[0] or mapping not in self._clocks:
            return mapping
        earlier = [m for m in self._clocks if m[0] <= t_s]
        return earlier[-1] if earlier else self._clocks[0]

    @staticmethod
    def _clocks_since(t: float, clocks: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
        """``clocks`` (as :attr:`_clocks`, in time order) without those no longer in force at ``t`` (s, the targets'
        clock) or after: a long loop re-planned ~90 times an hour, one clock each, kept them all until 7 Dec."""
        k = bisect.bisect_right(clocks, t, key=lambda m: m[0])  # the first that starts after t
        return clocks[max(k - 1, 0):]

    def _lay(self, timeline: Timeline | None, before: Timeline | None, anchor: float,
             mapping: tuple[float, float, float], lag: float) -> None:
        """A plan from played time ``anchor`` (s) with ``timeline`` (None: the score as written; ``before``: the
        one it replaces) is spliced, the score's clock ``mapping``: keep it, and say where a loop now starts or
        ends (rig time and written bar)."""
        self._timeline, self._loop_changed, self._unloop = timeline, False, False
        if self._run is not None:
            self._run.timeline = timeline
        if before is None:  # a fresh play: its passes are said again (a second looped play said none)
            self._loop_said = -math.inf
        if timeline is None:
            return
        at, position, tempo = mapping
        score = timeline.score

        def rig(played: float) -> float:
            return at + (played - position) / tempo + lag

        passes = [seg for seg in timeline.segments if seg.loop is not None and seg.at >= anchor - 1e-9]
        if passes:
            first = passes[0]
            bars = first.loop
            assert bars is not None
            if before is not None and any(seg.loop == bars and abs(seg.at - first.at) < 1e-6
                                          for seg in before.segments):
                log.info("loop bars %d-%d: %d more passes planned, until rig %.3f s", *bars, len(passes),
                         rig(passes[-1].end))
                return
            log.info("loop bars %d-%d (%.3f s at tempo x%g): from rig %.3f s, after bar %s, back to %s; %d passes "
                     "planned, until rig %.3f s", *bars, first.length / tempo, tempo, rig(first.at),
                     self._bar_before(timeline, first.at), score_words(score, first.start), len(passes),
                     rig(passes[-1].end))
        elif before is not None and before.looping and timeline.segments[-1].at >= anchor - 1e-9:
            rest = timeline.segments[-1]
            log.info("loop off: the pass in progress ends at rig %.3f s, then the rest of the score from %s",
                     rig(rest.at), score_words(score, rest.start))

    @staticmethod
    def _bar_before(timeline: Timeline, played: float) -> str:
        """The counted bar that ends at played time ``played`` (s)."""
        where = counted_bar_beat(timeline.score, timeline.written(played - 1e-6))
        return "-" if where is None else str(where[0])

    def _say_loop(self, now: float) -> None:
        """Say in the log, once each, a loop's start, each wrap and its end the play has reached by rig time
        ``now`` (s) (the latest one only: a step never passes two)."""
        timeline, mapping = self._timeline, self.mapping
        if timeline is None or mapping is None or self.state != "playing" or not timeline.looping:
            return
        at, position, tempo = mapping
        played = position + (now - self.core.target_lag - at) * tempo
        segments = timeline.segments
        # the latest segment started by now and not said yet that starts, wraps or ends a loop: bisected, then back
        # only over those not said (at every step: a loop of tiny bars lays thousands of passes)
        k = bisect.bisect_right(segments, played + 1e-9, key=lambda seg: seg.at) - 1
        while k >= 1 and self._loop_said < segments[k].at:
            if segments[k].loop is not None or segments[k - 1].loop is not None:
                break
            k -= 1
        else:
            return
        seg, prev = segments[k], segments[k - 1]
        self._loop_said = seg.at
        rig = at + (seg.at - position) / tempo + self.core.target_lag
        if seg.loop is None:
            assert prev.loop is not None
            log.info("loop bars %d-%d ends at rig %.3f s: the play goes on at %s", *prev.loop, rig,
                     score_words(timeline.score, seg.start))
            return
        again = timeline.pass_numbers[k]
        what = "wraps" if prev.loop == seg.loop else "starts"
        log.info("loop bars %d-%d %s at rig %.3f s (pass %d): back to %s", *seg.loop, what, rig, again,
                 score_words(timeline.score, seg.start))

    def _extend_loop(self, now: float) -> None:
        """Plan more of the loop's passes once those planned end within :data:`LOOP_EXTEND_S` of rig time ``now``
        (s): a re-plan, as for a tempo change (in its turn behind the other plans); asked once per timeline."""
        timeline, mapping = self._timeline, self.mapping
        if (self.loop is None or timeline is None or mapping is None or not self._plays_loaded()
                or not timeline.looping or timeline is self._extending or self.busy):
            return
        at, position, tempo = mapping
        played = position + (now - self.core.target_lag - at) * tempo
        if (timeline.loop_end - played) / tempo > self._extend_within(timeline, tempo):
            return
        self._extending = timeline
        if self.background:
            self._waiting.append(_Waiting(ScoreLoop(first=self.loop[0], last=self.loop[1]), now, "", tries=1))
            return
        try:
            self.replan(now)
        except ValueError as exc:
            log.warning("loop bars %d-%d: more passes could not be planned: %s", *self.loop, exc)

    def _extend_within(self, timeline: Timeline, tempo: float) -> float:
        """:meth:`_extend_loop`'s threshold for ``timeline`` at ``tempo``, rig seconds (found once per timeline):
        :data:`LOOP_EXTEND_S`, or less in the share LOOP_EXTEND_S / LOOP_AHEAD_S of the passes laid at once when
        :func:`~common.score.bars.loop_passes` laid fewer than :data:`LOOP_AHEAD_S` of them (a tiny loop at a fast
        tempo: more passes then, not a re-plan at every step)."""
        cached = self._extend_threshold
        if cached is not None and cached[0] is timeline and cached[1] == tempo:
            return cached[2]
        last = timeline.last_pass
        assert last is not None
        seg = timeline.segments[last]
        assert seg.loop is not None
        laid_s = loop_passes(timeline.score, seg.loop, LOOP_AHEAD_S * tempo) * seg.length / tempo
        within = min(LOOP_EXTEND_S, LOOP_EXTEND_S / LOOP_AHEAD_S * laid_s)
        self._extend_threshold = (timeline, tempo, within)
        return within

    def _check_playing(self, action: str, t_s: float) -> None:
        """Refuse a stop or pause at ``t_s`` (s, the targets' clock: :meth:`_base`) with nothing to act on: no
        performance (score or live notes) whose plan lasts past ``t_s`` (it ended, was never started, was reset, or
        stops or pauses before). The refusal says rig times, as the stop and pause log lines do."""
        if t_s < self.end_time:
            return
        lag = self.core.target_lag
        was = {"paused": " (paused)", "idle": ""}.get(self.state,
                                                      f" (the performance ended at {self.end_time + lag:.3f} s)")
        raise _NothingPlaying(f"{action} at {t_s + lag:.3f} s: nothing is playing then{was}")

    def _stop_clock(self) -> None:
        """A stop or pause (after :meth:`_forget`): keep the playing score's clock until the plan's new end (a
        second one sent ahead only brings that end earlier)."""
        if self.state == "playing" and self.mapping is not None:
            self._stopping = (self.mapping, self.end_time)
        elif self._stopping is not None:
            self._stopping = (self._stopping[0], min(self._stopping[1], self.end_time))
        self.mapping = None

    def _mapping_at(self, t_s: float) -> tuple[float, float, float] | None:
        """The score's mapping (as :attr:`mapping`) at ``t_s`` (s, the targets' clock) if a score plays then: a playing
        score until its plan ends, or one with a stop or pause ahead until that time; None otherwise."""
        if self.state == "playing" and self.mapping is not None and t_s <= self.end_time:
            return self.mapping
        if self._stopping is not None and t_s <= self._stopping[1]:
            return self._stopping[0]
        return None

    def clock(self, now: float) -> tuple[float, float, float] | None:
        """The score's clock (as :attr:`mapping`) at rig time ``now`` (s) if a score plays then: a playing score
        until its plan ends, or one with a stop or pause ahead until that time; None otherwise."""
        lag = self.core.target_lag
        t = now - lag  # the targets' clock, which the mapping and the plan's end are on (:meth:`_base`)
        mapping = self._mapping_at(t)
        if mapping is None:
            return None
        if self._timeline is not None and self._timeline.looping:  # said in the written score, from now on
            played = mapping[1] + (t - mapping[0]) * mapping[2]
            return (now, self._timeline.written(played), mapping[2])
        return (mapping[0] + lag, mapping[1], mapping[2]) if lag > 0.0 else mapping

    def replan(self, now: float) -> GesturePlan | None:
        """A playing score follows a new tempo or style from ``preparation_s`` after ``now`` on.

        The notes before that keep their times (they may already be under way); the rest of the score is
        re-timed so that the score position there stays put, re-planned with the notes around it and
        spliced in. Nothing happens when no score is playing (the settings apply to the next play).
        """
        prepared = self._prepare_replan(now, 0.0)
        if prepared is None:
            return None
        return prepared.commit(self._plan(prepared.events, prepared.beats, prepared.lead_in, prepared.last_strokes),
                               prepared.t_s)

    def _prepare_replan(self, now: float, delay_s: float) -> _Prepared | None:
        """``replan``'s plan inputs (None: nothing to re-plan); ``delay_s``: seconds the splice moves later."""
        scene = self._maybe_drummer()
        if scene is None or self.mapping is None or self._playing is None or self.state != "playing":
            return None
        # the playing score (a score loaded since is for the next play: its notes on this clock were wrong)
        score = self._playing[0]
        base = self._base(now)  # nothing is said of a time before it, on either clock
        t_s = base + SPLICE_MARGIN_S + delay_s
        if t_s >= self.end_time:
            return None
        t_c = t_s + self.preparation_s - SPLICE_MARGIN_S
        at, position, old_tempo = self.mapping
        # the score clock's new anchor: its position at t_c, or the play's start if the score has not started
        # then (extrapolated back, the start would move: the asked position must still sound at the asked time)
        t_a = max(t_c, at)
        p_a = position + (t_a - at) * old_tempo
        tempo, dynamics = self._play_factors  # the playing score's: a score loaded since reset the next play's
        kept = [e for e in self.events if t_s - CONTEXT_S <= e.time < t_c]
        # a loop (asked, changed or on: its passes laid afresh from the anchor's pass on, at the new tempo)
        before = self._timeline if self._timeline is not None and self._timeline.score is score else None
        timeline = before
        # the loop asked is the loaded score's: after a load, the passes of the playing one laid so far stay
        # (the playing one's loop, if one was on at the load, ends: :attr:`_unloop`)
        bars, changed = (self.loop, self._loop_changed) if score is self.score else (None, self._unloop)
        if bars is not None or (changed and before is not None):
            timeline = looped(before or Timeline.plain(score), p_a, bars, LOOP_AHEAD_S * tempo)
        if timeline is not None:  # without the passes played (each extension would lay them all out again)
            timeline = timeline.since(min(position + (base - at) * old_tempo, p_a + (base - t_a) * tempo))
        played = self._played(score, timeline)
        # split the score where the old clock reaches t_c (the same formula that timed ``events``: no note in both)
        ahead = [dataclasses.replace(e, time=t_a + (e.time - p_a) / tempo,
                                     velocity=self._loudness(e.velocity, dynamics)) for e in played.events
                 if at + (e.time - position) / old_tempo >= t_c and e.time >= position - POSITION_TOLERANCE_S]
        if not ahead:
            return None
        beats = np.asarray(played.beats, dtype=float)
        beats = t_a + (beats[beats >= p_a] - p_a) / tempo
        live = [e for e in self.events if e.time >= t_c and (e.time, e.event.value) in self._live_keys]
        events = sorted(kept + ahead + live, key=lambda e: e.time)
        lag = self.core.target_lag

        def commit(plan: GesturePlan, t_s: float) -> GesturePlan:
            splice_plan(scene, plan, t_s, limbs={s.limb for s in plan.strokes if s.time > t_s})
            self._hold(lag, plan.end_time)
            self._keep_bass_feet(plan, t_s)
            if self._run is not None:  # a loop's passes laid or cut: the play's notes from t_c on change
                self._run.notes += len(ahead) - sum(1 for e in self.events if e.time >= t_c
                                                    and (e.time, e.event.value) not in self._live_keys)
            self.events = self._assigned(events, plan)
            self._note_dropped(plan, t_s)
            self.mapping = (t_a, p_a, tempo)
            self._clocks = self._clocks_since(base - CLOCKS_KEPT_S,
                                              [m for m in self._clocks if m[0] < t_a] + [self.mapping])
            self.end_time = plan.end_time
            log.info("re-planned from rig %.3f s (%s): tempo x%g, dynamics x%g, %s grip, %s", t_a + lag,
                     self._words(score, p_a), tempo, dynamics, self.grip.value, self.nuance.value)
            self._lay(timeline, before, p_a, (t_a, p_a, tempo), lag)
            return plan

        return _Prepared(t_s, events, beats, 1.0, commit, hold=self._pending(lag, events[-1].time))

    def live_note(self, note: LiveNote, now: float, source: str = "") -> GesturePlan | None:
        """Plan one live note with the notes around it and splice it in; a late note is counted, not played (and
        ``source`` told so)."""
        self._drummer()
        event = self._accept(note, source, now)
        if event is None:
            return None
        t_s = self._base(now) + SPLICE_MARGIN_S
        if not self._in_time(event, t_s):
            self._count_late(event, f"arrived at {now:.3f} s", source, now)
            return None
        whole = widen = False
        while True:  # the window, maybe widened, then the whole rest (whose commit always splices)
            prepared = self._prepare_live([event], t_s, whole, widen, (source,))
            plan, pulled = self._reachable(self._planner(prepared.events, prepared.beats, prepared.lead_in,
                                                         prepared.last_strokes)())
            try:
                plan = prepared.commit(plan, t_s)
            except _WindowMissed as missed:
                whole, widen = not missed.widen, missed.widen
                continue
            return self._account(plan, pulled)

    def _accept(self, note: LiveNote, source: str = "", now: float = 0.0) -> DrumEvent | None:
        """A live note's drum event on the targets' clock (:meth:`_base`), or None (a note-off, a double, or an
        unknown pitch: counted, logged and ``source`` told at rig time ``now``, s)."""
        unknown = len(self.live.unknown)
        event = self.live.accept(note)
        lag = self.core.target_lag
        if event is not None and lag > 0.0:  # a live core behind: the note sounds at its rig time all the same
            event = dataclasses.replace(event, time=event.time - lag)
        if event is None and len(self.live.unknown) > unknown:
            self.errors["unknown_pitch"] += 1
            self.unknown_pitches += 1
            del self.live.unknown[:-UNKNOWN_PITCHES_KEPT]  # a stream of them must not grow the list
            log.warning("live note: pitch %d has no drum event type; not played", note.pitch)
            self.core.queue_refusal(note.ADDRESS, f"live note: pitch {note.pitch} has no drum event type; not "
                                    "played", source, now)
        return event

    def _count_late(self, event: DrumEvent, why: str, source: str = "", now: float = 0.0,
                    cause: str | None = None) -> None:
        """Count a live note too late to prepare (not played), log it (the first ten, then every 100th) and tell
        ``source`` at rig time ``now`` (s): counted late (Health's ``late``), not as a rejection. ``cause``: why it
        cannot be prepared, if not for too short a lead."""
        self.late_notes += 1
        if cause is None:
            cause = f"less than {self.preparation_s * 1000:.0f} ms to prepare it"
        at = event.time + self.core.target_lag  # its rig time
        reason = f"live note {event.event.value} at {at:.3f} s {why}: {cause}; not played"
        if self.late_notes <= 10 or self.late_notes % 100 == 0:
            log.warning("%s (%d late so far)", reason, self.late_notes)
        self.core.queue_refusal(LiveNote.ADDRESS, reason, source, now)

    def drop_skipped(self, t_from: float, t_to: float, now: float) -> tuple[int, int]:
        """The live core's targets jumped from ``t_from`` to ``t_to`` (s, their clock) over the strokes between
        (``PhysicsCore._catch_up_targets``, past ``MAX_TARGET_LAG_S``): the performance's notes there are not
        played. Each is counted late (``late_notes``: Health's ``late``; ``skipped_notes`` by kind) and each live
        note's sender told why at rig time ``now`` (s), as for a note too late to prepare (a score's notes have no
        sender). Returns how many live and score notes were dropped."""
        half_step = 0.5 * self.core.world.dt  # a note at ``t_from`` was struck by the step before the jump
        first = bisect.bisect_right(self.events, t_from + half_step, key=lambda e: e.time)
        last = bisect.bisect_right(self.events, t_to + half_step, key=lambda e: e.time)
        live = score = 0
        for event in self.events[first:last]:
            key = (event.time, event.event.value)
            self._dropped.pop(key, None)  # said as skipped, once
            origin = self._live_keys.pop(key, None)
            if origin is None:
                score += 1
                continue
            live += 1
            self.core.queue_refusal(
                LiveNote.ADDRESS, f"live note {event.event.value} at {origin.rig_time:.3f} s skipped: physics fell "
                f"behind the rig clock and its targets jumped {(t_to - t_from) * 1e3:.0f} ms toward it, over the "
                "note's stroke; not played", origin.source, now)
        self.late_notes += live + score
        self.skipped_notes += Counter(live=live, score=score)  # (zeros left out)
        if self._run is not None:
            self._run.skipped += score
        return live, score

    def _prepare_live(self, new: list[DrumEvent], t_s: float, whole: bool = False, widen: bool = False,
                      sources: Sequence[str] = ()) -> _Prepared:
        """The plan inputs of live notes ``new`` (in time to be prepared) spliced at rig time ``t_s``: the notes of
        their window (:meth:`_window_end`; ``widen``: to the hi-hat foot's next note too), or with ``whole`` every
        note from the context on. The commit raises :class:`_WindowMissed` (nothing changed) when the window's plan
        does not re-join the queued one. ``sources``: each new note's sender (none: "")."""
        scene = self._drummer()
        senders = [*sources, *[""] * (len(new) - len(sources))][:len(new)]
        start = bisect.bisect_left(self.events, t_s - CONTEXT_S, key=lambda e: e.time)
        if len(self.events) - start + len(new) > MAX_PERFORMANCE_NOTES:
            event = new[-1]  # its time on the targets' clock: said as its rig time
            raise ScorePlayerError(f"live note {event.event.value} at {event.time + self.core.target_lag:.3f} s: the "
                                   f"performance already holds {len(self.events) - start} notes, the limit of "
                                   f"{MAX_PERFORMANCE_NOTES} (MAX_PERFORMANCE_NOTES); refused, the queued notes are "
                                   "kept")
        end = math.inf if whole else self._window_end(new, t_s, widen)
        stop = bisect.bisect_right(self.events, end, key=lambda e: e.time)
        later = self.events[stop:]
        events = sorted(self.events[start:stop] + new, key=lambda e: e.time)
        if not later:  # the window holds the whole rest of the performance
            end = math.inf
        lag = self.core.target_lag

        def commit(plan: GesturePlan, t_s: float) -> GesturePlan:
            moving = {s.limb for s in plan.strokes if s.time > t_s}
            # an open hi-hat lifts the pedal foot (a window's: a new one; the queued ones already do)
            opens = new if end < math.inf else [s for s in plan.strokes if s.time > t_s]
            pedal = self._pedal_foot()
            if pedal is not None and any(e.event == EventType.HIHATOPEN for e in opens):
                moving.add(pedal)
            if end == math.inf:
                splice_plan(scene, plan, t_s, limbs=moving)
            else:
                # the pedal's lifts come from the hands' open hi-hats: a window can change them without a pedal
                # note in it (an open dropped for the new note, a chain of opens cut at the context's start or at
                # the window's end, where a pedal note just past it would have cancelled the chain's lift)
                lifts = False
                if pedal is not None and pedal not in moving and pedal in plan.trajectories:
                    lifts = not agrees(scene.limb_tracks[pedal.value], plan.trajectories[pedal], t_s,
                                       end - JOIN_GUARD_S)
                    if lifts:
                        moving.add(pedal)
                joins = self._joins(scene, plan, t_s, moving, new, end - JOIN_GUARD_S, kick_feet(plan.strokes))
                if joins is None:
                    self.window_misses += 1
                    # only the pedal's lifts changed: a window past the foot's next note re-joins after it
                    wider = lifts and not widen and self._pedal_note_within(later, max(e.time for e in new))
                    log.debug("live notes at %s s: the window's plan does not re-join the queued plan by %.3f s; "
                              "planned again with %s", ", ".join(f"{e.time:.3f}" for e in new), end - JOIN_GUARD_S,
                              "its window widened to the hi-hat foot's next note" if wider else "the whole rest")
                    raise _WindowMissed(widen=wider)
                splice_window(scene, plan, t_s, joins, end - JOIN_GUARD_S)
            self._hold(lag, plan.end_time)
            self._keep_bass_feet(plan, t_s, end)
            self.events = self._assigned(events, plan) + later
            self._note_dropped(plan, t_s, end)
            if self._run is not None:
                self._run.live.update((e.time, e.event.value) for e in new)
            self._live_keys = {k: v for k, v in self._live_keys.items() if k[0] >= t_s - CONTEXT_S}
            self._live_keys.update(((e.time, e.event.value), _LiveOrigin(source, e.time + lag))
                                   for e, source in zip(new, senders, strict=True))
            self.state = "playing"
            self.end_time = max(self.end_time, plan.end_time)
            return plan

        return _Prepared(t_s, events, np.zeros(0), 1.0, commit, hold=self._pending(lag, events[-1].time))

    def _window_end(self, new: list[DrumEvent], t_s: float, widen: bool = False) -> float:
        """Rig time (s) up to which a live note's plan takes the performance's notes: :data:`WINDOW_AFTER_S` after
        the last new note, past the next note after the new notes of every limb that may take one (so that limb
        can re-join its queued plan after it) and past the first note after ``t_s`` of each limb with no note in
        the context (re-planned from its rest, as a plan of the whole rest would), plus :data:`JOIN_GUARD_S`;
        limbs are looked for at most :data:`WINDOW_MAX_S` after the last new note. ``widen``: past the hi-hat
        foot's next note too, as for an open hi-hat."""
        last = max(e.time for e in new)
        end = last + WINDOW_AFTER_S
        start = bisect.bisect_left(self.events, t_s - CONTEXT_S, key=lambda e: e.time)
        split = bisect.bisect_left(self.events, t_s, key=lambda e: e.time)
        first = set(Limb).difference(*(self._limbs_of(e) for e in self.events[start:split]))
        after_new = set().union(*(self._limbs_of(e) for e in new))
        pedal = self._pedal_foot()
        if pedal is not None and (widen or any(e.event == EventType.HIHATOPEN for e in new)):
            after_new.add(pedal)  # the pedal lifts for it
        # a kick foot's stroke is planned from the speed of its stroke before (a kick softer than the one before is
        # a smaller, deeper stroke: common/gesture/planner.py kick_feet), so the foot's next note after the new ones
        # may meet the pedal elsewhere, and the way to the note after it differs too: the foot re-joins its queued
        # plan after that second note (:meth:`_joins`), so the window holds a third. Before the plan the feet the
        # planner will take as kick feet are those that may get a BASS note (a double pedal's: either foot)
        kicking = bass_feet(self.core.kit)
        notes_after = {limb: FOOT_NOTES_AFTER if limb in kicking else 1 for limb in after_new}
        for e in self.events[split:]:
            if e.time > last + WINDOW_MAX_S or (e.time > end and not first and not notes_after):
                break
            limbs = self._limbs_of(e)
            if limbs & first or (e.time > last and limbs & notes_after.keys()):
                end = max(end, e.time)
                first -= limbs
                if e.time > last:
                    for limb in limbs & notes_after.keys():
                        notes_after[limb] -= 1
                        if not notes_after[limb]:
                            del notes_after[limb]
        return end + JOIN_GUARD_S

    def _pedal_foot(self) -> Limb | None:
        """The foot that plays the kit's hi-hat pedal (and lifts it for open hi-hats), or None."""
        if EventType.HIHATPEDAL not in self.core.kit.events:
            return None
        return self.core.kit.spec(EventType.HIHATPEDAL).preferred

    def _pedal_note_within(self, events: list[DrumEvent], last: float) -> bool:
        """Whether ``events`` (sorted) hold a note of the hi-hat foot by :data:`WINDOW_MAX_S` after ``last`` (s)."""
        pedal = self._pedal_foot()
        for e in events:
            if e.time > last + WINDOW_MAX_S:
                break
            if pedal in self._limbs_of(e):
                return True
        return False

    def _limbs_of(self, event: DrumEvent) -> set[Limb]:
        """The limb a note is played with: its hand once assigned, a pedal's foot (a double pedal's kick: either
        foot, :func:`bass_feet`), else either hand."""
        if event.limb in HANDS:
            return {event.limb}
        kit = self.core.kit
        if event.event == EventType.BASS and kit.double_pedal:  # as planned, else (a new note) either foot
            foot = self._bass_feet.get(event.time)
            return {foot} if foot is not None else bass_feet(kit)
        if event.event in (EventType.BASS, EventType.HIHATPEDAL) and event.event in kit.events:
            return {kit.spec(event.event).preferred}
        return set(HANDS)

    def _keep_bass_feet(self, plan: GesturePlan, t_s: float, until: float = math.inf) -> None:
        """Record the foot of each of ``plan``'s BASS strokes from the splice at ``t_s`` (s) on, in place of the
        record up to ``until`` (s: a window's end; the notes after it keep theirs); the record from before the
        re-planning context is dropped (:attr:`_bass_feet`)."""
        if not self.core.kit.double_pedal:  # a single pedal's kicks are all its foot's
            return
        self._bass_feet = {t: foot for t, foot in self._bass_feet.items()
                           if t_s - CONTEXT_S <= t < t_s or t > until}
        self._bass_feet.update((s.time, s.limb) for s in plan.strokes
                               if s.event == EventType.BASS and s.limb in FEET and t_s <= s.time <= until)

    @staticmethod
    def _joins(scene: DrummerScene, plan: GesturePlan, t_s: float, moving: set[Limb], new: list[DrumEvent],
               trusted: float, kick_feet: set[Limb]) -> dict[Limb, float] | None:
        """Each moving limb's join time (s): where the window's plan re-joins its queued track (:func:`join_time`)
        after the splice's blend and the new notes it plays, and no later than ``trusted`` (s; after that the
        window's plan may differ from a plan of the whole performance) nor than its last stroke in the window
        (after which the window's plan brings it to rest); None if a limb has none. ``kick_feet``: the window plan's
        own (common.gesture.planner.kick_feet)."""
        new_times = {e.time for e in new}
        joins: dict[Limb, float] = {}
        chosen = [(limb, plan.trajectories[limb]) for limb in moving if limb in plan.trajectories]
        if len(chosen) < len(moving):
            return None
        for (limb, _), splice in zip(chosen, plan_splices(scene, plan, chosen, t_s, BLEND_S, BRAKE_S), strict=True):
            strokes = [s.time for s in plan.strokes_of(limb) if s.time > t_s]
            if not strokes:  # the window's plan rests it: it cannot re-join
                return None
            played = [t for t in strokes if t in new_times]
            if played and limb in kick_feet:  # the two strokes after a new one may differ (_window_end)
                played += [t for t in strokes if t > max(played)][:FOOT_NOTES_AFTER - 1]
            after = max([splice.cut, *played])  # past any blend at the splice and the new strokes
            # after its last stroke the window's plan brings the limb to rest: join before that
            until = trusted if strokes[-1] > trusted else strokes[-1]
            t_j = join_time(scene.limb_tracks[limb.value], plan.trajectories[limb], after, until)
            if t_j is None or t_j >= until - KNOT_TIME_S:  # agreeing at the trusted span's last knot only: past it
                return None  # the queued track may be what a whole re-plan would change (a double pedal's feet)
            joins[limb] = t_j
        return joins

    # ------------------------------------------------------------------ background plans

    def start_background(self, direct: Callable[[OscMessage, float, str], list[Outgoing]],
                         worker: PlanWorker | PlanWorkers = "process") -> None:
        """Plan in a worker from now on (the live node). ``direct(message, now, source)``: the core's own handler,
        which every other message goes to, in its turn (see :meth:`submit`); ``worker``: its kind, or workers
        started already (the node starts its first process before it builds its scene)."""
        if self._worker is None:
            self._worker = worker if isinstance(worker, PlanWorkers) else PlanWorkers(worker)
        elif isinstance(worker, PlanWorkers) and worker is not self._worker:
            worker.close()  # workers of their own already: none left running unused
        self._direct = direct

    @property
    def loading(self) -> bool:
        """Background plans: the planning worker still loads the planner (live notes, ``play`` and a style or tempo
        change while a score plays are refused meanwhile, at their turn: their plans would wait for the load)."""
        return self._worker is not None and self._worker.loading

    @property
    def planner_load_error(self) -> BaseException | None:
        """Why the planning worker's load failed (None: it loads, has loaded, or there is none); the plans then go
        to a thread of the node (:meth:`PlanWorkers.submit`)."""
        return None if self._worker is None else self._worker.load_error

    def wait_loaded(self, timeout_s: float | None = None) -> bool:
        """Block until the planning worker has loaded the planner (the node, before it says it is up); True if it
        has (or there is none), False after ``timeout_s`` seconds."""
        return self._worker is None or self._worker.wait_loaded(timeout_s)

    @property
    def background(self) -> bool:
        """Plans run in a worker (:meth:`start_background`), not in the handler."""
        return self._direct is not None and self._worker is not None

    @property
    def busy(self) -> bool:
        """Background plans: a plan is in flight or messages wait behind one."""
        return self._job is not None or bool(self._waiting)

    def submit(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        """Background plans: take any message at rig time ``now`` (s), in arrival order.

        With nothing in flight or waiting, a message that plans (``play``, style, tempo, live note) starts its
        plan in the worker and any other is applied at once (``direct``); otherwise it waits its turn, so a stop
        or a target after a live note acts after that note's plan, except a reset, which drops the plan in flight
        and acts at once (:meth:`_drop_for_reset`), and a stop or pause for at once, which drops the plans it makes
        pointless and acts at once (:meth:`_stop_at_once`). While the worker loads (:attr:`loading`) a message whose
        plan would wait for the load is refused at its turn instead, its sender told why. Raises
        :class:`ScorePlayerError` past :data:`MAX_WAITING_MESSAGES` waiting (the core rejects the message).
        """
        if self._direct is None:
            raise RuntimeError("background plans are off (start_background)")
        if isinstance(message, LiveNote) and self.loading:  # planned after the load: late (seconds); said now
            self._refuse_loading(_Waiting(message, now, source), now)
            return []
        if not self.busy and not isinstance(message, SCORE_MESSAGES):
            return self._direct(message, now, source)
        if isinstance(message, PhysicsReset):  # at once: what waits for the planner is stale
            self._drop_for_reset(now)
            return self._direct(message, now, source)
        if (isinstance(message, ScoreTransport) and message.action != "play" and self.busy
                and self._overtakes(message, now)):
            self._stop_at_once(message, now, source)
            return []
        if len(self._waiting) >= MAX_WAITING_MESSAGES:
            raise ScorePlayerError(f"{len(self._waiting)} messages already wait behind the plan in flight, the "
                                   f"limit (MAX_WAITING_MESSAGES); refused")
        behind = self._kind(self._job.requests[0], flight=True) if self._job is not None else ""
        self._waiting.append(_Waiting(message, now, source, behind=behind))
        self.pump(now)
        return []

    def _overtakes(self, message: ScoreTransport, now: float) -> bool:
        """Whether a stop or pause at rig time ``now`` (s) while busy acts at once, ahead of the plans in flight and
        waiting (:meth:`_stop_at_once`): sent for at once (or a time past), or for no later than the splice of the
        plan in flight with no other plan waiting; either way nothing of those plans could play before it. A stop
        or pause sent further ahead waits its turn (a plan before it may play until then)."""
        base = self._base(now) + SPLICE_MARGIN_S
        t_s = max(message.time - self.core.target_lag, base)  # on the targets' clock, as stop() places it
        if t_s <= base:
            return True
        job = self._job
        planning = any(isinstance(w.message, (LiveNote, *SETTINGS_MESSAGES))
                       or (isinstance(w.message, ScoreTransport) and w.message.action == "play") for w in self._waiting)
        return job is not None and t_s <= job.prepared.t_s and not planning

    def _stop_at_once(self, message: ScoreTransport, now: float, source: str) -> None:
        """A stop or pause that acts at once while plans are in flight or wait (:meth:`_overtakes`): on a loaded
        machine a plan took 5-26 s, and a stop waited 20 s behind two of them. The plans it makes pointless are
        dropped and said in the log (:meth:`_drop_for_stop`), then it acts; the messages after it keep their order
        after it. Refused as always when nothing plays (:meth:`_check_playing`), unless it dropped a plan."""
        dropped = self._drop_for_stop(message.action, now)
        try:
            self._dispatch(message, now, source)
        except _NothingPlaying as exc:
            if not dropped:
                self._fail([_Waiting(message, now, source)], exc, now)
        except (ValueError, OSError) as exc:
            self._fail([_Waiting(message, now, source)], exc, now)
        except Exception as exc:  # a bug must not stop the loop (as in _start)
            log.exception("score player: %s failed", message.action)
            self._fail([_Waiting(message, now, source)], ValueError(f"{type(exc).__name__}: {exc}"), now)

    def _drop_for_stop(self, action: str, now: float) -> bool:
        """A stop or pause acting at once (rig time ``now``, s): drop what it makes pointless, said in the log, and
        return whether anything was: the plan in flight (its result never read: :meth:`_drop_job`), a waiting
        ``play``, live notes and a loop's next passes or a plan again after a late one; a waiting style, tempo,
        dynamics or loop message keeps its settings without its re-plan (for the next ``play``, as when stopped;
        a stop then ends the loop, :meth:`_clear_loop`: a loop is kept after a pause only) and any other message
        acts as it would have, in order, before the stop (a score load, a stop or pause sent ahead, a target, a
        controller change). Each live note dropped is counted late and its sender told, as for a note too late to
        prepare (:meth:`_drop_live`)."""
        job = self._drop_job()
        dropped: list[str] = []
        if job is not None:
            dropped.append(f"the {self._kind(job.requests[0], flight=True)} in flight")
            for request, note in zip(job.requests, job.notes, strict=False):  # a live-note plan's notes
                self._drop_live(request, note, action, now)
        waiting, self._waiting = list(self._waiting), deque()
        kinds: Counter[str] = Counter()
        for item in waiting:
            message = item.message
            if (item.tries or isinstance(message, LiveNote)
                    or (isinstance(message, ScoreTransport) and message.action == "play")):
                kinds[self._kind(item)] += 1
                if isinstance(message, LiveNote):
                    self._drop_live(item, item.event, action, now)
            elif isinstance(message, SETTINGS_MESSAGES):
                try:
                    self._apply_settings(message)
                except ValueError as exc:  # a loop refused (no score, bars it does not have)
                    self._fail([item], exc, now)
            else:
                self._start(item, now, plans=False)
        dropped += [f"{n} waiting {kind}{'s' if n > 1 else ''}" for kind, n in kinds.items()]
        if dropped:
            log.info("%s at rig %.3f s acts at once: %s dropped", action, now, ", ".join(dropped))
        return bool(dropped)

    def _drop_live(self, waiting: _Waiting, event: DrumEvent | None, action: str, now: float) -> None:
        """A live note dropped unplayed by a stop or pause acting at once (rig time ``now``, s): counted late
        (Health's ``late``) and its sender told, as a note too late to prepare is (:meth:`_count_late`); until 7 Dec
        only the log said so. ``event``: the note as accepted, None if it was not yet (a note-off, a double or an
        unknown pitch is handled as always: :meth:`_accept`)."""
        assert isinstance(waiting.message, LiveNote)
        if event is None:
            event = self._accept(waiting.message, waiting.source, now)
            if event is None:
                return
        self._count_late(event, f"arrived at {waiting.now:.3f} s", waiting.source, now,
                         cause=f"a {action} at rig {now:.3f} s acted at once and dropped it before it was planned")

    def _drop_job(self, reset: bool = False) -> _Job | None:
        """Drop the plan in flight (returned): its result is never read (nothing takes it, and the generation moves
        on). A plan not started yet is never computed. One being computed is abandoned
        (:meth:`PlanWorkers.abandon`: a process is terminated, a thread cannot be and finishes it alone; either
        way a new worker plans the next at once) for a ``reset``, or for a stop or pause when a worker is ready to
        plan at once (:attr:`PlanWorkers.stops_at_once`: a thread, a loaded spare process); otherwise the worker
        finishes it unused and the next plan waits for it, rather than be refused while a new process loads
        (seconds)."""
        job, self._job = self._job, None
        if job is None:
            return None
        self._generation += 1
        if job.future.cancel() or job.future.done() or self._worker is None:
            return job
        if reset or self._worker.stops_at_once:
            self._worker.abandon()
        else:  # finished unused: the next plans wait for it, and are timed from its end (not as slow plans)
            self._orphan = job.future
            job.future.add_done_callback(self._orphan_finished)
        return job

    def _orphan_finished(self, _future: Future[GesturePlan]) -> None:
        """A plan dropped unread has finished (called by the worker's thread)."""
        self._orphan_done = time.perf_counter()

    def _took(self, job: _Job) -> float:
        """Seconds ``job``'s plan took, from its submission or, queued behind a plan dropped unread, from that
        plan's end: the wait behind it is no planning time (it swelled the estimate and a plan again's least
        time, :meth:`_estimate`)."""
        started = job.started if job.behind is None else max(job.started, self._orphan_done)
        return time.perf_counter() - started

    @staticmethod
    def _kind(waiting: _Waiting, flight: bool = False) -> str:
        """What a message asks to plan, in words: ``play``, ``tempo re-plan``, ``loop extension`` (more passes),
        ``live note`` (``flight``: ``live-note plan``)."""
        message = waiting.message
        if isinstance(message, LiveNote):
            return "live-note plan" if flight else "live note"
        if isinstance(message, ScoreTransport):
            return message.action
        if isinstance(message, ScoreLoop) and waiting.tries and not waiting.source:  # _extend_loop's
            return "loop extension"
        names = {TempoScale: "tempo", GestureStyle: "style", ScoreDynamics: "dynamics", ScoreLoop: "loop",
                 ScoreLoad: "loop-off"}  # a load's: the playing score's loop ends
        return f"{names.get(type(message), type(message).__name__)} re-plan"

    def _drop_for_reset(self, now: float) -> None:
        """A reset while busy (rig time ``now``, s): drop the plan in flight (the reset clears the tracks it would
        be spliced into: :meth:`_drop_job`), then act on the messages that waited behind it, in order, without
        planning: a transport message or live note is dropped with the plan (the reset leaves nothing playing), a
        style or tempo keeps its settings, any other message acts as it would have (a controller change stays;
        targets are cleared by the reset)."""
        job = self._drop_job(reset=True)
        waiting, self._waiting = list(self._waiting), deque()
        dropped = 0
        for item in waiting:
            message = item.message
            if isinstance(message, (ScoreTransport, LiveNote)):
                dropped += 1
            elif isinstance(message, SETTINGS_MESSAGES):
                if item.tries == 0:  # a retry's settings were applied when it first started
                    try:
                        self._apply_settings(message)
                    except ValueError as exc:  # a loop refused (no score, bars it does not have)
                        self._fail([item], exc, now)
            else:
                self._start(item, now, plans=False)  # a score load, a kit, a target, a controller change ...
        log.info("reset at %.3f s: the plan in flight (%d message(s)) and %d waiting transport message(s) or live "
                 "note(s) dropped", now, len(job.requests) if job is not None else 0, dropped)

    def pump(self, now: float) -> None:
        """Background plans, at every step and message (rig time ``now``, s): splice the plan that is ready, then
        act on the messages waiting, in order, until one starts a plan. Never raises: failures are counted and
        logged as the handler's are (``errors``, ``PhysicsCore.rejected``); says a play that has ended
        (:meth:`say_ended`)."""
        self._say_loop(now)
        self._extend_loop(now)
        self.say_ended(now)
        while True:
            job = self._job
            if job is not None:
                if not job.future.done():
                    return
                self._job = None
                self._finish(job, now)
                continue
            if not self._waiting:
                if self._worker is not None:
                    self._worker.idle()
                return
            self._start(self._waiting.popleft(), now)

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until the plan in flight is ready (tests and benchmarks; the node never waits); True if it is
        (or there is none), False after ``timeout_s`` seconds. The next :meth:`pump` splices it."""
        job = self._job
        if job is None:
            return True
        done, _ = wait_futures([job.future], timeout=timeout_s)
        return bool(done)

    def close(self) -> None:
        """Stop the planning worker (a process is terminated): a plan in flight is abandoned (nothing waits for
        it), waiting messages dropped; from then on plans run in the handler."""
        worker, self._worker = self._worker, None
        self._job = None
        self._waiting.clear()
        self._generation += 1
        if worker is not None:
            worker.close()

    def _start(self, waiting: _Waiting, now: float, plans: bool = True) -> None:
        """Act on one waiting message: start its plan in the worker, or apply it at once (``plans`` False: a
        message that does not plan, acting before a stop or reset: a load does not end the playing score's loop by
        a re-plan, as the stop or reset ends it)."""
        message = waiting.message
        try:
            if isinstance(message, ScoreLoad):
                if waiting.tries == 0:  # a retry only plans again
                    self.load(message.path)
                if plans and self._unloop:  # the playing score's loop ends: a re-plan, in the worker
                    self._start_replan(waiting, now)
            elif isinstance(message, LiveNote):
                self._start_live(waiting, now)
            elif isinstance(message, ScoreTransport) and message.action == "play":
                self._start_play(waiting, now)
            elif isinstance(message, SETTINGS_MESSAGES):
                if waiting.tries == 0:  # a retry only plans again
                    if self.loading and self._prepare_replan(now, 0.0) is not None:
                        # its re-plan would wait for the load, and every message after it (a stop) behind that
                        raise self._still_loading("a score plays and its re-plan would start seconds late; not "
                                                  "applied")
                    self._apply_settings(message)  # nothing playing: applied at once, no plan to wait for
                if waiting.tries or self._replans(message):
                    self._start_replan(waiting, now)
            elif isinstance(message, SCORE_MESSAGES):
                self._dispatch(message, now)
            else:
                assert self._direct is not None
                self._direct(message, now, waiting.source)  # the core counts and logs its own rejections
        except (ValueError, OSError) as exc:
            self._fail([waiting], exc, now)
        except Exception as exc:  # a bug must not stop the loop or lose the messages after it
            log.exception("score player: %s failed", type(message).__name__)
            self._fail([waiting], ValueError(f"{type(exc).__name__}: {exc}"), now)

    def _fail(self, requests: list[_Waiting], exc: ValueError | OSError, now: float) -> None:
        """Count and log each request as rejected, as the handler would (``errors``, ``PhysicsCore.rejected``)."""
        for waiting in requests:
            error = self._counted(waiting.message, exc)
            self.core.reject(waiting.message, waiting.source, error, now)

    def _estimate(self, notes: int, took: float = 0.0) -> float:
        """Seconds a background plan of ``notes`` notes is expected to take (from the latest timed plans): the
        overhead plus the median per-note time of the plans of :data:`PLAN_MEASURED_NOTES` notes or more, and at
        least the median time of the plans of no more notes (a short score under load: its own plan's time, mostly
        overhead, which a per-note share would make too long for a long plan), and at least ``took`` (s: the time
        this message's own plan took, when it is planned again), times :data:`PLAN_SAFETY`. Medians, not the
        slowest (until 7 Dec): one plan slowed 50-fold on a loaded core made the next 8 wait seconds each, and a
        ``play`` started a minute late. Either median only once :data:`PLAN_MIN_TIMED` plans give it."""
        timed = len(self._plan_times) >= PLAN_MIN_TIMED
        per_note = statistics.median(self._plan_times) if timed else PLAN_PER_NOTE_S
        shorter = [t for n, t in self._short_plan_times if n <= notes]
        short = statistics.median(shorter) if len(shorter) >= PLAN_MIN_TIMED else 0.0
        return PLAN_SAFETY * max(PLAN_OVERHEAD_S + per_note * notes, short, took)

    def _submit(self, requests: list[_Waiting], prepared: _Prepared,
                finish: Callable[[_Job, GesturePlan, float], None], notes: tuple[DrumEvent, ...] = ()) -> None:
        assert self._worker is not None
        future = self._worker.submit(self._planner(prepared.events, prepared.beats, prepared.lead_in,
                                                   prepared.last_strokes))
        orphan = self._orphan
        if orphan is not None and orphan.done():
            orphan = self._orphan = None  # finished: its unread plan let go
        self._job = _Job(requests, prepared, future, time.perf_counter(), self._generation, finish, notes,
                         behind=orphan)

    def _still_loading(self, what: str) -> ScorePlayerError:
        """The refusal of a message whose plan would wait for the planning worker's load (``what``: what becomes
        of it): planned after the load, seconds later, it would start late, and the messages after it would wait
        behind it (a live note meanwhile: :meth:`_refuse_loading`)."""
        assert self._worker is not None
        return ScorePlayerError(f"the planning process is still loading the planner ({self._worker.loading_s:.1f} s "
                                f"so far): {what}; send it again once it has loaded (seconds)")

    def _start_play(self, waiting: _Waiting, now: float) -> None:
        assert isinstance(waiting.message, ScoreTransport)
        if self.loading:  # the score would start seconds after its time: refused now, its sender told why
            raise self._still_loading("not played")
        notes = len(self.score.events) if self.score is not None else 0
        # planned again (its plan was ready too late): the whole score later rather than its first notes left out
        prepared = self._prepare_play(waiting.message.time, waiting.message.position, now,
                                      self._estimate(notes, waiting.took),
                                      whole=waiting.tries > 0)
        self._submit([waiting], prepared, self._finish_whole)

    def _start_replan(self, waiting: _Waiting, now: float) -> None:
        prepared = self._prepare_replan(now, self._estimate(len(self.events), waiting.took))
        if prepared is not None:
            self._submit([waiting], prepared, self._finish_whole)
        else:
            self._say_unplanned(waiting.message, waiting.tries > 0 and not waiting.source)

    def _say_unplanned(self, message: OscMessage, extension: bool = False) -> None:
        """A settings message's re-plan found nothing left to re-plan although a play was on (its plan ends before
        the re-plan's splice, or has no note after it): say so, rather than let a loop asked near the end vanish
        (``extension``: :meth:`_extend_loop`'s more passes, said at DEBUG). Nothing is said with nothing playing
        (the settings are for the next ``play``, said when they were applied)."""
        if self.state != "playing" or self._playing is None or isinstance(message, ScoreLoad):
            return  # a load's loop off: the play ends before the loop would
        if extension:
            log.debug("loop: no more passes planned: the play ends before them")
            return
        what = (f"loop bars {message.first}-{message.last}" if isinstance(message, ScoreLoop) and message.first
                else "loop off" if isinstance(message, ScoreLoop) else self._kind(_Waiting(message, 0.0, "")))
        log.info("%s: the play of %s ends (its plan at rig %.3f s) before it could be laid; it applies to the next "
                 "play", what, self._playing[1], self.end_time + self.core.target_lag)

    def _refuse_loading(self, waiting: _Waiting, now: float) -> None:
        """A live note while the planning worker still loads: not played, counted late (Health's ``late``) and its
        sender told why at once (planned after the load, seconds later, it would be late anyway); a note-off, a
        double or an unknown pitch is handled as always (:meth:`_accept`)."""
        assert isinstance(waiting.message, LiveNote) and self._worker is not None
        try:
            self._drummer()
            event = waiting.event if waiting.event is not None else self._accept(waiting.message, waiting.source, now)
        except ValueError as exc:
            self._fail([waiting], exc, now)
            return
        if event is not None:
            self._count_late(event, f"arrived at {waiting.now:.3f} s", waiting.source, now,
                             cause=f"the planning process is still loading the planner ({self._worker.loading_s:.1f} "
                             "s so far)")

    def _start_live(self, waiting: _Waiting, now: float) -> None:
        """Plan this live note and the live notes waiting right after it together (refused while the planning
        worker loads: :meth:`_refuse_loading`)."""
        batch = [waiting]
        while self._waiting and isinstance(self._waiting[0].message, LiveNote):
            batch.append(self._waiting.popleft())
        if self.loading:
            for item in batch:
                self._refuse_loading(item, now)
            return
        t0 = self._base(now) + SPLICE_MARGIN_S
        accepted: list[tuple[_Waiting, DrumEvent]] = []
        for item in batch:
            assert isinstance(item.message, LiveNote)
            try:
                self._drummer()
                event = item.event if item.event is not None else self._accept(item.message, item.source, now)
            except ValueError as exc:
                self._fail([item], exc, now)
                continue
            if event is None:
                continue
            if not self._in_time(event, t0):
                waited = ""
                if now > item.now:  # behind another plan (in order: a note never overtakes the plans before it)
                    waited = f", its turn came at {now:.3f} s"
                    if item.behind:
                        waited = (f", waited {now - item.now:.1f} s behind a {item.behind} (its turn came at "
                                  f"{now:.3f} s)")
                self._count_late(event, f"arrived at {item.now:.3f} s{waited}", item.source, now)
                continue
            accepted.append((item, event))
        if not accepted:
            return
        requests, new = [a[0] for a in accepted], [a[1] for a in accepted]
        whole = any(item.whole for item, _ in accepted)
        widen = any(item.widen for item, _ in accepted)
        latest = min(e.time for e in new) - (self.preparation_s - SPLICE_MARGIN_S)
        end = math.inf if whole else self._window_end(new, t0, widen)
        context = sum(1 for e in self.events if t0 - CONTEXT_S <= e.time <= end)
        t_s = max(t0, min(t0 + self._estimate(context + len(new)), latest))
        try:
            prepared = self._prepare_live(new, t_s, whole, widen, [item.source for item in requests])
        except ValueError as exc:
            self._fail(requests, exc, now)
            return
        self._submit(requests, prepared, self._finish_live, tuple(new))

    def _finish(self, job: _Job, now: float) -> None:
        """A plan is ready (at rig time ``now``, s): splice it, plan again, or reject its messages."""
        if job.generation != self._generation:
            log.info("a plan for %d message(s) was ready after a reset: dropped", len(job.requests))
            return
        try:
            plan, job.pulled = self._reachable(job.future.result())
            notes, took = len(job.prepared.events), self._took(job)
            if notes >= PLAN_MEASURED_NOTES:
                self._plan_times.append(took / notes)
            else:
                self._short_plan_times.append((notes, took))
            job.finish(job, plan, now)
        except (ValueError, OSError) as exc:  # the planner's and the splice's errors, as in the handler
            self._fail(job.requests, exc, now)
        except Exception as exc:  # a bug must not stop the loop or lose the messages after it
            log.exception("score player: applying a plan failed")
            self._fail(job.requests, ValueError(f"{type(exc).__name__}: {exc}"), now)

    def _finish_whole(self, job: _Job, plan: GesturePlan, now: float) -> None:
        """``play`` or a re-plan: splice at the chosen time, or plan again from now if that has passed."""
        waiting, prepared = job.requests[0], job.prepared
        if self._base(now) + SPLICE_MARGIN_S > prepared.t_s:
            self.replanned_late += 1
            took = self._took(job)
            if waiting.tries >= MAX_PLAN_RETRIES:
                raise ScorePlayerError(f"its plan took {took:.3f} s and was ready after its splice time "
                                       f"({prepared.t_s:.3f} s, now {now:.3f} s) {waiting.tries + 1} times; "
                                       "not played")
            log.warning("%s: its plan took %.3f s and was ready after its splice time (%.3f s, now %.3f s): "
                        "planned again", type(waiting.message).__name__, took, prepared.t_s, now)
            self._waiting.appendleft(dataclasses.replace(waiting, tries=waiting.tries + 1, took=took))
            return
        prepared.announce()
        prepared.commit(self._account(plan, job.pulled), prepared.t_s)

    def _finish_live(self, job: _Job, plan: GesturePlan, now: float) -> None:
        """Live notes: splice at the chosen time or, if that has passed, at the next step when every note still
        has its preparation time; notes that no longer have it are counted late and the others planned again."""
        prepared = job.prepared
        t_s = max(prepared.t_s, self._base(now) + SPLICE_MARGIN_S)
        pairs = list(zip(job.requests, job.notes, strict=True))
        in_time = [self._in_time(e, t_s, 1e-9) for _, e in pairs]  # t_s may be the latest (_start_live)
        if t_s > prepared.t_s:
            self.replanned_late += 1
        if not all(in_time):
            took = self._took(job)
            for (waiting, event), ok in zip(pairs, in_time, strict=True):
                if not ok:
                    self._count_late(event, f"was planned by {now:.3f} s (planning took {took:.3f} s)",
                                     waiting.source, now)
            rest = [dataclasses.replace(w, event=e) for (w, e), ok in zip(pairs, in_time, strict=True) if ok]
            self._waiting.extendleft(reversed(rest))
            return
        if t_s > prepared.t_s:
            log.info("live notes: plan ready after its splice time %.3f s: spliced at %.3f s", prepared.t_s, t_s)
        try:
            prepared.commit(plan, t_s)
        except _WindowMissed as missed:  # plan them again: a widened window, or with the rest of the performance
            self._waiting.extendleft(reversed([dataclasses.replace(w, event=e, whole=not missed.widen,
                                                                   widen=missed.widen) for w, e in pairs]))
            return
        self._account(plan, job.pulled)

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
        """The later of the message's rig time and the simulation's (a splice is never in the simulated past), on
        the clock of the drummer's targets: a live core that fell behind has them trail the rig clock by
        ``PhysicsCore.target_lag`` seconds, so the player places its splices and notes (and keeps its notes, score
        clock and plan end) that much earlier on their clock and they sound at their rig times; offline the two
        clocks are one."""
        return max(float(now), self.core.time) - self.core.target_lag

    def _hold(self, lag: float, until: float, replace: bool = False) -> None:
        """A plan, stop or pause placed ``lag`` seconds early on the targets' clock (:meth:`_base`) plays until
        ``until`` (s, their clock): the targets must keep that lag until then, or its notes would sound early
        (:meth:`lag_floor`). ``replace``: what was placed before plays no longer after it (a stop or pause brakes
        every limb, a ``play`` replaces every limb's track): the hold ends with it, not with the plan it cut."""
        if replace:
            self._held = None
        if lag <= 0.0:
            return
        if self._held is not None:
            until = max(until, self._held[1])
        self._held = (lag, until)

    @staticmethod
    def _pending(lag: float, until: float) -> tuple[float, float] | None:
        """A plan's hold while it is in flight (:attr:`_Prepared.hold`): its notes placed ``lag`` s early until
        ``until`` (s, the targets' clock); None when the targets do not trail."""
        return (lag, until) if lag > 0.0 else None

    def lag_floor(self, t: float) -> float:
        """The least lag (s) the live core's targets may jump back to at their clock's time ``t`` (s): the lag the
        plans still playing were placed with (:meth:`_hold`; the latest one's) or, while a background plan is in
        flight, its own (:attr:`_Prepared.hold`: a plan that fails or is replaced holds nothing), else 0."""
        floor = 0.0
        if self._held is not None:
            if t > self._held[1]:
                self._held = None
            else:
                floor = self._held[0]
        pending = self._job.prepared.hold if self._job is not None else None
        if pending is not None and t <= pending[1]:
            floor = max(floor, pending[0])
        return floor

    def _plan(self, events: list[DrumEvent], beats: np.ndarray, lead_in: float,
              last_strokes: dict[Limb, float] | None = None) -> GesturePlan:
        """Distribute and plan rig-timed events (the planner's times are rig seconds), in this thread."""
        return self._account(*self._reachable(self._planner(events, beats, lead_in, last_strokes)()))

    def _planner(self, events: list[DrumEvent], beats: np.ndarray, lead_in: float,
                 last_strokes: dict[Limb, float] | None = None) -> Callable[[], GesturePlan]:
        """The planning of rig-timed events with the present style, as a call that reads nothing of the player's
        state (it may run in the worker while the loop changes it; picklable, for a worker process);
        ``last_strokes``: each foot's last note played before them (:meth:`_last_strokes`)."""
        self._check_grip()
        return functools.partial(plan_events, events, beats, lead_in, self.core.kit, self.algorithm, self.sticking,
                                 self.grip, self.nuance, height_m=self.core.settings.height_m,
                                 lengths=self._limb_lengths(), last_strokes=dict(last_strokes or {}))

    def _last_strokes(self, before: float) -> dict[Limb, float]:
        """Each foot's last note of the performance before ``before`` (s, the targets' clock), looked for
        :data:`CONTEXT_S` back: a ``play`` spliced in then is planned without the notes before it, and its first
        kick is made from rest (raised to the beater's contact height, common/gesture/planner.py) only if that
        foot has not kicked for ``KICK_REST_GAP_S`` (0.75 s), part of the way after ``KICK_RAISE_FROM_S`` (0.35 s),
        not at all before. A double pedal's kick whose foot is not on record
        counts for both feet."""
        last: dict[Limb, float] = {}
        for k in range(bisect.bisect_left(self.events, before, key=lambda e: e.time) - 1, -1, -1):
            e = self.events[k]
            if e.time < before - CONTEXT_S or len(last) == len(FEET):
                break
            if e.event in (EventType.BASS, EventType.HIHATPEDAL):
                for limb in self._limbs_of(e) & FEET:
                    last.setdefault(limb, e.time)
        return last

    def _limb_lengths(self) -> LimbLengths | None:
        """The arms and legs of the body physics built from the node's skeleton (``skeleton_bvh``), metres, for the
        planner's reach (as ``batteur render --skeleton-bvh``); None without one: the height's."""
        scene = self._maybe_drummer()
        if scene is None or not self.core.settings.skeleton_bvh:
            return None
        return LimbLengths.of_segments({name: s.length_m for name, s in scene.anthro.segments.items()})

    def _check_grip(self) -> None:
        """Warn when the hands hold another grip than the one the gestures are planned with (american,
        traditional: no gesture units; or a /batteur/physics/grip since the last style), once until either grip
        changes."""
        scene = self._maybe_drummer()
        if scene is None:
            return
        left, right = scene.grip["left"], scene.grip["right"]
        pairing = (left, right, self.grip)
        if left == right == self.grip.value:
            self._grip_warned = None  # a later mismatch is news again
            return
        if pairing == self._grip_warned:
            return
        self._grip_warned = pairing
        hands = f"the {left} grip" if left == right else f"the {left} (left) and {right} (right) grips"
        why = ("" if {left, right} <= {g.value for g in Grip} else
               f" (the gesture database has {' and '.join(g.value for g in Grip)} units only)")
        log.warning("the drummer's hands hold %s; the gestures are planned with the %s grip%s "
                    "(/batteur/score/style sets the hands' grip and the planned one)", hands, self.grip.value, why)

    def _reachable(self, plan: GesturePlan) -> tuple[GesturePlan, dict[str, int]]:
        """``plan`` with its knots beyond the body's reach brought just within it, and how many per limb
        (:func:`common.gesture.reach.pull_into_reach`): physics refuses a whole plan for one such knot (an instrument
        too far for a small drummer); its notes are missed instead (the planner flags them ``unreachable`` for the
        same height) and the rest plays. Every plan goes through here before its splice."""
        scene = self._maybe_drummer()
        if scene is None:
            return plan, {}
        return pull_into_reach(plan, scene.reach)

    def _account(self, plan: GesturePlan, pulled: dict[str, int] | None = None) -> GesturePlan:
        """Count and log a plan about to be spliced (its flagged notes; ``pulled``: its knots brought within
        reach per limb, :meth:`_reachable`)."""
        self.flagged += len(plan.issues)
        for issue in plan.issues:
            log.info("planner: note at %.3f s (%s): %s, %s (%s)", issue.time, issue.event.value if issue.event else "-",
                     issue.reason.value, issue.action.value, issue.detail)
        if pulled:
            self.pulled_into_reach.update(pulled)
            settings = self.core.settings
            body = "the skeleton's" if settings.skeleton_bvh else f"the {settings.height_m:g} m drummer's"
            log.info("plan: %s beyond %s reach brought within it: the notes there are missed",
                     ", ".join(f"{count} {limb.replace('_', ' ')} knot{'s' if count > 1 else ''}"
                               for limb, count in sorted(pulled.items())), body)
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

    def _note_dropped(self, plan: GesturePlan, t_s: float, until: float = math.inf) -> None:
        """Keep the notes ``plan`` (spliced at ``t_s``, s, the targets' clock; a live window's up to ``until``)
        does not play, by reason (the planner dropped or merged them, or they are out of reach), in place of those
        the plans before it left out from ``t_s`` on (for the play's summary: :meth:`say_ended`)."""
        self._dropped = {k: v for k, v in self._dropped.items() if not t_s <= k[0] < until}
        for issue in plan.issues:
            missed = (issue.action in (IssueAction.DROPPED, IssueAction.MERGED)
                      or issue.reason == IssueReason.UNREACHABLE)
            if missed and issue.event is not None and t_s <= issue.time < until:
                self._dropped[(issue.time, issue.event.value)] = issue.reason.value

    def _end_run(self, t_s: float, cause: str, ending: str, at_once: bool = False) -> None:
        """The play in progress ends at ``t_s`` (s, the targets' clock) by ``cause`` (a stop, pause, new play or
        reset; ``ending`` says where): its score notes from then on are not played. Its summary follows once its
        plan's end passes (:meth:`say_ended`), or ``at_once`` (a new play, a reset: nothing of it plays after)."""
        run = self._run
        if run is None:
            return
        if not run.ending or t_s < run.ended_at:  # the earliest of a stop and a pause sent ahead ends it
            run.ending, run.cause, run.ended_at = ending, cause, t_s
            mapping = self._mapping_at(t_s)
            if mapping is not None:
                at, position, tempo = self._sounding(t_s, mapping)
                run.played_end = position + max(t_s - at, 0.0) * tempo
        # the notes the plans still hold from then on (a second one ahead: those the first one left)
        run.cut += sum(1 for e in self.events if e.time >= t_s and (e.time, e.event.value) not in run.live)
        self._dropped = {k: v for k, v in self._dropped.items() if k[0] < t_s}  # said as cut, once
        if at_once:
            self._say_run(run)

    def say_ended(self, now: float) -> None:
        """Log the summary of a play whose plan has ended by rig time ``now`` (s) (:meth:`_say_run`); the live
        node calls it at every step (:meth:`pump`)."""
        run = self._run
        if run is not None and self._base(now) > self.end_time:
            self._say_run(run)

    def _say_run(self, run: _Run) -> None:
        """``rock.txt: 60 of 68 notes played; not played: 5 skipped (...), 3 too_fast (planner); ended after its
        last note at score 16.000 s, bar 9 beat 1.0``; a play that looped says its passes, as a teacher counts
        them, not "of" the notes its passes planned: ``five.txt: 246 notes played with 12 passes of bars 3-4 (20
        notes a pass); ...``."""
        self._run = None
        score_drops = Counter(reason for key, reason in self._dropped.items() if key not in run.live)
        why = Counter({"too close to prepare when it started": run.late,
                       "skipped: physics fell behind the rig clock": run.skipped})
        why.update({f"{reason} (planner)": n for reason, n in score_drops.items()})
        why[f"cut by the {run.cause}"] += run.cut
        missed = sum(why.values())
        played = run.notes - missed
        lost = "; not played: " + ", ".join(f"{n} {reason}" for reason, n in why.most_common() if n) if missed else ""
        where = run.ending or self._ended_after(run)
        passes = run.timeline.passes(run.played_end) if run.timeline is not None else {}
        if passes:
            looping = " and ".join(f"{n} pass{'es' if n > 1 else ''} of bars {a}-{b} ({loop_notes(run.score, (a, b))} "
                                   "notes a pass)" for (a, b), n in passes.items())
            log.info("%s: %d notes played with %s%s; %s", run.name, played, looping, lost, where)
            return
        log.info("%s: %d of %d notes played%s; %s", run.name, played, run.notes, lost, where)

    @staticmethod
    def _ended_after(run: _Run) -> str:
        """Where a play that ran to its plan's end ended: after the last note its timeline laid, said in the
        written score; a timeline ending on a loop's pass (no more passes laid) says which (until 7 Dec the
        score's own last note was said, after bar 5 for a play that stopped in pass 15 of bars 3-4)."""
        timeline, score = run.timeline, run.score
        if timeline is None or timeline.last_pass != len(timeline.segments) - 1:
            return f"ended after its last note at {score_words(score, score.events[-1].time)}"
        seg = timeline.segments[-1]  # the last pass, as Timeline.played takes its notes
        notes = [e.time for e in score.events if seg.start - 1e-9 <= e.time < seg.start + seg.length - 1e-9]
        last = max(notes, default=seg.start)
        assert seg.loop is not None
        return (f"ended after its last note at {score_words(score, last)}, in pass {timeline.pass_numbers[-1]} of "
                f"bars {seg.loop[0]}-{seg.loop[1]} (the last laid)")

    def _forget(self, t_s: float) -> None:
        """Drop the performance's notes from ``t_s`` on (they are no longer in the tracks)."""
        self.events = [e for e in self.events if e.time < t_s]
        self._bass_feet = {t: foot for t, foot in self._bass_feet.items() if t < t_s}
        self.end_time = min(self.end_time, t_s)

    def reset(self) -> None:
        """The scene was reset (tracks cleared; a reset message, or a divergence): nothing is playing any more; a
        plan in flight is dropped and the next plan does not wait for it (:meth:`_drop_job`), the messages waiting
        behind it act from the next :meth:`pump` on."""
        job = self._drop_job(reset=True)
        if job is not None:
            log.info("reset: the plan in flight (%d message(s)) dropped", len(job.requests))
        t = self.core.time - self.core.target_lag
        self._end_run(t, "reset", self._said_at("reset", t), at_once=True)
        self._generation += 1
        self._held = None
        self._clear_loop("reset")
        self._timeline = None
        self._playing = None
        self.events = []
        self._live_keys.clear()
        self._bass_feet.clear()
        self.state = "idle"
        self.mapping = None
        self._stopping = None
        self.end_time = -math.inf

    def status(self) -> dict[str, object]:
        """Counters and state, for logs and tests (a performance whose plan has ended is ``idle``)."""
        ended = self.core.time - self.core.target_lag > self.end_time  # the targets' clock
        state = "idle" if self.state == "playing" and ended else self.state
        return {"state": state, "score": str(self.score_path) if self.score_path else None,
                "late_notes": self.late_notes, "skipped_notes": dict(self.skipped_notes), "errors": dict(self.errors),
                "flagged": self.flagged,
                "plans": self.plans, "unknown_live_pitches": self.unknown_pitches,
                "live_duplicates": self.live.duplicates, "replanned_late": self.replanned_late,
                "live_window_misses": self.window_misses, "pulled_into_reach": dict(self.pulled_into_reach)}
