"""Synthetic contact streams: what physics would send for known strokes (tests, benchmarks, demos).

Each stroke is rendered on the physics step grid (``dt`` seconds): one
``Contact`` per step in contact, with a half-sine normal force of peak
``peak_force`` newtons, per-step impulse ``force * dt``, the approach
velocity on the first step and a normal velocity turning negative (the
stick leaving) over the contact. Positions are given in the instrument's
frame (metres) and turned into world coordinates with the kit's pose.

Stroke vocabulary (times in seconds):

* :func:`strike`: one clean contact of ``steps`` steps;
* :func:`chatter`: a strike whose contact breaks and re-makes for a step or
  two at low speed (one impact);
* :func:`double_stroke`: two strikes ``gap`` apart (two impacts);
* :func:`buzz`: a strike followed by rebounds every ``interval`` at
  ``decay`` times the previous speed, until the stick rests (press);
* :func:`dead_stroke`: a strike whose stick stays on the head for ``hold``;
* :func:`rest`: a stick laid on the head at walking pace (damping only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from common.core import Core, Outgoing
from common.kit import Kit, KitObject
from common.messages import Contact


@dataclass(frozen=True)
class StrokeTruth:
    """What a stroke should be detected as: its impacts' ground truth."""

    time: float
    velocity: float
    impulse: float
    peak_force: float
    duration: float
    local_x: float
    local_y: float


class StreamBuilder:
    """Renders strokes on one instrument for one striker part into Contact messages.

    Parameters
    ----------
    kit : the kit (for world positions)
    instrument : kit object id
    part : striker part name
    dt : physics step, seconds
    """

    def __init__(self, kit: Kit, instrument: str, part: str = "right_stick_tip", dt: float = 0.001) -> None:
        self.obj: KitObject = kit.object(instrument)
        self.instrument = instrument
        self.part = part
        self.dt = dt
        self.contacts: list[Contact] = []
        self.truths: list[StrokeTruth] = []
        self._rotation = Rotation.from_euler("xyz", self.obj.rotation_deg, degrees=True)

    def _step(self, t: float) -> int:
        return int(round(t / self.dt))

    def _contact(self, step: int, local: tuple[float, float], velocity: float, force: float) -> Contact:
        world = np.asarray(self.obj.position) + self._rotation.apply([local[0], local[1], 0.0])
        normal = self.obj.normal()
        return Contact(
            time=step * self.dt,
            step=step,
            instrument=self.instrument,
            part=self.part,
            x=float(world[0]),
            y=float(world[1]),
            z=float(world[2]),
            local_x=local[0],
            local_y=local[1],
            local_z=0.0,
            normal_x=normal[0],
            normal_y=normal[1],
            normal_z=normal[2],
            normal_velocity=velocity,
            impulse=max(force, 0.0) * self.dt,
            normal_force=max(force, 0.0),
        )

    def pulse(
        self,
        t: float,
        velocity: float,
        *,
        steps: int = 4,
        peak_force: float | None = None,
        at: tuple[float, float] = (0.03, 0.02),
        skip: tuple[int, ...] = (),
        truth: bool = True,
    ) -> StreamBuilder:
        """One contact starting at ``t`` lasting ``steps`` steps (steps in ``skip`` left out: chatter gaps)."""
        step0 = self._step(t)
        if peak_force is None:
            peak_force = 400.0 * velocity  # roughly a stick on a head
        impulse = 0.0
        peak = 0.0
        for i in range(steps):
            if i in skip:
                continue
            force = peak_force * math.sin(math.pi * (i + 0.5) / steps)
            v = velocity if i == 0 else velocity * (1.0 - 2.0 * i / max(steps - 1, 1)) * 0.8
            self.contacts.append(self._contact(step0 + i, at, v, force))
            impulse += force * self.dt
            peak = max(peak, force)
        if truth:
            last = max(i for i in range(steps) if i not in skip)
            self.truths.append(
                StrokeTruth(step0 * self.dt, velocity, impulse, peak, (last + 1) * self.dt, at[0], at[1])
            )
        return self

    def hold(self, t: float, duration: float, force: float = 1.5, at: tuple[float, float] = (0.03, 0.02)) -> None:
        """Resting contact from ``t`` for ``duration`` seconds at ``force`` newtons, no approach speed."""
        step0 = self._step(t)
        for i in range(max(int(round(duration / self.dt)), 1)):
            self.contacts.append(self._contact(step0 + i, at, 0.0, force))


def strike(b: StreamBuilder, t: float, velocity: float = 3.0, **kw: object) -> StreamBuilder:
    """One clean strike (one impact)."""
    return b.pulse(t, velocity, **kw)  # type: ignore[arg-type]


def chatter(b: StreamBuilder, t: float, velocity: float = 3.0) -> StreamBuilder:
    """A strike whose 6-step contact loses touch on steps 2 and 4 (one impact)."""
    return b.pulse(t, velocity, steps=6, skip=(2, 4))


def double_stroke(b: StreamBuilder, t: float, velocity: float = 3.0, gap: float = 0.020) -> StreamBuilder:
    """Two strikes ``gap`` seconds apart, the second at 95 % of the first's speed (two impacts)."""
    b.pulse(t, velocity)
    return b.pulse(t + gap, velocity * 0.95)


def buzz(
    b: StreamBuilder, t: float, velocity: float = 2.0, interval: float = 0.008, decay: float = 0.6, v_min: float = 0.05
) -> int:
    """A buzz stroke: a strike, then rebounds every ``interval`` s slower by ``decay`` until under ``v_min``,
    then the stick rests for 40 ms. Returns the number of impacts it should give (strike + rebounds)."""
    count = 0
    v = velocity
    time = t
    while v >= v_min:
        b.pulse(time, v, steps=3)
        count += 1
        v *= decay
        time += interval
    b.hold(time, 0.040)
    return count


def dead_stroke(b: StreamBuilder, t: float, velocity: float = 2.5, hold: float = 0.2) -> StreamBuilder:
    """A strike whose stick stays on the head for ``hold`` seconds (one impact, then damping)."""
    b.pulse(t, velocity, steps=4, truth=True)
    b.hold(t + 4 * b.dt, hold)
    return b


def rest(b: StreamBuilder, t: float, duration: float = 0.2) -> StreamBuilder:
    """A stick laid on the head with no approach speed (damping only, no impact)."""
    b.hold(t, duration)
    return b


def merged(*builders: StreamBuilder) -> list[Contact]:
    """Every builder's contacts in physics order (by step, then instrument and part)."""
    contacts = [c for b in builders for c in b.contacts]
    return sorted(contacts, key=lambda c: (c.step, c.instrument, c.part))


def drive(core: Core, contacts: list[Contact], dt: float = 0.001, tail: float = 0.05) -> list[tuple[float, Outgoing]]:
    """Feed ``contacts`` to an interaction core the way the offline runner would.

    At each physics step time t: the step's contacts go to ``core.handle(c, t, "physics")``,
    then ``core.step(t)`` runs. Goes on ``tail`` seconds after the last contact.

    Returns
    -------
    list of (t, Outgoing) in sending order
    """
    out: list[tuple[float, Outgoing]] = []
    if not contacts:
        return []
    by_step: dict[int, list[Contact]] = {}
    for c in contacts:
        by_step.setdefault(c.step, []).append(c)
    first, last = min(by_step), max(by_step) + int(round(tail / dt))
    for step in range(first, last + 1):
        t = step * dt
        for c in by_step.get(step, ()):
            out.extend((t, o) for o in core.handle(c, t, "physics"))
        out.extend((t, o) for o in core.step(t))
    return out
