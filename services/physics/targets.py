"""Target trajectories streamed ahead of time: knot buffers with cubic Hermite interpolation.

A :class:`Track` holds knots (time s, value (D,), velocity (D,)) and samples
position and velocity at any time (C1 cubic Hermite between knots, the last
knot held with zero velocity after it, the first before it). A new knot at or
before the last one replaces the tail from there (re-planning). Knots older
than the one in use are pruned.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from services.physics.kernels import hermite


class TargetError(ValueError):
    """A target the physics service cannot use: non-finite, wrong length, unreachable, out of limits, past."""


class Track:
    """A Hermite-interpolated trajectory of ``dim`` values (see the module docstring)."""

    def __init__(self, dim: int) -> None:
        self.dim = dim
        self.times: list[float] = []
        self.values: list[np.ndarray] = []
        self.velocities: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.times)

    def add(self, time: float, value: np.ndarray, velocity: np.ndarray) -> None:
        """Append a knot (time seconds, value (dim,), velocity (dim,) per second)."""
        v = np.asarray(value, dtype=float).reshape(-1)
        d = np.asarray(velocity, dtype=float).reshape(-1)
        if v.shape != (self.dim,) or d.shape != (self.dim,):
            raise TargetError(f"expected {self.dim} values and {self.dim} velocities, got {v.size} and {d.size}")
        if not (math.isfinite(time) and np.all(np.isfinite(v)) and np.all(np.isfinite(d))):
            raise TargetError("target time, values and velocities must be finite (no NaN or inf)")
        cut = bisect.bisect_left(self.times, time)
        del self.times[cut:], self.values[cut:], self.velocities[cut:]
        self.times.append(float(time))
        self.values.append(v)
        self.velocities.append(d)

    def extend(self, times: np.ndarray, values: np.ndarray, velocities: np.ndarray) -> None:
        """Add many knots: times (N,), values (N, dim), velocities (N, dim)."""
        t = np.asarray(times, dtype=float)
        if t.ndim != 1 or np.any(np.diff(t) <= 0):
            raise TargetError("knot times must be a strictly increasing 1-D array")
        for k in range(len(t)):
            self.add(float(t[k]), values[k], velocities[k])

    def clear(self) -> None:
        self.times.clear()
        self.values.clear()
        self.velocities.clear()

    @property
    def end_time(self) -> float:
        return self.times[-1] if self.times else -math.inf

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Value (dim,) and velocity (dim,) at time ``t`` seconds. Raises ``IndexError`` when empty."""
        if not self.times:
            raise IndexError("empty track")
        k = bisect.bisect_right(self.times, t) - 1
        if k < 0:
            return self.values[0], np.zeros(self.dim)
        if k >= len(self.times) - 1:
            return self.values[-1], np.zeros(self.dim)
        return hermite(t, self.times[k], self.times[k + 1], self.values[k], self.values[k + 1], self.velocities[k],
                       self.velocities[k + 1])

    def prune(self, before: float) -> None:
        """Drop knots no longer needed to sample at times >= ``before``."""
        k = bisect.bisect_right(self.times, before) - 1
        if k > 0:
            del self.times[:k], self.values[:k], self.velocities[:k]
