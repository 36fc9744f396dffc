"""Contact markers while the kit and pose editor is open: the node's frames carried none (the editor's still pose),
so a user moving an instrument while the drummer played saw no strikes; they are now drawn (in the page, on the
kit as edited: tests/graphics/test_kit_editor_actions.py)."""

from __future__ import annotations

import numpy as np
import pytest

from common.messages import Impact, Pose, Skeleton
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import synthetic_performance
from services.graphics.scene import impact_point

NAMES = ["pelvis", "right_hand"]
STILL = np.array([[0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 1.0], [0.3, 0.3, 1.0, 0.0, 0.0, 0.0, 1.0]])
"""A two-link body, (L, 7): position metres, quaternion x y z w."""


def test_the_editors_frames_mark_the_strikes_as_the_live_ones_do() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(Skeleton(layout=1, names=tuple(NAMES)), 0.0, "physics")
    core.handle(Pose(time=0.0, layout=1, values=tuple(STILL.ravel())), 0.0, "physics")
    core.handle(Impact(seq=1, time=1.0, instrument="crash", zone="bow", r=0.8, theta=0.3, velocity=3.0,
                       impulse=0.05, peak_force=300.0, duration=0.004, part="right_stick_tip"), 1.0, "interaction")
    live = core.frame_at(1.1)
    core.show_pose(["edited_" + n for n in NAMES], STILL + [0.1, 0, 0, 0, 0, 0, 0])  # the editor opens
    edited = core.frame_at(1.1)
    assert live is not None and edited is not None
    assert edited.pose[1, 0] == pytest.approx(0.4)  # the editor's body is shown
    expected = impact_point(core.kit.object("crash"), 0.8, 0.3)
    assert len(edited.hits) == 1 and edited.hits == live.hits
    assert edited.hits[0][:3] == pytest.approx(tuple(expected)) and edited.hits[0][4] == "crash"
    later = core.frame_at(1.7)  # a marker lasts 0.5 s, as with the editor closed
    assert later is not None and later.hits == []


def test_the_editors_frames_mark_a_previewed_scores_strikes() -> None:
    """With a score previewed (no physics), the open editor's frames flash the kit and mark the strikes of the
    previewed performance, as the preview's own frames do (they came from the live stream's kit, still)."""
    sequence, impacts = synthetic_performance(duration=2.0)
    core = GraphicsCore(GraphicsSettings(latency=0.0))
    core.load_preview(sequence, impacts, now=10.0)
    struck = next(i for i in impacts if i.time > sequence.times[0] + 0.1)
    now = 10.0 + struck.time - sequence.times[0] + 0.05  # 50 ms after the strike, on the preview's first loop
    preview = core.frame_at(now)
    core.show_pose(["edited_" + n for n in NAMES], STILL)
    edited = core.frame_at(now)
    assert preview is not None and edited is not None and np.array_equal(edited.pose, STILL)
    assert struck.instrument in [h[4] for h in edited.hits]
    assert edited.hits == preview.hits and np.array_equal(edited.kit, preview.kit) and edited.time == preview.time
    assert edited.kit[:, 0].max() > 0.5  # an object flashes
