"""PhysicsRejected's description (docs/osc.md) gives both budgets its refusals have: the physics core's and the
node's (a message it could not decode, another service's control), each as the code sets it (it gave the core's
alone, as if the node's refusals had it too)."""

from __future__ import annotations

from common.messages.physics import PhysicsRejected
from common.runtime import WRONG_NODE_REPLY_BURST, WRONG_NODE_REPLY_RATE_HZ
from common.transport import DECODE_REPLY_BURST, DECODE_REPLY_RATE_HZ
from services.physics.core import REPLY_BURST, REPLY_RATE_HZ


def test_physics_rejected_says_both_budgets() -> None:
    doc = " ".join((PhysicsRejected.__doc__ or "").split())
    assert (WRONG_NODE_REPLY_BURST, WRONG_NODE_REPLY_RATE_HZ) == (DECODE_REPLY_BURST, DECODE_REPLY_RATE_HZ)
    core = f"core's refusals {REPLY_BURST:g} at once, then {REPLY_RATE_HZ:g} a second"
    node = f"another service's control, {DECODE_REPLY_BURST:g} at once, then {DECODE_REPLY_RATE_HZ:g} a second"
    assert core in doc and node in doc, doc
