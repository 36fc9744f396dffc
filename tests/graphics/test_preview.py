"""Kinematic preview: the figure follows a keyframe plan of a real groove (Groove MIDI Dataset file)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from common.gesture.keyframe import plan_keyframes
from common.kit import load_kit
from common.score.limbs import distribute
from common.score.midi import read_midi
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import LINK_NAMES
from services.graphics.preview import plan_preview

DATA = Path(__file__).resolve().parents[1] / "data"


def test_figure_follows_the_keyframe_plan_and_strikes_on_time() -> None:
    kit = load_kit()
    score = read_midi(DATA / "groove_drummer6_s3_1_rock_90_beat_4-4.mid")
    plan = plan_keyframes(distribute(score, kit), kit, score)
    first = min(s.time for s in plan.strokes)
    plan.end_time = min(plan.end_time, first + 3.0)  # a few seconds are enough for the test
    sequence, impacts = plan_preview(plan, rate_hz=60.0)
    assert sequence.names == LINK_NAMES
    strokes = [s for s in plan.strokes if s.time <= plan.end_time]
    assert len(strokes) > 5
    assert [i.time for i in impacts[: len(strokes)]] == sorted(s.time for s in strokes)
    for s in strokes:  # the stick tip (ball of the foot) is at the planned contact point at the contact time
        part = f"{s.limb.value.split('_')[0]}_{'stick_tip' if 'hand' in s.limb.value else 'toe'}"
        effector = sequence.sample(s.time)[LINK_NAMES.index(part), :3]
        assert np.linalg.norm(effector - s.target) < 0.01, (s.event, s.limb)
    core = GraphicsCore(GraphicsSettings(latency=0.0))
    core.load_preview(sequence, impacts, now=0.0)
    frame = core.frame_at(strokes[0].time - sequence.times[0] + 0.01)
    assert frame is not None
    ids = [o.id for o in kit.objects]
    assert frame.kit[ids.index(strokes[0].object_id), 0] > 0.3  # the first stroke flashes its drum
