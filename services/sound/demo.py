"""Render a drum groove (a General MIDI drum file, e.g. from the Groove MIDI Dataset) on the full kit.

    python -m services.sound.demo -o groove.wav
    python -m services.sound.demo -o groove.wav --midi my_beat.mid --seconds 20 --model sample
    python -m services.sound.demo -o beat.wav --score beat.txt

The score is read by Batteur's score reader (``common.score``: MIDI files, RIFF
MIDI ``.rmi`` files and text scores, with its drum map and its errors). Each
drum event becomes an :class:`~common.messages.Impact` on the kit object that
plays it (``note_objects`` of the kit choosing by MIDI pitch), at the event
type's hit point with a little random scatter, with a stick velocity from the
note's velocity. The impacts go through the same :class:`SoundCore` as the rig.
This is a sound-only demo: the full pipeline (score, physics, interaction)
is ``batteur render``.
"""

from __future__ import annotations

import os
import signal

from common.exit_status import FAILED, INTERRUPTED, USAGE  # the convention (README, "Exit status"); loads only sys

PROG = "python -m services.sound.demo"
"""The command's name in its usage and error lines."""


def _quit_unwritten(signum: int, frame: object) -> None:
    """SIGINT before the render starts: nothing is written yet, so leave at once. A KeyboardInterrupt raised while
    the modules below load can land in importlib's callbacks, which print it as "Exception ignored" and go on."""
    os.write(2, f"{PROG}: interrupted: nothing written\n".encode())
    os._exit(INTERRUPTED)


if __name__ == "__main__":  # the command: the modules below take about 1 s to load (SciPy, pyo)
    signal.signal(signal.SIGINT, _quit_unwritten)

# after the handler (E402): a Ctrl-C while they load must not print a traceback
import argparse  # noqa: E402
import functools  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from common.arg_types import number, unit  # noqa: E402
from common.kit import EventType, Kit, load_kit  # noqa: E402
from common.messages import Impact  # noqa: E402
from common.output_paths import check_output_file  # noqa: E402
from common.score.events import Score, ScoreError  # noqa: E402
from common.score.text import read_score  # noqa: E402
from services.sound.core import SoundSettings, render_offline, wav_format  # noqa: E402
from services.sound.params_file import apply_sound_params, check_against_kit, load_sound_params  # noqa: E402

DEFAULT_MIDI = Path(__file__).resolve().parents[2] / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"

PITCH_ZONES: dict[int, str] = {
    40: "rimshot", 37: "rim", 50: "rimshot", 46: "open", 26: "half", 42: "closed", 22: "closed", 44: "pedal",
    53: "bell",
}
"""MIDI pitch -> the zone the sound service plays it on, where it differs from its event type's zone on the kit
(an electric snare's rimshot, a half-open hi-hat edge, ...); every other note is struck at its event's zone."""


def stick_velocity(velocity: float) -> float:
    """Stick speed at impact, m/s, from a note's velocity in [0, 1] (MIDI velocity / 127: 1/127 -> 0.3 m/s,
    1 -> 8 m/s; softer is played as 1/127)."""
    return 0.3 + 7.7 * max(1 / 127.0, min(1.0, velocity)) ** 1.4


def impacts_from_score(score: Score, kit: Kit, max_seconds: float = math.inf, start: float = 0.5) -> list[Impact]:
    """Impacts for every drum event of ``score`` the kit plays, up to ``max_seconds`` into it, shifted to begin at
    ``start`` seconds."""
    rng = np.random.default_rng(7)
    impacts: list[Impact] = []
    hihats = [o.id for o in kit.objects if o.kind == "hihat"]
    # simultaneous events in pitch order: the order their scatter is drawn in (as the Groove MIDI files list
    # them, so the default render is as it was), whatever order a file or the reader gives them
    for e in sorted(score.events, key=lambda e: (e.time, -1 if e.pitch is None else e.pitch, e.event.value)):
        if e.time > max_seconds:
            break
        spec = kit.events.get(e.event)
        if spec is None:
            continue
        instrument = kit.object_for(e.event, e.pitch).id
        if e.event is EventType.HIHATPEDAL and hihats:  # the pedal closes the hi-hat: its plates sound
            instrument = hihats[0]
        zone = PITCH_ZONES.get(e.pitch, spec.zone) if e.pitch is not None else spec.zone
        r = float(np.clip(spec.r + rng.normal(0.0, 0.03), 0.0, 1.0))
        theta = spec.theta + float(rng.normal(0.0, 0.1))
        impacts.append(Impact(seq=len(impacts), time=start + e.time, instrument=instrument, zone=zone, r=r,
                              theta=theta, velocity=stick_velocity(e.velocity), impulse=0.0, peak_force=0.0,
                              duration=0.0, part=spec.preferred.value))
    return impacts


def impacts_from_midi(path: Path, kit: Kit, max_seconds: float = math.inf, start: float = 0.5) -> list[Impact]:
    """Impacts for every drum note of a score file (MIDI, RIFF MIDI or text: :func:`common.score.text.read_score`)
    up to ``max_seconds``, shifted to begin at ``start`` seconds; :class:`ScoreError` naming the file and the
    problem if it cannot be read."""
    return impacts_from_score(read_score(path, kit=kit), kit, max_seconds, start)  # ids and doubles: the kit's


