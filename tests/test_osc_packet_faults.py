"""Hostile OSC bundles and argument types (found by an OSC walkthrough): a bundle element of negative size
hung any node forever in python-osc's parser; malformed bundles were dropped uncounted, each logged to the root
logger unrated; ``T``/``F`` arguments were taken as numbers.

Every datagram here goes through :func:`common.messages.decode` and an endpoint's receive path."""

from __future__ import annotations

import asyncio
import logging
import random
import struct
import subprocess
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pythonosc.osc_message import OscMessage as PyOscMessage
from pythonosc.osc_message_builder import OscMessageBuilder

from common.messages import DropReason, decode, encode
from common.messages.base import MessageError
from common.messages.codec import MAX_BUNDLE_DEPTH, _parse_message, _unpack, _Unsupported, parse_packet
from common.messages.sound import SoundLatency
from common.stats import TrafficStats
from common.transport import UdpEndpoint

pytestmark = pytest.mark.timeout(120)

HEADER = b"#bundle\0" + bytes(8)
LATENCY = encode(SoundLatency(value=0.25))


def element(data: bytes) -> bytes:
    return struct.pack(">i", len(data)) + data


def bundle(*elements: bytes) -> bytes:
    return HEADER + b"".join(element(e) for e in elements)


def osc_string(text: str) -> bytes:
    raw = text.encode() + b"\0"
    return raw + b"\0" * (-len(raw) % 4)


MALFORMED_BUNDLES = {
    "negative size": HEADER + struct.pack(">i", -4),
    "negative size after a message": bundle(LATENCY) + struct.pack(">i", -4) + LATENCY,
    "most negative size": HEADER + struct.pack(">i", -(2**31)) + bytes(8),
    "negative size in a nested bundle": bundle(HEADER + struct.pack(">i", -8)),
    "zero size": HEADER + struct.pack(">i", 0),
    "size not a multiple of 4": HEADER + struct.pack(">i", 5) + LATENCY[:5] + bytes(3),
    "truncated element": HEADER + struct.pack(">i", 100) + b"/a",
    "element past its nested bundle": bundle(HEADER + struct.pack(">i", len(LATENCY) + 4) + LATENCY) + bytes(4),
    "garbage element": bundle(b"\x01" * 8),
    "stray bytes after the last element": bundle(LATENCY) + b"\0\0",
    "cut in the timetag": b"#bundle\0" + bytes(4),
    "nested bundle shorter than its header": bundle(b"#bundle\0"),
    "malformed message inside": bundle(LATENCY, osc_string("/batteur/sound/latency") + b",f\0\0"),
}


def nested(depth: int) -> bytes:
    """``depth`` bundles one inside the other around one latency message."""
    data = LATENCY
    for _ in range(depth):
        data = bundle(data)
    return data


def test_a_negative_element_size_ends_instead_of_hanging() -> None:
    """The walkthrough's datagram, in a child process so a hang fails the test instead of stalling the run."""
    code = ("import struct; from common.messages import decode; "
            "print(decode(b'#bundle\\x00' + bytes(8) + struct.pack('>i', -4)).errors[0].reason)")
    try:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("parsing a bundle element of size -4 did not end")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "malformed"


@pytest.mark.parametrize("name", list(MALFORMED_BUNDLES))
def test_a_malformed_bundle_is_one_malformed_drop_that_says_why(name: str) -> None:
    result = decode(MALFORMED_BUNDLES[name])
    assert result.messages == []
    assert [e.reason for e in result.errors] == [DropReason.MALFORMED]
    assert str(result.errors[0]).strip() != "malformed:"


def test_bundles_as_osc_allows_are_taken() -> None:
    assert decode(HEADER).errors == [] and decode(HEADER).messages == []  # no elements: valid OSC, holds nothing
    assert decode(bundle(HEADER, LATENCY)).messages == [SoundLatency(value=0.25)]  # an empty bundle inside
    assert decode(nested(MAX_BUNDLE_DEPTH)).messages == [SoundLatency(value=0.25)]
    assert [e.reason for e in decode(nested(MAX_BUNDLE_DEPTH + 1)).errors] == [DropReason.MALFORMED]


def test_malformed_bundles_are_counted_by_the_endpoint() -> None:
    async def main() -> None:
        endpoint = await UdpEndpoint.open()
        for data in MALFORMED_BUNDLES.values():
            endpoint.receive_datagram(data, "127.0.0.1", 5)
        endpoint.receive_datagram(HEADER, "127.0.0.1", 5)  # empty: no drop
        assert endpoint.stats.dropped[DropReason.MALFORMED] == len(MALFORMED_BUNDLES)
        assert endpoint.stats.dropped_total == len(MALFORMED_BUNDLES)
        endpoint.close()

    asyncio.run(main())


