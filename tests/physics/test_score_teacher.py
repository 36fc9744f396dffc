"""The live score player as a teacher uses it: where a pause, stop or re-plan falls in the score (score seconds, and
bar and beat of the score's own meter), how much of a play played once it ends, and ``/batteur/score/dynamics`` to
play louder or softer.

Until 7 Dec the log said only rig seconds (``pause at 74.814 s``), nothing at the end of a play, and
no control scaled the notes' velocities (``nuance`` is the stroke's manner, sound levels only the mix). The player
runs on a bare PhysicsCore (no physics steps: planning only), fast."""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path

import pytest

from common.kit import load_kit
from common.messages import MessageError
from common.messages.physics import PhysicsRejected
from common.messages.score import ScoreDynamics, ScoreLoad, ScoreTransport, TempoScale
from common.transport import UdpEndpoint
from services.physics.core import PhysicsCore
from services.physics.node import LivePhysicsCore
from services.physics.score_player import ScorePlayer
from tests.waiting import wait_for

SENDER = "127.0.0.1:9"
LOGGER = "batteur.physics.score"
# 100 bpm: a beat is 0.6 s; one 4/4 bar of 13 notes, the last at 2.1 s (bar 1, beat 4.5)
GROOVE = """tempo 100
meter 4/4
HH |X.x.X.x.X.x.X.x.|
SN |....X.......X...|
BD |x.......x.x.....|
"""
# 120 bpm in 6/8: an eighth is 0.25 s, a bar 1.5 s, counted 1 to 6 in eighths
SIX_EIGHT = """tempo 120
meter 6/8
HH |x.x.x.x.x.x.|x.x.x.x.x.x.|
BD |x.....x.....|x.....x.....|
"""


def _player(tmp_path: Path, text: str = GROOVE, name: str = "groove.txt") -> tuple[PhysicsCore, ScorePlayer]:
    (tmp_path / name).write_text(text, encoding="utf-8")
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    player = core.score_player
    player.library = [tmp_path]
    core.handle(ScoreLoad(path=name), 0.0, SENDER)
    return core, player


def _said(caplog: pytest.LogCaptureFixture, start: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and r.getMessage().startswith(start)]


def test_a_pause_a_stop_and_a_replan_say_where_in_the_score(tmp_path: Path, caplog: pytest.LogCaptureFixture
                                                            ) -> None:
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        core.handle(ScoreTransport(action="pause", time=3.0, position=0.0), 0.5, SENDER)  # 1.5 s in: 2.5 beats
        core.handle(ScoreTransport(action="play", time=5.0, position=1.5), 3.5, SENDER)  # resumed from there
        core.handle(TempoScale(factor=0.5), 5.3, SENDER)  # its anchor: preparation_s after the message
        assert player.mapping is not None
        t_a, p_a, _ = player.mapping
        core.handle(ScoreTransport(action="stop", time=t_a + 0.4, position=0.0), 5.4, SENDER)  # 0.2 s more of it
    core.close()
    assert _said(caplog, "pause at") == ["pause at rig 3.000 s: score 1.500 s, bar 1 beat 3.5"]
    assert p_a == pytest.approx(1.5 + (t_a - 5.0))
    replan = _said(caplog, "re-planned from")
    beat = 1 + p_a / 0.6
    assert len(replan) == 1 and replan[0].startswith(f"re-planned from rig {t_a:.3f} s (score {p_a:.3f} s, bar 1 beat "
                                                     f"{int(beat * 10) / 10:.1f}): tempo x0.5, dynamics x1")
    stop = p_a + 0.4 * 0.5
    assert _said(caplog, "stop at") == [f"stop at rig {t_a + 0.4:.3f} s: score {stop:.3f} s, bar 1 beat "
                                        f"{int((1 + stop / 0.6) * 10) / 10:.1f}"]


def test_the_bar_and_beat_are_counted_in_the_scores_own_meter(tmp_path: Path, caplog: pytest.LogCaptureFixture
                                                              ) -> None:
    """6/8 counts eighths, 1 to 6 a bar: 2.0 s in at 120 bpm is the second bar's third eighth (as batteur compare
    counts; quarter notes would say beat 2)."""
    core, _ = _player(tmp_path, SIX_EIGHT, "six.txt")
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        core.handle(ScoreTransport(action="pause", time=3.0, position=0.0), 0.5, SENDER)
    core.close()
    assert _said(caplog, "pause at") == ["pause at rig 3.000 s: score 2.000 s, bar 2 beat 3.0"]


