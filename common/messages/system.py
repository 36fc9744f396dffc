"""Messages every node speaks: hello, health and the clock exchange."""

from __future__ import annotations

from typing import Annotated, ClassVar

from pydantic import Field

from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register

PROTOCOL_VERSION = 1
"""Batteur OSC protocol version. Bump when a message's arguments change meaning."""

NodeId = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.:-]+$")]
Role = Annotated[str, Field(min_length=1, max_length=32, pattern=r"^[a-z][a-z0-9_-]*$")]
Count = Annotated[int, Field(ge=0)]
TOOL_ROLE = "cli"
"""The role command-line tools say Hello as (``batteur ls``, ``batteur rig``'s readiness probe): answered like any
Hello, but not a node of the rig (the graphics view does not list it)."""


@register
class Hello(OscMessage):
    """A node announces itself (sent at start and to newly found peers)."""

    ADDRESS = "/batteur/hello"
    FAMILY = Family.HEALTH

    role: Role = Field(description="service role: physics, interaction, sound, graphics, ...")
    node_id: NodeId = Field(description="unique id of the node process")
    protocol: int = Field(ge=0, description="Batteur OSC protocol version")
    osc_port: int = Field(ge=0, le=65535, description="UDP port the node receives OSC on")


@register
class Health(OscMessage):
    """Health of one node, published at 1 Hz."""

    ADDRESS = "/batteur/health"
    FAMILY = Family.HEALTH

    node_id: NodeId = Field(description="unique id of the node process")
    role: Role = Field(description="service role")
    protocol: int = Field(ge=0, description="Batteur OSC protocol version")
    time: RigTime = Field(description="rig time of this report, seconds")
    rate_hz: float = Field(ge=0, description="loop rate achieved over the last interval, Hz")
    target_rate_hz: float = Field(ge=0, description="configured loop rate, Hz (0: event-driven)")
    overruns: Count = Field(description="loop iterations that overran their period, total")
    messages_in: Count = Field(description="valid messages received, total")
    messages_out: Count = Field(description="messages sent, total")
    dropped: Count = Field(description="messages dropped for any reason, total")
    dropped_malformed: Count = Field(description="dropped: unparseable packets")
    dropped_unknown: Count = Field(description="dropped: unknown address")
    dropped_type: Count = Field(description="dropped: wrong argument count or type")
    dropped_range: Count = Field(description="dropped: value out of range")
    dropped_other: Count = Field(description="dropped: oversize, not allowed, rate limited, handler error, "
                                   "refused by the service (e.g. an unreachable target, a Subscribe to a full "
                                   "table or of a bad pattern)")
    late: Count = Field(description="service-specific late events (e.g. late strikes), total")
    peers: Count = Field(description="peers currently known")
    # appended (readers taking arguments by position, such as Pd patches, find the ones above unmoved)
    decode_unanswered: Count = Field(default=0, description="undecodable controls of this node's service not "
                                     "answered with a refusal: their sender host was over its reply budget "
                                     "(counted in dropped too), total")
    replies_unanswered: Count = Field(default=0, description="refusals the service did not send: their "
                                      "sender host was over its reply budget (physics: refused controls, live "
                                      "score notes too late or of no drum; 0 for the others), total")
    target_lag: float = Field(default=0.0, ge=0, le=1e6, description="physics: how far the drummer's targets "
                              "trail the rig clock after skipped steps, seconds (what was queued before plays that "
                              "late until the hands are still; 0 for the others)")
    target_jumps: Count = Field(default=0, description="physics: times the trailing targets jumped back toward the "
                                "rig clock, total (0 for the others)")

    unroutable: Count = Field(default=0, description="messages not sent for want of a destination: to a role no "
                              "peer of which is known (its node not started, or not found: --peer ROLE=HOST:PORT, or "
                              "discovery's interfaces), or to an address that cannot be resolved or reached, total")

    dropped_wrong_node: Count = Field(default=0, description="dropped: a valid control of another service, which "
                                      "this node does not take (a live note sent to interaction or sound: physics "
                                      "takes it; a sound control sent to interaction), total")

    errors: Count = Field(default=0, description="failures inside the node's service: loop steps that raised, and "
                          "the service's own (sound: strikes that raised, not played, also counted in dropped), "
                          "total; the first of each is logged with its traceback")
    duplicates: Count = Field(default=0, description="redundant copies of impacts and presses dropped (sound: same "
                              "sender, seq and time; 0 for the others), total")
    wrong_node_unanswered: Count = Field(default=0, description="controls of another service not answered with "
                                         "this node's refusal: their sender host was over its reply budget (counted "
                                         "in dropped_wrong_node too), total")
    skipped_steps: Count = Field(default=0, description="physics: simulation steps skipped to follow the rig clock "
                                 "when the node fell behind it (1 ms each at 1 kHz; the drummer then plays late, "
                                 "target_lag), total (0 for the others)")
    discovery: int = Field(default=0, ge=0, le=3, description="zeroconf discovery: 0 off (or an older node, which "
                           "does not say), 1 on, 2 starting (registering, about a second), 3 failed to start (the node "
                           "uses static peers only: it finds no node on another machine; its log says why)")

    APPENDED: ClassVar[tuple[str, ...]] = ("decode_unanswered", "replies_unanswered", "target_lag", "target_jumps",
                                           "unroutable", "dropped_wrong_node", "errors", "duplicates",
                                           "wrong_node_unanswered", "skipped_steps", "discovery")
    """The fields appended after ``peers`` (one argument each), oldest first: a Health without the last of them (an
    older node's) decodes with their defaults."""
    NEWER_ARGS: ClassVar[int] = 16
    """Arguments after the last known field that a newer node's Health may carry (fields appended since): ignored,
    so ``batteur ls``, the rig and graphics still see such a node (a sound node on a second machine updated first)."""


