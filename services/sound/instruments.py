"""The instruments of a kit: modal models, with sample playback and signal synthesis as live alternatives.

Every instrument owns one :class:`~services.sound.modal_bank.ModeSet` holding
all its modes (head, hoop, bell, ...), a parameter set that can change live,
and a choice of model (``modal``, ``sample``, ``synth``). Switching the model
only changes how *new* strikes sound: what is ringing keeps ringing, so a
switch never cuts or clicks.

Amplitudes: a strike gives each mode the complex amplitude
``gain_k * phi_k(r, theta) / M_k * F(s_k)`` where ``phi_k`` is the mode shape at
the strike point, ``M_k`` the modal mass and ``F(s_k)`` the Laplace transform of
the contact force at the mode's pole (see :mod:`services.sound.excitation`):
the output is proportional to the modal velocities. One calibration factor per
instrument, computed once from its initial parameters, brings a medium strike
to a sensible level; later parameter changes are heard physically (a heavier
head is quieter, a tighter one higher).
"""

from __future__ import annotations

import copy
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import numpy.typing as npt
from scipy.special import jv

from common.kit import EventType, Kit, KitObject
from common.score.gm import GM_TO_EVENT
from services.sound.excitation import (
    ContactPulse,
    Striker,
    clip_restitution,
    hunt_crossley,
    mode_response,
    mode_response_chunks,
)
from services.sound.membrane import membrane_modes
from services.sound.modal_bank import MIN_DECAY_PER_S, ModeSet
from services.sound.plates import (
    BELL_GAINS,
    BELL_RATIOS,
    BRONZE_RHO,
    COWBELL_GAINS,
    COWBELL_RATIOS,
    plate_modes,
    ring_modes,
)
from services.sound.samples import SampleBank, sample_trim
from services.sound.synth import SynthVoice, recipe_for
from services.sound.voices import NoiseVoice, SampleVoice, VoicePool

Model = Literal["modal", "sample", "synth"]
MODELS: tuple[Model, ...] = ("modal", "sample", "synth")
F64 = npt.NDArray[np.float64]

REFERENCE_VELOCITY = 3.0
"""Velocity of the calibration strike, m/s (a medium stroke)."""
REFERENCE_PEAK = 0.2
"""Output peak the calibration strike aims at (full scale 1), before the per-instrument mix level."""
WIRE_DECAY_S = 0.09
"""Decay time constant of the snare wires' buzz with the drum's initial damping, seconds. The head drives the wires,
so the time scales with the head's decay rate: a damping change (a hand on the head) shortens ringing wires too."""


PRESS_DASHPOT_S_PER_M: dict[str, float] = {"hand": 20.0, "shaft": 1.2, "tip": 0.6}
"""Damping a resting contact adds, as a dashpot coefficient per newton of its force, (N s/m) / N = s/m, by
contact: a hand (palm and fingers: a large soft lossy patch, a choke), a stick's shaft laid across, a stick tip,
beater or foot (a small hard patch). A dashpot c on a plate or head of vibrating mass M adds the decay rate
c / (2 M) on average over the modes, so a press's rate is ``PRESS_DASHPOT_S_PER_M[contact] * force / (2 M)``:
a stick tip resting with 5 N on the default snare (M 0.035 kg) adds 43 1/s, a T60 about 5x shorter; a hand
holding the default crash (M 1.34 kg) with 10 N adds 75 1/s on average, more to its edge modes (T60
0.1-0.2 s, a choke)."""
PRESS_POINT_SHARE = 0.5
"""Share of a press's damping that follows the modes' amplitude at the press point (the rest is spread evenly):
a point damper only damps the modes moving under it, but a finger or palm covers a patch and the contact is
nonlinear, which spreads its losses over every mode."""
PRESS_POINT_MAX = 6.0
"""Largest point weight of one mode (its squared shape at the press over its mean square): bounds the damping of
a mode whose antinode is right under the press."""
HIHAT_CLOSED_DECAY_PER_S = 90.0
"""Decay rate the hi-hat's plates held together add, 1/s (times (1 - openness)^2): a closed hat's T60 is about
6.9 / 90 = 77 ms."""
HIHAT_TICK_UNTIL = 0.3
"""Openness up to which a stick on the hi-hat also ticks (the plates held together click under it), at full level
closed and fading linearly to nothing here, so a hat opened a little ticks a little (it was all or nothing at
0.3)."""
CHICK_SPEED_SCALE = {"modal": 0.3, "sample": 2.5, "synth": 3.5}
"""A hi-hat pedal chick (zone ``pedal``) sounds as a plate clash at this share of the top plate's speed, by sound
model: the plates close at about the pedal toe's speed (0.8-2.3 m/s for score velocities 0.1-1 on the default kit
since 8 Dec, 0.14-0.40 m/s before), and a chick stays below a stick stroke of its velocity, louder with its speed,
no brighter (its spectrum's centroid stays below the stick's). Modal (tuned first): a loud chick (2.3 m/s) 10.5 dB
below its 6.1 m/s stick stroke, a velocity-0.6 one 6 dB, a velocity-0.2 one 4 dB (unscaled, chicks were louder
than their stick strokes). Sample and synth at modal's 0.3: a loud chick 40 dB below its stroke, unheard; their
strokes span more level over the velocities than their chicks do, so one scale cannot match modal's at both ends:
theirs give the velocity-0.6 chick modal's 6 dB (sample 6.1, synth 5.3), the loud one 13.5-13.7 dB below, the
velocity-0.2 one 2-3.4 dB below (RMS over 50 ms, tests/sound/test_sound_chick_level.py)."""
COWBELL_MASS_KG = 0.3
"""Vibrating mass of a cowbell, kg (for presses; its partials have no mode shapes here)."""


def contact_of(part: str) -> str:
    """The kind of contact of a pressing part (a key of PRESS_DASHPOT_S_PER_M): ``hand``, ``shaft`` or ``tip``."""
    name = part.lower()
    if any(k in name for k in ("hand", "palm", "finger")):
        return "hand"
    return "shaft" if "shaft" in name else "tip"


@dataclass(frozen=True)
class Press:
    """A part resting on an instrument: its mean added decay rate (1/s) and where it rests (r / a, radians)."""

    rate: float
    r: float
    theta: float


