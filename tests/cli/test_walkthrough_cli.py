"""Command-line polish from a new user's walkthrough (README, "Exit status": one line ``PROG: error: MESSAGE``).

* PyBullet's C library printed ``pybullet build time: ...`` on stderr as it loaded: before ``batteur render
  --help``, and as a second line of every error of the commands that simulate;
* ``--skeleton-bvh`` given a folder said "no such file"; ``--kit`` given a MIDI file said it "is not UTF-8 text
  (invalid continuation byte ...)"; a misspelt kit key ended "(and 1 more)", the one more the typo itself;
* ``--strikes -1:3`` and ``batteur send ADDRESS -1e-3`` were taken for options by argparse;
* ``batteur echo`` printed a node's Health once per peer it went to;
* ``batteur docs`` outside a checkout gave no hint, and wrote docs/osc.md in place;
* ``batteur render --help`` showed argparse's metavars (TEMPO_SCALE ...) and --gltf among the video options.
"""

from __future__ import annotations

import asyncio
import os
import re
import socket
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import ClassVar

import pytest

from batteur import render
from batteur.tools import docs, send
from common.config import load_settings
from common.gesture.bvh import BvhError, read_bvh
from common.kit import KITS_DIR, load_kit
from common.messages import Health, OscMessage, Subscribe, decode
from common.messages.sound import SoundMaster
from common.runtime import Node
from common.transport import UdpEndpoint
from tests.null_core import NullCore
from tests.waiting import wait_for

ROOT = Path(__file__).resolve().parents[2]
MIDI = ROOT / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"
DIRECT_IMPORT = re.compile(r"^\s*(?:import pybullet\b|from pybullet(?:_utils)?(?:\.\S+)? import )", re.MULTILINE)


def _batteur(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "batteur", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, check=False, env={**os.environ, "PYTHONPATH": str(ROOT)})


# ---------------------------------------------------------------- 1. PyBullet's banner


def test_pybullet_is_imported_only_through_the_module_that_silences_its_banner() -> None:
    direct = [str(path.relative_to(ROOT)) for folder in ("common", "services", "batteur")
              for path in sorted((ROOT / folder).rglob("*.py"))
              if path.name != "quiet_pybullet.py" and DIRECT_IMPORT.search(path.read_text(encoding="utf-8"))]
    assert direct == []  # each would print the banner when it is the first to load PyBullet


def test_render_help_and_a_render_error_write_no_banner(tmp_path: Path) -> None:
    shown = _batteur("render", "--help")
    assert shown.returncode == 0 and shown.stderr == "", shown.stderr  # was "pybullet build time: ..."
    refused = _batteur("render", "--strikes", "-1:3", "-o", str(tmp_path / "out"))
    assert refused.returncode == 2
    assert refused.stderr.splitlines() == [refused.stderr.strip()], refused.stderr  # one line
    assert refused.stderr.startswith("batteur render: error: strike '-1:3': "), refused.stderr
    assert not (tmp_path / "out").exists()


def test_the_banner_s_line_is_dropped_and_other_lines_kept(capfd: pytest.CaptureFixture[str]) -> None:
    from common.quiet_pybullet import banner_dropped

    with banner_dropped():
        os.write(2, b"pybullet build time: Jan 29 2025 23:17:20\nanother thread's line\n")
    assert capfd.readouterr().err == "another thread's line\n"


# ---------------------------------------------------------------- 2, 3. files given for the wrong option


