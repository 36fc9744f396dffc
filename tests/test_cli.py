"""The ``batteur`` command line: help for every command, send, ls and echo against a real node."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from batteur import cli
from batteur.tools import send
from common.messages import Hello, decode


@pytest.mark.parametrize("command", sorted(cli.COMMANDS))
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        cli.main([command, "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "usage:" in out and "--help" in out


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


@pytest.fixture
def interaction_node() -> Iterator[int]:
    """An interaction node on loopback (no discovery), yielding its UDP port."""
    sock, port = _udp_listener()
    sock.close()
    proc = subprocess.Popen(
        [sys.executable, "-m", "batteur", "interaction", "--port", str(port), "--no-discovery", "--no-oscquery"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    time.sleep(1.5)
    try:
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
    time.sleep(2.0)
    assert send.main(["/batteur/hello", "cli", "tester", "1", "9", "--to", f"127.0.0.1:{interaction_node}"]) == 0
    out, err = echo.communicate(timeout=30)
    assert echo.returncode == 0, err
    assert out.startswith("/batteur/hello 'cli' 'tester' 1 9")
