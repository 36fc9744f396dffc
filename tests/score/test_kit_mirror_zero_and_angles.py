"""Mirroring writes zero as ``0.0`` (a mirrored kit file held ``-0.0`` wherever x, pitch or yaw was 0), and a kit's
hit-point angles are bounded to -pi..2pi rad: the range mirroring (``pi - theta``) maps onto itself, holding an
angle written -pi..pi or 0..2pi, within which every angle written with up to 12 decimals mirrors back exactly
(no bound held angles of any size, NaN too)."""

from __future__ import annotations

import math
import random
import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from common.kit import EventType, Kit, load_kit, mirrored_angle, save_kit

NEGATIVE_ZERO = re.compile(r"(?<![\d.])-0\.0(?![\d.e])")
"""``-0.0`` as yaml writes it (and not -0.05 or -0.0e+00's neighbours)."""


def _negative_zeros(value: Any, where: str = "") -> list[str]:
    """Where ``value`` (a kit's ``model_dump``) holds -0.0."""
    if isinstance(value, dict):
        return [w for k, v in value.items() for w in _negative_zeros(v, f"{where}.{k}")]
    if isinstance(value, (list, tuple)):
        return [w for i, v in enumerate(value) for w in _negative_zeros(v, f"{where}[{i}]")]
    return [where] if isinstance(value, float) and value == 0.0 and math.copysign(1.0, value) < 0 else []


def _kit_file(path: Path, **snare: Any) -> Path:
    """The default kit with the snare's spec updated by ``snare``, saved as YAML at ``path``."""
    data = load_kit("default", warn=False).model_dump(mode="json")
    data["events"]["SNARE"].update(snare)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.mark.parametrize("name", ["default", "double_pedal"])
def test_a_mirrored_kit_is_written_without_negative_zeros(tmp_path: Path, name: str) -> None:
    kit = load_kit(name, warn=False)
    assert _negative_zeros(kit.model_dump()) == []
    mirrored = kit.mirrored()
    assert _negative_zeros(mirrored.model_dump()) == []  # was: every object's zero x, pitch and yaw
    save_kit(mirrored, tmp_path / "left.yaml")
    assert NEGATIVE_ZERO.findall((tmp_path / "left.yaml").read_text()) == []
    assert mirrored.mirrored() == kit


def test_an_angle_mirrored_to_zero_is_positive_zero() -> None:
    just_past_pi = math.nextafter(math.pi, 4.0)  # pi - theta: -4.4e-16, within noise of the 12-decimal 0
    assert math.copysign(1.0, mirrored_angle(just_past_pi)) == 1.0
    assert math.copysign(1.0, mirrored_angle(math.pi)) == 1.0


@pytest.mark.parametrize(("snare", "field", "value"), [
    ({"theta": 7.0}, "events.SNARE.theta", "7.0"),
    ({"theta": -3.2}, "events.SNARE.theta", "-3.2"),
    ({"theta": 100.0}, "events.SNARE.theta", "100.0"),
    ({"off_hand": [0.25, -4.0]}, "events.SNARE.off_hand.1", "-4.0"),
])
def test_a_hit_point_angle_beyond_the_range_is_refused_in_words(tmp_path: Path, snare: dict[str, Any],
                                                                field: str, value: str) -> None:
    path = _kit_file(tmp_path / "far.yaml", **snare)
    with pytest.raises(ValueError) as refused:  # was: loaded, and a 100 rad angle did not mirror back exactly
        load_kit(path, warn=False)
    message = str(refused.value)
    assert message.startswith(f"kit file {str(path)!r} is not a valid kit: {field}: must be within -pi..2pi rad "
                              f"(-3.141593..6.283185")
    assert message.endswith(f", got {value}")


def test_a_nan_hit_point_angle_is_refused(tmp_path: Path) -> None:
    path = _kit_file(tmp_path / "nan.yaml", theta=math.nan)
    assert "theta: .nan" in path.read_text()
    with pytest.raises(ValueError, match=r"events\.SNARE\.theta: must be within -pi\.\.2pi rad"):
        load_kit(path, warn=False)


def test_angles_at_the_ends_of_the_range_load_and_mirror_into_it(tmp_path: Path) -> None:
    """-pi and 2pi mirror into each other exactly: a kit with either loads, and so does its mirror."""
    kit = load_kit(_kit_file(tmp_path / "ends.yaml", theta=-math.pi, off_hand=[0.25, 2 * math.pi]), warn=False)
    once = kit.mirrored()
    assert once.spec(EventType.SNARE).theta == 2 * math.pi and once.spec(EventType.SNARE).off_hand == (0.25,
                                                                                                        -math.pi)
    assert once.mirrored() == kit


def test_every_12_decimal_angle_in_the_range_mirrors_back_exactly() -> None:
    """Any angle a kit may hold written with up to 12 decimals, -pi..2pi: its mirror is the float nearest
    pi - theta, in the range, and mirrors back to it."""
    rng = random.Random(29)
    low, high = -math.pi, 2 * math.pi
    for _ in range(20000):
        theta = min(max(round(rng.uniform(low, high), rng.randint(0, 12)), low), high)
        mirrored = mirrored_angle(theta)
        assert mirrored == math.pi - theta and low <= mirrored <= high
        assert mirrored_angle(mirrored) == theta, theta


def test_a_kit_holding_an_angle_out_of_range_cannot_be_built() -> None:
    data = load_kit("default", warn=False).model_dump()
    data["events"][EventType.SNARE]["theta"] = 2 * math.pi + 1e-9
    with pytest.raises(ValueError, match="must be within -pi..2pi rad"):
        Kit.model_validate(data)
