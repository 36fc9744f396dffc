"""Stick-head contacts in the strike scene: duration, rebound and impulse per instrument and speed.

    python bench/physics_contact.py          # a few seconds

For each instrument (its kit elasticity) and tip speed, a stick on a fulcrum
is thrown onto the event's hit point (services/physics/strike_scene.py) and
the contact is measured: steps in contact (1 ms each), the approach velocity
reported in the Contact messages, the rebound ratio (tip speed away from the
head right after the contact / speed into it) and the total impulse.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from common.kit import EventType
from common.messages import Contact
from services.physics.core import PhysicsCore
from services.physics.strike_scene import StrikeScene

EVENTS = (EventType.SNARE, EventType.FLOORTOM, EventType.HIGHTOM, EventType.RIDE, EventType.CRASH,
          EventType.HIHATCLOSED, EventType.COWBELL)
SPEEDS = (1.0, 3.0, 6.0)
STEPS = 120
"""Steps simulated per throw (1 ms each)."""


def measure(event: EventType, speed: float) -> tuple[int, float, float, float, float]:
    core = PhysicsCore(scene="strike", strike_event=event, strikes=[(0.05, speed)], pose_rate_hz=0.0)
    scene = core.scene
    assert isinstance(scene, StrikeScene)
    contacts: list[Contact] = []
    omega: dict[int, float] = {}
    for k in range(1, STEPS + 1):
        # the stick's only: a closed hi-hat's plates report their resting contact too (part hihat_rattle)
        contacts += [o.message for o in core.step(k / 1000)
                     if isinstance(o.message, Contact) and "stick" in o.message.part]
        omega[k] = core.world.client.getJointState(scene.body, 0)[1]
    core.close()
    if not contacts:
        return 0, 0.0, 0.0, 0.0, 0.0
    first, last = contacts[0].step, contacts[0].step
    for c in contacts[1:]:
        if c.step == last + 1:
            last = c.step
    episode = [c for c in contacts if first <= c.step <= last]
    # a stick still on the head when the throw's time is up (it came to rest there) has no rebound: NaN
    rebound = omega[last + 1] / max(-omega[first - 1], 1e-9) if last + 1 in omega else math.nan
    elasticity = core.kit.object(core.kit.events[event].object).elasticity
    return len(episode), episode[0].normal_velocity, rebound, sum(c.impulse for c in episode), elasticity


def build_parser() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                                   epilog=f"No options. A rebound of nan: the stick was still on the head after "
                                          f"{STEPS} ms (it came to rest there).")


def main(argv: Sequence[str] | None = None) -> int:
    build_parser().parse_args(argv)
    print(f"{'event':<13}{'elast.':>7}{'speed m/s':>10}{'steps':>7}{'v_in m/s':>10}{'rebound':>9}{'impulse Ns':>12}")
    for event in EVENTS:
        for speed in SPEEDS:
            steps, v_in, rebound, impulse, e = measure(event, speed)
            print(f"{event.value:<13}{e:7.2f}{speed:10.1f}{steps:7d}{v_in:10.2f}{rebound:9.2f}{impulse:12.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
