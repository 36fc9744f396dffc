"""``batteur rig`` and what its ``--ROLE-arg`` give one service, and the pose editor's ``--kit-dir``.

* A service given its own ``--host`` (``--sound-arg '--host 127.0.0.1'``) listens there (argparse keeps the last
  ``--host``): the rig's allow-list check, its peers and its Hellos take that address. The rig refused ``batteur rig
  --host 0.0.0.0 ... --sound-arg '--host 127.0.0.1'`` as if sound were off loopback, and let a service sent off
  loopback by its ``--ROLE-arg`` without an allow-list start (to exit 2 once the others had started).
* ``--ROLE-arg '--kit X'`` gave that one service another kit than the others (physics striking one kit while sound
  and graphics voiced and drew another): refused, pointing to the rig's ``--kit``.
* ``--kit-dir DIR`` gives graphics the folder its page saves kits and poses into: under the rig saving was off, short
  of ``--graphics-arg='--kit-dir DIR'``.
* Services all on ::1 (``--physics-arg '--host ::1'``) under a rig on 127.0.0.1 were never up: the rig asked them
  from an IPv4 socket, its Hellos lost without a word, until ``--ready-timeout``.
* Abbreviations (``--ki X``, ``--ho 0.0.0.0``), which the services' argparse takes, escaped the ``--kit`` refusal and
  the allow-list check.
* A refusal for want of an allow-list did not say which services lacked one: docs/deployment.md's example, with
  only physics given one, was refused.
* A Hello the rig's asking socket could not send (an address of the other family, an unreachable one) was lost
  without a word: the rig said only "no answer to a Hello" at ``--ready-timeout``. It now says why at once, once a
  service, and at the timeout how many could not be sent.
* A ``--ROLE-arg`` giving what the rig gives that service (``--physics-arg '--port N'``, ``'--score X'``,
  ``--sound-arg '--po N'``, ...) silently overrode it (argparse keeps the last): the rig's peers, readiness checks
  and the other services then talked to a port nobody listened on, or physics played a score the rig never checked
  nor gave the others the kit of. Refused, naming the rig's own option; what the rig does not give, or adds to
  (``--peer``, ``--log-level``), stays allowed.

Tested on the command lines the rig builds (:func:`batteur.rig.plan_services`) or with its process runner replaced:
no service starts; the rig's asking is tested against a Health answerer in the test's process.
"""

from __future__ import annotations

import argparse
import asyncio
import importlib
import io
import os
import re
import shlex
import time
from pathlib import Path

import pytest

from batteur import rig
from common.peers import parse_static_peer
from tests.health_answerer import HealthAnswerer
from tests.ports import free_ports
from tests.test_rig_inputs import no_rig, refused  # noqa: F401 - no_rig is a fixture
from tests.test_rig_ready import health

REPO = Path(__file__).resolve().parents[2]
REAL_RIG = rig.Rig
"""The rig's runner itself (the recorder replaces it in :mod:`batteur.rig`): its asking is what is tested."""

pytestmark = pytest.mark.timeout(60)


class _Recorder:
    """Stands in for :class:`rig.Rig`: records the plans, starts nothing."""

    started: list[rig.ServicePlan] = []
    ready: rig.ReadyWait | None = None

    def __init__(self, plans: list[rig.ServicePlan], *args: object, ready: rig.ReadyWait | None = None,
                 **kwargs: object) -> None:
        _Recorder.started = list(plans)
        _Recorder.ready = ready

    async def run(self, duration_s: float | None) -> int:
        return 0


@pytest.fixture
def recorder(monkeypatch: pytest.MonkeyPatch) -> type[_Recorder]:
    _Recorder.started, _Recorder.ready = [], None
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


# --------------------------------------------------------------------------- asked in the services' address family


def test_services_on_ipv6_are_asked_from_ipv6_under_a_rig_on_ipv4(recorder: type[_Recorder]) -> None:
    # was: the asking socket on 127.0.0.1 sent its Hellos to ::1, lost without a word: "physics not up within
    # --ready-timeout" (a physics answering at once stands in here)
    base = free_ports(4, host="::1")[0]
    argv = ["--host", "127.0.0.1", "--no-discovery", "--services", "physics", "--base-port", str(base),
            "--physics-arg", "--host ::1", "--score", "demo", "--ready-timeout", "20"]
    answerer = HealthAnswerer(bytes.fromhex(health("physics")), host="::1", port=base)
    try:
        assert rig.main(argv) == 0
        assert recorder.ready is not None and [p.host for p in recorder.started] == ["::1"]
        out, err = io.StringIO(), io.StringIO()
        asker = REAL_RIG(recorder.started, 1.0, out=out, err=err)
        asyncio.run(asker._wait_ready(recorder.ready, time.monotonic()))
    finally:
        answerer.close()
    assert not asker.gave_up, err.getvalue()
    assert "batteur rig: services up" in out.getvalue(), out.getvalue() + err.getvalue()


