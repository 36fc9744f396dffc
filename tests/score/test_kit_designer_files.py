"""Kit files a designer writes (a walkthrough copying the default kit and editing it): the kick and its pedal found
by what the kit says, not by the ids ``kick`` and ``kick_pedal``; a pedal out of the foot's reach costs its notes,
not the hands'; impossible geometry warned of as the kit loads; a stale ``pair_preference`` overridden by the
geometry; problems named by the object's id; the double pedal's second footboard worded by role."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from common.gesture.plan import IssueAction, IssueReason
from common.gesture.planner import plan_gestures
from common.kit import KITS_DIR, EventType, Kit, Limb, kit_hardware, layout_problems, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import HANDS, distribute

SHIPPED = sorted(p.stem for p in KITS_DIR.glob("*.yaml"))


def _default() -> dict[str, Any]:
    return load_kit("default", warn=False).model_dump(mode="json")


def _object(data: dict[str, Any], object_id: str) -> dict[str, Any]:
    return next(o for o in data["objects"] if o["id"] == object_id)


def _written(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "designer.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


# 1. the kick and its pedal by what the kit says


def _renamed(double: bool = False) -> Kit:
    data = load_kit("double_pedal" if double else "default", warn=False).model_dump(mode="json")
    names = {"kick": "bassdrum", "kick_pedal": "bd_pedal", "kick_pedal_left": "bd_pedal_2"}
    for obj in data["objects"]:
        obj["id"] = names.get(obj["id"], obj["id"])
    data["events"]["BASS"].update(object="bassdrum", pedal="bd_pedal")
    if double:
        data["left_bass_pedal"] = "bd_pedal_2"
    return Kit.model_validate(data)


@pytest.mark.parametrize("double", [False, True])
def test_a_renamed_kick_and_pedal_get_their_beaters(double: bool) -> None:
    """Before: no beater at all (every kick silent). Each beater is where the shipped kit's is, by the new ids."""
    kit = _renamed(double)
    shipped = kit_hardware(load_kit("double_pedal" if double else "default", warn=False))
    built = kit_hardware(kit)
    assert [b.pedal for b in built.beaters] == (["bd_pedal", "bd_pedal_2"] if double else ["bd_pedal"])
    assert [b.axle for b in built.beaters] == [b.axle for b in shipped.beaters]
    assert kit.kick() == kit.object("bassdrum") and kit.kick_pedal() == "bd_pedal"
    assert built.stands == shipped.stands  # no stand rod under the renamed kick either


def test_a_kit_without_what_a_foot_event_needs_is_refused_or_warned_naming_it() -> None:
    """A foot event without a pedal loads (the sound service's kits need none) with a warning; a pedal that is no
    footboard is refused."""
    data = _default()
    del data["events"]["BASS"]["pedal"]
    assert layout_problems(Kit.model_validate(data)) == [
        "events.BASS has no pedal: nothing a foot presses drives a beater into 'kick', so its notes do not sound "
        "when played (pedal: the id of a footboard object, kind pedal)"]
    data = _default()
    data["events"]["BASS"]["pedal"] = "snare"
    with pytest.raises(ValueError, match="event BASS's pedal 'snare' is a membrane, not a pedal"):
        Kit.model_validate(data)
    data = {**load_kit("double_pedal", warn=False).model_dump(mode="json"), "left_bass_pedal": "floortom"}
    with pytest.raises(ValueError, match="left_bass_pedal 'floortom' is a membrane, not a pedal"):
        Kit.model_validate(data)


# 2. a pedal out of the foot's reach


def _far_pedal() -> Kit:
    data = _default()
    _object(data, "kick_pedal")["position"] = [0.05, 1.5, 0.02]
    return Kit.model_validate(data)


def test_notes_on_a_pedal_out_of_reach_are_dropped_and_the_hands_play() -> None:
    """Kicks on a pedal 1.57 m from the hip are dropped and flagged unreachable (before: played anyway, the foot
    stretched for it pulled the body and no note sounded, the hands' neither); the hands' notes are all planned and
    the bass foot gets no trajectory out to the pedal (physics pulled 505 of its knots into reach)."""
    kit = _far_pedal()
    events = sorted([DrumEvent(time=0.5 + 0.3 * k, event=EventType.SNARE, velocity=0.8, pitch=38) for k in range(4)]
                    + [DrumEvent(time=0.5 + 0.6 * k, event=EventType.BASS, velocity=0.8, pitch=36)
                       for k in range(2)], key=lambda e: e.time)
    score = Score(events=events, beats=np.array([0.5]))
    assignment = distribute(score, kit)
    flagged = [(i.event, i.reason, i.action) for i in assignment.issues]
    assert flagged == [(EventType.BASS, IssueReason.UNREACHABLE, IssueAction.DROPPED)] * 2
    assert "from the right foot's hip" in assignment.issues[0].detail
    assert [n.event for n in assignment.notes] == [EventType.SNARE] * 4
    assert all(n.limb in HANDS for n in assignment.notes)
    assert (Limb.RIGHT_FOOT, "kick_pedal") in assignment.pedals_out_of_reach
    plan = plan_gestures(assignment, kit, score)
    assert [s.event for s in plan.strokes] == [EventType.SNARE] * 4
    assert Limb.RIGHT_FOOT not in plan.trajectories  # nothing drags the foot (and the body) out to the pedal
    assert Limb.LEFT_FOOT in plan.trajectories  # the hi-hat foot, in reach, rests on its pedal as before
    default = load_kit("default", warn=False)
    assert distribute(score, default).pedals_out_of_reach == frozenset()


