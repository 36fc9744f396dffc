"""Registered messages an OSC walkthrough got through that it should not have: a constant no OSC float carries
(``=1e400``, ``=nan``) was taken and sent as the string '1e400'; a type written as a curve field
(``velocity:linear:0:10:0:127:i``) was answered "could not convert string to float: 'i'"; and a message to a role
no node of which the interaction node can ever reach (``nosuchrole``) was taken without a word."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import pytest

from common.core import Outgoing
from common.kit import load_kit
from common.messages.interaction import InteractionError, MapSet, MessageAdd, RouteSet
from common.runtime import Node
from services.interaction.config import InteractionConfig
from services.interaction.core import InteractionCore
from services.interaction.mapping import ArgSpec
from services.interaction.node import InteractionSettings, _setup, reachable_roles

pytestmark = pytest.mark.timeout(60)

KIT = load_kit("default")


def _add(*specs: str, to: str = "127.0.0.1:9999", name: str = "n") -> MessageAdd:
    return MessageAdd(name=name, to=to, address="/x", instruments="*", when="onset", specs=specs)


def _errors(out: list[Outgoing]) -> list[str]:
    return [o.message.detail for o in out if isinstance(o.message, InteractionError)]


@pytest.mark.parametrize("constant", ["=1e400", "=nan", "=inf", "=-inf"])
def test_a_constant_no_osc_float_carries_is_refused_not_sent_as_a_string(constant: str) -> None:
    core = InteractionCore(kit=KIT)
    (detail,) = _errors(core.handle(_add(constant), 0.0, "127.0.0.1:5"))
    assert f"constant {constant[1:]!r} is not a finite number" in detail and f"{constant}@s" in detail
    assert core.config.messages == [] and core.rejected_total == 1
    assert _errors(core.handle(MapSet(to="sound", field="velocity", spec=constant), 0.0, "127.0.0.1:5"))


def test_such_a_constant_is_still_a_string_when_asked_for_one() -> None:
    core = InteractionCore(kit=KIT)
    assert core.handle(_add("=nan@s", "=1e400@s"), 0.0, "127.0.0.1:5") == []
    assert [a.value for a in core.config.messages[0].args] == ["nan", "1e400"]
    assert [a.to_spec() for a in core.config.messages[0].args] == ["=nan@s", "=1e400@s"]  # listed as re-addable


def test_a_number_sent_as_a_string_stays_the_text_written() -> None:
    """``=1e39@s`` became the float 1e39 (``=1e400@s`` stayed text): ``@s`` sends the text as written."""
    assert [ArgSpec.parse(spec).value for spec in ("=1e39@s", "=5@s", "=0.25@s")] == ["1e39", "5", "0.25"]
    assert ArgSpec.parse("=5@i").value == 5


def test_a_type_written_as_a_curve_field_is_told_its_at_form() -> None:
    core = InteractionCore(kit=KIT)
    (detail,) = _errors(core.handle(_add("instrument", "velocity:linear:0:10:0:127:i"), 0.0, "127.0.0.1:5"))
    assert "could not convert" not in detail
    assert "the OSC type is written after @" in detail and "'velocity:linear:0:10:0:127@i'" in detail
    with pytest.raises(ValueError, match="'velocity@f'"):
        ArgSpec.parse("velocity:f")


def test_a_curve_value_that_is_no_number_is_named() -> None:
    with pytest.raises(ValueError, match=r"linear's value 2, 'ten', is not a number"):
        ArgSpec.parse("velocity:linear:0:ten:0:127")


def test_a_role_the_node_cannot_reach_is_refused_a_host_port_or_a_reachable_role_is_taken() -> None:
    core = InteractionCore(kit=KIT)
    core.reachable_roles = lambda: {"sound", "graphics", "pd"}
    (detail,) = _errors(core.handle(_add("velocity", to="nosuchrole"), 0.0, "127.0.0.1:5"))
    assert "no 'nosuchrole' node can be reached" in detail and "--peer nosuchrole=HOST:PORT" in detail
    assert "graphics, pd, sound" in detail
    assert _errors(core.handle(RouteSet(to="nosuchrole", instruments="*"), 0.0, "127.0.0.1:5"))
    assert _errors(core.handle(MapSet(to="nosuchrole", field="velocity", spec="velocity"), 0.0, "127.0.0.1:5"))
    assert core.config.messages == [] and all(r.to != "nosuchrole" for r in core.config.routes)
    assert core.rejected_total == 3
    assert core.handle(_add("velocity", to="pd", name="a"), 0.0, "127.0.0.1:5") == []
    assert core.handle(_add("velocity", to="127.0.0.1:9999", name="b"), 0.0, "127.0.0.1:5") == []
    (detail,) = _errors(core.handle(_add("velocity", to="reply"), 0.0, "127.0.0.1:5"))
    assert "'reply' is not a target" in detail  # the documented reason, not "cannot be reached"


class _NoDiscovery:
    """Discovery that finds nothing and announces nothing."""

    def __init__(self, **kwargs: Any) -> None:
        pass

    async def start(self) -> None:
        pass

    async def stop(self) -> None:
        pass


@pytest.mark.parametrize("discovery", [False, True])
def test_the_node_reaches_its_peers_roles_and_with_discovery_the_roles_it_browses(tmp_path: Path,
                                                                                  discovery: bool) -> None:
    async def scenario() -> None:
        settings = InteractionSettings(role="interaction", discovery=discovery, oscquery=False, clock_master="self",
                                       peers=["pd=127.0.0.1:9"], interaction_config="none")
        core = InteractionCore(kit=KIT, config=InteractionConfig())
        node = Node(core, settings, discovery_factory=_NoDiscovery)
        await node.start()
        try:
            _setup(node)
            expected = {"pd", "physics", "interaction", "sound", "graphics"} if discovery else {"pd"}
            assert reachable_roles(node) == expected
            assert core.reachable_roles is not None and set(core.reachable_roles()) == expected
            out = core.handle(_add("velocity", to="sound"), 0.0, "127.0.0.1:5")
            assert bool(_errors(out)) is not discovery  # no sound peer, and discovery off: never reached
        finally:
            await node.stop()

    asyncio.run(scenario())
