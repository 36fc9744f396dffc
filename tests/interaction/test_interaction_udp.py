"""The interaction node over UDP on loopback: registered messages reach a listener; no impact is lost
under 5 % packet loss between interaction and sound (a lossy relay with a fixed seed)."""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing
import random
import select
import socket
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path

from common.dedupe import Deduplicator
from common.messages import Contact, Impact, decode, encode
from common.messages.codec import parse_packet
from common.messages.interaction import ListEnd, MessageAdd, MessageInfo, MessageList
from common.runtime import Node
from services.interaction.config import InteractionConfig, RedundancyConfig, save_config
from services.interaction.core import InteractionCore
from services.interaction.node import InteractionSettings, make_core

INSTRUMENTS = ("snare", "hightom", "midtom", "floortom", "ride", "crash", "hihat", "splash", "china", "cowbell")


class Collector(asyncio.DatagramProtocol):
    """Keeps every datagram it receives."""

    def __init__(self) -> None:
        self.datagrams: list[bytes] = []

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.datagrams.append(data)


IMPACT_PREFIX = b"/batteur/impact\x00"  # the OSC address of /batteur/impact, null-padded


class LossyLink:
    """A lossy relay and the sound side it forwards to, served by a child process of their own.

    The relay drops each impact datagram with probability ``loss`` (seeded); other datagrams (the node's hello
    and health) pass, so they do not shift the random sequence. The sound side keeps every datagram. Both
    sockets are read by a process that shares no interpreter lock with the node under test: in one process
    with it, a busy node starved the readers and the kernel dropped datagrams beyond their 32 MB buffers,
    which the test then took for loss of its own.
    """

    def __init__(self, loss: float, seed: int) -> None:
        self.relay_sock, self.sound_sock = bound_socket(), bound_socket()
        self.port: int = self.relay_sock.getsockname()[1]
        fork = multiprocessing.get_context("fork")
        self._control, child_end = fork.Pipe()
        self._process = fork.Process(
            target=_serve_link, args=(self.relay_sock, self.sound_sock, loss, seed, child_end), daemon=True)

    def start(self) -> None:
        self._process.start()

    def counts(self) -> tuple[int, int, int]:
        """Impact datagrams the relay has seen, those it dropped, and those the sound side received."""
        self._control.send("counts")
        seen, dropped, arrived = self._control.recv()
        return int(seen), int(dropped), int(arrived)

    def datagrams(self) -> list[bytes]:
        """Every datagram the sound side received so far."""
        self._control.send("datagrams")
        return list(self._control.recv())

    def close(self) -> None:
        if self._process.is_alive():
            self._control.send("stop")
            self._process.join(timeout=5)
        if self._process.is_alive():
            self._process.kill()
        self.relay_sock.close()
        self.sound_sock.close()


def _serve_link(relay_sock: socket.socket, sound_sock: socket.socket, loss: float, seed: int,
                control: Connection) -> None:
    """The child process of :class:`LossyLink`: forward, drop, keep, and answer the parent's questions."""
    rng = random.Random(seed)
    target = sound_sock.getsockname()
    seen = dropped = arrived = 0
    kept: list[bytes] = []
    while True:
        readable, _, _ = select.select([relay_sock, sound_sock, control], [], [], 0.05)
        if relay_sock in readable:
            data = relay_sock.recv(65536)
            if data.startswith(IMPACT_PREFIX):
                seen += 1
                if rng.random() < loss:
                    dropped += 1
                    continue
            relay_sock.sendto(data, target)
        if sound_sock in readable:
            data = sound_sock.recv(65536)
            arrived += data.startswith(IMPACT_PREFIX)
            kept.append(data)
        if control in readable:
            what = control.recv()
            if what == "stop":
                return
            control.send((seen, dropped, arrived) if what == "counts" else kept)