BAD_TAG_MESSAGES = [
    osc_string("/batteur/sound/latency") + b",fc\0" + struct.pack(">f", 0.1) + b"x\0\0\0",  # python-osc skipped c
    osc_string("/batteur/sound/latency") + b",fI\0" + struct.pack(">f", 0.1),  # ... and I
    osc_string("/batteur/sound/latency") + osc_string(",x") + struct.pack(">f", 0.1),  # a tag of unknown size
]


def test_a_burst_of_bad_packets_logs_a_bounded_number_of_lines(caplog: pytest.LogCaptureFixture) -> None:
    """python-osc logged one root WARNING per garbage bundle element and per unknown tag: 400 bad bundles, 403
    lines. Now every bad packet is a counted drop, logged once per reason per interval (a frozen clock: one
    interval however slow the machine)."""
    bad = [*MALFORMED_BUNDLES.values(), *BAD_TAG_MESSAGES, bundle(b"\x01" * 8, LATENCY), bundle(LATENCY, b"ab\0\0")]

    async def main() -> int:
        endpoint = await UdpEndpoint.open(stats=TrafficStats(clock=lambda: 0.0))
        for k in range(400):
            endpoint.receive_datagram(bad[k % len(bad)], "127.0.0.1", 5)
        endpoint.close()
        return endpoint.stats.dropped_total

    with caplog.at_level(logging.DEBUG):
        caplog.clear()
        dropped = asyncio.run(main())
    assert dropped == 400
    lines = [r for r in caplog.records if r.levelno >= logging.INFO]
    assert 1 <= len(lines) <= 3, [r.getMessage()[:80] for r in lines]  # malformed, wrong arity, wrong type


def fuzzed_bundle(rng: random.Random, depth: int = 0) -> bytes:
    """A random bundle: valid elements, nested bundles and garbage, with sizes sometimes lying."""
    out = bytearray(HEADER if rng.random() < 0.9 else b"#bundle\0" + bytes(rng.randrange(8)))
    for _ in range(rng.randrange(5)):
        kind = rng.randrange(6)
        if kind == 0 and depth < 12:
            body = fuzzed_bundle(rng, depth + 1)
        elif kind == 1:
            body = bytes(rng.randrange(256) for _ in range(rng.randrange(12)))
        else:
            body = LATENCY
        size = len(body)
        if rng.random() < 0.3:
            size = rng.choice([-4, -8, -1, -(2**31), 0, 2**31 - 1, size + rng.randint(-9, 9), -size])
        out += struct.pack(">i", size) + body
    if rng.random() < 0.2:
        out += bytes(rng.randrange(4))
    return bytes(out)


def test_random_bundles_end_and_raise_nothing_but_a_malformed_error() -> None:
    """A seeded fuzz in a child process (so a hang fails rather than stalls): every bundle parses or is refused
    as malformed, and decoding never raises."""
    code = """
import random, sys
from tests.test_osc_packet_faults import fuzzed_bundle
from common.messages import DropReason, decode
from common.messages.base import MessageError
from common.messages.codec import parse_packet
rng = random.Random(2026)
refused = parsed = 0
for _ in range(4000):
    data = fuzzed_bundle(rng)
    try:
        parse_packet(data)
        parsed += 1
    except MessageError as exc:
        assert exc.reason is DropReason.MALFORMED, exc
        refused += 1
    decode(data)
print(parsed, refused)
"""
    try:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=100)
    except subprocess.TimeoutExpired:
        pytest.fail("a random bundle did not end")
    assert done.returncode == 0, done.stderr[-2000:]
    parsed, refused = map(int, done.stdout.split())
    assert parsed > 100 and refused > 100  # both kinds were tried


# --------------------------------------------------------------------------- argument types


def one_arg(tag: str, payload: bytes) -> bytes:
    return osc_string(SoundLatency.ADDRESS) + osc_string("," + tag) + payload


TAKEN = {  # int64 and float64 are numbers like i and f (docs/osc.md)
    "h": struct.pack(">q", 1),
    "d": struct.pack(">d", 0.5),
}
REFUSED = {  # every other type is not an argument Batteur takes: a wrong type
    "T": b"", "F": b"", "N": b"", "I": b"",
    "t": bytes(8), "b": struct.pack(">i", 2) + b"ab\0\0", "c": b"\0\0\0a", "r": b"\0\0\0\1", "m": b"\0\x90\x40\x7f",
    "S": osc_string("one"), "[f]": struct.pack(">f", 0.5),
}


