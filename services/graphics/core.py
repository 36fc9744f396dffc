"""Graphics core: poses and impacts in, view frames for the page out. Deterministic, no I/O.

The core buffers ``/batteur/pose`` by rig time and, at every step, produces a
:class:`ViewFrame` for display time ``now - latency`` (the same latency window
the sound service schedules strikes with, so picture and sound coincide),
interpolating between the two poses around it. Impacts (de-duplicated on
``seq`` per sender) animate the kit (:mod:`services.graphics.scene`). Health
and hello messages fill the status panel's node table. Graphics control
messages (:mod:`common.messages.graphics`) change the view settings sent to
every page.

Everything for the page leaves through :meth:`GraphicsCore.take_page_messages`
as plain JSON-able dicts; the node sends them over the WebSocket. The only OSC
the core sends is the pose editor's (:meth:`GraphicsCore.request_posture`):
``/batteur/physics/posture`` to physics (at most one per ``posture_period``,
on physics' clock) and ``/batteur/physics/reset`` when the editor lets go.
"""

from __future__ import annotations

import bisect
import logging
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from common.core import Outgoing
from common.kit import Kit, load_kit
from common.messages import Health, Hello, Impact, OscMessage, Pose, Skeleton
from common.messages.graphics import (
    GraphicsCamera,
    GraphicsLatency,
    GraphicsMode,
    GraphicsPlot,
    GraphicsPreviewBars,
    GraphicsPreviewRate,
    GraphicsRejected,
    GraphicsShow,
    GraphicsTrails,
    ScorePosition,
)
from common.messages.physics import PhysicsPosture, PhysicsReset
from common.messages.system import TOOL_ROLE
from common.rated_log import RatedWarnings
from common.score.events import Score
from common.score.position import bar_beat, bar_unit
from services.graphics.camera import camera_for, default_camera, presets_json
from services.graphics.preview import LOOP_PAUSE_S, PREVIEW_RATES, PreviewClock, bar_loop
from services.graphics.scene import HISTORY, KitAnimator, hardware_json, kit_json
from services.graphics.sequence import FLOATS_PER_LINK, PoseSequence, interpolate_pose, normalize_quats
from services.graphics.skeleton import guess_parents

CLOCK_JUMP = 0.5  # seconds: a pose clock this much behind the current offset has been restarted
CLOCK_SLEW = 0.1
"""Auto clock: how fast the offset may come down, seconds per second. When the largest recent lag ages out, the
display time advances 10 % slower until the offset matches, never steps back (trails and contacts would jump)."""
SEEN_IMPACTS = 4096  # impacts remembered per sender to drop redundant copies
MAX_SENDERS = 64  # impact senders remembered (least recently heard forgotten first)
MAX_NODES = 256  # nodes in the status table (least recently heard forgotten first)
NO_PREVIEW = ("no preview is loaded, the view stays live: start the graphics node with --preview-score SCORE or "
              "--preview FILE.npz")
"""Why ``/batteur/graphics/mode preview`` is refused on a node without a preview."""
SCORE_POSITION_KEPT_S = 1.0  # seconds a score position is shown after it arrived (the player sends 10 a second)
_MAX_BEAT, _MAX_BPM = 64.0, 1000.0  # ScorePosition's bounds (a longer bar or a faster tempo is shown at the bound)
_MAX_UNIT = 4.0  # and its beat_unit's (a whole note): a unit it cannot carry is counted in quarter notes
NO_PREVIEW_RATE = "no preview is loaded: there is no preview to slow down or speed up"
"""Why a preview rate is refused on a node without a preview."""
NO_PREVIEW_BARS = ("no score preview is loaded: there are no bars to loop (start the graphics node with "
                   "--preview-score SCORE)")
"""Why a bar range is refused on a node without a preview, or with a pose sequence file's (no score, no bars)."""
REFUSAL_LOG_INTERVAL_S = 1.0
"""Refusals of one kind are logged at most once per this many seconds of rig time (the others are counted and
summed into the next line), so a broken pose stream cannot flood the log."""

log = logging.getLogger("batteur.graphics")


