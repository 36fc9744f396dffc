"""Further recorded acoustic kits for training, from Debian packages other than hydrogen-drumkits.

Only six of the Hydrogen training kits are acoustic; these add two more (``train_net --more-kits``):

- ``sonicpi-menegass``: the acoustic kit of Sonic Pi's samples (package sonic-pi-samples; recorded by
  menegass, freesound.org, CC0), a soft and a hard velocity layer per drum.
- ``sf-avl-red-zeppelin``: x42's AVL Red Zeppelin soundfont (package avldrums.lv2-soundfont; Glen MacArthur,
  CC-BY-SA-3.0), rendered by FluidSynth at five velocities. Its Sabian hi-hats and Zildjian splash are left
  out: they are the held-out kit's own recordings (normalised correlation 0.84-0.996 with The Black Pearl
  1.0's samples over their first 50 ms, against 0.13 or less for other kits' hi-hats), so only its kick,
  snare, side stick, rimshot, two toms, crash and ride are used.
"""

from __future__ import annotations

from pathlib import Path

import soundfile as sf

from services.recogniser.audio import resample, to_mono
from services.recogniser.training.kits import RENDER_RATE, Instrument, Kit, Layer
from services.recogniser.training.one_shots import trimmed
from services.recogniser.training.soundfont import SoundfontKit, render_font_kit, require_font

SONIC_PI_DIR = Path("/usr/share/sonic-pi/samples")

SONIC_PI_KIT: dict[str, tuple[str, ...]] = {
    "kick": ("drum_bass_soft", "drum_bass_hard"),
    "snare": ("drum_snare_soft", "drum_snare_hard"),
    "hh_closed": ("drum_cymbal_closed",),
    "hh_pedal": ("drum_cymbal_pedal",),
    "hh_open": ("drum_cymbal_open",),
    "tom_high": ("drum_tom_hi_soft", "drum_tom_hi_hard"),
    "tom_mid": ("drum_tom_mid_soft", "drum_tom_mid_hard"),
    "tom_floor": ("drum_tom_lo_soft", "drum_tom_lo_hard"),
    "crash": ("drum_cymbal_soft", "drum_cymbal_hard"),
    "splash": ("drum_splash_soft", "drum_splash_hard"),
}
"""Instrument kind -> Sonic Pi sample names (FLAC), softest first: one velocity layer each, split evenly."""

AVL_RED_ZEPPELIN = SoundfontKit(
    Path("/usr/share/sounds/sf2/Red_Zeppelin_4_LV2.sf2"), 0, "CC-BY-SA-3.0", "avldrums.lv2-soundfont", channel=0,
    notes={"kick": 36, "snare": 38, "stick": 37, "rimshot": 40, "tom_high": 45, "tom_floor": 41, "crash": 49,
           "ride": 51, "ride_bell": 53},
)
"""The AVL Red Zeppelin kit: a bank-0 preset (played on channel 1); its 14" rack tom plays the high tom."""

FONT_KITS: dict[str, SoundfontKit] = {"sf-avl-red-zeppelin": AVL_RED_ZEPPELIN}
"""The further kits FluidSynth renders from a soundfont: kit name -> font."""
MORE_KITS: dict[str, str] = {"sonicpi-menegass": "CC0", **{n: f.licence for n, f in FONT_KITS.items()}}
"""Kit name -> licence."""


class MoreKitsMissingError(RuntimeError):
    """A package the further kits come from is not installed."""


def require_more_kits() -> None:
    """Raise :class:`MoreKitsMissingError` (or the soundfont's error) with an install hint unless every
    further kit can be made."""
    require_sonic_pi()
    require_font(AVL_RED_ZEPPELIN)


def require_sonic_pi() -> None:
    """Raise :class:`MoreKitsMissingError` with an install hint unless Sonic Pi's drum samples are installed."""
    if not all((SONIC_PI_DIR / f"{n}.flac").exists() for names in SONIC_PI_KIT.values() for n in names):
        raise MoreKitsMissingError(f"Sonic Pi's drum samples not found in {SONIC_PI_DIR}: install them with "
                                   "`apt-get install sonic-pi-samples` (Debian/Ubuntu)")


def load_more_kit(name: str) -> Kit:
    """The further kit ``name`` (a key of :data:`MORE_KITS`) at :data:`RENDER_RATE`.

    Raises
    ------
    KeyError
        ``name`` is not one of them.
    MoreKitsMissingError, SoundfontsMissingError
        its package is not installed.
    """
    if name in FONT_KITS:
        return render_font_kit(name, FONT_KITS[name])
    if name != "sonicpi-menegass":
        raise KeyError(name)
    require_sonic_pi()
    kit = Kit(name=name, licence=MORE_KITS[name])
    for kind, names in SONIC_PI_KIT.items():
        layers = []
        for i, sample in enumerate(names):
            audio, rate = sf.read(str(SONIC_PI_DIR / f"{sample}.flac"), dtype="float32", always_2d=False)
            one = trimmed(resample(to_mono(audio), int(rate), RENDER_RATE))
            if one is not None:
                layers.append(Layer(i / len(names), (i + 1) / len(names), 1.0, one))
        kit.instruments[kind] = [Instrument(f"{name} {kind}", kind, 1.0, layers)]
    return kit


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
