"""The MIDI reading options of the command lines that read scores (``batteur render``, ``batteur evaluate``,
``batteur compare``, ``batteur rig`` and ``python -m common.score``): one place adds them to a parser and turns what
was given into :func:`common.score.midi.read_midi`'s keyword arguments, so they say and do the same. The services
that read scores (physics' ``--score`` and score library, graphics' ``--preview-score``) take them as settings of
the same names and syntax (:func:`midi_setting_kwargs`); ``batteur rig`` gives them its own
(:func:`midi_service_args`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from common.score.midi_notes import (
    HIHAT_CLOSED_MIN_CC4,
    HIHAT_OPEN_MAX_CC4,
    SHIPPED_MAPS,
    DrumMapError,
    NoteMap,
    load_drum_map,
)

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


DRUM_CHANNELS_HELP = ("read a MIDI file's drums from these channels only, 1 to 16 as a DAW shows them (e.g. 1,10; "
                      "default: channel 10 and channels set to a drum bank, else every channel but those with a "
                      "melodic program and click tracks)")
DRUM_MAP_HELP = ("a MIDI file's note layout when it is not General MIDI: a note map file (.json or .toml: pitch -> GM "
                 f"drum pitch or event type, docs/score-format.md) or a shipped map ({', '.join(SHIPPED_MAPS)})")
HIHAT_CC4_HELP = ("open and close a MIDI file's hi-hat notes with the hi-hat pedal it sends as CC4 (a closed note "
                  f"with CC4 at most {HIHAT_OPEN_MAX_CC4} plays open, an open one with at least {HIHAT_CLOSED_MIN_CC4} "
                  "closed; default: the notes as written, as an e-kit that chooses open or closed itself, a Roland "
                  "TD-11, sends them)")


class _DrumMapAction(argparse.Action):
    """``--drum-map``: the map loaded (:func:`drum_map`) in ``dest``, and the name or file as given in
    ``drum_map_spec`` (:func:`midi_service_args` gives it on)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        try:
            setattr(namespace, self.dest, drum_map(str(values)))
        except argparse.ArgumentTypeError as exc:  # argparse's one-line error, as a type's
            raise argparse.ArgumentError(self, str(exc)) from None
        namespace.drum_map_spec = str(values)


def add_midi_arguments(parser: argparse._ActionsContainer) -> None:
    """Add the MIDI reading options to ``parser`` (a parser or an argument group)."""
    parser.add_argument("--drum-channels", type=drum_channels, default=None, metavar="N,N", help=DRUM_CHANNELS_HELP)
    parser.add_argument("--drum-map", action=_DrumMapAction, default=None, metavar="NAME|FILE", help=DRUM_MAP_HELP)
    parser.add_argument("--hihat-cc4", action="store_true", default=None, help=HIHAT_CC4_HELP)


def midi_read_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of :func:`common.score.midi.read_midi` (and :func:`common.score.text.read_score`,
    which passes them on) that the options of :func:`add_midi_arguments` given in ``args`` ask for; those not given
    are left out (the reader's defaults)."""
    kwargs: dict[str, Any] = {}
    if getattr(args, "drum_channels", None) is not None:
        kwargs["drum_channels"] = args.drum_channels
    if getattr(args, "drum_map", None) is not None:
        kwargs["note_map"] = args.drum_map
    if getattr(args, "hihat_cc4", None):
        kwargs["hihat_cc4"] = True
    return kwargs


def midi_service_args(args: argparse.Namespace) -> list[str]:
    """The options of :func:`add_midi_arguments` given in ``args`` as a service's command line takes them (the
    settings of :func:`midi_setting_kwargs`): ``batteur rig`` gives them to physics and graphics. A map file's
    path made absolute (a service may run elsewhere)."""
    given: list[str] = []
    if getattr(args, "drum_channels", None) is not None:
        given += ["--drum-channels", ",".join(str(c) for c in args.drum_channels)]
    spec = getattr(args, "drum_map_spec", None)
    if getattr(args, "drum_map", None) is not None and spec is not None:
        path = Path(spec).expanduser()
        given += ["--drum-map", str(path.resolve()) if path.is_file() else spec]
    if getattr(args, "hihat_cc4", None):
        given += ["--hihat-cc4"]
    return given


def midi_setting_kwargs(channels: str, note_map: str, hihat_cc4: bool) -> dict[str, Any]:
    """:func:`common.score.midi.read_midi`'s keyword arguments from a service's settings ``drum_channels`` ("1,10";
    "": the reader's choice), ``drum_map`` (a shipped map's name or a note map file; "": General MIDI) and
    ``hihat_cc4``, written as :func:`add_midi_arguments`'s options. ValueError naming the option for bad channels,
    :class:`common.score.midi_notes.DrumMapError` (a ValueError) for a map it cannot use (a file: a service's
    InputError, exit 1)."""
    kwargs: dict[str, Any] = {}
    try:
        if channels.strip():
            kwargs["drum_channels"] = drum_channels(channels)
    except argparse.ArgumentTypeError as exc:
        raise ValueError(f"--drum-channels: {exc}") from None
    if note_map.strip():
        try:
            kwargs["note_map"] = load_drum_map(note_map.strip())
        except DrumMapError as exc:
            raise DrumMapError(f"--drum-map: {exc}") from None
    if hihat_cc4:
        kwargs["hihat_cc4"] = True
    return kwargs
