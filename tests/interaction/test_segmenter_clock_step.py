"""The segmenter's estimate of physics' clock (``Segmenter.clock_offset``, the smallest recent receive time minus
contact time) follows a step of the rig clock back (the clock master restarted): its one-second windows turn over
at once, not only once rig time is back past where the last window began (35 s later after a 35 s step)."""

from __future__ import annotations

from common.kit import load_kit
from common.messages import Contact
from services.interaction.detect import Segmenter

KIT = load_kit("default")


def contact(time: float, step: int) -> Contact:
    return Contact(time=time, step=step, instrument="snare", part="right_stick_tip", x=0.0, y=0.0, z=0.0,
                   local_x=0.01, local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                   normal_velocity=3.0, impulse=0.01, normal_force=10.0)  # fmt: skip


def test_the_offset_estimate_follows_a_step_of_the_rig_clock_back() -> None:
    seg = Segmenter(KIT)
    for k in range(30):  # 3 s at 10 Hz, received 2 ms after each contact's time
        t = 50.0 + 0.1 * k
        seg.contact(contact(t, k), t + 0.002)
    assert abs(seg.clock_offset - 0.002) < 1e-9
    # physics restarted, the receiver's rig time stepped back 35 s with it; contacts now arrive 20 ms after their
    # time (a slower path): after two seconds of them the estimate is theirs, as it would be without the step
    for k in range(25):
        t = 18.0 + 0.1 * k
        seg.contact(contact(t, 1000 + k), t + 0.020)
    assert abs(seg.clock_offset - 0.020) < 1e-9