def test_a_folder_given_as_skeleton_bvh_is_said_to_be_a_folder(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(BvhError, match="is a folder, not a BVH file"):  # was "no such file"
        read_bvh(tmp_path)
    with pytest.raises(BvhError, match="no such file"):
        read_bvh(tmp_path / "missing.bvh")
    assert render.main([str(MIDI), "-o", str(tmp_path / "out"), "--quiet", "--skeleton-bvh", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"batteur render: error: --skeleton-bvh: {tmp_path}: is a folder, not a BVH file", err


def test_a_midi_or_audio_file_given_as_the_kit_is_named_as_such(tmp_path: Path) -> None:
    with pytest.raises(ValueError) as refused:
        load_kit(MIDI)
    said = str(refused.value)  # was "kit file '...mid' is not UTF-8 text (invalid continuation byte at byte 13)"
    assert said.startswith(f"{str(MIDI)!r} is a MIDI file, not a kit: "), said
    assert "UTF-8" not in said and "default" in said  # what to give instead: the shipped kits
    wav = tmp_path / "take.wav"
    wav.write_bytes(b"RIFF\x24\x00\x00\x00WAVEfmt \x10\x00\x00\x00\x01\x00\x01\x00\x80\xbb")
    with pytest.raises(ValueError, match=r"'.*take\.wav' is an audio file \(WAV\), not a kit: "):
        load_kit(wav)
    latin = tmp_path / "latin.yaml"  # a text kit in another encoding is still said to be not UTF-8
    latin.write_bytes("# caf\xe9\nname: x\n".encode("latin-1"))
    with pytest.raises(ValueError, match=r"is not UTF-8 text \(invalid continuation byte"):
        load_kit(latin)


def _kit_text(*replacements: tuple[str, str]) -> str:
    text = (KITS_DIR / "default.yaml").read_text()
    for old, new in replacements:
        assert old in text
        text = text.replace(old, new, 1)
    return text


def test_a_misspelt_kit_key_is_one_problem_not_two(tmp_path: Path) -> None:
    kit = tmp_path / "kit.yaml"
    typo = ("id: snare, kind: membrane, position:", "id: snare, kind: membrane, positon:")
    kit.write_text(_kit_text(typo))
    with pytest.raises(ValueError) as refused:
        load_kit(kit)
    said = str(refused.value)
    assert said.endswith("('position' is missing: misspelt?)"), said  # was "... misspelt?) (and 1 more)"
    kit.write_text(_kit_text(typo, ("double_pedal: false", "double_pedal: maybe")))  # a second problem: counted
    with pytest.raises(ValueError) as refused:
        load_kit(kit)
    assert str(refused.value).endswith("misspelt?) (and 1 more)"), str(refused.value)


# ---------------------------------------------------------------- 4. values that start with '-'


def test_render_takes_a_strike_at_a_negative_time_as_a_value(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert render.main(["--strikes", "-1:3", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("batteur render: error: strike '-1:3': "), err  # was "expected one argument"
    assert render.main([str(MIDI), "-o", str(tmp_path / "out"), "--quiet", "--tempo-scale", "-1e-3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("batteur render: error: --tempo-scale -0.001: "), err  # its own check, not argparse's
    assert not (tmp_path / "out").exists()


def test_evaluate_takes_a_negative_tempo_scale_to_its_own_check(capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import evaluate

    assert evaluate.main([str(MIDI), "--tempo-scale", "-1e-3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("batteur evaluate: error: --tempo-scale -0.001: "), err  # was "expected one argument"


def test_send_takes_negative_numbers_as_arguments() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(5)
        to = f"127.0.0.1:{sock.getsockname()[1]}"
        assert send.main(["/batteur/sound/master", "-1.5e1", "0.5", "--to", to]) == 0  # was "unrecognized"
        assert decode(sock.recv(65535)).messages == [SoundMaster(gain_db=-15.0, reverb=0.5)]


# ---------------------------------------------------------------- 5. a node's message once per send


def test_a_message_sent_to_several_destinations_at_once_is_tapped_once() -> None:
    async def main() -> None:
        node = await UdpEndpoint.open()
        taps: list[str] = []
        node.tap = lambda address, packet, direction: taps.append(address)
        health = Health(node_id="n", role="sound", protocol=1, time=1.0, rate_hz=0.0, target_rate_hz=0.0,
                        overruns=0, messages_in=0, messages_out=0, dropped=0, dropped_malformed=0,
                        dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=2)
        node.send(health, ("127.0.0.1", 9))
        node.send(health, ("127.0.0.1", 10))  # the same message to a second peer: the same send
        assert taps == ["/batteur/health"]
        await asyncio.sleep(0)
        node.send(health, ("127.0.0.1", 9))  # the next send of it (a later second): copied again
        assert taps == ["/batteur/health"] * 2
        node.close()

    asyncio.run(main())


class QuietCore(NullCore):
    """The null core in a role of its own (``echo``), so a node of it may have sound and graphics peers."""

    ROLE: ClassVar[str] = "echo"


def _into(inbox: list[OscMessage]) -> Callable[[OscMessage, str], None]:
    """A handler keeping what an endpoint receives."""
    return lambda message, source: inbox.append(message)


@pytest.mark.timeout(60)
def test_a_subscriber_gets_each_health_once_whatever_the_node_s_peers() -> None:
    async def main() -> None:
        peers = [await UdpEndpoint.open(), await UdpEndpoint.open()]
        heard: list[list[OscMessage]] = [[], []]
        for peer, inbox in zip(peers, heard, strict=True):
            peer.set_handler(_into(inbox))
        node = Node(QuietCore(), load_settings({"role": "echo", "discovery": False, "clock_master": "self",
                                                "peers": [f"sound={peers[0].local_address}",
                                                          f"graphics={peers[1].local_address}"]}),
                    health_interval_s=0.05)
        task = asyncio.ensure_future(node.run())
        await wait_for(lambda: node.endpoint is not None)
        assert node.endpoint is not None
        echo = await UdpEndpoint.open()  # the `batteur echo` side
        copies: list[OscMessage] = []
        echo.set_handler(lambda m, s: copies.append(m))
        echo.send(Subscribe(pattern="/batteur/health", duration_s=30.0), node.endpoint.local_address)
        await wait_for(lambda: bool(node.subscriptions.active))
        await wait_for(lambda: len(copies) >= 4, timeout=30.0)
        node.request_stop()
        await asyncio.wait_for(task, 5.0)
        times = [m.time for m in copies if isinstance(m, Health)]
        assert len(times) == len(set(times)), times  # was each Health twice: once per peer it went to
        assert all(any(isinstance(m, Health) for m in inbox) for inbox in heard)  # both peers still get it
        for endpoint in (echo, *peers):
            endpoint.close()

    asyncio.run(main())


# ---------------------------------------------------------------- 6. batteur docs


def test_docs_outside_a_checkout_says_to_give_o(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert docs.main([]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("batteur docs: error: -o docs/osc.md: folder ") and "-o PATH" in err, err
    assert docs.main(["-o", "osc.md"]) == 0
    assert (tmp_path / "osc.md").read_text(encoding="utf-8").startswith("#")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_FSIZE and EFBIG as on Linux")
def test_docs_that_cannot_be_written_whole_leave_the_earlier_file(tmp_path: Path) -> None:
    earlier = tmp_path / "osc.md"
    earlier.write_text("the earlier reference\n", encoding="utf-8")
    # a file size limit below the reference's: the write fails halfway, as on a full disk
    code = ("import resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
            "resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096)); from batteur.tools import docs; "
            f"sys.exit(docs.main(['-o', {str(earlier)!r}]))")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                         check=False)
    assert run.returncode == 1 and run.stderr.startswith("batteur docs: error: -o "), run.stderr
    assert earlier.read_text(encoding="utf-8") == "the earlier reference\n"  # was cut to 4096 bytes of the new one
    assert [p.name for p in tmp_path.iterdir()] == ["osc.md"]  # no temporary file left


# ---------------------------------------------------------------- 7. batteur render --help


def test_render_help_names_values_by_what_they_are_and_keeps_the_video_options_together() -> None:
    shown = render.build_parser().format_help()
    for option in ("--tempo-scale X", "--latency SECONDS", "--calibration FILE", "--video-size WxH",
                   "--video-fps FPS"):
        assert option in shown, option
    assert not re.search(r"TEMPO_SCALE|LATENCY|CALIBRATION|VIDEO_SIZE|VIDEO_FPS", shown)
    listed = re.findall(r"^  (--[a-z-]+)", shown, re.MULTILINE)  # the options as the help lists them
    at = listed.index("--video")
    assert listed[at:at + 3] == ["--video", "--video-size", "--video-fps"], listed  # --gltf was between the last two
