"""A loud hi-hat pedal chick closes the plates at a stick stroke's speed, a soft one slower, both on time.

The hi-hat's last 4 mm close at the footboard toe's pace, as a real stand's direct pull does
(services/physics/kitbodies.py ``hihat_gap``): before (8 Dec) the gap closed linearly over the whole pedal travel,
the plates met at a quarter of the foot's speed (0.14-0.40 m/s for velocities 0.1-1), and every chick ranked below
every stick stroke (the pooled velocity Spearman of docs/evaluation.md).
"""

from __future__ import annotations

from common.gesture.heights import chick_speed, stick_speed
from common.kit import EventType
from services.interaction.detect import DetectionConfig
from tests.physics.held_pedal import onset_contacts, played_pedal_notes

SOFT, LOUD = 0.2, 0.9
"""Score velocities of the two chicks."""


def test_a_loud_chick_closes_the_plates_at_a_stick_strokes_speed_and_faster_than_a_soft_one() -> None:
    """The plates follow the foot: the loud chick's top plate meets the bottom one at least as much faster than
    the soft one's as the planner's foot is (``chick_speed``: 2.15 / 1.1 m/s, 1.95 times; measured 0.93 and 2.13 m/s,
    2.3 times), and at least as fast as a soft stick stroke (``stick_speed(SOFT)``, 1.06 m/s; before, 0.16 and 0.38
    m/s). Each chick is heard (faster than interaction's slowest top plate), once, within 10 ms of its note."""
    notes, contacts = played_pedal_notes(1.75, EventType.HIHATPEDAL, 44, (SOFT, LOUD), ("hihat_top",), start_s=0.5)
    slowest = DetectionConfig().part_velocity_min["hihat_top"]
    chicks = [c for c in onset_contacts(contacts) if c.normal_velocity >= slowest]
    assert len(chicks) == len(notes) == 2, (notes, [(c.time, c.normal_velocity) for c in chicks])
    for note, chick in zip(notes, chicks, strict=True):
        assert abs(chick.time - note) <= 0.010, f"pedal note at {note:.3f} s closed at {chick.time:.3f} s"
    soft, loud = (c.normal_velocity for c in chicks)
    assert loud >= chick_speed(LOUD) / chick_speed(SOFT) * soft, f"soft {soft:.2f} m/s, loud {loud:.2f} m/s"
    assert loud >= stick_speed(SOFT), f"the loud chick's plates met at {loud:.2f} m/s"
