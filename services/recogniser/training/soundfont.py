"""Training kits rendered from the drum kits of General MIDI soundfonts (Debian packages) with FluidSynth.

Each kit is a soundfont and a drum-kit program (channel 10, bank 128): the one-shot file of
:mod:`.one_shots` is rendered dry (no reverb or chorus) by the ``fluidsynth`` command and cut into
velocity layers. The fonts' drum samples are recorded kits other than the Hydrogen ones, so they add
snares, hi-hats and cymbals recorded elsewhere to what the network is fitted on. Only kits whose
snare, hi-hats and kick differ from each other's are listed (a font's kits share many samples:
FluidR3's Room kit is its Standard kit's, its Brush kit plays brushes).
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import soundfile as sf

from services.recogniser.training.kits import Kit
from services.recogniser.training.one_shots import cut_kit, write_strike_file

RENDER_RATE_HZ = 44_100
"""FluidSynth's output rate, Hz (the kit is resampled to the recogniser's rate when cut)."""
START_S = 0.5
"""The first strike's time in the one-shot file, seconds."""


@dataclass(frozen=True)
class SoundfontKit:
    """A General MIDI soundfont's drum kit: the font file, its drum-kit program and the font's licence."""

    path: Path
    program: int
    licence: str
    package: str
    """Debian package that installs the font."""
    channel: int = 9
    """MIDI channel (0-based) the strikes are played on: 9, General MIDI's drums (bank 128), or a melodic
    channel for a font whose kit is a bank-0 preset."""
    notes: dict[str, int] | None = None
    """Instrument kind -> the note that plays it, for the kinds taken from the font (default: every kind, at
    its General MIDI note, :data:`~.one_shots.KIND_NOTE`)."""


_FLUID = Path("/usr/share/sounds/sf2/FluidR3_GM.sf2")
_MUSESCORE = Path("/usr/share/sounds/sf3/MuseScore_General.sf3")
_TIMGM = Path("/usr/share/sounds/sf2/TimGM6mb.sf2")

SOUNDFONT_KITS: dict[str, SoundfontKit] = {
    "sf-fluidr3-standard": SoundfontKit(_FLUID, 0, "MIT", "fluid-soundfont-gm"),
    "sf-fluidr3-power": SoundfontKit(_FLUID, 16, "MIT", "fluid-soundfont-gm"),
    "sf-fluidr3-jazz": SoundfontKit(_FLUID, 32, "MIT", "fluid-soundfont-gm"),
    "sf-musescore-standard": SoundfontKit(_MUSESCORE, 0, "MIT", "musescore-general-soundfont-small"),
    "sf-musescore-power": SoundfontKit(_MUSESCORE, 16, "MIT", "musescore-general-soundfont-small"),
    "sf-musescore-jazz": SoundfontKit(_MUSESCORE, 32, "MIT", "musescore-general-soundfont-small"),
    "sf-timgm6mb-standard": SoundfontKit(_TIMGM, 0, "GPL-2", "timgm6mb-soundfont"),
}
"""Pseudo kit name -> the soundfont drum kit it renders."""


class SoundfontsMissingError(RuntimeError):
    """FluidSynth or a soundfont the training renders with is not installed."""


def require_soundfonts(names: tuple[str, ...] | list[str]) -> None:
    """Raise :class:`SoundfontsMissingError` with an install hint unless FluidSynth and every font of
    ``names`` (keys of :data:`SOUNDFONT_KITS`) are installed."""
    require_font(*(SOUNDFONT_KITS[n] for n in names))


def require_font(*specs: SoundfontKit) -> None:
    """Raise :class:`SoundfontsMissingError` with an install hint unless FluidSynth and every font of
    ``specs`` are installed."""
    packages = sorted({s.package for s in specs if not s.path.exists()})
    if shutil.which("fluidsynth") is None:
        packages.insert(0, "fluidsynth")
    if packages:
        raise SoundfontsMissingError(
            f"the soundfont kits need {', '.join(packages)}: install with `apt-get install {' '.join(packages)}`"
            " (Debian/Ubuntu)"
        )


def render_soundfont_kit(name: str) -> Kit:
    """Render the one-shots of the soundfont kit ``name`` (a key of :data:`SOUNDFONT_KITS`) and cut them
    (:func:`render_font_kit`)."""
    return render_font_kit(name, SOUNDFONT_KITS[name])


def render_font_kit(name: str, spec: SoundfontKit) -> Kit:
    """Render the one-shots of the soundfont kit ``spec`` and cut them into the kit ``name``.

    Raises
    ------
    SoundfontsMissingError
        FluidSynth or the font is not installed.
    RuntimeError
        FluidSynth failed (its error output is in the message).
    """
    require_font(spec)
    with tempfile.TemporaryDirectory() as tmp:
        midi = Path(tmp) / "strikes.mid"
        wav = Path(tmp) / "strikes.wav"
        strikes = write_strike_file(midi, program=spec.program, start_s=START_S, channel=spec.channel,
                                    notes=spec.notes)
        cmd = ["fluidsynth", "-ni", "-R", "0", "-C", "0", "-g", "0.5", "-r", str(RENDER_RATE_HZ),
               "-F", str(wav), str(spec.path), str(midi)]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0 or not wav.exists():
            raise RuntimeError(f"fluidsynth failed ({' '.join(cmd)}): {done.stderr.strip()[-500:]}")
        data, sr = sf.read(str(wav), dtype="float32", always_2d=False)
    return cut_kit(name, spec.licence, data, int(sr), strikes, START_S)


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