def plain_text(docstring: str) -> str:
    """A reStructuredText docstring as a terminal shows it: ``:class:`~a.b.C``` as ``C``, ````code```` as
    ``code`` (Sphinx's markup is noise in ``--help``)."""
    def role(match: re.Match[str]) -> str:
        tilde, target = match.groups()
        return target.rsplit(".", 1)[-1] if tilde else target  # "~" shows the last name only, as Sphinx does

    return re.sub(r":[a-z]+:`(~?)([^`]+)`", role, docstring).replace("``", "")


def _play_seconds(text: str) -> float:
    """``--seconds``: a positive number of seconds, ``inf`` for the whole file."""
    value = number(text)
    if not value > 0.0:  # also refuses nan
        raise argparse.ArgumentTypeError(f"{text!r}: give a positive number of seconds (inf: the whole file)")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; the exit status (130 after Ctrl-C, with one line and nothing written)."""
    try:
        return _main(argv)
    except KeyboardInterrupt:  # before the render (reading the kit or the score): nothing was written yet
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the exit short
        print(f"{PROG}: interrupted: nothing written", file=sys.stderr)
        return INTERRUPTED


def _main(argv: Sequence[str] | None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description=plain_text(__doc__ or ""),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-o", "--output", type=Path, default=Path("groove.wav"),
                        help="WAV file to write (default groove.wav)")
    parser.add_argument("--midi", "--score", dest="midi", metavar="SCORE", type=Path, default=DEFAULT_MIDI,
                        help="score to play: a General MIDI drum file (.mid, .rmi) or a text score "
                             f"(default {DEFAULT_MIDI.name})")
    parser.add_argument("--seconds", type=_play_seconds, default=16.0,
                        help="how much of the file to play, seconds (default 16; inf: all of it)")
    parser.add_argument("--model", choices=("modal", "sample", "synth"), default="modal",
                        help="synthesis model (default modal)")
    parser.add_argument("--kit", default="default", help="kit name or file (default: the default kit)")
    parser.add_argument("--mono", action="store_true", help="mono instead of stereo")
    parser.add_argument("--reverb", type=unit, default=0.12, help="room reverb wet/dry 0..1 (default 0.12)")
    parser.add_argument("--sound-params", type=Path, default=None, metavar="FILE",
                        help="start from this sound parameters file (what batteur sound --sound-params-out "
                             "writes; docs/sound.md)")
    args = parser.parse_args(argv)
    try:
        kit = load_kit(args.kit)
        check_output_file(args.output, "-o")
        params = load_sound_params(args.sound_params) if args.sound_params is not None else []
        if args.sound_params is not None:
            check_against_kit(params, kit, args.sound_params)
    except (FileNotFoundError, ValueError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return FAILED
    try:
        wav_format(args.output, "-o")  # before the render, not after it
    except ValueError as exc:  # a name no WAV format takes: an option's value refused, as argparse's
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return USAGE
    try:
        score = read_score(args.midi, kit=kit)  # a score's object ids and doubles are the kit's
    except ScoreError as exc:  # it names the file and the problem
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return FAILED
    for warning in score.warnings:  # unknown notes, a key signature ignored, no drum channel ...
        print(f"{PROG}: warning: {warning}", file=sys.stderr)
    impacts = impacts_from_score(score, kit, args.seconds)
    if not impacts:
        print(f"{PROG}: error: no drum notes in the first {args.seconds} s of {args.midi}", file=sys.stderr)
        return FAILED
    settings = SoundSettings(latency=0.0, channels=1 if args.mono else 2, model=args.model, reverb=args.reverb)
    import time

    t0 = time.perf_counter()
    duration = impacts[-1].time + 2.5
    if signal.getsignal(signal.SIGINT) is _quit_unwritten:  # from here a Ctrl-C has a staged file to remove
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:  # the line too: a Ctrl-C may land as it is written
        print(f"rendering {len(impacts)} strikes ({duration:.1f} s) to {args.output} ...", file=sys.stderr,
              flush=True)
        audio = render_offline(impacts, duration, kit, settings, wav=args.output,
                               prepare=None if args.sound_params is None else
                               functools.partial(apply_sound_params, messages=params, source=args.sound_params))
    except ValueError as exc:  # a value an instrument refuses (every mode above Nyquist)
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return FAILED
    except OSError as exc:  # a full disk: the file is written whole or not at all
        print(f"{PROG}: error: -o {args.output}: cannot write it ({exc.strerror or exc})", file=sys.stderr)
        return FAILED
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the exit short (a traceback)
        print(f"{PROG}: interrupted: {args.output} not written", file=sys.stderr)
        return INTERRUPTED
    took = time.perf_counter() - t0
    print(f"{args.output}: {len(impacts)} strikes, {audio.shape[0] / 48000:.1f} s rendered in {took:.1f} s "
          f"({audio.shape[0] / 48000 / took:.1f}x real time), peak {float(np.max(np.abs(audio))):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