# 3. impossible geometry


def _moved(**objects: dict[str, Any]) -> Kit:
    data = _default()
    for object_id, update in objects.items():
        _object(data, object_id).update(update)
    return Kit.model_validate(data)


@pytest.mark.parametrize("name", SHIPPED)
def test_the_shipped_kits_give_no_geometry_warning(name: str, caplog: pytest.LogCaptureFixture) -> None:
    kit = load_kit(name, warn=False)
    assert layout_problems(kit) == [] and kit.stale_pairs() == {}
    with caplog.at_level(logging.WARNING):
        load_kit(name)
    assert caplog.records == []


@pytest.mark.parametrize(("kit", "said"), [
    (_moved(floortom={"position": [0.0, 0.0, 0.55]}),
     "floortom: its centre (0, 0, 0.55) is in the throne, where the drummer sits"),
    (_moved(hightom={"position": [-0.08, 0.40, 0.66]}), "snare and hightom overlap: one stands inside the other"),
    (_moved(crash={"rotation_deg": [180, 0, 0]}), "crash: its playing surface faces the floor"),
    (_moved(floortom={"position": [0.48, 0.32, -0.2]}), "floortom: its centre (0.48, 0.32, -0.2) is 0.2 m below"),
    (_moved(splash={"position": [-0.30, 0.72, 1.18]}), "crash and splash overlap"),
])
def test_impossible_geometry_is_warned_naming_the_objects(kit: Kit, said: str) -> None:
    problems = layout_problems(kit)
    assert len(problems) == 1 and problems[0].startswith(said)


def test_an_upright_plate_does_not_face_the_floor() -> None:
    """A gong hung nearly upright (pitched 95 degrees: normal z -0.09) was said to face the floor (any downward
    normal); past 120 degrees it still is."""
    assert layout_problems(_moved(crash={"rotation_deg": [95, 0, 0]})) == []
    assert layout_problems(_moved(crash={"rotation_deg": [125, 0, 0]}))[0].startswith(
        "crash: its playing surface faces the floor")


def test_steep_toms_keep_their_stand_rods() -> None:
    """Toms tilted 65 degrees lost their rods (every drum past 60 degrees was taken for a kick) and floated; the
    kick (whatever its id) and a drum whose shell reaches the floor stand without one."""
    shipped = kit_hardware(load_kit("default", warn=False)).stands
    steep = kit_hardware(_moved(hightom={"rotation_deg": [65, 0, 0]}, midtom={"rotation_deg": [65, 0, 0]})).stands
    assert len(steep) == len(shipped)
    lying = _moved(floortom={"rotation_deg": [90, 0, 0], "position": [0.48, 0.32, 0.2]})  # on its side, on the floor
    assert len(kit_hardware(lying).stands) == len(shipped) - 1
    assert len(kit_hardware(_renamed()).stands) == len(shipped)  # the renamed kick: no rod either


