"""``batteur rig --host 0.0.0.0`` without an allow-list is refused before any service starts, with the message a
node gives (exit 2). Until 7 Dec the rig started every service, interaction exited with status 2 on it, and the rig
stopped the others: docs/deployment.md says the rig checks its options first.

Nothing is started (the rig's process runner is replaced) and no port is bound: the accepted cases skip the port
check, which would bind the wildcard address.
"""

from __future__ import annotations

import pytest

from batteur import rig
from common.config import SettingsError, load_settings
from tests.ports import free_ports
from tests.test_rig_inputs import refused

pytestmark = pytest.mark.timeout(60)


class _Recorder:
    """Stands in for :class:`rig.Rig`: records the plans, starts nothing."""

    started: list[rig.ServicePlan] = []

    def __init__(self, plans: list[rig.ServicePlan], *args: object, **kwargs: object) -> None:
        _Recorder.started = list(plans)

    async def run(self, duration_s: float | None) -> int:
        return 0


@pytest.fixture
def recorder(monkeypatch: pytest.MonkeyPatch) -> type[_Recorder]:
    _Recorder.started = []
    monkeypatch.setattr(rig, "Rig", _Recorder)
    monkeypatch.setattr(rig, "check_ports", lambda *args, **kwargs: None)
    for name in ("BATTEUR_ALLOW", "BATTEUR_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    return _Recorder


def _node_message(host: str) -> str:
    with pytest.raises(SettingsError) as info:
        load_settings({"role": "interaction", "host": host})
    return str(info.value).split(": ", 1)[1]  # after "invalid settings"


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.10"])
def test_a_host_off_loopback_without_an_allow_list_is_refused_up_front(
        host: str, recorder: type[_Recorder], capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(["--host", host, "--no-discovery", "--base-port", str(free_ports(4)[0])], capsys, 2)
    assert recorder.started == []  # no service started
    assert err.startswith("batteur rig: error: ") and _node_message(host) in err  # the node's own words
    assert "BATTEUR_ALLOW=" in err  # how the rig's services get one


def test_one_service_without_an_allow_list_is_enough_to_refuse(recorder: type[_Recorder],
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--host", "0.0.0.0", "--no-discovery", "--services", "physics,sound", "--base-port",
            str(free_ports(4)[0]), "--sound-arg=--allow 10.0.0.0/8"]
    refused(argv, capsys, 2)
    assert recorder.started == []


@pytest.mark.parametrize(("env", "extra"), [
    ({"BATTEUR_ALLOW": "192.168.1.0/24"}, []),
    ({}, ["--physics-arg=--allow 10.0.0.0/8", "--sound-arg=--allow 10.0.0.0/8"]),
    ({"BATTEUR_CONFIG": "rig.yaml"}, []),  # a config file may give it: each node checks its own
])
def test_an_allow_list_the_services_get_is_accepted(env: dict[str, str], extra: list[str],
                                                    recorder: type[_Recorder], monkeypatch: pytest.MonkeyPatch) -> None:
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    argv = ["--host", "0.0.0.0", "--no-discovery", "--services", "physics,sound", "--base-port",
            str(free_ports(4)[0]), *extra]
    assert rig.main(argv) == 0
    assert [p.role for p in recorder.started] == ["physics", "sound"]


def test_loopback_needs_no_allow_list(recorder: type[_Recorder]) -> None:
    assert rig.main(["--no-discovery", "--services", "sound", "--base-port", str(free_ports(4)[0])]) == 0
    assert [p.role for p in recorder.started] == ["sound"]
