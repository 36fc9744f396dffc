"""The kit model: shipped kits, hit points, pedals, second objects, mirroring, validation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from common.kit import (
    CHICK_PRESS_MARGIN,
    KITS_DIR,
    EventType,
    Kit,
    Limb,
    foot_target_for_press,
    footboard_rise,
    load_kit,
    save_kit,
)


@pytest.mark.parametrize("name", sorted(p.stem for p in KITS_DIR.glob("*.yaml")))
def test_shipped_kits_load_and_play_all_15_events(name: str) -> None:
    kit = load_kit(name)
    assert set(kit.events) == set(EventType)
    for event in EventType:
        point, normal = kit.hit_point(event)
        assert np.isclose(np.linalg.norm(normal), 1.0)
        assert 0.0 <= point[2] < 1.6
    assert set(p.stem for p in KITS_DIR.glob("*.yaml")) >= {"default", "double_pedal", "left_handed"}


def test_hit_point_on_surface_and_ride_bell_on_same_cymbal() -> None:
    kit = load_kit()
    ride, bell = kit.hit_point(EventType.RIDE)[0], kit.hit_point(EventType.RIDEBELL)[0]
    obj = kit.object("ride")
    assert kit.spec(EventType.RIDE).object == kit.spec(EventType.RIDEBELL).object == "ride"
    # both on the cymbal's playing surface at r * radius from its centre: the bow on the plate's plane,
    # the bell on the bell's top, which stands above the bow (a stick aimed at the plane would meet it early)
    n = np.array(obj.normal())
    assert obj.bell_height > 0.01
    for point, spec, height in ((ride, kit.spec(EventType.RIDE), 0.0),
                                (bell, kit.spec(EventType.RIDEBELL), obj.bell_height)):
        offset = np.array(point) - np.array(obj.position)
        assert offset @ n == pytest.approx(height, abs=1e-9)
        assert np.linalg.norm(offset - (offset @ n) * n) == pytest.approx(spec.r * obj.radius)
    assert kit.spec(EventType.RIDEBELL).r * obj.radius < obj.bell_radius < kit.spec(EventType.RIDE).r * obj.radius
    # drums tilt toward the drummer (normal has a -y component)
    assert kit.object("snare").normal()[1] < 0 and kit.object("hightom").normal()[1] < 0


def test_foot_targets_are_pedals() -> None:
    kit = load_kit("double_pedal")
    assert kit.effector_target(EventType.BASS, Limb.RIGHT_FOOT)[0] == kit.object("kick_pedal").position
    assert kit.effector_target(EventType.BASS, Limb.LEFT_FOOT)[0] == kit.object("kick_pedal_left").position
    # the hi-hat pedal's target is where the cymbals meet: the footboard not yet flat, the chick on the way down
    chick = np.array(kit.effector_target(EventType.HIHATPEDAL, Limb.LEFT_FOOT)[0])
    flat = np.array(kit.object("hihat_pedal").position)
    assert np.allclose(chick[:2], flat[:2])
    aimed = kit.object("hihat").closes_at + CHICK_PRESS_MARGIN  # a little past the closing point: the board lags
    assert chick[2] - flat[2] == pytest.approx(foot_target_for_press(aimed))
    assert 0.0 < footboard_rise(0.85) < footboard_rise(0.5) < footboard_rise(0.0)
    assert footboard_rise(1.0) == 0.0
    assert foot_target_for_press(0.863) == pytest.approx(0.020)  # the measured table, interpolated
    assert 0.015 < foot_target_for_press(0.85) < 0.030
    assert kit.effector_target(EventType.SNARE, Limb.LEFT_HAND) == kit.hit_point(EventType.SNARE)


def test_second_ride_and_more_toms_by_pitch() -> None:
    kit = load_kit("double_pedal")
    assert kit.object_for(EventType.RIDE, 51).id == "ride"
    assert kit.object_for(EventType.RIDE, 59).id == "ride2"
    assert kit.object_for(EventType.FLOORTOM, 41).id == "floortom2"
    assert kit.hit_point(EventType.RIDE, 59)[0][0] < 0  # on the left


def test_mirrored_kit_swaps_sides_and_limbs() -> None:
    kit = load_kit()
    left = load_kit("left_handed")
    assert left.handedness == "left"
    for event in EventType:
        a, b = np.array(kit.hit_point(event)[0]), np.array(left.hit_point(event)[0])
        np.testing.assert_allclose(b, a * [-1, 1, 1], atol=1e-4)
    assert left.spec(EventType.BASS).preferred == Limb.LEFT_FOOT
    assert left.spec(EventType.SNARE).preferred == Limb.RIGHT_HAND
    assert left.pair(EventType.HIHATCLOSED, EventType.SNARE) == -kit.pair(EventType.HIHATCLOSED, EventType.SNARE)
    for kit_b in (left, kit.mirrored()):  # the other hand's hi-hat point mirrors too
        a = np.array(kit.effector_target(EventType.HIHATCLOSED, Limb.LEFT_HAND)[0])
        b = np.array(kit_b.effector_target(EventType.HIHATCLOSED, Limb.RIGHT_HAND)[0])
        np.testing.assert_allclose(b, a * [-1, 1, 1], atol=1e-4)


def test_the_other_hand_strikes_the_hihat_where_its_stick_reaches_tip_first() -> None:
    """The left hand plays the hi-hat on its near side (the right hand's point is far from it: the left stick,
    rising from below the plates, met the rim with its shaft 20-30 ms before its tip reached that point)."""
    kit = load_kit()
    for event in (EventType.HIHATCLOSED, EventType.HIHATOPEN):
        right = np.array(kit.effector_target(event, Limb.RIGHT_HAND)[0])
        left = np.array(kit.effector_target(event, Limb.LEFT_HAND)[0])
        np.testing.assert_allclose(right, kit.hit_point(event)[0])
        hihat = kit.object("hihat")
        r, theta = kit.spec(event).off_hand or (0.0, 0.0)
        local = np.array(hihat.rotation_matrix()).T @ (left - np.array(hihat.position))
        np.testing.assert_allclose(np.hypot(local[0], local[1]), r * hihat.radius, atol=1e-9)
        assert left[1] < right[1] - 0.05  # nearer the drummer
    tom = [np.array(kit.effector_target(EventType.HIGHTOM, limb)[0]) for limb in (Limb.LEFT_HAND, Limb.RIGHT_HAND)]
    np.testing.assert_array_equal(tom[0], tom[1])  # without off_hand: one point for both hands


def test_pair_is_antisymmetric() -> None:
    kit = load_kit()
    assert kit.pair(EventType.SNARE, EventType.HIHATCLOSED) == -1.0
    assert kit.pair(EventType.BASS, EventType.COWBELL) == 0.0


def test_invalid_kits_are_refused(tmp_path: Path) -> None:
    data = load_kit().model_dump(mode="json")
    bad = dict(data, double_pedal=True)
    with pytest.raises(ValidationError, match="left_bass_pedal"):
        Kit.model_validate(bad)
    bad = dict(data, note_objects={59: "nope"})
    with pytest.raises(ValidationError, match="unknown object"):
        Kit.model_validate(bad)
    with pytest.raises(FileNotFoundError, match="shipped kits"):
        load_kit("no_such_kit")
    path = tmp_path / "k.json"
    save_kit(load_kit("double_pedal"), path)
    assert load_kit(path) == load_kit("double_pedal")


def test_saving_a_kit_or_key_poses_that_fails_leaves_the_earlier_file(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    # the pose editor saves both; a full disk mid-write left them cut short, the user's work lost
    from common.gesture.keyposes import KeyPoses

    kit_file, poses_file = tmp_path / "mine.yaml", tmp_path / "poses.yaml"
    save_kit(load_kit("default"), kit_file)
    poses_file.write_text("# the user's key poses\n", encoding="utf-8")
    before = {p: p.read_bytes() for p in (kit_file, poses_file)}

    def disk_full(*args: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("common.output_paths.os.replace", disk_full)
    with pytest.raises(OSError):
        save_kit(load_kit("double_pedal"), kit_file)
    with pytest.raises(OSError):
        KeyPoses().save(poses_file)
    assert {p: p.read_bytes() for p in (kit_file, poses_file)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.yaml", "poses.yaml"]


def test_the_right_hand_strikes_the_snare_nearer_the_drummer_than_the_left() -> None:
    """Its rebound no longer carries the right stick's tip into the high tom's rim, which overhangs the snare's far
    side (a hard right-hand snare stroke was followed 15-20 ms later by a loud hit on the high tom)."""
    right, left = Limb.RIGHT_HAND, Limb.LEFT_HAND
    for name, near_hand in (("default", right), ("double_pedal", right), ("left_handed", left)):
        kit = load_kit(name)
        far_hand = left if near_hand == right else right
        near = kit.effector_target(EventType.SNARE, near_hand)[0]
        far = kit.effector_target(EventType.SNARE, far_hand)[0]
        assert far[1] - near[1] > 0.08  # metres, along the drummer's facing direction
        assert abs(far[0] - near[0]) < 1e-6


@pytest.mark.parametrize(("name", "content", "says"), [
    ("k.yaml", b"objects: [snare\n", "not valid YAML: expected ',' or ']', but got '<stream end>' at line 2, column 1"),
    ("k.json", b'{"objects": ', "not valid JSON: Expecting value"),
    ("k.yaml", bytes(range(128, 256)), "is not UTF-8 text (invalid start byte at byte 0)"),
    ("k.yaml", b"- 1\n- 2\n", "not a valid kit: Input should be a valid dictionary"),
    ("k.yaml", b"objects: 5\n", "not a valid kit: name: Field required (and 2 more)"),
])
def test_a_broken_kit_file_is_refused_with_its_name_and_the_problem(tmp_path: Path, name: str, content: bytes,
                                                                    says: str) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ValueError, match="k.(yaml|json)' is ") as refused:
        load_kit(path)
    assert says in str(refused.value)
