"""``batteur rig`` and what its ``--ROLE-arg`` give one service, and the pose editor's ``--kit-dir``.

* A service given its own ``--host`` (``--sound-arg '--host 127.0.0.1'``) listens there (argparse keeps the last
  ``--host``): the rig's allow-list check, its peers and its Hellos take that address. The rig refused ``batteur rig
  --host 0.0.0.0 ... --sound-arg '--host 127.0.0.1'`` as if sound were off loopback, and let a service sent off
  loopback by its ``--ROLE-arg`` without an allow-list start (to exit 2 once the others had started).
* ``--ROLE-arg '--kit X'`` gave that one service another kit than the others (physics striking one kit while sound
  and graphics voiced and drew another): refused, pointing to the rig's ``--kit``.
* ``--kit-dir DIR`` gives graphics the folder its page saves kits and poses into: under the rig saving was off, short
  of ``--graphics-arg='--kit-dir DIR'``.

Tested on the command lines the rig builds (:func:`batteur.rig.plan_services`) or with its process runner replaced:
no service starts, no port is bound.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from batteur import rig
from common.peers import parse_static_peer
from tests.test_rig_inputs import no_rig, refused  # noqa: F401 - no_rig is a fixture

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
    monkeypatch.setattr(rig, "check_ports", lambda *args, **kwargs: None)  # would bind the wildcard address
    for name in list(os.environ):
        if name.startswith("BATTEUR_"):
            monkeypatch.delenv(name)
    return _Recorder


def _plans(*argv: str) -> dict[str, rig.ServicePlan]:
    opts = rig.build_parser().parse_args(["--no-discovery", *argv])
    return {plan.role: plan for plan in rig.plan_services(opts, epoch=0.0)}


def _peers(plan: rig.ServicePlan) -> dict[str, tuple[str, int]]:
    specs = [plan.args[i + 1] for i, arg in enumerate(plan.args) if arg == "--peer"]
    return {p.role: p.address for p in map(parse_static_peer, specs)}


# --------------------------------------------------------------------------- a service's own --host


@pytest.mark.parametrize("own", [["--sound-arg", "--host 127.0.0.1"], ["--sound-arg=--host=127.0.0.1"]])
def test_a_service_kept_on_loopback_needs_no_allow_list(own: list[str], recorder: type[_Recorder]) -> None:
    argv = ["--host", "0.0.0.0", "--no-discovery", "--services", "physics,sound",
            "--physics-arg=--allow 10.0.0.0/8", *own]
    assert rig.main(argv) == 0  # was refused: "host 0.0.0.0 listens off loopback" for sound
    plans = {p.role: p for p in recorder.started}
    assert (plans["physics"].host, plans["sound"].host) == ("0.0.0.0", "127.0.0.1")


def test_a_service_sent_off_loopback_by_its_own_host_needs_an_allow_list(
        no_rig: None, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:  # noqa: F811
    monkeypatch.delenv("BATTEUR_ALLOW", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    err = refused(["--no-discovery", "--services", "physics,sound", "--sound-arg", "--host 0.0.0.0"], capsys, 2)
    assert "--sound-arg --host 0.0.0.0: host 0.0.0.0 listens off loopback" in err, err  # was started, to exit 2


def test_its_own_allow_list_with_its_own_host_is_enough(recorder: type[_Recorder]) -> None:
    argv = ["--no-discovery", "--services", "physics,sound", "--sound-arg", "--host 0.0.0.0 --allow 10.0.0.0/8"]
    assert rig.main(argv) == 0
    assert [p.role for p in recorder.started] == ["physics", "sound"]


def test_the_others_reach_a_service_at_its_own_host() -> None:
    plans = _plans("--services", "physics,sound,graphics", "--sound-arg", "--host 127.0.0.2")
    assert _peers(plans["physics"])["sound"] == ("127.0.0.2", plans["sound"].port)  # was 127.0.0.1: nobody there
    assert _peers(plans["graphics"])["sound"] == ("127.0.0.2", plans["sound"].port)
    assert _peers(plans["sound"])["physics"] == ("127.0.0.1", plans["physics"].port)


def test_ipv4_and_ipv6_services_are_refused_together() -> None:
    with pytest.raises(ValueError, match=r"mix IPv4 and IPv6 \(physics on 127.0.0.1, sound on ::1\)"):
        _plans("--services", "physics,sound", "--sound-arg", "--host ::1")


# --------------------------------------------------------------------------- one kit for every service


@pytest.mark.parametrize(("role", "given"), [("physics", ["--physics-arg", "--kit double_pedal"]),
                                             ("sound", ["--sound-arg=--kit=double_pedal"]),
                                             ("graphics", ["--graphics-arg", "--log-level DEBUG --kit double_pedal"])])
def test_a_kit_for_one_service_is_refused(role: str, given: list[str], no_rig: None,  # noqa: F811
                                          capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(["--no-discovery", "--kit", "default", *given], capsys, 2)
    assert err.startswith(f"batteur rig: error: --{role}-arg: --kit double_pedal ") and "--kit double_pedal" in err
    assert "rig's --kit double_pedal" in err, err


def test_the_kit_folder_is_no_kit() -> None:
    plans = _plans("--graphics-arg", "--kit-dir kits", "--kit", "double_pedal")
    assert {role: rig.option_values(plan.args, "--kit") for role, plan in plans.items()} == {
        role: ["double_pedal"] for role in rig.ROLES}


# --------------------------------------------------------------------------- --kit-dir


def test_kit_dir_is_where_graphics_saves(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # a relative folder: graphics gets it in full
    plans = _plans("--kit-dir", "my-kits")
    assert rig.option_values(plans["graphics"].args, "--kit-dir") == [str(tmp_path / "my-kits")]
    assert all(not rig.option_values(p.args, "--kit-dir") for role, p in plans.items() if role != "graphics")
    assert not _plans()["graphics"].args.count("--kit-dir")  # none given: saving stays off
    assert "--kit-dir" in rig.build_parser().format_help()


def test_kit_dir_without_graphics_is_refused(no_rig: None, tmp_path: Path,  # noqa: F811
                                             capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(["--no-discovery", "--services", "physics,sound", "--kit-dir", str(tmp_path)], capsys, 2)
    assert "--kit-dir needs the graphics service" in err, err


def test_a_kit_dir_graphics_could_not_save_in_is_refused_up_front(no_rig: None, tmp_path: Path,  # noqa: F811
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    a_file = tmp_path / "a-file"
    a_file.write_text("")
    err = refused(["--no-discovery", "--kit-dir", str(a_file / "kits")], capsys, 1)
    assert f"--kit-dir {a_file / 'kits'}: {a_file} is a file, not a directory" in err, err