@register
class ClockPing(OscMessage):
    """Asks the rig clock master for the rig time (NTP-like exchange)."""

    ADDRESS = "/batteur/clock/ping"
    FAMILY = Family.CLOCK

    node_id: NodeId = Field(description="id of the asking node (the pong goes back to the sender)")
    seq: int = Field(ge=0, description="sequence number, echoed in the pong")
    t_send: RigTime = Field(description="asker's local clock at send, seconds")


@register
class ClockPong(OscMessage):
    """Answer to a ping: the rig time when the ping arrived and when the pong left."""

    ADDRESS = "/batteur/clock/pong"
    FAMILY = Family.CLOCK

    node_id: NodeId = Field(description="id of the node that asked")
    seq: int = Field(ge=0, description="sequence number of the ping")
    t_send: RigTime = Field(description="asker's local clock at ping send (echoed), seconds")
    t_receive: RigTime = Field(description="rig time when the ping was received, seconds")
    t_reply: RigTime = Field(description="rig time when this pong was sent, seconds")
    # appended (7 Dec): a master restarted at the same address is told from its first pong
    launch: int = Field(default=0, ge=0, le=2**31 - 1, description="the master's launch: a random number it draws at "
                        "start and puts in all its pongs, so a new one (a restart at the same address) is followed "
                        "at its first pong; 0: not given (a master from before 7 Dec)")

    APPENDED: ClassVar[tuple[str, ...]] = ("launch",)
    """The fields appended after ``t_reply``, oldest first: an older master's pong, without them, decodes with their
    defaults."""
    NEWER_ARGS: ClassVar[int] = 8
    """Arguments after the last known field that a newer master's pong may carry (fields appended since): ignored."""


@register
class Subscribe(OscMessage):
    """Ask a node to copy matching messages to the sender (``batteur echo``).

    The node forwards every message it sends or receives whose address matches
    ``pattern`` (OSC address pattern: ``*``, ``?``, ``[...]``, ``{a,b}``) to the
    subscriber's address until ``duration_s`` has passed; renew to keep it.
    """

    ADDRESS = "/batteur/subscribe"
    FAMILY = Family.HEALTH

    pattern: str = Field(min_length=1, max_length=256, pattern=r"^/", description="OSC address pattern")
    duration_s: float = Field(gt=0, le=3600, description="how long to forward, seconds")


@register
class SubscribeRefused(OscMessage):
    """A node did not take a Subscribe, and why (sent back to the subscriber, at most once a second each).

    A node refuses when its subscription table is full, the pattern is not a valid OSC
    address pattern, or the Subscribe's arguments are not what it takes (e.g. a duration of 0;
    ``pattern`` is then ``/`` if the one sent was no pattern); ``batteur echo`` prints the reason
    once per node.
    """

    ADDRESS = "/batteur/subscribe/refused"
    FAMILY = Family.HEALTH

    node_id: NodeId = Field(description="id of the node that refused")
    pattern: str = Field(min_length=1, max_length=256, pattern=r"^/", description="the pattern it was asked for")
    reason: str = Field(max_length=512, description="why, e.g. 'table full (16 subscriptions)' or 'bad pattern ...'")


@register
class ClockStatus(OscMessage):
    """How well a node's rig clock follows the clock master, published at 1 Hz beside its Health.

    Sent by every node whose clock master is another node, to the same peers as its Health.
    ``uncertainty_s`` and ``round_trip_s`` are -1 until the first sample. Every node also sends one after the
    Health it answers a tool's Hello with (``batteur ls``); the clock master's names itself as ``master``.
    """

    ADDRESS = "/batteur/clock/status"
    FAMILY = Family.CLOCK

    node_id: NodeId = Field(description="unique id of the node process")
    synced: int = Field(ge=0, le=1, description="1 once the offset comes from an estimate, 0 before")
    offset_s: float = Field(description="offset added to the node's own clock (master minus local), seconds "
                            "(a 32-bit float: to about 1e-7 of its size)")
    uncertainty_s: float = Field(ge=-1, description="half-width of the interval the true offset lies in, seconds "
                                 "(-1: no estimate yet)")
    round_trip_s: float = Field(ge=-1, description="smallest ping round trip among the samples, seconds "
                                "(-1: no sample yet)")
    samples: Count = Field(description="samples in the estimator's window")
    rejected: Count = Field(description="pongs from the master the estimator refused (stray, stale, implausible "
                            "or outliers), total")
    outliers: Count = Field(description="of rejected: samples that disagreed with the estimate, total")
    steps: Count = Field(description="steps of rig time (over 0.1 s) since the node synced, one per restart of the "
                         "estimate, each logged once as a WARNING ('rig clock stepped back ...'): the clock master "
                         "restarted or was replaced, or its clock moved, total")
    foreign_pongs: Count = Field(description="pongs dropped because they did not come from the master's address, "
                                 "total")
    master: str = Field(max_length=64, pattern=r"^[A-Za-z0-9_.:-]*$",
                        description="node id of the clock master pinged ('' while none is known)")
