"""Impact detection: segment each (instrument, striker part) contact stream into impacts and presses.

Physics sends one ``/batteur/contact`` per step while a striker touches an
instrument. Per (instrument, striker) track (a striker's parts, e.g. a stick's
tip and shaft, share one track: :meth:`Segmenter.striker_of`):

* A contact after a silence whose approach velocity is at least
  ``strike_velocity_min`` is an **impact**, emitted at once (:class:`ImpactOnset`)
  with what the first step tells: time, position, zone, approach velocity
  (impulse, peak force and duration 0: not known yet).
* Re-contacts less than ``retrigger_gap`` after the previous contact step are
  **chatter** of the same contact: they never retrigger; their impulse and
  force add to the impact being measured.
* When the contact is over (no step for ``retrigger_gap``), the impact is
  final (:class:`ImpactFinal`): total impulse, peak force, duration.
* A new impact within ``bounce_window`` of the previous contact's end, slower
  than ``bounce_ratio`` times the previous impact, is a **bounce** (the first)
  or **buzz** (the following ones) of the same stroke; otherwise a **strike**.
  Bounces and buzz are real strikes and sound; their kind is reported.
* A contact slower than ``strike_velocity_min`` (or its striker's own
  ``part_velocity_min``) is a **touch**: no impact.
* A re-contact of the same striker within ``mask_window`` (30 ms) of its last
  impact's onset and slower than ``mask_ratio`` (0.5) times that impact is the
  stroke's own rebound touch (the stick falling back onto the head 10-25 ms
  later at a fraction of the speed): no impact, counted as ``masked``. An
  e-kit's trigger does the same (retrigger mask: a second hit must beat a
  threshold set by the first), so a stroke sounds once; a double stroke of
  similar speed 20 ms apart still gives two strikes.
* A contact of a rattle part (``rattle_parts``: ``hihat_rattle``, the hi-hat's
  plates knocked together by a stick while the foot is not closing the pedal, as
  physics reports them) is that stroke's **rattle**: no impact (counted). The
  plates meeting while the foot closes the pedal (``hihat_top``) are a chick.
  Plates meeting too slowly for either (``plate_parts`` touching: the foot
  letting the pedal down) come to rest together: a **press** at once (physics
  reports resting plates for 10 ms only), which closes the hat in the sound.
* A contact (touch or strike) lasting ``press_after`` or longer is a **press**:
  :class:`DampingChange` on, and off when it ends. A strike that turns into a
  press is a **dead** stroke: its figures are final when the press begins.

Bad streams: a step of a contact already over, delivered late or twice, is
dropped (``out_of_order``); a contact datagram delivered twice (UDP may
duplicate) is dropped (``duplicates``): it is told from another contact point
of the same step by its content, which two points never share (their
positions differ), so its impulse is not added twice; a contact more than ``CLOCK_JUMP_S`` older than
the newest is a physics clock that went back (a restarted physics node):
every contact ends and segmentation starts again (``clock_resets``). At most
``MAX_TRACKS`` tracks are kept (``dropped`` counts contacts refused for room).

Deterministic; no clock but the times given.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field, replace
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from common.kit import Kit, KitObject
from common.messages import Contact
from services.interaction.features import PLAYABLE_KINDS, ZoneConfig, hihat_openness, polar, zone

SEQ_LIMIT = 2**31
"""Sequence numbers wrap here (they travel as OSC int32)."""
RECENT_CONTACTS = 64
"""Contacts remembered per track to drop repeated datagrams: PyBullet reports at most 4 points per pair and
step, so this covers the last 16 steps at least; a network repeats a datagram within microseconds."""

FLOAT32_MAX = 3.4028234663852886e38
"""Largest value an OSC float32 carries; larger figures cannot be sent, so they are held to it."""

MAX_TRACKS = 256
"""Most (instrument, striker) tracks kept: a kit has about 15 instruments and a few strikers; contacts of
ever new striker names (a broken or hostile sender) must not grow memory or the per-contact work."""

CLOCK_JUMP_S = 1.0
"""A contact this much older than the newest physics time (seconds) comes from a physics clock that went back
(physics restarted with a new epoch): segmentation starts again, or every later step would end and restart
its contact (one impact per step, no presses) until physics' time caught up with the old one."""

