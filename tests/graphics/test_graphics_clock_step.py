"""The graphics node's rig time steps back (the clock master restarted): the page's status and the pose editor's
postures go on at their periods, not only once rig time is back where it was; stale nodes still age out.

Was: after a step back of 35 s the status panel froze for 35 s (its period measured from a time in the future),
the editor's postures were not sent, and nodes last heard before the step were listed with negative ages."""

from __future__ import annotations

import numpy as np

from common.messages import Health
from services.graphics.core import GraphicsCore, GraphicsSettings


def _health(node_id: str, t: float) -> Health:
    return Health(node_id=node_id, role="physics", protocol=1, time=t, rate_hz=240.0, target_rate_hz=240.0,
                  overruns=0, messages_in=0, messages_out=0, dropped=0, dropped_malformed=0, dropped_unknown=0,
                  dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=2)


def _stepped(core: GraphicsCore, step_s: float, now: float) -> None:
    """What the node does when its rig clock steps (a core without the hook is left to guess)."""
    hook = getattr(core, "clock_stepped", None)
    if hook is not None:
        hook(step_s, now)


def test_status_and_postures_go_on_after_a_step_back() -> None:
    core = GraphicsCore(GraphicsSettings(clock="rig"))
    core.handle(_health("physics-old", 54.0), 54.0, "127.0.0.1:9101")
    core.step(54.0)
    core.take_page_messages()
    core.request_posture(np.zeros(57))
    assert core.step(54.05)  # the first posture goes at once
    _stepped(core, -35.0, 19.1)
    core.handle(_health("physics-new", 19.1), 19.1, "127.0.0.1:9101")
    core.request_posture(np.full(57, 0.1))
    assert core.step(19.2)  # a posture period after the last one, on the new clock
    core.step(20.5)
    statuses = [m for m in core.take_page_messages() if m["type"] == "status"]
    assert statuses  # status_period after the last, on the new clock
    core.handle(_health("physics-new", 29.0), 29.0, "127.0.0.1:9101")
    core.step(29.5)  # the old physics, last heard 10.4 s ago by the new clock, has aged out
    statuses = [m for m in core.take_page_messages() if m["type"] == "status"]
    assert [n["id"] for n in statuses[-1]["nodes"]] == ["physics-new"]
    assert all(n["age"] >= 0 for s in statuses for n in s["nodes"])
