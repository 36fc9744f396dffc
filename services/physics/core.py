"""PhysicsCore: the physics service's deterministic core (ROLE "physics").

It owns one PyBullet world and a scene:

* ``scene="strike"``: a stick on a fulcrum over one instrument of the kit,
  thrown onto it at scheduled (time, velocity) strikes (integration and tests);
* ``scene="drummer"``: the 57-DOF percussionist on the throne at the whole kit,
  tracking joint or Cartesian targets (see :mod:`services.physics.drummer`).

Every step (default 1 kHz) it advances the world by one fixed step and sends a
:class:`~common.messages.Contact` to ``interaction`` for each striker-instrument
pair in contact; at the pose rate (default 60 Hz) it sends a
:class:`~common.messages.Pose` to ``graphics``, preceded at start, every 5 s
and on every Hello by the :class:`~common.messages.Skeleton` layout.

Time: ``step(now)`` advances the simulation to rig time ``now`` (seconds). In
``offline`` mode every step is simulated (as fast as the caller steps; the same
inputs give bit-identical contacts). In ``live`` mode a call that finds the
simulation more than ``max_catchup_steps`` behind simulates that many and skips
the rest of the gap, counting ``overruns`` and ``skipped_steps``: the
simulation is never silently slowed. The drummer's targets do not jump with a
skip: they trail the rig clock by the time skipped (``target_lag``) and jump
where no stroke is cut or jumped over and no limb's target moves, there or
between (``DrummerScene.can_jump``), or once they trail by ``MAX_TARGET_LAG_S``;
past ``MAX_TARGET_LAG_HARD_S`` even when what was placed while they trailed
holds the lag (:meth:`PhysicsCore._jump_past_bound`).

Example (offline, one process)::

    core = PhysicsCore(scene="strike", strikes=[(0.1, 3.0), (0.3, 1.5)])
    for k in range(1, 400):
        out = core.step(k / 1000)
"""

from __future__ import annotations

import bisect
import itertools
import logging
import math
import zlib
from collections import Counter
from collections.abc import Iterable, Sequence
from operator import itemgetter
from typing import TYPE_CHECKING, ClassVar, Literal, NamedTuple, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from common.core import Outgoing
from common.kit import EventType, Kit, load_kit
from common.messages import Contact, Hello, OscMessage, Pose, Skeleton
from common.messages.physics import (
    CartesianTarget,
    ControlModeName,
    JointTarget,
    PhysicsControlMode,
    PhysicsGains,
    PhysicsGrip,
    PhysicsIk,
    PhysicsPosture,
    PhysicsRejected,
    PhysicsReset,
    PhysicsStrike,
)
from common.rated_log import RatedWarnings
from common.score.events import MAX_SCORE_NOTES
from common.token_bucket import TokenBuckets
from services.physics.anthropometry import SkeletonUnits
from services.physics.contacts import ContactTracker
from services.physics.posture import apply_posture
from services.physics.score_player import SCORE_MESSAGES, ScorePlayer
from services.physics.strike_scene import Strike, StrikeScene
from services.physics.targets import TargetError, Track
from services.physics.world import World, WorldSettings

if TYPE_CHECKING:
    from common.gesture.plan import GesturePlan

log = logging.getLogger("batteur.physics")

DRUMMER_MESSAGES = (CartesianTarget, JointTarget, PhysicsControlMode, PhysicsGains, PhysicsGrip, PhysicsIk)
"""Messages only the drummer scene acts on: the strike scene rejects them (counted) rather than drop them unseen."""
MAX_PENDING_STRIKES = MAX_SCORE_NOTES
"""Strike scene: most strikes scheduled and not yet thrown (a score's most notes, 500,000): a
/batteur/physics/strike past it is refused (TargetError, counted), the schedule kept."""
REJECT_LOG_INTERVAL_S = 1.0
"""Rejections of one message kind are logged at most once per this many seconds of rig time (the rest are counted
and summed into the next warning), so a stream of bad targets cannot flood the log."""
REPLY_RATE_HZ = 10.0
"""Refusals answered (:class:`PhysicsRejected`) per second of rig time to one sender host; past it (and the
burst) a refusal is still counted and logged but not answered (``replies_unanswered``), so a flood of bad packets
(perhaps with a forged source) cannot make physics send as much back."""
REPLY_BURST = 20.0
"""Refusals answered to one sender host at once before :data:`REPLY_RATE_HZ` applies."""
REPLY_SENDERS = 1024
"""Sender hosts whose reply budget is remembered (the least recently refused is forgotten first)."""
MAX_TARGET_LAG_S = 0.5
"""Live mode: the drummer's targets trail the rig clock by up to this much after skipped steps, seconds, waiting for
a moment the jump to it moves no limb's target (:meth:`PhysicsCore._catch_up_targets`); past it they jump where the
jump cuts no stroke and moves each target by at most ``LATE_JUMP_MAX_M`` (the strokes of the time jumped over are
dropped whole, not cut), ..."""
MAX_TARGET_LAG_HARD_S = 1.0
"""... and past this, seconds, wherever the limbs are (as every skip did until 6 Dec evening); a lag held by what
was placed while the targets trailed (streamed targets, score plans) is no exception: past it the targets jump back
to the lag of the score plans playing (at most this, since the bound held when they were placed) or to the rig
clock, the streamed knots still queued re-timed onto the new clock (:meth:`PhysicsCore._jump_past_bound`)."""
LATE_JUMP_MAX_M = 0.10
"""Past ``MAX_TARGET_LAG_S``: the most a limb's target may move at the jump, metres ..."""
LATE_JUMP_MAX_SPEED_M_S = 2.0
"""... and the most its velocity may change, m/s."""
STREAM_SHORT_CUT_S = 0.1
"""Live mode: a streamed knot placed after the lag grew is placed with the lag as it is (reached at its rig time) even
where that cuts the stream's queued knots for earlier rig times, if these are within this many seconds of rig time
before its own (a dense stream's short cut: it stays on time); knots further before it are kept, the knot keeping its
interval after them and their lag (:meth:`PhysicsCore._stream_lag`) ..."""
STREAM_DENSE_S = 0.05
"""... unless the stream is dense over what it would cut: those knots and the one kept before them are each within this
many seconds of rig time of the next (at least two knots per ``STREAM_SHORT_CUT_S``: no knot there is a lone
waypoint), ..."""
STREAM_DENSE_MIN_KNOTS = 3
"""... at least this many of them (a rate takes two intervals to show: a pair of knots close together is as likely two
waypoints a sender meant, a quick lift and strike), none a posture's (its start and end are waypoints, however short
its glide), so the knot cuts over all the lag grown since (a dense stream catches up after a long skip)."""
def behind_advice(control_rate_hz: float) -> str:
    """What the live warnings of physics falling behind tell the user to do, after saying what they hear: a lower
    control rate only while there is one to suggest (half of ``control_rate_hz``, Hz, down to 250, where the strokes'
    tracking misses its 5 mm; until 7 Dec "e.g. 500" was suggested at 500 too)."""
    lower = f"a lower --control-rate-hz (e.g. {max(250.0, control_rate_hz / 2):g}), " if control_rate_hz > 250 else ""
    return f"give physics a less loaded machine, {lower}or fewer programs on its CPU core"
