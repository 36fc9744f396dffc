"""`batteur send` given too few or too many arguments names the ones the message takes: it said only
`wrong_arity: /batteur/sound/master: expected 2 arguments, got 1`, which two left to docs/osc.md."""

from __future__ import annotations

import socket

import pytest

from batteur.tools import send
from common.messages import decode
from common.messages.score import ScoreTransport


@pytest.mark.parametrize(("args", "takes"), [
    (["/batteur/sound/master", "0.5"], "GAIN_DB REVERB"),
    (["/batteur/score/transport", "play"],  # a rig time is two on the wire, or one number of seconds
     "ACTION TIME_WHOLE_S TIME_FRACTION POSITION (or TIME_S for TIME_WHOLE_S TIME_FRACTION)"),
    (["/batteur/hello", "sound", "n1", "1", "9000", "extra"], "ROLE NODE_ID PROTOCOL OSC_PORT"),
])
def test_a_wrong_number_of_arguments_names_those_the_message_takes(args: list[str], takes: str,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert send.main([*args, "--to", "127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"batteur send: error: wrong_arity: {args[0]}: expected "), err
    assert err.endswith(f"; {args[0]} takes {takes}"), err


@pytest.mark.parametrize("args", [["play", "12.25", "1.5"], ["play", "12", "0.25", "1.5"]])
def test_a_rig_time_may_be_one_number_of_seconds(args: list[str]) -> None:
    """As docs/physics.md writes it (``/batteur/score/transport play TIME POSITION``): was wrong_arity, "expected 4
    arguments, got 3"; the wire's two numbers still work."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as node:
        node.bind(("127.0.0.1", 0))
        node.settimeout(5)
        to = f"127.0.0.1:{node.getsockname()[1]}"
        assert send.main(["/batteur/score/transport", *args, "--to", to]) == 0
        assert decode(node.recv(65536)).messages == [ScoreTransport(action="play", time=12.25, position=1.5)]


@pytest.mark.parametrize("args", [["top", "1", "2"], ["free", "1", "2"], []])
def test_the_camera_s_usage_says_a_preset_may_be_sent_alone(args: list[str],
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    """The refusal said "or the preset alone (not free)", the usage after it only the seven arguments."""
    assert send.main(["/batteur/graphics/camera", *args, "--to", "127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("; /batteur/graphics/camera takes PRESET AZIMUTH_DEG ELEVATION_DEG DISTANCE TARGET_X "
                        "TARGET_Y TARGET_Z, or PRESET alone (any preset but free)"), err


@pytest.mark.parametrize(("time", "reason"), [("nan", "out_of_range"), ("inf", "out_of_range"),
                                              ("-inf", "out_of_range"), ("soon", "wrong_type")])
def test_a_one_number_time_that_is_not_a_finite_number_is_named(time: str, reason: str,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """``play nan 0`` has the one-number form's count: it said "wrong_arity: ... expected 4 arguments, got 3".
    Refused before anything is sent (nothing listens at the address given)."""
    assert send.main(["/batteur/score/transport", "play", time, "0", "--to", "127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"batteur send: error: {reason}: /batteur/score/transport: TIME: must be a finite number of "
                   f"seconds, got {time!r}"), err
