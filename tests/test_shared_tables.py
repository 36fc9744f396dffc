"""Two tables each kept once: a service's refusal message (``common.transport.service_refusal``), sent for a control
it could not decode (``decode_refusal``) and for another service's control at its node (``common.runtime.
wrong_node_refusal``); and how a config file's settings for one node are read (``common.config.file_settings``),
by the node (``load_settings``) and by ``batteur rig`` for the peers each node will hold (``node_peer_roles``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur.rig import node_peer_roles
from common.config import load_settings
from common.messages import REGISTRY, Family
from common.runtime import wrong_node_refusal
from common.transport import REFUSAL_ENDINGS, SERVICE_ROLES, decode_refusal, owner_role


@pytest.mark.parametrize("role", sorted(SERVICE_ROLES))
def test_a_service_refuses_with_the_same_message_either_way(role: str) -> None:
    address = next(model.ADDRESS for model in REGISTRY if model.FAMILY is Family.CONTROL
                   and owner_role(model.ADDRESS) == role and not model.ADDRESS.endswith(REFUSAL_ENDINGS))
    undecoded = decode_refusal(address, "wrong_arity", role=role)
    wrong_node = wrong_node_refusal(role, address, "wrong_arity")
    assert undecoded is not None and type(undecoded) is type(wrong_node)
    assert undecoded.model_dump() == wrong_node.model_dump()  # no instrument named here: the same fields


RIG_FILE = """peers = ["sound=127.0.0.1:9000"]

[physics]
peers = ["interaction=127.0.0.1:9002", "graphics=127.0.0.1:9003"]

[graphics]
log-level = "DEBUG"
"""


@pytest.mark.parametrize(("role", "env_role"), [("physics", None), ("sound", None), ("graphics", None),
                                                ("sound", "physics")])
def test_the_rig_reads_a_nodes_peers_from_its_config_file_as_the_node_does(
        role: str, env_role: str | None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "rig.toml"
    config.write_text(RIG_FILE)
    monkeypatch.delenv("BATTEUR_PEERS", raising=False)
    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    if env_role is None:
        monkeypatch.delenv("BATTEUR_ROLE", raising=False)
    else:
        monkeypatch.setenv("BATTEUR_ROLE", env_role)
    settings = load_settings({"discovery": False}, config, {"role": role})
    node = {peer.role for peer in settings.static_peers}
    assert node_peer_roles([], ["--config", str(config)], role) == node
    assert node  # a file that gives this node peers
