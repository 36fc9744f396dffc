"""The service runtime: fixed-rate loop, node behaviour over loopback, settings, CLI and clean shutdown."""

from __future__ import annotations

import asyncio
import os
import shutil
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any, ClassVar

import pytest

from common.config import NodeSettings, SettingsError, load_settings
from common.core import Outgoing
from common.messages import ClockPing, ClockPong, DropReason, Health, Hello, Impact, OscMessage, encode_raw
from common.peers import Peer, PeerTable
from common.runtime import Node, RateLoop, build_parser, run_node
from common.transport import UdpEndpoint
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)
ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------- fixed-rate loop


class FakeTime:
    """A monotonic clock the loop's sleep and the ticks advance explicitly."""

    def __init__(self, wake_late: float = 0.0) -> None:
        self.t = 0.0
        self.wake_late = wake_late
        self.sleeps = 0

    def __call__(self) -> float:
        return self.t

    async def sleep_until(self, deadline: float) -> None:
        self.sleeps += 1
        if deadline > self.t:
            self.t = deadline + self.wake_late


def test_rate_loop_ticks_on_absolute_deadlines_without_drift() -> None:
    fake = FakeTime(wake_late=0.0003)
    starts: list[float] = []

    def tick() -> None:
        starts.append(fake.t)
        fake.t += 0.0004  # work: 0.4 ms of a 1 ms period

    loop = RateLoop(1000.0, tick, clock=fake, sleep_until=fake.sleep_until)
    asyncio.run(loop.run(max_ticks=1000))
    assert loop.ticks == 1000 and loop.overruns == 0 and loop.skipped == 0
    # every tick starts at its own deadline plus the wake-up lateness: lateness does not accumulate
    assert starts[0] == 0.0
    assert all(abs(s - (k * 0.001 + 0.0003)) < 1e-9 for k, s in enumerate(starts) if k > 0)
    assert fake.t == pytest.approx(0.999 + 0.0003 + 0.0004)


def test_rate_loop_counts_overruns_and_skips_missed_deadlines() -> None:
    fake = FakeTime()
    period = 0.01
    slow_ticks = {10: 1.5 * period, 20: 3.5 * period, 30: 0.99 * period}
    starts: list[float] = []

    def tick() -> None:
        starts.append(fake.t)
        fake.t += slow_ticks.get(len(starts) - 1, 0.1 * period)

    loop = RateLoop(1 / period, tick, clock=fake, sleep_until=fake.sleep_until)
    asyncio.run(loop.run(max_ticks=100))
    assert loop.ticks == 100
    assert loop.overruns == 2  # tick 10 and tick 20 end after the next deadline; tick 30 just fits
    assert loop.skipped == 0 + 2  # tick 10 is half a period late (none skipped); tick 20: 2.5 late (2 skipped)
    # after an overrun the next tick runs at once, then the grid resumes
    assert starts[11] == pytest.approx(10 * period + 1.5 * period)
    assert starts[12] == pytest.approx(12 * period)
    assert starts[21] == pytest.approx(20 * period + 3.5 * period)
    assert starts[22] == pytest.approx(24 * period)
    # the rate holds: 100 ticks took 100 periods plus the 2 skipped ones
    assert fake.t == pytest.approx((100 + 2 - 1) * period + 0.1 * period)


def test_rate_loop_catches_up_short_stalls() -> None:
    fake = FakeTime()
    period = 0.01
    starts: list[float] = []

    def tick() -> None:
        starts.append(fake.t)
        fake.t += 4.5 * period if len(starts) == 6 else 0.1 * period

    loop = RateLoop(1 / period, tick, clock=fake, sleep_until=fake.sleep_until, max_catch_up=2)
    asyncio.run(loop.run(max_ticks=20))
    # tick 5 ends 3.5 periods late: 2 periods are caught up back to back, 1 is skipped
    assert loop.skipped == 1
    assert loop.overruns == 3  # tick 5 and the two catch-up ticks that still end late
    assert starts[6] == pytest.approx(9.5 * period)
    assert starts[7] == pytest.approx(9.6 * period) and starts[8] == pytest.approx(9.7 * period)
    assert starts[9] == pytest.approx(10 * period)  # back on the grid


