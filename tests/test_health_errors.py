"""A node whose core fails says so: Health's ``errors`` counts the failed steps and the failures the core caught
itself (a sound strike that raised), ``duplicates`` the redundant impact copies the sound core dropped; the first
failure of each kind is logged at once with its traceback (the rest at most every 5 s, as before), and
``batteur ls`` shows the count. Both fields are appended (a positional reader finds the others unmoved).

Nodes run in-process on loopback (no discovery, no OSCQuery).
"""

from __future__ import annotations

import asyncio
import json
import logging
from typing import ClassVar

import pytest

from batteur.tools import ls
from common.config import load_settings
from common.core import Outgoing
from common.messages import Health, OscMessage, encode
from common.runtime import Node
from tests.health_answerer import HealthAnswerer
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

HEALTH = Health(node_id="fake-1", role="sound", protocol=1, time=1.5, rate_hz=187.0, target_rate_hz=187.5,
                overruns=0, messages_in=1, messages_out=1, dropped=3, dropped_malformed=0, dropped_unknown=0,
                dropped_type=0, dropped_range=0, dropped_other=3, late=0, peers=3, errors=5, duplicates=24,
                wrong_node_unanswered=7, skipped_steps=9, discovery=1)


class FailingCore:
    """Steps at 200 Hz and fails every step (as a sound core whose drum has no modes did), reporting failures
    it caught itself and duplicates it dropped."""

    ROLE: ClassVar[str] = "sound"
    rate_hz = 200.0
    core_errors = 4
    duplicates = 11

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        raise ValueError("operands could not be broadcast together with shapes (195,) (0,)")


async def _health_after_failures(core: FailingCore, failures: int) -> tuple[Health, int]:
    node = Node(core, load_settings({"role": "sound", "discovery": False, "clock_master": "self",  # type: ignore[arg-type]
                                     "oscquery": False}))
    await node.start()
    try:
        await wait_for(lambda: node.step_errors >= failures, 20.0)
        return node.health(), node.step_errors
    finally:
        await node.stop()


def test_a_failing_core_shows_in_health_and_its_first_failure_has_a_traceback(
        caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.ERROR, logger="batteur"):
        health, step_errors = asyncio.run(_health_after_failures(FailingCore(), 3))
    # was: counted in step_errors only, which Health did not carry (``batteur ls``: ok, 0 dropped)
    assert health.errors >= step_errors + FailingCore.core_errors >= 3 + 4
    assert health.duplicates == FailingCore.duplicates
    failures = [r for r in caplog.records if "core step failed" in r.getMessage()]
    assert failures[0].exc_info is not None and "broadcast" in failures[0].getMessage()  # was: no traceback
    assert len(failures) == 1  # the rest within 5 s: rate-limited


def test_the_fields_are_appended_and_an_older_nodes_health_decodes() -> None:
    names = [f.name for f in Health.wire_fields()]
    since = len(names) - names.index("errors")  # they and the fields appended after them (wrong_node_unanswered, ...)
    assert names[-since:][:2] == ["errors", "duplicates"] and Health.APPENDED[-since:] == tuple(names[-since:])
    args = HEALTH.to_args()
    assert Health.from_args(args) == HEALTH
    # a node older by k fields sends the args without the last k: each decodes as 0 (every appended field non-zero in
    # HEALTH, so a field decoded from the wrong argument, or not defaulted, fails here)
    assert all(getattr(HEALTH, name) for name in names[-since:])
    for k in range(1, since + 1):
        older = Health.from_args(args[:-k])
        assert older == HEALTH.model_copy(update=dict.fromkeys(names[-k:], 0)), names[-k:]


def test_ls_shows_the_errors(capsys: pytest.CaptureFixture[str]) -> None:
    node = HealthAnswerer(encode(HEALTH))
    try:
        assert ls.main(["--node", f"127.0.0.1:{node.port}", "--timeout", "3", "--json"]) == 0
        row = json.loads(capsys.readouterr().out)[0]
        assert (row["errors"], row["duplicates"]) == (5, 24)
        assert ls.main(["--node", f"127.0.0.1:{node.port}", "--timeout", "3"]) == 0
        header, line = capsys.readouterr().out.splitlines()[:2]
        # after the rig and the status: rate/target Hz, late, skipped, dropped (the header's "node id" and
        # "rate/target Hz" two words)
        assert header.split()[11] == "errors" and line.split()[9] == "5"
    finally:
        node.close()
