"""Build the shipped gesture database from published drumming kinematics.

No percussion motion capture is available to Batteur, so the units in
``common/gesture/units/`` are synthesised (see docs/gestures.md for every
number's source). Each unit is one grip x nuance x tempo: two stroke cycles at
250 Hz of a sagittal forearm -> hand -> stick chain, written as BVH (metres,
y up, z forward) plus a JSON metadata file (grip, nuance, tempo, contact
frame indices, contact duration).

Regenerate with ``python -m common.gesture.synth``.
"""

from __future__ import annotations

import os
import signal

PROG = "python -m common.gesture.synth"
"""The command's name in its usage and error lines."""


def _quit_unwritten(signum: int, frame: object) -> None:
    """SIGINT while the modules below load (about half a second: NumPy, SciPy): nothing is written yet, so leave
    at once. A KeyboardInterrupt raised there would print a traceback, or land in importlib's callbacks."""
    os.write(2, f"{PROG}: interrupted: nothing written\n".encode())
    os._exit(130)


if __name__ == "__main__":  # the command: a Ctrl-C while its modules load must not print a traceback
    signal.signal(signal.SIGINT, _quit_unwritten)

# after the handler (E402)
import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from common.gesture.bvh import Bvh, BvhJoint, write_bvh  # noqa: E402
from common.gesture.plan import Grip, Nuance  # noqa: E402

UNITS_DIR = Path(__file__).parent / "units"
RATE_HZ = 250.0
TEMPI_BPM = (60, 100, 160, 240)
"""Tempi of the shipped units: one stroke per beat, inter-onset 1.0 s to 0.25 s."""
FOREARM, HAND, STICK = 0.26, 0.08, 0.40
"""Segment lengths, metres: forearm (elbow to wrist), hand (wrist to fulcrum), stick beyond the fulcrum."""

# Share of the stick's elevation made by each joint, and how far (fraction of
# the cycle, capped in seconds) the proximal joints lead the stick: the whiplash.
GRIP_STYLE: dict[Grip, dict[str, float]] = {
    Grip.GERMAN: {"forearm": 0.30, "wrist": 0.55, "fingers": 0.15, "lead_s": 0.030, "height": 1.1, "contact_s": 0.004},
    Grip.FRENCH: {"forearm": 0.15, "wrist": 0.35, "fingers": 0.50, "lead_s": 0.020, "height": 0.9, "contact_s": 0.005},
}
NUANCE_HEIGHT = {
    Nuance.LEGATO: 1.0,
    Nuance.TENUTO: 1.0,
    Nuance.ACCENT: 1.3,
    Nuance.VERTICAL_ACCENT: 1.6,
    Nuance.STACCATO: 0.7,
}
AMPLITUDE_DEG = 28.0
"""Stick elevation at the top of a mezzo-forte unit, degrees (about 15 cm tip lift)."""


