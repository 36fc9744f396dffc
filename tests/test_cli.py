"""The ``batteur`` command line: help for every command, send, ls and echo against a real node."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from batteur import cli
from batteur.tools import send
from common.messages import Hello, decode
from tests.waiting import until


def test_top_level_help_lists_every_command(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = capsys.readouterr().out
    for command in cli.COMMANDS:
        assert command in out


def _udp_listener() -> tuple[socket.socket, int]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(5)
    return sock, sock.getsockname()[1]


def test_send_types_arguments_by_the_model() -> None:
    sock, port = _udp_listener()
    with sock:
        assert send.main(["/batteur/hello", "sound", "n1", "1", "9000", "--to", f"127.0.0.1:{port}"]) == 0
        message = decode(sock.recv(65535)).messages[0]
    assert message == Hello(role="sound", node_id="n1", protocol=1, osc_port=9000)


@pytest.mark.parametrize(
    ("args", "error"),
    [
        (["/batteur/hello", "sound", "n1", "one", "9000"], "wrong_type"),
        (["/batteur/hello", "sound"], "wrong_arity"),
        (["/batteur/hello", "sound", "n1", "1", "99999"], "out_of_range"),
        (["/no/such"], "no message is registered"),
    ],
)
def test_send_refuses_a_message_that_would_be_rejected(
    args: list[str], error: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert send.main([*args, "--to", "127.0.0.1:9"]) == 2
    assert error in capsys.readouterr().err


def test_send_names_a_bad_target_and_a_failed_send(capsys: pytest.CaptureFixture[str]) -> None:
    hello = ["/batteur/hello", "sound", "n1", "1", "9000"]
    assert send.main([*hello, "--to", "127.0.0.1:99999"]) == 2
    assert "port out of range" in capsys.readouterr().err
    assert send.main([*hello, "--to", "::1:9000"]) == 2
    assert "brackets" in capsys.readouterr().err
    # a datagram larger than UDP allows: the OS refuses it (nothing leaves loopback), the command says so
    assert send.main(["--raw", "/x", "a" * 70_000, "--to", "127.0.0.1:9"]) == 1
    assert "cannot send to 127.0.0.1:9" in capsys.readouterr().err


@pytest.fixture(scope="module")
def interaction_node(tmp_path_factory: pytest.TempPathFactory) -> Iterator[int]:
    """An interaction node on loopback (no discovery), yielding its UDP port once it says it listens; one per
    module: ls only asks it and echo's subscription ends with echo."""
    sock, port = _udp_listener()
    sock.close()
    log_path = tmp_path_factory.mktemp("interaction") / "node.log"
    with open(log_path, "wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "batteur", "interaction", "--port", str(port), "--no-discovery", "--no-oscquery"],
            stdout=subprocess.DEVNULL, stderr=log,
        )
    try:
        said = f"listening on 127.0.0.1:{port} (rate"  # the runtime's line: its handlers are in place
        assert until(lambda: proc.poll() is not None or said in log_path.read_text(errors="replace"),
                     timeout_s=30), "the interaction node never said it listens"
        assert proc.poll() is None, log_path.read_text(errors="replace")
        yield port
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_ls_reports_a_running_node_and_fails_for_a_silent_one(interaction_node: int) -> None:
    ok = subprocess.run([sys.executable, "-m", "batteur", "ls", "--node", f"127.0.0.1:{interaction_node}",
                         "--timeout", "5"], capture_output=True, text=True, timeout=30)
    assert ok.returncode == 0, ok.stderr
    assert "interaction" in ok.stdout and "ok" in ok.stdout
    silent = subprocess.run([sys.executable, "-m", "batteur", "ls", "--node", "127.0.0.1:9", "--timeout", "0.5"],
                            capture_output=True, text=True, timeout=30)
    assert silent.returncode == 1 and "no answer" in silent.stdout


