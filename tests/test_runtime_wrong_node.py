"""A node drops a valid control of another service (a live note sent to interaction or sound: physics takes it; a
sound control sent to interaction), counted by reason in its Health (``dropped_wrong_node``, in ``dropped`` too),
with a rated warning naming the role that takes it. Before, the node handed it to its core, which ignored it:
``messages_in`` grew, no drop was counted, nothing answered, and the musician's note was lost in silence.

What every node receives and ignores on purpose is no drop: Health, Hello and clock status (broadcast to every
peer), impacts, dampings and poses (forwarded to graphics, copied by routes), answers to a node's own requests
(physics refusing graphics' posture, interaction's listings), the recogniser's hits; nor is a node's own control,
nor anything a core of no service's role (a test's, a wrapper's) is sent.

Nodes run in-process on loopback (no discovery, no OSCQuery); a Hello after the messages is answered with the
Health, so the counts are read once every message before it was handled (one sender's datagrams, in order).
"""

from __future__ import annotations

import asyncio
import json
import logging

import pytest

from batteur.tools import ls
from common.config import load_settings
from common.messages import ClockStatus, Health, Hello, Impact, OscMessage, Pose, Skeleton, decode, encode
from common.messages.graphics import GraphicsLatency, ScorePosition
from common.messages.interaction import Damping, InteractionError, ListEnd, MapInfo, RouteSet
from common.messages.physics import CartesianTarget, PhysicsRejected
from common.messages.recogniser import DrumHit
from common.messages.score import LiveNote, TempoScale
from common.messages.sound import SoundMaster, SoundRejected
from common.runtime import Node
from common.transport import UdpEndpoint
from services.interaction.core import InteractionCore
from tests.health_answerer import HealthAnswerer
from tests.recording_core import RecordingCore
from tests.test_health_unanswered import health_after
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

NOTE = LiveNote(time=5.25, pitch=38, velocity=100, channel=10)
MASTER = SoundMaster(gain_db=-6.0, reverb=0.2)
TARGET = CartesianTarget(limb="right_hand", time=1.0, x=0.1, y=0.3, z=0.9, vx=0.0, vy=0.0, vz=0.0)
ROUTE = RouteSet(to="127.0.0.1:57120", instruments="*")
LATENCY = GraphicsLatency(seconds=0.1)
IMPACT = Impact(seq=1, time=1.0, instrument="snare", zone="centre", r=0.25, theta=0.0, velocity=2.0,
                impulse=0.0625, peak_force=10.0, duration=0.00390625, part="stick")
HEALTH = Health(node_id="sound-1", role="sound", protocol=1, time=1.5, rate_hz=0.0, target_rate_hz=0.0, overruns=0,
                messages_in=0, messages_out=0, dropped=0, dropped_malformed=0, dropped_unknown=0, dropped_type=0,
                dropped_range=0, dropped_other=0, late=0, peers=2)
STATUS = ClockStatus(node_id="sound-1", synced=1, offset_s=0.001, uncertainty_s=0.0001, round_trip_s=0.0002,
                     samples=8, rejected=0, outliers=0, steps=0, foreign_pongs=0, master="physics-1")


def wire(message: OscMessage) -> OscMessage:
    """``message`` as a node decodes it (its floats made 32-bit)."""
    return decode(encode(message)).messages[0]


def run(core: object, role: str, messages: list[OscMessage]) -> Health:
    health, _ = asyncio.run(health_after(core, role, messages))  # type: ignore[arg-type]
    return health


@pytest.mark.parametrize(("role", "message", "owner"), [
    ("interaction", NOTE, "physics"),  # the walkthrough's note, sent to interaction's port
    ("sound", NOTE, "physics"),
    ("graphics", TempoScale(factor=1.5), "physics"),
    ("interaction", MASTER, "sound"),  # the walkthrough's sound control, sent to interaction's port
    ("physics", MASTER, "sound"),
    ("sound", TARGET, "physics"),
    ("sound", ROUTE, "interaction"),
    ("physics", LATENCY, "graphics"),
])
def test_a_control_of_another_service_is_a_counted_drop_naming_its_role(
        role: str, message: OscMessage, owner: str, caplog: pytest.LogCaptureFixture) -> None:
    core = RecordingCore(role)
    with caplog.at_level(logging.WARNING, logger="batteur.traffic"):
        health = run(core, role, [message, message])
    assert health.dropped_wrong_node == 2 and health.dropped == 2
    assert (health.dropped_unknown, health.dropped_type, health.dropped_other) == (0, 0, 0)
    assert health.messages_in >= 2  # it decoded: a valid message, dropped for where it was sent
    assert not any(type(m) is type(message) for m in core.handled)  # never handed to a core that ignores it
    lines = [r.getMessage() for r in caplog.records if "wrong_node" in r.getMessage()]
    assert len(lines) == 1, lines  # rated: the second within the interval only counted
    assert message.ADDRESS in lines[0] and f"a control of {owner}" in lines[0] and f"this {role} node" in lines[0]


