"""Every message model round-trips through OSC bytes; every bad input is rejected with its reason."""

from __future__ import annotations

import math
import time
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import Field, ValidationError
from pythonosc.osc_message import OscMessage as PyOscMessage

from common.messages import (
    REGISTRY,
    DropReason,
    Impact,
    MessageRegistry,
    OscMessage,
    WireKind,
    decode,
    encode,
    encode_bundle,
    encode_raw,
    parse_packet,
)
from common.messages.base import MessageError
from common.messages.codec import _build as build_with_python_osc
from common.messages.state import Pose

CROSS_FIELD_EXAMPLES: dict[str, dict[str, Any]] = {"/batteur/graphics/plot": {"z_min": 0.0, "z_max": 1.5}}
"""Values for fields whose rule involves another field (z_max above z_min): a valid pair, not each one's midpoint."""


def example_args(model: type[OscMessage]) -> dict[str, Any]:
    """A valid value for every field, inside its declared range (and valid together: ``CROSS_FIELD_EXAMPLES``)."""
    values: dict[str, Any] = {}
    for f in model.wire_fields():
        if f.choices:
            value: Any = f.choices[0]
            if f.kind is WireKind.INT:
                value = int(value)
        elif f.kind is WireKind.STR:
            patterns = [getattr(m, "pattern", None) for m in model.model_fields[f.name].metadata]
            value = "/a/name" if any(p and p.startswith("^/") for p in patterns) else "a_name"
        elif f.kind is WireKind.TIME:
            value = 1234.5
        elif f.kind is WireKind.INT:
            value = int(f.minimum) + 1 if f.minimum is not None else 7
        else:
            low = f.minimum if f.minimum is not None else -1.0
            high = f.maximum if f.maximum is not None else low + 2.0
            value = (low + high) / 2 if math.isfinite(high) else low + 1.0
        if f.variadic:
            value = (value, value, value)
        values[f.name] = value
    return {**values, **CROSS_FIELD_EXAMPLES.get(model.ADDRESS, {})}


@pytest.mark.parametrize("model", list(REGISTRY), ids=lambda m: m.ADDRESS)
def test_every_model_round_trips(model: type[OscMessage]) -> None:
    message = model.model_validate(example_args(model))
    decoded = decode(encode(message))
    assert decoded.errors == []
    assert len(decoded.messages) == 1
    back = decoded.messages[0]
    assert type(back) is model
    for name in model.model_fields:
        a, b = getattr(message, name), getattr(back, name)
        if isinstance(a, float):
            assert b == pytest.approx(a, rel=1e-6, abs=1e-6)
        else:
            assert a == b


def _impact() -> Impact:
    return Impact(
        # values exact in float32, so a decoded copy compares equal
        seq=1, time=100.25, instrument="snare", zone="centre", r=0.375, theta=1.0,
        velocity=2.0, impulse=0.0078125, peak_force=150.0, duration=0.00390625, part="right_stick_tip",
    )


def test_rig_time_keeps_sample_accuracy_after_hours() -> None:
    t = 7 * 3600 + 0.123456
    message = _impact().model_copy(update={"time": t})
    back = decode(encode(message)).messages[0]
    assert isinstance(back, Impact)
    assert abs(back.time - t) < 1e-6  # float32 alone would be off by about 1 ms


def test_bundles_are_accepted() -> None:
    decoded = decode(encode_bundle([_impact(), _impact()], timetag=time.time() + 3600))
    assert [type(m) for m in decoded.messages] == [Impact, Impact]


def test_pure_data_floats_are_accepted_for_ints() -> None:
    args = _impact().to_args()
    args[0] = 1.0  # seq as Pd sends it
    assert decode(encode_raw(Impact.ADDRESS, args)).messages[0] == _impact()


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"\x00\x01garbage", DropReason.MALFORMED),
        (b"/batteur/impact\x00,i", DropReason.MALFORMED),
        (encode_raw("/no/such/address", [1]), DropReason.UNKNOWN_ADDRESS),
        (encode_raw(Impact.ADDRESS, [1, 2]), DropReason.WRONG_ARITY),
        (encode_raw(Impact.ADDRESS, ["one", *_impact().to_args()[1:]]), DropReason.WRONG_TYPE),
        (encode_raw(Impact.ADDRESS, [1.5, *_impact().to_args()[1:]]), DropReason.WRONG_TYPE),
        (encode_raw(Impact.ADDRESS, [-1, *_impact().to_args()[1:]]), DropReason.OUT_OF_RANGE),
        (encode_raw(Impact.ADDRESS, [*_impact().to_args()[:6], float("nan"), *_impact().to_args()[7:]]),
         DropReason.OUT_OF_RANGE),
    ],
    ids=["garbage", "truncated", "unknown", "arity", "type-str", "type-frac", "range", "nan"],
)
def test_bad_input_is_rejected_with_its_reason(data: bytes, reason: DropReason) -> None:
    decoded = decode(data)
    assert decoded.messages == []
    assert [e.reason for e in decoded.errors] == [reason]


def test_one_bad_message_in_a_bundle_does_not_lose_the_others() -> None:
    good = _impact()
    bad = good.model_copy(update={"velocity": 1000.0})  # bypasses validation, out of range on decode
    decoded = decode(encode_bundle([good, bad, good]))
    assert decoded.messages == [good, good]
    assert [e.reason for e in decoded.errors] == [DropReason.OUT_OF_RANGE]


