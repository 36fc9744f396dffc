"""The first end-to-end strike: physics -> interaction -> sound, in one process.

A stick in the physics strike scene is thrown onto a kit instrument on a
schedule; every contact goes through interaction's segmentation to an impact;
the sound core renders it. The cores are the ones the rig runs as nodes; here
an :class:`~common.bus.OfflineRunner` wires them through the in-memory bus.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from common.bus import OfflineRunner
from common.kit import EventType, Kit, load_kit
from common.messages import Contact, Impact, OscMessage
from services.interaction.core import InteractionCore
from services.physics.core import PhysicsCore
from services.sound.core import SoundCore, SoundSettings

DEFAULT_STRIKES: tuple[tuple[float, float], ...] = ((0.25, 3.0), (0.75, 1.5), (1.25, 4.5))
"""(contact time seconds, tip speed m/s) of the default strike demo."""


def parse_strikes(text: str) -> list[tuple[float, float]]:
    """``"0.25:3,0.75:1.5"`` -> [(0.25, 3.0), (0.75, 1.5)]; raises ValueError with the bad item."""
    strikes: list[tuple[float, float]] = []
    for item in text.split(","):
        time_text, sep, speed_text = item.strip().partition(":")
        try:
            if not sep:
                raise ValueError
            strikes.append((float(time_text), float(speed_text)))
        except ValueError:
            raise ValueError(f"strike {item!r}: expected TIME:SPEED (seconds:m/s)") from None
    return strikes


@dataclass
class StrikeResult:
    """What a strike run produced."""

    impacts: list[Impact]
    contacts: int
    audio: np.ndarray
    sample_rate: int
    duration_s: float


def run_strikes(
    strikes: Sequence[tuple[float, float]] = DEFAULT_STRIKES,
    event: EventType = EventType.SNARE,
    kit: Kit | None = None,
    latency_s: float = 0.05,
    tail_s: float = 1.0,
    on_progress: Callable[[float, float], None] | None = None,
) -> StrikeResult:
    """Run the strike scene offline and render its sound.

    Returns the unique impacts (rig times in seconds), the number of contact
    messages, and mono float32 audio whose sample 0 is rig time 0.
    """
    kit = kit if kit is not None else load_kit()
    physics = PhysicsCore(scene="strike", strikes=strikes, kit=kit, strike_event=event, pose_rate_hz=0.0)
    interaction = InteractionCore(kit=kit)
    sound = SoundCore(SoundSettings(latency=latency_s, origin=0.0), kit=kit)
    runner = OfflineRunner([physics, interaction, sound])
    seen: dict[int, Impact] = {}
    contacts = 0

    def tap(message: OscMessage, source: str, destination: str) -> None:
        nonlocal contacts
        if isinstance(message, Contact):
            contacts += 1
        elif isinstance(message, Impact) and destination == "sound":
            seen.setdefault(message.seq, message)

    runner.bus.tap(tap)
    duration = max((t for t, _ in strikes), default=0.0) + latency_s + tail_s
    runner.run_until(duration, None if on_progress is None else (lambda t: on_progress(t, duration)))
    try:
        audio = sound.recording()
    finally:
        sound.close()
    impacts = sorted(seen.values(), key=lambda i: i.time)
    return StrikeResult(impacts, contacts, audio, sound.sample_rate, duration)