def mix_level(instrument_id: str, kind: str) -> float:
    """Relative peak level of a medium strike in the default mix (a mixing choice, not physics)."""
    for key, level in (("kick", 0.9), ("bass", 0.9), ("snare", 1.2), ("crash", 1.0), ("china", 0.9),
                       ("splash", 0.8), ("ride", 0.6)):
        if key in instrument_id:
            return level
    return {"membrane": 1.0, "hihat": 0.6, "bell": 0.7, "cymbal": 0.9}.get(kind, 1.0)


class ParamError(ValueError):
    """A parameter change this instrument cannot take (the message says why)."""


@dataclass(frozen=True)
class Strike:
    """One scheduled strike, as the instruments see it.

    Attributes
    ----------
    offset : int
        Onset inside the current block, samples.
    velocity : float
        Normal velocity, m/s.
    impulse : float
        Normal impulse, newton-seconds (0: unknown).
    r, theta : float
        Strike point, r / a and radians.
    zone : str
        Zone name from the impact.
    seq : int
        Impact sequence number (seeds noise, so renders repeat exactly).
    openness : float
        A hi-hat stroke's openness from the impact, 0 closed ... 1 open; -1: not given (the zone says it).
    """

    offset: int
    velocity: float
    impulse: float
    r: float
    theta: float
    zone: str
    seq: int
    openness: float = -1.0


@dataclass
class Params:
    """Live parameters of one instrument (not all kinds use all of them)."""

    radius: float
    tension: float = 0.0
    density: float = 0.0
    thickness: float = 0.0
    damping0: float = 5.0  # decay rate at 0 Hz, 1/s
    damping1: float = 1e-5  # decay rate growth, s (sigma = damping0 + damping1 f^2)
    n_modes: int = 80
    air_loading: float = 1.0
    splitting: float = 0.002
    position: float = 1.0  # strike-position sensitivity
    resonances: tuple[float, ...] = ()
    stick_mass: float = 0.03
    stick_stiffness: float = 6.5e5
    stick_exponent: float = 1.5
    restitution: float = 0.6
    level_db: float = 0.0
    snares: float = 0.0
    openness: float = 0.3
    curvature_hz: float = 150.0
    irregularity: float = 0.03
    shimmer: float = 0.0
    bell_hz: float = 0.0
    second_head: float = 0.0  # coupling of the resonant head
    reso_ratio: float = 1.1  # its frequency ratio to the batter head


POSITION_REFERENCE_THETA = 0.0
"""Strike angle, radians, of the fixed point that stands in for the strike point as ``position`` goes to 0 (with
r/a 0.35 on a head, 0.6 on a plate): at 0 every strike point in a zone sounds the same."""

COMMON_PARAMS = frozenset({"damping", "n_modes", "position", "resonances", "stick", "level", "model"})
KIND_PARAMS: dict[str, frozenset[str]] = {
    "membrane": COMMON_PARAMS | {"radius", "tension", "density", "snares", "air_loading", "second_head"},
    "cymbal": COMMON_PARAMS | {"radius", "thickness"},
    "hihat": COMMON_PARAMS | {"radius", "thickness", "openness"},
    "bell": COMMON_PARAMS | {"radius"},
}


LOOP_STATE = ("bank", "_delayed", "presses", "_press_events", "press_decay")
"""Instrument attributes that belong to the render loop: :meth:`Instrument.adopt` keeps them."""


def _seed(name: str) -> int:
    return zlib.crc32(name.encode())


