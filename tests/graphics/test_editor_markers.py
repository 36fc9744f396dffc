"""Contact markers while the kit and pose editor is open: the node's frames carried none (the editor's still pose),
so a user moving an instrument while the drummer played saw no strikes; they are now drawn, on the kit as edited."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from common.kit import Kit
from common.messages import Impact, Pose, Skeleton
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import SyntheticDrummer, synthetic_performance
from services.graphics.scene import impact_point

from .conftest import GraphicsNodeProcess, needs_browser
from .test_kit_editor import _type, crash_in_editor  # noqa: F401 - the fixture
from .test_kit_editor_actions import _markers_after_strike
from .test_page import PoseSender

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


@needs_browser
def test_a_strike_is_marked_on_the_edited_kit_with_the_editor_open(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """The crash moved and turned in the open editor (not saved): a strike's marker shows, on the crash where the
    editor has put it."""
    page, node, loaded = crash_in_editor
    _type(page, 0, "0.5")
    _type(page, 5, "60")
    edited = loaded.model_dump(mode="json")
    crash = next(o for o in edited["objects"] if o["id"] == "crash")
    crash["position"][0], crash["rotation_deg"][2] = 0.5, 60.0
    r, theta = 0.8, 0.3
    expected = impact_point(Kit.model_validate(edited).object("crash"), r, theta)
    assert np.linalg.norm(expected - impact_point(loaded.object("crash"), r, theta)) > 0.2  # tells the two apart

    sender = PoseSender(node, SyntheticDrummer(strokes={}, duration=0.0).pose(0.0))
    try:
        page.wait_for_function("window.batteur.frames > 5", timeout=15000)
        markers = _markers_after_strike(page, node, sender, r, theta)
    finally:
        sender.stop()
    assert page.is_visible("#editor")  # still editing
    for marker in markers:  # the node rounds a marker to 1 mm
        assert marker == pytest.approx(expected.tolist(), abs=2e-3), (marker, expected)
