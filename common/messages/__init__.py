"""Batteur's OSC messages: typed models, the registry and the codec.

Importing this package registers every message. A module that defines
messages registers them with :func:`register` and is imported here.
"""

from common.messages import events, state, system  # noqa: F401  (register the messages)
from common.messages.base import (
    Arg,
    DropReason,
    Family,
    MessageError,
    OscMessage,
    RigTime,
    WireField,
    WireKind,
)
from common.messages.codec import Decoded, RawMessage, decode, encode, encode_bundle, encode_raw, parse_packet
from common.messages.events import Contact, Impact
from common.messages.registry import REGISTRY, MessageRegistry, register
from common.messages.state import Pose, Skeleton
from common.messages.system import PROTOCOL_VERSION, ClockPing, ClockPong, Health, Hello

__all__ = [
    "Arg",
    "ClockPing",
    "ClockPong",
    "Contact",
    "Decoded",
    "DropReason",
    "Family",
    "Health",
    "Hello",
    "Impact",
    "MessageError",
    "MessageRegistry",
    "OscMessage",
    "PROTOCOL_VERSION",
    "Pose",
    "Skeleton",
    "REGISTRY",
    "RawMessage",
    "RigTime",
    "WireField",
    "WireKind",
    "decode",
    "encode",
    "encode_bundle",
    "encode_raw",
    "parse_packet",
    "register",
]
