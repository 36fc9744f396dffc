"""Render a drum groove (a General MIDI drum file, e.g. from the Groove MIDI Dataset) on the full kit.

    python -m services.sound.demo -o groove.wav
    python -m services.sound.demo -o groove.wav --midi my_beat.mid --seconds 20 --model sample

Each MIDI drum note becomes an :class:`~common.messages.Impact` on the kit
object its General MIDI / Roland TD-11 note maps to (the Groove MIDI
Dataset's mapping, reduced to the 15 event types of Kragtwijk et al.), at the
event type's hit point on the default kit, with a stick velocity from the
MIDI velocity. The impacts go through the same :class:`SoundCore` as the rig.
This is a sound-only demo: the full pipeline (score, physics, interaction)
is ``batteur render``.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

import mido
import numpy as np

from common.arg_types import number, unit
from common.kit import EventType, Kit, load_kit
from common.messages import Impact
from common.output_paths import check_output_file
from services.sound.core import SoundSettings, render_offline, wav_format

DEFAULT_MIDI = Path(__file__).resolve().parents[2] / "tests" / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"

# note -> (event type, zone override for the sound service or '')
GM_NOTES: dict[int, tuple[EventType, str]] = {
    35: (EventType.BASS, ""), 36: (EventType.BASS, ""),
    38: (EventType.SNARE, ""), 40: (EventType.SNARE, "rimshot"), 37: (EventType.RIM, "rim"), 39: (EventType.RIM, "rim"),
    48: (EventType.HIGHTOM, ""), 50: (EventType.HIGHTOM, "rimshot"), 47: (EventType.MIDTOM, ""),
    45: (EventType.MIDTOM, ""), 43: (EventType.FLOORTOM, ""), 58: (EventType.FLOORTOM, "rimshot"),
    41: (EventType.FLOORTOM, ""),
    46: (EventType.HIHATOPEN, "open"), 26: (EventType.HIHATOPEN, "half"),
    42: (EventType.HIHATCLOSED, "closed"), 22: (EventType.HIHATCLOSED, "closed"), 44: (EventType.HIHATPEDAL, "pedal"),
    49: (EventType.CRASH, ""), 55: (EventType.SPLASH, ""), 57: (EventType.CRASH, ""), 52: (EventType.CHINA, ""),
    51: (EventType.RIDE, ""), 59: (EventType.RIDE, ""), 53: (EventType.RIDEBELL, "bell"),
    56: (EventType.COWBELL, ""),
}


def stick_velocity(midi_velocity: int) -> float:
    """Stick speed at impact, m/s, from a MIDI velocity (1 -> 0.3 m/s, 127 -> 8 m/s)."""
    return 0.3 + 7.7 * (max(1, min(127, midi_velocity)) / 127.0) ** 1.4


def impacts_from_midi(path: Path, kit: Kit, max_seconds: float = math.inf, start: float = 0.5) -> list[Impact]:
    """Impacts for every drum note of a MIDI file up to ``max_seconds``, shifted to begin at ``start`` seconds."""
    rng = np.random.default_rng(7)
    impacts: list[Impact] = []
    t = 0.0
    for msg in mido.MidiFile(path):
        t += msg.time
        if t > max_seconds:
            break
        if msg.type != "note_on" or msg.velocity == 0 or msg.note not in GM_NOTES:
            continue
        event, zone = GM_NOTES[msg.note]
        spec = kit.events.get(event)
        if spec is None:
            continue
        instrument = spec.object
        if event is EventType.HIHATPEDAL:
            hihats = [o.id for o in kit.objects if o.kind == "hihat"]
            instrument = hihats[0] if hihats else instrument
        r = float(np.clip(spec.r + rng.normal(0.0, 0.03), 0.0, 1.0))
        theta = spec.theta + float(rng.normal(0.0, 0.1))
        impacts.append(Impact(seq=len(impacts), time=start + t, instrument=instrument, zone=zone or spec.zone, r=r,
                              theta=theta, velocity=stick_velocity(msg.velocity), impulse=0.0, peak_force=0.0,
                              duration=0.0, part=spec.preferred.value))
    return impacts


def _play_seconds(text: str) -> float:
    """``--seconds``: a positive number of seconds, ``inf`` for the whole file."""
    value = number(text)
    if not value > 0.0:  # also refuses nan
        raise argparse.ArgumentTypeError(f"{text!r}: give a positive number of seconds (inf: the whole file)")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m services.sound.demo", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-o", "--output", type=Path, default=Path("groove.wav"),
                        help="WAV file to write (default groove.wav)")
    parser.add_argument("--midi", type=Path, default=DEFAULT_MIDI,
                        help=f"General MIDI drum file (default {DEFAULT_MIDI.name})")
    parser.add_argument("--seconds", type=_play_seconds, default=16.0,
                        help="how much of the file to play, seconds (default 16; inf: all of it)")
    parser.add_argument("--model", choices=("modal", "sample", "synth"), default="modal",
                        help="synthesis model (default modal)")
    parser.add_argument("--kit", default="default", help="kit name or file (default: the default kit)")
    parser.add_argument("--mono", action="store_true", help="mono instead of stereo")
    parser.add_argument("--reverb", type=unit, default=0.12, help="room reverb wet/dry 0..1 (default 0.12)")
    args = parser.parse_args(argv)
    try:
        kit = load_kit(args.kit)
        check_output_file(args.output, "-o")
        wav_format(args.output, "-o")  # before the render, not after it
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    try:
        impacts = impacts_from_midi(args.midi, kit, args.seconds)
    except EOFError:  # mido's, without a message
        print(f"error: {args.midi}: truncated MIDI file", file=sys.stderr)
        return 2
    except (OSError, ValueError, KeyError, IndexError) as exc:
        print(f"error: {args.midi}: not a readable MIDI file ({exc})", file=sys.stderr)
        return 2
    if not impacts:
        print(f"no drum notes in the first {args.seconds} s of {args.midi}")
        return 1
    settings = SoundSettings(latency=0.0, channels=1 if args.mono else 2, model=args.model, reverb=args.reverb)
    import time

    t0 = time.perf_counter()
    duration = impacts[-1].time + 2.5
    try:  # the line too: a Ctrl-C may land as it is written
        print(f"rendering {len(impacts)} strikes ({duration:.1f} s) to {args.output} ...", file=sys.stderr,
              flush=True)
        audio = render_offline(impacts, duration, kit, settings, wav=args.output)
    except OSError as exc:  # a full disk: the file is written whole or not at all
        print(f"error: -o {args.output}: cannot write it ({exc.strerror or exc})", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the exit short (a traceback)
        print(f"interrupted: {args.output} not written", file=sys.stderr)
        return 130
    took = time.perf_counter() - t0
    print(f"{args.output}: {len(impacts)} strikes, {audio.shape[0] / 48000:.1f} s rendered in {took:.1f} s "
          f"({audio.shape[0] / 48000 / took:.1f}x real time), peak {float(np.max(np.abs(audio))):.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
