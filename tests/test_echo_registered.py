"""``batteur echo`` prints the messages a client registered with interaction (``/batteur/interaction/message/add``,
sent to the client's synth): they have no model, and echo dropped them as unknown addresses ("dropped
unknown_address ... no message is registered here" on stderr, nothing printed), though the node copied them.
Nodes are fakes on loopback (no discovery)."""

from __future__ import annotations

import json
from collections.abc import Iterator

import pytest

from common.messages import encode_raw
from tests.ports import free_port
from tests.test_tools_qa import FakeNode, batteur

HIT = encode_raw("/synth/hit", ["snare", 64, 0.5, "centre"])
"""What interaction sends for ``message/add hit HOST:PORT /synth/hit * onset instrument velocity...@i r zone``."""
OTHER = encode_raw("/synth/other", [1])


@pytest.fixture
def registered_node() -> Iterator[FakeNode]:
    node = FakeNode(port=free_port(), node_id="interaction-1")
    node.stream = [OTHER, HIT]  # as interaction copies what it sends (encoded already: no model to encode them)
    yield node
    node.close()


def _echo(node: FakeNode, pattern: str, *options: str) -> tuple[list[str], str]:
    proc = batteur("echo", pattern, "--node", f"127.0.0.1:{node.port}", "--count", "1", "--duration", "30", *options)
    try:
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 0, err
    return out.splitlines(), err


def test_echo_prints_a_registered_message(registered_node: FakeNode) -> None:
    lines, err = _echo(registered_node, "/synth/hit")
    assert lines == ["/synth/hit 'snare' 64 0.5 'centre'"], (lines, err)
    assert "unknown_address" not in err


def test_echo_prints_a_registered_message_as_json(registered_node: FakeNode) -> None:
    lines, err = _echo(registered_node, "/synth/hit", "--json")
    assert [json.loads(line) for line in lines] == [{"address": "/synth/hit", "args": ["snare", 64, 0.5, "centre"]}], \
        (lines, err)
