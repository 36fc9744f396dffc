"""A physics node that falls behind has its drummer's targets trail the rig clock (``PhysicsCore.target_lag``,
docs/physics.md "Time and determinism"); its Health reports that lag (seconds) and the jumps back
(``target_jumps``), so ``batteur ls --json`` shows a late drummer, not only its ``late`` notes (since 7 Dec not
the skipped steps).
The fields are appended (a positional reader finds the earlier ones unmoved); other nodes send 0, and a Health from
an older node, without them, still decodes.

Nodes run in-process on loopback (no discovery, no OSCQuery).
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator

import pytest

from batteur.tools import ls
from common.messages import Health, decode
from common.messages.base import MessageError
from common.messages.codec import encode_raw
from services.physics.core import PhysicsCore
from tests.health_answerer import HealthAnswerer
from tests.null_core import NullCore
from tests.test_health_unanswered import health_after

pytestmark = pytest.mark.timeout(120)

HEALTH = Health(node_id="fake-1", role="physics", protocol=1, time=1.5, rate_hz=990.0, target_rate_hz=1000.0,
                overruns=4, messages_in=1, messages_out=1, dropped=0, dropped_malformed=0, dropped_unknown=0,
                dropped_type=0, dropped_range=0, dropped_other=0, late=350, peers=3, decode_unanswered=0,
                replies_unanswered=0, target_lag=0.125, target_jumps=2)


def test_the_physics_node_reports_how_far_its_targets_trail_the_rig_clock() -> None:
    core = PhysicsCore(scene="strike")
    try:
        core.target_lag, core.target_jumps = 0.25, 3  # as a live drummer core that fell behind leaves them
        health, _ = asyncio.run(health_after(core, "physics", []))
    finally:
        core.close()
    assert (health.target_lag, health.target_jumps) == (0.25, 3)


def test_other_nodes_report_no_target_lag() -> None:
    health, _ = asyncio.run(health_after(NullCore(), "sound", []))
    assert (health.target_lag, health.target_jumps, health.skipped_steps) == (0.0, 0, 0)


def test_the_physics_node_reports_the_steps_it_skipped() -> None:
    """Health's ``skipped_steps`` (appended 8 Dec; ``batteur ls``'s column skipped): until then only the "behind
    real time" warnings in physics' log counted them."""
    core = PhysicsCore(scene="strike")
    try:
        core.skipped_steps = 4321  # as a live core whose loop fell behind leaves it
        health, _ = asyncio.run(health_after(core, "physics", []))
    finally:
        core.close()
    assert health.skipped_steps == 4321


def test_the_fields_are_appended_and_an_older_nodes_health_still_decodes() -> None:
    names = [f.name for f in Health.wire_fields()]
    after_peers = names[names.index("peers"):][:5]  # fields appended since (unroutable) come after these
    assert after_peers == ["peers", "decode_unanswered", "replies_unanswered", "target_lag", "target_jumps"]
    args = HEALTH.to_args()
    assert Health.from_args(args) == HEALTH
    args = args[:len(args) - (len(names) - names.index("target_jumps") - 1)]  # a Health up to target_jumps
    for appended in (2, 4):  # the previous session's Health (without the lag), and the one before it
        older = decode(encode_raw(Health.ADDRESS, args[:-appended])).messages
        assert older == [HEALTH.model_copy(update={"decode_unanswered": 0, "replies_unanswered": 0,
                                                   "target_lag": 0.0, "target_jumps": 0}
                                           if appended == 4 else {"target_lag": 0.0, "target_jumps": 0})]
    with pytest.raises(MessageError):  # short of a field every version has: still refused
        Health.from_args(args[:-5])


@pytest.fixture(params=["this", "older"])
def answerer(request: pytest.FixtureRequest) -> Iterator[tuple[HealthAnswerer, tuple[float, int]]]:
    """A node answering with this version's Health (a lag of 125 ms, 2 jumps) or an older node's (no lag fields)."""
    args = HEALTH.to_args()
    older = request.param == "older"
    since_lag = len(Health.wire_fields()) - [f.name for f in Health.wire_fields()].index("target_lag")
    node = HealthAnswerer(encode_raw(Health.ADDRESS, args[:-since_lag] if older else args))
    yield node, ((0.0, 0) if older else (0.125, 2))
    node.close()


def test_ls_json_shows_the_physics_nodes_target_lag(answerer: tuple[HealthAnswerer, tuple[float, int]],
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    node, (lag, jumps) = answerer
    assert ls.main(["--node", f"127.0.0.1:{node.port}", "--timeout", "3", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert (row["status"], row["target_lag"], row["target_jumps"], row["late"]) == ("ok", lag, jumps, 350)


def test_a_newer_nodes_longer_health_decodes_without_its_new_fields() -> None:
    """Fields appended after these (a node updated before this reader) are ignored, not a wrong arity: an older
    ``batteur ls`` had dropped the 22-argument Health of a node with ``target_lag`` and said "no answer"."""
    args = HEALTH.to_args()
    assert Health.from_args([*args, 0.5, 9]) == HEALTH
    assert decode(encode_raw(Health.ADDRESS, [*args, 1, 2, 3])).messages == [HEALTH]
    with pytest.raises(MessageError):  # far more than a few appended fields: not a Health
        Health.from_args([*args, *range(Health.NEWER_ARGS + 1)])
