"""Stroke heights and speeds from score velocity (sources in docs/gestures.md).

Preparatory stick height rises with dynamics: about 7.6 cm at p to 30 cm at
ff and up to vertical (the whole 40 cm stick) at fff; striking speed grows with
the height (about 1.5 m/s at p to 6 m/s at fff). Feet lift the pedal a few
centimetres.
"""

from __future__ import annotations

import numpy as np

from common.gesture.plan import Nuance

# score velocity in [0, 1] (MIDI / 127) -> stick-tip preparatory height, metres
_VEL = np.array([0.0, 0.20, 0.39, 0.63, 0.88, 1.0])  # silence, pp, p, mf, ff, fff
_HEIGHT = np.array([0.02, 0.04, 0.076, 0.16, 0.30, 0.40])

NUANCE_GAIN = {
    Nuance.LEGATO: 1.0,
    Nuance.TENUTO: 1.0,
    Nuance.ACCENT: 1.15,
    Nuance.VERTICAL_ACCENT: 1.3,
    Nuance.STACCATO: 0.8,
}
STICK_LENGTH = 0.40
"""Stick length beyond the fulcrum, metres: the highest a tip can be lifted above the hit point."""


def stick_height(velocity: float, nuance: Nuance = Nuance.TENUTO) -> float:
    """Preparatory stick-tip height (metres) for a score velocity in [0, 1]."""
    h = float(np.interp(velocity, _VEL, _HEIGHT)) * NUANCE_GAIN[nuance]
    return min(h, STICK_LENGTH)


def stick_speed(velocity: float, nuance: Nuance = Nuance.TENUTO) -> float:
    """Stick-tip speed into the head at contact (m/s) for a score velocity in [0, 1]."""
    return 0.5 + 14.0 * stick_height(velocity, nuance)


def tempo_cap(height: float, interval: float) -> float:
    """Height reachable in an inter-onset ``interval`` (seconds): at most 0.9 m per second of interval."""
    return max(0.01, min(height, 0.9 * interval))


def foot_height(velocity: float) -> float:
    """Footboard lift before a pedal stroke, metres."""
    return 0.02 + 0.06 * velocity


def foot_speed(velocity: float) -> float:
    """Footboard speed at the bottom of a pedal stroke, m/s."""
    return 0.3 + 2.0 * velocity


def chick_speed(velocity: float) -> float:
    """Foot speed (m/s) where a hi-hat pedal stroke closes the cymbals, for a score velocity in [0, 1].

    The plates meet at about the footboard toe's speed (a direct pull: physics' ``hihat_gap``; until 8 Dec a sixth
    to a quarter of the foot's speed); the softest chick must still close them faster than a foot letting the pedal
    down after an open note (which interaction takes for silent), so the range starts higher than a kick's: with
    ``foot_speed`` and the linear pull before a chick at velocity 0.16 closed at 0.098 m/s and was not heard (soft
    pedal notes were most of the 380 hi-hat pedal notes without a contact on 76 Groove validation files).
    """
    return 0.8 + 1.5 * velocity