def test_rate_loop_with_a_real_clock_keeps_its_tick_count() -> None:
    count = 0

    def tick() -> None:
        nonlocal count
        count += 1

    loop = RateLoop(200.0, tick)

    async def main() -> float:
        t0 = time.monotonic()
        await loop.run(max_ticks=40)
        return time.monotonic() - t0

    elapsed = asyncio.run(main())
    assert count == 40
    assert elapsed >= 39 / 200.0  # never faster than the rate (deadlines are absolute)


def test_rate_loop_rejects_a_zero_rate() -> None:
    with pytest.raises(ValueError):
        RateLoop(0.0, lambda: None)


# --------------------------------------------------------------------------- node over loopback


class EchoCore:
    """Counts steps; answers every Impact with a Hello to the sender; raises on Impact seq 13, refuses seq 7."""

    ROLE: ClassVar[str] = "echo"

    def __init__(self, rate_hz: float = 100.0, step_seconds: float = 0.0) -> None:
        self.rate_hz = rate_hz
        self.steps: list[float] = []
        self.handled: list[tuple[OscMessage, float, str]] = []
        self.step_seconds = step_seconds
        self.late = 4
        self.rejected_total = 0
        self.closed = False

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        self.handled.append((message, now, source))
        if isinstance(message, Impact):
            if message.seq == 13:
                raise RuntimeError("unlucky")
            if message.seq == 7:  # a valid message this core cannot use (as physics refuses an unreachable target)
                self.rejected_total += 1
                return []
            if message.seq == 9:  # an answer OSC cannot carry (a float beyond 32 bits), then one it can
                unsendable = impact(9).model_copy(update={"impulse": 1e39})
                return [Outgoing(unsendable, "reply"),
                        Outgoing(Hello(role="echo", node_id="core", protocol=1, osc_port=9), "reply")]
            return [Outgoing(Hello(role="echo", node_id="core", protocol=1, osc_port=message.seq), "reply")]
        return []

    def step(self, now: float) -> list[Outgoing]:
        self.steps.append(now)
        if self.step_seconds:
            time.sleep(self.step_seconds)
        return []

    def close(self) -> None:
        self.closed = True


def impact(seq: int) -> Impact:
    return Impact(seq=seq, time=1.0, instrument="snare", zone="centre", r=0.25, theta=0.0, velocity=2.0,
                  impulse=0.0625, peak_force=10.0, duration=0.00390625, part="stick")




class FakeDiscovery:
    """Records how it was built; on start, 'finds' the peers it was given."""

    instances: ClassVar[list[FakeDiscovery]] = []

    def __init__(self, found: list[Peer], **kwargs: Any) -> None:
        self.kwargs = kwargs
        self.found = found
        self.started = False
        self.stopped = False
        FakeDiscovery.instances.append(self)

    async def start(self) -> None:
        self.started = True
        peers: PeerTable = self.kwargs["peers"]
        for peer in self.found:
            peers.add(peer)

    async def stop(self) -> None:
        self.stopped = True