def test_the_asking_address_is_the_rigs_own_without_a_host_of_their_own() -> None:
    assert rig.asking_host(list(_plans("--host", "0.0.0.0").values())) == "127.0.0.1"
    assert rig.asking_host(list(_plans("--host", "::").values())) == "::1"
    assert rig.asking_host(list(_plans("--host", "localhost").values())) == "localhost"
    assert rig.asking_host(list(_plans("--host", "localhost", "--services", "physics",
                                       "--physics-arg", "--host ::1").values())) == "::1"


@pytest.mark.parametrize(("asking", "address", "why"), [
    # each fails in the kernel before any packet leaves, the address being loopback all the same: an IPv6 address
    # from an IPv4 socket (getaddrinfo refuses it), an IPv4-mapped one from a socket bound to ::1 (no route)
    ("127.0.0.1", "::1", "(EAI_ADDRFAMILY)"),
    ("::1", "::ffff:127.0.0.1", "Network is unreachable (ENETUNREACH)"),
])
def test_a_hello_the_rig_cannot_send_is_said_at_once_and_once(
        asking: str, address: str, why: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rig, "READY_POLL_S", 0.05)  # many Hellos, one line
    sound = HealthAnswerer(bytes.fromhex(health("sound")), host=asking)
    physics = free_ports(1)[0]
    plans = [rig.ServicePlan("physics", physics, ["--host", address]),
             rig.ServicePlan("sound", sound.port, ["--host", asking])]
    out, err = io.StringIO(), io.StringIO()
    asker = REAL_RIG(plans, 1.0, out=out, err=err)
    try:
        asyncio.run(asker._wait_ready(rig.ReadyWait(2.0, asking, time.time(), 1.0), time.monotonic()))
    finally:
        sound.close()
    lines = err.getvalue().splitlines()
    where = f"[{address}]:{physics}"
    warned = [line for line in lines if "warning" in line]
    assert len(warned) == 1 and why in warned[0], lines  # was: nothing until the timeout
    assert warned[0].startswith(f"batteur rig: warning: cannot send physics a Hello at {where}: "), lines
    assert asker.gave_up, lines
    assert lines[-1].startswith("batteur rig: error: physics not up within --ready-timeout 2 s"), lines
    sent = re.search(rf"the (\d+) Hellos to physics at {re.escape(where)} could not be sent: [^;]*{re.escape(why)}",
                     lines[-1])
    assert sent is not None and int(sent.group(1)) >= 2, lines  # sound's answer made the rig send again at least


# --------------------------------------------------------------------------- abbreviations, as the services take them


