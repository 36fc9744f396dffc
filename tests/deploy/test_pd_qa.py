"""Pure Data patches under abuse: malformed and hostile OSC, close strikes, full velocity; the generators' CLIs."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import soundfile as sf

from common.messages import Impact, WireKind, encode, encode_raw
from tests.deploy.pdrun import PD_DIR, PdProcess, physics_and_sound_nodes, require_pd
from tests.ports import free_port

pytestmark = pytest.mark.timeout(120)


def _impact(t: float, instrument: str, velocity: float = 3.0, seq: int = 1) -> bytes:
    return encode(Impact(seq=seq, time=t, instrument=instrument, zone="centre", r=0.2, theta=0.0, velocity=velocity,
                         impulse=0.0, peak_force=0.0, duration=0.0, part="right_stick_tip"))


def _raw_impact(seconds: Any, fraction: Any, instrument: Any, velocity: Any) -> bytes:
    """An impact with any values in the fields the Pd client reads (bypasses the model's validation)."""
    return encode_raw("/batteur/impact", [7, seconds, fraction, instrument, "centre", 0.2, 0.0, velocity, 0.0, 0.0,
                                          0.0, "right_stick_tip"])


class Client:
    """The Pd sound client on a loopback port, with a socket to send it OSC."""

    def __init__(self, pd: PdProcess, port: int) -> None:
        self.pd = pd
        self.port = port
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._mark = 900.0

    def send(self, data: bytes, port: int | None = None) -> None:
        self.sock.sendto(data, ("127.0.0.1", port or self.port))

    def sync(self, port: int | None = None) -> None:
        """Wait until the client has handled everything sent so far (it plays a marker impact, in order)."""
        self._mark += 1.0
        mark = self._mark
        self.send(_impact(mark, "cowbell", velocity=0.0), port)
        self.pd.wait_for(lambda _: any(p[0] == "cowbell" and float(p[1]) == mark for p in self.played()))

    def played(self) -> list[list[str]]:
        return self.pd.printed("batteur-impact")

    def strikes(self) -> list[tuple[str, float]]:
        """What the voices played, without the sync markers: (instrument, rig time)."""
        return [(p[0], float(p[1]) + float(p[2])) for p in self.played() if p[0] != "cowbell"]

    def bad(self) -> list[list[str]]:
        return self.pd.printed("batteur-bad")


@contextmanager
def sound_client(tmp_path: Path) -> Iterator[Client]:
    port = free_port()
    takes = tmp_path / "takes"
    takes.mkdir()
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=[f"sc-dir symbol {takes}", f"sc-port {port}"])
    client = Client(pd, port)
    try:
        pd.wait_for(lambda lines: any(f"listen {port}" in line for line in lines))
        yield client
    finally:
        client.sock.close()
        pd.stop()


def _take(path: Path) -> np.ndarray:
    audio, rate = sf.read(path)
    assert rate > 0 and len(audio) > 0
    return np.asarray(audio)


# ---------------------------------------------------------------- the sound client


def test_close_strikes_with_interleaved_copies_play_once_each(tmp_path: Path) -> None:
    """A roll of strikes 10 ms apart, each sent 5 times 4 ms apart (interaction's default redundancy): the copies
    of one strike arrive after the next strike's first copy, and each strike must still play exactly once."""
    require_pd()
    strikes = [5.0 + 0.01 * k for k in range(8)]
    schedule = sorted((t + 0.004 * copy, k, t) for k, t in enumerate(strikes) for copy in range(5))
    with sound_client(tmp_path) as client:
        for _, k, t in schedule:
            client.send(_impact(t, "snare", seq=k))
        client.sync()
        played = client.strikes()
        assert [name for name, _ in played] == ["snare"] * len(strikes), played
        assert [t for _, t in played] == pytest.approx(strikes, abs=1e-5)
        assert client.pd.errors() == [], "\n".join(client.pd.lines)