ImpactKind = Literal["strike", "bounce", "buzz", "dead"]


class DetectionConfig(BaseModel):
    """Thresholds of the contact segmentation (module docstring). Seconds, metres per second."""

    model_config = ConfigDict(extra="forbid")

    strike_velocity_min: float = Field(default=0.05, ge=0, le=10, description="slowest strike, m/s")
    part_velocity_min: dict[str, Annotated[float, Field(ge=0, le=100)]] = Field(
        default_factory=lambda: {"hihat_top": 0.1},
        description="slowest strike of particular strikers, m/s (default: a hi-hat's top plate closing slower than "
                    "0.1 m/s is the foot letting it down, silent, as an e-kit's pedal sensor does not report it)",
    )
    retrigger_gap: float = Field(default=0.004, gt=0, le=0.1, description="re-contact sooner is chatter, s")
    bounce_window: float = Field(default=0.06, ge=0, le=1, description="a faster re-strike is a bounce, s")
    bounce_ratio: float = Field(default=0.85, ge=0, le=1, description="a bounce is slower than this x previous")
    press_after: float = Field(default=0.025, gt=0, le=2, description="contact this long is a press, s")
    mask_window: float = Field(default=0.03, ge=0, le=0.2,
                               description="a re-contact this soon after a striker's impact onset ... s")
    mask_ratio: float = Field(default=0.5, ge=0, le=1,
                              description="... and slower than this x that impact is the same stroke's rebound "
                                          "touch (an e-kit trigger's retrigger mask): no impact")
    rattle_parts: tuple[str, ...] = Field(
        default=("hihat_rattle",),
        description="parts whose contacts are another stroke's rattle, never strikes (physics reports the hi-hat's "
                    "plates meeting while the foot is not closing the pedal as hihat_rattle; closing: hihat_top)",
    )
    plate_parts: tuple[str, ...] = Field(
        default=("hihat_top", "hihat_rattle"),
        description="a hi-hat's plate parts: their touch (too slow for a chick or a rattle: the foot letting the "
                    "pedal down) is the plates coming to rest together, a press at once (physics reports resting "
                    "plates for 10 ms only), which the sound takes as the hat closing",
    )
    default_step: float = Field(default=0.001, gt=0, le=0.1, description="physics step until measured, s")
    part_suffixes: tuple[Annotated[str, Field(min_length=1)], ...] = Field(
        default=("_tip", "_shaft", "_shoulder", "_butt"),
        description="parts of one striker: contacts of left_stick_tip and left_stick_shaft are one track",
    )
    zones: ZoneConfig = Field(default_factory=ZoneConfig)


@dataclass
class ImpactFeatures:
    """Everything known about one impact. Seconds, metres, m/s, newton-seconds, newtons."""

    seq: int
    time: float
    instrument: str
    part: str
    zone: str
    kind: ImpactKind
    r: float
    theta: float
    x: float
    y: float
    z: float
    local_x: float
    local_y: float
    local_z: float
    velocity: float
    impulse: float
    peak_force: float
    duration: float
    final: bool = False
    openness: float = -1.0
    """A hi-hat stroke's openness as heard, 0 closed ... 1 open (features.hihat_openness of the contact's gap); -1
    for another instrument or a contact without the gap."""

    def feature(self, name: str) -> float | str:
        """One feature by name (``FEATURES``); raises KeyError for an unknown name."""
        if name not in FEATURES:
            raise KeyError(f"unknown impact feature {name!r} (known: {', '.join(sorted(FEATURES))})")
        value: float | str = getattr(self, name)
        return value


