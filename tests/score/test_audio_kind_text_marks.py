"""``audio_kind`` never calls UTF-16 or UTF-32 text an MP3, whoever asks: UTF-16 LE's byte order mark FF FE is also
an MPEG layer I frame's sync bits. Score reading looked for the mark first; a kit saved as UTF-16 was still "an audio
file (MP3)" had the kit loader not skipped every file starting FF, real MP3 files with it."""

from __future__ import annotations

import codecs
from pathlib import Path

import pytest

from common.kit import load_kit
from common.score.events import audio_kind

KIT_TEXT = "name: mine\nobjects: []\n"
MP3_FRAME = b"\xff\xfb\x90\x64" + bytes(8)
"""An MPEG-1 layer III frame header (128 kbit/s, 44.1 kHz), as an MP3 file without an ID3 tag starts."""


@pytest.mark.parametrize("encoding", ["utf-16-le", "utf-16-be", "utf-32-le", "utf-32-be"])
def test_text_after_a_byte_order_mark_is_no_audio(encoding: str) -> None:
    mark = {"utf-16-le": codecs.BOM_UTF16_LE, "utf-16-be": codecs.BOM_UTF16_BE, "utf-32-le": codecs.BOM_UTF32_LE,
            "utf-32-be": codecs.BOM_UTF32_BE}[encoding]
    assert audio_kind((mark + KIT_TEXT.encode(encoding))[:12]) is None  # UTF-16 LE and UTF-32 LE were "MP3"


def test_mp3_frames_and_tags_are_still_mp3() -> None:
    assert audio_kind(MP3_FRAME) == "MP3"
    assert audio_kind(b"\xff\xfd\x90\x00" + bytes(8)) == "MP3"  # layer II
    assert audio_kind(b"ID3\x04" + bytes(8)) == "MP3"


def test_a_kit_saved_as_utf16_is_not_called_audio(tmp_path: Path) -> None:
    kit = tmp_path / "kit.yaml"
    kit.write_bytes(codecs.BOM_UTF16_LE + KIT_TEXT.encode("utf-16-le"))  # Notepad's "Unicode"
    with pytest.raises(ValueError) as refused:
        load_kit(kit)
    said = str(refused.value)
    assert "not UTF-8 text" in said and "audio" not in said and "MP3" not in said, said


def test_an_mp3_given_as_the_kit_is_named_as_such(tmp_path: Path) -> None:
    # was "is not UTF-8 text (invalid start byte at byte 0)": the kit skipped audio_kind for any file starting FF
    kit = tmp_path / "take.mp3"
    kit.write_bytes(MP3_FRAME * 4)
    with pytest.raises(ValueError, match=r"'.*take\.mp3' is an audio file \(MP3\), not a kit: "):
        load_kit(kit)