def _smooth(x: np.ndarray) -> np.ndarray:
    """Quintic smoothstep on [0, 1] (zero velocity and acceleration at both ends)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10 - 15 * x + 6 * x * x)


def _ramp(phi: np.ndarray, a: float, b: float) -> np.ndarray:
    return _smooth((phi - a) / (b - a))


def shape(nuance: Nuance, phi: np.ndarray) -> np.ndarray:
    """Normalised stick elevation (0 at contact, 1 at the top) over a cycle, phase in [0, 1)."""
    phi = np.mod(phi, 1.0)
    if nuance == Nuance.LEGATO:  # free rebound, symmetric and continuous
        return np.asarray(np.sin(np.pi * phi) ** 1.5)
    if nuance == Nuance.TENUTO:  # up, dwell at the top, down
        return _ramp(phi, 0.0, 0.35) - _ramp(phi, 0.7, 1.0)
    if nuance == Nuance.ACCENT:  # rebound damped low (down stroke), late up stroke, fast fall
        return 0.25 * _ramp(phi, 0.0, 0.15) + 0.75 * _ramp(phi, 0.45, 0.8) - _ramp(phi, 0.82, 1.0)
    if nuance == Nuance.VERTICAL_ACCENT:  # lifted high early, held, very fast fall
        return _ramp(phi, 0.0, 0.3) - _ramp(phi, 0.86, 1.0)
    # staccato: quick rebound, stick stopped at mid height, short fall
    return 0.6 * _ramp(phi, 0.0, 0.12) + 0.4 * _ramp(phi, 0.5, 0.75) - _ramp(phi, 0.85, 1.0)


def _tempo_blend(bpm: float, nuance: Nuance, phi: np.ndarray) -> np.ndarray:
    """At fast tempi dwell disappears: blend toward the legato shape."""
    w = float(np.clip((bpm - 60.0) / 240.0, 0.0, 0.8))
    return np.asarray((1 - w) * shape(nuance, phi) + w * shape(Nuance.LEGATO, phi))


def make_unit(grip: Grip, nuance: Nuance, bpm: float, cycles: int = 2) -> tuple[Bvh, dict[str, object]]:
    """One unit: BVH of ``cycles`` strokes at ``bpm`` and its metadata."""
    style = GRIP_STYLE[grip]
    ioi = 60.0 / bpm
    per_cycle = int(round(ioi * RATE_HZ))
    frames = per_cycle * cycles + 1
    t = np.arange(frames) / RATE_HZ
    phi = t / (per_cycle / RATE_HZ)
    # the proximal joints lead; tempo lowers the lift (less time to raise the stick)
    lift = AMPLITUDE_DEG * NUANCE_HEIGHT[nuance] * style["height"] * min(1.0, 0.35 + 0.65 * ioi)
    lead = min(style["lead_s"], 0.12 * ioi) / ioi
    fore = -10.0 + lift * style["forearm"] * _tempo_blend(bpm, nuance, phi + 2 * lead)
    wrist = 5.0 + lift * style["wrist"] * _tempo_blend(bpm, nuance, phi + lead)
    fingers = -5.0 + lift * style["fingers"] * _tempo_blend(bpm, nuance, phi)
    zeros = np.zeros(frames)
    # Xrotation: positive turns +z toward -y, so elevation is a negative X rotation
    motion = np.stack([zeros, zeros, zeros, zeros, -fore, zeros, zeros, -wrist, zeros, zeros, -fingers, zeros], axis=1)
    joints = [
        BvhJoint(
            "Forearm",
            np.zeros(3),
            ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"],
            -1,
            children=[1],
        ),
        BvhJoint("Hand", np.array([0.0, 0.0, FOREARM]), ["Zrotation", "Xrotation", "Yrotation"], 0, children=[2]),
        BvhJoint(
            "Stick",
            np.array([0.0, 0.0, HAND]),
            ["Zrotation", "Xrotation", "Yrotation"],
            1,
            end_site=np.array([0.0, 0.0, STICK]),
        ),
    ]
    meta: dict[str, object] = {
        "grip": grip.value,
        "nuance": nuance.value,
        "tempo_bpm": bpm,
        "rate_hz": RATE_HZ,
        "contact_frames": [k * per_cycle for k in range(cycles + 1)],
        "contact_duration_s": style["contact_s"],
        "tip": "Stick_end",
        "up_axis": "y",
        "units": "m",
        "source": "synthesised from published drumming kinematics, see docs/gestures.md",
    }
    return Bvh(joints, 1.0 / RATE_HZ, motion), meta


def unit_name(grip: Grip, nuance: Nuance, bpm: float) -> str:
    return f"{grip.value}_{nuance.value}_{int(bpm)}"


def build(out_dir: Path = UNITS_DIR) -> list[Path]:
    """Write every grip x nuance x tempo unit (BVH + JSON) into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for grip in Grip:
        for nuance in Nuance:
            for bpm in TEMPI_BPM:
                bvh, meta = make_unit(grip, nuance, bpm)
                stem = out_dir / unit_name(grip, nuance, bpm)
                stem.with_suffix(".bvh").write_text(write_bvh(bvh), encoding="utf-8")
                stem.with_suffix(".json").write_text(json.dumps(meta, indent=1) + "\n", encoding="utf-8")
                written.append(stem.with_suffix(".bvh"))
    return written


def main(argv: list[str] | None = None) -> int:
    """``python -m common.gesture.synth [--out DIR]``: (re)write the units; the shipped ones by default."""
    if signal.getsignal(signal.SIGINT) is _quit_unwritten:  # loaded: from here a Ctrl-C is a KeyboardInterrupt
        signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = argparse.ArgumentParser(prog=PROG,
                                     description="Synthesise the gesture database's units (grip x nuance x tempo, "
                                     "BVH + JSON; docs/gestures.md) into DIR, the shipped folder by default.")
    parser.add_argument("--out", type=Path, default=UNITS_DIR, metavar="DIR",
                        help=f"folder to write the units into (default: {UNITS_DIR})")
    args = parser.parse_args(argv)
    try:
        paths = build(args.out)
    except OSError as exc:  # a folder it cannot write in: 1 (README, "Exit status")
        print(f"{parser.prog}: error: --out {args.out}: cannot write the units ({exc.strerror or exc})",
              file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # one line, not a traceback; the units written before it stay
        print(f"{parser.prog}: interrupted", file=sys.stderr)
        return 130
    print(f"wrote {len(paths)} units to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