class Instrument:
    """Base class. Subclasses build the mode set and turn strikes into mode amplitudes.

    Parameters
    ----------
    obj : KitObject
        The kit object (geometry) this instrument sounds.
    params : Params
        Initial parameters.
    sample_rate : float
        Hz.
    block : int
        Block length, samples.
    samples : SampleBank
        Recorded samples for the ``sample`` model.
    role : str
        What it is in the kit (:func:`drum_role`); '': its id.
    """

    KIND = "membrane"

    def __init__(self, obj: KitObject, params: Params, sample_rate: float, block: int, samples: SampleBank,
                 role: str = "") -> None:
        self.id = obj.id
        self.role = role or obj.id
        """What the instrument is in the kit (kick, snare, ride, ...: :func:`drum_role`), for the choices made by
        name (mix level, samples, snare click, synthesis recipe); its id when the kit does not say."""
        self.obj = obj
        self.p = params
        self.sr = float(sample_rate)
        self.block = int(block)
        self.samples = samples
        self.model: Model = "modal"
        self.bank = ModeSet(sample_rate, block)
        self.gains: F64 = np.zeros(0)  # radiation gain per mode
        self.calibration = 1.0
        self._delayed: list[tuple[int, npt.NDArray[np.complex128]]] = []  # (samples from block start, amplitudes)
        self.presses: dict[str, Press] = {}  # part -> its press, while it rests here
        self._press_events: list[tuple[int, str, Press | None]] = []  # (offset, part, press or None: lifted)
        self.press_decay: F64 | None = None  # decay rate the presses add per mode, 1/s (None: no press)
        self._law_decay: F64 = np.zeros(0)  # the modes' own decay rates, 1/s (before presses)
        self.rebuild()
        self.calibration = self._calibrate()

    # ---------------------------------------------------------------- params
    @property
    def accepted(self) -> frozenset[str]:
        return KIND_PARAMS[self.KIND]

    @property
    def gain(self) -> float:
        """Output gain from the level, linear."""
        return float(10.0 ** (self.p.level_db / 20.0))

    def set_param(self, name: str, **values: float | tuple[float, ...] | str) -> None:
        """Change one parameter group; raises :class:`ParamError` if it does not apply or makes no sense.

        ``name`` is the message's parameter (radius, tension, ...); ``values`` its fields.
        """
        if name not in self.accepted:
            raise ParamError(f"{self.KIND} instrument {self.id!r} has no parameter {name!r} "
                             f"(it takes: {', '.join(sorted(self.accepted))})")
        if name == "model":
            self.model = values["model"]  # type: ignore[assignment]
            return
        old = self.p
        if name == "level":
            self.p = replace(self.p, level_db=float(values["gain_db"]))  # type: ignore[arg-type]
            return
        if name == "damping":
            new = replace(old, damping0=float(values["sigma0"]), damping1=float(values["sigma1"]))  # type: ignore[arg-type]
        elif name == "stick":
            new = replace(old, stick_mass=float(values["mass"]), stick_stiffness=float(values["stiffness"]),  # type: ignore[arg-type]
                          stick_exponent=float(values["exponent"]))  # type: ignore[arg-type]
        elif name == "second_head":
            new = replace(old, second_head=float(values["gain"]), reso_ratio=float(values["ratio"]))  # type: ignore[arg-type]
        elif name == "resonances":
            new = replace(old, resonances=tuple(float(g) for g in values["gains"]))  # type: ignore[union-attr]
        else:
            field_name = {"n_modes": "n_modes", "position": "position", "radius": "radius", "tension": "tension",
                          "density": "density", "thickness": "thickness", "snares": "snares",
                          "openness": "openness", "air_loading": "air_loading"}[name]
            value = values["value"]
            new = replace(old, **{field_name: int(value) if field_name == "n_modes" else float(value)})  # type: ignore[arg-type]
        self.p = new
        try:
            self.rebuild()
        except ValueError as exc:
            self.p = old
            self.rebuild()
            raise ParamError(f"{self.id}: {exc}") from None
        if self.bank.size and not np.any(self.bank.freq < 0.48 * self.sr):
            self.p = old
            self.rebuild()
            raise ParamError(f"{self.id}: every mode would be above the Nyquist frequency")

    def detached(self) -> Instrument:
        """A copy to change parameters on away from the render loop (a worker thread): it shares nothing the
        loop mutates, and its silent bank gets the new tables. Apply it with :meth:`adopt`."""
        twin = copy.copy(self)
        twin.bank = ModeSet(self.sr, self.block)
        twin._delayed = []
        twin.presses, twin._press_events, twin.press_decay = {}, [], None  # the law only: adopt() adds presses
        return twin

    def adopt(self, twin: Instrument) -> None:
        """Take the parameters and modes of ``twin`` (from :meth:`detached`), keeping what rings: the same as
        having applied its parameter changes here, but cheap (the tables were built with ``twin``)."""
        bank, delayed = self.bank, self._delayed
        self.__dict__.update({k: v for k, v in vars(twin).items() if k not in LOOP_STATE})
        self.bank, self._delayed = bank, delayed
        self.bank.adopt(twin.bank)
        if self.presses:  # still resting here: the new modes are damped by them too
            self.press_decay = self.press_extra()
            self.bank.set_decay(self._law_decay + self.press_decay)

    def set_modes(self, freq: F64, decay: F64) -> None:
        """Render modes ``freq`` (Hz) decaying at their own rates ``decay`` (1/s) plus what the presses add."""
        self._law_decay = np.asarray(decay, dtype=np.float64)
        self.bank.set_modes(freq, decay)
        if not self.presses:
            self.press_decay = None
            return
        self.press_decay = self.press_extra()
        self.bank.set_decay(self._law_decay + self.press_decay)

    # ---------------------------------------------------------------- presses
    def vibrating_mass(self) -> float:
        """Mass of what vibrates, kg (a press's damping rate is inversely proportional to it)."""
        return COWBELL_MASS_KG

    def press_rate(self, part: str, force: float) -> float:
        """Mean decay rate, 1/s, that ``part`` resting with ``force`` newtons adds (PRESS_DASHPOT_S_PER_M)."""
        return PRESS_DASHPOT_S_PER_M[contact_of(part)] * force / (2.0 * self.vibrating_mass())

    def press_weights(self, r: float, theta: float) -> F64:
        """Relative damping of every mode by a press at (r / a, theta radians); mean about 1 (no mode shapes
        here: all alike)."""
        return np.ones(self._law_decay.shape[0])

    def _point_weights(self, shape: F64, modal_mass: F64) -> F64:
        """Weights of modes of shapes ``shape`` at the press and masses ``modal_mass`` (kg): PRESS_POINT_SHARE
        follows the squared shape over its mean square (vibrating mass / modal mass), the rest is even."""
        point = np.minimum(shape**2 * (self.vibrating_mass() / modal_mass), PRESS_POINT_MAX)
        return np.asarray((1.0 - PRESS_POINT_SHARE) + PRESS_POINT_SHARE * point)

    def press_extra(self) -> F64:
        """Decay rate every press adds per mode, summed, 1/s."""
        extra = np.zeros(self._law_decay.shape[0])
        for press in self.presses.values():
            extra += press.rate * self.press_weights(press.r, press.theta)
        return extra

    def press(self, offset: int, part: str, press: Press | None) -> None:
        """``part`` rests here (``press``) or is lifted (None) from sample ``offset`` of the next block."""
        self._press_events.append((offset, part, press))

    @property
    def press_rate_total(self) -> float:
        """Mean decay rate the presses add, 1/s (what voices without modes decay by: samples, synthesis)."""
        return sum(p.rate for p in self.presses.values())

    def apply_presses(self) -> None:
        """This block's presses and lifts, each from its sample: the modes' decay changes there (at once on a
        silent bank, where the sample makes no difference). :meth:`process` calls it; the core too for an
        instrument it does not process (silent)."""
        if not self._press_events:
            return
        for offset, part, press in sorted(self._press_events, key=lambda e: e[0]):
            if press is None:
                self.presses.pop(part, None)
            else:
                self.presses[part] = press
            self.press_decay = self.press_extra() if self.presses else None
            decay = self._law_decay if self.press_decay is None else self._law_decay + self.press_decay
            if not self.bank.size:
                continue
            if self.bank.active:
                self.bank.retune(decay, offset)
            else:
                self.bank.set_decay(decay)
        self._press_events.clear()
        self.presses_changed()

    def presses_changed(self) -> None:
        """What else follows the presses (the snare wires)."""

    def damping_law(self, freq: F64) -> F64:
        """Decay rate per mode, 1/s: sigma0 + sigma1 f^2."""
        return np.asarray(self.p.damping0 + self.p.damping1 * freq**2)

    def _apply_resonances(self, gains: F64) -> F64:
        res = np.asarray(self.p.resonances, dtype=np.float64)
        if res.size:
            n = min(res.size, gains.size)
            gains = gains.copy()
            gains[:n] *= res[:n]
        return gains

    # -------------------------------------------------------------- physics
    def rebuild(self) -> None:
        """Recompute modes (frequencies, decays, gains) from the parameters; ringing modes keep their state."""
        raise NotImplementedError

    def striker(self) -> Striker:
        return Striker(self.p.stick_mass, self.p.stick_stiffness, self.p.stick_exponent)

    def pulse(self, strike: Strike, striker: Striker | None = None) -> ContactPulse:
        st = striker or self.striker()
        if strike.impulse > 0 and strike.velocity > 0:
            # the impulse tells the effective striker mass: J = m v (1 + e), e the one the contact gives (clipped)
            m_eff = strike.impulse / (strike.velocity * (1.0 + clip_restitution(self.p.restitution)))
            st = replace(st, mass=float(np.clip(m_eff, 0.25 * st.mass, 4.0 * st.mass)))
        return hunt_crossley(strike.velocity, st, self.p.restitution, self.sr, oversample=8)

    def weights(self, strike: Strike) -> F64:
        """Real weight of every mode for a unit impulse at the strike point: gain * shape / modal mass."""
        raise NotImplementedError

    def amplitudes(self, strike: Strike, pulse: ContactPulse) -> npt.NDArray[np.complex128]:
        """Complex amplitude of every mode after the whole contact (before calibration)."""
        return np.asarray(self.weights(strike) * mode_response(pulse, self.bank.poles_log))

    def _calibrate(self) -> float:
        """Gain that makes a medium strike (3 m/s) peak at REFERENCE_PEAK x the mix level, from its first 60 ms."""
        ref = Strike(0, REFERENCE_VELOCITY, 0.0, 0.35, 0.3, "centre", 0)
        amp = self.amplitudes(ref, self.pulse(ref))
        # render it with the (still silent) bank itself, then silence the bank again
        self.bank.strike(amp, 0)
        out = np.zeros(self.block, dtype=np.float32)
        peak = 0.0
        for _ in range(int(np.ceil(0.06 * self.sr / self.block))):
            out[:] = 0.0
            self.bank.process(out)
            peak = max(peak, float(np.max(np.abs(out))))
        self.bank.clear()
        target = REFERENCE_PEAK * mix_level(self.role, self.KIND)
        return target / peak if peak > 0 else 1.0

    # -------------------------------------------------------------- strikes
    def strike(self, strike: Strike, pool: VoicePool) -> None:
        """Play one strike with the current model."""
        if self.model == "modal":
            self.strike_modal(strike, pool)
        elif self.model == "sample":
            self.strike_sample(strike, pool)
        else:
            self.strike_synth(strike, pool)

    def strike_modal(self, strike: Strike, pool: VoicePool, gain: float = 1.0) -> None:
        pulse = self.pulse(strike)
        weights = self.weights(strike)  # the mode shapes at the strike point: once per strike
        w = weights * (self.calibration * gain)
        tables = self.bank.tables
        for start, resp in mode_response_chunks(pulse, tables.poles_log, inverse_powers=tables.inverse_powers):
            self.inject(strike.offset + start, w * resp)
        self.extras(strike, pulse, pool, weights)

    def inject(self, delay: int, amplitudes: npt.NDArray[np.complex128]) -> None:
        """Add ``amplitudes`` to the modes ``delay`` samples after the current block's start."""
        if delay < self.block:
            self.bank.strike(amplitudes, delay)
        else:
            self.add_delayed(delay, amplitudes)

    def extras(self, strike: Strike, pulse: ContactPulse, pool: VoicePool, weights: F64) -> None:
        """Non-modal components of a modal strike (snare wires, ...); ``weights``: :meth:`weights` of ``strike``."""

    def sample_name(self, strike: Strike) -> tuple[str, float]:
        """(sample name, playback rate) for a strike."""
        return self.id, 1.0

    def sample_layers(self, strike: Strike) -> list[tuple[str, float, float]]:
        """(sample name, playback rate, amplitude weight) of each sample a strike plays: :meth:`sample_name`'s
        alone, at weight 1 (the hi-hat crossfades two)."""
        name, rate = self.sample_name(strike)
        return [(name, rate, 1.0)]

    def strike_sample(self, strike: Strike, pool: VoicePool) -> None:
        layers = []
        for name, rate, weight in self.sample_layers(strike):
            data = self.samples.get(name) if weight > 0.0 else None
            if weight > 0.0 and data is None:  # a sample missing: the strike synthesised whole
                self.strike_synth(strike, pool)
                return
            if data is not None:
                layers.append((name, rate, weight, data))
        v = strike.velocity / REFERENCE_VELOCITY
        cutoff = 1500.0 + 5000.0 * v**1.5
        for name, rate, weight, data in layers:
            gain = 0.5 * REFERENCE_PEAK / 0.25 * sample_trim(name, strike.zone) * min(v, 4.0) ** 1.1 * weight
            pool.add(SampleVoice(self.id, data, gain, rate, cutoff, self.sr, strike.offset))

    def strike_synth(self, strike: Strike, pool: VoicePool) -> None:
        recipe = recipe_for(self.KIND, self.role, strike.zone, self.p.radius, self.p.openness)
        v = strike.velocity / REFERENCE_VELOCITY
        gain = 0.22 * mix_level(self.role, self.KIND) * recipe.trim * min(v, 4.0) ** recipe.velocity_exponent
        pool.add(SynthVoice(self.id, recipe, gain, min(v, 2.0) / 2.0, strike.seq, self.sr, strike.offset))

    # --------------------------------------------------------------- render
    def add_delayed(self, delay: int, amplitudes: npt.NDArray[np.complex128]) -> None:
        """Inject ``amplitudes`` ``delay`` samples after the current block's start."""
        self._delayed.append((delay, amplitudes))

    def process(self, out: npt.NDArray[np.float32]) -> None:
        """Add the modal output of the next block into ``out`` (gain applied by the caller)."""
        keep = []
        for delay, amp in self._delayed:
            if delay < self.block:
                if amp.shape[0] == self.bank.size:
                    self.bank.strike(amp, delay)
            else:
                keep.append((delay - self.block, amp))
        self._delayed = keep
        if self._press_events:
            self.apply_presses()
        self.bank.process(out)

    @property
    def sounding(self) -> bool:
        return self.bank.active or bool(self._delayed)

    def silence(self) -> None:
        """Stop ringing at once: modes and strikes still to come (their injections) alike."""
        self.bank.clear()
        self._delayed.clear()

    def reset(self) -> None:
        """After its render raised (a bug, a bad bank): silent, the bank's state rebuilt to fit its modes and its
        half-done changes dropped, so the next strike starts clean. Presses and lifts still due are applied now
        (on the silent bank their sample makes no difference), then dropped even if that raises again."""
        self.silence()
        self.bank.reset()
        try:
            self.apply_presses()
        finally:
            self._press_events.clear()


