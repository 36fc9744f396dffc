"""While a live core's targets trail the rig clock (``PhysicsCore.target_lag``) the score player works on the
targets' clock; its refusals say rig times, as its stop and pause log lines do. A stop at rig time 2.0 with the
targets 0.5 s behind was refused as "stop at 1.500 s: nothing is playing then", and a live note past the
performance's bound named its time 0.5 s early."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

import services.physics.score_player as player_module
from common.core import Outgoing
from common.messages.physics import PhysicsReset
from common.messages.score import LiveNote, ScoreTransport
from services.physics.core import PhysicsCore

LAG = 0.5


def _reasons(out: list[Outgoing]) -> list[str]:
    return [str(getattr(o.message, "reason", "")) for o in out]


@pytest.fixture
def trailing(drummer: PhysicsCore) -> Iterator[PhysicsCore]:
    """The module's drummer core, reset, with its targets ``LAG`` s behind the rig clock (reset again after)."""
    drummer.handle(PhysicsReset(time=drummer.time), drummer.time, "")
    drummer.target_lag = LAG
    yield drummer
    drummer.handle(PhysicsReset(time=drummer.time), drummer.time, "")


def test_a_stop_or_pause_with_nothing_playing_says_its_rig_time(trailing: PhysicsCore) -> None:
    now = trailing.time
    for action in ("stop", "pause"):
        out = trailing.handle(ScoreTransport(action=action, time=now + 2.0, position=0.0), now, "127.0.0.1:9")
        assert _reasons(out) == [f"{action} at {now + 2.0:.3f} s: nothing is playing then"]  # was now + 1.5


def test_a_pause_after_the_performance_says_its_end_in_rig_time(trailing: PhysicsCore) -> None:
    now = trailing.time
    assert not trailing.handle(LiveNote(time=now + 1.0, pitch=38, velocity=100, channel=10), now, "")
    end = trailing.score_player.end_time + LAG  # its rig time
    at = end + 1.0
    out = trailing.handle(ScoreTransport(action="pause", time=at, position=0.0), now, "127.0.0.1:9")
    assert _reasons(out) == [f"pause at {at:.3f} s: nothing is playing then (the performance ended at {end:.3f} s)"]


def test_a_live_note_past_the_bound_says_its_rig_time(trailing: PhysicsCore,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(player_module, "MAX_PERFORMANCE_NOTES", 2)
    now = trailing.time
    times = [now + 1.1, now + 1.6, now + 2.1]  # not the other test's (a live note at the same time is a double)
    outs = [trailing.handle(LiveNote(time=t, pitch=38, velocity=100, channel=10), now, "127.0.0.1:9")
            for t in times]
    assert not outs[0] and not outs[1]
    reasons = _reasons(outs[2])
    assert len(reasons) == 1 and reasons[0].startswith(f"live note SNARE at {times[2]:.3f} s: the performance "
                                                       "already holds 2 notes"), reasons