class GraphicsSettings(BaseModel):
    """Settings of the graphics core (command line or configuration file)."""

    model_config = ConfigDict(extra="forbid")

    rate_hz: float = Field(default=60.0, ge=1, le=240, description="view frames per second, Hz")
    latency: float = Field(default=0.1, ge=0, le=5, description="display delay = the sound's latency window, s")
    buffer_seconds: float = Field(default=5.0, ge=0.5, le=60, description="pose history kept, seconds")
    kit: str = Field(default="default", description="kit name or file path")
    clock: Literal["auto", "rig"] = Field(
        default="auto", description="rig: trust the local rig time; auto: follow the clock of the poses"
    )
    status_period: float = Field(default=0.5, gt=0, le=10, description="status panel update period, seconds")
    decimals: int = Field(default=4, ge=2, le=7, description="decimals of positions/quaternions sent to the page")
    posture_period: float = Field(default=0.1, gt=0, le=5,
                                  description="pose editor: at most one posture to physics per this many seconds")
    posture_duration: float = Field(default=0.3, ge=0, le=10,
                                    description="pose editor: time physics takes to reach an edited posture, s")


class ViewSettings(BaseModel):
    """What the page shows and from where (changed over OSC or from the page)."""

    model_config = ConfigDict(extra="forbid")

    camera: dict[str, Any] = Field(default_factory=default_camera)  # the page's front preset (camera.py)
    layers: dict[str, bool] = Field(
        default_factory=lambda: {"body": True, "sticks": True, "kit": True, "contacts": True, "trails": True,
                                 "plot": True, "status": True, "floor": True}
    )
    trails: float = 1.0
    plot: dict[str, float] = Field(default_factory=lambda: {"window": 4.0, "z_min": 0.5, "z_max": 1.6})


@dataclass
class NodeSeen:
    """One node in the status table."""

    role: str
    node_id: str
    last_seen: float
    rate_hz: float = 0.0
    target_rate_hz: float = 0.0
    late: int = 0
    dropped: int = 0


@dataclass
class ViewFrame:
    """What the page draws at one display time.

    Attributes
    ----------
    time : float
        Display time on the rig clock, seconds (the pose time shown).
    pose : np.ndarray, shape (L, 7)
        Link poses, metres and quaternions (x y z w).
    kit : np.ndarray, shape (K, 4)
        Kit state per object (flash, swing_x, swing_y, extra), see ``scene``.
    hits : list
        Recent strikes (x, y, z, age seconds, instrument).
    """

    time: float
    pose: np.ndarray
    kit: np.ndarray
    hits: list[tuple[float, float, float, float, str]] = field(default_factory=list)

    def to_json(self, decimals: int = 4) -> dict[str, Any]:
        return {
            "type": "frame",
            "t": round(self.time, 4),
            "p": np.round(self.pose.ravel(), decimals).tolist(),
            "k": np.round(self.kit.ravel(), 4).tolist(),
            "h": [[round(x, 3), round(y, 3), round(z, 3), round(a, 3), name] for x, y, z, a, name in self.hits],
        }


