"""The service nodes (``batteur physics|interaction|sound|graphics``) read a value that starts with '-' and is a
number (``-1e3``, ``-.5``, ``-inf``) as the option's value, as ``batteur render`` does (common/arg_types.py): argparse
took all but ``-1`` and ``-1.5`` for options and said "expected one argument", where the setting's own check should
say what is wrong with the value."""

from __future__ import annotations

import argparse

import pytest

from common.config import NodeSettings
from common.runtime import run_node
from services.sound.node import SoundNodeSettings
from tests.cli.test_exit_statuses import NODES, run
from tests.null_core import NullCore


@pytest.mark.parametrize("name", NODES)
@pytest.mark.parametrize("value", ["-1e3", "-inf"])
def test_a_negative_epoch_reaches_the_settings_own_check(name: str, value: str,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    status, line, prog = run(name, ["--no-discovery", "--epoch", value, "--show-settings"], capsys)
    assert status == 2
    # was "argument --epoch: expected one argument"
    assert line.startswith(f"{prog}: error: invalid setting epoch: "), line
    assert f"(got '{value}') [--epoch / BATTEUR_EPOCH]" in line, line


def test_a_services_own_option_takes_a_negative_number(capsys: pytest.CaptureFixture[str]) -> None:
    def make_core(settings: NodeSettings, extra: argparse.Namespace) -> NullCore:
        raise AssertionError("the setting's own check refuses it before the core is made")

    argv = ["--no-discovery", "--no-oscquery", "--reverb", "-1e-3"]
    # was SystemExit: "expected one argument"
    assert run_node("sound", make_core, argv, settings_cls=SoundNodeSettings) == 2
    line = capsys.readouterr().err.strip()
    assert line.startswith("batteur sound: error: invalid setting reverb: "), line
    assert "(got '-1e-3') [--reverb / BATTEUR_REVERB]" in line, line


@pytest.mark.parametrize(("name", "argv", "said"), [
    ("rig", ["--play-at", "-1e-3"], "argument --play-at: '-1e-3': give a finite number of at least 0"),
    ("transcribe", ["x.wav", "-o", "x.mid", "--tempo", "-1e2"], "--tempo must be "),
    ("ls", ["--node", "127.0.0.1:9", "--timeout", "-1e-3"], "argument --timeout: '-1e-3': give a positive finite"),
])
def test_the_rig_transcribe_and_ls_take_negative_numbers_to_their_own_checks(
        name: str, argv: list[str], said: str, capsys: pytest.CaptureFixture[str]) -> None:
    """The other commands of this kind (the rig launches the nodes; transcribe is the recogniser's; ls asks them)."""
    status, line, prog = run(name, argv, capsys)
    assert status == 2
    assert line.startswith(f"{prog}: error: ") and said in line, line  # was "expected one argument"
