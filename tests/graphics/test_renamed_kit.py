"""A kit whose designer renamed the kick, its pedal and the hi-hat (and its pedal) is drawn and animated as the
shipped one: the graphics find them by the kit's events (BASS's object and ``pedal``, HIHATPEDAL's ``pedal``),
never by their ids."""

from __future__ import annotations

import numpy as np
import pytest

from common.kit import EventType, Kit, load_kit
from common.messages import Impact
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import FOOTBOARD, LINK_NAMES, SyntheticDrummer
from services.graphics.node import synthetic_groove
from services.graphics.scene import HIHAT_MAX_GAP, PEDAL_TRAVEL, KitAnimator
from tests.renamed_kits import renamed_kit


def _moved(kit: Kit, object_id: str, x: float) -> Kit:
    """``kit`` with object ``object_id`` moved to ``x`` (metres)."""
    objects = [o.model_copy(update={"position": (x, *o.position[1:])}) if o.id == object_id else o
               for o in kit.objects]
    return kit.model_copy(update={"objects": objects})


def _feet(left_z: float, right_z: float) -> np.ndarray:
    """Poses (L, 7) of the synthetic figure's links, all at the origin but its toes at these heights, metres."""
    pose = np.zeros((len(LINK_NAMES), 7))
    pose[:, 6] = 1.0
    pose[LINK_NAMES.index("left_toe"), 2] = left_z
    pose[LINK_NAMES.index("right_toe"), 2] = right_z
    return pose


def _pressed_by(kit: Kit) -> dict[str, str]:
    """Pedal id -> the foot whose toe moves it on the animator (no kit links: the feet drive the pedals)."""
    animator = KitAnimator(kit)
    animator.bind(list(LINK_NAMES))
    ids = [o.id for o in kit.objects]
    animator.state(0.0, _feet(0.1, 0.1))  # both feet down: the lowest each reaches
    out = {}
    for foot, pose in (("left", _feet(0.1, 0.1 + PEDAL_TRAVEL)), ("right", _feet(0.1 + PEDAL_TRAVEL, 0.1))):
        state = animator.state(0.1, pose)  # the other foot lifted: only this foot's pedals stay down
        out.update({o.id: foot for o in kit.objects if o.kind == "pedal" and state[ids.index(o.id), 3] > 0.99})
    return out


@pytest.mark.parametrize("name", ["default", "left_handed"])
def test_the_synthetic_drummer_plays_the_renamed_kit(name: str) -> None:
    kit = renamed_kit(name)
    drummer = SyntheticDrummer(kit, duration=2.5)
    impacts = drummer.impacts()
    assert {i.instrument for i in impacts} >= {"bassdrum", "sd", "hats"}
    pose = drummer.pose(1.0)  # mid-bar, hi-hat foot down
    kick_foot, hihat_foot = ("left", "right") if kit.handedness == "left" else ("right", "left")  # as physics
    for foot, pedal in ((kick_foot, kit.kick_pedal()), (hihat_foot, kit.hihat_pedal())):
        assert pedal is not None
        toe = pose[LINK_NAMES.index(f"{foot}_toe"), :3]
        on_board = np.asarray(kit.object(pedal).position) + FOOTBOARD
        assert np.linalg.norm(toe[:2] - on_board[:2]) < 0.02, (foot, pedal, toe)
    sequence, grooved = synthetic_groove(kit, "renamed.yaml")  # batteur graphics --synthetic takes it
    assert {i.instrument for i in grooved} == {i.instrument for i in impacts} and len(sequence.times) > 1


@pytest.mark.parametrize("kit", [load_kit("default"), renamed_kit("default"), renamed_kit("left_handed")],
                         ids=["shipped", "renamed", "renamed_left_handed"])
