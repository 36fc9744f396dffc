"""Recorded drum kits from Debian's hydrogen-drumkits package, mapped onto the recogniser's classes.

Only kits whose licence is free (GPL-2, CC0, CC-BY, CC-BY-SA; see docs/recogniser.md)
are listed in :data:`KITS`. Instrument names are mapped to *kinds* (kick, snare,
side stick, hi-hat closed/open/pedal, toms, crash, china, splash, ride, ride bell)
by regular expressions; a Groove MIDI pitch picks a kind, falling back to the
class's main kind when the kit lacks it.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import soundfile as sf

from services.recogniser.audio import resample, to_mono

DRUMKITS_DIR = Path("/usr/share/hydrogen/data/drumkits")

KITS: dict[str, str] = {
    "Audiophob": "CC0",
    "BJA_Pacific": "CC-BY-SA-3.0-US",
    "ColomboAcousticDrumkit": "GPL-2+ with composition exception",
    "ElectricEmpireKit": "GPL-2+",
    "ForzeeStereo": "GPL-2",
    "HardElectro1": "GPL-2+",
    "Millo-Drums_v.1": "GPL-2",
    "Millo_MultiLayered2": "GPL-2",
    "Millo_MultiLayered3": "GPL-2",
    "The Black Pearl 1.0": "GPL-2",
    "VariBreaks": "GPL-2+",
    "rumpf_kit_z01_h2": "CC-BY-3.0",
}
"""Kit folder -> licence (from /usr/share/doc/hydrogen-drumkits/copyright)."""

TEST_KITS = ("The Black Pearl 1.0",)
"""Kits never used for training: the benchmark renders its audio with these."""

VALID_KITS = ("Millo_MultiLayered2",)
"""Kits kept out of fitting to choose decision thresholds on (a validation kit, not the test kit)."""

TRAIN_KITS = tuple(k for k in KITS if k not in TEST_KITS and k not in VALID_KITS)


class KitsMissingError(RuntimeError):
    """The hydrogen-drumkits samples the training and the benchmark render with are not installed."""


def require_kits(names: tuple[str, ...] | list[str], root: Path = DRUMKITS_DIR) -> None:
    """Raise :class:`KitsMissingError` with an install hint unless every kit folder in ``names`` exists."""
    missing = [n for n in names if not (root / n / "drumkit.xml").exists()]
    if missing:
        installed = sorted(p.parent.name for p in root.glob("*/drumkit.xml")) if root.is_dir() else []
        there = f" (installed there: {', '.join(installed)})" if installed else ""  # a misspelt name shows
        raise KitsMissingError(f"hydrogen drum kits not found in {root}: {', '.join(missing)}{there}. "
                               "Install them with `apt-get install hydrogen-drumkits` (Debian/Ubuntu).")

RENDER_RATE = 44100
"""Sample rate of training and benchmark audio, Hz: kits are loaded and excerpts rendered at it (a network
whose band analysis reads another rate gets the audio resampled; the live classifier reads 22,050 Hz)."""

# kind -> class index (see services.recogniser.classes.CLASSES)
KIND_CLASS = {
    "kick": 0, "snare": 1, "stick": 1, "rimshot": 1, "hh_closed": 2, "hh_pedal": 2, "hh_open": 3,
    "tom_high": 4, "tom_mid": 5, "tom_floor": 6, "crash": 7, "china": 7, "splash": 7, "ride": 8, "ride_bell": 8,
}
CLASS_MAIN_KIND = ("kick", "snare", "hh_closed", "hh_open", "tom_high", "tom_mid", "tom_floor", "crash", "ride")

PITCH_KIND = {
    35: "kick", 36: "kick", 37: "stick", 38: "snare", 40: "rimshot", 22: "hh_closed", 42: "hh_closed",
    44: "hh_pedal", 26: "hh_open", 46: "hh_open", 48: "tom_high", 50: "tom_high", 45: "tom_mid", 47: "tom_mid",
    41: "tom_floor", 43: "tom_floor", 58: "tom_floor", 49: "crash", 57: "crash", 52: "china", 55: "splash",
    51: "ride", 59: "ride", 53: "ride_bell",
}
"""Groove MIDI pitch -> preferred instrument kind."""

_EXCLUDE = re.compile(r"roll|clap|snap|cowbell|tamb|agogo|conga|whistle|zap|\bfx\b|^click|swish|choke|flink|hat free|"
                      r"^\d+$|^none$|sample:|^drum [12]$", re.I)
_RULES: list[tuple[str, re.Pattern[str]]] = [
    ("hh_pedal", re.compile(r"(hat|hh).*(pedal|\bpd\b)|pedal.*(hh|hat)", re.I)),
    ("hh_open", re.compile(r"(hat|hh).*(open|\bop\b|semi)|open.*(hh|hat)|ohh", re.I)),
    ("hh_closed", re.compile(r"hat|\bhh\b", re.I)),
    ("kick", re.compile(r"kick|bass ?drum|bassdrum|\bbd\b", re.I)),
    ("rimshot", re.compile(r"snare.*rimshot", re.I)),
    ("stick", re.compile(r"stick|rim click", re.I)),
    ("snare", re.compile(r"snare", re.I)),
    ("ride_bell", re.compile(r"(ride|paiste).*(bell|cup)|ride-cup|ride bell", re.I)),
    ("ride", re.compile(r"ride", re.I)),
    ("china", re.compile(r"china", re.I)),
    ("splash", re.compile(r"splash", re.I)),
    ("crash", re.compile(r"crash|cymbal", re.I)),
    ("tom_floor", re.compile(r"tom.*(floor|low)|(floor|low).*tom", re.I)),
    ("tom_mid", re.compile(r"tom.*(mid|middle|\b2\b)|(mid|middle).*tom", re.I)),
    ("tom_high", re.compile(r"tom", re.I)),
]


def kind_of(name: str) -> str | None:
    """Instrument kind of a Hydrogen instrument name, or None if it is not used."""
    if _EXCLUDE.search(name.strip()):
        return None
    for kind, rule in _RULES:
        if rule.search(name):
            return kind
    return None


@dataclass
class Layer:
    """One velocity layer: velocity range 0..1 and its sample (mono, RENDER_RATE)."""

    lo: float
    hi: float
    gain: float
    audio: np.ndarray


@dataclass
class Instrument:
    name: str
    kind: str
    gain: float
    layers: list[Layer]

    def layer(self, velocity: float, rng: np.random.Generator) -> Layer:
        """A layer for a velocity 0..1 (random among the fitting ones, else the nearest)."""
        fits = [la for la in self.layers if la.lo <= velocity <= la.hi] or [
            min(self.layers, key=lambda la: min(abs(la.lo - velocity), abs(la.hi - velocity)))
        ]
        return fits[int(rng.integers(len(fits)))]


@dataclass
class Kit:
    name: str
    licence: str
    instruments: dict[str, list[Instrument]] = field(default_factory=dict)

    def copy(self) -> Kit:
        """A copy whose instrument lists can be replaced without touching this kit's (the instruments and
        their samples are shared)."""
        return Kit(self.name, self.licence, dict(self.instruments))

    def choose(self, kind: str, rng: np.random.Generator) -> Instrument | None:
        """An instrument of that kind, else of the main kind of its class, else None."""
        options = self.instruments.get(kind) or self.instruments.get(CLASS_MAIN_KIND[KIND_CLASS[kind]])
        if not options:
            return None
        return options[int(rng.integers(len(options)))]


def _text(el: ET.Element, tag: str, ns: str, default: str = "") -> str:
    x = el.find(ns + tag)
    return x.text.strip() if x is not None and x.text else default


def _read_sample(path: Path) -> np.ndarray:
    data, sr = sf.read(str(path), dtype="float32", always_2d=False)
    mono = resample(to_mono(np.asarray(data, np.float32)), int(sr), RENDER_RATE)
    # trim leading silence (some samples start late) so the onset is at the start
    above = np.flatnonzero(np.abs(mono) > 10 ** (-50 / 20) * max(float(np.max(np.abs(mono))), 1e-9))
    return mono[int(above[0]) if above.size else 0 :]


def load_kit(name: str, root: Path = DRUMKITS_DIR) -> Kit:
    """Load a Hydrogen kit's mapped instruments (samples resampled to RENDER_RATE, mono)."""
    folder = root / name
    tree = ET.parse(folder / "drumkit.xml")
    r = tree.getroot()
    ns = r.tag[: r.tag.index("}") + 1] if r.tag.startswith("{") else ""
    kit = Kit(name=name, licence=KITS.get(name, "?"))
    for inst in r.iter(ns + "instrument"):
        iname = _text(inst, "name", ns)
        kind = kind_of(iname)
        if kind is None:
            continue
        gain = float(_text(inst, "volume", ns, "1") or 1) * float(_text(inst, "gain", ns, "1") or 1)
        layers: list[Layer] = []
        for la in inst.iter(ns + "layer"):
            fn = _text(la, "filename", ns)
            if fn and (folder / fn).exists():
                layers.append(Layer(float(_text(la, "min", ns, "0")), float(_text(la, "max", ns, "1")),
                                    float(_text(la, "gain", ns, "1")), _read_sample(folder / fn)))
        if not layers:
            fn = _text(inst, "filename", ns)
            if fn and (folder / fn).exists():
                layers.append(Layer(0.0, 1.0, 1.0, _read_sample(folder / fn)))
        if layers:
            kit.instruments.setdefault(kind, []).append(Instrument(iname, kind, gain, layers))
    return kit


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
