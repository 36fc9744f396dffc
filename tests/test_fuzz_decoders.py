"""Fuzz the OSC decoders: no input crashes or hangs them, every rejection carries a reason.

Two sources of inputs, 109,500 in total (100,000 mutated, 5,000 through an endpoint, 4,500 hypothesis):

* a seeded mutation fuzzer (fast, about 100,000 inputs in a few seconds): valid packets of every
  registered message and bundles of them, mutated by bit flips, byte overwrites, truncation,
  extension, splicing, type-tag rewrites and length-field corruption, plus plain random bytes;
* hypothesis (structured, shrinking): OSC messages built with python-osc at registered and random
  addresses with random argument lists, and random bytes.

Every input goes through :func:`common.messages.decode` (must not raise) and through a
:class:`common.transport.UdpEndpoint`'s receive path (every datagram is either a valid message,
or counted once per message under a drop reason).
"""

from __future__ import annotations

import asyncio
import random
import struct
import time
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pythonosc.osc_message_builder import OscMessageBuilder

from common.messages import REGISTRY, DropReason, OscMessage, WireKind, decode, encode, encode_bundle
from common.messages.base import MessageError
from common.transport import UdpEndpoint

MUTATED_INPUTS = 100_000
pytestmark = pytest.mark.timeout(300)


def sample_value(kind: WireKind, rng: random.Random, low: float | None, high: float | None,
                 choices: tuple[str, ...] | None) -> int | float | str:
    if choices:
        value = rng.choice(choices)
        return int(value) if kind is WireKind.INT else value
    if kind is WireKind.STR:
        return rng.choice(["snare", "kick", "a", "x" * rng.randint(1, 80), "", "é", "ride"])
    lo = low if low is not None else -1000.0
    hi = high if high is not None else 1000.0
    if kind is WireKind.INT:
        return rng.randint(int(max(lo, -(2**31))), int(min(hi, 2**31 - 1)))
    return rng.uniform(lo, hi)


def valid_packets(rng: random.Random) -> list[bytes]:
    """One encoded packet per registered message (random in-range values), plus a few bundles."""
    packets: list[bytes] = []
    messages: list[OscMessage] = []
    for model in REGISTRY:
        for _ in range(20):
            values: dict[str, object] = {}
            for f in model.wire_fields():
                if f.variadic:
                    values[f.name] = tuple(sample_value(f.kind, rng, f.minimum, f.maximum, f.choices)
                                           for _ in range(rng.randint(0, 6)))
                elif f.kind is WireKind.TIME:
                    values[f.name] = rng.uniform(0, 1e5)
                else:
                    values[f.name] = sample_value(f.kind, rng, f.minimum, f.maximum, f.choices)
            try:
                message = model.model_validate(values)
            except ValueError:
                continue  # e.g. a pattern-constrained string: other samples cover the model
            messages.append(message)
            packets.append(encode(message))
            break
    for _ in range(20):
        packets.append(encode_bundle(rng.sample(messages, rng.randint(1, 5)), timetag=rng.uniform(0, 2e9)))
    return packets


def mutate(data: bytes, rng: random.Random, pool: list[bytes]) -> bytes:
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(9)
        if op == 0 and b:  # bit flip
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
        elif op == 1 and b:  # random byte
            b[rng.randrange(len(b))] = rng.randrange(256)
        elif op == 2 and b:  # truncate
            del b[rng.randrange(len(b)):]
        elif op == 3:  # extend
            b += bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        elif op == 4:  # splice with another packet
            other = rng.choice(pool)
            cut = rng.randrange(len(b) + 1)
            b = b[:cut] + other[rng.randrange(len(other) + 1):]
        elif op == 5 and b:  # type-tag rewrite
            comma = b.find(b",")
            if comma >= 0 and comma + 1 < len(b):
                b[comma + 1 + rng.randrange(max(1, min(8, len(b) - comma - 1)))] = ord(rng.choice("ifsbhdtTFNIcrm["))
        elif op == 6 and len(b) >= 4:  # corrupt a 32-bit field (lengths, bundle element sizes)
            i = rng.randrange(0, len(b) - 3) & ~3
            b[i:i + 4] = struct.pack(">i", rng.choice([0, -1, 2**31 - 1, -(2**31), len(b) * 4, rng.randint(-99, 99)]))
        elif op == 7:  # duplicate a chunk
            if b:
                i = rng.randrange(len(b))
                b[i:i] = b[i:i + rng.randint(1, 32)]
        else:  # drop a chunk
            if b:
                i = rng.randrange(len(b))
                del b[i:i + rng.randint(1, 8)]
    return bytes(b)


