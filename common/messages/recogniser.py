"""Drum strikes recognised in live audio (recogniser -> whoever plays or records them)."""

from __future__ import annotations

from pydantic import Field

from common.kit import EventType
from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register


@register
class DrumHit(OscMessage):
    """One drum strike heard by the live percussion recogniser (``batteur transcribe --live``).

    Sent once per recognised strike, as soon as it is classified (at most about
    50 ms after the onset). Several hits may share a ``time`` (e.g. kick and hi-hat).
    """

    ADDRESS = "/batteur/recogniser/hit"
    FAMILY = Family.CONTROL

    seq: int = Field(ge=0, description="hit sequence number (per recogniser node)")
    time: RigTime = Field(description="onset time, seconds from the start of the audio (the file, or listening to "
                                      "the device); sent as a rig time's two arguments")
    note: int = Field(ge=0, le=127, description="General MIDI drum note (channel 10), e.g. 36 kick, 38 snare")
    event_type: EventType = Field(description="drum event type (Kragtwijk et al. 2001), e.g. BASS, SNARE")
    velocity: int = Field(ge=1, le=127, description="MIDI velocity 1..127")
    confidence: float = Field(ge=0, le=1, description="classifier probability 0..1")
