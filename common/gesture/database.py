"""The gesture database: percussion gesture units and their stroke profiles.

A unit is a BVH clip plus a JSON metadata file with the same stem::

    {"grip": "german", "nuance": "tenuto", "tempo_bpm": 100, "rate_hz": 250,
     "contact_frames": [0, 150, 300], "tip": "Stick_end", "up_axis": "y"}

From the clip the loader takes the stick tip's height (forward kinematics of
the ``tip`` joint or end site, along ``up_axis``) over the first stroke cycle
(between the first two contact frames), relative to the contact height and
normalised to a peak of 1: the unit's *profile* h(phase), phase in [0, 1],
with its derivative. The planner time-warps that profile to each inter-onset
interval and scales it by the stroke's preparatory height.

User captures load with :func:`load_unit` (metadata optional: contact frames
are then detected as the tip's height minima).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from common.datafile import parse_file
from common.gesture.bvh import Bvh, BvhError, forward_kinematics, read_bvh
from common.gesture.plan import Grip, Nuance
from common.gesture.synth import UNITS_DIR
from common.input_file import NO_SUCH_FILE, file_problem


@dataclass(frozen=True)
class GestureUnit:
    """One gesture unit.

    Parameters
    ----------
    name : str
        File stem.
    grip, nuance : Grip, Nuance
    tempo_bpm : float
        Strokes per minute the unit was captured at (inter-onset ``60 / tempo_bpm`` s).
    rate_hz : float
        Capture rate (250 Hz for the shipped units).
    contact_frames : tuple[int, ...]
        Frame indices of the stick contacts.
    contact_duration : float
        Stick-head contact time, seconds.
    tip_height : np.ndarray, shape (F,)
        Stick-tip height above the first contact, metres.
    profile : CubicSpline
        Normalised height over the first cycle, phase in [0, 1] -> [0, 1].
    apex_phase : float
        Phase of the profile's maximum.
    """

    name: str
    grip: Grip
    nuance: Nuance
    tempo_bpm: float
    rate_hz: float
    contact_frames: tuple[int, ...]
    contact_duration: float
    tip_height: np.ndarray
    profile: CubicSpline
    apex_phase: float

    @property
    def period(self) -> float:
        """The captured inter-onset interval, seconds (first cycle)."""
        return (self.contact_frames[1] - self.contact_frames[0]) / self.rate_hz


PROFILE_FLOOR = 0.01
"""Profile values at or below this (fraction of the peak) count as the tip resting at the contact height."""


def _profile(height: np.ndarray, c0: int, c1: int) -> tuple[CubicSpline, float]:
    cycle = np.maximum(height[c0 : c1 + 1] - height[c0], 0.0)
    peak = float(cycle.max())
    if peak <= 1e-6:
        raise BvhError("the tip does not rise between the first two contacts")
    values = cycle / peak
    # The tip may rest on (or, clamped, dip to) the contact height for a while after one contact and before the
    # next (the proximal joints lead the stick). Played as is, the planned tip would touch the surface early and
    # linger after the stroke (extra contacts). Keep the part of the cycle where the tip is up, stretched over
    # the whole cycle, so the profile is positive strictly between its two contacts.
    up = np.flatnonzero(values > PROFILE_FLOOR)
    values = values[max(int(up[0]) - 1, 0): min(int(up[-1]) + 1, len(values) - 1) + 1]
    phase = np.linspace(0.0, 1.0, len(values))
    values[0] = values[-1] = 0.0
    spline = CubicSpline(phase, values)
    return spline, float(phase[int(np.argmax(values))])


def load_unit(
    bvh_path: str | Path,
    tip: str | None = None,
    up_axis: str | None = None,
    contact_frames: list[int] | None = None,
    grip: Grip | str | None = None,
    nuance: Nuance | str | None = None,
    tempo_bpm: float | None = None,
) -> GestureUnit:
    """Load a unit from BVH (+ the JSON metadata next to it, when present).

    Arguments override the metadata. Without contact frames, the tip's height
    minima are taken as contacts. Raises :class:`BvhError` on a bad file.
    """
    path = Path(bvh_path)
    meta: dict[str, object] = {}
    meta_path = path.with_suffix(".json")
    problem = file_problem(meta_path, "a metadata file (JSON)")
    if problem not in (None, NO_SUCH_FILE):  # a folder or a pipe of that name: said, never opened (a pipe blocks)
        raise BvhError(f"{meta_path}: {problem}")
    if problem is None:
        try:
            meta = parse_file(meta_path)
        except ValueError as exc:  # not UTF-8, not JSON
            raise BvhError(f"{meta_path}: bad metadata JSON ({exc})") from None
        if not isinstance(meta, dict):
            raise BvhError(f"{meta_path}: bad metadata JSON (not an object)")
    bvh: Bvh = read_bvh(path)
    positions = forward_kinematics(bvh)
    tip_name = tip or str(meta.get("tip", ""))
    if not tip_name:
        ends = [k for k in positions if k.endswith("_end")]
        if not ends:
            raise BvhError(f"{path}: no end site; name the stick tip joint")
        tip_name = ends[-1]
    if tip_name not in positions:
        raise BvhError(f"{path}: no joint or end site {tip_name!r} (have {', '.join(positions)})")
    axis = "xyz".index(str(up_axis or meta.get("up_axis", "y")).lower())
    height = positions[tip_name][:, axis]
    rate = float(meta.get("rate_hz", bvh.rate_hz))  # type: ignore[arg-type]
    frames = contact_frames or [int(f) for f in meta.get("contact_frames", [])]  # type: ignore[attr-defined]
    if not frames:
        # imported here: scipy.signal brings scipy.stats (0.4 s of CPU to import), which every planning process and
        # physics node paid at start for shipped units that all name their contact frames
        from scipy.signal import find_peaks

        minima, _ = find_peaks(-height, distance=max(1, int(0.05 * rate)), prominence=0.01)
        frames = [int(f) for f in minima]
    if len(frames) < 2:
        raise BvhError(f"{path}: need at least two contacts to make a stroke cycle (found {len(frames)})")
    profile, apex = _profile(height, frames[0], frames[1])
    period = (frames[1] - frames[0]) / rate
    return GestureUnit(
        name=path.stem,
        grip=Grip(str(grip or meta.get("grip", "german"))),
        nuance=Nuance(str(nuance or meta.get("nuance", "legato"))),
        tempo_bpm=float(tempo_bpm or meta.get("tempo_bpm", 60.0 / period)),  # type: ignore[arg-type]
        rate_hz=rate,
        contact_frames=tuple(frames),
        contact_duration=float(meta.get("contact_duration_s", 0.004)),  # type: ignore[arg-type]
        tip_height=height - height[frames[0]],
        profile=profile,
        apex_phase=apex,
    )


class GestureDatabase:
    """Gesture units indexed by grip and nuance; pick one by tempo."""

    def __init__(self, units: list[GestureUnit]) -> None:
        if not units:
            raise ValueError("a gesture database needs at least one unit")
        self.units = units
        self._by_key: dict[tuple[Grip, Nuance], list[GestureUnit]] = {}
        for u in units:
            self._by_key.setdefault((u.grip, u.nuance), []).append(u)

    @classmethod
    def load(cls, *dirs: str | Path) -> GestureDatabase:
        """Load the shipped units, plus every ``*.bvh`` in ``dirs`` (user captures)."""
        paths = sorted(UNITS_DIR.glob("*.bvh"))
        for d in dirs:
            paths.extend(sorted(Path(d).glob("*.bvh")))
        return cls([load_unit(p) for p in paths])

    def select(self, grip: Grip, nuance: Nuance, interval: float) -> GestureUnit:
        """The unit of ``grip``/``nuance`` whose captured interval is nearest ``interval`` (log scale).

        Falls back to any grip, then to any unit, when the pair is missing.
        """
        candidates = self._by_key.get((grip, nuance)) or [u for u in self.units if u.nuance == nuance] or self.units
        target = math.log(max(interval, 1e-3))
        return min(candidates, key=lambda u: abs(math.log(u.period) - target))


_DEFAULT: GestureDatabase | None = None


def default_database() -> GestureDatabase:
    """The shipped database, loaded once."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = GestureDatabase.load()
    return _DEFAULT