def test_a_play_that_ends_says_how_much_of_it_played_and_where_it_ended(tmp_path: Path,
                                                                        caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        player.pump(player.end_time - 0.01)  # still playing: nothing said
        assert _said(caplog, "groove.txt:") == []
        # the live core's targets jumped over three notes (physics fell behind the rig clock): 0.3 s and 0.6 s in
        assert player.drop_skipped(1.5 + 0.3 - 0.01, 1.5 + 0.6 + 0.01, 2.0) == (0, 3)
        player.pump(player.end_time + 0.01)
        player.pump(player.end_time + 1.0)  # said once
    core.close()
    assert _said(caplog, "groove.txt:") == ["groove.txt: 10 of 13 notes played; not played: 3 skipped: physics fell "
                                            "behind the rig clock; ended after its last note at score 2.100 s, bar 1 "
                                            "beat 4.5"]


def test_a_stopped_play_counts_the_notes_it_cut_and_a_late_start_the_notes_too_close(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        # from 0.3 s of the score at rig time 0.3: the note then cannot be prepared (0.02 + 0.2 + preparation_s)
        core.handle(ScoreTransport(action="play", time=0.3, position=0.3), 0.0, SENDER)
        assert player.late_notes == 1
        core.handle(ScoreTransport(action="stop", time=2.0, position=0.0), 0.1, SENDER)  # score 2.0 s: 1 note left
        player.pump(1.9)
        assert _said(caplog, "groove.txt:") == []  # said once the stop is reached
        player.pump(2.1)
    core.close()
    # 11 notes from 0.3 s on (the first hi-hat and kick are before it); beat 1 + 2.0 / 0.6 = 4.33
    assert _said(caplog, "groove.txt:") == ["groove.txt: 9 of 11 notes played; not played: 1 too close to prepare "
                                            "when it started, 1 cut by the stop; stopped at rig 2.000 s: score "
                                            "2.000 s, bar 1 beat 4.3"]


def test_a_new_play_and_a_reset_end_the_play_at_once(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        core.handle(ScoreTransport(action="play", time=2.0, position=1.2), 0.3, SENDER)  # before its first note
        player.reset()
    core.close()
    assert _said(caplog, "groove.txt:") == [
        "groove.txt: 0 of 13 notes played; not played: 13 cut by the new play; replaced by a new play at rig 0.320 s, "
        "before the score started (from score 0.000 s, bar 1 beat 1.0)",
        "groove.txt: 0 of 7 notes played; not played: 7 cut by the reset; reset at rig 0.000 s, before the score "
        "started (from score 1.200 s, bar 1 beat 3.0)"]


def test_notes_the_planner_drops_are_counted_by_reason(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Three hand notes at once: the planner drops one (too_many_hands)."""
    core, player = _player(tmp_path, "tempo 100\nat 0 SN\nat 0 HT\nat 0 CR\nat 1 SN\n", "three.txt")
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        player.pump(player.end_time + 0.01)
    core.close()
    assert _said(caplog, "three.txt:") == ["three.txt: 3 of 4 notes played; not played: 1 too_many_hands (planner); "
                                           "ended after its last note at score 0.600 s, bar 1 beat 2.0"]


def _speeds(tmp_path: Path, factor: float) -> dict[int, tuple[float, float]]:
    """Each note's (planned effector speed into the surface m/s, note velocity) at dynamics ``factor``."""
    core, player = _player(tmp_path)
    if factor != 1.0:
        core.handle(ScoreDynamics(factor=factor), 0.0, SENDER)
    core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
    plan = player.last_plan
    core.close()
    assert plan is not None and core.rejected == {}
    return {s.note_index: (s.velocity, s.note_velocity) for s in plan.strokes}


def test_dynamics_scales_the_notes_velocities_and_the_planned_stroke_speeds(tmp_path: Path) -> None:
    written, soft, loud = _speeds(tmp_path, 1.0), _speeds(tmp_path, 0.5), _speeds(tmp_path, 4.0)
    assert written.keys() == soft.keys() == loud.keys() and len(written) == 13
    for note, (speed, velocity) in written.items():
        assert soft[note][1] == pytest.approx(velocity * 0.5)
        assert loud[note][1] == pytest.approx(min(1.0, velocity * 4.0)) and loud[note][1] <= 1.0  # clipped
        assert soft[note][0] < speed < loud[note][0] or loud[note][1] == velocity == 1.0, note


def test_dynamics_while_playing_re_plans_from_where_the_tempo_would(tmp_path: Path,
                                                                    caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
    before = player.last_plan
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreDynamics(factor=0.5), 2.0, SENDER)
    after = player.last_plan
    core.close()
    assert before is not None and after is not None and after is not before and player.dynamics == 0.5
    assert player.mapping is not None and player.mapping[0] == pytest.approx(2.0 + player.preparation_s)
    t_c = player.mapping[0]
    old = {(round(s.time, 6), s.event): s.note_velocity for s in before.strokes}
    new = {(round(s.time, 6), s.event): s.note_velocity for s in after.strokes if s.time >= t_c}
    assert new and all(v == pytest.approx(old[k] * 0.5) for k, v in new.items())  # the rest softer, same times
    kept = [s for s in after.strokes if s.time < t_c]
    assert kept and all(s.note_velocity == old[(round(s.time, 6), s.event)] for s in kept)  # the notes before
    assert any(m.startswith("dynamics: velocity factor 0.5 (softer)") for m in _said(caplog, "dynamics"))


def test_dynamics_takes_the_live_nodes_background_path(tmp_path: Path) -> None:
    """The node plans in a worker: the dynamics waits its turn in the FIFO as a tempo change does and re-plans."""
    (tmp_path / "groove.txt").write_text(GROOVE, encoding="utf-8")
    core = LivePhysicsCore(planner="thread", scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0,
                           mode="live")
    player = core.score_player
    try:
        assert player.wait_loaded(120.0) and player.background
        player.library = [tmp_path]

        def settle(now: float) -> None:
            player.pump(now)
            while player.busy:
                assert player.wait(60.0)
                player.pump(now)

        core.handle(ScoreLoad(path="groove.txt"), 0.0, SENDER)
        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        core.handle(ScoreDynamics(factor=0.5), 0.0, SENDER)  # waits behind the play's plan
        settle(0.0)
        assert player.dynamics == 0.5 and player.plans == 2 and core.rejected == {}
        plan = player.last_plan
        assert plan is not None and player.mapping is not None
        assert player.score is not None
        written = {(round(e.time, 6), e.event): e.velocity for e in player.score.events}
        at, position, _ = player.mapping
        later = [s for s in plan.strokes if s.time >= at]  # the re-plan's notes from its anchor on: half as loud
        assert later
        for s in later:
            assert s.note_velocity == pytest.approx(0.5 * written[(round(position + s.time - at, 6), s.event)])
    finally:
        core.close()


@pytest.mark.parametrize(("args", "said"), [
    ([5.0], "out_of_range: /batteur/score/dynamics: factor: must be at most 4, got 5"),
    ([0.125], "out_of_range: /batteur/score/dynamics: factor: must be at least 0.25, got 0.125"),
])
def test_a_dynamics_out_of_range_is_refused_saying_the_bound(args: list[object], said: str) -> None:
    with pytest.raises(MessageError) as err:
        ScoreDynamics.from_args(args)  # type: ignore[arg-type]
    assert str(err.value) == said


def test_a_bad_dynamics_is_answered_with_the_physics_refusal_and_counted() -> None:
    """As a bad ``/batteur/score/tempo`` (tests/test_transport_refusals.py): the node's transport answers the sender
    with ``/batteur/physics/rejected`` and counts it dropped."""
    async def main() -> None:
        node = await UdpEndpoint.open("127.0.0.1", clock=lambda: 0.0)
        client = await UdpEndpoint.open("127.0.0.1")
        got: list[object] = []
        client.set_handler(lambda message, _: got.append(message))
        try:
            for args in ([-1.0], [9.0], ["loud"], []):
                client.send_raw("/batteur/score/dynamics", args, node.local_address)
            await wait_for(lambda: len(got) >= 4, 10.0)
            assert node.stats.dropped_total == 4 and node.stats.messages_in == 0
            assert all(isinstance(m, PhysicsRejected) and m.address == "/batteur/score/dynamics" for m in got)
            reasons = [m.reason for m in got if isinstance(m, PhysicsRejected)]
            assert ["out_of_range" in r for r in reasons] == [True, True, False, False]
            assert "wrong_type" in reasons[2] and "wrong_arity" in reasons[3]
        finally:
            client.close()
            node.close()

    asyncio.run(main())