def test_distinct_impacts_at_the_same_rig_time_both_play(tmp_path: Path) -> None:
    """Copies share the sequence number as well as the rig time: two impacts with the same rig time but their own
    numbers (two sticks in one physics step; a test script looping a pattern) are two strikes."""
    require_pd()
    with sound_client(tmp_path) as client:
        for seq in (10, 10, 11, 11, 10):
            client.send(_impact(4.0, "floortom", seq=seq))
        for _ in range(2):  # a script sending the same pattern twice, numbering its impacts
            for t in (5.0, 5.5):
                client.send(_impact(t, "hihat", seq=int(t * 10) + 100 * _))
                client.send(_impact(t, "hihat", seq=int(t * 10) + 100 * _))
        client.sync()
        assert client.strikes() == [("floortom", 4.0)] * 2 + [("hihat", 5.0), ("hihat", 5.5)] * 2
        assert client.pd.errors() == [], "\n".join(client.pd.lines)


BAD_IMPACTS: list[tuple[bytes, str]] = [
    (encode_raw("/batteur/impact", [7, 10, 0.0]), "has 3 arguments (12 to 21 expected)"),
    (encode_raw("/batteur/impact", []), "has 0 arguments (12 to 21 expected)"),
    (_raw_impact(11, 0.0, "snare", -3.0), "velocity -3 is not in 0..100"),
    (_raw_impact(12, 0.0, "snare", 1000.0), "velocity 1000 is not in 0..100"),
    (_raw_impact(13, 0.0, "snare", "loud"), "velocity loud is not in 0..100"),
    (_raw_impact(14, 0.0, 5, 3.0), "instrument 5 is not a name"),
    (_raw_impact(15, 1.5, "snare", 3.0), "time fraction 1.5 is not in 0..1"),
    (_raw_impact("noon", 0.0, "snare", 3.0), "time seconds noon is not a whole number"),
    (_raw_impact(16.5, 0.0, "snare", 3.0), "time seconds 16.5 is not a whole number"),
    (encode_raw("/batteur/impact/set", ["x"]), "/batteur/impact has 2 arguments"),
    (encode_raw("/batteur/impact", [7, 17, 0.0, "snare", "centre", 0.2, 0.0, 3.0, 0.0, 0.0, 0.0, "right_stick_tip",
                                    *[0.0] * 10]), "has 22 arguments (12 to 21 expected)"),
]


def test_impacts_from_older_and_newer_senders_play(tmp_path: Path) -> None:
    """An impact from interaction carries 13 arguments since 8 Dec (the hi-hat's ``openness`` appended): the client
    plays it, as it plays a 12-argument one ([batteur-strike], an older interaction) and a newer sender's with
    fields appended since (before: every 13-argument impact was refused as malformed, nothing played)."""
    require_pd()
    with sound_client(tmp_path) as client:
        older = _raw_impact(1, 0.0, "snare", 3.0)
        now = encode(Impact(seq=8, time=2.0, instrument="hihat", zone="half", r=0.6, theta=0.0, velocity=3.0,
                            impulse=0.0, peak_force=0.0, duration=0.0, part="right_stick_tip", openness=0.7))
        newer = encode_raw("/batteur/impact", [9, 3, 0.0, "kick", "centre", 0.2, 0.0, 3.0, 0.0, 0.0, 0.0,
                                               "kick_beater", 0.5, 1, "x"])
        for data in (older, now, newer):
            client.send(data)
        client.sync()
        assert client.strikes() == [("snare", 1.0), ("hihat", 2.0), ("kick", 3.0)], client.pd.lines
        assert client.bad() == [] and client.pd.errors() == [], "\n".join(client.pd.lines)


def test_malformed_impacts_are_refused_counted_and_the_client_keeps_playing(tmp_path: Path) -> None:
    require_pd()
    with sound_client(tmp_path) as client:
        client.send(encode_raw("/pd/record", [1]))
        client.pd.wait_for(lambda _: bool(client.pd.printed("batteur-record")))
        client.send(_impact(1.0, "snare"))
        for data, _ in BAD_IMPACTS:
            client.send(data)
            client.send(_impact(2.0, "kick"))  # the same good strike again and again: played once
        # Pd itself turns a non-finite float into 0 before the patch sees it: a silent strike, never garbage
        client.send(_raw_impact(20, 0.0, "splash", float("nan")))
        client.send(_raw_impact(21, 0.0, "splash", float("inf")))
        client.send(_impact(3.0, "ride"))
        client.sync()
        client.send(encode_raw("/pd/stop", []))
        client.pd.wait_for(lambda _: bool(client.pd.printed("batteur-stop")))
        assert client.strikes() == [("snare", 1.0), ("kick", 2.0), ("splash", 20.0), ("splash", 21.0),
                                    ("ride", 3.0)], client.pd.lines
        assert [p[3] for p in client.played() if p[0] == "splash"] == ["0", "0"]
        bad = client.bad()
        assert [int(b[0]) for b in bad] == list(range(1, len(BAD_IMPACTS) + 1)), bad  # a running count
        for (_, reason), printed in zip(BAD_IMPACTS, bad, strict=True):
            assert printed[1] == "/batteur/impact" and reason in " ".join(printed[1:]), printed
        assert client.pd.errors() == [], "\n".join(client.pd.lines)
    audio = _take(tmp_path / "takes" / "take-1.wav")
    assert np.all(np.isfinite(audio)) and np.max(np.abs(audio)) < 0.99  # nothing wild played at full level