@pytest.mark.parametrize(("role", "given", "name"), [
    ("physics", ["--physics-arg=--ki double_pedal"], "--ki"),
    ("sound", ["--sound-arg=--k=double_pedal"], "--k"),
    ("interaction", ["--interaction-arg=--log-level INFO --ki=double_pedal"], "--ki"),
])
def test_an_abbreviated_kit_for_one_service_is_refused(
        role: str, given: list[str], name: str, no_rig: None,  # noqa: F811
        capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(["--no-discovery", "--kit", "default", *given], capsys, 2)  # was started, on double_pedal
    assert err.startswith(f"batteur rig: error: --{role}-arg: {name} (--kit, as argparse takes it abbreviated) "
                          "double_pedal "), err
    assert "rig's --kit double_pedal" in err, err


@pytest.mark.parametrize("own", [["--sound-arg=--ho 0.0.0.0"], ["--sound-arg=--hos=0.0.0.0"]])
def test_an_abbreviated_host_off_loopback_needs_an_allow_list(
        own: list[str], no_rig: None, monkeypatch: pytest.MonkeyPatch,  # noqa: F811
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("BATTEUR_ALLOW", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    err = refused(["--no-discovery", "--services", "physics,sound", *own], capsys, 2)  # was started, to exit 2
    assert "--sound-arg --host 0.0.0.0: host 0.0.0.0 listens off loopback" in err, err


def test_an_abbreviated_host_and_allow_list_are_read() -> None:
    plans = _plans("--services", "physics,sound", "--sound-arg", "--ho 127.0.0.2 --al 10.0.0.0/8")
    assert plans["sound"].host == "127.0.0.2"
    assert _peers(plans["physics"])["sound"] == ("127.0.0.2", plans["sound"].port)
    plans = _plans("--services", "physics,sound", "--sound-arg", "--ho 0.0.0.0 --al 10.0.0.0/8")
    rig.check_allow(list(plans.values()), "127.0.0.1", environ={})  # its own allow-list, abbreviated: accepted


def _service_parser(role: str) -> argparse.ArgumentParser:
    """The command-line parser ``batteur ROLE`` reads (common.runtime.build_parser with the service's settings)."""
    from common.runtime import build_parser

    settings = {"physics": "PhysicsNodeSettings", "interaction": "InteractionSettings",
                "sound": "SoundNodeSettings", "graphics": "GraphicsNodeSettings"}[role]
    return build_parser(role, settings_cls=getattr(importlib.import_module(f"services.{role}.node"), settings))


@pytest.mark.parametrize("role", rig.ROLES)
def test_the_rig_reads_every_abbreviation_a_service_takes(role: str, capsys: pytest.CaptureFixture[str]) -> None:
    # each prefix of each option the rig reads, as the service's own parser takes it: one the service takes as the
    # option the rig must read as it (--ho, --ki escaped it); one the rig reads as it, the service takes or refuses
    parser = _service_parser(role)
    for flag in rig.ABBREVIATIONS:
        if flag not in parser._option_string_actions:  # another service's (--score: physics'), refused by this one
            assert flag not in ("--host", "--kit", "--allow", "--config", "--port", "--epoch", "--role"), flag
            continue
        dest = parser._option_string_actions[flag].dest
        for end in range(3, len(flag) + 1):
            for argv in ([flag[:end], "VALUE"], [f"{flag[:end]}=VALUE"]):
                try:
                    known, _ = parser.parse_known_args(argv)
                    verdict = "taken" if getattr(known, dest, None) in ("VALUE", ["VALUE"]) else "not taken"
                except SystemExit:  # ambiguous: refused
                    verdict = "refused"
                read = rig.option_values(argv, flag) == ["VALUE"]
                assert verdict == "refused" or read == (verdict == "taken"), (role, argv, verdict, read)
    capsys.readouterr()


def test_every_option_the_rig_refuses_is_read_abbreviated() -> None:
    # an option the rig refuses that it did not read abbreviated would escape the refusal as --ki X did
    assert set(rig.RIG_GIVES) <= set(rig.ABBREVIATIONS)


# --------------------------------------------------------------------------- what the rig gives a service itself

SCORE = REPO / "tests" / "render" / "short_groove.txt"


@pytest.mark.parametrize(("role", "given", "written", "instead"), [
    ("physics", ["--physics-arg", "--port 9999"], "--port 9999", "use batteur rig --base-port"),
    ("sound", ["--sound-arg=--po=9999"], "--po (--port, as argparse takes it abbreviated) 9999",
     "use batteur rig --base-port"),
    ("interaction", ["--interaction-arg", "--log-level INFO --epoch 5"], "--epoch 5", "use batteur rig --start-delay"),
    ("graphics", ["--graphics-arg=--e=5"], "--e (--epoch, as argparse takes it abbreviated) 5",
     "use batteur rig --start-delay"),
    ("physics", ["--physics-arg", "--ro sound"], "--ro (--role, as argparse takes it abbreviated) sound",
     "use batteur rig --services"),
    ("physics", ["--physics-arg", f"--score {SCORE}"], f"--score {SCORE}", f"use batteur rig --score {SCORE}"),
    ("physics", ["--score", str(SCORE), "--physics-arg", "--score demo"], "--score demo",
     "use batteur rig --score demo"),
    ("physics", ["--score", str(SCORE), "--physics-arg=--pl=3"],
     "--pl (--play-at, as argparse takes it abbreviated) 3", "use batteur rig --play-at 3"),
    ("graphics", ["--graphics-arg", "--ht 9000"], "--ht (--http-port, as argparse takes it abbreviated) 9000",
     "use batteur rig --http-port 9000"),
    ("sound", ["--record", "take", "--sound-arg", "--wav other.wav"], "--wav other.wav",
     "use batteur rig --record DIR alone"),
    ("graphics", ["--kit-dir", "kits", "--graphics-arg", "--kit-d other"],
     "--kit-d (--kit-dir, as argparse takes it abbreviated) other", "give batteur rig --kit-dir alone"),
    ("physics", ["--strike-period", "1", "--physics-arg", "--strike-velocity 5"], "--strike-velocity 5",
     "use batteur rig --strike-velocity 5"),
    ("physics", ["--strike-period", "1", "--physics-arg", "--scene drummer"], "--scene drummer",
     "use batteur rig --strike-period alone"),
])
def test_what_the_rig_gives_a_service_is_refused_in_its_role_arg(
        role: str, given: list[str], written: str, instead: str, no_rig: None, tmp_path: Path,  # noqa: F811
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)  # --record take, --kit-dir kits: nothing is created, the refusal comes first
    err = refused(["--no-discovery", *given], capsys, 2)  # was started, the service's own winning (the last)
    assert err.startswith(f"batteur rig: error: --{role}-arg: {written} would "), err
    assert instead in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("given", "role", "flag", "value"), [
    (["--interaction-arg", "--peer sound=127.0.0.1:9203"], "interaction", "--peer", "sound=127.0.0.1:9203"),
    (["--sound-arg", "--log-level DEBUG"], "sound", "--log-level", "DEBUG"),
    (["--graphics-arg", "--node-id view"], "graphics", "--node-id", "view"),
    (["--physics-arg", "--score-dir scores"], "physics", "--score-dir", "scores"),
    (["--physics-arg", "--play-at 3"], "physics", "--play-at", "3"),  # no --score: the rig gives none
    (["--sound-arg", "--wav take.wav"], "sound", "--wav", "take.wav"),  # no --record
    (["--graphics-arg", "--kit-dir kits"], "graphics", "--kit-dir", "kits"),  # no --kit-dir
    (["--physics-arg", "--scene strike --strike-period 0.5"], "physics", "--strike-period", "0.5"),
])
def test_what_the_rig_does_not_give_a_service_stays_allowed(given: list[str], role: str, flag: str,
                                                            value: str) -> None:
    plans = _plans(*given)
    assert rig.option_values(plans[role].args, flag)[-1] == value
    assert all(value not in plan.args for other, plan in plans.items() if other != role)


def test_a_role_arg_value_with_a_space_is_given_whole_when_quoted() -> None:
    # until 7 Dec split on spaces: the path came to sound as "'/tmp/a" and "b/p.yaml'"
    plans = _plans("--sound-arg", "--sound-params '/tmp/a b/p.yaml' --log-level DEBUG")
    assert rig.option_values(plans["sound"].args, "--sound-params") == ["/tmp/a b/p.yaml"]
    assert rig.option_values(plans["sound"].args, "--log-level")[-1] == "DEBUG"


def test_a_role_arg_with_an_unclosed_quote_is_refused(
        no_rig: None, capsys: pytest.CaptureFixture[str]) -> None:  # noqa: F811
    err = refused(["--no-discovery", "--sound-arg", "--wav 'a b.wav"], capsys, 2)
    assert err.startswith("batteur rig: error: --sound-arg \"--wav 'a b.wav\": no closing quotation"), err


# --------------------------------------------------------------------------- the services an allow-list is missing for


def test_the_refusal_names_the_services_without_an_allow_list(
        no_rig: None, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:  # noqa: F811
    monkeypatch.delenv("BATTEUR_ALLOW", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    err = refused(["--host", "0.0.0.0", "--no-discovery", "--physics-arg", "--allow 192.168.1.0/24",
                   "--sound-arg", "--host 127.0.0.1"], capsys, 2)
    assert err.startswith("batteur rig: error: interaction, graphics without an allow-list: host 0.0.0.0 listens "
                          "off loopback"), err
    assert "--allow in --interaction-arg and --graphics-arg" in err, err


def test_the_deployment_docs_example_is_accepted(recorder: type[_Recorder]) -> None:
    # docs/deployment.md gave one the rig refused (interaction and graphics on 0.0.0.0 without an allow-list)
    text = " ".join((REPO / "docs" / "deployment.md").read_text(encoding="utf-8").split())
    example = re.search(r"`batteur rig --host 0\.0\.0\.0 [^`]*--sound-arg '--host 127\.0\.0\.1'`", text)
    assert example is not None
    argv = shlex.split(example.group(0).strip("`"))[2:]
    assert rig.main([*argv, "--no-discovery"]) == 0
    plans = {p.role: p for p in recorder.started}
    assert plans["sound"].host == "127.0.0.1" and plans["physics"].host == "0.0.0.0"