def test_node_steps_handles_replies_greets_and_publishes_health() -> None:
    async def main() -> None:
        tester = await UdpEndpoint.open()
        got: list[tuple[OscMessage, str]] = []
        tester.set_handler(lambda m, s: got.append((m, s)))
        core = EchoCore(rate_hz=100.0)
        settings = load_settings({"role": "echo", "discovery": False, "clock_master": "self",
                                  "peers": [f"tester={tester.local_address}"]})
        node = Node(core, settings, health_interval_s=0.1)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None and len(core.steps) >= 20)
        assert node.endpoint is not None
        target = node.endpoint.local_address
        # greeted on start (static peer added)
        await wait_for(lambda: any(isinstance(m, Hello) for m, _ in got))
        hello = next(m for m, _ in got if isinstance(m, Hello))
        assert isinstance(hello, Hello) and hello.role == "echo" and hello.osc_port == node.endpoint.port
        # core messages routed back with "reply"
        tester.send(impact(5), target)
        await wait_for(lambda: any(isinstance(m, Hello) and m.osc_port == 5 for m, _ in got))
        # a core that raises is counted as a handler error; the node carries on
        tester.send(impact(13), target)
        tester.send(impact(6), target)
        await wait_for(lambda: any(isinstance(m, Hello) and m.osc_port == 6 for m, _ in got))
        assert node.endpoint.stats.dropped[DropReason.HANDLER_ERROR] == 1
        tester.send(impact(7), target)
        await wait_for(lambda: core.rejected_total == 1)
        # a message the core made that cannot be encoded is counted and not sent; the node sends the rest, runs on
        tester.send(impact(9), target)
        await wait_for(lambda: any(isinstance(m, Hello) and m.osc_port == 9 for m, _ in got))
        assert node.endpoint.send_errors == 1
        # the clock answers pings
        tester.send(ClockPing(node_id="tester", seq=3, t_send=1.5), target)
        await wait_for(lambda: any(isinstance(m, ClockPong) for m, _ in got))
        pong = next(m for m, _ in got if isinstance(m, ClockPong))
        assert isinstance(pong, ClockPong) and pong.seq == 3 and pong.t_send == pytest.approx(1.5)
        assert 0 <= pong.t_receive <= pong.t_reply < 60
        # bad input from the wire is counted and shows in health
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
            raw.sendto(encode_raw("/batteur/hello", ["x", "y"]), ("127.0.0.1", node.endpoint.port))
        await wait_for(lambda: node.endpoint is not None and node.endpoint.stats.dropped_total >= 2)
        # a Hello is answered with the node's Health (the stranger is no peer: it gets no periodic Health)
        stranger = await UdpEndpoint.open()
        answers: list[OscMessage] = []
        stranger.set_handler(lambda m, s: answers.append(m))
        stranger.send(Hello(role="tester", node_id="t", protocol=1, osc_port=stranger.port), target)
        await wait_for(lambda: any(isinstance(m, Health) for m in answers))
        await asyncio.sleep(0.25)
        assert len(answers) == 1
        stranger.close()
        # Health is published periodically to every peer, with the loop's figures
        got.clear()
        await wait_for(lambda: sum(isinstance(m, Health) for m, _ in got) >= 2)
        health = [m for m, _ in got if isinstance(m, Health)][-1]
        assert isinstance(health, Health)
        assert health.role == "echo" and health.target_rate_hz == 100.0
        assert 50.0 < health.rate_hz < 150.0
        # the core's refusal is dropped like the handler's error
        assert health.dropped_type == 1 and health.dropped_other == 2 and health.dropped == 3
        assert health.late == 4 and health.peers == 1
        assert health.messages_in >= 5
        # steps carry increasing rig times
        assert core.steps == sorted(core.steps) and core.steps[0] >= 0
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        assert core.closed and node.endpoint.closed
        tester.close()

    asyncio.run(main())


def test_node_overruns_are_counted_with_a_slow_core() -> None:
    async def main() -> None:
        core = EchoCore(rate_hz=100.0, step_seconds=0.025)  # 25 ms of work per 10 ms period
        settings = load_settings({"role": "echo", "discovery": False, "clock_master": "self"})
        node = Node(core, settings)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: len(core.steps) >= 10)
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        assert node.loop is not None
        assert node.loop.overruns >= node.loop.ticks - 1  # (the last tick may be cancelled before its check)
        assert node.loop.skipped >= node.loop.ticks - 1  # each 25 ms step misses 1-2 deadlines
        assert node.health().overruns == node.loop.overruns

    asyncio.run(main())


def test_discovery_is_injected_started_stopped_and_its_peers_greeted() -> None:
    async def main() -> None:
        tester = await UdpEndpoint.open()
        got: list[OscMessage] = []
        tester.set_handler(lambda m, s: got.append(m))
        FakeDiscovery.instances.clear()
        found = [Peer(role="sound", host="127.0.0.1", port=tester.port, node_id="sound-x")]
        settings = load_settings({"role": "echo", "clock_master": "self", "interfaces": ["127.0.0.1"]})

        def factory(**kwargs: Any) -> FakeDiscovery:
            return FakeDiscovery(found, **kwargs)

        node = Node(EchoCore(rate_hz=0.0), settings, discovery_factory=factory)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: any(isinstance(m, Hello) for m in got))
        fake = FakeDiscovery.instances[0]
        assert fake.started
        assert node.endpoint is not None
        assert fake.kwargs["role"] == "echo" and fake.kwargs["port"] == node.endpoint.port
        assert fake.kwargs["interfaces"] == ["127.0.0.1"] and fake.kwargs["protocol"] >= 1
        assert set(fake.kwargs["browse_roles"]) >= {"physics", "interaction", "sound", "graphics"}
        assert node.loop is None  # event-driven core: no rate loop
        node.request_stop()
        await asyncio.wait_for(task, 3.0)
        assert fake.stopped
        tester.close()

    asyncio.run(main())