def _bundle(*messages: bytes) -> bytes:
    """An OSC bundle (timetag 1: at once) holding ``messages``."""
    return b"#bundle\0" + b"\0" * 7 + b"\1" + b"".join(len(m).to_bytes(4, "big") + m for m in messages)


NOT_OSC: list[tuple[bytes, str]] = [
    (b"snare 1 2;\n", "datagram of 11 bytes is not OSC: its first byte 115 is not a slash"),
    (b"\n", "datagram of 1 bytes is not OSC: its first byte 10 is not a slash"),
    (b"\xff" * 3000, "datagram of 3000 bytes is not OSC: its first byte 255 is not a slash"),
    (b"/batteur/impact\0,f\0\0", "datagram of 20 bytes is not an OSC message Pd can read"),  # cut short
    (b"/", "datagram of 1 bytes is not an OSC message Pd can read"),
    (b"#bundle\0\0", "datagram of 9 bytes is not an OSC message Pd can read"),
    (b"#bundleX" + b"\0" * 8, "datagram of 16 bytes is not an OSC message Pd can read"),  # Pd says nothing
]


def test_datagrams_that_are_not_osc_are_refused_counted_and_the_client_keeps_playing(tmp_path: Path) -> None:
    """Packet-level garbage (text, binary, an OSC message cut short, a broken bundle) reaches no voice: Pd's
    [oscparse] prints its own error and gives nothing; the client counts each as ``batteur-bad`` with its size
    and why, in the same running count as a malformed impact, and plays on. A valid bundle plays what it holds;
    an empty bundle is valid OSC with nothing in it, not counted."""
    require_pd()
    with sound_client(tmp_path) as client:
        client.send(encode_raw("/batteur/impact", [7]))  # a malformed impact first: the counts run on from it
        for k, (data, _) in enumerate(NOT_OSC):
            client.send(data)
            client.send(_impact(1.0 + k, "snare"))
        client.send(_bundle())
        client.send(_bundle(_impact(10.0, "kick"), _impact(11.0, "ride")))
        client.sync()
        assert client.strikes() == [("snare", 1.0 + k) for k in range(len(NOT_OSC))] + [("kick", 10.0),
                                                                                         ("ride", 11.0)]
        bad = client.bad()
        assert [int(b[0]) for b in bad] == list(range(1, len(NOT_OSC) + 2)), bad
        assert bad[0][1] == "/batteur/impact"
        for (_, reason), printed in zip(NOT_OSC, bad[1:], strict=True):
            assert " ".join(printed[1:]).startswith(reason), printed
        # Pd's own errors, and no other
        assert client.pd.errors() and all("oscparse" in e for e in client.pd.errors()), client.pd.errors()


def test_bad_port_messages_leave_the_client_listening(tmp_path: Path) -> None:
    """/pd/port with no number, 0, 70000, 9103.5 or a word must not move (or close) the client's socket."""
    require_pd()
    with sound_client(tmp_path) as client:
        for args in ([0], [70000], [9103.5], ["x"], [], [9200, 1]):
            client.send(encode_raw("/pd/port", args))
        client.send(_impact(1.0, "snare"))
        client.sync()
        assert client.strikes() == [("snare", 1.0)]
        assert len(client.bad()) == 6 and all("port" in " ".join(b) for b in client.bad()), client.bad()
        # a good one still moves it
        new = free_port()
        client.send(encode_raw("/pd/port", [new]))
        client.pd.wait_for(lambda lines: any(f"listen {new}" in line for line in lines))
        client.send(_impact(2.0, "kick"), new)
        client.sync(new)
        assert client.strikes() == [("snare", 1.0), ("kick", 2.0)]
        assert client.pd.errors() == [], "\n".join(client.pd.lines)