class Membrane(Instrument):
    """A drum: a circular head (Bessel modes) plus its metal hoop; snare wires as a noise component.

    Zones: anything but ``rim``/``rimshot`` strikes the head at (r, theta);
    ``rim`` is a cross-stick/rim click (hoop rings, head barely); ``rimshot``
    hits head and hoop together.
    """

    KIND = "membrane"

    def __init__(self, obj: KitObject, params: Params, sample_rate: float, block: int, samples: SampleBank,
                 role: str = "") -> None:
        self._wires: list[NoiseVoice] = []  # snare-wire voices that may still ring (they follow the head's damping)
        self._wire_reference = 0.0  # head decay rate the wires' WIRE_DECAY_S goes with, 1/s (0: not built yet)
        super().__init__(obj, params, sample_rate, block, samples, role)
        self._wire_reference = self.head_decay_rate()

    def head_decay_rate(self) -> float:
        """Decay rate of the head's lowest mode, (0, 1), 1/s: the one whose air push drives the snare-side head
        and so the wires (as the bank renders it: at least MIN_DECAY_PER_S)."""
        rate = float(self.damping_law(self.modes.freq[:1])[0])
        if self.press_decay is not None:  # a stick or hand resting on the head damps it, and so the wires
            rate += float(self.press_decay[0])
        return max(rate, MIN_DECAY_PER_S)

    def wire_decay(self) -> float:
        """Decay time constant of the snare wires now, seconds: WIRE_DECAY_S scaled by the head's decay rate
        relative to the initial one (exactly WIRE_DECAY_S until the damping changes)."""
        if self._wire_reference <= 0.0:
            return WIRE_DECAY_S
        scale = self.head_decay_rate() / self._wire_reference
        return min(WIRE_DECAY_S / scale, 1.0 / MIN_DECAY_PER_S)

    def _retune_wires(self) -> None:
        """Ringing wires take the head's current damping from the next sample on."""
        self._wires = [w for w in self._wires if not w.done]
        if self._wires:
            decay = self.wire_decay()
            for wire in self._wires:
                wire.set_decay(decay)

    def presses_changed(self) -> None:
        self._retune_wires()

    def vibrating_mass(self) -> float:
        return float(self.p.density * np.pi * self.p.radius**2)

    def press_weights(self, r: float, theta: float) -> F64:
        """The head's modes by their amplitude at the press; the resonant head and the hoop evenly."""
        head = self._point_weights(self.modes.shape_at(min(r, 1.0), theta), self.modes.mass)
        rest = np.full(self.n_reso + self.ring_f.shape[0], 1.0 - PRESS_POINT_SHARE)
        return np.concatenate([head, rest])

    def detached(self) -> Instrument:
        twin = super().detached()
        assert isinstance(twin, Membrane)
        twin._wires = []  # the ringing voices belong to the render loop, not to the worker's copy
        return twin

    def adopt(self, twin: Instrument) -> None:
        wires = self._wires
        super().adopt(twin)
        self._wires = wires
        self._retune_wires()

    def silence(self) -> None:
        super().silence()
        self._wires.clear()

    def rebuild(self) -> None:
        p = self.p
        self.modes = membrane_modes(p.radius, p.tension, p.density, p.n_modes, p.air_loading, p.splitting)
        head_f = self.modes.freq
        self.n_head = head_f.shape[0]
        # the resonant head: the same membrane tuned by reso_ratio (its lowest 24 mode orientations)
        n_reso = min(24, p.n_modes) if p.second_head > 0 else 0
        self.reso = membrane_modes(p.radius, p.tension * p.reso_ratio**2, p.density, max(n_reso, 1),
                                   p.air_loading, p.splitting)
        reso_f = self.reso.freq[:n_reso]
        self.n_reso = n_reso
        self.ring_f = ring_modes(900.0 * (0.178 / p.radius) ** 2, 12)
        freq = np.concatenate([head_f, reso_f, self.ring_f])
        decay = np.concatenate([self.damping_law(head_f), self.damping_law(reso_f), 60.0 + 2e-6 * self.ring_f**2])
        # far-field radiation: monopoles (m = 0) radiate best, higher m less
        rad = np.concatenate([1.0 / (1.0 + 0.6 * self.modes.m), 1.0 / (1.0 + 0.6 * self.reso.m[:n_reso]),
                              np.full(self.ring_f.shape[0], 1.0)])
        self.gains = self._apply_resonances(rad)
        self.set_modes(freq, decay)
        self._retune_wires()

    def weights(self, strike: Strike) -> F64:
        p = self.p
        zone = strike.zone
        head_r = strike.r
        head_w, ring_w = 1.0, 0.0
        if zone == "rim":
            head_r, head_w, ring_w = 0.97, 0.25, 1.0
        elif zone == "rimshot":
            head_r, head_w, ring_w = min(max(strike.r, 0.85), 0.95), 1.0, 0.8
        shape = self.modes.shape_at(head_r, strike.theta)
        # the second head is pushed by the air the batter head moves: its axisymmetric modes get the
        # batter's volume displacement (the (0,1) shape at the strike), the others a little shell coupling
        n = self.n_reso
        reso_m, reso_n = self.reso.m[:n], self.reso.n[:n]
        drive = head_w * float(jv(0, 2.405 * min(max(head_r, 0.0), 1.0)))
        reso_shape = self.reso.shape_at(head_r, strike.theta)[:n]
        if p.position < 1.0:  # towards a fixed point, angle included: at 0 the strike point is ignored
            w, ref_r, ref_theta = p.position, 0.35, POSITION_REFERENCE_THETA
            shape = w * shape + (1.0 - w) * self.modes.shape_at(ref_r, ref_theta)
            drive = w * drive + (1.0 - w) * head_w * float(jv(0, 2.405 * ref_r))
            reso_shape = w * reso_shape + (1.0 - w) * self.reso.shape_at(ref_r, ref_theta)[:n]
        head = head_w * shape / self.modes.mass
        coupling = np.where(reso_m == 0, drive / reso_n, 0.15 * head_w * reso_shape)
        reso = p.second_head * coupling / self.reso.mass[:n]
        # the hoop is much stiffer and lighter in play: a short metallic click
        ring_mass = 0.04
        ring = ring_w * np.ones(self.ring_f.shape[0]) / ring_mass
        return np.asarray(self.gains * np.concatenate([head, reso, ring]))

    def pulse(self, strike: Strike, striker: Striker | None = None) -> ContactPulse:
        if strike.zone in ("rim", "rimshot"):
            # the stick meets the metal hoop: a much stiffer, shorter contact
            striker = replace(self.striker(), stiffness=max(self.p.stick_stiffness, 3e8))
        return super().pulse(strike, striker)

    def extras(self, strike: Strike, pulse: ContactPulse, pool: VoicePool, weights: F64) -> None:
        v = strike.velocity / REFERENCE_VELOCITY
        kick = "kick" in self.role or "bass" in self.role
        # the striker's own click (beater felt on the head, stick tip): a very short high burst
        band, decay, level = ((1200.0, 6000.0), 0.004, 0.05) if kick else ((2500.0, 12000.0), 0.0015, 0.03)
        pool.add(NoiseVoice(self.id, band, level * min(v, 4.0) ** 1.5, 0.0003, decay, strike.seq * 7907 + 11,
                            self.sr, strike.offset))
        if self.p.snares <= 0 or strike.zone == "rim":
            return
        # snare wires buzz with the bottom head: noise whose level follows the drive
        amp = 0.06 * self.p.snares * min(v, 4.0) ** 1.2
        wire = NoiseVoice(self.id, (1800.0, 9000.0 * min(0.6 + 0.2 * v, 1.0)), amp, 0.002, self.wire_decay(),
                          strike.seq * 7919 + 1, self.sr, strike.offset)
        wire.press_exempt = True  # a press damps the head, and the wires with it (wire_decay)
        pool.add(wire)
        self._wires = [w for w in self._wires if not w.done]
        self._wires.append(wire)

    def sample_name(self, strike: Strike) -> tuple[str, float]:
        if strike.zone in ("rim", "rimshot") and "snare" in self.role:
            return "rim", 1.0
        for name in ("kick", "snare", "hightom", "midtom", "floortom"):
            if name in self.role:
                return name, 1.0
        return "midtom", float(np.clip(0.152 / self.p.radius, 0.5, 2.0))


