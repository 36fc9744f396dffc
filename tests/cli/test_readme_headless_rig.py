"""The README's rig command for a machine without a sound card does not have sound ask portaudio for its devices.

Sound's ``--device auto`` (its default) calls ``services.sound.pyo_stage.audio_device_count``, portaudio's device
count: on a headless machine a noisy ALSA probe on stderr. The README's command gives sound ``--device none`` (it
records with ``--record`` all the same). Tested on the command line the rig builds from the README's own line
(:func:`batteur.rig.plan_rig`), read with sound's own parser: no service starts.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from batteur import rig
from common.runtime import build_parser
from services.sound.node import SoundNodeSettings

README = Path(__file__).resolve().parents[2] / "README.md"


def headless_rig_command() -> list[str]:
    """The README's ``batteur rig ... --record`` command (the one for machines without a sound card), split."""
    commands = [line for block in re.findall(r"```\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
                for line in block.splitlines() if line.startswith("batteur rig ") and "--record" in line]
    assert len(commands) == 1, commands
    return shlex.split(commands[0])


def test_the_readme_s_headless_rig_gives_sound_device_none() -> None:
    argv = headless_rig_command()
    opts = rig.build_parser().parse_args(argv[2:])
    sound = {plan.role: plan for plan in rig.plan_rig(opts, epoch=0.0, environ={})}["sound"]
    settings = build_parser("sound", settings_cls=SoundNodeSettings).parse_args(sound.args)
    assert vars(settings).get("device") == "none", sound.args  # not given: the default, auto
    assert Path(settings.wav) == Path("out") / rig.RECORDING  # still recording what it plays