def test_take_names_and_the_stop_command_cannot_be_changed_from_the_network(tmp_path: Path) -> None:
    """Pd messages tucked into OSC (``set``) must not rename takes outside the take folder or disable /pd/stop;
    a /pd/record without a number must not end the take being recorded."""
    require_pd()
    with sound_client(tmp_path) as client:
        client.send(encode_raw("/pd/record", ["set", "../evil-%d.wav"]))
        client.send(encode_raw("/pd/stop/set", []))  # taken as /pd/stop (nothing is being recorded)
        client.pd.wait_for(lambda _: len(client.pd.printed("batteur-stop")) == 1)
        client.send(encode_raw("/pd/record", [1]))
        client.pd.wait_for(lambda _: bool(client.pd.printed("batteur-record")))
        client.send(encode_raw("/pd/record", []))  # no number: refused, take-1 goes on
        client.send(encode_raw("/pd/record", [-2]))
        client.send(_impact(1.0, "snare"))
        client.sync()
        client.send(encode_raw("/pd/stop", []))  # still a stop
        client.pd.wait_for(lambda _: len(client.pd.printed("batteur-stop")) == 2)
        assert client.pd.printed("batteur-record") == [["take-1.wav", str(tmp_path / "takes")]]
        assert len(client.bad()) == 3 and all("take" in " ".join(b) for b in client.bad()), client.bad()
        assert client.pd.errors() == [], "\n".join(client.pd.lines)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["takes"]
    assert sorted(p.name for p in (tmp_path / "takes").iterdir()) == ["take-1.wav"]
    assert np.max(np.abs(_take(tmp_path / "takes" / "take-1.wav"))) > 0.05  # the snare is in take-1


def test_full_velocity_strikes_do_not_clip(tmp_path: Path) -> None:
    """The loudest strike the protocol allows (100 m/s) on the noisiest voice, then five instruments struck at once
    at that velocity, stay below full scale: a take never holds hard-clipped samples."""
    require_pd()
    with sound_client(tmp_path) as client:
        client.send(encode_raw("/pd/record", [1]))
        client.pd.wait_for(lambda _: bool(client.pd.printed("batteur-record")))
        client.send(_impact(10.0, "snare", velocity=100.0))
        time.sleep(0.4)  # in the take only: the snare alone, then the crowd
        for name in ("kick", "snare", "hihat", "crash", "china"):
            client.send(_impact(11.0, name, velocity=100.0))
        client.sync()
        client.send(encode_raw("/pd/stop", []))
        client.pd.wait_for(lambda _: bool(client.pd.printed("batteur-stop")))
        assert len(client.strikes()) == 6
    audio = _take(tmp_path / "takes" / "take-1.wav")
    assert np.all(np.isfinite(audio))
    clipped = int(np.count_nonzero(np.abs(audio) >= 0.999))
    assert clipped == 0 and float(np.max(np.abs(audio))) > 0.2, (clipped, float(np.max(np.abs(audio))))


def test_the_clients_impact_fields_match_the_impact_message() -> None:
    """sound-client.pd reads /batteur/impact by argument position (instrument, rig time, velocity, sequence
    number): they must be Impact's wire positions, and its checks the model's argument count and velocity range."""
    position: dict[str, int] = {}
    n = 0
    for f in Impact.wire_fields():
        position[f.name] = n
        n += 2 if f.kind is WireKind.TIME else 1
    velocity = next(f for f in Impact.wire_fields() if f.name == "velocity")
    patch = (PD_DIR / "sound-client.pd").read_text(encoding="utf-8")
    inst, t, v = position["instrument"] + 1, position["time"] + 1, position["velocity"] + 1
    seq = position["seq"] + 1
    assert f"#X msg 100 460 \\${inst} \\${t} \\${t + 1} \\${v} \\${seq};" in patch
    # the counts the service takes: without the appended fields (an older sender's) up to a newer sender's
    low, high = n - len(Impact.APPENDED), n + Impact.NEWER_ARGS
    assert f"expr \\$f1 < {low} || \\$f1 > {high};" in patch and f"({low} to {high} expected)" in patch
    assert f"\\$f1 >= {velocity.minimum:g} && \\$f1 <= {velocity.maximum:g}" in patch
    assert f"velocity \\${v + 1} is not in {velocity.minimum:g}..{velocity.maximum:g}" in patch


