"""The MIDI reading options of the command lines that read scores (``batteur render``, ``batteur evaluate``,
``batteur compare`` and ``python -m common.score``): one place adds them to a parser and turns what was given into
:func:`common.score.midi.read_midi`'s keyword arguments, so the four say and do the same."""

from __future__ import annotations

import argparse
from typing import Any

from common.score.midi_notes import SHIPPED_MAPS, DrumMapError, NoteMap, load_drum_map

MIDI_CHANNELS = range(1, 17)
"""MIDI channels as DAWs show them (1-based)."""


def drum_channels(text: str) -> tuple[int, ...]:
    """``--drum-channels``'s value: 1-based channels separated by commas ("1,10"), each 1 to 16, in the order
    given without repeats; :class:`argparse.ArgumentTypeError` (argparse's one-line error, exit 2) otherwise."""
    channels: list[int] = []
    for part in text.split(","):
        word = part.strip()
        try:
            channel = int(word)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r}: expected MIDI channels 1 to 16 separated by commas, e.g. 1,10 ({word!r} is not a "
                "channel number)") from None
        if channel not in MIDI_CHANNELS:
            hint = " (channels count from 1, as DAWs show them)" if channel == 0 else ""
            raise argparse.ArgumentTypeError(f"{text!r}: channel {channel} is not a MIDI channel, 1 to 16{hint}")
        if channel not in channels:
            channels.append(channel)
    return tuple(channels)


def drum_map(text: str) -> NoteMap:
    """``--drum-map``'s value: a shipped map's name or a note map file, loaded
    (:func:`common.score.midi_notes.load_drum_map`); :class:`argparse.ArgumentTypeError` naming the map and its bad
    entry (argparse's one-line error, exit 2) for one it cannot use."""
    try:
        return load_drum_map(text)
    except DrumMapError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_midi_arguments(parser: argparse._ActionsContainer) -> None:
    """Add the MIDI reading options to ``parser`` (a parser or an argument group)."""
    parser.add_argument("--drum-channels", type=drum_channels, default=None, metavar="N,N",
                        help="read a MIDI file's drums from these channels only, 1 to 16 as a DAW shows them "
                        "(e.g. 1,10; default: channel 10 and channels set to a drum bank, else every channel "
                        "without a melodic program)")
    parser.add_argument("--drum-map", type=drum_map, default=None, metavar="NAME|FILE",
                        help="a MIDI file's note layout when it is not General MIDI: a note map file (.json or "
                        f".toml: pitch -> GM drum pitch or event type, docs/score-format.md) or a shipped map "
                        f"({', '.join(SHIPPED_MAPS)})")


def midi_read_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of :func:`common.score.midi.read_midi` (and :func:`common.score.text.read_score`,
    which passes them on) that the options of :func:`add_midi_arguments` given in ``args`` ask for; those not given
    are left out (the reader's defaults)."""
    kwargs: dict[str, Any] = {}
    if getattr(args, "drum_channels", None) is not None:
        kwargs["drum_channels"] = args.drum_channels
    if getattr(args, "drum_map", None) is not None:
        kwargs["note_map"] = args.drum_map
    return kwargs