@pytest.mark.parametrize("tag", list(REFUSED))
def test_an_argument_of_another_osc_type_is_a_wrong_type(tag: str) -> None:
    """``,T`` set the sound latency to 1 s: python-osc reads True, which was taken as the number 1."""
    result = decode(one_arg(tag, REFUSED[tag]))
    assert result.messages == []
    assert [e.reason for e in result.errors] == [DropReason.WRONG_TYPE], result.errors
    assert f"OSC type '{tag[0]}'" in str(result.errors[0])


@pytest.mark.parametrize("tag", list(TAKEN))
def test_int64_and_double_arguments_are_numbers(tag: str) -> None:
    (message,) = decode(one_arg(tag, TAKEN[tag])).messages
    assert message == SoundLatency(value=struct.unpack(">" + ("q" if tag == "h" else "d"), TAKEN[tag])[0])


def test_an_int64_must_still_fit_an_int_field() -> None:
    data = osc_string("/batteur/hello") + osc_string(",sshi") + osc_string("physics") + osc_string("n") + \
        struct.pack(">q", 2**40) + struct.pack(">i", 9000)
    assert [e.reason for e in decode(data).errors] == [DropReason.OUT_OF_RANGE]


@pytest.mark.parametrize("data", BAD_TAG_MESSAGES, ids=["c", "I", "unknown"])
def test_a_tag_python_osc_skipped_is_no_longer_lost(data: bytes) -> None:
    """python-osc skipped ``c``, ``I`` and unknown tags: ``,fc`` passed as one float."""
    result = decode(data)
    assert result.messages == []
    assert result.errors[0].reason in {DropReason.WRONG_ARITY, DropReason.MALFORMED}


def test_bytes_after_the_last_argument_are_malformed() -> None:
    with pytest.raises(MessageError) as caught:
        parse_packet(LATENCY + bytes(4))
    assert caught.value.reason is DropReason.MALFORMED and "after the last argument" in str(caught.value)


_ANY_ARGS = st.lists(st.one_of(
    st.integers(-(2**31), 2**31 - 1), st.floats(width=32, allow_nan=False), st.booleans(), st.none(),
    st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), max_size=12),
    st.binary(min_size=1, max_size=12)), max_size=12)  # python-osc builds no empty blob


@settings(max_examples=400, deadline=None)
@given(args=_ANY_ARGS)
def test_the_parser_reads_what_python_osc_reads(args: list[object]) -> None:
    """Batteur's parser replaced python-osc's: the same values for every type python-osc builds (i, f, s, T, F,
    N, b), numbers and strings as arguments, the rest as unsupported arguments that carry the same value."""
    builder = OscMessageBuilder(address="/batteur/x")
    for arg in args:
        builder.add_arg(arg)  # type: ignore[arg-type]
    data = builder.build().dgram
    (raw,) = parse_packet(data)
    reference = PyOscMessage(data).params
    assert len(raw.args) == len(reference)
    for mine, theirs in zip(raw.args, reference, strict=True):
        if isinstance(mine, _Unsupported):
            assert isinstance(theirs, (bool, bytes)) or theirs is None
            assert mine.value == theirs and type(mine.value) is type(theirs)
        else:
            assert not isinstance(theirs, bool) and mine == theirs and type(mine) is type(theirs)


def test_a_type_tag_the_fast_path_does_not_know_is_malformed_on_both_paths() -> None:
    """The fast path flushed its last run of numbers on a '|' it appended to the tags, and so took a real '|' tag
    (or any tag equal to its sentinel) as nothing: ``/x ,i|i 1 2`` was two ints there, malformed on the slow path."""
    data = b"/x\0\0,i|i\0\0\0\0" + struct.pack(">ii", 1, 2)
    assert _unpack(data) is None
    with pytest.raises(MessageError) as caught:
        parse_packet(data)
    assert caught.value.reason is DropReason.MALFORMED and "'|'" in str(caught.value)


_NUMBERS_AND_STRINGS = st.lists(st.one_of(
    st.integers(-(2**31), 2**31 - 1), st.floats(width=32, allow_nan=False),
    st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\0"), max_size=12)), max_size=12)


@settings(max_examples=300, deadline=None)
@given(args=_NUMBERS_AND_STRINGS, tail=st.binary(max_size=6))
def test_the_fast_path_and_the_slow_path_read_alike(args: list[object], tail: bytes) -> None:
    """Messages of i, f and s arguments (the ones the fast path reads), whole or with bytes after them: whatever
    the fast path reads, the slow path reads the same; what it leaves, the slow path reads or refuses."""
    builder = OscMessageBuilder(address="/batteur/x")
    for arg in args:
        builder.add_arg(arg)  # type: ignore[arg-type]
    for data in (builder.build().dgram, builder.build().dgram + tail):
        fast = _unpack(data)
        if fast is not None:
            assert _parse_message(data) == fast
