"""Interaction's OSC control surface as docs/interaction.md describes it: listings a client can add back as
they are, the docs' examples, and controls refused at decoding (no reply, nothing changed)."""

from __future__ import annotations

import argparse
import asyncio
import logging
import re
import socket
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from common.kit import load_kit
from common.messages import DropReason, decode, encode
from common.messages.codec import encode_raw, parse_packet
from common.messages.interaction import (
    InteractionError,
    ListEnd,
    MapInfo,
    MapList,
    MapSet,
    MessageAdd,
    MessageInfo,
    MessageList,
    Redundancy,
    RouteSet,
)
from common.runtime import Node
from services.interaction import node as node_module
from services.interaction.config import InteractionConfig, RedundancyConfig
from services.interaction.core import InteractionCore
from services.interaction.mapping import ArgSpec
from services.interaction.node import InteractionSettings, make_core, report_stats
from services.interaction.synthetic import StreamBuilder, drive, strike

KIT = load_kit("default")
DOC = Path(__file__).resolve().parents[2] / "docs" / "interaction.md"


def test_listed_specs_add_back_to_the_same_mapping() -> None:
    """map/list and message/list answer with the specs as added, to the last digit: a client that saves the
    listing and sends it back (a Pd preset) gets the same mapping, not one rounded to six digits."""
    core = InteractionCore(kit=KIT)
    field_spec = "velocity:linear:0:10:0:0.1234567"
    arg_specs = ("impulse:exp:0:0.0123456789:0:127.5:3.25@i", "r:table:0:1:0.8:0.5:1:1234567", "=0.1234567891")
    assert core.handle(MapSet(to="sound", field="velocity", spec=field_spec), 0.0, "pd") == []
    add = MessageAdd(name="pd", to="127.0.0.1:9999", address="/pd/hit", instruments="*", when="end", specs=arg_specs)
    assert core.handle(add, 0.0, "pd") == []
    maps = [o.message for o in core.handle(MapList(), 0.0, "pd") if isinstance(o.message, MapInfo)]
    listed = {m.field: m.spec for m in maps if m.to == "sound" and m.field}
    assert ArgSpec.parse(listed["velocity"]) == ArgSpec.parse(field_spec)
    infos = [o.message for o in core.handle(MessageList(), 0.0, "pd") if isinstance(o.message, MessageInfo)]
    assert [ArgSpec.parse(s) for s in infos[0].specs] == [ArgSpec.parse(s) for s in arg_specs]
    assert listed["velocity"] == field_spec  # and reads as typed ('10', not '10.0')


def _doc_block(language: str) -> str:
    blocks = re.findall(rf"```{language}\n(.*?)```", DOC.read_text(), flags=re.S)
    assert blocks, f"no {language} block in {DOC}"
    return str(blocks[0])


def test_the_docs_registered_message_example_sends_what_the_docs_say() -> None:
    """The message/add line of docs/interaction.md, as written, then a 5 m/s snare strike: /pd/hit snare 64 centre."""
    line = next(ln for ln in DOC.read_text().splitlines() if ln.startswith("/batteur/interaction/message/add "))
    _, name, to, address, instruments, when, *specs = line.split()
    core = InteractionCore(kit=KIT)
    add = MessageAdd(name=name, to=to, address=address, instruments=instruments, when=when, specs=tuple(specs))  # type: ignore[arg-type]
    assert core.handle(add, 0.0, "pd") == []
    sent = [o for _, o in drive(core, strike(StreamBuilder(KIT, "snare"), t=1.0, velocity=5.0).contacts)]
    raws = [parse_packet(encode(o.message))[0] for o in sent if o.to == to]
    assert [(r.address, r.args) for r in raws] == [("/pd/hit", ["snare", 64, "centre"])]


def test_the_docs_configuration_file_example_is_a_valid_configuration() -> None:
    config = InteractionConfig.model_validate(yaml.safe_load(_doc_block("yaml")))
    core = InteractionCore(kit=KIT, config=config)
    assert core.unplayable_instruments() == []
    assert [r.to for r in config.routes] == ["sound", "graphics"] and config.messages[0].address == "/pd/hit"


def _bound_socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    return sock


class _Collector(asyncio.DatagramProtocol):
    def __init__(self) -> None:
        self.messages: list[object] = []

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.messages.extend(decode(data).messages)


async def _wait_for(condition: Callable[[], bool], timeout: float) -> bool:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while loop.time() < deadline and not condition():
        await asyncio.sleep(0.01)
    return condition()