class SlowGoodbye(FakeDiscovery):
    """Discovery that takes its time to say goodbye, during which the user presses Ctrl-C again."""

    async def stop(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)
        await asyncio.sleep(0.2)
        self.stopped = True


def test_a_second_ctrl_c_while_the_node_stops_neither_kills_it_nor_skips_closing_its_core() -> None:
    # the signal handlers were removed before stopping: a second Ctrl-C while discovery said goodbye killed the
    # node before its core closed (sound's recording was left unfinished)
    core = EchoCore(rate_hz=0.0)

    async def main() -> None:
        settings = load_settings({"role": "echo", "clock_master": "self", "interfaces": ["127.0.0.1"]})
        node = Node(core, settings, discovery_factory=lambda **kwargs: SlowGoodbye([], **kwargs))
        task = asyncio.ensure_future(node.run(install_signal_handlers=True))
        await wait_for(lambda: node.endpoint is not None and bool(SlowGoodbye.instances))
        node.request_stop()
        await asyncio.wait_for(task, 5.0)
        assert SlowGoodbye.instances[-1].stopped

    asyncio.run(main())
    assert core.closed


def test_node_runs_without_discovery_when_it_is_unavailable() -> None:
    async def main() -> None:
        settings = load_settings({"role": "echo", "clock_master": "self"})
        node = Node(EchoCore(rate_hz=50.0), settings, discovery_factory=lambda **kw: None)  # type: ignore[arg-type,return-value]
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.loop is not None and node.loop.ticks >= 3)
        assert node.discovery is None
        node.request_stop()
        await asyncio.wait_for(task, 3.0)

    asyncio.run(main())


def test_remote_node_estimates_its_offset_to_the_clock_master() -> None:
    async def main() -> None:
        epoch = time.time() - 1000.0
        master_settings = load_settings({"role": "physics", "discovery": False, "epoch": epoch})
        master = Node(EchoCore(rate_hz=0.0), master_settings)
        await master.start()
        assert master.is_clock_master and master.endpoint is not None
        remote_settings = load_settings({"role": "sound", "discovery": False, "epoch": epoch + 10.0,
                                         "peers": [f"physics={master.endpoint.local_address}"]})
        remote = Node(EchoCore(rate_hz=0.0), remote_settings, ping_interval_s=0.05)
        await remote.start()
        assert not remote.is_clock_master and not remote.clock.synced
        await wait_for(lambda: len(remote.estimator.samples) >= 4)
        assert remote.clock.synced
        # the remote's epoch is 10 s later, so its local clock reads 10 s less than the rig clock
        assert remote.clock.offset == pytest.approx(10.0, abs=0.005)
        assert remote.clock.now() == pytest.approx(master.clock.now(), abs=0.005)
        assert remote.estimator.uncertainty < 0.005
        await remote.stop()
        await master.stop()

    asyncio.run(main())


# --------------------------------------------------------------------------- settings


