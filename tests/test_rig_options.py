"""``batteur rig`` options a user gets wrong: a folder given as the score, zeroconf interfaces without zeroconf."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur import rig
from tests.ports import free_ports
from tests.test_rig_inputs import no_rig, refused  # noqa: F401 - no_rig is a fixture


class Recorder:
    """Stands in for :class:`rig.Rig`: records the plans, starts nothing."""

    started: list[rig.ServicePlan] = []

    def __init__(self, plans: list[rig.ServicePlan], *args: object, **kwargs: object) -> None:
        Recorder.started = list(plans)

    async def run(self, duration_s: float | None) -> int:
        return 0


def test_a_folder_given_as_the_score_is_called_a_folder(no_rig: None, tmp_path: Path,  # noqa: F811
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    # it said "no such file" of a folder that is there
    folder = tmp_path / "adir.mid"
    folder.mkdir()
    err = refused(["--no-discovery", "--score", str(folder), "--base-port", str(free_ports(4)[0])], capsys, 1)
    assert f"--score {folder}: is a folder, not a score file" in err and "no such file" not in err


@pytest.mark.parametrize("interfaces", ["0.0.0.0", "eth0"])
def test_interfaces_without_discovery_are_said_to_be_ignored(interfaces: str, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    # a wildcard, an error wherever zeroconf runs, was accepted in silence
    monkeypatch.setattr(rig, "Rig", Recorder)
    assert rig.main(["--no-discovery", "--interfaces", interfaces, "--services", "sound",
                     "--base-port", str(free_ports(4)[0])]) == 0
    err = capsys.readouterr().err
    assert f"warning: --interfaces {interfaces} is ignored with --no-discovery" in err
    assert "--interface" not in Recorder.started[0].args


def test_no_warning_without_interfaces(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(rig, "Rig", Recorder)
    assert rig.main(["--no-discovery", "--services", "sound", "--base-port", str(free_ports(4)[0])]) == 0
    assert "warning" not in capsys.readouterr().err
