"""General MIDI drum notes and their drum event types.

The 47 General MIDI Level 1 percussion sounds (pitches 35-81, channel 10)
reduce to the 15 drum event types of Kragtwijk, Nijholt and Zwiers (2001).
Kit sounds map to the piece that makes them; the Latin and auxiliary
percussion of the GM set, which a drum kit does not have, map to the kit piece
played with the same kind of stroke (hand drums to toms, bells and blocks to
the cowbell or rim, shakers and scrapers to the hi-hat, triangle and whistles
to the ride bell). The Roland TD-11 (used to record the Groove MIDI Dataset)
adds pitch 22 (hi-hat edge, closed) and 26 (hi-hat edge, open).
"""

from __future__ import annotations

from common.kit import EventType

E = EventType

GM_DRUM_NAMES: dict[int, str] = {
    35: "Acoustic Bass Drum",
    36: "Bass Drum 1",
    37: "Side Stick",
    38: "Acoustic Snare",
    39: "Hand Clap",
    40: "Electric Snare",
    41: "Low Floor Tom",
    42: "Closed Hi-Hat",
    43: "High Floor Tom",
    44: "Pedal Hi-Hat",
    45: "Low Tom",
    46: "Open Hi-Hat",
    47: "Low-Mid Tom",
    48: "Hi-Mid Tom",
    49: "Crash Cymbal 1",
    50: "High Tom",
    51: "Ride Cymbal 1",
    52: "Chinese Cymbal",
    53: "Ride Bell",
    54: "Tambourine",
    55: "Splash Cymbal",
    56: "Cowbell",
    57: "Crash Cymbal 2",
    58: "Vibraslap",
    59: "Ride Cymbal 2",
    60: "Hi Bongo",
    61: "Low Bongo",
    62: "Mute Hi Conga",
    63: "Open Hi Conga",
    64: "Low Conga",
    65: "High Timbale",
    66: "Low Timbale",
    67: "High Agogo",
    68: "Low Agogo",
    69: "Cabasa",
    70: "Maracas",
    71: "Short Whistle",
    72: "Long Whistle",
    73: "Short Guiro",
    74: "Long Guiro",
    75: "Claves",
    76: "Hi Wood Block",
    77: "Low Wood Block",
    78: "Mute Cuica",
    79: "Open Cuica",
    80: "Mute Triangle",
    81: "Open Triangle",
}
"""The 47 GM Level 1 percussion sound names, by MIDI pitch."""

TD11_EXTRA_NAMES: dict[int, str] = {22: "Hi-Hat Edge Closed (TD-11)", 26: "Hi-Hat Edge Open (TD-11)"}
"""Roland TD-11 pitches outside the GM set, as found in the Groove MIDI Dataset."""

GM_TO_EVENT: dict[int, EventType] = {
    35: E.BASS,
    36: E.BASS,
    37: E.RIM,
    38: E.SNARE,
    39: E.SNARE,
    40: E.SNARE,
    41: E.FLOORTOM,
    42: E.HIHATCLOSED,
    43: E.FLOORTOM,
    44: E.HIHATPEDAL,
    45: E.MIDTOM,
    46: E.HIHATOPEN,
    47: E.MIDTOM,
    48: E.HIGHTOM,
    49: E.CRASH,
    50: E.HIGHTOM,
    51: E.RIDE,
    52: E.CHINA,
    53: E.RIDEBELL,
    54: E.HIHATOPEN,
    55: E.SPLASH,
    56: E.COWBELL,
    57: E.CRASH,
    58: E.CHINA,
    59: E.RIDE,
    60: E.HIGHTOM,
    61: E.MIDTOM,
    62: E.HIGHTOM,
    63: E.HIGHTOM,
    64: E.FLOORTOM,
    65: E.HIGHTOM,
    66: E.MIDTOM,
    67: E.COWBELL,
    68: E.COWBELL,
    69: E.HIHATCLOSED,
    70: E.HIHATCLOSED,
    71: E.RIDEBELL,
    72: E.RIDEBELL,
    73: E.HIHATCLOSED,
    74: E.HIHATOPEN,
    75: E.RIM,
    76: E.COWBELL,
    77: E.COWBELL,
    78: E.HIGHTOM,
    79: E.HIGHTOM,
    80: E.RIDEBELL,
    81: E.RIDEBELL,
}
"""GM percussion pitch -> drum event type (all 47 GM sounds)."""

