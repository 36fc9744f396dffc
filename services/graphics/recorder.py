"""Record what physics and interaction publish into a :class:`PoseSequence` and a list of impacts.

For the offline render (``batteur render``): tap the in-memory bus, run, then
hand the recording to :func:`services.graphics.video.render_video` and the
exporters::

    recorder = PerformanceRecorder()
    runner.bus.tap(recorder.tap)
    runner.run_until(t_end)
    sequence, impacts = recorder.sequence(), recorder.impacts
"""

from __future__ import annotations

import numpy as np

from common.messages import Impact, OscMessage, Pose, Skeleton
from services.graphics.sequence import FLOATS_PER_LINK, PoseSequence


class PerformanceRecorder:
    """Collects skeleton, poses (of the newest layout) and impacts (de-duplicated on sender and seq)."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.layout = -1
        self.times: list[float] = []
        self.values: list[np.ndarray] = []
        self.impacts: list[Impact] = []
        self._seen: set[tuple[str, int]] = set()
        self.dropped = 0

    def tap(self, message: OscMessage, source: str, destination: str) -> None:
        """``MemoryBus.tap`` callback; also usable as ``record(message, source)``."""
        self.record(message, source)

    def record(self, message: OscMessage, source: str = "") -> None:
        if isinstance(message, Skeleton):
            if message.layout != self.layout or list(message.names) != self.names:
                self.names, self.layout = list(message.names), message.layout
                self.times, self.values = [], []
        elif isinstance(message, Pose):
            if message.layout != self.layout or len(message.values) != FLOATS_PER_LINK * len(self.names):
                self.dropped += 1
                return
            if self.times and message.time <= self.times[-1]:
                return  # the same pose delivered to several destinations
            self.times.append(message.time)
            self.values.append(np.asarray(message.values, dtype=float).reshape(-1, FLOATS_PER_LINK))
        elif isinstance(message, Impact):
            key = (source, message.seq)
            if key not in self._seen:
                self._seen.add(key)
                self.impacts.append(message)

    def sequence(self) -> PoseSequence:
        """The recorded poses; ``ValueError`` if none were recorded."""
        if not self.times:
            raise ValueError("no poses recorded (did physics publish /batteur/skeleton and /batteur/pose?)")
        return PoseSequence(list(self.names), np.array(self.times), np.stack(self.values))
