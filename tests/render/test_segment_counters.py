"""``batteur render --jobs N``: report.json's controller counters (``physics.limit_violations``,
``physics.torque_saturated``) are the sum of what each segment's steps in its own window added (batteur/segments.py)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from batteur import render
from batteur.segments import Segment, SegmentResult, _CountingPhysics, _Player, plan_segments
from common.core import Outgoing


class _Controller:
    limit_violations = 0
    torque_saturated = 0


class _Physics:
    """A physics core whose controller's counters grow at every step: one violation, two saturated DOF."""

    rate_hz = 1000.0

    def __init__(self) -> None:
        self.scene = SimpleNamespace(controller=_Controller())

    def handle(self, message: Any, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        self.scene.controller.limit_violations += 1
        self.scene.controller.torque_saturated += 2
        return []


def test_a_segment_counts_only_the_steps_in_its_own_window() -> None:
    segment = Segment(1, 5.0, 10.0, 2.0, 10.25)
    physics = _Physics()
    counted = _CountingPhysics(physics, segment)
    steps = [2.0 + k * 0.25 for k in range(34)]  # 2.0 .. 10.25: lead-in, window (5.0 .. 9.75: 20 steps), overhang
    for now in steps:
        counted.step(now)
    assert physics.scene.controller.limit_violations == len(steps)  # every step counted by the controller ...
    assert counted.counters == {"limit_violations": 20, "torque_saturated": 40}  # ... the window's by the segment


def test_a_scene_without_a_controller_counts_nothing() -> None:
    """A scene without a drummer (no controller): no counter is made up (report.json leaves them out rather than say
    0), yet its steps' messages pass through and its contacts in the window are counted, and segments of such
    scenes merge to no counter."""
    def step(now: float) -> list[Outgoing]:
        return [Outgoing(SimpleNamespace(time=now), "interaction")]  # type: ignore[arg-type]  # a contact now

    physics = SimpleNamespace(rate_hz=1000.0, scene=SimpleNamespace(), step=step)
    counted = _CountingPhysics(physics, Segment(0, 0.0, 5.0, 0.0, 5.25))
    sent = [o for now in (1.0, 2.0, 5.1) for o in counted.step(now)]
    assert [o.message.time for o in sent] == [1.0, 2.0, 5.1]
    assert counted.contacts == 2  # 5.1 is the next segment's
    assert counted.counters == {}
    player = _Player(plan_segments(12.0, 5.0, 3.0), [], runner=None, duration_s=12.0)
    player.add(_result(0, counted.counters))
    player.add(_result(1, {}))
    assert player.counters == {} and player.contacts == 6


def _result(index: int, counters: dict[str, int]) -> SegmentResult:
    return SegmentResult(index, [], contacts=3, rejected={}, cpu_time_s=1.0, counters=counters)


def test_the_merged_counters_are_the_segments_sum_in_any_order_of_arrival() -> None:
    segments = plan_segments(12.0, 5.0, 3.0)
    player = _Player(segments, [], runner=None, duration_s=12.0)
    player.add(_result(1, {"limit_violations": 7, "torque_saturated": 100}))
    assert player.counters == {}  # segment 1 waits for segment 0
    player.add(_result(0, {"limit_violations": 5, "torque_saturated": 30}))
    assert player.counters == {"limit_violations": 12, "torque_saturated": 130}
    assert player.contacts == 6


SHORT = """tempo 120
meter 4/4
HH |x.x.x.x.|
SN |....X...|
BD |x.......|

HH |x.x.x.x.|
SN |....X...|
BD |x...x...|
"""
"""Two bars of eighths at 120 bpm (4 s): with the settle and the tail, two segments of 3 s."""


@pytest.mark.slow
def test_a_two_segment_render_reports_the_summed_counters(tmp_path: Path) -> None:
    score = tmp_path / "short.txt"
    score.write_text(SHORT)
    out = tmp_path / "out"
    assert render.main([str(score), "-o", str(out), "--jobs", "2", "--segment", "3", "--quiet"]) == 0
    physics = json.loads((out / "report.json").read_text())["physics"]
    assert physics["segments"]["count"] == 2
    assert isinstance(physics["limit_violations"], int) and isinstance(physics["torque_saturated"], int)
    assert physics["torque_saturated"] > 0  # strokes meet the torque limits
    # here the second segment's 3 s lead-in starts at rig time 0, as the first segment: both drummers play the
    # one-process render's performance, so the windows' sum is its count (each segment's whole run: more)
    one = tmp_path / "one"
    assert render.main([str(score), "-o", str(one), "--quiet"]) == 0
    whole = json.loads((one / "report.json").read_text())["physics"]
    assert (physics["limit_violations"], physics["torque_saturated"]) == (whole["limit_violations"],
                                                                          whole["torque_saturated"])