def test_a_control_its_model_refuses_is_dropped_at_decoding_and_its_sender_told(tmp_path: Path) -> None:
    """docs/interaction.md: values outside a message's declared ranges (copies 0, impact_at 'soon') never reach
    the core: nothing changed, counted by the node, the sender told why (by the node's transport); the next valid
    control is answered."""

    async def scenario() -> None:
        settings = InteractionSettings(role="interaction", discovery=False, clock_master="self",
                                       interaction_config=str(tmp_path / "interaction.yaml"))
        core = make_core(settings, argparse.Namespace())
        node = Node(core, settings)
        await node.start()
        loop = asyncio.get_running_loop()
        transport, client = await loop.create_datagram_endpoint(_Collector, sock=_bound_socket())
        try:
            assert node.endpoint is not None
            to = ("127.0.0.1", node.endpoint.port)
            before = core.config.redundancy
            transport.sendto(encode_raw(Redundancy.ADDRESS, [0, 0.004]), to)
            transport.sendto(encode_raw("/batteur/interaction/impact_at", ["soon"]), to)
            transport.sendto(encode(MapList()), to)
            assert await _wait_for(lambda: any(isinstance(m, ListEnd) for m in client.messages), 20.0)
            errors = [m for m in client.messages if isinstance(m, InteractionError)]
            assert [e.request for e in errors] == [Redundancy.ADDRESS, "/batteur/interaction/impact_at"]
            assert all("out_of_range" in e.detail for e in errors)
            assert core.config.redundancy == before and core.config.impact_at == "onset"
            assert core.control_errors == 0
            assert node.endpoint.stats.dropped[DropReason.OUT_OF_RANGE] == 2  # in Health's dropped_range
            transport.sendto(encode(Redundancy(copies=2, spacing=0.00390625)), to)  # exact in float32
            wanted = RedundancyConfig(copies=2, spacing=0.00390625)
            assert await _wait_for(lambda: core.config.redundancy == wanted, 20.0)
        finally:
            transport.close()
            await node.stop()

    asyncio.run(scenario())


def test_reply_is_not_a_target_for_routes_or_registered_messages() -> None:
    """'reply' means "the sender of the message being handled" to the node: a route or registered message to it
    would send impacts back to physics, not to the client who set it up. Refused with a reason."""
    core = InteractionCore(kit=KIT)
    before = core.config
    add = MessageAdd(name="me", to="reply", address="/me/hit", instruments="*", when="onset", specs=("velocity",))
    for control in (RouteSet(to="reply", instruments="*"), MapSet(to="reply", field="velocity", spec="velocity"), add):
        out = core.handle(control, 0.0, "127.0.0.1:9000")
        assert len(out) == 1 and isinstance(out[0].message, InteractionError), control
        assert "host:port" in out[0].message.detail
    assert core.config == before
    sent = [o for _, o in drive(core, strike(StreamBuilder(KIT, "snare"), t=1.0).contacts)]
    assert sent and all(o.to in ("sound", "graphics") for o in sent)


def test_the_docs_pure_data_example_builds_the_control_it_names() -> None:
    """The Pd line of docs/interaction.md, read the way Pd's [oscformat] reads it (the address from its creation
    arguments, the incoming list as the arguments; checked against Pd 0.5x), maps the sound route's velocity."""
    text = " ".join(DOC.read_text().split())
    match = re.search(r"From Pure Data: `\[list ([^(]*)\(` -> `\[oscformat([^\]]*)\]` -> `\[netsend -u -b\]`", text)
    assert match, "the Pure Data example of docs/interaction.md"
    args, path = match.group(1).split(), match.group(2).split()
    message = decode(encode_raw("/" + "/".join(path), args)).messages[0]
    assert isinstance(message, MapSet)
    core = InteractionCore(kit=KIT)
    assert core.handle(message, 0.0, "pd") == []
    sound = next(r for r in core.config.routes if r.to == "sound")
    assert sound.fields["velocity"] == ArgSpec.parse("velocity:exp:0:10:0:5:3")


def test_the_node_logs_its_counters_only_while_impacts_come(monkeypatch: pytest.MonkeyPatch,
                                                            caplog: pytest.LogCaptureFixture) -> None:
    """docs/interaction.md: the counters are logged every 30 s while impacts come; an idle node says nothing."""
    core = InteractionCore(kit=KIT)
    node = SimpleNamespace(core=core, clock=SimpleNamespace(now=lambda: 0.0))
    one_strike = strike(StreamBuilder(KIT, "snare"), t=1.0).contacts
    periods = iter([lambda: None, lambda: None, lambda: drive(core, one_strike), lambda: None])

    async def next_period(seconds: float) -> None:  # each "30 s" runs the next step of the scenario
        try:
            next(periods)()
        except StopIteration:
            raise asyncio.CancelledError from None

    monkeypatch.setattr(node_module.asyncio, "sleep", next_period)
    caplog.set_level(logging.INFO, logger="batteur.interaction")
    with pytest.raises(asyncio.CancelledError):
        asyncio.run(report_stats(node))  # type: ignore[arg-type]
    lines = [r.getMessage() for r in caplog.records if r.name == "batteur.interaction"]
    assert len(lines) == 1 and lines[0].startswith("4 contacts, 1 impacts")