def test_the_hihat_opens_when_its_foot_lifts_and_the_kick_pedal_follows_the_foot(kit: Kit) -> None:
    """On the shipped kit, the renamed one and the left-handed one (whose kick pedal stayed pressed between kicks,
    the synthetic right foot on it without kicking): the hi-hat and the kick pedal found by the kit's events."""
    hihat, kick_pedal = kit.events[EventType.HIHATCLOSED].object, kit.kick_pedal()
    assert kick_pedal is not None
    sequence = SyntheticDrummer(kit, duration=4.0).sequence(60.0)
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"), kit)
    core.handle(sequence.skeleton_message(), 0.0, "physics")
    for pose in sequence.pose_messages():
        core.handle(pose, pose.time, "physics")
        core.frame_at(pose.time)  # the pedal binding learns the lowest (pressed) foot height as it goes
    ids = [o.id for o in core.kit.objects]
    beat = 0.5
    closed = core.frame_at(0.5 + 2 * beat)  # mid-bar: hi-hat foot down
    opened = core.frame_at(0.5 + 3.5 * beat + 0.05)  # last eighth of the bar: foot up
    assert closed is not None and opened is not None
    assert closed.kit[ids.index(hihat), 3] == pytest.approx(0.0, abs=1e-3)
    assert opened.kit[ids.index(hihat), 3] == pytest.approx(kit.object(hihat).opening * HIHAT_MAX_GAP, rel=0.05)
    kick_hit, between = core.frame_at(0.5), core.frame_at(0.5 + 0.5 * beat * 1.5)  # a bass drum stroke, then none
    assert kick_hit is not None and between is not None
    assert kick_hit.kit[ids.index(kick_pedal), 3] > 0.95
    assert between.kit[ids.index(kick_pedal), 3] < 0.5


@pytest.mark.parametrize("double", [False, True])
def test_without_feet_the_renamed_bass_pedals_press_as_the_renamed_kick_is_struck(double: bool) -> None:
    kit = renamed_kit("double_pedal" if double else "default")
    animator = KitAnimator(kit)
    animator.add(Impact(seq=1, time=1.0, instrument="bassdrum", zone="centre", r=0.2, theta=0.0, velocity=3.0,
                        impulse=0.05, peak_force=300.0, duration=0.004, part="kick_beater"))
    ids = [o.id for o in kit.objects]
    pedals = ["bd_pedal", "bd_pedal_2"] if double else ["bd_pedal"]
    assert [animator.state(1.0, None)[ids.index(p), 3] for p in pedals] == pytest.approx([1.0] * len(pedals))
    assert animator.state(1.0, None)[ids.index("foot_chick"), 3] == 0.0
    assert animator.state(1.5, None)[ids.index("bd_pedal"), 3] < 1e-6


def test_feet_drive_the_pedals_they_play_whatever_the_ids_and_wherever_they_stand() -> None:
    """The kick's pedal by BASS's foot, the hi-hat's by HIHATPEDAL's, a double pedal's second footboard by the other
    foot than BASS's (as physics plays it), even where a pedal stands on the other side of the seat than its foot."""
    shipped = _pressed_by(load_kit("default"))
    assert shipped == {"kick_pedal": "right", "hihat_pedal": "left"}
    kit = _moved(renamed_kit(), "bd_pedal", -0.04)  # the kick's pedal just left of centre: still the right foot's
    assert _pressed_by(kit) == {"bd_pedal": "right", "foot_chick": "left"}
    lefty = _moved(renamed_kit("left_handed"), "bd_pedal", 0.04)
    assert lefty.events[EventType.BASS].preferred.value == "left_foot"
    assert _pressed_by(lefty) == {"bd_pedal": "left", "foot_chick": "right"}
    double = _pressed_by(load_kit("double_pedal"))  # 'kick_pedal_left' was the right foot's: 'kick' in its id
    assert double == {"kick_pedal": "right", "kick_pedal_left": "left", "hihat_pedal": "left"}
    assert _pressed_by(renamed_kit("double_pedal")) == {"bd_pedal": "right", "bd_pedal_2": "left",
                                                        "foot_chick": "left"}
