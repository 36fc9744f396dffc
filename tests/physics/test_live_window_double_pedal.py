"""A live note's window on a double pedal: the planner plays every foot given a BASS note as a kick foot (a kick
softer than the one before is a smaller, deeper stroke, so its stroke after a changed one differs too:
``FOOT_NOTES_AFTER``), and a fast kick goes to the other foot. The score player took only the kit's preferred
kick foot as one and counted every kick as that foot's: with the ``double_pedal`` kit a hi-hat pedal note left the
left foot's track off the whole re-plan's (0.5 mm), and a kick's window did not re-join (planned again whole). The
window now counts each foot's kicks as planned and takes the kick feet of its own plan
(``common.gesture.planner.kick_feet``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.gesture.planner import kick_feet, plan_gestures
from common.kit import Limb, load_kit
from common.messages.score import LiveNote, ScoreLoad, ScoreTransport
from common.score.limbs import bass_feet, distribute
from common.score.text import read_score
from services.physics.core import PhysicsCore
from services.physics.score_player import ScorePlayer
from services.physics.targets import Track

BARS = 3
KICKS = "|" + "".join("xx" + "." * 14 for _ in range(4))  # a double on every beat: 47 ms apart at 80 bpm (64ths)
PEDAL = "|" + "".join("." * 8 + "x" + "." * 7 for _ in range(4))  # the hi-hat foot between the beats
SCORE = f"tempo 80\nmeter 4/4\nBD {KICKS * BARS}|\nHP {PEDAL * BARS}|\n"
SENT_S = 2.4
"""Rig time the live note is sent (the score plays from 1 s: a beat every 0.75 s, kicks at 2.5 and 2.547 s ...)."""


Knots = tuple[list[Any], list[Any], list[Any]]
"""A track's knots: times (s), positions (m), velocities (m/s)."""


def _play(library: Path, pitch: int, note_s: float, score: str = SCORE) -> tuple[dict[str, object], dict[str, Knots]]:
    """``score`` from rig time 1 s on the double-pedal kit, a live note at ``note_s`` sent at SENT_S: the player's
    status and every limb's track (times, positions, velocities) right after."""
    (library / "doubles.txt").write_text(score)
    core = PhysicsCore(scene="drummer", kit=load_kit("double_pedal"), grip="german", pose_rate_hz=0)
    try:
        core.score_player.library = [library]
        core.handle(ScoreLoad(path="doubles.txt"), 0.0, "")
        assert not core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, "")
        assert not core.handle(LiveNote(time=note_s, pitch=pitch, velocity=100, channel=10), SENT_S, "")
        tracks = {name: (list(t.times), [v.copy() for v in t.values], [v.copy() for v in t.velocities])
                  for name, t in core.scene.limb_tracks.items()}  # type: ignore[attr-defined]
        return core.score_player.status(), tracks
    finally:
        core.close()


def _positions(knots: Knots, times: np.ndarray) -> np.ndarray:
    track = Track(3)
    track.times, track.values, track.velocities = knots
    return np.array([track.sample(float(t))[0] for t in times])


@pytest.mark.parametrize(("pitch", "note_s"), [(44, 3.5), (36, 3.6), (36, 2.95)])
def test_a_live_note_on_a_double_pedal_re_joins_as_a_whole_re_plan(tmp_path: Path, pitch: int, note_s: float,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A hi-hat pedal note (the left foot, which also kicks) and kicks: the window re-joins and every limb's track
    is the whole re-plan's."""
    status, window = _play(tmp_path, pitch, note_s)
    assert status["live_window_misses"] == 0 and status["late_notes"] == 0  # a kick's window was missed
    monkeypatch.setattr(ScorePlayer, "_window_end", lambda self, new, t_s, widen=False: math.inf)
    _, whole = _play(tmp_path, pitch, note_s)
    for name, knots in whole.items():
        times = np.arange(SENT_S, max(knots[0][-1], window[name][0][-1]) + 0.1, 0.001)
        gap = np.abs(_positions(window[name], times) - _positions(knots, times)).max()
        assert gap <= 1e-6, f"{name}: {gap:.1e} m off the whole re-plan"  # the left foot: 4.8e-4 m


SPARSE_KICKS = "|x" + "." * 23 + "xx" + "." * 22 + "x..x" + "." * 12
SPARSE_SCORE = (f"tempo 80\nmeter 4/4\nBD {SPARSE_KICKS * BARS}|\nHP {('|' + ('.' * 8 + 'x' + '.' * 7) * 4) * BARS}|\n"
                f"HH {('|' + 'x.x.x.x.' * 8) * BARS}|\n")
"""Sparse kicks, a few doubles, the hi-hat foot and the hands: a live kick's window whose left foot agreed with its
queued track only at the last knot it could trust re-joined there, and the left foot then played the queued track,
up to 68 mm off the whole re-plan's for the rest of the score."""


def test_a_window_that_agrees_only_at_its_last_trusted_knot_does_not_re_join_there(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _, window = _play(tmp_path, 36, 3.2, SPARSE_SCORE)
    monkeypatch.setattr(ScorePlayer, "_window_end", lambda self, new, t_s, widen=False: math.inf)
    _, whole = _play(tmp_path, 36, 3.2, SPARSE_SCORE)
    for name, knots in whole.items():
        times = np.arange(SENT_S, max(knots[0][-1], window[name][0][-1]) + 0.1, 0.001)
        gap = np.abs(_positions(window[name], times) - _positions(knots, times)).max()
        assert gap <= 1e-6, f"{name}: {gap:.1e} m off the whole re-plan"


def test_the_kick_feet_are_the_feet_the_planner_gives_a_bass_note(tmp_path: Path) -> None:
    """The double pedal's doubles put kicks on the left foot: both feet are kick feet, as bass_feet says they may
    be; a single pedal's kicks are its foot's."""
    (tmp_path / "doubles.txt").write_text(SCORE)
    score = read_score(tmp_path / "doubles.txt")
    for name, feet in (("double_pedal", {Limb.LEFT_FOOT, Limb.RIGHT_FOOT}), ("default", {Limb.RIGHT_FOOT})):
        kit = load_kit(name)
        plan = plan_gestures(distribute(score, kit), kit, score)
        assert kick_feet(plan.strokes) == feet == bass_feet(kit), name
