"""A route or registered message to a host without its port (``route/set 127.0.0.1 *``) is refused saying the port
is missing. Before, the host was read as a role name: the error said no '127.0.0.1' node could be reached and
suggested ``--peer 127.0.0.1=HOST:PORT``; and where the node does not check roles (offline), the route was taken,
to a role no node ever plays."""

from __future__ import annotations

from collections.abc import Callable, Collection

import pytest

from common.core import Outgoing
from common.kit import load_kit
from common.messages import OscMessage
from common.messages.interaction import InteractionError, MapSet, MessageAdd, RouteSet
from services.interaction.core import InteractionCore

pytestmark = pytest.mark.timeout(60)

KIT = load_kit("default")
ROLES = {"physics", "interaction", "sound", "graphics"}


def _errors(out: list[Outgoing]) -> list[str]:
    return [o.message.detail for o in out if isinstance(o.message, InteractionError)]


def _requests(to: str) -> list[OscMessage]:
    return [RouteSet(to=to, instruments="*"), MapSet(to=to, field="velocity", spec="velocity"),
            MessageAdd(name="hit", to=to, address="/synth/hit", instruments="*", when="onset", specs=("velocity",))]


@pytest.mark.parametrize("reachable", [lambda: ROLES, None], ids=["node", "offline"])
@pytest.mark.parametrize("host", ["127.0.0.1", "192.168.1.20", "synth.local", "localhost", "Studio-Mac"])
def test_a_host_without_a_port_is_refused_saying_the_port_is_missing(
        host: str, reachable: Callable[[], Collection[str]] | None) -> None:
    core = InteractionCore(kit=KIT)
    core.reachable_roles = reachable
    routes = list(core.config.routes)
    for request in _requests(host):
        (detail,) = _errors(core.handle(request, 0.0, "127.0.0.1:57120"))
        assert "no port" in detail and f"{host}:PORT" in detail, detail
        assert "--peer" not in detail and "node can be reached" not in detail, detail
    assert core.config.routes == routes and core.config.messages == []


@pytest.mark.parametrize("to", ["127.0.0.1:57120", "[::1]:57120", "sound", "localhost:9000"])
def test_a_host_port_or_a_reachable_role_is_still_taken(to: str) -> None:
    core = InteractionCore(kit=KIT)
    core.reachable_roles = lambda: ROLES
    for request in _requests(to):
        assert core.handle(request, 0.0, "127.0.0.1:57120") == []
    assert any(r.to == to for r in core.config.routes) and core.config.messages[0].to == to


def test_a_role_no_node_of_which_is_reachable_still_suggests_a_peer() -> None:
    core = InteractionCore(kit=KIT)
    core.reachable_roles = lambda: ROLES
    (detail,) = _errors(core.handle(RouteSet(to="mysynth", instruments="*"), 0.0, "127.0.0.1:57120"))
    assert "--peer mysynth=HOST:PORT" in detail and "no port" not in detail