def test_echo_prints_matching_messages_from_a_node(interaction_node: int) -> None:
    # echo subscribes at the node; a Hello the node then receives is copied to echo
    echo = subprocess.Popen([sys.executable, "-m", "batteur", "echo", "/batteur/hel*", "--node",
                             f"127.0.0.1:{interaction_node}", "--count", "1", "--duration", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # echo's subscription reaches the node some time after it starts (later on a loaded machine): say hello
    # until echo has printed its one message
    deadline = time.monotonic() + 25
    while echo.poll() is None and time.monotonic() < deadline:
        assert send.main(["/batteur/hello", "cli", "tester", "1", "9", "--to", f"127.0.0.1:{interaction_node}"]) == 0
        time.sleep(0.5)
    out, err = echo.communicate(timeout=30)
    assert echo.returncode == 0, err
    assert out.startswith("/batteur/hello 'cli' 'tester' 1 9")


def test_rig_refuses_a_recording_folder_it_cannot_write_before_starting(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import rig

    a_file = tmp_path / "take.wav"
    a_file.write_bytes(b"mine")
    assert rig.main(["--record", str(a_file), "--score", "demo"]) == 1  # an output it cannot use
    assert "--record" in capsys.readouterr().err and a_file.read_bytes() == b"mine"


@pytest.mark.parametrize(("tool", "option", "value"), [("ls", "--timeout", "-1"), ("ls", "--browse", "0"),
                                                        ("echo", "--duration", "nan"), ("send", "--timeout", "x")])
def test_tool_durations_must_be_positive_seconds(tool: str, option: str, value: str,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    import importlib

    module = importlib.import_module(f"batteur.tools.{tool}")
    args = ["/x", "--to", "127.0.0.1:9"] if tool == "send" else ["/x"] if tool == "echo" else []
    with pytest.raises(SystemExit) as refused:
        module.main([*args, option, value])
    assert refused.value.code == 2 and option in capsys.readouterr().err


def test_rig_reads_the_score_before_starting_a_service(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import rig

    broken = tmp_path / "cut.mid"
    broken.write_bytes(b"MThd\x00\x00\x00\x06\x00\x01\x00\x01\x01\xe0MTrk\x00\x00\x00\x10\x00\x90")
    empty = tmp_path / "empty.txt"
    empty.write_text("tempo 100\n")
    for score, says in ((broken, "truncated MIDI file"), (empty, "no drum events")):
        assert rig.main(["--score", str(score)]) == 1  # an input it cannot use
        assert says in capsys.readouterr().err


def test_positive_number_types_of_the_tools_and_benchmarks() -> None:
    import argparse

    from common.arg_types import count, seconds

    assert seconds("2.5") == 2.5 and count("3") == 3
    for bad in ("0", "-1", "nan", "inf", "x"):
        with pytest.raises(argparse.ArgumentTypeError):
            seconds(bad)
    for bad in ("0", "-2", "1.5", "x"):
        with pytest.raises(argparse.ArgumentTypeError):
            count(bad)
    bench = subprocess.run([sys.executable, "bench/physics_rtf.py", "--seconds", "0"], capture_output=True,
                           text=True, cwd=Path(__file__).resolve().parents[1], timeout=120)
    assert bench.returncode == 2 and "--seconds" in bench.stderr  # was a ZeroDivisionError after building


def test_docs_refuses_an_output_it_cannot_write(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from batteur.tools import docs

    a_file = tmp_path / "osc.md"
    a_file.write_text("mine")
    assert docs.main(["-o", str(a_file / "osc.md")]) == 1  # an output it cannot use
    assert "is a file, not a folder" in capsys.readouterr().err and a_file.read_text() == "mine"
    assert docs.main(["-o", str(tmp_path / "osc2.md")]) == 0 and "/batteur/" in (tmp_path / "osc2.md").read_text()


def test_ctrl_c_in_a_command_exits_130_without_a_traceback(monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C in a command that does not handle it, or while its modules load, is a clean stop (exit status 130,
    as a shell reports a SIGINT), not a Python traceback."""
    def interrupted(args: list[str]) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "load_command", lambda name: interrupted)
    assert cli.main(["evaluate", "x.mid"]) == 130
    assert "batteur evaluate: interrupted" in capsys.readouterr().err

    def loading(name: str) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "load_command", loading)
    assert cli.main(["transcribe", "x.wav"]) == 130


def test_demo_strikes_says_where_to_listen(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``batteur demo --strikes`` (the quick check without the drummer) ends as the demo does: where the WAV and
    the report are (it printed neither)."""
    from batteur import demo

    out = tmp_path / "strikes"
    assert demo.main(["--strikes", "-o", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert f"listen: {out / 'performance.wav'}" in printed and f"report: {out / 'report.json'}" in printed
    assert (out / "performance.wav").is_file() and (out / "report.json").is_file()
