"""Physics answers the controls it refuses: a /batteur/physics/rejected reply to the sender, naming the address and
the reason (at once, or from a step when the refusal came on the background planning path), within a reply budget
per sender host. Also what a reset does to a plan in flight and what stop/pause do with nothing playing.

The cores are driven through their handlers (rig times as sent; no wall clock).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import common.gesture.planner as planner_module
from common.core import Outgoing
from common.messages.physics import CartesianTarget, PhysicsRejected, PhysicsReset, PhysicsStrike
from common.messages.score import ScoreLoad, ScoreTransport
from services.physics.core import REPLY_BURST, REPLY_RATE_HZ, PhysicsCore
from tests.physics.test_live_score_position import SCORE as FOUR_BARS  # four bars at 100 bpm

SENDER = "127.0.0.1:9"
OUT_OF_REACH = CartesianTarget(limb="left_hand", time=0.5, x=0.0, y=4.0, z=1.0, vx=0.0, vy=0.0, vz=0.0)
IN_REACH = CartesianTarget(limb="right_hand", time=0.5, x=0.1, y=0.45, z=0.75, vx=0.0, vy=0.0, vz=0.0)


def refusals(out: list[Outgoing]) -> list[tuple[str, str, str]]:
    """(destination, refused address, reason) of every PhysicsRejected in ``out``."""
    return [(o.to, o.message.address, o.message.reason) for o in out if isinstance(o.message, PhysicsRejected)]


def test_a_refused_target_is_answered_to_its_sender_and_an_accepted_one_is_not(drummer: PhysicsCore) -> None:
    answered = refusals(drummer.handle(OUT_OF_REACH, 0.0, SENDER))
    assert len(answered) == 1
    to, address, reason = answered[0]
    assert (to, address) == (SENDER, "/batteur/physics/target") and "reach" in reason
    assert drummer.handle(IN_REACH, 0.0, SENDER) == []
    assert drummer.rejected["CartesianTarget"] == 1


def test_the_strike_scene_answers_what_it_refuses() -> None:
    core = PhysicsCore(scene="strike")
    try:
        for _ in range(50):
            core.step(core.time + 0.001)
        late = refusals(core.handle(PhysicsStrike(time=0.01, velocity=2.0), core.time, SENDER))
        assert [(to, address) for to, address, _ in late] == [(SENDER, "/batteur/physics/strike")]
        assert "in the past" in late[0][2]
        wrong_scene = refusals(core.handle(OUT_OF_REACH, core.time, "[::1]:7000"))
        assert [(to, address) for to, address, _ in wrong_scene] == [("[::1]:7000", "/batteur/physics/target")]
        assert "drummer scene" in wrong_scene[0][2]
        assert core.handle(PhysicsStrike(time=core.time + 0.5, velocity=2.0), core.time, SENDER) == []
    finally:
        core.close()


def test_a_flood_of_bad_packets_is_answered_within_a_budget_per_host_and_the_rest_counted() -> None:
    """A flood from one host (any ports) gets the burst answered, then the rate; the rest is refused and counted,
    not answered; another host keeps its own budget."""
    core = PhysicsCore(scene="strike")
    try:
        flood = 5 * int(REPLY_BURST)
        answered = sum(len(refusals(core.handle(OUT_OF_REACH, 0.0, f"10.0.0.1:{1000 + k}"))) for k in range(flood))
        assert answered == REPLY_BURST
        assert core.replies_unanswered == flood - REPLY_BURST and core.rejected_total == flood
        assert len(refusals(core.handle(OUT_OF_REACH, 0.0, "10.0.0.2:1000"))) == 1  # another host
        one_second = sum(len(refusals(core.handle(OUT_OF_REACH, 1.0, "10.0.0.1:1000"))) for _ in range(flood))
        assert one_second == REPLY_RATE_HZ  # a second of rig time later: the rate's worth
    finally:
        core.close()


@pytest.fixture
def live(tmp_path: Path) -> Iterator[Any]:
    """The live core (plans in a thread), four bars in its library, loaded."""
    from services.physics.node import LivePhysicsCore

    (tmp_path / "four_bars.txt").write_text(FOUR_BARS)
    physics = LivePhysicsCore(planner="thread", scene="drummer", grip="german", pose_rate_hz=0, mode="live")
    assert physics.score_player.wait_loaded(120.0)  # as the node before it listens (play: refused meanwhile)
    physics.score_player.library = [tmp_path]
    physics.step(0.1)
    assert physics.handle(ScoreLoad(path="four_bars.txt"), 0.1, SENDER) == []
    try:
        yield physics
    finally:
        physics.close()


def _steps_until_idle(physics: Any) -> list[Outgoing]:
    """Step the live core until no plan is in flight (rig time stands still while a plan is computed); what the
    steps sent."""
    out: list[Outgoing] = []
    for _ in range(10):
        assert physics.score_player.wait(60.0)
        out += physics.step(physics.time + 0.001)
        if not physics.score_player.busy:
            break
    return out


def test_a_target_refused_after_waiting_behind_a_plan_is_answered_to_its_own_sender(live: Any,
                                                                                     gate: threading.Event) -> None:
    assert live.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.1, SENDER) == []
    assert live.handle(OUT_OF_REACH, 0.1, "127.0.0.1:5555") == []  # waits behind the plan: not refused yet
    assert live.score_player.busy
    gate.set()
    answered = refusals(_steps_until_idle(live))
    assert [(to, address) for to, address, _ in answered] == [("127.0.0.1:5555", "/batteur/physics/target")]
    assert "reach" in answered[0][2]


def test_a_play_whose_planning_fails_in_the_background_is_answered_to_its_sender(
        live: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    release = threading.Event()

    def failing(*args: Any, **kwargs: Any) -> Any:
        release.wait(60.0)
        raise RuntimeError("no gesture fits")

    monkeypatch.setattr(planner_module, "plan_gestures", failing)
    assert live.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.1, "127.0.0.1:6000") == []
    release.set()
    answered = refusals(_steps_until_idle(live))
    assert [(to, address) for to, address, _ in answered] == [("127.0.0.1:6000", "/batteur/score/transport")]
    assert "no gesture fits" in answered[0][2]
    assert live.score_player.state == "idle"


def test_a_reset_drops_the_plan_in_flight_and_acts_at_once(live: Any, gate: threading.Event) -> None:
    """A reset sent while a ``play`` is planned must not wait for that plan nor apply it later: at once, nothing
    waits, the drummer is at rest, and the plan, once ready, is dropped (not played)."""
    player = live.score_player
    live.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.1, SENDER)
    assert player.busy
    assert live.handle(PhysicsReset(time=0.1), 0.1, SENDER) == []
    assert not player.busy and player.state == "idle"  # at once, the planner still held
    gate.set()
    for _ in range(20):
        live.step(live.time + 0.001)
    assert player.plans == 0 and player.state == "idle" and player.clock(live.time) is None
    assert all(len(track) == 0 for track in live.scene.limb_tracks.values())
    assert live.rejected_total == 0  # the reset's own choice: not a refusal


def test_messages_sent_between_a_plan_and_a_reset_still_take_effect_in_order(live: Any,
                                                                            gate: threading.Event) -> None:
    """A reset drops the plan in flight; the messages that waited behind it act first (a controller change stays),
    and a play among them is dropped with it (its plan would be cleared by the reset)."""
    from common.messages.physics import PhysicsControlMode

    player = live.score_player
    live.handle(ScoreTransport(action="play", time=0.0, position=0.0), 0.1, SENDER)
    live.handle(PhysicsControlMode(mode="joint_pd"), 0.1, SENDER)
    live.handle(ScoreTransport(action="play", time=0.0, position=1.0), 0.1, SENDER)
    assert live.handle(PhysicsReset(time=0.1), 0.1, SENDER) == []
    assert not player.busy and live.settings.control == "joint_pd"
    gate.set()
    for _ in range(20):
        live.step(live.time + 0.001)
    assert player.plans == 0 and player.state == "idle" and live.rejected_total == 0


@pytest.mark.parametrize("action", ["pause", "stop"])
def test_a_pause_or_stop_with_nothing_playing_is_refused_and_leaves_the_player_idle(drummer: PhysicsCore,
                                                                                    action: str) -> None:
    player = drummer.score_player
    drummer.handle(PhysicsReset(time=0.0), 0.0, SENDER)  # at rest, nothing queued (the module's core is shared)
    before = drummer.rejected_total
    answered = refusals(drummer.handle(ScoreTransport(action=action, time=0.0, position=0.0), 0.0, SENDER))
    assert [(to, address) for to, address, _ in answered] == [(SENDER, "/batteur/score/transport")]
    assert "nothing is playing" in answered[0][2]
    assert player.state == "idle" and drummer.rejected_total == before + 1


def test_a_live_note_too_late_or_of_no_drum_is_answered_and_counted_late_not_rejected(drummer: PhysicsCore) -> None:
    from common.messages.score import LiveNote

    player = drummer.score_player
    rejected, late = drummer.rejected_total, player.late_notes
    too_late = refusals(drummer.handle(LiveNote(time=0.01, pitch=38, velocity=100, channel=10), 0.0, SENDER))
    assert [(to, address) for to, address, _ in too_late] == [(SENDER, "/batteur/score/note")]
    assert "not played" in too_late[0][2] and "to prepare it" in too_late[0][2]
    no_drum = refusals(drummer.handle(LiveNote(time=5.0, pitch=1, velocity=100, channel=10), 0.0, SENDER))
    assert [(to, address) for to, address, _ in no_drum] == [(SENDER, "/batteur/score/note")]
    assert "pitch 1 has no drum event type" in no_drum[0][2]
    assert player.late_notes == late + 1 and drummer.rejected_total == rejected  # counted as before
    assert player.state == "idle"


def test_a_live_note_found_late_after_its_plan_is_answered_to_its_sender(live: Any,
                                                                         gate: threading.Event) -> None:
    """A live note in time when it arrived, whose plan was ready too late for it (the planner held past the note's
    preparation time): counted late, not played, and its sender told so from the step that found it."""
    from common.messages.score import LiveNote

    player = live.score_player
    note_at = live.time + player.preparation_s + 0.1
    assert live.handle(LiveNote(time=note_at, pitch=38, velocity=100, channel=10), live.time,
                       "127.0.0.1:7000") == []
    assert player.busy
    for _ in range(int(0.2 / 0.001)):  # rig time runs on while the planner is held
        live.step(live.time + 0.001)
    gate.set()
    answered = refusals(_steps_until_idle(live))
    assert [(to, address) for to, address, _ in answered] == [("127.0.0.1:7000", "/batteur/score/note")]
    assert "not played" in answered[0][2] and player.late_notes == 1


def test_tempo_and_style_with_nothing_playing_are_kept_for_the_next_play(drummer: PhysicsCore) -> None:
    from common.messages.score import GestureStyle, TempoScale

    player = drummer.score_player
    assert drummer.handle(TempoScale(factor=1.5), 0.0, SENDER) == []
    assert drummer.handle(GestureStyle(grip="german", nuance="tenuto", algorithm="viterbi", sticking="none"), 0.0,
                          SENDER) == []
    assert player.tempo == 1.5 and player.state == "idle"
    player.tempo = 1.0


def test_a_pause_while_playing_then_a_stop_are_taken_and_a_second_pause_is_refused(tmp_path: Path) -> None:
    (tmp_path / "four_bars.txt").write_text(FOUR_BARS)
    core = PhysicsCore(scene="drummer", grip="german", pose_rate_hz=0)
    player = core.score_player
    player.library = [tmp_path]
    try:
        core.handle(ScoreLoad(path="four_bars.txt"), 0.0, SENDER)
        assert core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER) == []
        assert core.handle(ScoreTransport(action="pause", time=1.5, position=0.0), 0.1, SENDER) == []
        assert player.state == "paused"
        again = refusals(core.handle(ScoreTransport(action="pause", time=2.0, position=0.0), 0.2, SENDER))
        assert [address for _, address, _ in again] == ["/batteur/score/transport"] and "(paused)" in again[0][2]
        assert core.handle(ScoreTransport(action="stop", time=2.0, position=0.0), 0.2, SENDER) == []  # to rest
        assert player.state == "idle" and core.rejected_total == 1
    finally:
        core.close()


def test_a_drummer_moved_by_streamed_targets_can_be_paused_and_brought_to_rest() -> None:
    """No score plays, but the limbs follow targets streamed to them: a pause holds them and a stop brings them to
    rest, as for a score; after a reset (the drummer at rest, nothing queued) a stop has nothing to do."""
    core = PhysicsCore(scene="drummer", grip="german", pose_rate_hz=0)
    try:
        x, y, z = (float(c) for c in core.scene.rest_targets["right_hand"])
        raised = CartesianTarget(limb="right_hand", time=1.0, x=x, y=y, z=z + 0.05, vx=0.0, vy=0.0, vz=0.0)
        assert core.handle(raised, 0.0, SENDER) == []
        assert core.handle(ScoreTransport(action="pause", time=0.5, position=0.0), 0.0, SENDER) == []
        assert core.score_player.state == "paused"
        assert core.handle(ScoreTransport(action="stop", time=0.6, position=0.0), 0.0, SENDER) == []
        assert core.score_player.state == "idle" and core.rejected_total == 0
        core.handle(PhysicsReset(time=0.0), 0.0, SENDER)
        again = refusals(core.handle(ScoreTransport(action="stop", time=0.0, position=0.0), 0.0, SENDER))
        assert [address for _, address, _ in again] == ["/batteur/score/transport"]
    finally:
        core.close()
