"""The pedals under a drummer of a given height: the hi-hat pedal pressed by a left foot held still over it, and
single pedal notes played from the scene's start (what the tests of the feet by body size read)."""

from __future__ import annotations

import numpy as np

from common.gesture.planner import plan_gestures
from common.kit import EventType, Kit, load_kit
from common.messages import Contact
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene


def held_hihat_press(kit: Kit, above_flat_m: float, height_m: float = 1.75) -> float:
    """The hi-hat footboard's press (0 at rest, 1 flat) after 0.8 s of a ``height_m`` tall drummer's left foot
    moved (over 0.4 s) and held ``above_flat_m`` metres over the footboard pressed flat."""
    flat = np.array(kit.object("hihat_pedal").position)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0, height_m=height_m)
    try:
        scene = core.scene
        assert isinstance(scene, DrummerScene)
        scene.add_cartesian("left_foot", 0.0, scene.current_targets()["left_foot"], np.zeros(3), 0.0)
        scene.add_cartesian("left_foot", 0.4, flat + np.array([0.0, 0.0, above_flat_m]), np.zeros(3), 0.0)
        for k in range(1, 801):
            core.step(k / 1000)
        assert scene.kit_bodies.hihat is not None and scene.kit_bodies.hihat.pedal is not None
        return scene.kit_bodies.hihat.pedal.press(core.world)
    finally:
        core.close()


def played_pedal_notes(height_m: float, event: EventType, pitch: int, velocities: tuple[float, ...],
                       parts: tuple[str, ...], start_s: float, period_s: float = 0.6
                       ) -> tuple[list[float], list[Contact]]:
    """A ``height_m`` tall drummer on the default kit plays single ``event`` notes at ``velocities``, ``period_s``
    apart, from the scene's start (rest posture) on, the plan starting at rig time ``start_s``; returns the notes'
    rig times (seconds) and every contact of the striker ``parts`` until 0.2 s after the plan."""
    t0 = 0.5
    events = [DrumEvent(time=t0 + k * period_s, event=event, velocity=v, pitch=pitch) for k, v in enumerate(velocities)]
    score = Score(events=events, beats=t0 + period_s * np.arange(len(events)))
    times, contacts = played_score(score, parts, start_s, height_m)
    return [t for t, e in times if e == event], contacts


def played_score(score: Score, parts: tuple[str, ...], start_s: float, height_m: float = 1.75
                 ) -> tuple[list[tuple[float, EventType]], list[Contact]]:
    """A ``height_m`` tall drummer on the default kit plays ``score``'s plan from the scene's start (rest posture)
    on, the plan starting at rig time ``start_s``; returns each stroke's rig time (seconds) and event, and every
    contact of the striker ``parts`` until 0.2 s after the plan."""
    kit = load_kit("default", height_m=height_m, warn=False)
    plan = plan_gestures(distribute(score, kit, height_m=height_m), kit, score)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0, height_m=height_m)
    offset = start_s - plan.start_time
    core.load_plan(plan, start_at=start_s)
    contacts: list[Contact] = []
    try:
        for k in range(1, round((plan.end_time + offset + 0.2) * 1000) + 1):
            contacts += [o.message for o in core.step(k / 1000)
                         if isinstance(o.message, Contact) and o.message.part in parts]
    finally:
        core.close()
    return [(s.time + offset, s.event) for s in plan.strokes], contacts


def onset_contacts(contacts: list[Contact], gap_s: float = 0.015) -> list[Contact]:
    """The first contact of each onset of one striker's ``contacts``: contacts closer than ``gap_s`` (seconds)
    belong to one onset."""
    found: list[Contact] = []
    last = -1.0
    for c in contacts:
        if c.time - last > gap_s:
            found.append(c)
        last = c.time
    return found


def onsets(contacts: list[Contact], gap_s: float = 0.015) -> list[float]:
    """The onsets (rig times, s) of a striker's contacts: contacts closer than ``gap_s`` belong to one."""
    return [c.time for c in onset_contacts(contacts, gap_s)]