BEHIND_DOCS = "docs/physics.md, 'When physics falls behind'"
"""Where those warnings' details are explained (named at their end)."""


class StreamedKnot(NamedTuple):
    """A streamed knot still queued on a drummer track (:attr:`PhysicsCore._streamed`)."""

    rig_time: float
    """When it is to be reached, s (rig clock)."""
    time: float
    """Where it is queued, s (the targets' clock: ``rig_time`` less the lag it was placed with)."""
    posture: bool = False
    """One of a /batteur/physics/posture glide's two knots: a waypoint, never part of a dense stream."""


class PhysicsSettings(BaseModel):
    """Settings of the physics core (the node fills them from flags and environment)."""

    model_config = ConfigDict(extra="forbid")

    scene: Literal["strike", "drummer"] = Field(default="drummer", description="what to simulate")
    mode: Literal["offline", "live"] = Field(default="offline", description="time handling, see PhysicsCore")
    rate_hz: float = Field(default=1000.0, ge=100, le=10000, description="physics step rate, Hz")
    control_rate_hz: float = Field(default=1000.0, ge=50, le=10000,
                                   description="drummer: full control updates (IK, inverse dynamics) per second, "
                                               "Hz; the PD corrects the torques at every physics step between")
    pose_rate_hz: float = Field(default=60.0, ge=0, le=240, description="pose publishing rate, Hz (0: off)")
    kit: str = Field(default="default", description="kit name or YAML/JSON path (common/kits)")
    left_handed: bool = Field(default=False, description="mirror the kit for a left-handed drummer")
    strike_event: EventType = Field(default=EventType.SNARE, description="strike scene: which event's hit point")
    strike_period_s: float = Field(default=0.0, ge=0, le=60,
                                   description="strike scene: strike every this many seconds (0: on request)")
    strike_velocity: float = Field(default=3.0, gt=0, le=30, description="strike scene: periodic tip speed, m/s")
    solver_iterations: int = Field(default=50, ge=1, le=500, description="constraint solver iterations per step")
    substeps: int = Field(default=1, ge=1, le=16, description="internal substeps per physics step")
    max_catchup_steps: int = Field(default=50, ge=1, description="live mode: most steps simulated per call")
    skeleton_period_s: float = Field(default=5.0, gt=0, description="how often the Skeleton layout is repeated, s")
    height_m: float = Field(default=1.75, ge=1.2, le=2.2, description="drummer's height, metres")
    mass_kg: float = Field(default=73.0, ge=35, le=150, description="drummer's mass, kilograms")
    control: ControlModeName = Field(default="cartesian", description="controller")
    floating_base: bool = Field(default=False,
                                description="drummer: a floating base pinned to the throne instead of a fixed base "
                                            "(the pin costs about a fifth of each step; no controller needs it)")
    grip: Literal["french", "german", "american", "traditional"] = Field(default="american", description="grip")
    limits_from: tuple[str, ...] = Field(
        default=(), description="drummer: motion clips the joint limits are estimated from: BVH files, DeepMimic "
        "clip files or names of pybullet's DeepMimic clips (empty: every DeepMimic humanoid clip)")
    asymmetric_limits: bool = Field(
        default=False, description="drummer: with limits_from, keep each side's own joint limits as the clips "
        "give them (for a performer with a real asymmetry) instead of making each left/right pair mirror-symmetric "
        "(their common range, as the default limits: a side the clips let reach further drifts there under fast "
        "strokes); the default limits are always symmetric")
    skeleton_bvh: str | None = Field(
        default=None, description="drummer: BVH file whose skeleton gives the body's proportions (arms, legs, neck, "
        "shoulder height above the hips, shoulder and hip widths; hands, feet and head from de Leva's table for the "
        "height and mass)")
    skeleton_units: SkeletonUnits = Field(
        default="auto", description="drummer: the length unit of skeleton_bvh's file: auto (guessed: the one in which "
        "its lengths are a 1.2 to 2.2 m performer's), m, cm, mm or in (a child-sized or stylised character's unit, "
        "which a guess would take for another; a stature outside 1.2 to 2.2 m is then warned of, not refused)")


class Scene(Protocol):
    """What the core needs from a scene."""

    tracker: ContactTracker
    pose_links: list[tuple[str, int, int]]

    def pre_step(self, t_next: float) -> None: ...

    def reset(self) -> None: ...


