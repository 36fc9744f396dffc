"""Encode and decode throughput per message kind (messages per second).

Every registered message gets one sample instance (hand-made for the core
messages, generated from the wire fields for the rest) and is encoded and
decoded ``--count`` times through :mod:`common.messages.codec`, the path every
message takes on the wire and on the in-memory bus.

    python bench/codec_bench.py            # about 10 s
    python bench/codec_bench.py --count 2000
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.arg_types import count  # noqa: E402
from common.messages import (  # noqa: E402
    REGISTRY,
    Arg,
    ClockPing,
    ClockPong,
    Contact,
    Health,
    Hello,
    Impact,
    MessageError,
    OscMessage,
    Pose,
    Skeleton,
    WireKind,
    decode,
    encode,
)


def samples() -> dict[str, OscMessage]:
    """One representative instance per message kind (Pose: 21 links, as a full body sends)."""
    hand: list[OscMessage] = [
        Hello(role="physics", node_id="physics-host-1234", protocol=1, osc_port=9000),
        Health(node_id="physics-host-1234", role="physics", protocol=1, time=1234.5, rate_hz=999.7,
               target_rate_hz=1000.0, overruns=3, messages_in=12345, messages_out=67890, dropped=4,
               dropped_malformed=1, dropped_unknown=1, dropped_type=1, dropped_range=1, dropped_other=0,
               late=0, peers=3),
        ClockPing(node_id="sound-host-1", seq=42, t_send=1234.5678),
        ClockPong(node_id="sound-host-1", seq=42, t_send=1234.5678, t_receive=1244.1, t_reply=1244.1001),
        Contact(time=12.345, step=12345, instrument="snare", part="right_stick_tip", x=0.1, y=0.5, z=0.7,
                local_x=0.01, local_y=0.02, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                normal_velocity=3.2, impulse=0.015, normal_force=150.0),
        Impact(seq=7, time=12.345, instrument="snare", zone="centre", r=0.3, theta=0.4, velocity=3.2,
               impulse=0.02, peak_force=300.0, duration=0.004, part="right_stick_tip"),
        Skeleton(layout=1, names=tuple(f"link_{i}" for i in range(21))),
        Pose(time=12.345, layout=1, values=tuple(0.1 * i for i in range(21 * 7))),
    ]
    out = {type(m).__name__: m for m in hand}
    for model in REGISTRY:  # messages added by other modules: generated from their wire fields
        if model.__name__ not in out:
            generated = generate(model)
            if generated is not None:
                out[model.__name__] = generated
    return out


def generate(model: type[OscMessage]) -> OscMessage | None:
    args: list[Arg] = []
    for f in model.wire_fields():
        low = f.minimum if f.minimum is not None else 0.0
        high = f.maximum if f.maximum is not None else low + 1.0
        count = 8 if f.variadic else 1
        for _ in range(count):
            if f.kind is WireKind.TIME:
                args += [12, 0.5]
            elif f.kind is WireKind.INT:
                args.append(int(low))
            elif f.kind is WireKind.FLOAT:
                args.append(float(low + high) / 2)
            else:
                args.append(f.choices[0] if f.choices else "a")
    try:
        return model.from_args(args)
    except MessageError:
        return None


def bench(message: OscMessage, count: int) -> tuple[float, float, int]:
    """Encode and decode ``count`` times; (encodes/s, decodes/s, bytes)."""
    t0 = time.perf_counter()
    for _ in range(count):
        data = encode(message)
    t1 = time.perf_counter()
    for _ in range(count):
        decoded = decode(data)
    t2 = time.perf_counter()
    if decoded.errors or decoded.messages[0].ADDRESS != message.ADDRESS:
        raise AssertionError(f"{type(message).__name__} did not round-trip: {decoded.errors}")
    return count / (t1 - t0), count / (t2 - t1), len(data)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=count, default=5000, help="encodes and decodes per kind (default 5000)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    print(f"codec throughput, {args.count} encodes + {args.count} decodes per kind (python-osc + pydantic)")
    print(f"{'message':<20} {'bytes':>6} {'encode/s':>10} {'decode/s':>10} {'round trip/s':>13}")
    for name, message in samples().items():
        enc, dec, size = bench(message, args.count)
        both = 1 / (1 / enc + 1 / dec)
        print(f"{name:<20} {size:>6} {enc:>10,.0f} {dec:>10,.0f} {both:>13,.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
