"""Sound service controls: synthesis model and live instrument parameters.

Every parameter is its own small message so a control panel (Pure Data,
ossia score, Chataigne through OSCQuery) can drive one slider per address.
Ranges are part of the models: an out-of-range value is dropped at decoding
with reason ``out_of_range`` and counted, never clamped. A value in range
that an instrument cannot take (``tension`` on a cymbal, an unknown
instrument, every mode above Nyquist) is rejected by the sound service with
a :class:`SoundRejected` reply saying why.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from common.messages.base import Family, OscMessage
from common.messages.registry import register

Instrument = Annotated[
    str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$", description="kit object id (e.g. snare)")
]
InstrumentField = Field(description="kit object id of the instrument (e.g. snare, ride)")


@register
class SoundModel(OscMessage):
    """Switch an instrument's synthesis model live (ringing strikes finish; new ones use the new model)."""

    ADDRESS = "/batteur/sound/model"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    model: Literal["modal", "sample", "synth"] = Field(
        description="modal: physical modes; sample: recorded samples; synth: oscillators, noise, filters"
    )


@register
class SoundLevel(OscMessage):
    """An instrument's output level."""

    ADDRESS = "/batteur/sound/level"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    gain_db: float = Field(ge=-80.0, le=12.0, description="level, dB (0: calibrated level)")


@register
class SoundRadius(OscMessage):
    """Radius of a drum head, cymbal or bell."""

    ADDRESS = "/batteur/sound/radius"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.02, le=0.6, description="radius, metres")


@register
class SoundTension(OscMessage):
    """Tension of a drum head (membranes only): mode frequencies go as sqrt(tension)."""

    ADDRESS = "/batteur/sound/tension"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=10.0, le=100000.0, description="tension, newtons per metre")


@register
class SoundDensity(OscMessage):
    """Surface density of a drum head (the 'mass' of Bouenard et al.), membranes only."""

    ADDRESS = "/batteur/sound/density"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.01, le=20.0, description="surface density, kilograms per square metre")


@register
class SoundThickness(OscMessage):
    """Thickness of a cymbal or hi-hat plate: the flat plate's mode frequencies go as thickness (the lowest modes
    less, held up by the dome's curvature: sqrt(f_plate^2 + f_curvature^2))."""

    ADDRESS = "/batteur/sound/thickness"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.0003, le=0.006, description="plate thickness, metres")


@register
class SoundDamping(OscMessage):
    """Damping law of an instrument's modes: decay rate sigma(f) = sigma0 + sigma1 f^2 (T60 = 6.91 / sigma)."""

    ADDRESS = "/batteur/sound/damping"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    sigma0: float = Field(ge=0.0, le=500.0, description="frequency-independent decay rate, 1/s")
    sigma1: float = Field(ge=0.0, le=1e-3, description="decay rate growth with frequency squared, s (1/s per Hz^2)")


@register
class SoundModes(OscMessage):
    """Number of modes an instrument renders (each orientation of an m > 0 mode counts)."""

    ADDRESS = "/batteur/sound/modes"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: int = Field(ge=1, le=20000, description="number of modes")


@register
class SoundPosition(OscMessage):
    """How much the strike position shapes the sound (1: full mode-shape weighting, 0: position ignored)."""

    ADDRESS = "/batteur/sound/position"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.0, le=1.0, description="strike-position sensitivity, 0..1")


@register
class SoundStick(OscMessage):
    """The striker of an instrument, for the Hunt-Crossley contact F = k x^alpha + lambda x^alpha dx/dt
    (lambda set from the kit's restitution so that the contact gives it)."""

    ADDRESS = "/batteur/sound/stick"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    mass: float = Field(ge=0.002, le=2.0, description="effective striker mass, kilograms")
    stiffness: float = Field(ge=1e3, le=1e10, description="contact stiffness k, newtons per metre^alpha")
    exponent: float = Field(ge=1.0, le=3.0, description="contact exponent alpha (1.5: Hertz)")


@register
class SoundSnares(OscMessage):
    """Level of a drum's snare wires (membranes; 0: snares off)."""

    ADDRESS = "/batteur/sound/snares"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.0, le=2.0, description="snare wire level, 0..2 (1: default)")


@register
class SoundOpenness(OscMessage):
    """Hi-hat openness from the pedal: closing it damps (chokes) a ringing hat."""

    ADDRESS = "/batteur/sound/openness"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.0, le=1.0, description="openness, 0 closed .. 1 fully open")


@register
class SoundAirLoading(OscMessage):
    """Air loading of a drum head (membranes): 0 is the ideal membrane; 1 adds the air's mass estimate
    rho_air / k, which lowers the low modes most, (0,1) most of all: the partials spread further from the
    fundamental (snare (1,1)/(0,1) 1.593 -> 1.657), the drum gets more inharmonic, not less (a kettle's or
    shell's enclosed air, which raises (0,1), is not modelled)."""

    ADDRESS = "/batteur/sound/air"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    value: float = Field(ge=0.0, le=2.0, description="air loading factor, 0..2 (1: physical estimate)")


@register
class SoundSecondHead(OscMessage):
    """The resonant (bottom) head of a drum, driven through the air in the shell by the batter head."""

    ADDRESS = "/batteur/sound/second_head"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    gain: float = Field(ge=0.0, le=2.0, description="coupling of the second head, 0 (none) .. 2")
    ratio: float = Field(ge=0.5, le=2.0, description="its tuning: frequency ratio to the batter head")


@register
class SoundResonances(OscMessage):
    """Per-mode resonance gains, in frequency order (modes beyond the list keep gain 1; empty: reset)."""

    ADDRESS = "/batteur/sound/resonances"
    FAMILY = Family.CONTROL

    instrument: Instrument = InstrumentField
    gains: tuple[Annotated[float, Field(ge=0.0, le=16.0)], ...] = Field(
        description="linear gain of mode 1, 2, ... (each 0..16)"
    )


@register
class SoundLatency(OscMessage):
    """The scheduling window: each strike plays at its impact time plus this latency."""

    ADDRESS = "/batteur/sound/latency"
    FAMILY = Family.CONTROL

    value: float = Field(ge=0.0, le=2.0, description="latency, seconds")


@register
class SoundMaster(OscMessage):
    """Master gain and room reverb of the sound service."""

    ADDRESS = "/batteur/sound/master"
    FAMILY = Family.CONTROL

    gain_db: float = Field(ge=-80.0, le=12.0, description="master gain, dB")
    reverb: float = Field(ge=0.0, le=1.0, description="room reverb wet/dry balance, 0..1")


@register
class SoundRejected(OscMessage):
    """Reply to a sound control message that was well formed but could not be applied; also to another service's
    control sent to a sound node, naming the service that takes it."""

    ADDRESS = "/batteur/sound/rejected"
    FAMILY = Family.CONTROL

    address: str = Field(max_length=128, description="address of the rejected message")
    instrument: str = Field(max_length=64, description="instrument it named ('' when none)")
    reason: str = Field(max_length=512, description="why it was rejected")