class JumpTest(Protocol):
    """A scene's test of whether its targets may jump from one rig time to a later one (s) unnoticed, with the most
    a target may move (m) and change speed (m/s) (its defaults when not given) and whether the strokes between may
    be dropped whole (only the two ends checked): ``DrummerScene.can_jump``."""

    def __call__(self, t_from: float, t_to: float, max_move_m: float = ..., max_speed_change_m_s: float = ...,
                 drop_strokes: bool = ...) -> bool: ...


class PhysicsCore:
    """The physics service core (see the module docstring)."""

    ROLE: ClassVar[str] = "physics"

    def __init__(
        self,
        settings: PhysicsSettings | None = None,
        *,
        strikes: Iterable[tuple[float, float]] = (),
        kit: Kit | str | None = None,
        **overrides: object,
    ) -> None:
        if isinstance(kit, str):  # a kit name or file: the settings' field
            overrides["kit"] = kit
            kit = None
        base = settings if settings is not None else PhysicsSettings()
        self.settings = PhysicsSettings.model_validate({**base.model_dump(), **overrides})
        s = self.settings
        self.rate_hz = s.rate_hz
        self.world = World(WorldSettings(timestep_s=1.0 / s.rate_hz, solver_iterations=s.solver_iterations,
                                         substeps=s.substeps))
        kit_model = kit if kit is not None else load_kit(s.kit, height_m=s.height_m)
        if s.left_handed and kit_model.handedness == "right":
            kit_model = kit_model.mirrored()
        self.kit = kit_model
        self.scene: Scene
        if s.scene == "strike":
            strike_scene = StrikeScene(self.world, kit_model, event=s.strike_event, period_s=s.strike_period_s,
                                       period_velocity=s.strike_velocity)
            self.scene = strike_scene
            self.schedule_strikes(list(strikes))
        else:
            from services.physics.drummer import DrummerScene

            if tuple(strikes):
                raise ValueError("strikes are for scene='strike'; the drummer plays targets")
            self.scene = DrummerScene(self.world, kit_model, s)
        self.names = [name for name, _, _ in self.scene.pose_links]
        self.layout = zlib.crc32(",".join(self.names).encode()) & 0x7FFFFFFF
        self.time_offset = 0.0
        """rig time = simulation time + time_offset (live mode moves it forward when steps are skipped)."""
        self.overruns = 0
        self.skipped_steps = 0
        self.target_lag = 0.0
        """Live mode: how far the limbs' targets (the plan's clock) trail the rig clock after skipped steps, seconds
        (0 offline)."""
        self.target_jumps = 0
        """Live mode: times the targets jumped to the rig clock (the time they trailed by dropped)."""
        self.target_jumps_late = 0
        """... of which past ``MAX_TARGET_LAG_S`` (the strokes jumped over dropped; logged)."""
        self._streamed_held: tuple[float, float] | None = None
        """(lag s, targets' clock s): streamed targets queued while the targets trailed the rig clock by that lag
        (that much earlier on their clock, to be reached at their rig times: :meth:`_handle`) play until then; the
        targets keep at least that lag until it (:meth:`_lag_floor`, as ``ScorePlayer.lag_floor`` for plans)."""
        self._streamed: dict[str, list[StreamedKnot]] = {}
        """Track ("left_hand" ... or "joints") -> its streamed knots still queued, in order on both clocks: where a
        knot streamed after the lag grew goes (:meth:`_stream_lag`), and what a jump past ``MAX_TARGET_LAG_HARD_S``
        re-times (:meth:`_retime_streamed`)."""
        self.streamed_retimed = 0
        """Live mode: streamed knots moved onto the targets' new clock at a jump past ``MAX_TARGET_LAG_HARD_S``, to
        be reached at their rig times still (logged) ..."""
        self.streamed_passed = 0
        """... and those of them whose rig time had come: behind the targets' new time, passed (logged)."""
        self._can_jump: JumpTest | None = getattr(self.scene, "can_jump", None)
        """The scene's test of whether its targets may jump between two rig times unnoticed (the drummer's); a
        scene without one (the strike scene) jumps with every skip."""
        self.rejected: Counter[str] = Counter()
        self._reject_warnings = RatedWarnings(log, REJECT_LOG_INTERVAL_S)
        """Rejections logged at most once per ``REJECT_LOG_INTERVAL_S`` of rig time for each message kind."""
        self._replies: list[Outgoing] = []
        """Refusals to send back (:class:`PhysicsRejected`), handed out by the next :meth:`handle` or :meth:`step`
        (a plan refused in the background is answered from a step)."""
        self._reply_budgets = TokenBuckets(REPLY_RATE_HZ, REPLY_BURST, REPLY_SENDERS)
        """Sender host -> its reply budget."""
        self.replies_unanswered = 0
        """Refusals not answered: their sender was over its reply budget (the node's Health reports it)."""
        self.diverged = 0
        """Steps whose simulation diverged (non-finite state); each reset the scene (see :meth:`_one_step`)."""
        self.contacts_sent = 0
        self._last_skeleton = -math.inf
        self._last_skip_warning = -math.inf
        self._last_jump_warning = -math.inf
        self._last_bound_warning = -math.inf
        self._live_started = False
        """Live mode: the loop has called :meth:`step` (its first call sets where the simulation starts)."""
        self._poses_sent = 0
        self._pose_plan: list[tuple[int, list[int], list[int]]] | None = None
        self._pose_static: list[float] = []
        self.score_player = ScorePlayer(self)
        """Score control messages -> gesture plans for the drummer (services/physics/score_player.py)."""

    # ---------------------------------------------------------------- Core protocol

    def step(self, now: float) -> list[Outgoing]:
        """Advance the simulation to rig time ``now`` seconds; return contacts, poses and layout messages."""
        out = self._take_replies()
        if now - self._last_skeleton >= self.settings.skeleton_period_s:
            out.append(Outgoing(self.skeleton(), "graphics"))
            self._last_skeleton = now
        dt = self.world.dt
        target = math.floor((now - self.time_offset) / dt + 1e-6)
        behind = target - self.world.steps
        if self.settings.mode == "live" and not self._live_started:
            self._live_started = True
            if behind > 1:
                # the loop's first call: the rig clock ran while the scene was built (2-3 s); the simulation
                # starts here, which is not falling behind (nothing was due before it)
                self.time_offset += (behind - 1) * dt
                behind = 1
            log.info("physics simulation starts at rig time %.3f s", self.time + max(behind, 0) * dt)
        if behind <= 0:
            return out
        if self.settings.mode == "live":
            if behind > 1:
                self.overruns += 1
            if behind > self.settings.max_catchup_steps:
                skip = behind - self.settings.max_catchup_steps
                self.skipped_steps += skip
                self.time_offset += skip * dt
                if self._can_jump is not None:  # the targets trail the rig clock by it, not jump now
                    self.target_lag += skip * dt
                behind = self.settings.max_catchup_steps
                if now - self._last_skip_warning >= 5.0:  # at most one warning per 5 s of rig time
                    trailing = self._trailing() if self.target_lag > 0.0 else ""  # not silently slowed
                    # said plainly first (a teacher on a loaded machine saw it every 5 s), the detail after
                    log.warning("physics is %.0f ms behind real time%s: notes play late or are skipped; %s (detail: "
                                "%d steps behind the rig clock, %d skipped, %d in all%s; %s)",
                                (behind + skip) * dt * 1e3, self._playing_words(),
                                behind_advice(self.settings.control_rate_hz), behind + skip,
                                skip, self.skipped_steps, trailing, BEHIND_DOCS)
                    self._last_skip_warning = now
            if self.target_lag > 0.0:
                self._catch_up_targets(now)
        for _ in range(behind):
            out.extend(self._one_step())
        return out

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        """React to Hello (answer the layout) and to physics control messages; a refused one is answered with a
        :class:`PhysicsRejected` to ``source`` (see :meth:`reject`)."""
        return self.handle_counted(message, now, source) + self._take_replies()

    def handle_counted(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        """:meth:`handle` without handing out the refusals' replies (they wait for the next :meth:`handle` or
        :meth:`step`): the score player's handler for the messages that waited behind a background plan."""
        try:
            return self._handle(message, now, source)
        except (TargetError, ValueError) as exc:
            self.reject(message, source, exc, now)
            return []

    @property
    def rejected_total(self) -> int:
        """Messages this core refused (bad or unreachable targets, score errors ...), total; the node's Health
        counts them as dropped."""
        return sum(self.rejected.values())

    def reject(self, message: OscMessage, source: str, exc: Exception, now: float) -> None:
        """Count a refused message, answer its sender (a :class:`PhysicsRejected` to ``source``, within the
        sender's reply budget) and log it unless this kind was logged within ``REJECT_LOG_INTERVAL_S`` (the score
        player's refusals found on the background planning path come here too)."""
        kind = type(message).__name__
        self.rejected[kind] += 1
        self.queue_refusal(message.ADDRESS, str(exc), source, now)
        self._reject_warnings.warn(kind, now, "physics rejected %s from %s: %s", kind, source, exc)

    def queue_refusal(self, address: str, reason: str, source: str, now: float) -> None:
        """Queue a :class:`PhysicsRejected` (``address`` refused for ``reason``) for ``source`` ("host:port", or a
        role offline) if its host is within its reply budget at rig time ``now`` (s); else count it in
        ``replies_unanswered``. Counts no rejection: :meth:`reject` does, for a refused message; the score player
        also answers a live note too late or of no drum this way (counted as late or unknown, not as rejected)."""
        if not source:
            return
        host = source.rpartition(":")[0] or source  # the budget is the host's: a flood may vary its ports
        if not self._reply_budgets.take(host, now):
            self.replies_unanswered += 1
            return
        self._replies.append(Outgoing(PhysicsRejected(address=address[:128], reason=reason[:512]), source))

    def _take_replies(self) -> list[Outgoing]:
        """The refusals' replies queued since the last call (emptied)."""
        replies, self._replies = self._replies, []
        return replies

    def _handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Hello):
            return [Outgoing(self.skeleton(), "reply")]
        if isinstance(message, PhysicsReset):
            self.target_lag = 0.0  # the targets are cleared: nothing trails
            self._streamed_held = None
            self._streamed.clear()
            self.scene.reset()
            self.score_player.reset()
            return []
        if isinstance(message, PhysicsPosture):  # graphics' pose editor: a separate handler (posture.py)
            start = max(float(message.time), self.time)  # its two knots' rig times, as apply_posture places them
            # placed on the targets' clock as streamed knots are (below): a glide placed after the lag grew would cut
            # the knots sent for earlier rig times, a posture before it never reached
            lag = self._stream_lag("joints", start)
            end = apply_posture(self, message, lag)
            self._record_streamed("joints", start - lag, start, posture=True)
            self._record_streamed("joints", end - lag, end, posture=True)
            self._hold_streamed(lag, end - lag)
            return []
        if isinstance(message, PhysicsStrike):
            if not isinstance(self.scene, StrikeScene):
                raise TargetError("/batteur/physics/strike needs the strike scene")
            if message.time < self.time + self.world.dt:
                raise TargetError(f"strike at {message.time:.4f} s is in the past (now {self.time:.4f} s)")
            self.schedule_strikes([(message.time, message.velocity)])
            return []
        if isinstance(message, SCORE_MESSAGES):  # score player (its errors are ValueErrors: rejected and logged)
            self.score_player.handle(message, now, source)
            return []
        handler = getattr(self.scene, "handle", None)
        if handler is None:
            if isinstance(message, DRUMMER_MESSAGES):
                raise TargetError(f"{message.ADDRESS} needs the drummer scene (this is the {self.settings.scene} "
                                  "scene)")
            return []
        if isinstance(message, (CartesianTarget, JointTarget)):
            # the targets trail the rig clock (live, after skipped steps): queued that much earlier on their clock, a
            # streamed target is reached at its rig time, as the score player's plans and notes are, and the
            # targets keep that lag until it is (_lag_floor); after the lag grew, cutting the knots sent for
            # earlier rig times only over a short cut (_stream_lag)
            key = message.limb if isinstance(message, CartesianTarget) else "joints"
            lag = self._stream_lag(key, message.time)
            if lag > 0.0:
                handler(message, self.time, lag)
            else:
                handler(message, self.time)
            self._record_streamed(key, message.time - lag, message.time)
            self._hold_streamed(lag, message.time - lag)
            return []
        handler(message, self.time)
        if isinstance(message, PhysicsControlMode):  # after the scene accepted it
            self.settings = self.settings.model_copy(update={"control": message.mode})
        return []

    # ---------------------------------------------------------------- helpers

    @property
    def late(self) -> int:
        """Health.late, physics' late events: score and live notes that arrived too late to be prepared or whose
        strokes a jump of the lagging targets dropped (``score_player.late_notes``; the latter also in
        ``score_player.skipped_notes``). Not the steps skipped when the simulation falls behind the rig clock
        (``skipped_steps``, in the "behind real time" warning): until 7 Dec added here, they grew ``batteur ls``'s
        late column by ~700 a second on a loaded machine while nothing played, hiding the notes."""
        return self.score_player.late_notes

    @property
    def time(self) -> float:
        """Rig time of the current simulation state, seconds."""
        return self.world.time + self.time_offset

    def skeleton(self) -> Skeleton:
        return Skeleton(layout=self.layout, names=tuple(self.names))

    def schedule_strikes(self, strikes: Sequence[tuple[float, float]]) -> None:
        """Strike scene: add (time s, velocity m/s) strikes; :class:`TargetError` (none added) past
        :data:`MAX_PENDING_STRIKES` pending."""
        if not isinstance(self.scene, StrikeScene):
            raise TargetError("strikes need the strike scene")
        batch = [Strike(float(t), float(v)) for t, v in strikes]
        pending = len(self.scene.pending)
        if pending + len(batch) > MAX_PENDING_STRIKES:
            raise TargetError(f"strike schedule full: {pending} strikes pending and {len(batch)} more would pass the "
                              f"limit of {MAX_PENDING_STRIKES} (MAX_PENDING_STRIKES); refused, the schedule is kept")
        self.scene.schedule(batch)

    def load_plan(self, plan: GesturePlan, start_at: float | None = None) -> None:
        """Drummer scene: track a gesture plan; its ``start_time`` maps to rig time ``start_at`` (default: now).

        Raises :class:`TargetError` for a plan the drummer cannot follow (unknown limb, unreachable knot, more
        knots than a track holds with its lead-in: the scene checks every limb before it clears any track); the
        queued targets are kept then.
        """
        from services.physics.drummer import DrummerScene

        if not isinstance(self.scene, DrummerScene):
            raise TargetError("gesture plans need the drummer scene")
        self.scene.load_plan(plan, self.time if start_at is None else start_at, now=self.time)

    def pose(self) -> Pose:
        """Every pose link's world position (m) and quaternion (xyzw): one link-state read per moving body; the
        bases of fixed bodies (drums, stands) never move and are read once."""
        if self._pose_plan is None:
            self._pose_plan = self._plan_pose_reads()
        values = self._pose_static.copy()
        c = self.world.client
        for body, links, slots in self._pose_plan:
            for state, slot in zip(c.getLinkStates(body, links, computeForwardKinematics=1), slots, strict=True):
                values[slot:slot + 3] = state[4]
                values[slot + 3:slot + 7] = state[5]
        return Pose(time=self.time, layout=self.layout, values=tuple(values))

    def _plan_pose_reads(self) -> list[tuple[int, list[int], list[int]]]:
        """(body, links, value offsets) per body with moving pose links; fills ``_pose_static``."""
        self._pose_static = [0.0] * (7 * len(self.scene.pose_links))
        plan: dict[int, tuple[list[int], list[int]]] = {}
        for k, (_, body, link) in enumerate(self.scene.pose_links):
            if link < 0:  # every body's base is fixed (or, the drummer's seat, pinned): it never moves
                pos, quat = self.world.link_frame(body, link)
                self._pose_static[7 * k:7 * k + 7] = [*map(float, pos), *map(float, quat)]
            else:
                links, slots = plan.setdefault(body, ([], []))
                links.append(link)
                slots.append(7 * k)
        return [(body, links, slots) for body, (links, slots) in plan.items()]

    def _one_step(self) -> list[Outgoing]:
        """One physics step; a simulation that diverged (non-finite state) is reset to the rest posture, as
        /batteur/physics/reset would, counted in ``diverged`` and logged, so the service keeps running."""
        try:
            return self._advance()
        except Exception:
            if self.world.finite_state():
                raise  # not a divergence: the node counts it as a step error
        self.diverged += 1
        log.error("physics diverged at %.3f s (non-finite state): reset to the rest posture (%d in all)",
                  self.time, self.diverged)
        self.scene.reset()
        self.score_player.reset()
        self._streamed_held = None
        self._streamed.clear()
        if not self.world.finite_state():
            raise RuntimeError("physics diverged and a reset did not bring the state back to finite numbers")
        return []

    def _advance(self) -> list[Outgoing]:
        world = self.world
        t_next = world.time + world.dt
        if self.target_lag > 0.0:  # live, after skipped steps: the targets trail the rig clock
            self.scene.pre_step(t_next + self.time_offset - self.target_lag)
        else:
            self.scene.pre_step(t_next + self.time_offset)
        self.scene.tracker.before_step()
        world.step()
        contacts: list[Contact] = self.scene.tracker.after_step(self.time, world.steps)
        self.contacts_sent += len(contacts)
        out = [Outgoing(c, "interaction") for c in contacts]
        rate = self.settings.pose_rate_hz
        if rate > 0 and math.floor(world.steps * world.dt * rate + 1e-9) >= self._poses_sent:
            self._poses_sent += 1
            out.append(Outgoing(self.pose(), "graphics"))
        return out

    def _catch_up_targets(self, now: float) -> None:
        """Live mode, once per call while the targets trail the rig clock (``target_lag`` s): jump them to it
        (``target_lag`` 0) where that goes unnoticed (:data:`MAX_TARGET_LAG_S`); ``now``: rig time, seconds. While
        score plans placed with a lag play (the score player places them that much earlier on the targets' clock, so
        they sound on the rig's), the targets jump back only to that lag (``ScorePlayer.lag_floor``), and so for
        streamed targets (:meth:`_lag_floor`); past :data:`MAX_TARGET_LAG_HARD_S` all the same
        (:meth:`_jump_past_bound`).

        A node that falls behind skips rig time. Had the targets jumped with every skip (20-70 ms at once), a
        limb mid-stroke or mid-move would chase a target far ahead and take a short cut: on the demo's last bar
        the stick met the crash from under its edge and held the tilted plate up for seconds (the target above it
        rises with the plate's swing), or the skip jumped a downstroke and the note was lost.
        """
        self._jump_to_floor(now)
        if self.target_lag > MAX_TARGET_LAG_HARD_S:
            self._jump_past_bound(now)

    def _jump_to_floor(self, now: float) -> None:
        """:meth:`_catch_up_targets` within the lag held by what was placed while the targets trailed."""
        assert self._can_jump is not None  # only such a scene's targets trail
        lag, rig = self.target_lag, self.time
        # score plans and streamed targets placed while the targets trailed are that much early on their clock (to
        # sound on the rig's): the targets keep that lag while they play (ScorePlayer.lag_floor, _lag_floor)
        floor = min(self._lag_floor(rig - lag), lag)
        excess = lag - floor
        if excess <= 0.0:
            return
        if excess <= MAX_TARGET_LAG_S:
            jump = self._can_jump(rig - lag, rig - floor)
        else:
            jump = excess > MAX_TARGET_LAG_HARD_S or self._can_jump(rig - lag, rig - floor, LATE_JUMP_MAX_M,
                                                                    LATE_JUMP_MAX_SPEED_M_S, drop_strokes=True)
        if not jump:
            return
        self.target_jumps += 1
        self.target_lag = floor
        if excess > MAX_TARGET_LAG_S:
            self.target_jumps_late += 1
            # the notes of the strokes jumped over: counted late, each live note refused to its sender
            dropped = self.score_player.drop_skipped(rig - lag, rig - floor, now)
            if now - self._last_jump_warning >= 5.0:  # at most one warning per 5 s of rig time
                # said plainly first, as the skip's and the bound's warnings, the detail after
                log.warning("physics is %.0f ms behind real time: the drummer's hands jump to catch up and the notes "
                            "between are skipped%s; %s (detail: the targets jumped %.0f ms toward the rig clock, "
                            "%.0f ms behind it now; the strokes between dropped with %s; %d such jumps in all, %s; %s)",
                            lag * 1e3, self._skipped_words(rig - lag, rig - floor),
                            behind_advice(self.settings.control_rate_hz), excess * 1e3, floor * 1e3,
                            *self._notes_dropped(*dropped, self.target_jumps_late), BEHIND_DOCS)
                self._last_jump_warning = now

    def _jump_past_bound(self, now: float) -> None:
        """The targets trail the rig clock by more than :data:`MAX_TARGET_LAG_HARD_S`, held there by what was placed
        while they trailed (a stream of targets or of live notes holds the lag it arrived at, so it would hold it
        for ever: each new one at the lag grown since): jump, wherever the limbs are, to the lag of the score plans
        still playing (they keep their rig times: placed between calls, within the bound, it is at most the bound)
        or else to the rig clock. The streamed knots still queued are re-timed onto the new clock, each to its rig
        time (:meth:`_retime_streamed`), not jumped over nor played early; the strokes of plans placed with less
        lag, between the two times, are dropped (as at any jump past ``MAX_TARGET_LAG_S``). Counted and logged."""
        lag, rig = self.target_lag, self.time
        to = min(self.score_player.lag_floor(rig - lag), lag)
        if to >= lag:  # a score plan placed beyond the bound (only a lag set by hand): it keeps its rig times
            return
        ahead, passed = self._retime_streamed(rig - lag, to)
        dropped = self.score_player.drop_skipped(rig - lag, rig - to, now)  # as in _jump_to_floor
        self.target_lag = to
        self.target_jumps += 1
        self.target_jumps_late += 1
        if now - self._last_bound_warning >= 5.0:  # at most one warning per 5 s of rig time
            log.warning("physics is %.0f ms behind real time, past the %.0f ms it may lag: the drummer's hands jump "
                        "to catch up and the notes between are skipped%s; %s (detail: targets held by what was placed "
                        "while they trailed jumped %.0f ms, %.0f ms behind now: %s; %d streamed knots re-timed to "
                        "their rig times, %d passed; dropped %s; %d such jumps in all, %s; %s)",
                        lag * 1e3, MAX_TARGET_LAG_HARD_S * 1e3, self._skipped_words(rig - lag, rig - to),
                        behind_advice(self.settings.control_rate_hz),
                        (lag - to) * 1e3, to * 1e3,
                        "the lag the score plan playing was placed with" if to > 0.0 else "on it", ahead, passed,
                        *self._notes_dropped(*dropped, self.target_jumps_late), BEHIND_DOCS)
            self._last_bound_warning = now

    def _playing_words(self) -> str:
        """What the skip warning says of where the drummer is in the score it plays (``while playing groove.mid bar 12
        beat 3.4``: the targets' clock, what sounds now), "" while no score plays: a teacher hears which bars are
        late (until 8 Dec the warning gave step counts alone)."""
        where = self.score_player.where(self.time - self.target_lag)
        return f" while playing {where}" if where else ""

    def _skipped_words(self, t_from: float, t_to: float) -> str:
        """What a jump's warning says of the bars it skips, the targets' clock jumping from ``t_from`` to ``t_to``
        (s): `` (groove.mid bar 12 beat 3.4 to bar 13 beat 1.2)``; "" while no score plays then."""
        where = self.score_player.where(t_from, t_to)
        return f" ({where})" if where else ""

    def _notes_dropped(self, live: int, score: int, jumps: int) -> tuple[str, int, str]:
        """What a jump's warning says of the notes whose strokes it dropped (``live`` and ``score`` notes), of the
        ``jumps`` so far and of the notes they dropped (``ScorePlayer.skipped_notes``)."""
        total = self.score_player.skipped_notes
        return (f"{live} live notes (each refused to its sender) and {score} score notes", jumps,
                f"{total['live']} live and {total['score']} score notes dropped so far")

    def _trailing(self) -> str:
        """What the skip warning's detail says of the targets trailing the rig clock (``target_lag`` > 0): what
        plays late, by how much, and until when (true of what is queued: what was placed while they trailed plays
        at its rig time, less the lag grown since; what arrives now is placed for its rig time: docs/physics.md,
        'When physics falls behind')."""
        lag = self.target_lag
        if lag > MAX_TARGET_LAG_HARD_S:
            return (f"; the drummer's targets trail it by {lag * 1e3:.0f} ms, past the "
                    f"{MAX_TARGET_LAG_HARD_S * 1e3:.0f} ms bound: they jump toward it now, wherever the hands are")
        floor = min(self._lag_floor(self.time - lag), lag)
        if floor <= 0.0:
            return f"; the drummer plays {lag * 1e3:.0f} ms late until its hands are still"
        return (f"; the drummer's targets trail it by {lag * 1e3:.0f} ms and keep {floor * 1e3:.0f} ms of it while "
                f"what was placed with that lag plays, {(lag - floor) * 1e3:.0f} ms late (what was queued before, "
                f"up to {lag * 1e3:.0f} ms late)")

    def _stream_track(self, key: str) -> Track | None:
        """The drummer's track of streamed knots ``key`` (a limb, or "joints"), or None."""
        if key == "joints":
            return getattr(self.scene, "joint_track", None)
        tracks: dict[str, Track] = getattr(self.scene, "limb_tracks", {})
        return tracks.get(key)

    def _streamed_knots(self, key: str) -> list[StreamedKnot]:
        """Track ``key``'s streamed knots still queued (:attr:`_streamed`; the one in use and those after it): none
        once the track no longer ends with the last of them (cleared, or a plan queued over them: they are no longer
        the stream's)."""
        knots = self._streamed.get(key)
        if not knots:
            return []
        track = self._stream_track(key)
        if track is None or track.end_time != knots[-1].time:
            del self._streamed[key]
            return []
        used = bisect.bisect_right(knots, self.time - self.target_lag, key=itemgetter(1)) - 1
        if used > 0:
            del knots[:used]
        return knots

    def _record_streamed(self, key: str, time: float, rig_time: float, posture: bool = False) -> None:
        """A knot for rig time ``rig_time`` (s) was queued at ``time`` (s, the targets' clock) on track ``key`` (one
        of a posture's if ``posture``): it replaced the knots at and after that time (``Track.add``), and those for
        its rig time and after."""
        knots = self._streamed.setdefault(key, [])
        del knots[bisect.bisect_left(knots, time, key=itemgetter(1)):]
        while knots and knots[-1][0] >= rig_time:
            knots.pop()
        knots.append(StreamedKnot(rig_time, time, posture))

    def _stream_lag(self, key: str, rig_time: float) -> float:
        """The lag (s) a knot streamed for rig time ``rig_time`` (s) onto track ``key`` is queued with: the lag as it
        is (``target_lag``: reached at its rig time), unless that cuts knots streamed for rig times more than
        ``STREAM_SHORT_CUT_S`` before its own.

        A streamed knot at or before the last one queued replaces the tail from there (``Track.add``: a sender
        re-plans so). After the lag grew by more than the interval between two knots sent, the later one, placed
        with the lag as it is, lands before the earlier on the targets' clock and cuts it: the stream takes a short
        cut over the knots sent for earlier rig times. Measured live, every call 20-70 ms late, knots sent 200 ms
        ahead, a hand swaying 0.1 m at 2 Hz (distance from what was asked for the rig time, mean / max; lateness,
        mean / max; knots cut before their rig time):

        * always the lag as it is (before 7 Dec): 10 ms knots 46 / 157 mm, 68 / 145 ms late, 89 of 298 cut (each
          within 70 ms of the next kept); 50 ms knots 60 / 156 mm, 91 / 175 ms, 10 of 59 cut; 250 ms knots
          76 / 174 mm, 144 / 280 ms, none cut (the lag grew by less than 250 ms between two), but a longer
          skip cuts a sparse stream's waypoints (a stroke's lift);
        * never cut, closer than half the interval keep it and the knot before's lag (7 Dec, a few hours): 10 ms
          76 / 195 mm, 215 / 485 ms late, the dense stream drifting late until the targets jump back; 50 ms 77 /
          186 mm, 218 / 490 ms; 250 ms 74 / 185 mm, 167 / 445 ms;
        * never cut, at least half the interval (catch up at twice the sender's speed): 10 ms 98 / 186 mm, 149 /
          205 ms; 50 ms 93 / 186 mm, 146 / 205 ms;
        * cut within ``STREAM_SHORT_CUT_S`` of rig time, else keep the interval (this): 10 ms as always the lag;
          50 ms as always the lag; 250 ms as always the lag, and no knot more than ``STREAM_SHORT_CUT_S`` of rig
          time before the one that would cut it is ever cut.

        So a dense stream (mocap) takes short cuts over what it would play late anyway (the knots cut are within
        0.1 s of the one replacing them, which says where the limb should be then) and stays on time; a knot that
        would cut further (a sparse stream's waypoint) follows the knots before it at their interval and lag (the
        speeds its sender asked: a narrower interval would ask them faster, a short cut in time), and the stream
        plays on late by the lag grown since, as a queued plan does, until a later knot may cut back within 0.1 s
        or the targets jump back to that lag (it holds it: :meth:`_hold_streamed`). A knot that re-plans from an
        earlier rig time takes the place of the first knot it replaces if earlier.

        The lag growing by more than 0.1 s at once (a longer skip) made every later knot of a dense stream cut more
        than 0.1 s: it kept the lag of the knots before the skip, and the stream played late by all of it until the
        targets jumped back. A knot may now cut further when the knots it cuts, and the one kept before them, are a
        dense stream's (:meth:`_dense`: at least ``STREAM_DENSE_MIN_KNOTS``, each within ``STREAM_DENSE_S`` of the
        next, none a posture's; no lone waypoint): the first knot sent after the skip re-anchors the stream at the
        lag as it is. The gap a sender leaves over the rig time skipped is after the knots cut, not among them. How
        late the knot in use plays, with and without one such skip: bench/live_stream_lag.py (the table in
        docs/physics.md): a dense stream catches up, the knots queued before the skip still play late by it; a
        sparse one (250 ms) is as before."""
        lag = self.target_lag
        knots = self._streamed_knots(key)
        if not knots:
            return lag
        k = bisect.bisect_left(knots, rig_time, key=itemgetter(0))  # knots[:k]: for earlier rig times
        time = rig_time - lag
        if k:
            cut = bisect.bisect_left(knots, time, key=itemgetter(1))  # the first knot Track.add would replace
            if cut < k and rig_time - knots[cut][0] > STREAM_SHORT_CUT_S and not self._dense(knots[max(cut - 1, 0):k]):
                rig_before, before = knots[k - 1].rig_time, knots[k - 1].time  # a waypoint, not a short cut
                time = before + (rig_time - rig_before)
        if k < len(knots):
            time = min(time, knots[k][1])
        return rig_time - time

    @staticmethod
    def _dense(knots: Sequence[StreamedKnot]) -> bool:
        """Whether streamed knots, in order, are a dense stream's, whose knots a later one may cut over all the lag
        grown since (:meth:`_stream_lag`): at least ``STREAM_DENSE_MIN_KNOTS``, each within ``STREAM_DENSE_S`` of rig
        time of the next, none a posture's. A pair is not (two waypoints a sender meant, or a short posture's glide:
        cut, the body never went there)."""
        return (len(knots) >= STREAM_DENSE_MIN_KNOTS and not any(knot.posture for knot in knots)
                and all(b.rig_time - a.rig_time <= STREAM_DENSE_S + 1e-9 for a, b in itertools.pairwise(knots)))

    def _retime_streamed(self, t_from: float, lag: float) -> tuple[int, int]:
        """Move the streamed knots queued after ``t_from`` (s, the targets' clock) to their rig times less ``lag``
        (s, the targets' new lag), as if placed with it; returns how many were still ahead on the rig clock and how
        many were due already (behind the targets' new time: passed). A track whose knots from there on are not all
        the stream's (a plan queued among them) is left as it is. What was moved holds the new lag until it has
        played (:meth:`_hold_streamed`)."""
        ahead = passed = 0
        until = -math.inf
        rig = self.time
        for key in list(self._streamed):
            knots = self._streamed_knots(key)
            first = bisect.bisect_right(knots, t_from, key=itemgetter(1))
            if first == len(knots):
                continue
            track = self._stream_track(key)
            assert track is not None  # _streamed_knots found it
            times, values, velocities = track.knots(knots[first].time, track.end_time)
            if not np.array_equal(times, [knot.time for knot in knots[first:]]):
                del self._streamed[key]
                continue
            track.cut(knots[first][1])
            kept = knots[:first]
            for knot, value, velocity in zip(knots[first:], values, velocities, strict=True):
                rig_time = knot.rig_time
                time = rig_time - lag
                if time <= track.end_time:  # placed with less lag than the new: behind the knots before, passed
                    passed += 1
                    continue
                track.add(time, value, velocity)
                kept.append(knot._replace(time=time))
                until = max(until, time)
                if rig_time > rig:
                    ahead += 1
                else:
                    passed += 1
            self._streamed[key] = kept
        self.streamed_retimed += ahead
        self.streamed_passed += passed
        self._streamed_held = (lag, until) if lag > 0.0 and until > -math.inf else None
        return ahead, passed

    def _hold_streamed(self, lag: float, until: float) -> None:
        """Targets queued ``lag`` s early on the targets' clock (to be reached at their rig times) play until
        ``until`` (s, the targets' clock): keep that lag until then (:meth:`_lag_floor`); nothing with no lag."""
        if lag <= 0.0:
            return
        held = self._streamed_held  # the most lag: targets placed with less play late by the difference, not early
        self._streamed_held = (lag, until) if held is None else (max(lag, held[0]), max(until, held[1]))

    def _lag_floor(self, t: float) -> float:
        """The least lag (s) the live core's targets may jump back to at their clock's time ``t`` (s): the lag the
        score plans (``ScorePlayer.lag_floor``) or streamed targets (:attr:`_streamed_held`) still to play were
        placed with, the larger; else 0."""
        held = self._streamed_held
        if held is not None and t > held[1]:
            self._streamed_held = held = None
        return max(self.score_player.lag_floor(t), held[0] if held is not None else 0.0)

    def close(self) -> None:
        """Disconnect the PyBullet clients (the world and the scene's helpers)."""
        close = getattr(self.scene, "close", None)
        if close is not None:
            close()
        self.world.close()
