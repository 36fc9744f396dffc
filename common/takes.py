"""The hidden files beside a take while a sound node records it: their names, in one place.

A sound node recording ``--wav DIR/NAME`` (``services.sound.node.WavSink``) writes the audio to a hidden part file
beside it, ``DIR/.NAME.XXXXXXXX.part`` (``tempfile.mkstemp``'s random ``XXXXXXXX``; a WAV, W64, AIFF ... part
plays up to its last block, its header kept up to date; a FLAC part's header gets its length only when the node
closes it, so a killed one does not play as it is: :data:`TAKE_FORMATS`), and keeps the rig time of its first
sample beside that, in the part's timing file ``DIR/.NAME.XXXXXXXX.part.json``. A node that stops cleanly renames
the part file ``NAME``, writes ``NAME.json`` and removes the timing file; a node killed or failed leaves both,
which ``batteur wav-repair`` makes a take (``batteur.tools.wav_repair``) and ``batteur rig --record`` points to
(``batteur.rig.finish_recording``).

Light on purpose (no pyo, numpy or soundfile): ``batteur wav-repair`` imports it, and the node's modules take
seconds to load.
"""

from __future__ import annotations

import glob
import re
from pathlib import Path

PART_SUFFIX = ".part"
"""How a part file's name ends (after its random ``XXXXXXXX``)."""
TAKE_FORMATS = ("wav", "rf64", "w64", "aiff", "caf", "au", "flac")
"""The extensions (libsndfile formats) a sound node records a take into, and so the takes a part file can be
for. A killed take's part file in any but FLAC holds a header libsndfile kept up to date after each block
(``batteur wav-repair`` makes it a take; a WAV/RF64 one is given every whole frame on disk); a FLAC part's
length is written only when the node closes it (wav-repair refuses it and says how to convert it). Other
formats libsndfile writes as 24-bit (RAW, SD2, SDS, NIST, PAF, WAVEX) are refused by the node: rare for a take,
and a killed RAW or SD2 part does not read back at all."""
PART_NAME = re.compile(r"\.(?P<take>.+\.(?:" + "|".join(TAKE_FORMATS) + r"))\.[A-Za-z0-9_]+\.part", re.IGNORECASE)
"""A take's part file, ``.NAME.XXXXXXXX.part`` (``fullmatch`` it; ``take`` is ``NAME``): not the
``.NAME.json.XXXX.part`` of a .json being written (``common.output_paths.write_atomically``), nor a part file's
own timing file (``.part.json``)."""


def part_prefix(take: str) -> str:
    """How the part file of the take named ``take`` (a file name, no folder) begins: ``.NAME.`` (mkstemp's
    ``prefix``, with :data:`PART_SUFFIX` its ``suffix``)."""
    return f".{take}."


def part_name(take: str, tag: str) -> str:
    """The name of the take ``take``'s part file whose random part is ``tag``: ``.NAME.TAG.part``."""
    return f"{part_prefix(take)}{tag}{PART_SUFFIX}"


def part_take(name: str) -> str | None:
    """The name of the take the part file ``name`` (a file name, no folder) is recorded for; None if ``name`` is
    not a take's part file (see :data:`PART_NAME`)."""
    match = PART_NAME.fullmatch(name)
    return None if match is None else match["take"]


def is_part(name: str) -> bool:
    """Whether the file name ``name`` is a take's part file (see :data:`PART_NAME`)."""
    return PART_NAME.fullmatch(name) is not None


def part_timing(part: Path) -> Path:
    """Where a part file's timing is kept until the take is named: ``.NAME.XXXX.part.json`` beside it."""
    return part.with_name(part.name + ".json")


def parts_glob(take: str) -> str:
    """A glob (relative to the take's folder, ``take`` escaped) for the part files of the take named ``take``:
    ``.NAME.*.part``. Looser than :data:`PART_NAME`: it also matches ``.NAME.json.XXXX.part`` (``NAME.json``
    being written), a name taken all the same."""
    return glob.escape(part_prefix(take)) + "*" + PART_SUFFIX
