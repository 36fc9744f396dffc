"""Kit files a designer writes, played: a kit may name its kick and pedals as it likes (``bassdrum``, ``bd_pedal``,
``hh_pedal``): physics finds the kick as the object BASS strikes and its pedal as BASS's ``pedal``, not by the ids
``kick`` and ``kick_pedal`` (before, such a kit loaded without a word, got no beater, and every kick was silent:
``missed: no_contact`` on each BASS of a render). A kick pedal out of the foot's reach costs the kicks only (before,
the foot stretched for it pulled the body and no note sounded, the hands' neither)."""

from __future__ import annotations

import numpy as np

from common.gesture.planner import plan_gestures
from common.gesture.reach import pull_into_reach
from common.kit import EventType, Kit, load_kit
from common.messages import Contact
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from services.physics.core import PhysicsCore
from services.physics.drummer import DrummerScene

RENAMED = {"kick": "bassdrum", "kick_pedal": "bd_pedal", "hihat_pedal": "hh_pedal"}


def renamed_kit() -> Kit:
    """The default kit with its kick and pedals renamed (objects and the events that name them)."""
    data = load_kit("default", warn=False).model_dump(mode="json")
    for obj in data["objects"]:
        obj["id"] = RENAMED.get(obj["id"], obj["id"])
    for spec in data["events"].values():
        spec["object"] = RENAMED.get(spec["object"], spec["object"])
        if spec["pedal"] is not None:
            spec["pedal"] = RENAMED[spec["pedal"]]
    return Kit.model_validate(data)


def test_the_renamed_kick_sounds_by_the_bass_foot() -> None:
    """Two kicks on the renamed kit: the beater ('kick_beater', played by the right foot) meets the renamed kick
    near each note; the hi-hat's pedal is the renamed one; the feet rest over the renamed pedals."""
    kit = renamed_kit()
    events = [DrumEvent(time=0.5 + 0.6 * k, event=EventType.BASS, velocity=0.8, pitch=36) for k in range(2)]
    score = Score(events=events, beats=np.array([0.5, 1.1]))
    plan = plan_gestures(distribute(score, kit), kit, score)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0)
    start = 0.6
    core.load_plan(plan, start_at=start)
    offset = start - plan.start_time
    contacts: list[Contact] = []
    try:
        scene = core.scene
        assert isinstance(scene, DrummerScene)
        hihat = scene.kit_bodies.hihat
        assert hihat is not None and hihat.pedal is scene.kit_bodies.pedals["hh_pedal"]
        assert scene._striker_limbs["kick_beater"] == "right_foot"
        assert set(scene.rest_targets) >= {"right_foot", "left_foot"}
        for k in range(1, round((plan.end_time + offset + 0.2) * 1000) + 1):
            contacts += [o.message for o in core.step(k / 1000)
                         if isinstance(o.message, Contact) and o.message.part == "kick_beater"]
    finally:
        core.close()
    assert {c.instrument for c in contacts} == {"bassdrum"}
    for stroke in plan.strokes:
        assert any(abs(c.time - (stroke.time + offset)) < 0.03 for c in contacts), "a kick did not sound"


def test_the_hands_play_on_a_kit_whose_kick_pedal_is_out_of_reach() -> None:
    """Four snare notes and two kicks on a kit with the kick pedal 1.57 m from the hip: the stick meets the snare at
    every snare note, no knot needs pulling into reach (the render's ``pulled_into_reach``: 505 before), and the foot
    does not rest stretched out toward the pedal."""
    data = load_kit("default", warn=False).model_dump(mode="json")
    next(o for o in data["objects"] if o["id"] == "kick_pedal")["position"] = [0.05, 1.5, 0.02]
    kit = Kit.model_validate(data)
    events = sorted([DrumEvent(time=0.5 + 0.3 * k, event=EventType.SNARE, velocity=0.8, pitch=38) for k in range(4)]
                    + [DrumEvent(time=0.5 + 0.6 * k, event=EventType.BASS, velocity=0.8, pitch=36)
                       for k in range(2)], key=lambda e: e.time)
    score = Score(events=events, beats=np.array([0.5]))
    plan = plan_gestures(distribute(score, kit), kit, score)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0)
    contacts: list[Contact] = []
    try:
        scene = core.scene
        assert isinstance(scene, DrummerScene)
        assert "right_foot" not in scene.rest_targets  # the bass foot rests where it stands
        plan, pulled = pull_into_reach(plan, scene.reach)  # as the score player does before a splice
        assert pulled == {}
        start = 0.6
        offset = start - plan.start_time
        core.load_plan(plan, start_at=start)
        for k in range(1, round((plan.end_time + offset + 0.2) * 1000) + 1):
            contacts += [o.message for o in core.step(k / 1000)
                         if isinstance(o.message, Contact) and o.message.instrument == "snare"]
    finally:
        core.close()
    snare_times = [s.time + offset for s in plan.strokes if s.event == EventType.SNARE]
    assert len(snare_times) == 4
    for t in snare_times:
        assert any(abs(c.time - t) < 0.03 for c in contacts), f"the snare note at {t:.2f} s did not sound"
