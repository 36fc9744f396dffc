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

from collections.abc import Callable

import numpy as np

from common.messages import Impact, OscMessage, Pose, Skeleton
from services.graphics.sequence import FLOATS_PER_LINK, PoseSequence


class PerformanceRecorder:
    """Collects skeleton, poses (of the newest layout) and impacts (de-duplicated on sender and seq).

    ``on_skeleton(names)`` is told each new skeleton and ``on_pose(time s, values (L, 7))`` each pose taken (a
    writer streaming them, e.g. :class:`~services.graphics.export.bvh.BvhStream`); ``keep_poses=False`` keeps
    none in memory (no :meth:`sequence`)."""

    def __init__(self, keep_poses: bool = True, on_skeleton: Callable[[list[str]], None] | None = None,
                 on_pose: Callable[[float, np.ndarray], None] | None = None) -> None:
        self.names: list[str] = []
        self.layout = -1
        self.times: list[float] = []
        self.values: list[np.ndarray] = []
        self.impacts: list[Impact] = []
        self._seen: set[tuple[str, int]] = set()
        self.dropped = 0
        self.keep_poses = keep_poses
        self.on_skeleton = on_skeleton
        self.on_pose = on_pose
        self._last_time: float | None = None

    def tap(self, message: OscMessage, source: str, destination: str) -> None:
        """``MemoryBus.tap`` callback; also usable as ``record(message, source)``."""
        self.record(message, source)

    def record(self, message: OscMessage, source: str = "") -> None:
        if isinstance(message, Skeleton):
            if message.layout != self.layout or list(message.names) != self.names:
                self.names, self.layout = list(message.names), message.layout
                self.times, self.values, self._last_time = [], [], None
                if self.on_skeleton is not None:
                    self.on_skeleton(self.names)
        elif isinstance(message, Pose):
            if message.layout != self.layout or len(message.values) != FLOATS_PER_LINK * len(self.names):
                self.dropped += 1
                return
            if self._last_time is not None and message.time <= self._last_time:
                return  # the same pose delivered to several destinations
            self._last_time = message.time
            values = np.asarray(message.values, dtype=float).reshape(-1, FLOATS_PER_LINK)
            if self.on_pose is not None:
                self.on_pose(message.time, values)
            if self.keep_poses:
                self.times.append(message.time)
                self.values.append(values)
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