@pytest.mark.parametrize(("role", "message"), [
    ("physics", NOTE),  # each service's own controls
    ("sound", MASTER),
    ("interaction", ROUTE),
    ("graphics", LATENCY),
    ("sound", HEALTH),  # broadcast to every peer
    ("interaction", Hello(role="sound", node_id="sound-1", protocol=1, osc_port=9103)),
    ("graphics", STATUS),
    ("graphics", IMPACT),  # impacts forwarded to graphics, or copied to any node by a route
    ("physics", IMPACT),
    ("interaction", Damping(seq=1, time=1.0, instrument="snare", part="stick", state=1, zone="centre", r=0.1,
                            theta=0.0, force=1.0)),
    ("sound", Pose(time=1.0, layout=1, values=(0.0,) * 7)),
    ("sound", Skeleton(layout=1, names=("hips",))),
    ("sound", ScorePosition(time=1.0, bar=1, beat=1.0, tempo_bpm=120.0)),
    ("graphics", PhysicsRejected(address="/batteur/physics/posture", reason="unreachable")),  # answers to it
    ("physics", SoundRejected(address="/batteur/sound/level", instrument="snare", reason="no")),
    ("sound", InteractionError(request="/batteur/interaction/route/set", detail="no")),
    ("graphics", MapInfo(to="sound", instruments="*", field="", spec="")),
    ("graphics", ListEnd(what="map", count=1)),
    ("physics", DrumHit(seq=1, time=1.0, note=38, event_type="SNARE", velocity=100, confidence=0.9)),
])
def test_what_a_node_takes_or_ignores_on_purpose_is_no_drop(role: str, message: OscMessage) -> None:
    core = RecordingCore(role)
    health = run(core, role, [message])
    assert health.dropped_wrong_node == 0 and health.dropped == 0
    assert wire(message) in core.handled  # its core decides what to do with it


@pytest.mark.parametrize("message", [NOTE, MASTER, ROUTE])
def test_a_core_of_no_service_role_is_handed_every_control(message: OscMessage) -> None:
    core = RecordingCore("echo")  # a test's or a wrapper's core: what it takes is its own business
    health = run(core, "echo", [message])
    assert health.dropped == 0 and wire(message) in core.handled


def test_the_interaction_node_drops_a_live_note_and_takes_its_own_route() -> None:
    """The walkthrough: a note and a sound control sent to the interaction node, then a route, to the real core."""
    core = InteractionCore()
    health = run(core, "interaction", [NOTE, MASTER, ROUTE])
    assert (health.dropped_wrong_node, health.dropped) == (2, 2)
    assert [r.to for r in core.config.routes][-1] == ROUTE.to  # its own control: taken


def test_a_wrong_node_control_is_dropped_while_the_core_waits_for_the_clock() -> None:
    """A node waiting for its clock master holds messages for its core: a wrong node's control is not held."""
    async def main() -> tuple[Health, RecordingCore]:
        core = RecordingCore("sound")
        node = Node(core, load_settings({"role": "sound", "discovery": False, "clock_master": "physics",  # type: ignore[arg-type]
                                         "oscquery": False}), clock_wait_s=30.0)
        await node.start()
        assert node.endpoint is not None and not node.core_started
        client = await UdpEndpoint.open("127.0.0.1")
        try:
            client.send(NOTE, node.endpoint.local_address)
            client.send(MASTER, node.endpoint.local_address)
            await wait_for(lambda: node.endpoint is not None and node.endpoint.stats.messages_in >= 2)
            health = node.health()
            node.start_core("test")
            return health, core
        finally:
            client.close()
            await node.stop()

    health, core = asyncio.run(main())
    assert health.dropped_wrong_node == 1 and core.handled == [wire(MASTER)]


def test_health_appends_the_count_and_an_older_nodes_health_decodes() -> None:
    """Appended last: a reader taking Health's arguments by position (a Pd patch) finds the others unmoved, and a
    Health without it (an older node's) decodes with 0."""
    names = [f.name for f in Health.wire_fields()]
    since = len(names) - names.index("dropped_wrong_node")  # it and the fields appended after it (errors, ...)
    assert Health.APPENDED[-since:] == tuple(names[-since:])
    health = HEALTH.model_copy(update={"dropped_wrong_node": 3, "dropped": 3})
    args = health.to_args()
    assert args[-since] == 3 and Health.from_args(args) == health
    assert decode(encode(health)).messages == [health]
    older = Health.from_args(args[:-since])
    assert older.dropped_wrong_node == 0 and older.model_copy(update={"dropped_wrong_node": 3}) == health


def test_ls_json_shows_the_wrong_node_drops(capsys: pytest.CaptureFixture[str]) -> None:
    node = HealthAnswerer(encode(HEALTH.model_copy(update={"dropped": 4, "dropped_wrong_node": 4})))
    try:
        assert ls.main(["--node", f"127.0.0.1:{node.port}", "--timeout", "3", "--json"]) == 0
    finally:
        node.close()
    row = json.loads(capsys.readouterr().out)[0]
    assert (row["dropped"], row["dropped_wrong_node"]) == (4, 4)
    with pytest.raises(SystemExit):
        ls.main(["--help"])
    assert "dropped_wrong_node" in capsys.readouterr().out
