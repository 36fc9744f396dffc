"""Batteur's OSC messages: typed models, the registry and the codec.

Importing this package registers every message. A module that defines
messages registers them with :func:`register` and is imported here.
"""

from common.messages import (  # noqa: F401  (importing a module registers its messages)
    events,
    graphics,
    interaction,
    physics,
    recogniser,
    score,
    sound,
    state,
    system,
)
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
from common.messages.system import (
    PROTOCOL_VERSION,
    ClockPing,
    ClockPong,
    ClockStatus,
    Health,
    Hello,
    Subscribe,
    SubscribeRefused,
)

__all__ = [
    "Arg",
    "ClockPing",
    "ClockPong",
    "ClockStatus",
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
    "Subscribe",
    "SubscribeRefused",
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
