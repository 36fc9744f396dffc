"""A one-bar rock groove planned by common.gesture and played by the full-dynamics drummer: one contact onset
per note, on its instrument, near the note time, and no other onset."""

from __future__ import annotations

import numpy as np

from common.gesture.planner import plan_score
from common.kit import EventType, load_kit
from common.messages import Contact
from common.score.events import DrumEvent, Score
from services.interaction.detect import DetectionConfig
from services.physics.core import PhysicsCore

BEAT_S = 0.6  # 100 bpm
ONSET_GAP_S = 0.015
"""Contacts of one striker on one instrument closer than this belong to one impact."""


def _rock_bar(t0: float = 0.5) -> Score:
    ev = [DrumEvent(time=t0 + k * BEAT_S / 2, event=EventType.HIHATCLOSED, velocity=0.8, pitch=42) for k in range(8)]
    ev += [DrumEvent(time=t0 + k * BEAT_S, event=EventType.SNARE, velocity=0.8, pitch=38) for k in (1, 3)]
    ev += [DrumEvent(time=t0 + k * BEAT_S, event=EventType.BASS, velocity=0.8, pitch=36) for k in (0, 2, 2.5)]
    ev.sort(key=lambda e: e.time)
    return Score(events=ev, beats=t0 + BEAT_S * np.arange(4))


def _onsets(contacts: list[Contact]) -> list[tuple[float, str]]:
    """(time s, instrument) of each contact episode that is a strike, as interaction segments them: a striker's
    first contact after a gap, arriving faster than the slowest strike (a hi-hat closing gently under the foot
    is no note), and not a closed hi-hat's plates rattling right after a stick stroke."""
    detection = DetectionConfig()
    last: dict[tuple[str, str], float] = {}
    struck: dict[str, float] = {}
    out = []
    for c in contacts:
        striker = c.part.split("_")[0] if "stick" in c.part else c.part  # tip and shaft of one stick: one striker
        key = (c.instrument, striker)
        if (key not in last or c.time - last[key] > ONSET_GAP_S) and c.normal_velocity >= detection.strike_velocity_min:
            if c.part not in detection.rattle_parts:
                struck[c.instrument] = c.time
                out.append((c.time, c.instrument))
            elif c.time - struck.get(c.instrument, -1.0) > detection.rattle_window:  # not the plates' rattle
                out.append((c.time, c.instrument))
        last[key] = c.time
    return out


def test_a_planned_groove_gives_one_onset_per_note_near_its_time() -> None:
    kit = load_kit("default")
    plan = plan_score(_rock_bar(), kit)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0)
    start = 0.5
    offset = start - plan.start_time
    core.load_plan(plan, start_at=start)
    contacts: list[Contact] = []
    for k in range(1, round((plan.end_time + offset) * 1000) + 1):
        contacts += [o.message for o in core.step(k / 1000) if isinstance(o.message, Contact)]
    core.close()
    onsets = _onsets(contacts)
    notes = sorted((s.time + offset, s.object_id, s.event) for s in plan.strokes)
    assert len(notes) == 13
    unmatched = list(onsets)
    for t, obj, event in notes:
        mine = [o for o in unmatched if o[1] == obj and abs(o[0] - t) < 0.06]
        assert len(mine) == 1, f"{event.value} at {t:.3f} s: onsets {mine}"
        # sticks land within a few ms; the pedal (its beater is geared to a footboard the foot presses
        # through a compliant contact) is looser
        tolerance = 0.04 if event == EventType.BASS else 0.005
        assert abs(mine[0][0] - t) <= tolerance, f"{event.value} at {t:.3f} s sounded at {mine[0][0]:.3f} s"
        unmatched.remove(mine[0])
    assert unmatched == [], f"onsets without a note: {unmatched}"