def test_settings_precedence_cli_over_env_over_file_over_defaults(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    for key in list(os.environ):
        if key.startswith("BATTEUR_"):
            monkeypatch.delenv(key)
    yaml_file = tmp_path / "node.yaml"
    yaml_file.write_text("port: 9001\nlatency_s: 0.1\nrate_hz: 500\npeers: [sound=10.0.0.5:9000]\nlog-level: debug\n")
    s = load_settings({}, yaml_file)
    assert (s.port, s.latency_s, s.rate_hz, s.log_level) == (9001, 0.1, 500.0, "DEBUG")
    assert s.static_peers == [Peer(role="sound", host="10.0.0.5", port=9000, node_id="static:sound:10.0.0.5:9000",
                                   static=True)]
    assert s.host == "127.0.0.1" and s.discovery is True and s.interfaces == ["127.0.0.1"]  # defaults
    monkeypatch.setenv("BATTEUR_PORT", "9002")
    monkeypatch.setenv("BATTEUR_PEERS", "sound=127.0.0.1:9100, graphics=[::1]:9200")
    monkeypatch.setenv("BATTEUR_DISCOVERY", "false")
    s = load_settings({}, yaml_file)
    assert (s.port, s.latency_s, s.discovery) == (9002, 0.1, False)
    found = [(p.role, p.host, p.port) for p in s.static_peers]
    assert found == [("sound", "127.0.0.1", 9100), ("graphics", "::1", 9200)]
    s = load_settings({"port": "9003", "latency_s": 0.2}, yaml_file)
    assert (s.port, s.latency_s, s.rate_hz) == (9003, 0.2, 500.0)
    toml_file = tmp_path / "node.toml"
    toml_file.write_text('clock_master = "self"\nport = 7000\nallow = ["10.0.0.0/8"]\n')
    monkeypatch.delenv("BATTEUR_PORT")
    monkeypatch.setenv("BATTEUR_CONFIG", str(toml_file))
    s = load_settings({})
    assert (s.port, s.clock_master, [str(n) for n in s.allow]) == (7000, "self", ["10.0.0.0/8"])


def test_shared_config_file_with_role_sections(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for key in list(os.environ):
        if key.startswith("BATTEUR_"):
            monkeypatch.delenv(key)
    rig = tmp_path / "rig.toml"
    rig.write_text("latency_s = 0.08\nepoch = 1700000000\n[sound]\nport = 9100\n"
                   "[physics]\nport = 9000\nrate_hz = 2000\n")
    sound = load_settings({}, rig, defaults={"role": "sound"})
    physics = load_settings({}, rig, defaults={"role": "physics"})
    assert (sound.port, sound.latency_s, sound.epoch, sound.rate_hz) == (9100, 0.08, 1_700_000_000, None)
    assert (physics.port, physics.latency_s, physics.rate_hz) == (9000, 0.08, 2000.0)


def test_settings_defaults() -> None:
    s = NodeSettings(role="sound")
    assert s.node_id.startswith("sound-") and s.node_id.endswith(str(os.getpid()))
    assert s.host == "127.0.0.1" and s.port == 0 and s.clock_master == "physics" and s.latency_s == 0.05
    assert s.allow_networks is None  # loopback: no allow-list needed
    assert abs(s.epoch - time.time()) < 60


@pytest.mark.parametrize(
    ("values", "needle"),
    [
        ({"port": 70000}, "port"),
        ({"peers": ["sound:9000"]}, "ROLE=HOST:PORT"),
        ({"host": "0.0.0.0"}, "--allow"),
        ({"allow": ["10.0.0.300/8"]}, "is not an IP network"),
        ({"rate_hz": "fast"}, "rate_hz"),
        ({"interfaces": ["eth 0"]}, "neither an IP address nor an interface name"),
        ({"interfaces": ""}, "at least one interface"),
        ({"role": "Sound!"}, "role"),
        ({"log_level": "loud"}, "log_level"),
        ({"bogus": 1}, "bogus"),
    ],
)
def test_bad_settings_give_a_clear_message(values: dict[str, Any], needle: str) -> None:
    with pytest.raises(SettingsError) as info:
        load_settings(values)
    assert needle in str(info.value)
    assert "Traceback" not in str(info.value)


@pytest.mark.parametrize("line", ["port: true", "latency_s: false", "max_rate: yes"])
def test_true_or_false_in_a_config_file_is_no_number_for_any_node(tmp_path: Path, line: str) -> None:
    """pydantic took ``port: true`` as port 1 and ``latency_s: false`` as 0 s; a switch stays a switch."""
    config = tmp_path / "node.yaml"
    config.write_text(line + "\n")
    with pytest.raises(SettingsError, match="a number, not (true|false)"):
        load_settings({}, config)
    config.write_text("discovery: false\n")
    assert load_settings({}, config).discovery is False


def test_bad_config_files(tmp_path: Path) -> None:
    with pytest.raises(SettingsError, match="missing.yaml: no such file$"):  # as every input file (input_file.py)
        load_settings({}, tmp_path / "missing.yaml")
    broken = tmp_path / "broken.toml"
    broken.write_text("port = = 3")
    with pytest.raises(SettingsError, match="broken.toml: not valid TOML: "):
        load_settings({}, broken)
    yaml_file = tmp_path / "broken.yaml"
    yaml_file.write_text("peers: [a\n")
    with pytest.raises(SettingsError, match="not valid YAML: .* at line 2, column 1$"):
        load_settings({}, yaml_file)
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(bytes(range(128, 256)))
    with pytest.raises(SettingsError, match="binary.yaml: not UTF-8 text"):  # was a UnicodeDecodeError
        load_settings({}, binary)
    listing = tmp_path / "list.yaml"
    listing.write_text("- 1\n- 2\n")
    with pytest.raises(SettingsError, match="mapping"):
        load_settings({}, listing)


def test_off_loopback_allows_the_given_networks_and_loopback() -> None:
    s = load_settings({"host": "0.0.0.0", "allow": ["192.168.1.0/24"]})
    assert [str(n) for n in s.allow_networks or []] == ["192.168.1.0/24", "127.0.0.0/8", "::1/128"]


# --------------------------------------------------------------------------- command line


def test_help_lists_every_setting(capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser("sound", "Run the sound service.", lambda p: p.add_argument("--voices", type=int))
    with pytest.raises(SystemExit) as info:
        parser.parse_args(["--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for flag in ("--config", "--role", "--node-id", "--host", "--port", "--peer", "--no-discovery", "--interface",
                 "--rate-hz", "--epoch", "--clock-master", "--latency-s", "--allow", "--max-rate", "--log-level",
                 "--max-datagram", "--voices", "BATTEUR_PORT", "Run the sound service."):
        assert flag in text


def test_run_node_reports_bad_settings_without_a_traceback(capsys: pytest.CaptureFixture[str]) -> None:
    code = run_node("echo", lambda s, a: EchoCore(), ["--port", "99999", "--no-discovery"])
    err = capsys.readouterr().err
    assert code == 2
    assert "port" in err and "65535" in err and "Traceback" not in err


def test_run_node_rejects_an_unknown_interface(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("common.discovery")
    code = run_node("echo", lambda s, a: EchoCore(), ["--interface", "nosuchif0"])
    err = capsys.readouterr().err
    assert code == 2 and "nosuchif0" in err and "Traceback" not in err


def test_run_node_show_settings_and_extra_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    seen: dict[str, Any] = {}

    def make(settings: NodeSettings, args: Any) -> EchoCore:
        seen["voices"] = args.voices
        raise ValueError("voices must be even")

    code = run_node("echo", make, ["--voices", "3", "--no-discovery"],
                    add_arguments=lambda p: p.add_argument("--voices", type=int, default=2))
    assert code == 2 and seen["voices"] == 3
    assert "voices must be even" in capsys.readouterr().err
    code = run_node("echo", make, ["--show-settings", "--peer", "sound=127.0.0.1:9000", "--rate-hz", "250"])
    out = capsys.readouterr().out
    assert code == 0 and '"rate_hz": 250.0' in out and "sound=127.0.0.1:9000" in out and '"role": "echo"' in out


NODE_SCRIPT = textwrap.dedent(
    """
    import sys
    from typing import ClassVar
    from common.runtime import run_node

    class Trivial:
        ROLE: ClassVar[str] = "trivial"
        rate_hz = 200.0

        def handle(self, message, now, source):
            return []

        def step(self, now):
            return []

    if __name__ == "__main__":
        sys.exit(run_node("trivial", lambda settings, args: Trivial(), description="a trivial node"))
    """
)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_node_process_stops_cleanly_on_a_signal(tmp_path: Path, sig: signal.Signals) -> None:
    script = tmp_path / "trivial_node.py"
    script.write_text(NODE_SCRIPT)
    env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.Popen(
        [sys.executable, str(script), "--no-discovery", "--clock-master", "self"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    try:
        assert proc.stderr is not None
        lines = []
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            line = proc.stderr.readline()
            lines.append(line)
            if "listening on" in line and "trivial node" in line or not line:
                break
        assert any("trivial node" in line for line in lines), "".join(lines)
        t0 = time.monotonic()
        proc.send_signal(sig)
        code = proc.wait(timeout=5)
        elapsed = time.monotonic() - t0
        rest = proc.stderr.read()
        assert code == 0, rest
        assert elapsed < 5.0
        assert "stopped" in rest and "Traceback" not in rest
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _can_make_netns() -> bool:
    return sys.platform.startswith("linux") and os.geteuid() == 0 and shutil.which("ip") is not None


@pytest.mark.netns
@pytest.mark.skipif(not _can_make_netns(), reason="needs root and iproute2 (ip netns)")
def test_two_node_processes_find_each_other_and_sync_clocks_in_a_namespace(tmp_path: Path) -> None:
    """Discovery runs only on the loopback of a network namespace made here, never on the host's interfaces."""
    ns = f"bt-runtime-{os.getpid()}"
    subprocess.run(["ip", "netns", "add", ns], check=True)
    procs: list[subprocess.Popen[str]] = []
    try:
        subprocess.run(["ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up"], check=True)
        subprocess.run(["ip", "netns", "exec", ns, "ip", "link", "set", "lo", "multicast", "on"], check=True)
        script = tmp_path / "trivial_node.py"
        script.write_text(NODE_SCRIPT.replace('run_node("trivial"', "run_node(sys.argv.pop(1)"))
        env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
        env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
        logs = [tmp_path / "physics.log", tmp_path / "sound.log"]
        for role, log_path in zip(("physics", "sound"), logs, strict=True):
            procs.append(subprocess.Popen(
                ["ip", "netns", "exec", ns, sys.executable, str(script), role, "--interface", "127.0.0.1"],
                stdout=subprocess.DEVNULL, stderr=log_path.open("w"), text=True, env=env,
            ))
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            sound_log = logs[1].read_text()
            if "rig clock synced to physics" in sound_log and "peer sound" in logs[0].read_text():
                break
            time.sleep(0.1)
        physics_log, sound_log = logs[0].read_text(), logs[1].read_text()
        assert "peer physics" in sound_log and "rig clock synced to physics" in sound_log, sound_log
        assert "peer sound" in physics_log, physics_log
        for proc in procs:
            proc.send_signal(signal.SIGTERM)
        for proc in procs:
            assert proc.wait(timeout=5) == 0
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        subprocess.run(["ip", "netns", "del", ns], check=False)


def test_every_node_pings_the_same_master_and_keeps_it_while_it_is_there() -> None:
    # two records of the master role (a restarted master's lingering one, two rigs on a LAN): nodes took the
    # first in insertion order, so they could differ, and a record flapping switched masters (rig time jumped)
    settings = load_settings({"role": "echo", "discovery": False, "clock_master": "physics"})
    node = Node(EchoCore(rate_hz=0.0), settings)
    b = Peer(role="physics", host="127.0.0.1", port=9201, node_id="physics-b")
    a = Peer(role="physics", host="127.0.0.1", port=9202, node_id="physics-a")
    node.peers.add(b)
    node.peers.add(a)
    master = node.clock_master_peer()
    assert master is not None and master.node_id == "physics-a"  # the same choice on every node
    node._master_id = "physics-b"  # in use: kept while it is known
    chosen = node.clock_master_peer()
    assert chosen is not None and chosen.node_id == "physics-b"
    node.peers.remove("physics-b")
    chosen = node.clock_master_peer()
    assert chosen is not None and chosen.node_id == "physics-a"


def test_a_node_whose_clock_is_not_synced_does_not_answer_clock_pings() -> None:
    # it answered with its own clock: a node pinging it (a restarted master's old port) synced to a wrong time
    async def main() -> tuple[list[OscMessage], list[OscMessage]]:
        answers: dict[str, list[OscMessage]] = {"waiting": [], "master": []}
        nodes = {
            "waiting": Node(EchoCore(rate_hz=0.0), load_settings({"role": "echo", "discovery": False,
                                                                  "clock_master": "physics"}), clock_wait_s=60.0),
            "master": Node(EchoCore(rate_hz=0.0), load_settings({"role": "echo", "discovery": False,
                                                                 "clock_master": "self"})),
        }
        tasks = [asyncio.ensure_future(n.run()) for n in nodes.values()]
        await wait_for(lambda: all(n.endpoint is not None for n in nodes.values()))
        for name, node in nodes.items():
            asker = await UdpEndpoint.open()
            asker.set_handler(lambda m, s, name=name: answers[name].append(m))
            assert node.endpoint is not None
            asker.send(ClockPing(node_id="asker", seq=1, t_send=0.5), node.endpoint.local_address)
            endpoint = node.endpoint
            await wait_for(lambda: endpoint.stats.messages_in >= 1)  # noqa: B023 (awaited here)
            await asyncio.sleep(0.2)
            asker.close()
        waiting = nodes["waiting"].endpoint
        assert waiting is not None and waiting.stats.dropped[DropReason.NOT_ALLOWED] == 1
        for node in nodes.values():
            node.request_stop()
        await asyncio.gather(*tasks)
        return answers["waiting"], answers["master"]

    waiting, master = asyncio.run(main())
    assert waiting == [] and any(isinstance(m, ClockPong) for m in master)