# ---------------------------------------------------------------- the control panel


def test_panel_instrument_box_chooses_what_it_shows_and_every_control_is_accepted() -> None:
    """Typing an instrument into the SOUND box (what a gatom does with a symbol on its receive name) must make the
    controls act on it; and every control of the panel sends a message the rig's cores accept (none dropped)."""
    require_pd()
    import asyncio

    from common.messages.physics import PhysicsReset
    from common.messages.score import GestureStyle
    from common.messages.sound import SoundDensity, SoundLevel, SoundMaster, SoundRadius, SoundTension

    async def main() -> None:
        async with physics_and_sound_nodes() as rig:
            physics, sound, pport, sport, nodes = rig.physics, rig.sound, rig.physics_port, rig.sound_port, rig.nodes
            sends = [f"bp-port-physics {pport}", f"bp-port-score {pport}", f"bp-port-sound {sport}",
                     "bp-instrument-show symbol hightom", "bp-tension 900",
                     "bp-instrument symbol ride", "bp-level -3", "bp-radius 0.3", "bp-density 1.5",
                     "bp-reset bang", "bp-sticking symbol paradiddle", "bp-master -6", "bp-reverb 0.5"]
            pd = PdProcess(PD_DIR / "control.pd", sends=sends)
            try:
                deadline = time.monotonic() + 20
                while len(sound.of(SoundMaster)) < 2 or not physics.of(GestureStyle):
                    assert time.monotonic() < deadline, "\n".join(pd.lines)
                    await asyncio.sleep(0.02)
            finally:
                pd.stop()
        assert pd.errors() == [], "\n".join(pd.lines)
        assert [m.instrument for m in sound.of(SoundTension)] == ["hightom"]
        assert sound.core.instruments.instruments["hightom"].p.tension == pytest.approx(900, rel=1e-4)
        assert [m.instrument for m in sound.of(SoundLevel) + sound.of(SoundRadius) + sound.of(SoundDensity)] == \
            ["ride"] * 3
        # only the sticking was changed: the other three stay as the node's score player starts
        assert physics.of(PhysicsReset) and physics.of(GestureStyle)[-1] == GestureStyle(
            grip="german", nuance="tenuto", algorithm="viterbi", sticking="paradiddle")
        assert sound.of(SoundMaster)[-1].gain_db == pytest.approx(-6) and sound.of(SoundMaster)[-1].reverb == \
            pytest.approx(0.5)
        for node in nodes:
            assert node.endpoint is not None and node.endpoint.stats.dropped_total == 0, \
                node.endpoint.stats.drops_by_reason()

    asyncio.run(main())


# ---------------------------------------------------------------- the generators


def _run(script: str, args: Sequence[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(PD_DIR / script), *args], cwd=str(cwd), capture_output=True,
                          text=True, timeout=60)


def test_make_control_help_and_output(tmp_path: Path) -> None:
    before = (PD_DIR / "control.pd").stat().st_mtime_ns
    helped = _run("make_control.py", ["--help"], tmp_path)
    assert helped.returncode == 0 and "--output" in helped.stdout and "wrote" not in helped.stdout
    out = tmp_path / "panel.pd"
    made = _run("make_control.py", ["--output", str(out)], tmp_path)
    assert made.returncode == 0, made.stderr
    assert (PD_DIR / "control.pd").stat().st_mtime_ns == before  # the committed panel was not touched
    text = out.read_text(encoding="utf-8")
    assert text.startswith("#N canvas") and "oscformat batteur sound tension" in text
    assert _run("make_control.py", ["--check", "--output", str(out)], tmp_path).returncode == 0
    out.write_text(text.replace("9103", "9999"), encoding="utf-8")
    stale = _run("make_control.py", ["--check", "--output", str(out)], tmp_path)
    assert stale.returncode == 1 and "stale" in stale.stderr
    wrong = _run("make_control.py", ["panel.pd"], tmp_path)
    assert wrong.returncode == 2 and "unrecognized arguments" in wrong.stderr
    assert (PD_DIR / "control.pd").stat().st_mtime_ns == before


