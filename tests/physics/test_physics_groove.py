"""A one-bar rock groove planned by common.gesture and played by the full-dynamics drummer: one contact onset
per note, on its instrument, near the note time, and no other onset."""

from __future__ import annotations

import math

import numpy as np

from common.gesture.planner import plan_score
from common.kit import EventType, load_kit
from common.messages import Contact
from common.score.events import DrumEvent, Score
from services.interaction.detect import DetectionConfig
from services.physics.core import PhysicsCore
from tests.physics.held_pedal import held_hihat_press

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
    out = []
    for c in contacts:
        striker = c.part.split("_")[0] if "stick" in c.part else c.part  # tip and shaft of one stick: one striker
        key = (c.instrument, striker)
        slowest = detection.part_velocity_min.get(c.part, detection.strike_velocity_min)
        if (key not in last or c.time - last[key] > ONSET_GAP_S) and c.normal_velocity >= slowest:
            if c.part not in detection.rattle_parts:  # not the plates' rattle after a stick stroke
                out.append((c.time, c.instrument))
        last[key] = c.time
    return out


def _play(score: Score) -> tuple[list[tuple[float, str, EventType, float]], list[tuple[float, str]], list[Contact]]:
    """Plan and play a score: (note time s, object, event, velocity) of every planned stroke, strike onsets, and
    every contact, on the rig clock."""
    kit = load_kit("default")
    plan = plan_score(score, kit)
    core = PhysicsCore(scene="drummer", kit=kit, pose_rate_hz=0)
    start = 0.5
    offset = start - plan.start_time
    core.load_plan(plan, start_at=start)
    contacts: list[Contact] = []
    for k in range(1, round((plan.end_time + offset) * 1000) + 1):
        contacts += [o.message for o in core.step(k / 1000) if isinstance(o.message, Contact)]
    core.close()
    notes = sorted((s.time + offset, s.object_id, s.event, s.note_velocity) for s in plan.strokes)
    return notes, _onsets(contacts), contacts


def _part_strikes(contacts: list[Contact], part: str, slowest: float = -math.inf) -> list[tuple[float, float]]:
    """(time s, approach velocity m/s) of each contact episode of one striker ``part``: its first contact after a
    gap of ``ONSET_GAP_S``, arriving at ``slowest`` m/s or faster."""
    out = []
    last = -1.0
    for c in contacts:
        if c.part == part:
            if c.time - last > ONSET_GAP_S and c.normal_velocity >= slowest:
                out.append((c.time, c.normal_velocity))
            last = c.time
    return out


def test_a_planned_groove_gives_one_onset_per_note_near_its_time() -> None:
    notes, onsets, _ = _play(_rock_bar())
    assert len(notes) == 13
    unmatched = list(onsets)
    for t, obj, event, _ in notes:
        mine = [o for o in unmatched if o[1] == obj and abs(o[0] - t) < 0.06]
        assert len(mine) == 1, f"{event.value} at {t:.3f} s: onsets {mine}"
        # sticks land within a few ms; the pedal (its beater is geared to a footboard the foot presses
        # through a compliant contact) is looser
        tolerance = 0.04 if event == EventType.BASS else 0.005
        assert abs(mine[0][0] - t) <= tolerance, f"{event.value} at {t:.3f} s sounded at {mine[0][0]:.3f} s"
        unmatched.remove(mine[0])
    assert unmatched == [], f"onsets without a note: {unmatched}"


def test_hihat_pedal_chicks_sound_on_their_notes_and_louder_with_velocity() -> None:
    """Ride eighths, hi-hat pedal on 2 and 4 (soft and loud) and then eighths: each pedal note closes the
    hi-hat's plates once, within a few ms of the note, faster for a louder note; the foot holding the hi-hat
    shut between notes makes no chick."""
    t0 = 0.5
    ev = [DrumEvent(time=t0 + k * BEAT_S / 2, event=EventType.RIDE, velocity=0.6, pitch=51) for k in range(8)]
    ev += [DrumEvent(time=t0 + k * BEAT_S, event=EventType.HIHATPEDAL, velocity=v, pitch=44)
           for k, v in ((1, 0.3), (3, 0.9))]
    ev += [DrumEvent(time=t0 + 4 * BEAT_S + k * BEAT_S / 2, event=EventType.HIHATPEDAL, velocity=0.6, pitch=44)
           for k in range(4)]
    ev.sort(key=lambda e: e.time)
    notes, _, contacts = _play(Score(events=ev, beats=t0 + BEAT_S * np.arange(6)))
    chicks = _part_strikes(contacts, "hihat_top", DetectionConfig().part_velocity_min["hihat_top"])
    pedal = [(t, v) for t, obj, event, v in notes if event == EventType.HIHATPEDAL]
    assert len(pedal) == 6 and len(chicks) == 6, (pedal, chicks)
    for (t, _), (heard, _) in zip(pedal, chicks, strict=True):
        assert abs(heard - t) <= 0.008, f"pedal note at {t:.3f} s closed at {heard:.3f} s"
    assert chicks[1][1] > chicks[0][1] * 1.3  # the loud note (0.9) closes faster than the soft one (0.3)


def test_the_kits_foot_press_table_is_what_the_simulated_foot_does() -> None:
    """common.kit.FOOT_PRESS_TABLE (where the planner aims a hi-hat chick) against the drummer's own foot: a
    foot target held above the pedal's flat target presses the footboard as far as the table says."""
    from common.kit import FOOT_PRESS_TABLE

    kit = load_kit("default")
    for height, expected in (FOOT_PRESS_TABLE[2], FOOT_PRESS_TABLE[4], FOOT_PRESS_TABLE[6]):
        press = held_hihat_press(kit, height)
        assert abs(press - expected) < 0.02, f"foot {height * 1000:.0f} mm above flat pressed {press:.3f}"


def test_a_kick_soon_after_another_is_played_as_fast_as_the_same_kick_alone() -> None:
    """Two soft kicks 0.2 s apart and the same kick alone: the beater meets the head at about the same speed
    for the second of the pair as alone (a foot letting its footboard up and down again in a fifth of a second
    must not turn a soft note into a loud one)."""
    t0 = 0.5
    ev = [DrumEvent(time=t, event=EventType.BASS, velocity=0.2, pitch=36) for t in (t0, t0 + 0.2, t0 + 1.2)]
    _, _, contacts = _play(Score(events=ev, beats=t0 + BEAT_S * np.arange(4)))
    strikes = [v for _, v in _part_strikes(contacts, "kick_beater")]
    assert len(strikes) == 3, strikes
    assert abs(strikes[1] - strikes[2]) <= 0.25 * strikes[2], f"beater speeds {strikes} m/s (pair, pair, alone)"