def test_a_geometry_warning_is_logged_as_the_kit_loads(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    data = _default()
    _object(data, "crash")["rotation_deg"] = [180, 0, 0]
    path = _written(tmp_path, data)
    with caplog.at_level(logging.WARNING):
        load_kit(path)
    assert [r.getMessage() for r in caplog.records if "faces the floor" in r.getMessage()] != []
    caplog.clear()
    load_kit(path, warn=False)  # a kit read again, already warned of
    assert caplog.records == []


# 4. a stale pair preference


def _ride_left() -> Kit:
    """The walkthrough's kit: hi-hat and ride swapped (hi-hat to the right, ride far left), the table kept."""
    return _moved(hihat={"position": [0.42, 0.42, 0.92]}, ride={"position": [-0.7, 0.5, 1.04]})


def test_a_moved_ride_gets_the_geometrys_preference_and_no_crossing() -> None:
    """``RIDE,SNARE: 1`` (the right hand on the ride) with the ride 0.47 m left of the snare: the ride went to the
    left hand (reach) and every backbeat was flagged "crossing -> played_anyway"; now the geometry's -1 is used."""
    kit = _ride_left()
    assert kit.pair_preference["RIDE,SNARE"] == 1.0
    assert kit.pair(EventType.RIDE, EventType.SNARE) == -1.0 == -kit.pair(EventType.SNARE, EventType.RIDE)
    assert kit.stale_pairs()["RIDE,SNARE"] == (1.0, -1.0)
    assert kit.pair(EventType.HIHATCLOSED, EventType.SNARE) == 1.0  # hi-hat now right of the snare: kept
    events = [DrumEvent(time=0.25 * k, event=EventType.RIDE, velocity=0.7, pitch=51) for k in range(8)]
    events += [DrumEvent(time=0.5 + k, event=EventType.SNARE, velocity=0.8, pitch=38) for k in range(2)]
    score = Score(events=sorted(events, key=lambda e: e.time), beats=np.array([0.0]))
    assignment = distribute(score, kit)
    assert [i for i in assignment.issues if i.reason == IssueReason.CROSSING] == []
    assert {n.limb for n in assignment.notes if n.event == EventType.RIDE} == {Limb.LEFT_HAND}
    assert any("pair_preference: " in line and "RIDE,SNARE 1 -> -1" in line for line in layout_problems(kit))


@pytest.mark.parametrize(("moved", "key"), [({"crash": {"position": [-0.50, 0.66, 1.20]}}, "CRASH,SNARE"),
                                            ({"hihat": {"position": [-0.58, 0.40, 0.92]}}, "HIHATCLOSED,SNARE")])
def test_a_users_crossing_convention_stands(moved: dict[str, dict[str, Any]], key: str) -> None:
    """A crash moved left of the hi-hat (crossing 0.42 m) or a hi-hat far left (0.39 m), the right hand on it over
    the snare as written: the 0.38 m limit of 7 Dec flipped the entry to -1 and warned "write it again" of a table
    the user wrote. A ride moved across the kit (0.69 m) is still caught."""
    kit = _moved(**moved)
    a, b = (EventType(part) for part in key.split(","))
    assert kit.pair(a, b) == 1.0 and kit.stale_pairs() == {}
    assert not any("pair_preference" in line for line in layout_problems(kit))
    ride = _moved(ride={"position": [-0.62, 0.58, 1.02]})  # the review's ride moved left
    assert 0.6 < ride.hit_point(EventType.SNARE)[0][0] - ride.hit_point(EventType.RIDE)[0][0] < 0.7
    assert ride.stale_pairs()["RIDE,SNARE"] == (1.0, -1.0)


def test_the_shipped_kits_conventions_stand() -> None:
    """The crossed hi-hat and the crash over the backbeat (crossing 0.21-0.27 m) are kept as written, mirrored
    too; a copy with moved objects is judged on its own objects (not the original's table)."""
    for name in SHIPPED:
        kit = load_kit(name, warn=False)
        for key, written in kit.pair_preference.items():
            a, b = (EventType(part) for part in key.split(","))
            assert kit.pair(a, b) == written
    moved = _ride_left()
    copy = load_kit("default", warn=False).model_copy(update={"objects": moved.objects})
    assert copy.pair(EventType.RIDE, EventType.SNARE) == -1.0


# 5. problems named by the object


@pytest.mark.parametrize(("edit", "said"), [
    (lambda d: _object(d, "ride").update(radius=-0.25), r"objects\.8 \(ride\)\.radius: -0\.25 is out of range"),
    (lambda d: _object(d, "snare").update(radius="14in"), r"objects\.1 \(snare\)\.radius: Input should be a valid"),
    (lambda d: _object(d, "cowbell").update(kind="woodblock"), r"objects\.10 \(cowbell\)\.kind: must be "),
    (lambda d: _object(d, "splash").update(id="crash"),
     r"kit object ids must be unique: 'crash' is the id of objects\.6 and objects\.7$"),
    (lambda d: d["events"].update(TAMBOURINE=dict(d["events"]["COWBELL"])),
     r"events\.TAMBOURINE: 'TAMBOURINE' is not an event type \(the event types are BASS, SNARE, RIM, .*, COWBELL\)$"),
])
def test_a_kit_problem_names_the_object(tmp_path: Path, edit: Any, said: str) -> None:
    data = _default()
    edit(data)
    with pytest.raises(ValueError, match=said):
        load_kit(_written(tmp_path, data))


# 6. the double pedal's second footboard, by role


def test_left_bass_pedal_is_described_by_role() -> None:
    said = Kit.model_fields["left_bass_pedal"].description or ""
    assert "BASS by the left foot" not in said and "the right on a mirrored one" in said