def bound_socket() -> socket.socket:
    """A loopback UDP socket with a large receive buffer (the test's receivers share one busy event loop)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_RCVBUFFORCE", 33), 16 * 1024 * 1024)
    except OSError:  # not root: as large as the system allows
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 * 1024 * 1024)
    sock.bind(("127.0.0.1", 0))
    return sock


def contact(t: float, step: int, instrument: str, velocity: float = 2.0) -> Contact:
    return Contact(
        time=t, step=step, instrument=instrument, part="right_stick_tip", x=0.0, y=0.4, z=0.7,
        local_x=0.04, local_y=0.01, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
        normal_velocity=velocity, impulse=0.002, normal_force=400.0,
    )  # fmt: skip


async def start_node(config_path: Path, peers: list[str]) -> Node:
    settings = InteractionSettings(
        role="interaction", discovery=False, peers=peers, clock_master="self", interaction_config=str(config_path)
    )
    core = make_core(settings, argparse.Namespace())
    node = Node(core, settings)
    await node.start()
    return node


async def wait_for(condition: Callable[[], bool], timeout: float) -> bool:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while loop.time() < deadline:
        if condition():
            return True
        await asyncio.sleep(0.01)
    return condition()


def test_a_registered_message_reaches_a_udp_listener(tmp_path: Path) -> None:
    async def scenario() -> None:
        loop = asyncio.get_running_loop()
        listener_transport, listener = await loop.create_datagram_endpoint(Collector, sock=bound_socket())
        client_transport, client = await loop.create_datagram_endpoint(Collector, sock=bound_socket())
        listen_port = listener_transport.get_extra_info("sockname")[1]
        node = await start_node(tmp_path / "interaction.yaml", peers=[])
        try:
            assert node.endpoint is not None
            node_addr = ("127.0.0.1", node.endpoint.port)
            add = MessageAdd(
                name="pd", to=f"127.0.0.1:{listen_port}", address="/pd/hit", instruments="snare", when="onset",
                specs=("instrument", "velocity:linear:0:10:0:127@i", "r"),
            )  # fmt: skip
            client_transport.sendto(encode(add), node_addr)
            client_transport.sendto(encode(MessageList()), node_addr)
            assert await wait_for(lambda: len(client.datagrams) >= 2, 20.0)
            replies = [m for d in client.datagrams for m in decode(d).messages]
            assert isinstance(replies[0], MessageInfo) and replies[0].address == "/pd/hit"
            assert replies[-1] == ListEnd(what="message", count=1)
            t0 = node.clock.now()
            client_transport.sendto(encode(contact(t0, 1, "ride")), node_addr)  # filtered out
            client_transport.sendto(encode(contact(t0 + 0.001, 2, "snare", velocity=5.0)), node_addr)
            assert await wait_for(lambda: len(listener.datagrams) >= 1, 20.0)
            await asyncio.sleep(0.05)
            assert len(listener.datagrams) == 1
            raw = parse_packet(listener.datagrams[0])[0]
            assert raw.address == "/pd/hit"
            assert raw.args[:2] == ["snare", 64] and abs(float(raw.args[2]) - 0.041231 / 0.178) < 1e-3
            assert "/pd/hit" in (tmp_path / "interaction.yaml").read_text()  # persisted
        finally:
            await node.stop()
            listener_transport.close()
            client_transport.close()

    asyncio.run(scenario())


def test_no_impact_is_lost_under_5_percent_packet_loss(tmp_path: Path) -> None:
    total = 10_000

    async def scenario() -> None:
        link = LossyLink(loss=0.05, seed=20261122)
        link.start()
        path = tmp_path / "interaction.yaml"
        config = InteractionConfig(
            redundancy=RedundancyConfig(),  # the defaults: 5 copies, 4 ms apart
            routes=[{"to": "sound", "ends": False}],  # type: ignore[list-item]
        )
        save_config(config, path)
        node = await start_node(path, peers=[f"sound=127.0.0.1:{link.port}"])
        sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            assert node.endpoint is not None
            core = node.core
            assert isinstance(core, InteractionCore)
            node_addr = ("127.0.0.1", node.endpoint.port)
            t0 = node.clock.now()
            for i in range(total):  # one single-step strike per impact, ten tracks taking turns
                sender.sendto(encode(contact(t0 + i * 0.001, i, INSTRUMENTS[i % len(INSTRUMENTS)])), node_addr)
                if i % 20 == 19:
                    await asyncio.sleep(0.004)  # paced: a fast drummer's contact stream, not a flood
            assert await wait_for(lambda: core.segmenter.stats.contacts == total, 60.0), "contacts lost on input"
            assert await wait_for(lambda: len(core.scheduler) == 0, 60.0)
            copies = core.config.redundancy.copies
            assert await wait_for(lambda: link.counts()[0] == copies * total, 60.0), (link.counts(), copies * total)

            def all_arrived() -> bool:
                seen, dropped, arrived = link.counts()
                return arrived == seen - dropped

            assert await wait_for(all_arrived, 60.0), link.counts()
            dedupe = Deduplicator(window=8192)
            seqs = set()
            for data in link.datagrams():
                for message in decode(data).messages:  # impacts, and the node's hello and health
                    if isinstance(message, Impact) and dedupe.accept_message("interaction", message):
                        seqs.add(message.seq)
            seen, dropped, _ = link.counts()
            assert core.impacts_sent == total
            assert 0.04 < dropped / seen < 0.06  # the loss really happened
            assert len(seqs) == total  # ... and no impact was lost
        finally:
            sender.close()
            await node.stop()
            link.close()

    asyncio.run(scenario())


def test_node_command_line_refuses_a_bad_kit_or_configuration(tmp_path: Path, capsys: object) -> None:
    from services.interaction.node import main

    assert main(["--interaction-config", "none", "--show-settings"]) == 0
    assert main(["--kit", "no-such-kit", "--no-discovery", "--interaction-config", "none"]) == 1
    bad = tmp_path / "bad.yaml"
    bad.write_text("redundancy: {copies: 0}\n")
    assert main(["--no-discovery", "--interaction-config", str(bad)]) == 1