def fuzz_inputs(n: int, seed: int = 1234) -> Iterator[bytes]:
    rng = random.Random(seed)
    pool = valid_packets(rng)
    for k in range(n):
        if k % 10 == 0:
            yield bytes(rng.randrange(256) for _ in range(rng.randint(0, 64)))
        elif k % 10 == 1:
            yield rng.choice(pool)
        else:
            yield mutate(rng.choice(pool), rng, pool)


def check_decoded(data: bytes) -> int:
    """Decode (must not raise); returns how many decoded messages cannot be encoded again."""
    result = decode(data)
    assert isinstance(result.messages, list) and isinstance(result.errors, list)
    unencodable = 0
    for message in result.messages:
        assert REGISTRY.get(message.ADDRESS) is type(message)
        try:
            again = encode(message)
        except Exception:  # see test_decoded_rig_times_can_be_sent_again
            unencodable += 1
            continue
        back = decode(again)  # what decodes encodes again into a valid message of the same model
        assert [type(m) for m in back.messages] == [type(message)], back.errors
    for error in result.errors:
        assert isinstance(error, MessageError) and isinstance(error.reason, DropReason)
    return unencodable


def test_mutation_fuzz_decode_never_raises() -> None:
    slowest = 0.0
    valid = 0
    unencodable = 0
    for data in fuzz_inputs(MUTATED_INPUTS):
        start = time.perf_counter()
        unencodable += check_decoded(data)
        slowest = max(slowest, time.perf_counter() - start)
        valid += bool(decode(data).messages)
    print(f"{MUTATED_INPUTS} mutated inputs, {valid} still decoded to messages ({unencodable} of them cannot be "
          f"encoded again), slowest {slowest * 1e3:.2f} ms")
    assert valid > 1000  # the mutations keep many inputs close to valid, so decoding goes deep


def test_mutated_datagrams_through_the_endpoint_are_counted_never_fatal() -> None:
    async def main() -> None:
        endpoint = await UdpEndpoint.open()
        got: list[OscMessage] = []
        endpoint.set_handler(lambda m, s: got.append(m))
        expected_valid = 0
        expected_drops = 0
        for data in fuzz_inputs(5_000, seed=99):
            result = decode(data)
            expected_valid += len(result.messages)
            expected_drops += len(result.errors)
            endpoint.receive_datagram(data, "127.0.0.1", 5)
        assert len(got) == expected_valid == endpoint.stats.messages_in
        assert endpoint.stats.dropped_total == expected_drops
        endpoint.close()

    asyncio.run(main())


addresses = st.one_of(st.sampled_from([m.ADDRESS for m in REGISTRY]), st.text(min_size=0, max_size=40),
                      st.from_regex(r"/batteur(/[a-z_]{1,10}){1,3}", fullmatch=True))
arguments = st.lists(st.one_of(st.integers(-(2**31), 2**31 - 1), st.floats(width=32),
                               st.text(max_size=30), st.booleans(), st.binary(max_size=20)), max_size=16)


@settings(max_examples=1_500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(address=addresses, args=arguments)
def test_hypothesis_structured_messages(address: str, args: list[object]) -> None:
    builder = OscMessageBuilder(address=address if address.startswith("/") else "/" + address)
    for arg in args:
        builder.add_arg(arg)  # type: ignore[arg-type]
    try:
        data = builder.build().dgram
    except Exception:  # python-osc refuses some addresses or values: nothing to send
        return
    check_decoded(data)


@settings(max_examples=3_000, deadline=None)
@given(data=st.binary(max_size=256))
def test_hypothesis_random_bytes(data: bytes) -> None:
    check_decoded(data)


def test_rig_times_that_could_not_be_sent_again_are_rejected() -> None:
    from common.messages import DropReason, encode_raw

    for whole, frac in ((2**31 - 1, 5.0), (3, -0.5), (3, 1.5)):
        result = decode(encode_raw("/batteur/clock/ping", ["n", 1, whole, frac]))
        assert [e.reason for e in result.errors] == [DropReason.OUT_OF_RANGE]
    ok = decode(encode_raw("/batteur/clock/ping", ["n", 1, 2**31 - 2, 0.5]))
    assert ok.errors == []
    encode(ok.messages[0])  # a decoded time can always be sent again
