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
from services.physics.strike_scene import Strike
from services.sound.core import SoundCore, SoundSettings

DEFAULT_STRIKES: tuple[tuple[float, float], ...] = ((0.25, 3.0), (0.75, 1.5), (1.25, 4.5))
"""(contact time seconds, tip speed m/s) of the default strike demo."""
MAX_STRIKE_TIME_S = 600.0
"""The latest strike time, seconds (10 minutes). The strike scene keeps its whole recording in memory (about
24 MB a minute, measured: float32 at 48 kHz and the WAV's copy), so the 24 h a score may last
(:data:`common.score.events.MAX_SCORE_SECONDS`, rendered streaming to disk) would need some 35 GB; ``1e9:3``
ran for 10 minutes, 3.9 GB and counting, before it was stopped."""


def parse_strikes(text: str) -> list[tuple[float, float]]:
    """``"0.25:3,0.75:1.5"`` -> [(0.25, 3.0), (0.75, 1.5)]; raises ValueError with the bad item: not
    TIME:SPEED, a time outside 0 to :data:`MAX_STRIKE_TIME_S`, or a speed the strike scene refuses."""
    strikes: list[tuple[float, float]] = []
    for item in text.split(","):
        time_text, sep, speed_text = item.strip().partition(":")
        try:
            if not sep:
                raise ValueError
            time_s, speed = float(time_text), float(speed_text)
        except ValueError:
            raise ValueError(f"strike {item!r}: expected TIME:SPEED (seconds:m/s)") from None
        if time_s > MAX_STRIKE_TIME_S:  # checked here, before hours of simulation fill the memory
            raise ValueError(f"strike {item!r}: {time_s:g} s is later than the strike scene renders (at most "
                             f"{MAX_STRIKE_TIME_S:g} s)")
        try:
            Strike(time_s, speed)  # the scene's own checks (a finite time >= 0, a speed in (0, 30] m/s), now
        except ValueError as exc:
            raise ValueError(f"strike {item!r}: {exc}") from None
        strikes.append((time_s, speed))
    return strikes


@dataclass
class StrikeResult:
    """What a strike run produced."""

    impacts: list[Impact]
    contacts: int
    audio: np.ndarray
    sample_rate: int
    duration_s: float
    """The audio's length, seconds: whole blocks of the sound, up to one (5.3 ms) short of the run."""


def run_strikes(
    strikes: Sequence[tuple[float, float]] = DEFAULT_STRIKES,
    event: EventType = EventType.SNARE,
    kit: Kit | None = None,
    latency_s: float = 0.05,
    tail_s: float = 1.0,
    on_progress: Callable[[float, float], None] | None = None,
    prepare: Callable[[SoundCore], None] | None = None,
) -> StrikeResult:
    """Run the strike scene offline and render its sound.

    Returns the unique impacts (rig times in seconds), the number of contact
    messages, and mono float32 audio whose sample 0 is rig time 0.
    """
    kit = kit if kit is not None else load_kit()
    physics = PhysicsCore(scene="strike", strikes=strikes, kit=kit, strike_event=event, pose_rate_hz=0.0)
    interaction = InteractionCore(kit=kit)
    sound = SoundCore(SoundSettings(latency=latency_s, origin=0.0), kit=kit)
    if prepare is not None:  # a sound parameters file applied
        prepare(sound)
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
    impacts = sorted(seen.values(), key=lambda i: i.time)  # the WAV's length: its whole blocks, not the run's
    return StrikeResult(impacts, contacts, audio, sound.sample_rate, len(audio) / sound.sample_rate)