def test_a_value_sent_exactly_at_a_range_bound_survives_float32() -> None:
    class Gain(OscMessage):
        ADDRESS = "/test/gain"
        level: float = Field(ge=0.01, le=0.3)

    registry = MessageRegistry()
    registry.add(Gain)
    for value in (0.01, 0.3):
        decoded = decode(encode_raw(Gain.ADDRESS, [value]), registry)  # float32: 0.0099999998, 0.30000001
        assert decoded.errors == [] and decoded.messages[0] == Gain(level=value)
    # beyond float32 rounding it is still out of range
    assert [e.reason for e in decode(encode_raw(Gain.ADDRESS, [0.0099]), registry).errors] == [DropReason.OUT_OF_RANGE]


_ARGS = st.lists(st.one_of(
    st.floats(width=32, allow_nan=False), st.integers(-2**31, 2**31 - 1), st.booleans(),
    st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), max_size=12)), max_size=40)


@settings(max_examples=300, deadline=None)
@given(address=st.from_regex(r"/[a-z/_]{0,20}", fullmatch=True), args=_ARGS)
def test_the_fast_codec_gives_python_oscs_bytes_and_values(address: str, args: list[Any]) -> None:
    """Batteur's messages take a one-struct-call path (codec.py); it must be python-osc's encoding exactly."""
    data = encode_raw(address, args)
    assert data == bytes(build_with_python_osc(address, args).dgram)
    (raw,) = parse_packet(data)
    reference = PyOscMessage(data)
    assert raw.address == reference.address
    assert raw.args == [int(a) if isinstance(a, bool) else a for a in reference.params]


def test_the_fast_codec_leaves_errors_and_other_types_to_the_full_parser() -> None:
    with pytest.raises(Exception, match="(?i)float|range|pack"):
        encode_raw("/batteur/x", [1e40])  # beyond float32: python-osc's error
    blob = b"/x\0\0,b\0\0\0\0\0\x02ab\0\0"  # a blob argument: parsed by codec._parse_message
    (raw,) = parse_packet(blob)
    assert raw.address == "/x" and len(raw.args) == 1
    for malformed in (b"/x\0\0,s\0\0abc", b"/x\0\0,i\0\0\0\0"):  # a string without its null; half an int
        with pytest.raises(MessageError):
            parse_packet(malformed)
    # python-osc reads a float cut short as padded with zeros (some senders drop the trailing nulls): so do we
    assert parse_packet(b"/x\0\0,f\0\0\0\0")[0].args == [0.0]


@settings(max_examples=200, deadline=None)
@given(head=_ARGS, tail=st.lists(st.one_of(st.floats(width=32, allow_nan=False, allow_infinity=False),
                                           st.integers(-5, 5)), max_size=60),
       start=st.integers(0, 3))
def test_a_float_tail_packed_as_one_run_gives_python_oscs_bytes(head: list[Any], tail: list[Any], start: int) -> None:
    """``floats_from`` (a pose's values) changes only the speed: a tail with an int in it is packed value by value."""
    args = head + tail
    at = max(0, len(head) - start)
    assert encode_raw("/batteur/pose", args, at) == bytes(build_with_python_osc("/batteur/pose", args).dgram)


def test_a_pose_round_trips_and_a_bad_value_in_its_tail_is_still_refused() -> None:
    pose = Pose(time=12.5, layout=7, values=tuple(float(k) / 8 for k in range(700)))
    data = encode(pose)
    assert data == bytes(build_with_python_osc(Pose.ADDRESS, pose.to_args()).dgram)
    (back,) = decode(data).messages
    assert back == pose
    raw = pose.to_args()
    for bad, reason in ((math.nan, DropReason.OUT_OF_RANGE), (math.inf, DropReason.OUT_OF_RANGE),
                        ("x", DropReason.WRONG_TYPE)):
        args = [*raw[:100], bad, *raw[101:]]
        with pytest.raises(MessageError) as caught:
            Pose.from_args(args)
        assert caught.value.reason is reason
    assert Pose.from_args([*raw[:3], 1, *raw[4:]]).values[0] == 1.0  # an int (Pure Data) is a float there


def test_a_float_beyond_32_bits_is_refused_when_the_message_is_made() -> None:
    # it was accepted and then failed to encode ("float too large to pack"), after the sender had committed to it
    checked = 0
    for model in REGISTRY:
        args = example_args(model)
        for f in model.wire_fields():
            if f.kind is not WireKind.FLOAT or (f.maximum is not None and f.maximum < 1e39):
                continue
            big = (0.0, 1e39) if f.variadic else 1e39
            with pytest.raises(ValidationError, match=f.name):  # its own range, or the wire's
                model(**{**args, f.name: big})
            checked += 1
    assert checked >= 5  # impulses, forces, joint values, poses ...
    with pytest.raises(ValidationError, match="impulse: beyond a 32-bit float"):
        Impact(**{**example_args(Impact), "impulse": 1e39})
    largest = Impact(**{**example_args(Impact), "impulse": 3.0e38})
    (back,) = decode(encode(largest)).messages  # the largest a 32-bit float holds still goes
    assert isinstance(back, Impact) and back.impulse == pytest.approx(3.0e38, rel=1e-7)
