"""``batteur rig``'s ``--absent ROLE`` and the peers a node holds from its environment or config file.

The rig tells a service a role it did not start is absent (no "no graphics peer known" every minute) only where no
node of it can be expected, and no static peer of it is given. Until 7 Dec only a ``--peer`` in the
service's ``--ROLE-arg`` counted: a graphics peer given by ``BATTEUR_PEERS`` or the node's config file, which the node
sends to, was told absent all the same (its messages counted as unroutable, unsaid). The rig now resolves the peers
as the node's settings do (flags, else ``BATTEUR_PEERS``, else the config file; a list replaces the one below it;
since 8 Dec the rig adds ``BATTEUR_PEERS`` to the ``--peer`` it gives, which would replace it), and each case is
checked against the settings the interaction node itself would run with (``--show-settings``)."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

from batteur.errors import UsageError
from batteur.rig import build_parser, left_out_environment_peers, node_peer_roles, option_values, plan_rig

GRAPHICS = "graphics=127.0.0.1:9104"


def _absent(argv: list[str], environ: dict[str, str]) -> dict[str, list[str]]:
    plans = plan_rig(build_parser().parse_args(argv), epoch=0.0, environ=environ)
    return {p.role: [p.args[i + 1] for i, a in enumerate(p.args) if a == "--absent"] for p in plans}


def _node_settings(argv: list[str], environ: dict[str, str], monkeypatch: pytest.MonkeyPatch,
                   capsys: pytest.CaptureFixture[str]) -> dict[str, object]:
    """The settings the rig's interaction service would run with, in ``environ``."""
    from batteur import cli

    plans = plan_rig(build_parser().parse_args(argv), epoch=0.0, environ=environ)
    plan = next(p for p in plans if p.role == "interaction")
    for name, value in environ.items():
        monkeypatch.setenv(name, value)
    module = importlib.import_module(cli.COMMANDS["interaction"][0])
    capsys.readouterr()
    assert module.main([*plan.args, "--show-settings"]) == 0
    settings: dict[str, object] = json.loads(capsys.readouterr().out)
    return settings


def _config(tmp_path: Path, text: str) -> str:
    path = tmp_path / "rig.yaml"
    path.write_text(text, encoding="utf-8")
    return str(path)