def _pd_module(name: str) -> Any:
    sys.path.insert(0, str(PD_DIR))
    try:
        return __import__(name)
    finally:
        sys.path.remove(str(PD_DIR))


def test_make_control_refuses_a_control_whose_argument_kinds_do_not_fit_the_model() -> None:
    """A panel control that would send a fraction where the model takes an int, a number where it takes a name,
    or the wrong number of arguments stops the generator with a message naming the model."""
    from common.messages.physics import PhysicsReset
    from common.messages.sound import SoundLevel, SoundModes

    make_control = _pd_module("make_control")
    for model, sends in ((SoundModes, "sf"), (SoundLevel, "ff"), (SoundLevel, "sff"), (PhysicsReset, "f")):
        with pytest.raises(SystemExit, match=rf"{model.__name__} \({model.ADDRESS}\): the panel sends '{sends}'"):
            make_control.check_sends(model, sends)
    make_control.check_sends(SoundModes, "si")
    make_control.check_sends(SoundLevel, "si")  # a whole number is a number
    make_control.check_sends(PhysicsReset, "ii")  # rig time 0: whole seconds, fraction


@pytest.mark.parametrize(("args", "message"), [
    (["missing.pd", "out.png"], "missing.pd: No such file"),
    (["notes.txt", "out.png"], "is not a Pure Data patch"),
    ([str(PD_DIR / "control.pd"), "out.xyz"], "unknown picture format"),
    ([str(PD_DIR / "control.pd")], "required"),
])
def test_render_patch_refuses_bad_arguments_clearly(tmp_path: Path, args: list[str], message: str) -> None:
    (tmp_path / "notes.txt").write_text("not a patch\n", encoding="utf-8")
    result = _run("render_patch.py", args, tmp_path)
    assert result.returncode == 2 and message in result.stderr, result.stderr
    assert "Traceback" not in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_render_patch_help(tmp_path: Path) -> None:
    result = _run("render_patch.py", ["--help"], tmp_path)
    assert result.returncode == 0 and "PATCH.pd" in result.stdout and "OUT.png" in result.stdout


def test_render_patch_draws_a_subpatch_as_one_box_of_its_parent(tmp_path: Path) -> None:
    """Pd counts ``[pd NAME]`` as one object of the parent: the connections after it must join the right boxes."""
    render_patch = _pd_module("render_patch")
    patch = tmp_path / "sub.pd"
    patch.write_text("#N canvas 0 0 400 300 12;\n#X obj 10 10 inlet;\n#N canvas 0 0 200 200 12;\n"
                     "#X obj 5 5 inlet;\n#X obj 5 50 outlet;\n#X connect 0 0 1 0;\n#X restore 10 60 pd inner;\n"
                     "#X obj 10 110 print after;\n#X connect 0 0 1 0;\n#X connect 1 0 2 0;\n", encoding="utf-8")
    boxes, connects, _ = render_patch.parse(patch)
    assert [b.text for b in boxes] == ["inlet", "pd inner", "print after"]
    assert [(boxes[a].text, boxes[b].text) for a, _, b, _ in connects] == [("inlet", "pd inner"),
                                                                           ("pd inner", "print after")]
    boxes, connects, _ = render_patch.parse(PD_DIR / "sound-client.pd")
    assert all(a < len(boxes) and b < len(boxes) for a, _, b, _ in connects)
    route_end = next(k for k, b in enumerate(boxes) if b.text == "route end")
    check = [boxes[b].text for a, o, b, _ in connects if a == route_end and o == 1]
    assert check == ["pd check-impact"]
    assert render_patch.main([str(PD_DIR / "sound-client.pd"), str(tmp_path / "sc.png")]) == 0


def test_every_patch_and_subpatch_loads_in_pd_without_errors() -> None:
    """The voice abstraction alone too (it is opened by users who want to edit it)."""
    pd = PdProcess(PD_DIR / "batteur-voice.pd", extra=["-send", "pd quit"])
    try:
        pd.popen.wait(timeout=20)
        pd.wait_for(lambda lines: True, timeout=1)
    finally:
        pd.stop()
    assert pd.errors() == [], "\n".join(pd.lines)
    assert not re.search(r"couldn't create|bad arguments", "\n".join(pd.lines))
