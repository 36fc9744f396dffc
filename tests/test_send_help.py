"""``batteur send``: the help's examples work, and ``--replies`` says when no answer came."""

from __future__ import annotations

import re
import shlex
import socket

import pytest

from batteur.tools import send
from common.messages import REGISTRY


def help_text(capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit):
        send.main(["--help"])
    return capsys.readouterr().out


def test_every_address_in_the_help_is_registered(capsys: pytest.CaptureFixture[str]) -> None:
    # the help gave /batteur/sound/param, which send refuses: "no message is registered"
    addresses = re.findall(r"/batteur/[\w/]+", help_text(capsys))
    assert addresses
    assert [a for a in addresses if REGISTRY.get(a) is None] == []


def test_the_helps_example_command_is_a_message_send_accepts(capsys: pytest.CaptureFixture[str]) -> None:
    example = re.search(r"example: (batteur send .+)", help_text(capsys))
    assert example is not None
    words = shlex.split(example.group(1))[2:]
    address, args = words[0], words[1:words.index("--to")]
    assert send._encode(address, send.typed_args(address, args))  # MessageError if the model refused it


def test_replies_says_when_no_answer_came(capsys: pytest.CaptureFixture[str]) -> None:
    # a node that stays silent (an accepted control, an address it drops): --replies printed nothing at all
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as node:
        node.bind(("127.0.0.1", 0))
        to = f"127.0.0.1:{node.getsockname()[1]}"
        code = send.main(["/batteur/graphics/latency", "0.1", "--to", to, "--replies", "0.2"])
        assert node.recv(65536)  # it was sent
    out, err = capsys.readouterr()
    assert code == 0  # docs: --replies fails on a refusal or nothing listening; an accepted control gets no answer
    assert out == ""
    assert f"no reply from {to} within 0.2 s" in err