FEATURES: frozenset[str] = frozenset(
    {
        "seq",
        "time",
        "instrument",
        "part",
        "zone",
        "kind",
        "r",
        "theta",
        "x",
        "y",
        "z",
        "local_x",
        "local_y",
        "local_z",
        "velocity",
        "impulse",
        "peak_force",
        "duration",
        "openness",
    }
)
"""Impact features a mapping or a registered message can use."""

STRING_FEATURES: frozenset[str] = frozenset({"instrument", "part", "zone", "kind"})


@dataclass
class ImpactOnset:
    """An impact at its first contact step: impulse, peak force and duration are 0 (not known yet)."""

    impact: ImpactFeatures
    contact_time: float


@dataclass
class ImpactFinal:
    """An impact whose contact is over (or became a press): final impulse, peak force, duration."""

    impact: ImpactFeatures


@dataclass
class DampingChange:
    """A press began (state 1) or ended (state 0)."""

    seq: int
    time: float
    instrument: str
    part: str
    state: int
    zone: str
    r: float
    theta: float
    force: float


SegmentEvent = ImpactOnset | ImpactFinal | DampingChange


@dataclass
class DetectionStats:
    """Counters of the segmentation since start."""

    contacts: int = 0
    chatter: int = 0
    touches: int = 0
    ignored: int = 0
    unknown_instrument: int = 0
    out_of_order: int = 0  # steps older than their track's last (counted), and late steps of ended contacts (dropped)
    dropped: int = 0  # contacts of a new striker while MAX_TRACKS tracks are in use
    clock_resets: int = 0  # the physics clock went back (physics restarted): segmentation started again
    reopened: int = 0  # contacts the receiver's clock ended too early, continued by later steps
    rattles: int = 0  # a rattle striker's contacts right after a stroke on its instrument (no impact)
    masked: int = 0  # re-contacts inside a striker's retrigger mask (the stroke's own rebound touch; no impact)
    duplicates: int = 0  # contact datagrams received twice (dropped: their impulse would count twice)
    impacts: Counter[str] = field(default_factory=Counter)  # by kind
    by_instrument: dict[str, Counter[str]] = field(default_factory=dict)  # instrument -> kind -> count
    dampings: int = 0

    def count(self, instrument: str, kind: str) -> None:
        self.by_instrument.setdefault(instrument, Counter())[kind] += 1


@dataclass
class _Track:
    instrument: str
    part: str
    obj: KitObject
    active: bool = False
    start: float = 0.0
    last: float = 0.0
    last_step: int = -1
    open: ImpactFeatures | None = None
    pressing: bool = False
    press_force: float = 0.0
    press_steps: int = 0
    first_contact: Contact | None = None
    prev_velocity: float = 0.0
    prev_onset: float = -math.inf
    """Time of the track's last impact onset, seconds."""
    prev_end: float | None = None
    chain: int = 0
    ended_by_clock: bool = False
    recent: deque[tuple[object, ...]] = field(default_factory=lambda: deque(maxlen=RECENT_CONTACTS))
    """Contents of the track's last contacts, to tell a datagram delivered twice from another contact point."""