def test_a_peer_in_batteur_peers_is_not_told_absent(monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("BATTEUR_PEERS", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    argv = ["--services", "interaction", "--no-discovery"]
    assert _absent(argv, {}) == {"interaction": ["physics", "sound", "graphics"]}
    env = {"BATTEUR_PEERS": GRAPHICS}
    assert _absent(argv, env) == {"interaction": ["physics", "sound"]}  # was told graphics too
    settings = _node_settings(argv, env, monkeypatch, capsys)
    assert settings["peers"] == [GRAPHICS] and settings["absent"] == ["physics", "sound"]


def test_a_peer_in_the_node_config_file_is_not_told_absent(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("BATTEUR_PEERS", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    role_table = _config(tmp_path, f"interaction:\n  peers: [\"{GRAPHICS}\"]\n")
    argv = ["--services", "interaction", "--no-discovery", f"--interaction-arg=--config {role_table}"]
    assert _absent(argv, {}) == {"interaction": ["physics", "sound"]}
    settings = _node_settings(argv, {}, monkeypatch, capsys)
    assert settings["peers"] == [GRAPHICS] and settings["absent"] == ["physics", "sound"]
    # BATTEUR_CONFIG, a top-level list (a comma-separated string is one too), for the rig's every service
    shared = _config(tmp_path, f"peers: \"{GRAPHICS},sound=127.0.0.1:9103\"\n")
    argv = ["--services", "interaction", "--no-discovery"]
    assert _absent(argv, {"BATTEUR_CONFIG": shared}) == {"interaction": ["physics"]}
    # the environment's list wins over the file's, and replaces it (pydantic-settings' precedence)
    assert _absent(argv, {"BATTEUR_CONFIG": shared, "BATTEUR_PEERS": "sound=127.0.0.1:9103"}) == {
        "interaction": ["physics", "graphics"]}


def test_the_environment_s_peers_add_to_the_rig_s(monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """``BATTEUR_PEERS`` adds to the ``--peer`` the rig gives its services: the node holds both, and graphics is not
    told absent. Until 8 Dec the rig's own static peers (a flag, which replaces the environment's list in a node's
    settings) dropped it: each node held no graphics peer, a remote sound or physics named there was never sent to,
    and the rig said graphics was absent."""
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    env = {"BATTEUR_PEERS": GRAPHICS}
    static = ["--services", "physics,interaction,sound", "--no-discovery"]
    assert _absent(static, env) == {"physics": [], "interaction": [], "sound": []}  # was graphics for each
    settings = _node_settings(static, env, monkeypatch, capsys)
    assert settings["peers"] == ["physics=127.0.0.1:9101", "sound=127.0.0.1:9103", GRAPHICS]  # was without graphics
    found = ["--services", "physics,interaction,sound", "--no-static-peers"]
    assert _absent(found, env) == {"physics": [], "interaction": [], "sound": []}
    # with --no-static-peers and no --ROLE-arg peer the node reads BATTEUR_PEERS itself: nothing added
    plans = plan_rig(build_parser().parse_args(found), epoch=0.0, environ=env)
    assert all("--peer" not in plan.args for plan in plans)


def test_a_peer_the_rig_gives_already_is_not_given_twice_and_a_bad_one_is_refused() -> None:
    env = {"BATTEUR_PEERS": f"sound=127.0.0.1:9103, {GRAPHICS}"}
    plans = plan_rig(build_parser().parse_args(["--services", "physics,sound", "--no-discovery"]), epoch=0.0,
                     environ=env)
    physics = next(plan for plan in plans if plan.role == "physics")
    assert [physics.args[i + 1] for i, a in enumerate(physics.args) if a == "--peer"] == [
        "sound=127.0.0.1:9103", GRAPHICS]
    # a peer no node would take: said at once, naming the variable (the nodes ignored it while the rig's --peer
    # replaced it, and would now each refuse it)
    with pytest.raises(UsageError, match=r"BATTEUR_PEERS=graphics: peer 'graphics': expected ROLE=HOST:PORT"):
        plan_rig(build_parser().parse_args(["--services", "physics,sound"]), epoch=0.0,
                 environ={"BATTEUR_PEERS": "graphics"})


def test_a_peer_of_a_role_the_rig_starts_is_left_out_and_said(monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``BATTEUR_PEERS`` naming a role the rig starts itself is left out of the peers the rig gives, and said once.
    Until the day after 8 Dec it was added beside the rig's own: interaction, sound and graphics held two physics
    peers, physics one of its own role, and the lowest node id (the remote or dead physics) was their clock master.
    A role the rig does not start (sound on a second laptop) is still added."""
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    env = {"BATTEUR_PEERS": "physics=10.0.0.5:9101,sound=127.0.0.1:9200"}
    argv = ["--services", "physics,interaction,sound,graphics"]
    plans = plan_rig(build_parser().parse_args(argv), epoch=0.0, environ=env)
    peers = {plan.role: option_values(plan.args, "--peer") for plan in plans}
    assert [spec for spec in peers["sound"] if spec.startswith("physics=")] == ["physics=127.0.0.1:9101"]
    for role, specs in peers.items():  # each holds the rig's one peer of every other role, none of its own
        assert sorted(spec.split("=")[0] for spec in specs) == sorted(set(peers) - {role}), (role, specs)
    assert not {"physics=10.0.0.5:9101", "sound=127.0.0.1:9200"} & {s for specs in peers.values() for s in specs}
    settings = _node_settings(argv, env, monkeypatch, capsys)  # what the interaction node runs with
    assert settings["peers"] == ["physics=127.0.0.1:9101", "sound=127.0.0.1:9103", GRAPHICS]
    said = left_out_environment_peers(plans, env)
    assert said is not None and said.startswith("BATTEUR_PEERS: physics=10.0.0.5:9101, sound=127.0.0.1:9200 left "
                                                 "out of the peers the rig gives its services: this rig starts "
                                                 "physics at 127.0.0.1:9101, sound at 127.0.0.1:9103 itself"), said
    # sound on another machine: the rig does not start it, so its peer is added; physics' still left out
    argv = ["--services", "physics,interaction,graphics", "--no-discovery"]
    plans = plan_rig(build_parser().parse_args(argv), epoch=0.0, environ=env)
    assert {plan.role: option_values(plan.args, "--peer") for plan in plans}["interaction"] == [
        "physics=127.0.0.1:9101", GRAPHICS, "sound=127.0.0.1:9200"]
    said = left_out_environment_peers(plans, env)
    assert said is not None and said.startswith("BATTEUR_PEERS: physics=10.0.0.5:9101 left out"), said
    # nothing left out (the rig's own address, a role it does not start): nothing said
    env = {"BATTEUR_PEERS": f"physics=127.0.0.1:9101,{GRAPHICS}"}
    plans = plan_rig(build_parser().parse_args(["--services", "physics,sound"]), epoch=0.0, environ=env)
    assert left_out_environment_peers(plans, env) is None


def test_peers_the_node_would_refuse_count_as_none(tmp_path: Path) -> None:
    """A file that is no config file or a peer that is no ROLE=HOST:PORT: the node refuses them and says so; the rig
    counts no peer from them (it never fails on them itself)."""
    assert node_peer_roles([], ["--config", str(tmp_path / "missing.yaml")], "interaction", {}) == set()
    assert node_peer_roles([], [], "interaction", {"BATTEUR_PEERS": "graphics"}) == set()
    assert node_peer_roles([], [], "interaction", {"BATTEUR_PEERS": ""}) == set()  # empty: not set
    assert node_peer_roles([GRAPHICS], [], "interaction", {"BATTEUR_PEERS": "sound=127.0.0.1:9103"}) == {"graphics"}
