"""Copies of one impact (same sender, seq and time) play once and are counted; a sender that numbers nothing (a Pd
socket sending every strike as seq 0) has each of its strikes played, as the Pd sound client plays them."""

from __future__ import annotations

from sound_helpers import impact

from common.messages.interaction import Damping
from services.sound.core import SoundCore

PD = "127.0.0.1:50123"


def test_strikes_of_one_seq_at_different_times_all_play(drum_core: SoundCore) -> None:
    for k in range(12):
        drum_core.handle(impact(0, 0.1 * k), 0.0, PD)
    drum_core.render(1.5)
    # was: the first played, the other 11 dropped as duplicates of it (Health: dropped 0)
    assert drum_core.stats.strikes == 12 and drum_core.duplicates == 0


def test_copies_of_one_impact_play_once_and_are_counted(drum_core: SoundCore) -> None:
    for _copy in range(3):
        drum_core.handle(impact(5, 0.2), 0.0, PD)
        drum_core.handle(impact(6, 0.3), 0.0, PD)
    drum_core.handle(impact(5, 0.2), 0.0, "127.0.0.1:50124")  # another sender's seq 5: its own
    drum_core.render(1.0)
    assert drum_core.stats.strikes == 3 and drum_core.duplicates == 4


def test_a_press_and_its_lift_under_one_seq_both_apply(drum_core: SoundCore) -> None:
    def damping(state: int, t: float) -> Damping:
        return Damping(seq=0, time=t, instrument="drum", part="left_hand", state=state, zone="centre", r=0.3,
                       theta=0.0, force=5.0 * state)

    for message in (damping(1, 0.1), damping(1, 0.1), damping(0, 0.3)):
        drum_core.handle(message, 0.0, PD)
    drum_core.render(0.5)
    assert (drum_core.stats.presses, drum_core.stats.lifts, drum_core.duplicates) == (1, 1, 1)