class Segmenter:
    """Turns contacts into impact onsets, finals and damping changes (module docstring).

    Parameters
    ----------
    kit : the kit model (object kinds and radii for r/a and zones)
    config : thresholds
    seq_start : first impact sequence number (a node starts from a fresh value
        so receivers notice a restart)
    """

    def __init__(self, kit: Kit, config: DetectionConfig | None = None, seq_start: int = 0) -> None:
        self.kit = kit
        self.config = config or DetectionConfig()
        self.stats = DetectionStats()
        self.step_dt = self.config.default_step
        self._objects = {o.id: o for o in kit.objects}
        self._tracks: dict[tuple[str, str], _Track] = {}
        self._next_seq = seq_start % SEQ_LIMIT
        self._next_damping_seq = seq_start % SEQ_LIMIT
        self._physics_time = -math.inf
        self._offset_min = (math.inf, math.inf)  # (current, previous) window minimum of now - contact time
        self._offset_window_start = -math.inf

    # ------------------------------------------------------------------ input

    def contact(self, c: Contact, now: float) -> list[SegmentEvent]:
        """Handle one contact step received at rig time ``now`` (seconds)."""
        self.stats.contacts += 1
        self._note_offset(now - c.time, now)
        events: list[SegmentEvent] = []
        if c.time < self._physics_time - CLOCK_JUMP_S:
            self._restart(events)  # physics' clock went back (a restart); UDP does not hold a datagram seconds
        self._physics_time = max(self._physics_time, c.time)
        self._end_stale(self._physics_time, events, skip=(c.instrument, self.striker_of(c.part)))
        obj = self._objects.get(c.instrument)
        if obj is None:
            self.stats.unknown_instrument += 1
            return events
        if obj.kind not in PLAYABLE_KINDS:
            self.stats.ignored += 1
            return events
        key = (c.instrument, self.striker_of(c.part))
        track = self._tracks.get(key)
        if track is None:
            if not self._make_room():
                self.stats.dropped += 1
                return events
            track = _Track(instrument=c.instrument, part=c.part, obj=obj)
            self._tracks[key] = track
        # physics' next step: a live node that fell behind skips rig time (20-70 ms), not steps, and a contact
        # held over the skip (a stick resting on a cymbal) is the same contact, not a new strike at its first
        # step's approach velocity (physics repeats it in every step)
        next_step = track.last_step >= 0 and c.step == track.last_step + 1
        if track.active and c.time - track.last > self.config.retrigger_gap and not next_step:
            self._end(track, events)
        if self._late(track, c):
            self.stats.out_of_order += 1  # a late (or repeated) step of a contact already ended: not a new one
            return events
        content = _content(c)
        if content in track.recent:
            self.stats.duplicates += 1  # the same datagram again (UDP may repeat one), not another contact point
            return events
        track.recent.append(content)
        if not track.active and track.prev_end is not None and (next_step or (
                track.ended_by_clock and 0.0 <= c.time - track.prev_end <= self.config.retrigger_gap)):
            # the receiver's clock (or another contact's time) ended this contact early (a live physics node
            # catching up delivers its steps late, or skipped time between two of its steps); by physics time or
            # steps it never stopped: the same strike goes on, with no new onset
            track.active = True
            self.stats.reopened += 1
        if track.active:
            self._continue(track, c, events)
        else:
            self._begin(track, c, events)
        return events

    def advance(self, now: float) -> list[SegmentEvent]:
        """End the contacts that have been silent for ``retrigger_gap`` by rig time ``now``."""
        events: list[SegmentEvent] = []
        estimate = now - self.clock_offset
        self._end_stale(max(self._physics_time, estimate), events, by_clock=estimate > self._physics_time)
        return events

    def striker_of(self, part: str) -> str:
        """The striker a part belongs to (``left_stick_shaft`` -> ``left_stick``): one track per striker,
        so a stick whose contact slides from the bead to the shoulder stays one impact."""
        for suffix in self.config.part_suffixes:
            if part.endswith(suffix) and len(part) > len(suffix):
                return part[: -len(suffix)]
        return part

    @property
    def clock_offset(self) -> float:
        """Smallest recent (receive time - contact time): transit plus clock offset, seconds (0 before any)."""
        best = min(self._offset_min)
        return 0.0 if math.isinf(best) else best

    @property
    def active_tracks(self) -> int:
        return sum(1 for t in self._tracks.values() if t.active)

    @property
    def track_count(self) -> int:
        """Tracks kept (active or remembered for bounce and mask classification), at most MAX_TRACKS."""
        return len(self._tracks)

    # ------------------------------------------------------------------ internals

    def _note_offset(self, offset: float, now: float) -> None:
        current, previous = self._offset_min
        # two one-second windows: follows clock corrections; rig time stepped back (the clock master restarted):
        # new windows at once, not only once it is back past the last window's start
        if not 0.0 <= now - self._offset_window_start < 1.0:
            previous, current = current, math.inf
            self._offset_window_start = now
        self._offset_min = (min(current, offset), previous)

    @staticmethod
    def _late(track: _Track, c: Contact) -> bool:
        """True for a step of an earlier, ended contact of this track delivered late: it would start a second
        impact (the approach velocity is repeated in every step) or add its impulse to the next one. A step at
        the time of the last step of a contact the receiver's clock ended is another contact point of that
        step: it reopens the contact. A reordered step of the current contact is no earlier contact's."""
        if track.prev_end is None:
            return False
        if track.active:
            return c.time < track.start and c.time <= track.prev_end
        return c.time < track.prev_end or (c.time == track.prev_end and not track.ended_by_clock)

    def _make_room(self) -> bool:
        """Room for one more track: forget the idle track that ended longest ago when MAX_TRACKS are kept
        (it loses only its bounce and mask history); False when every track is in contact."""
        if len(self._tracks) < MAX_TRACKS:
            return True
        idle = [(t.last, key) for key, t in self._tracks.items() if not t.active]
        if not idle:
            return False
        del self._tracks[min(idle)[1]]
        return True

    def _restart(self, events: list[SegmentEvent]) -> None:
        """Physics' clock went back: end every contact and forget the tracks (their times are of the old clock)."""
        for track in self._tracks.values():
            if track.active:
                self._end(track, events)
        self._tracks.clear()
        self._physics_time = -math.inf
        self.stats.clock_resets += 1

    def _end_stale(self, physics_now: float, events: list[SegmentEvent], skip: tuple[str, str] | None = None,
                   by_clock: bool = False) -> None:
        gap = self.config.retrigger_gap
        for key, track in self._tracks.items():
            if track.active and key != skip and physics_now - track.last > gap:
                self._end(track, events, by_clock)

    def _classify(self, track: _Track, time: float, velocity: float) -> ImpactKind:
        cfg = self.config
        if (
            track.prev_end is not None
            and time - track.prev_end <= cfg.bounce_window
            and track.prev_velocity > 0
            and velocity < cfg.bounce_ratio * track.prev_velocity
        ):
            track.chain += 1
            return "bounce" if track.chain == 1 else "buzz"
        track.chain = 0
        return "strike"

    def _begin(self, track: _Track, c: Contact, events: list[SegmentEvent]) -> None:
        track.active = True
        track.part = c.part
        track.start = track.last = c.time
        track.last_step = c.step
        track.pressing = False
        track.press_force = 0.0
        track.press_steps = 0
        track.first_contact = c
        track.open = None
        velocity = min(max(c.normal_velocity, 0.0), 100.0)
        striker = self.striker_of(c.part)
        if velocity < self.config.part_velocity_min.get(striker, self.config.strike_velocity_min):
            self.stats.touches += 1
            if striker in self.config.plate_parts and track.obj.kind == "hihat":
                self._press(track, c, events)  # the plates closed gently: silent, but an open hat rings no more
            return
        if striker in self.config.rattle_parts:
            self.stats.rattles += 1
            self.stats.touches += 1  # a contact that makes no impact (InteractionStats.touches)
            return
        if (c.time - track.prev_onset <= self.config.mask_window
                and velocity < self.config.mask_ratio * track.prev_velocity):
            self.stats.masked += 1  # the stick falling back onto the head it just struck: part of that stroke
            self.stats.touches += 1
            return
        kind = self._classify(track, c.time, velocity)
        track.prev_velocity = velocity
        track.prev_onset = c.time
        r, theta = polar(track.obj, c.local_x, c.local_y)
        impact = ImpactFeatures(
            seq=self._take_seq(),
            time=c.time,
            instrument=c.instrument,
            part=c.part,
            zone=zone(track.obj, r, self.config.zones, c.openness),
            kind=kind,
            r=r,
            theta=theta,
            x=c.x,
            y=c.y,
            z=c.z,
            local_x=c.local_x,
            local_y=c.local_y,
            local_z=c.local_z,
            velocity=velocity,
            impulse=c.impulse,
            peak_force=c.normal_force,
            duration=0.0,
            openness=hihat_openness(track.obj, c.openness, self.config.zones),
        )
        track.open = impact
        # at onset the contact's totals are unknown: 0, as the Impact message documents
        events.append(ImpactOnset(impact=replace(impact, impulse=0.0, peak_force=0.0), contact_time=c.time))

    def _continue(self, track: _Track, c: Contact, events: list[SegmentEvent]) -> None:
        if c.step > track.last_step:
            if c.step > track.last_step + 1:
                self.stats.chatter += 1  # a gap shorter than retrigger_gap: same contact
            elif c.time > track.last:
                dt = c.time - track.last
                if 1e-5 <= dt <= self.config.retrigger_gap:  # not the rig time a late live node skipped
                    self.step_dt = dt
            track.last = max(track.last, c.time)
            track.last_step = c.step
        elif c.step < track.last_step:
            self.stats.out_of_order += 1
        # the same step again: another contact point of the same pair; its impulse adds up
        if track.open is not None:
            track.open.impulse = min(track.open.impulse + c.impulse, FLOAT32_MAX)
            track.open.peak_force = max(track.open.peak_force, c.normal_force)
        if track.pressing:
            track.press_force += c.normal_force
            track.press_steps += 1
        elif c.time - track.start + self.step_dt >= self.config.press_after:
            self._press(track, c, events)

    def _press(self, track: _Track, c: Contact, events: list[SegmentEvent]) -> None:
        track.pressing = True
        track.press_force = c.normal_force
        track.press_steps = 1
        if track.open is not None:  # a dead stroke: the strike is over, the press goes on
            impact = track.open
            impact.kind = "dead"
            impact.duration = min(c.time - impact.time + self.step_dt, 1.0)
            impact.final = True
            self.stats.impacts["dead"] += 1
            self.stats.count(track.instrument, "dead")
            events.append(ImpactFinal(impact=replace(impact)))
            track.open = None
        first = track.first_contact or c
        r, theta = polar(track.obj, first.local_x, first.local_y)
        self.stats.dampings += 1
        self.stats.count(track.instrument, "damping")
        events.append(
            DampingChange(
                seq=self._take_damping_seq(),
                time=c.time,
                instrument=track.instrument,
                part=track.part,
                state=1,
                zone=zone(track.obj, r, self.config.zones, first.openness),
                r=r,
                theta=theta,
                force=c.normal_force,
            )
        )

    def _end(self, track: _Track, events: list[SegmentEvent], by_clock: bool = False) -> None:
        if track.open is not None:
            impact = track.open
            impact.duration = min(track.last - impact.time + self.step_dt, 1.0)
            impact.final = True
            self.stats.impacts[impact.kind] += 1
            self.stats.count(track.instrument, impact.kind)
            events.append(ImpactFinal(impact=replace(impact)))
            track.open = None
        if track.pressing:
            first = track.first_contact
            r, theta = polar(track.obj, first.local_x, first.local_y) if first else (0.0, 0.0)
            openness = first.openness if first else -1.0
            events.append(
                DampingChange(
                    seq=self._take_damping_seq(),
                    time=track.last + self.step_dt,
                    instrument=track.instrument,
                    part=track.part,
                    state=0,
                    zone=zone(track.obj, r, self.config.zones, openness),
                    r=r,
                    theta=theta,
                    force=0.0,
                )
            )
            track.pressing = False
        track.active = False
        track.ended_by_clock = by_clock
        track.prev_end = track.last
        track.first_contact = None

    def _take_seq(self) -> int:
        seq = self._next_seq
        self._next_seq = (seq + 1) % SEQ_LIMIT
        return seq

    def _take_damping_seq(self) -> int:
        seq = self._next_damping_seq
        self._next_damping_seq = (seq + 1) % SEQ_LIMIT
        return seq


def _content(c: Contact) -> tuple[object, ...]:
    """What tells one contact datagram from another: two contact points of a step differ in position."""
    return (c.step, c.time, c.part, c.x, c.y, c.z, c.impulse, c.normal_force, c.normal_velocity)
