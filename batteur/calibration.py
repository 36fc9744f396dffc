"""Feed-forward calibration of a plan from measured performances (physics-independent).

Two corrections, fitted from evaluated renders (:func:`fit_calibration`) and
applied to the limb assignment before the gesture planner runs
(:meth:`Calibration.apply`), so the plan itself anticipates what the
simulated body does:

* **timing** (lag anticipation, closed-loop correction of systematic offsets):
  per kit object and drum event (``"hihat/HIHATPEDAL"``: the pedal closing the
  hi-hat lags differently from a stick on it), and per object as a fallback,
  the median signed timing error (impact time - note time, seconds) of the
  notes matched within 100 ms (so lags beyond the 25 ms window are seen).
  Applying it moves every such note earlier by that much, so the contact
  lands on the written time. Fitting
  from renders made *with* a calibration adds the residual to the old offset
  (each pass of render -> evaluate -> fit closes the loop further).
* **velocity**: per kit object, an affine fit ``impact_velocity = a + b *
  planned_velocity`` (m/s against score velocity in [0, 1]). Applying it
  remaps each note's velocity so every object follows the reference line (the
  fit pooled over all objects): ``v' = (a_ref + b_ref * v - a) / b``, clipped
  to [0, 1]. This equalises objects whose strokes come out harder or softer
  than planned (so pooled loudness rank follows the score).

The calibration file is JSON::

    {"timing_s": {"snare": 0.004, "hihat/HIHATPEDAL": -0.05, ...}, "velocity": {"snare": [a, b], ...},
     "reference": [a, b], "samples": {"snare": 120, ...}}
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from common.datafile import read_text
from common.input_file import file_problem
from common.kit import Kit
from common.output_paths import write_atomically
from common.score.limbs import Assignment

if TYPE_CHECKING:
    from batteur.evaluate import FileResult

MAX_SHIFT_S = 0.05
"""Largest timing correction applied, seconds (larger measured lags are not a systematic offset)."""
PEDAL_EVENTS = frozenset({"HIHATPEDAL", "BASS"})
"""Events played by a foot: their lag does not set the object's fallback lag."""
MIN_SAMPLES = 5
"""Pairs needed on an object before its offset or velocity map is fitted."""

CALIBRATION_KEYS = ("timing_s", "velocity", "reference", "samples")
"""The keys of a calibration JSON file (:meth:`Calibration.save`)."""


WHAT_A_CALIBRATION_IS = ("a calibration file is the JSON `batteur evaluate --fit-calibration FILE` writes (timing "
                         "offsets and velocity maps)")
"""Said after a file's problem when it is not a calibration file: what one is and how one is made."""