class GraphicsCore:
    """The graphics service's core (see module docstring)."""

    ROLE: ClassVar[str] = "graphics"

    def __init__(self, settings: GraphicsSettings | None = None, kit: Kit | None = None) -> None:
        self.settings = settings or GraphicsSettings()
        self.rate_hz = self.settings.rate_hz
        self.latency = self.settings.latency
        self.kit = kit or load_kit(self.settings.kit)
        self.view = ViewSettings()
        self.animator = KitAnimator(self.kit)
        self.names: list[str] = []
        """The links the pages draw: the live stream's, the preview's figure or the editor's body."""
        self.parents: list[int] = []
        self.live_names: list[str] = []
        """The links of the live pose stream (/batteur/skeleton), whatever is shown."""
        self.layout = -1
        """The live stream's layout id (-1: no skeleton yet)."""
        self._times: deque[float] = deque()
        self._poses: deque[np.ndarray] = deque()
        self._seen_impacts: dict[str, dict[int, float]] = {}
        """Per sender, the recent impacts' seq -> time (oldest first)."""
        self.nodes: dict[str, NodeSeen] = {}
        self.score: ScorePosition | None = None
        self._score_seen = -math.inf
        """Local rig time the score position arrived, seconds (a stopped score stops sending)."""
        self.mode: Literal["live", "preview"] = "live"
        self.preview: PoseSequence | None = None
        self.preview_impacts: list[Impact] = []
        self.preview_score: Score | None = None
        """The score the preview plays (None: a pose sequence file): its bar and beat fill the status."""
        self.preview_clock = PreviewClock(0.0, 1.0)
        """Where the preview is at a rig time, at its playback rate (``--preview-rate``, the page's select)."""
        self._preview_rate = 1.0
        """The playback rate a preview loaded next starts with (a re-planned preview keeps the one chosen)."""
        self.preview_bars: tuple[int, int] | None = None
        """The bars (first, last, from 1) the score preview loops (None: the whole preview, with a pause)."""
        self._preview_animator = KitAnimator(self.kit)
        self.clock_offset = 0.0
        """Auto clock: the offset at ``_offset_since`` (local time); :meth:`offset_at` slews it down from there."""
        self._offset_since = 0.0
        self._offset_target = 0.0
        """Auto clock: the largest lag of the window, where the offset slews to."""
        self._lags: deque[tuple[float, float]] = deque()
        self.counters: dict[str, int] = {
            "poses": 0, "impacts": 0, "frames": 0, "bad_layout": 0, "no_skeleton": 0, "duplicate_impacts": 0,
            "starved": 0, "clock_jumps": 0, "postures_sent": 0, "pose_resets": 0, "mode_refused": 0,
            "preview_refused": 0,
        }
        self._refusal_warnings = RatedWarnings(log, REFUSAL_LOG_INTERVAL_S)
        """Refusals logged at most once per :data:`REFUSAL_LOG_INTERVAL_S` of rig time for each kind."""
        self._outbox: list[dict[str, Any]] = []
        self._last_status = -math.inf
        self.last_frame: ViewFrame | None = None
        self._edit: np.ndarray | None = None
        self._edit_names: list[str] = []
        self._posture: np.ndarray | None = None
        self._posture_sent = -math.inf
        self._release = False
        self.page_sink: Callable[[list[dict[str, Any]]], None] | None = None
        """If set, called with the page messages at the end of every step (the node's WebSocket broadcast)."""

    # --- the Core protocol --------------------------------------------------------------------
    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Pose):
            self._on_pose(message, now, source)
        elif isinstance(message, Skeleton):
            self._on_skeleton(message)
        elif isinstance(message, Impact):
            self._on_impact(message, source)
        elif isinstance(message, (Health, Hello)) and message.role == TOOL_ROLE:
            pass  # a tool asking, not a node: listing it would show the rig a node that is not there
        elif isinstance(message, Health):
            node = self._node_seen(message.node_id, message.role, now)
            node.role = message.role
            node.rate_hz, node.target_rate_hz = message.rate_hz, message.target_rate_hz
            node.late, node.dropped = message.late, message.dropped
        elif isinstance(message, Hello):
            self._node_seen(message.node_id, message.role, now)
        elif isinstance(message, ScorePosition):
            self.score, self._score_seen = message, now
        elif isinstance(message, GraphicsMode) and message.mode == "preview" and self.preview is None:
            self.apply_control(message)  # the view stays live, and the pages are told so
            self.counters["mode_refused"] += 1
            self._log_refusal("mode", now, f"graphics refused /batteur/graphics/mode preview from {source}: "
                              f"{NO_PREVIEW}")
            return [Outgoing(GraphicsRejected(address=message.ADDRESS, reason=NO_PREVIEW), "reply")]
        elif isinstance(message, (GraphicsPreviewRate, GraphicsPreviewBars)):
            try:
                if isinstance(message, GraphicsPreviewRate):
                    # OSC carries a float32: 0.6 arrives as 0.6000000238, which the page and status would show
                    self.set_preview_rate(round(message.rate, 4), now)
                else:
                    self.set_preview_bars(message.bars, now)
            except ValueError as exc:  # no preview, no score, bars past it: the sender is told, the preview plays on
                self.counters["preview_refused"] += 1
                self._log_refusal("preview", now, f"graphics refused {message.ADDRESS} from {source}: {exc}")
                return [Outgoing(GraphicsRejected(address=message.ADDRESS, reason=str(exc)[:512]), "reply")]
        else:
            self.apply_control(message)
        return []

    @property
    def rejected_total(self) -> int:
        """Messages this core refused, total: poses of the wrong length or another layout, the preview mode with
        no preview loaded, and a preview rate or bar range it cannot apply (``preview_refused``). The node's Health
        counts them in ``dropped`` and ``dropped_other``; poses before any skeleton (a node starting before physics'
        layout reached it) are only counted (``no_skeleton``)."""
        return self.counters["bad_layout"] + self.counters["mode_refused"] + self.counters["preview_refused"]

    def clock_stepped(self, step_s: float, now: float) -> list[Outgoing]:
        """The node's rig time just stepped by ``step_s`` seconds (the clock master restarted): move the times this
        core stamped by its own clock with it, so the page's status (once per ``status_period``), the editor's
        postures (one per ``posture_period``), node ages and the score position go on as before the step, not
        only once rig time is back where it was. Poses and impacts are on physics' clock: untouched."""
        del now
        self._last_status += step_s
        self._posture_sent += step_s
        self._score_seen += step_s
        self.preview_clock.shift(step_s)
        for node in self.nodes.values():
            node.last_seen += step_s
        # auto clock: the lags (pose time - local time) seen so far, as the new local clock would have seen them
        self._lags = deque((t + step_s, lag - step_s) for t, lag in self._lags)
        if self._lags:
            self._offset_since += step_s
            self.clock_offset -= step_s
            self._offset_target -= step_s
        return []

    def _log_refusal(self, kind: str, now: float, detail: str) -> None:
        """Warn about a refusal, at most once per :data:`REFUSAL_LOG_INTERVAL_S` of rig time for each kind."""
        self._refusal_warnings.warn(kind, now, detail)

    def step(self, now: float) -> list[Outgoing]:
        frame = self.frame_at(now)
        if frame is not None:
            self.last_frame = frame
            self.counters["frames"] += 1
            self._outbox.append(frame.to_json(self.settings.decimals))
        if now - self._last_status >= self.settings.status_period:
            self._last_status = now
            self._outbox.append(self.status(now))
        if self.page_sink is not None:
            self.page_sink(self.take_page_messages())
        return self._postures(now)

    def _node_seen(self, node_id: str, role: str, now: float) -> NodeSeen:
        """The status table's entry of ``node_id``, heard at ``now``; the table keeps :data:`MAX_NODES`."""
        node = self.nodes.pop(node_id, None) or NodeSeen(role, node_id, now)
        node.last_seen = now
        self.nodes[node_id] = node  # most recently heard last
        while len(self.nodes) > MAX_NODES:  # made-up ids (a broken tool) must not grow it without bound
            del self.nodes[next(iter(self.nodes))]
        return node

    # --- the pose editor driving physics ------------------------------------------------------
    def request_posture(self, angles: np.ndarray | None) -> None:
        """Pose editor: send physics these 57 joint angles (radians) at the next step (rate-limited).

        ``None`` releases the body: a /batteur/physics/reset if any posture was sent.
        """
        if angles is None:
            self._release = self._release or self.counters["postures_sent"] > 0 or self._posture is not None
            self._posture = None
            return
        self._release = False
        self._posture = np.asarray(angles, dtype=float).copy()

    def _postures(self, now: float) -> list[Outgoing]:
        physics_now = now + self.offset_at(now)  # physics' rig time as its poses tell (auto clock)
        if self._release:
            self._release = False
            self.counters["postures_sent"] = 0
            return [Outgoing(PhysicsReset(time=max(physics_now, 0.0)), "physics")]
        if self._posture is None or now - self._posture_sent < self.settings.posture_period:
            return []
        message = PhysicsPosture(time=max(physics_now, 0.0), duration=self.settings.posture_duration,
                                 values=tuple(float(v) for v in self._posture))
        self._posture = None
        self._posture_sent = now
        self.counters["postures_sent"] += 1
        return [Outgoing(message, "physics")]

    def live_body(self) -> tuple[list[str], np.ndarray] | None:
        """The newest pose received (names, (L, 7)), not an edited one; None before any."""
        if not self._poses or len(self._poses[-1]) != len(self.live_names):
            return None
        return list(self.live_names), self._poses[-1].copy()

    # --- inputs -------------------------------------------------------------------------------
    def _on_skeleton(self, message: Skeleton) -> None:
        names = list(message.names)
        if message.layout == self.layout and names == self.live_names:
            return
        self.set_skeleton(names, message.layout)

    def set_skeleton(self, names: list[str], layout: int = 0) -> None:
        """Adopt a new link layout of the live stream; forgets buffered poses of the old one."""
        self.live_names = list(names)
        self.layout = layout
        self._times.clear()
        self._poses.clear()
        self.animator.bind(self.live_names)
        self._show()

    def _shown_names(self) -> list[str]:
        """The links drawn now: the editor's body over the preview's figure over the live stream's."""
        if self._edit is not None:
            return self._edit_names
        if self.mode == "preview" and self.preview is not None:
            return list(self.preview.names)
        return self.live_names

    def _show(self) -> None:
        """Tell the pages when the links they must draw change (live, preview and editor each have theirs).

        Frames the page gets must match its skeleton (it drops the others): a live skeleton arriving while
        the preview is shown must not replace the preview's on the page.
        """
        names = self._shown_names()
        if names != self.names:
            self.names = list(names)
            self.parents = guess_parents(self.names)
            self._outbox.append(self.skeleton_json())

    def _on_pose(self, message: Pose, now: float, source: str) -> None:
        count = len(message.values)
        if count % FLOATS_PER_LINK:  # no layout has it: a broken sender, with or without a skeleton
            self._refuse_pose(now, f"{count} values, not {FLOATS_PER_LINK} per link (x y z qx qy qz qw)", source)
            return
        if self.layout < 0:
            self.counters["no_skeleton"] += 1  # waiting for physics' layout (it answers this node's Hello with it)
            return
        if message.layout != self.layout:
            self._refuse_pose(now, f"layout {message.layout}, not the skeleton's {self.layout} (a pose of another "
                              "physics node, or sent before its /batteur/skeleton)", source)
            return
        if count != FLOATS_PER_LINK * len(self.live_names):
            self._refuse_pose(now, f"{count // FLOATS_PER_LINK} links, the skeleton of layout {self.layout} has "
                              f"{len(self.live_names)}", source)
            return
        if self.settings.clock == "auto":
            self._follow_clock(message.time - now, now)
        if self._times and message.time < self._times[-1] - CLOCK_JUMP:
            # the pose clock went back (physics restarted, or the newest pose was a stray from the future):
            # the buffered poses would hide the new ones until the new clock caught up with them
            self._times.clear()
            self._poses.clear()
            self.counters["pose_resets"] += 1
        values = np.asarray(message.values, dtype=float).reshape(len(self.live_names), FLOATS_PER_LINK)
        values[:, 3:] = normalize_quats(values[:, 3:])  # a zero quaternion (broken sender) would stop the kit
        if self._times and message.time <= self._times[-1]:
            if message.time == self._times[-1]:
                return
            i = bisect.bisect_left(list(self._times), message.time)
            self._times.insert(i, message.time)
            self._poses.insert(i, values)
        else:
            self._times.append(message.time)
            self._poses.append(values)
        self.counters["poses"] += 1
        horizon = self._times[-1] - self.settings.buffer_seconds
        while self._times and self._times[0] < horizon:
            self._times.popleft()
            self._poses.popleft()

    def _refuse_pose(self, now: float, why: str, source: str) -> None:
        self.counters["bad_layout"] += 1
        self._log_refusal("pose", now, f"graphics dropped /batteur/pose from {source}: {why}")

    def _follow_clock(self, lag: float, now: float) -> None:
        """Auto clock: offset = the largest ``pose time - local time`` seen over the last 2 s.

        Transport delays only make the lag smaller, so the largest recent lag is
        the pose clock's offset plus the smallest delay. A larger lag moves the
        offset up at once (display time steps forward); a smaller one, when the
        largest ages out of the window, is slewed to at :data:`CLOCK_SLEW` so the
        display time never goes back. A drop of more than :data:`CLOCK_JUMP` (a
        restarted physics clock) resets the window and steps the offset.
        """
        lags = self._lags
        current = self.offset_at(now) if lags else lag  # the first pose sets the clock
        if lags and lag < self._offset_target - CLOCK_JUMP:
            lags.clear()
            self.counters["clock_jumps"] += 1
            current = lag
        lags.append((now, lag))
        while lags and lags[0][0] < now - 2.0:
            lags.popleft()
        self._offset_target = max(value for _, value in lags)
        if current - self._offset_target > CLOCK_JUMP:
            # lags dropping window after window: the slew never trails by more than a restart would step
            current = self._offset_target
            self.counters["clock_jumps"] += 1
        self.clock_offset = max(current, self._offset_target)
        self._offset_since = now

    def offset_at(self, now: float) -> float:
        """The clock offset at local time ``now``: the last one, slewed down toward the window's largest lag."""
        slewed = self.clock_offset - CLOCK_SLEW * max(0.0, now - self._offset_since)
        return max(self._offset_target, slewed) if self.settings.clock == "auto" else self.clock_offset

    def _on_impact(self, message: Impact, source: str) -> None:
        """Animate the kit with a strike; a redundant copy (same sender, ``seq`` and time) is counted, dropped.

        The time is part of the key: a restarted interaction node counts from seq 0 again on the same
        address, and its strikes must not be taken for copies of the old ones.
        """
        seen = self._seen_impacts.pop(source, None) or {}
        self._seen_impacts[source] = seen  # most recently heard last
        while len(self._seen_impacts) > MAX_SENDERS:
            del self._seen_impacts[next(iter(self._seen_impacts))]
        if seen.get(message.seq) == message.time:
            self.counters["duplicate_impacts"] += 1
            return
        seen.pop(message.seq, None)
        seen[message.seq] = message.time
        while len(seen) > SEEN_IMPACTS:
            del seen[next(iter(seen))]
        self.counters["impacts"] += 1
        self.animator.add(message)

    def apply_control(self, message: OscMessage) -> bool:
        """Apply one graphics control message; True when it was one.

        The view message it sends names the setting (``control``: ``camera``, ``layer:NAME``, ...), so a page
        replaces its own camera or layer choice only with one the node was sent, not on any other control.
        """
        control = type(message).ADDRESS.rsplit("/", 1)[-1]
        if isinstance(message, GraphicsCamera):
            # a named preset keeps its own numbers (the page draws those), so the core reports where the view is
            self.view.camera = camera_for(message.preset, message.azimuth_deg, message.elevation_deg,
                                          message.distance, (message.target_x, message.target_y, message.target_z))
        elif isinstance(message, GraphicsShow):
            self.view.layers[message.layer] = bool(message.visible)
            control = f"layer:{message.layer}"
        elif isinstance(message, GraphicsTrails):
            self.view.trails = message.seconds
        elif isinstance(message, GraphicsPlot):
            # the model refuses z_max <= z_min (with a reply), so the range is shown as sent
            self.view.plot = {"window": message.window, "z_min": message.z_min, "z_max": message.z_max}
        elif isinstance(message, GraphicsLatency):
            self.latency = message.seconds
        elif isinstance(message, GraphicsMode):
            self.mode = message.mode if (message.mode == "live" or self.preview is not None) else "live"
            self._show()
        else:
            return False
        self._outbox.append({**self.view_json(), "control": control})
        return True

    # --- preview (kinematic keyframe animation, no physics) ----------------------------------
    def load_preview(self, sequence: PoseSequence, impacts: list[Impact] | None = None, now: float | None = None,
                     score: Score | None = None, rate: float | None = None,
                     loop: tuple[float, float] | None = None, bars: tuple[int, int] | None = None) -> None:
        """Show ``sequence`` (e.g. the keyframe animation of a score) instead of the live stream.

        It plays from its first pose at rig time ``now`` (None: when it is first shown) and loops, at ``rate``
        (motion seconds per second; None: the rate of the preview shown before, else 1). ``impacts`` (times on the
        sequence's clock) flash and swing the kit as live ones do. ``score`` (the sequence's clock being the
        score's, as ``score_preview`` makes it) gives the status panel the preview's bar and beat. ``loop`` (start,
        end), seconds on the sequence's clock: play only that span, with no pause between laps (a bar range);
        ``bars`` (first, last, from 1) of ``score``: the span of those bars (``ValueError``, nothing changed, for
        a range ending past the bar of the score's last note or without a score).
        """
        if bars is not None:
            if score is None:
                raise ValueError(NO_PREVIEW_BARS)
            loop = bar_loop(score, list(impacts or []), float(sequence.times[-1]), *bars)
        self.preview_bars = bars
        self.preview = sequence
        self.preview_impacts = sorted(impacts or [], key=lambda i: i.time)
        self.preview_score = score
        if rate is not None:
            self._preview_rate = rate
        if loop is None:
            self.preview_clock = PreviewClock(sequence.times[0], sequence.duration, now, self._preview_rate)
        else:
            self.preview_clock = PreviewClock(loop[0], loop[1] - loop[0], now, self._preview_rate, pause=0.0)
        self._preview_animator = KitAnimator(self.kit)
        self._preview_animator.bind(sequence.names)
        self.mode = "preview"
        self._show()
        self._outbox.append(self.view_json())

    def set_preview_rate(self, rate: float, now: float) -> None:
        """Play the preview at ``rate`` from rig time ``now`` (from where it is); every page is told. ``ValueError``
        for a rate out of range or no preview loaded."""
        if self.preview is None:
            raise ValueError(NO_PREVIEW_RATE)
        self.preview_clock.set_rate(rate, now)
        self._preview_rate = self.preview_clock.rate
        self._outbox.append({**self.view_json(), "control": "preview_rate"})

    def set_preview_bars(self, bars: tuple[int, int] | None, now: float) -> None:
        """Loop bars (first, last) of the previewed score (from 1; None: the whole preview, with its pause) from rig
        time ``now``; the motion goes on from where it is when that is inside the new range, else from the range's
        start. Every page is told. ``ValueError`` (nothing changed) with no score preview loaded or a range ending
        past the bar of the score's last note."""
        if self.preview is None or self.preview_score is None:
            raise ValueError(NO_PREVIEW_BARS)
        times = self.preview.times
        if bars is None:
            start, end, pause = float(times[0]), float(times[-1]), LOOP_PAUSE_S
        else:
            try:
                start, end = bar_loop(self.preview_score, self.preview_impacts, float(times[-1]), *bars)
            except ValueError as exc:
                raise ValueError(f"bars {bars[0]} to {bars[1]}: {exc}") from None
            pause = 0.0
        # the whole preview's span is its duration, as load_preview gives it
        self.preview_clock.set_span(start, end - start, pause, now)
        self.preview_bars = bars
        self._outbox.append({**self.view_json(), "control": "preview_bars"})

    def preview_position(self, now: float) -> ScorePosition | None:
        """Where the previewed score is at rig time ``now``: the bar and beat of the motion shown, from the score's
        beats as physics' score player computes them (``common.score.position.bar_beat``), the tempo as played
        (written x rate). None without a score, before its first beat, or with the live view shown."""
        if self.mode != "preview" or self.preview is None or self.preview_score is None:
            return None
        where = bar_beat(self.preview_score, self.preview_clock.position(now))
        if where is None:
            return None
        # the beat the page counts the bar in: its meter's 1/D note, as physics' score player sends it
        unit = bar_unit(self.preview_score, where.bar)
        return ScorePosition(time=now, bar=where.bar, beat=min(where.beat, _MAX_BEAT),
                             tempo_bpm=min(where.tempo_bpm * self.preview_clock.rate, _MAX_BPM),
                             beat_unit=unit if 0 < unit <= _MAX_UNIT else 1.0)

    def preview_counts(self, now: float) -> dict[str, Any] | None:
        """The preview's own numbers for the status (None with none loaded): its ``rate``, its ``poses`` and
        ``strokes`` (of the span it loops), the strokes ``played`` in this lap and the ``laps`` completed."""
        if self.preview is None:
            return None
        clock = self.preview_clock
        times = [i.time for i in self.preview_impacts]
        first = bisect.bisect_left(times, clock.start)
        strokes = bisect.bisect_left(times, clock.start + clock.span) - first
        played = min(bisect.bisect_right(times, clock.position(now)) - first, strokes)
        return {"rate": clock.rate, "poses": len(self.preview.times), "strokes": strokes,
                "played": played, "laps": clock.lap(now)}

    def show_pose(self, names: list[str] | None, pose: np.ndarray | None) -> None:
        """Show one still pose (L, 7) of links ``names`` (the pose editor); ``None`` goes back to the stream."""
        if names is None or pose is None:
            self._edit, self._edit_names = None, []
        else:
            self._edit, self._edit_names = np.asarray(pose, dtype=float), list(names)
        self._show()

    def _preview_frame(self, now: float) -> ViewFrame | None:
        seq = self.preview
        if seq is None:
            return None
        local = self.preview_clock.position(now)
        animator = self._preview_animator
        animator.impacts = [i for i in self.preview_impacts if local - HISTORY <= i.time <= local]
        pose = seq.sample(float(local))
        return ViewFrame(float(local), pose, animator.state(float(local), pose), animator.hits(float(local)))

    # --- outputs ------------------------------------------------------------------------------
    def display_time(self, now: float) -> float:
        """Rig time of the pose shown at local time ``now``: ``now + clock offset - latency``."""
        return now + self.offset_at(now) - self.latency

    def frame_at(self, now: float) -> ViewFrame | None:
        """The frame to show at rig time ``now`` (None before any pose)."""
        preview = self._preview_frame(now) if self.mode == "preview" and self.preview is not None else None
        if self._edit is not None:  # the editor's still body; the kit keeps flashing and marking the strikes
            if preview is not None:  # the previewed score's, as with the editor closed
                return ViewFrame(preview.time, self._edit.copy(), preview.kit, preview.hits)
            shown = self.display_time(now)
            return ViewFrame(shown, self._edit.copy(), self.animator.state(shown, None), self.animator.hits(shown))
        if preview is not None:
            return preview
        if not self._times:
            return None
        t = self.display_time(now)
        times = self._times
        if t >= times[-1]:  # starved: hold the newest pose, the kit keeps moving
            if t > times[-1] + 2.0 / self.rate_hz:
                self.counters["starved"] += 1
            pose = self._poses[-1].copy()
        elif t <= times[0]:
            pose = self._poses[0].copy()
        else:
            i = bisect.bisect_right(times, t) - 1
            u = (t - times[i]) / (times[i + 1] - times[i])
            pose = interpolate_pose(self._poses[i], self._poses[i + 1], u)
        shown = t
        return ViewFrame(shown, pose, self.animator.state(shown, pose), self.animator.hits(shown))

    def take_page_messages(self) -> list[dict[str, Any]]:
        """Messages for every connected page since the last call (frames, status, settings)."""
        out, self._outbox = self._outbox, []
        return out

    def skeleton_json(self) -> dict[str, Any]:
        return {"type": "skeleton", "layout": self.layout, "names": self.names, "parents": self.parents}

    def kit_message(self) -> dict[str, Any]:
        """The kit the page draws and the hardware physics builds around it (beaters, stands)."""
        return {"type": "kit", "kit": kit_json(self.kit), "hardware": hardware_json(self.kit)}

    def view_json(self) -> dict[str, Any]:
        return {"type": "view", "mode": self.mode, "latency": self.latency, **self.view.model_dump(),
                "presets": presets_json(),
                "preview_rate": self.preview_clock.rate if self.preview is not None else None,
                "preview_rates": list(PREVIEW_RATES),
                # a score preview loops bars; a pose sequence file has none to loop (null)
                "preview_bars": (list(self.preview_bars) if self.preview_bars is not None else "all")
                if self.preview is not None and self.preview_score is not None else None}

    def set_kit(self, kit: Kit) -> None:
        """Adopt an edited kit (already validated) and tell every page."""
        self.kit = kit
        self.animator.set_kit(kit)
        self._preview_animator.set_kit(kit)
        self._outbox.append(self.kit_message())

    def welcome(self) -> list[dict[str, Any]]:
        """Everything a newly connected page needs before frames: kit, skeleton, view."""
        out = [self.kit_message(), self.view_json()]
        if self.names:
            out.insert(1, self.skeleton_json())
        return out

    def status(self, now: float) -> dict[str, Any]:
        nodes: list[dict[str, Any]] = [
            {"role": n.role, "id": n.node_id, "rate_hz": round(n.rate_hz, 1), "target_hz": n.target_rate_hz,
             "age": round(now - n.last_seen, 1), "late": n.late, "dropped": n.dropped}
            for n in sorted(self.nodes.values(), key=lambda n: (n.role, n.node_id))
            if now - n.last_seen < 10.0
        ]
        late = sum(int(n["late"]) for n in nodes if n["role"] == "sound")
        score = None
        position = self.preview_position(now) if self.mode == "preview" and self.preview is not None else (
            self.score if self.score is not None and now - self._score_seen <= SCORE_POSITION_KEPT_S else None)
        if position is not None:  # the preview's own position while it is shown, else the score player's
            score = {"bar": position.bar, "beat": round(position.beat, 2), "tempo_bpm": round(position.tempo_bpm, 1),
                     "beat_unit": position.beat_unit}
        newest = self._times[-1] if self._times else None
        return {
            "type": "status", "time": round(now, 3), "mode": self.mode, "latency": self.latency,
            "nodes": nodes, "late": late, "score": score, "counters": dict(self.counters),
            "preview": self.preview_counts(now) if self.mode == "preview" else None,
            "pose_lag": None if newest is None else round(now + self.offset_at(now) - newest, 3),
        }
