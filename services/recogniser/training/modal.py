"""A training "kit" made with Batteur's own sound synthesis (modal and signal-based models).

The one-shots are rendered by the sound service's public command line
(``python -m services.sound.demo``, run as a subprocess: services never import each
other): a General MIDI file of isolated strikes, each drum note at several velocities,
is played dry and mono, then cut into one sample per strike. The result is a
:class:`~services.recogniser.training.kits.Kit` like a Hydrogen kit, with one
velocity layer per rendered velocity, so :func:`~services.recogniser.training.render.render`
plays Groove performances with it like with any recorded kit.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import soundfile as sf

from services.recogniser.training.kits import Kit
from services.recogniser.training.one_shots import cut_kit, write_strike_file

MODAL_KITS = ("batteur-modal", "batteur-synth")
"""Pseudo kit names: Batteur's modal synthesis and its signal-based synthesis."""

START_S = 0.5
"""The sound demo starts the file this late, seconds."""


def render_modal_kit(model: str = "modal") -> Kit:
    """Render the one-shots with the sound service's ``model`` ('modal' or 'synth') and make a kit of them.

    Raises
    ------
    RuntimeError
        the sound demo failed (its error output is in the message).
    """
    with tempfile.TemporaryDirectory() as tmp:
        midi = Path(tmp) / "strikes.mid"
        wav = Path(tmp) / "strikes.wav"
        strikes = write_strike_file(midi)
        seconds = strikes[-1][2] + 1.0
        cmd = [sys.executable, "-m", "services.sound.demo", "--midi", str(midi), "-o", str(wav), "--mono",
               "--reverb", "0", "--model", model, "--seconds", str(seconds)]
        done = subprocess.run(cmd, capture_output=True, text=True, cwd=Path(__file__).resolve().parents[3])
        if done.returncode != 0 or not wav.exists():
            raise RuntimeError(f"sound demo failed ({' '.join(cmd)}): {done.stderr.strip()[-500:]}")
        data, sr = sf.read(str(wav), dtype="float32", always_2d=False)
    return cut_kit(f"batteur-{model}", "Batteur's own synthesis", np.asarray(data, np.float32), int(sr), strikes,
                   START_S)


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
