"""Contacts (physics -> interaction) and impacts (interaction -> sound, graphics)."""

from __future__ import annotations

from typing import Annotated, ClassVar

from pydantic import Field

from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register

Name = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")]


@register
class Contact(OscMessage):
    """One physics step of contact between a striker part and an instrument.

    Sent every step while in contact. Positions in metres, normal a unit vector
    pointing from the instrument towards the striker.
    """

    ADDRESS = "/batteur/contact"
    FAMILY = Family.CONTACTS

    time: RigTime = Field(description="rig time of the physics step, seconds")
    step: int = Field(ge=0, description="physics step index")
    instrument: Name = Field(description="kit object id (e.g. snare, ride)")
    part: Name = Field(description="striker part (e.g. right_stick_tip, kick_beater)")
    x: float = Field(description="world position x, metres")
    y: float = Field(description="world position y, metres")
    z: float = Field(description="world position z, metres")
    local_x: float = Field(description="position in the instrument frame x, metres")
    local_y: float = Field(description="position in the instrument frame y, metres")
    local_z: float = Field(description="position in the instrument frame z, metres")
    normal_x: float = Field(ge=-1.0001, le=1.0001, description="contact normal x")
    normal_y: float = Field(ge=-1.0001, le=1.0001, description="contact normal y")
    normal_z: float = Field(ge=-1.0001, le=1.0001, description="contact normal z")
    normal_velocity: float = Field(description="relative normal approach velocity, m/s (positive: closing)")
    impulse: float = Field(ge=0, description="normal impulse during this step, newton-seconds")
    normal_force: float = Field(ge=0, description="normal force during this step, newtons")
    # appended (7 Dec; an older physics, a Pd patch, sends the 17 arguments above): the impact could not tell an
    # open hi-hat from a closed one, the sound heard every stroke at the kit's rest opening
    openness: float = Field(default=-1.0, ge=-1, le=1, description="the hi-hat only: how far apart its plates were "
                            "at this contact's first step, their gap above first touch over 25 mm "
                            "(HIHAT_MAX_GAP_M): 0 closed (touching or clamped) ... 1; -1: not given (another "
                            "instrument, or a sender without it: 17 arguments)")

    APPENDED: ClassVar[tuple[str, ...]] = ("openness",)
    """The fields appended after ``normal_force``, oldest first: a contact without them decodes with their
    defaults."""
    NEWER_ARGS: ClassVar[int] = 8
    """Arguments after the last known field a newer sender's contact may carry (fields appended since): ignored."""


@register
class Impact(OscMessage):
    """One strike on an instrument, segmented from the contact stream.

    Sent at the first contact step, so ``impulse``, ``peak_force`` and
    ``duration`` are 0 ("not known yet"); the final figures follow in
    ``/batteur/impact/end`` with the same ``seq`` (interaction can be set to
    send the impact only at the contact's end instead). Sent redundantly with
    the same ``seq`` and ``time``; the sound service and the Pd sound client
    (pd/batteur-voice.pd) de-duplicate on (sender, seq, time), so a sender
    that reuses a ``seq`` for another strike (a Pd patch sending every strike
    as seq 0) has each played. The sound service counts the copies it drops
    (its Health's ``duplicates``).
    """

    ADDRESS = "/batteur/impact"
    FAMILY = Family.IMPACTS

    seq: int = Field(ge=0, description="impact sequence number (per interaction node)")
    time: RigTime = Field(description="rig time of first contact, seconds")
    instrument: Name = Field(description="kit object id")
    zone: Name = Field(description="zone struck: centre, edge, rim, bell, bow, ...")
    r: float = Field(ge=0, le=2, description="radial strike position r/a (0 centre, 1 edge)")
    theta: float = Field(ge=-7, le=7, description="strike angle in the instrument frame, radians")
    velocity: float = Field(ge=0, le=100, description="normal velocity before contact, m/s")
    impulse: float = Field(ge=0, description="total normal impulse, newton-seconds (0: not known yet)")
    peak_force: float = Field(ge=0, description="peak normal force, newtons (0: not known yet)")
    duration: float = Field(ge=0, le=1, description="contact duration, seconds (0: not known yet)")
    part: Name = Field(description="striker part (e.g. right_stick_tip)")
    # appended (8 Dec; an older interaction, a Pd patch's [batteur-strike], sends the 12 arguments above): the
    # sound heard a hi-hat stroke in three steps (the zone's open / half / closed), not how open the plates were
    openness: float = Field(default=-1.0, ge=-1, le=1, description="the hi-hat only: how open it sounds at this "
                            "stroke, 0 closed ... 1 open, mapped by interaction from the plates' simulated gap "
                            "(docs/interaction.md, 'Hi-hat openness'); -1: not given (another instrument, a "
                            "contact without the gap, or a sender without the field: 12 arguments), the zone "
                            "(open, half, closed) says it")

    APPENDED: ClassVar[tuple[str, ...]] = ("openness",)
    """The fields appended after ``part``, oldest first: an impact without them decodes with their defaults."""
    NEWER_ARGS: ClassVar[int] = 8
    """Arguments after the last known field a newer sender's impact may carry (fields appended since): ignored."""
