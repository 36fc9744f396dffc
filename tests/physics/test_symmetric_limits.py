"""The default joint limits are the same on both sides, mirrored (``limits.symmetric_limits``), so the right foot
plays fast kicks as the mirrored kit's left foot does. Before, the 15 DeepMimic clips let the right ankle flex
66.8 degrees up and the left 59.0: under 16th-note kicks at 140 bpm the right foot's posture drifted to that bound
(toe up, off the footboard) and 5 kicks of 32 sounded; the left-handed kit's left foot played all 32."""

from __future__ import annotations

import numpy as np
import pytest

from common.kit import EventType
from common.score.events import DrumEvent, Score
from services.physics.character import JOINTS
from services.physics.drummer import cached_default_limits
from services.physics.limits import default_limits, mirrored_limit
from tests.physics.held_pedal import onsets, played_score

PAIRED = [joint[len("right_"):] for joint in JOINTS if joint.startswith("right_")]


def test_default_limits_are_mirror_symmetric_within_both_sides_estimates() -> None:
    """Each right box is the left's mirrored (x kept, y and z negated), and lies within what the clips gave each
    side (the range both agree on)."""
    limits, raw = cached_default_limits(), default_limits()
    assert PAIRED == ["clavicle", "shoulder", "elbow", "wrist", "hip", "knee", "ankle"]
    for kind in PAIRED:
        right, left = limits.euler[f"right_{kind}"], limits.euler[f"left_{kind}"]
        mirrored = mirrored_limit(left)
        assert right.lower == pytest.approx(mirrored.lower, abs=1e-12), kind
        assert right.upper == pytest.approx(mirrored.upper, abs=1e-12), kind
        for side_raw in (raw.euler[f"right_{kind}"], mirrored_limit(raw.euler[f"left_{kind}"])):
            assert np.all(right.lower >= side_raw.lower - 1e-12) and np.all(right.upper <= side_raw.upper + 1e-12)
    assert np.degrees(limits.euler["right_ankle"].upper[0]) < 62.0  # the drift's bound that kept the toe pressing
    assert limits.sources["right_ankle"] == "mocap+symmetric" and raw.sources["right_ankle"] == "mocap"


def test_sixteenth_kicks_at_140_bpm_sound_on_the_default_kit() -> None:
    """16 kicks 107 ms apart (16th notes at 140 bpm, velocity 0.7) by the right foot on the default kit: at least
    90 % sound (one beater onset each). Before: 5 of 16."""
    gap = 60.0 / 140 / 4
    events = [DrumEvent(time=0.5 + k * gap, event=EventType.BASS, velocity=0.7, pitch=36) for k in range(16)]
    score = Score(events=events, beats=0.5 + 4 * gap * np.arange(5))
    strokes, contacts = played_score(score, ("kick_beater",), start_s=1.0)
    found = onsets(contacts)
    assert len(strokes) == 16
    assert len(found) >= 0.9 * len(strokes), f"{len(found)} beater onsets for {len(strokes)} kicks: {found}"