@dataclass
class Calibration:
    """Per kit object: timing offset (s) to anticipate and velocity map (see the module docstring)."""

    timing: dict[str, float] = field(default_factory=dict)
    velocity: dict[str, tuple[float, float]] = field(default_factory=dict)
    reference: tuple[float, float] | None = None
    samples: dict[str, int] = field(default_factory=dict)

    def lag(self, instrument: str, event: str = "") -> float:
        """Seconds to play ``event`` notes on ``instrument`` ahead of their written time."""
        value = self.timing.get(f"{instrument}/{event}", self.timing.get(instrument, 0.0))
        return float(np.clip(value, -MAX_SHIFT_S, MAX_SHIFT_S))

    def remap_velocity(self, instrument: str, velocity: float) -> float:
        """Score velocity in [0, 1] to plan with so ``instrument`` follows the reference line."""
        fit = self.velocity.get(instrument)
        if fit is None or self.reference is None or fit[1] <= 1e-6:
            return velocity
        a, b = fit
        ra, rb = self.reference
        return float(np.clip((ra + rb * velocity - a) / b, 0.0, 1.0))

    def apply(self, assignment: Assignment, kit: Kit) -> Assignment:
        """A new assignment with every note shifted by its object's lag and its velocity remapped."""
        from batteur.evaluate import expected_instrument

        notes = []
        for n in assignment.notes:
            inst = expected_instrument(kit, n.event, n.pitch)
            notes.append(dataclasses.replace(n, time=n.time - self.lag(inst, n.event.value),
                                             velocity=self.remap_velocity(inst, n.velocity)))
        notes.sort(key=lambda n: n.time)
        return dataclasses.replace(assignment, notes=notes)

    def save(self, path: Path) -> None:
        data = {"timing_s": self.timing, "velocity": {k: list(v) for k, v in self.velocity.items()},
                "reference": list(self.reference) if self.reference else None, "samples": self.samples}
        # whole or not at all: a fit is often written over the calibration it was made with (docs/evaluation.md)
        write_atomically(Path(path), json.dumps(data, indent=2, sort_keys=True).encode("utf-8"))

    @classmethod
    def load(cls, path: Path) -> Calibration:
        """Read a calibration JSON; ``ValueError`` naming the file when it is not one (a pipe or a device: never
        opened, as a pipe without a writer would wait for one for ever)."""
        problem = file_problem(Path(path), "a calibration file (JSON)")  # said as for every other input
        if problem is not None:
            raise ValueError(f"{path}: {problem}")
        try:
            text = read_text(Path(path))
        except (OSError, ValueError) as exc:  # not UTF-8 text: said as it is, a binary file is no JSON either
            raise ValueError(f"{path}: not a calibration file ({exc})") from exc
        try:
            try:
                data = json.loads(text)
            except json.JSONDecodeError as exc:  # e.g. a kit's YAML: Python's "Expecting value: ... (char 0)"
                raise ValueError(f"not JSON: {exc.msg[:1].lower()}{exc.msg[1:]} at line {exc.lineno}, column "
                                 f"{exc.colno}".replace("expecting value", "expecting a value")) from None
            if not isinstance(data, dict):
                raise ValueError(f"a JSON {type(data).__name__}, not an object")
            unknown = sorted(set(data) - set(CALIBRATION_KEYS))
            if unknown:  # a misspelt key would otherwise calibrate nothing, silently
                raise ValueError(f"unknown keys {unknown}; a calibration has {list(CALIBRATION_KEYS)}")
            ref = data.get("reference")
            cal = cls(timing={str(k): float(v) for k, v in data.get("timing_s", {}).items()},
                      velocity={str(k): (float(v[0]), float(v[1])) for k, v in data.get("velocity", {}).items()},
                      reference=(float(ref[0]), float(ref[1])) if ref else None,
                      samples={str(k): int(v) for k, v in data.get("samples", {}).items()})
            numbers = [*cal.timing.values(), *(x for v in cal.velocity.values() for x in v), *(cal.reference or ())]
            if not all(math.isfinite(x) for x in numbers):
                raise ValueError("a timing offset or velocity fit is not a finite number")
            return cal
        except (OSError, ValueError, TypeError, KeyError, IndexError, AttributeError) as exc:
            raise ValueError(f"{path}: not a calibration file ({exc}); {WHAT_A_CALIBRATION_IS}") from exc


def _affine(x: np.ndarray, y: np.ndarray) -> tuple[float, float] | None:
    if len(x) < MIN_SAMPLES or np.ptp(x) < 1e-3:
        return None
    b, a = np.polyfit(x, y, 1)
    return float(a), float(b)


def fit_calibration(results: Sequence[FileResult], kit: Kit, base: Path | Calibration | None = None) -> Calibration:
    """Fit timing offsets and velocity maps from evaluated performances (25 ms pairs).

    ``base``: the calibration the performances were rendered with (its offsets
    are added to the measured residuals; velocities are fitted against the
    remapped velocities that were actually planned).
    """
    old = Calibration.load(base) if isinstance(base, Path) else (base or Calibration())
    errors: dict[str, list[float]] = defaultdict(list)
    vel: dict[str, list[tuple[float, float]]] = defaultdict(list)
    base_lag: dict[str, float] = {}
    for r in results:
        for i, j in r.pairs_loose:
            note, hit = r.note_refs[i], r.hits[j]
            keys = [f"{note.instrument}/{note.event}"]
            if note.event not in PEDAL_EVENTS:  # a pedal's lag is its own, not the object's
                keys.append(note.instrument)
            for key in keys:
                errors[key].append(hit.time - note.time)
            base_lag[f"{note.instrument}/{note.event}"] = old.lag(note.instrument, note.event)
            base_lag.setdefault(note.instrument, old.timing.get(note.instrument, 0.0))
        for i, j in r.pairs_25:
            note, hit = r.note_refs[i], r.hits[j]
            vel[note.instrument].append((old.remap_velocity(note.instrument, note.velocity), hit.velocity))
    cal = Calibration()
    for key, e in sorted(errors.items()):
        cal.samples[key] = len(e)
        if len(e) >= MIN_SAMPLES:
            cal.timing[key] = round(base_lag.get(key, 0.0) + float(np.median(e)), 6)
    pooled_x = np.array([p[0] for v in vel.values() for p in v])
    pooled_y = np.array([p[1] for v in vel.values() for p in v])
    cal.reference = _affine(pooled_x, pooled_y) if len(pooled_x) else None
    for inst, pairs in vel.items():
        fit = _affine(np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]))
        if fit is not None:
            cal.velocity[inst] = (round(fit[0], 6), round(fit[1], 6))
    return cal
