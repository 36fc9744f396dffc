"""``batteur ls`` marks a node whose loop runs well under its target rate as ``behind`` (table and --json) and shows
the rate against its target and the late events. A walkthrough's physics node ran at 5.5 Hz of its 1000 with 16513
late events, and the table said ``ok 7.4``: "ok" only meant "answered", and neither the target nor ``late`` was in
the table. A node that answered still exits 0 (a healthcheck asks whether it runs).

The nodes are sockets of this test answering a Hello with a Health of its choosing (tests/health_answerer.py).
"""

from __future__ import annotations

import json

import pytest

from batteur.tools import ls
from common.messages import Health, encode
from tests.health_answerer import HealthAnswerer

pytestmark = pytest.mark.timeout(60)

PHYSICS = Health(node_id="physics-rig", role="physics", protocol=1, time=60.0, rate_hz=5.5, target_rate_hz=1000.0,
                 overruns=900, messages_in=40, messages_out=3, dropped=0, dropped_malformed=0, dropped_unknown=0,
                 dropped_type=0, dropped_range=0, dropped_other=0, late=16513, peers=3)
"""The walkthrough's physics node."""


def listed(health: Health, capsys: pytest.CaptureFixture[str], *options: str) -> tuple[int, str]:
    node = HealthAnswerer(encode(health))
    try:
        code = ls.main(["--node", f"127.0.0.1:{node.port}", "--timeout", "3", *options])
    finally:
        node.close()
    return code, capsys.readouterr().out


def test_a_node_far_under_its_target_rate_is_behind_in_the_table(capsys: pytest.CaptureFixture[str]) -> None:
    code, out = listed(PHYSICS, capsys)
    assert code == 0  # it answered
    header, row = out.splitlines()
    assert "rate/target Hz" in header and "late" in header
    assert row.split()[4:7] == ["behind", "5.5/1000", "16513"], row


def test_the_json_status_says_behind(capsys: pytest.CaptureFixture[str]) -> None:
    code, out = listed(PHYSICS, capsys, "--json")
    row = json.loads(out)[0]
    assert code == 0 and row["status"] == "behind"
    assert (row["rate_hz"], row["target_rate_hz"], row["late"]) == (5.5, 1000.0, 16513)


@pytest.mark.parametrize(("rate", "target", "status", "shown"), [
    (999.8, 1000.0, "ok", "999.8/1000"),
    (950.0, 1000.0, "ok", "950.0/1000"),  # a busy machine's few percent: still keeping time
    (500.0, 1000.0, "ok", "500.0/1000"),  # half: the threshold itself
    (499.0, 1000.0, "behind", "499.0/1000"),
    (20.0, 60.0, "behind", "20.0/60"),
    (186.6, 187.5, "ok", "186.6/187.5"),
    (0.0, 250.0, "ok", "0.0/250"),  # not stepped yet (its first second, or waiting for its clock master)
    (0.0, 0.0, "ok", "0.0/-"),  # event-driven: no loop to be behind
])
def test_the_rule(rate: float, target: float, status: str, shown: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out = listed(PHYSICS.model_copy(update={"rate_hz": rate, "target_rate_hz": target, "late": 0}), capsys)
    assert code == 0
    assert out.splitlines()[1].split()[4:6] == [status, shown]


def test_the_help_says_the_rule(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        ls.main(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "behind" in text and "under half its target rate" in text


def test_the_skipped_steps_are_a_column_and_in_the_json(capsys: pytest.CaptureFixture[str]) -> None:
    """Physics' simulation steps skipped to follow the rig clock (Health's ``skipped_steps``, appended 8 Dec): until
    then only its log's "behind real time" warnings counted them, and ``batteur ls`` (table and ``--json``) had no
    field for them: a node behind for minutes and one behind for a second looked alike."""
    behind = PHYSICS.model_copy(update={"skipped_steps": 123456})
    code, out = listed(behind, capsys)
    header, row = out.splitlines()
    assert code == 0
    assert header.split()[8:10] == ["late", "skipped"] and row.split()[6:8] == ["16513", "123456"], (header, row)
    code, out = listed(behind, capsys, "--json")
    assert json.loads(out)[0]["skipped_steps"] == 123456