class Cymbal(Instrument):
    """A cymbal: a dense inharmonic plate, plus bell partials excited from the bell zone.

    Crash, splash and china get a shimmer: part of the strike's energy reaches
    the high modes a few tens of milliseconds late, standing in for the
    nonlinear energy cascade of a real cymbal.
    """

    KIND = "cymbal"

    def rebuild(self) -> None:
        p = self.p
        self.modes = plate_modes(p.radius, p.thickness, p.n_modes, p.curvature_hz, p.irregularity, _seed(self.id))
        plate_f = self.modes.freq
        self.n_plate = plate_f.shape[0]
        bell_f = p.bell_hz * BELL_RATIOS if p.bell_hz > 0 else np.zeros(0)
        bell_f = np.repeat(bell_f, 2) * np.tile([1.0, 1.003], bell_f.shape[0])
        self.bell_gains = np.repeat(BELL_GAINS[: bell_f.shape[0] // 2], 2) if bell_f.size else np.zeros(0)
        freq = np.concatenate([plate_f, bell_f])
        decay = self._decays(plate_f, bell_f)
        # below the coincidence frequency a plate mode radiates more the higher it is (efficiency ~ f / f_c):
        # amplitude ~ sqrt(f), which is what makes a cymbal bright rather than gong-like
        tilt = np.concatenate([np.minimum(np.sqrt(plate_f / 3000.0), 2.5), np.ones(bell_f.shape[0])])
        self.gains = self._apply_resonances(tilt)
        self.set_modes(freq, decay)

    def _decays(self, plate_f: F64, bell_f: F64) -> F64:
        """Decay rate of the plate's modes ``plate_f`` and the bell partials ``bell_f`` (Hz), 1/s."""
        return np.concatenate([self.damping_law(plate_f), 0.5 * self.damping_law(bell_f) + 0.3])

    def vibrating_mass(self) -> float:
        return float(BRONZE_RHO * self.p.thickness * np.pi * self.p.radius**2)

    def press_weights(self, r: float, theta: float) -> F64:
        """The plate's modes by their amplitude at the press (a hand on the edge: the edge's antinodes); the
        bell partials evenly."""
        plate = self._point_weights(self.modes.shape_at(min(r, 1.0), theta), self.modes.mass)
        return np.concatenate([plate, np.full(self._law_decay.shape[0] - self.n_plate, 1.0 - PRESS_POINT_SHARE)])

    def weights(self, strike: Strike) -> F64:
        p = self.p
        bell_r = self.obj.bell_radius / self.obj.radius if self.obj.radius > 0 else 0.0
        on_bell = strike.zone == "bell" or strike.r < bell_r
        shape = self.modes.shape_at(strike.r, strike.theta)
        if p.position < 1.0:
            shape = p.position * shape + (1.0 - p.position) * self.modes.shape_at(0.6, POSITION_REFERENCE_THETA)
        plate = shape / self.modes.mass * (0.3 if on_bell else 1.0)
        bell_w = 1.0 if on_bell else 0.08
        bell = bell_w * self.bell_gains / (self.modes.mass[0] if self.n_plate else 1.0)
        return np.asarray(self.gains * np.concatenate([plate, bell]))

    def extras(self, strike: Strike, pulse: ContactPulse, pool: VoicePool, weights: F64) -> None:
        if self.p.shimmer <= 0 or self.n_plate == 0:
            return
        rng = np.random.default_rng(strike.seq * 104729 + _seed(self.id))
        f = self.bank.freq
        amplitudes = np.asarray(weights * mode_response(pulse, self.bank.poles_log))  # = amplitudes(strike, pulse)
        base = np.sum(np.abs(amplitudes)) * self.calibration / max(self.bank.size, 1)
        for delay_s, share in ((0.012, 0.6), (0.035, 0.4)):
            phase = np.exp(2j * np.pi * rng.random(self.bank.size))
            tilt = np.clip(f / 6000.0, 0.0, 1.5)
            tilt[self.n_plate:] = 0.0
            amp = self.p.shimmer * share * base * tilt * phase * min(strike.velocity / REFERENCE_VELOCITY, 3.0)
            self.inject(strike.offset + int(delay_s * self.sr), amp)

    def sample_name(self, strike: Strike) -> tuple[str, float]:
        bell_r = self.obj.bell_radius / self.obj.radius if self.obj.radius > 0 else 0.0
        if "ride" in self.role:
            return ("ridebell" if strike.zone == "bell" or strike.r < bell_r else "ride"), 1.0
        if "china" in self.role:
            return "china", 1.0
        if "splash" in self.role:
            return "crash", 1.4
        return "crash", float(np.clip(0.203 / self.p.radius, 0.6, 1.6))


class HiHat(Cymbal):
    """Two plates whose contact damps them: the openness (0 closed, 1 open) sets the damping live.

    A stroke's openness (the impact's, interaction's map of the plates' gap) sets the openness from that strike
    on, as /batteur/sound/openness does; one without it (-1: a Pd patch, an older interaction) goes by its zone:
    ``open``, ``half``, ``closed`` set 1, 0.5, 0 (other zones leave it);
    ``pedal`` (or the instrument ``hihat_pedal``) is the foot chick, which also
    closes the hat and so chokes it; the plates meeting silently (a press of them: the core) close it too. A drop
    of the openness chokes the sample and synthesis voices as well (:meth:`choke`). Every model follows the
    openness continuously: the modes' damping, the stick tick (HIHAT_TICK_UNTIL), the synthesised decay and the
    sample crossfade (:meth:`sample_layers`).
    """

    KIND = "hihat"

    def damping_law(self, freq: F64) -> F64:
        closed = 1.0 - self.p.openness
        return np.asarray(self.p.damping0 + self.p.damping1 * freq**2 + HIHAT_CLOSED_DECAY_PER_S * closed**2
                          + 6e-7 * closed * freq**2)

    def set_openness(self, openness: float, pool: VoicePool, derived: bool = False) -> None:
        """The plates' gap from now on (0 closed, 1 open): the modes retuned (ringing ones keep their state and
        take the new damping, :meth:`retune_openness`, ``derived`` as there); a drop chokes the sample and synthesis
        voices still ringing (:meth:`choke`)."""
        old = self.p.openness
        if openness == old:
            return
        self.retune_openness(openness, derived)
        if openness < old:
            self.choke(old, openness, pool)

    def retune_openness(self, openness: float, derived: bool = False) -> None:
        """Take ``openness`` for the modes' damping alone (no choke). The openness only enters the damping law: the
        modes' frequencies, shapes and gains stay (no :meth:`rebuild`). ``derived``: the bank's tables are derived
        from those of the last full build by real factors (:meth:`ModeSet.set_decay`, as a press is), about 4x
        cheaper than computing them (0.8 against 3.2 ms for the shipped hat's 506 modes, a rebuild 4.3:
        bench/sound_openness.py) and equal to them to rounding: what a pedal controller's stream of openness
        takes. Otherwise computed exactly as a rebuild would (a stroke's or the plates' openness: an offline render
        stays bit for bit what it was)."""
        self.p = replace(self.p, openness=openness)
        if not self.bank.size:  # nothing built yet to derive from (a detached twin before its rebuild)
            self.rebuild()
            return
        freq = self.bank.freq
        decay = self._decays(freq[: self.n_plate], freq[self.n_plate:])
        if not derived:
            self.set_modes(freq, decay)
            return
        self._law_decay = decay
        self.bank.set_decay(decay if self.press_decay is None else decay + self.press_decay)

    def choke(self, old: float, new: float, pool: VoicePool) -> None:
        """The openness dropped from ``old`` to ``new``: this hat's sample and synthesis voices fade out (they have
        no modes to damp) over the T60 the modes' damping gains by it (HIHAT_CLOSED_DECAY_PER_S: 77 ms open to
        closed). The noise voices (chick, stick tick) are a few ms long already."""
        added = HIHAT_CLOSED_DECAY_PER_S * ((1.0 - new) ** 2 - (1.0 - old) ** 2)  # 1/s
        if added <= 0.0:
            return
        fade = int(np.log(1000.0) / added * self.sr)
        for voice in pool.voices:
            if voice.instrument == self.id and isinstance(voice, SampleVoice | SynthVoice) and not voice.done:
                voice.release(fade)  # one already fading (stolen, choked) keeps its fade

    def strike(self, strike: Strike, pool: VoicePool) -> None:
        openness = {"open": 1.0, "half": 0.5, "closed": 0.0, "pedal": 0.0}.get(strike.zone)
        if strike.openness >= 0.0 and strike.zone != "pedal":  # the foot chick closes the hat whatever it says
            openness = min(strike.openness, 1.0)
        if openness is not None:
            self.set_openness(openness, pool)  # before this strike's own voices: they are not choked
        if strike.zone == "pedal":
            # the plates' speed scaled by model (the impulse with it: the pulse's striker mass is kept)
            scale = CHICK_SPEED_SCALE[self.model]
            strike = replace(strike, velocity=strike.velocity * scale, impulse=strike.impulse * scale)
        if strike.zone == "pedal" and self.model == "modal":
            # the plates clash: a softer, shorter excitation plus a noise chick
            self.strike_modal(replace(strike, velocity=strike.velocity * 0.5, r=0.9), pool, gain=0.4)
            pool.add(NoiseVoice(self.id, (2500.0, 12000.0), 0.08 * min(strike.velocity / 2.0, 2.0), 0.001, 0.012,
                                strike.seq * 31 + 5, self.sr, strike.offset))
            return
        super().strike(strike, pool)

    def extras(self, strike: Strike, pulse: ContactPulse, pool: VoicePool, weights: F64) -> None:
        if self.p.openness < HIHAT_TICK_UNTIL:
            # stick tick on a closed hat, fading as it opens (exactly the closed hat's at openness 0)
            amp = 0.05 * min(strike.velocity / REFERENCE_VELOCITY, 3.0) * (1.0 - self.p.openness / HIHAT_TICK_UNTIL)
            pool.add(NoiseVoice(self.id, (4000.0, 15000.0), amp, 0.0005, 0.008, strike.seq * 13 + 3, self.sr,
                                strike.offset))

    def sample_layers(self, strike: Strike) -> list[tuple[str, float, float]]:
        """The foot chick's sample; a stick stroke crossfades the closed and open samples by the openness o at
        equal power: the closed one at amplitude sqrt(1 - o), the open one at sqrt(o) (two recordings do not
        correlate, so their powers add: the stroke's power goes from the closed one's to the open one's in
        proportion to o). Only the closed sample at 0, only the open one at 1; a sample at weight 0 is not played."""
        if strike.zone == "pedal":
            return [("hihat_pedal", 1.0, 1.0)]
        o = min(max(self.p.openness, 0.0), 1.0)
        return [("hihat_closed", 1.0, float(np.sqrt(1.0 - o))), ("hihat_open", 1.0, float(np.sqrt(o)))]


class Bell(Instrument):
    """A cowbell: a few strong inharmonic partials (two orientations each), fairly short."""

    KIND = "bell"

    def rebuild(self) -> None:
        p = self.p
        n = max(1, min(p.n_modes // 2, COWBELL_RATIOS.shape[0]))
        f0 = 84.0 / max(self.obj.depth, 0.05) * (0.04 / p.radius)
        base = f0 * COWBELL_RATIOS[:n]
        freq = np.repeat(base, 2) * np.tile([1.0, 1.004], n)
        self.base_gains = np.repeat(COWBELL_GAINS[:n], 2)
        self.gains = self._apply_resonances(self.base_gains)
        self.set_modes(freq, self.damping_law(freq))

    def weights(self, strike: Strike) -> F64:
        pos = 1.0 + 0.5 * (strike.r - 0.5) * np.linspace(-1, 1, self.bank.size) * self.p.position
        return np.asarray(self.gains * pos / 0.2)

    def sample_name(self, strike: Strike) -> tuple[str, float]:
        return "cowbell", 1.0


def default_params(obj: KitObject, role: str = "") -> Params:
    """Physical defaults for a kit object, from its role (:func:`drum_role`; '': its id), kind and geometry."""
    name = role or obj.id
    a = obj.radius
    if obj.kind == "membrane":
        density = 0.35
        if "kick" in name or "bass" in name:
            f01, d0, d1, mass, stiff, snares, second, ratio = 55.0, 22.0, 4e-5, 0.1, 2e5, 0.0, 0.5, 1.12
        elif "snare" in name:
            f01, d0, d1, mass, stiff, snares, second, ratio = 220.0, 14.0, 1.2e-5, 0.03, 6e6, 1.0, 0.3, 1.45
        else:
            f01 = 2.405 / (2 * np.pi * a) * 60.0  # toms: wave speed about 60 m/s
            d0, d1, mass, stiff, snares, second, ratio = 4.5, 8e-6, 0.03, 5e6, 0.0, 0.5, 1.07
        tension = (2 * np.pi * a * f01 / 2.405) ** 2 * density
        return Params(radius=a, tension=float(tension), density=density, damping0=d0, damping1=d1, n_modes=160,
                      stick_mass=mass, stick_stiffness=stiff, restitution=obj.elasticity, snares=snares,
                      second_head=second, reso_ratio=ratio)
    if obj.kind in ("cymbal", "hihat"):
        thickness = obj.thickness
        shimmer = 0.0 if "ride" in name else 0.5
        irregularity, curvature = (0.08, 110.0) if "china" in name else (0.03, 150.0)
        d0 = 0.35 if "ride" in name else (1.2 if "splash" in name else 0.6)
        if "china" in name:
            d0 = 1.0
        bell_hz = 0.0
        if obj.bell_radius > 0 and "ride" in name:
            bell_hz = 42.0 / obj.bell_radius  # about 600 Hz for a 7 cm bell
        return Params(radius=a, thickness=thickness, damping0=d0, damping1=4e-8, n_modes=1500, stick_mass=0.03,
                      stick_stiffness=1e9, restitution=obj.elasticity, openness=obj.opening, splitting=0.0,
                      curvature_hz=curvature, irregularity=irregularity,
                      shimmer=shimmer if obj.kind == "cymbal" else 0.0, bell_hz=bell_hz)
    return Params(radius=a, damping0=9.0, damping1=2e-6, n_modes=16, stick_mass=0.03, stick_stiffness=5e8,
                  restitution=obj.elasticity)


EVENT_ROLES: dict[EventType, str] = {
    EventType.BASS: "kick", EventType.SNARE: "snare", EventType.RIM: "snare", EventType.HIGHTOM: "hightom",
    EventType.MIDTOM: "midtom", EventType.FLOORTOM: "floortom", EventType.CRASH: "crash", EventType.RIDE: "ride",
    EventType.RIDEBELL: "ride", EventType.SPLASH: "splash", EventType.CHINA: "china", EventType.HIHATOPEN: "hihat",
    EventType.HIHATCLOSED: "hihat", EventType.HIHATPEDAL: "hihat", EventType.COWBELL: "cowbell",
}
"""The instrument a drum event type is played on (the names the sound's choices by name look for)."""


def drum_role(kit: Kit, obj: KitObject) -> str:
    """What ``obj`` is in ``kit``: the instrument of the events the kit plays on it (``events``, and the General
    MIDI pitches of ``note_objects``), so a kick named ``bd`` sounds as a kick; its id when the kit plays no
    event on it, or events of different instruments (the id's words then decide: ``kick``, ``snare``, ``ride``
    ...)."""
    events = [e for e, spec in kit.events.items() if spec.object == obj.id]
    events += [GM_TO_EVENT[p] for p, o in kit.note_objects.items() if o == obj.id and p in GM_TO_EVENT]
    roles = {EVENT_ROLES[e] for e in events}
    return roles.pop() if len(roles) == 1 else obj.id


INSTRUMENT_CLASSES: dict[str, Callable[..., Instrument]] = {
    "membrane": Membrane,
    "cymbal": Cymbal,
    "hihat": HiHat,
    "bell": Bell,
}


@dataclass
class InstrumentSet:
    """Every sounding instrument of a kit, by id, with pedal aliases."""

    instruments: dict[str, Instrument] = field(default_factory=dict)
    aliases: dict[str, tuple[str, str, float]] = field(default_factory=dict)
    """Pedal id -> (instrument it sounds, forced zone or '', forced r/a or -1)."""

    def resolve(self, instrument: str, zone: str, r: float = 0.0) -> tuple[Instrument, str, float] | None:
        """The instrument an impact on ``instrument`` sounds, with the zone and r/a to use, or None."""
        if instrument in self.instruments:
            return self.instruments[instrument], zone, r
        alias = self.aliases.get(instrument)
        if alias is not None:
            target, forced_zone, forced_r = alias
            if target in self.instruments:
                return self.instruments[target], forced_zone or zone, forced_r if forced_r >= 0 else r
        return None