DRUM_MAP: dict[int, EventType] = {**GM_TO_EVENT, 22: E.HIHATCLOSED, 26: E.HIHATOPEN}
"""The default map: GM plus the TD-11's hi-hat edge pitches 22 and 26."""


def note_name(pitch: int) -> str:
    """Human-readable name of a drum pitch ("pitch 27" when it is not a known drum sound)."""
    return GM_DRUM_NAMES.get(pitch) or TD11_EXTRA_NAMES.get(pitch) or f"pitch {pitch}"


GM_STAND_INS: frozenset[int] = frozenset({39, 54, 58, *range(60, 82)})
"""GM percussion a drum kit does not have (hand clap, tambourine, vibraslap, the Latin and auxiliary percussion
60-81): :data:`GM_TO_EVENT` plays each on the kit piece struck the same way, and the reader says so once a pitch
(another layout may use these pitches for kit pieces: Roland's tom 3 rim is 58)."""

EVENT_WORDS: dict[EventType, str] = {
    E.BASS: "bass drum", E.SNARE: "snare", E.RIM: "rim (side stick)", E.HIGHTOM: "high tom", E.MIDTOM: "mid tom",
    E.FLOORTOM: "floor tom", E.CRASH: "crash", E.RIDE: "ride", E.RIDEBELL: "ride bell", E.SPLASH: "splash",
    E.CHINA: "china", E.HIHATOPEN: "open hi-hat", E.HIHATCLOSED: "closed hi-hat", E.HIHATPEDAL: "hi-hat pedal",
    E.COWBELL: "cowbell",
}
"""Each drum event type in words, for messages ("played as high tom")."""

EVENT_PITCHES: dict[EventType, int] = {
    E.BASS: 36, E.SNARE: 38, E.RIM: 37, E.HIGHTOM: 48, E.MIDTOM: 45, E.FLOORTOM: 43, E.CRASH: 49, E.RIDE: 51,
    E.RIDEBELL: 53, E.SPLASH: 55, E.CHINA: 52, E.HIHATOPEN: 46, E.HIHATCLOSED: 42, E.HIHATPEDAL: 44,
    E.COWBELL: 56,
}
"""The General MIDI pitch that stands for each event type where a note map names the type instead of a pitch:
the kit's first piece of that type (the toms as a Roland module and most kits lay them out: 48, 45, 43), so a
kit's ``note_objects`` for a second piece (41, 57, 59) are not chosen by a name."""

NOTE_NAMES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")
MIDDLE_C_OCTAVE = 3
"""The octave number of middle C (pitch 60) in :func:`midi_note_name`: C3, as Ableton Live, Cubase, Logic and
Pro Tools show it (Yamaha's convention; Reaper's and the MIDI Manufacturers Association's C4 is an octave up)."""


def midi_note_name(pitch: int) -> str:
    """The note name a DAW's piano roll shows for ``pitch`` with middle C = C3: 60 ``C3``, 25 ``C#0``, 0 ``C-2``."""
    return f"{NOTE_NAMES[pitch % 12]}{pitch // 12 - 5 + MIDDLE_C_OCTAVE}"


def pitch_label(pitch: int) -> str:
    """A pitch for a message: ``pitch 25 (C#0)``, or with its drum sound ``pitch 60 (Hi Bongo, C3)``."""
    sound = GM_DRUM_NAMES.get(pitch) or TD11_EXTRA_NAMES.get(pitch)
    return f"pitch {pitch} ({sound + ', ' if sound else ''}{midi_note_name(pitch)})"
