"""The sound service core: impacts and controls in, audio blocks out (deterministic, no I/O).

``SoundCore`` follows :class:`common.core.Core`. It renders audio in blocks
on a sample clock locked to rig time (output sample n is rig time
``origin + n / sample_rate``): :meth:`SoundCore.step` renders every block that
ends by ``now``, :meth:`SoundCore.render` renders up to a rig time and returns
the new samples. The node hands the blocks to the sound card (when there is
one) and/or a WAV file; offline, the recording is kept in memory
(:meth:`SoundCore.recording`, :meth:`SoundCore.write_wav`).
"""

from __future__ import annotations

import collections
import io
import logging
import math
from collections import Counter
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar, Literal, Protocol

import numpy as np
import numpy.typing as npt
import soundfile as sf
from pydantic import BaseModel, ConfigDict, Field

from common.core import Outgoing
from common.kit import ZONES, EventType, Kit, load_kit
from common.messages import Impact, OscMessage
from common.messages.interaction import Damping
from common.messages.sound import (
    SoundAirLoading,
    SoundDamping,
    SoundDensity,
    SoundLatency,
    SoundLevel,
    SoundMaster,
    SoundModel,
    SoundModes,
    SoundOpenness,
    SoundPosition,
    SoundRadius,
    SoundRejected,
    SoundResonances,
    SoundSecondHead,
    SoundSnares,
    SoundStick,
    SoundTension,
    SoundThickness,
)
from common.output_paths import write_atomically
from common.rated_log import RatedWarnings
from services.sound.excitation import warm_up as excitation_warm_up
from services.sound.instruments import (
    INSTRUMENT_CLASSES,
    KIND_PARAMS,
    HiHat,
    Instrument,
    InstrumentSet,
    ParamError,
    Params,
    Press,
    Strike,
    default_params,
    drum_role,
)
from services.sound.modal_bank import MAX_T60_S
from services.sound.pyo_stage import PyoStage
from services.sound.rebuild_worker import RebuildWorker
from services.sound.samples import SampleBank
from services.sound.scheduler import Scheduler
from services.sound.voices import VoicePool

F32 = npt.NDArray[np.float32]

# control message -> (parameter name, fields passed to Instrument.set_param)
PARAM_MESSAGES: dict[type[OscMessage], tuple[str, tuple[str, ...]]] = {
    SoundModel: ("model", ("model",)),
    SoundLevel: ("level", ("gain_db",)),
    SoundRadius: ("radius", ("value",)),
    SoundTension: ("tension", ("value",)),
    SoundDensity: ("density", ("value",)),
    SoundThickness: ("thickness", ("value",)),
    SoundDamping: ("damping", ("sigma0", "sigma1")),
    SoundModes: ("n_modes", ("value",)),
    SoundPosition: ("position", ("value",)),
    SoundStick: ("stick", ("mass", "stiffness", "exponent")),
    SoundSnares: ("snares", ("value",)),
    SoundOpenness: ("openness", ("value",)),
    SoundResonances: ("resonances", ("gains",)),
    SoundAirLoading: ("air_loading", ("value",)),
    SoundSecondHead: ("second_head", ("gain", "ratio")),
}
PARAM_ADDRESSES: dict[str, str] = {name: cls.ADDRESS for cls, (name, _) in PARAM_MESSAGES.items()}
"""An instrument's parameter name (``air_loading``) -> the address of the control that sets it."""


def not_taken(kind: str, instrument: str, address: str) -> str:
    """Why the control at ``address`` does not apply to a ``kind`` instrument, naming the addresses it takes."""
    taken = sorted(PARAM_ADDRESSES[name] for name in KIND_PARAMS[kind])
    return f"{kind} instrument {instrument!r} takes no {address} (it takes: {', '.join(taken)})"


CHEAP_PARAMS = frozenset({"model", "level"})
"""Parameters that rebuild nothing: applied at once even with ``background_rebuilds`` (queued behind a rebuild of
their instrument: applied as soon as it is swapped in)."""


WAV_LIMIT_BYTES = 0xFFFFFFFF
"""A RIFF/WAVE header's 32-bit sizes cannot describe more (about 4 h of 48 kHz stereo 24-bit)."""
WAV_DATA_LIMIT_BYTES = WAV_LIMIT_BYTES - 1024
"""Most sample bytes a WAV file holds with room for its header: longer offline renders are written as RF64."""

WAV_FORMATS = frozenset(f for f in sf.available_formats() if sf.check_format(f, "PCM_24"))
"""File formats libsndfile writes as 24-bit PCM, named by extension (WAV, FLAC, AIFF, W64, RF64, ...)."""


def wav_format(path: Path, option: str) -> str:
    """The libsndfile format that ``path``'s extension names; ValueError naming ``option`` (e.g. ``--wav``)
    when it names none that takes 24-bit PCM (.mp3, .ogg, no extension)."""
    fmt = path.suffix[1:].upper()
    if fmt not in WAV_FORMATS:
        raise ValueError(f"{option} {path}: give a file ending in .wav (or .flac, .aiff, .w64), "
                         f"not {path.suffix or 'no extension'}")
    return fmt


log = logging.getLogger("batteur.sound")

DROP_LOG_INTERVAL_S = 1.0
"""Dropped impacts of one kind are logged at most once per this many seconds of rig time (the rest are counted and
summed into the next warning), so a flood cannot flood the log too."""

MAX_LATENCY_S = 2.0
"""Longest latency window, seconds: /batteur/sound/latency's range."""

MAX_PRESS_FORCE_N = 5000.0
"""Largest press force taken, newtons (a drummer leaning on a head: a few hundred): a larger or non-finite one is
malformed, dropped and counted (press_malformed)."""

PASSIVE_PRESS_PARTS = frozenset({"hihat_top", "hihat_rattle"})
"""The hi-hat's plates: not a damper resting on it but its openness. Their press (state 1: the plates met, however
gently: the foot letting the pedal down meets them at ~0 m/s, no impact) closes the hat silently, openness 0 as a
chick sets it (counted plate_closes); their lift (state 0: physics stops reporting resting plates after 10 ms, it
never reports them parting) and their presses on anything but a hi-hat are counted (press_ignored), not applied."""

KNEE = 0.7
"""Master soft limiter: linear below this level, a tanh knee above, never beyond 1."""
MASTER_RAMP_S = 0.02
"""A master gain change glides over this long, seconds (no zipper noise, no click)."""


def soft_limit(x: F32) -> None:
    """In place: samples above KNEE in magnitude bend smoothly towards 1 (no delay, no hard clip)."""
    over = np.abs(x) > KNEE
    if np.any(over):
        v = x[over]
        x[over] = np.sign(v) * (KNEE + (1.0 - KNEE) * np.tanh((np.abs(v) - KNEE) / (1.0 - KNEE)))


class Sink(Protocol):
    """An output of rendered blocks (float32, (n,) or (n, 2))."""

    def __call__(self, block: F32) -> None: ...

    def close(self) -> None: ...


class SoundSettings(BaseModel):
    """Configuration of a sound core."""

    model_config = ConfigDict(extra="forbid")

    sample_rate: Literal[44100, 48000, 96000] = Field(48000, description="output rate, Hz")
    block_size: Literal[64, 128, 256, 512] = Field(256, description="samples per block")
    latency: float = Field(0.05, ge=0.0, le=MAX_LATENCY_S, description="scheduling window added to impact times, "
                           "seconds")
    origin: float | None = Field(0.0, description="rig time of the first output sample, seconds "
                                 "(None: the rig time of the first step or message, for live nodes)")
    render_ahead: float = Field(0.0, ge=0.0, le=1.0, description="live: step(now) renders up to now + this, "
                                "seconds, so each block is ready before its output time (offline: 0)")
    channels: Literal[1, 2] = Field(1, description="1: mono; 2: stereo panned from the kit layout")
    max_voices: int = Field(64, ge=1, le=1024, description="sample/synthesis/noise voices at once")
    use_pyo: bool = Field(True, description="run the master section through pyo's graph")
    reverb: float = Field(0.0, ge=0.0, le=1.0, description="room reverb wet/dry, 0..1")
    master_db: float = Field(0.0, ge=-80.0, le=12.0, description="master gain, dB")
    record: bool = Field(True, description="keep every rendered block in memory (offline renders)")
    model: Literal["modal", "sample", "synth"] = Field("modal", description="initial model of every instrument")
    max_strikes_per_block: int = Field(16, ge=1, le=4096, description="strikes started in one block at most: "
                                       "beyond (more than any drummer plays) the loudest are kept and the rest "
                                       "dropped and counted (overload), so a burst cannot stall the renderer")
    horizon: float | None = Field(None, gt=0.0, description="impacts more than this many seconds after the render "
                                  "position are dropped and counted (too_early): a sender's clock error would "
                                  "otherwise hold them in memory for ever. None: no limit (offline renders)")
    max_pending: int | None = Field(None, ge=1, description="impacts waiting for their block at most; beyond, "
                                    "new ones are dropped and counted (overload). None: no limit (offline)")
    pedal_impacts: bool = Field(False, description="sound impacts on pedal objects (footboards) on the instrument "
                                "they drive; off by default because the physics reports the beater on the kick "
                                "and the hi-hat's top plate closing (part hihat_top) as impacts of their own")
    background_rebuilds: bool = Field(False, description="live nodes: a parameter change that rebuilds an "
                                      "instrument's modes is computed in a worker thread and swapped in at the "
                                      "next step (the old modes play until then), so a large one (20,000 modes: "
                                      "seconds) never stalls the render loop. False (offline): applied at once, "
                                      "in message order, so renders are deterministic")


@dataclass
class SoundStats:
    """Counters of a sound core since start."""

    strikes: int = 0
    late: int = 0
    duplicates: int = 0
    unknown_instrument: int = 0
    unknown_zone: int = 0  # impacts whose zone no instrument knows (common.kit.ZONES): dropped
    pedal_impacts: int = 0  # impacts on footboards, not sounded (unless settings.pedal_impacts)
    too_early: int = 0  # impacts beyond the horizon (a sender's clock far ahead)
    overload: int = 0  # strikes dropped by a burst: over max_strikes_per_block or max_pending
    silenced: int = 0  # times an instrument's output went non-finite and it was stopped
    ring_limited: int = 0  # damping changes applied with some modes' ring cut to MAX_T60_S (damping near 0)
    presses: int = 0  # /batteur/damping state 1 applied (a part resting on an instrument, or its new force)
    lifts: int = 0  # state 0 applied (that part lifted)
    stray_lifts: int = 0  # state 0 for a part not resting there (its state 1 lost or never sent): ignored
    press_unknown: int = 0  # presses on an instrument the kit does not have: dropped
    press_malformed: int = 0  # presses with a force above MAX_PRESS_FORCE_N or not finite: dropped
    press_ignored: int = 0  # presses on pedals, lifts of PASSIVE_PRESS_PARTS: counted, not applied
    plate_closes: int = 0  # presses of PASSIVE_PRESS_PARTS on a hi-hat applied: its plates closed it (openness 0)
    implicit_lifts: int = 0  # parts lifted by their own next strike (their state 0 lost, or not sent yet)
    rejected: Counter[str] = field(default_factory=Counter)  # by control address
    blocks: int = 0
    clock_steps: int = 0  # steps of rig time the output was re-anchored on (SoundCore.clock_stepped)
    strike_errors: Counter[str] = field(default_factory=Counter)  # strikes that raised, not played, by instrument
    render_errors: Counter[str] = field(default_factory=Counter)  # blocks whose render raised (silenced), by instrument

    @property
    def rejected_total(self) -> int:
        """Valid messages refused: controls, and impacts not played (the node's Health counts them as dropped)."""
        return (sum(self.rejected.values()) + self.unknown_instrument + self.unknown_zone + self.too_early
                + self.overload + self.press_unknown + self.press_malformed + sum(self.strike_errors.values()))


@dataclass(frozen=True)
class _Change:
    """A parameter message waiting to be applied in the background."""

    message: OscMessage
    source: str  # "host:port" of its sender, for a rejection
    name: str
    values: dict[str, float | tuple[float, ...] | str]


@dataclass(frozen=True)
class _Rebuild:
    """Changes being applied to a detached copy of an instrument in the worker thread."""

    base: object  # the instrument's Params when the copy was made (a strike may replace them meanwhile)
    changes: list[_Change]
    future: Future[tuple[Instrument, list[tuple[_Change, str]]]]


def _apply_changes(twin: Instrument, changes: list[_Change]) -> tuple[Instrument, list[tuple[_Change, str]]]:
    """In the worker: apply ``changes`` in order to ``twin`` (from :meth:`Instrument.detached`, whose bank is empty
    until a change rebuilds it); returns it with the refused ones and why. A twin no change rebuilt (only cheap
    ones, or every one refused before rebuilding) is rebuilt here: adopting an empty bank would leave the
    instrument's strikes failing for good."""
    refused = []
    for change in changes:
        try:
            twin.set_param(change.name, **change.values)
        except ParamError as exc:
            refused.append((change, str(exc)))
    if not twin.bank.size:
        twin.rebuild()
    return twin, refused


class SoundCore:
    """Turns impacts into audio. See the module docstring.

    Parameters
    ----------
    settings : SoundSettings, optional
        Rates, latency, output options.
    kit : Kit, optional
        The kit whose objects become instruments (default: the shipped kit).
    """

    ROLE: ClassVar[str] = "sound"

    def __init__(self, settings: SoundSettings | None = None, kit: Kit | None = None) -> None:
        self.settings = settings or SoundSettings()
        s = self.settings
        self.kit = kit or load_kit("default")
        self.sample_rate = int(s.sample_rate)
        self.block = int(s.block_size)
        self.rate_hz = self.sample_rate / self.block
        self.channels = int(s.channels)
        self.scheduler: Scheduler[tuple[str, Impact]] = Scheduler(
            float(self.sample_rate), s.latency, s.origin if s.origin is not None else 0.0)
        self.press_scheduler: Scheduler[Damping] = Scheduler(
            float(self.sample_rate), s.latency, s.origin if s.origin is not None else 0.0)
        """Presses and lifts (/batteur/damping), on the same sample clock as impacts; their own seq space."""
        self._resting: dict[str, set[str]] = {}  # part -> instruments it rests on (as applied, in time order)
        self._touched: set[str] = set()  # instruments whose presses changed in the block being rendered
        self.pool = VoicePool(s.max_voices, float(self.sample_rate))
        self.samples = SampleBank(self.sample_rate)
        self.instruments = self._build_instruments(self.kit)
        excitation_warm_up()  # the contact kernel compiled now, not at the first live strike
        self.stats = SoundStats()
        self.next_sample = 0  # first output sample not rendered yet
        self.master_db = s.master_db
        self._master_gain = 10.0 ** (s.master_db / 20.0)  # linear, as applied to the last sample rendered
        self._master_glide = (self._master_gain, 0.0)  # (linear gain gliding to, change per sample)
        self.reverb = s.reverb
        self._stage: PyoStage | None = None
        if s.use_pyo:
            # its own master gain stays at 0 dB: the core applies the master before the limiter
            self._stage = PyoStage(self.sample_rate, self.block, self.channels, s.reverb, 0.0)
        self._record: list[F32] = []
        self.on_block: Callable[[F32], None] | None = None
        """Called with every rendered block."""
        self.sinks: list[Sink] = []
        """Outputs fed every rendered block (the node's WAV file, sound card); closed by :meth:`close`."""
        self.before_close: Callable[[], None] | None = None
        """Called once by :meth:`close`, after the sinks are closed and before the rebuild worker is: changes still
        being computed can be waited for and taken in there (the node's ``--sound-params-out``)."""
        self._origin_set = s.origin is not None
        self.clock_steps: list[tuple[int, float]] = []
        """(output sample, its rig time) at each step of rig time (:meth:`clock_stepped`), in order."""
        self._first_origin = self.scheduler.origin  # sample 0's rig time, kept once a step moves the origin
        self.strike_latencies: collections.deque[float] = collections.deque(maxlen=10000)
        """Output time of each strike's first sample minus its impact time, seconds (most recent last)."""
        self._bus: dict[str, F32] = {}
        self._pedal_ids = {o.id for o in self.kit.objects if o.kind == "pedal"}
        self._drop_warnings = RatedWarnings(log, DROP_LOG_INTERVAL_S)  # by kind, on rig time
        self._pans = {i.id: self._pan(i.obj.position[0]) for i in self.instruments.instruments.values()}
        self._worker = RebuildWorker() if s.background_rebuilds else None
        self._rebuilds: dict[str, _Rebuild] = {}  # instrument id -> changes in the worker
        self._queued: dict[str, list[_Change]] = {}  # instrument id -> changes that arrived meanwhile, in order
        self._openness: dict[str, float] = {}  # hi-hat id -> the latest /batteur/sound/openness not applied yet

    # ------------------------------------------------------------- building
    def _build_instruments(self, kit: Kit) -> InstrumentSet:
        out = InstrumentSet()
        for obj in kit.objects:
            cls = INSTRUMENT_CLASSES.get(obj.kind)
            if cls is None:
                continue
            role = drum_role(kit, obj)  # the kit's events say what it is (a kick named bd), else its id
            inst: Instrument = cls(obj, default_params(obj, role), self.sample_rate, self.block, self.samples, role)
            inst.model = self.settings.model
            out.instruments[obj.id] = inst
        hihats = [i.id for i in out.instruments.values() if i.KIND == "hihat"]
        kick = kit.kick()  # the drum BASS strikes, whatever its id
        kicks = [kick.id] if kick is not None and kick.id in out.instruments else [
            i.id for i in out.instruments.values() if i.KIND == "membrane" and ("kick" in i.role or "bass" in i.role)]
        # Footboards by the events (and left_bass_pedal) that press them, whatever their ids: HIHATPEDAL's (or the
        # pedal object it is played on, a kit for sound alone giving no ``pedal``) is the foot chick, BASS's (both of
        # a double pedal's) the kick. A pedal no event names keeps the id rule: "hihat" in its id is a chick,
        # "kick"/"bass" a kick, any other is silent (it was the kick: a hi-hat footboard HIHATPEDAL did not name
        # thumped as one).
        hh_event, bass = kit.events.get(EventType.HIHATPEDAL), kit.events.get(EventType.BASS)
        chick = {hh_event.pedal, hh_event.object} if hh_event is not None else set()
        kick_pedals = {kit.kick_pedal(), kit.left_bass_pedal, bass.object if bass is not None else None}
        named = kick_pedals.union(*({e.pedal, e.object} for e in kit.events.values()))
        # the hi-hat HIHATPEDAL closes, else the kit's first
        chick_hat = hh_event.object if hh_event is not None and hh_event.object in hihats else \
            (hihats[0] if hihats else None)
        for obj in kit.objects:
            if obj.kind != "pedal" or not self.settings.pedal_impacts:
                continue
            if obj.id in named:
                is_chick, is_kick = obj.id in chick, obj.id in kick_pedals
            else:
                is_chick, is_kick = "hihat" in obj.id, "kick" in obj.id or "bass" in obj.id
            if is_chick and chick_hat is not None:
                out.aliases[obj.id] = (chick_hat, "pedal", 0.9)
            elif is_kick and kicks:
                out.aliases[obj.id] = (kicks[0], "centre", bass.r if bass is not None else 0.2)
        return out

    def _pan(self, x: float) -> tuple[float, float]:
        """Equal-power (left, right) gains from the object's x, metres (as the drummer hears the kit)."""
        pos = float(np.clip(x / 0.8, -1.0, 1.0))
        angle = (pos + 1.0) * math.pi / 4.0
        return math.cos(angle), math.sin(angle)

    # ----------------------------------------------------------- core API
    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        """Schedule an impact or apply a control message. ``now``: rig time, seconds."""
        self._set_origin(now)
        if isinstance(message, Impact):
            self._schedule(message, source)
            return []
        if isinstance(message, Damping):
            self._schedule_press(message, source)
            return []
        if isinstance(message, SoundLatency):
            self.scheduler.latency = float(message.value)
            self.press_scheduler.latency = self.scheduler.latency
            three_blocks_s = 3 * self.block / self.sample_rate
            if self.scheduler.latency < three_blocks_s:  # as the node warns for --latency-s
                log.warning("latency %.1f ms (from %s) is under three blocks (%.1f ms): most strikes will be late",
                            self.scheduler.latency * 1e3, source, three_blocks_s * 1e3)
            return []
        if isinstance(message, SoundMaster):
            self.master_db, self.reverb = float(message.gain_db), float(message.reverb)
            if self._stage is not None:
                self._stage.set_master(0.0, self.reverb)
            return []
        spec = PARAM_MESSAGES.get(type(message))
        if spec is None:
            return []
        name, fields = spec
        instrument_id = str(message.model_dump().get("instrument", ""))
        inst = self.instruments.instruments.get(instrument_id)
        if inst is None:
            return self._reject(message, instrument_id, f"no instrument {instrument_id!r} "
                                f"(known: {', '.join(sorted(self.instruments.instruments))})")
        if name not in inst.accepted:  # named by address: a panel's user never sees our parameter names
            return self._reject(message, instrument_id, not_taken(inst.KIND, instrument_id, message.ADDRESS))
        if isinstance(message, SoundOpenness) and isinstance(inst, HiHat):
            # the pedal moved: applied at the next block's start (_apply_openness), as a stroke's zone and the plates
            # meeting apply it, so a drop chokes the ringing hat's sample and synth voices too (set_param retuned the
            # modes alone); only the latest of a block's messages is applied (a pedal controller or a slider sends
            # many: each a retune on the render thread otherwise); never queued behind a background rebuild, which
            # would land it late (one in flight is adopted and retuned to it: _finish_rebuilds)
            self._openness[inst.id] = float(message.value)
            return []
        values = {f: getattr(message, f) for f in fields}
        if self._worker is not None and (instrument_id in self._rebuilds or name not in CHEAP_PARAMS):
            change = _Change(message, source, name, values)
            if instrument_id in self._rebuilds:  # after the change in flight, in message order
                self._queued.setdefault(instrument_id, []).append(change)
            else:
                self._start_rebuild(inst, [change])
            return []
        try:
            inst.set_param(name, **values)
        except ParamError as exc:
            return self._reject(message, instrument_id, str(exc))
        self._note_ring_limit(inst, name)
        return []

    def _reject(self, message: OscMessage, instrument: str, reason: str, to: str = "reply") -> list[Outgoing]:
        self.stats.rejected[message.ADDRESS] += 1
        return [Outgoing(SoundRejected(address=message.ADDRESS, instrument=instrument, reason=reason[:512]), to)]

    def _note_ring_limit(self, inst: Instrument, name: str) -> None:
        """Count (and warn, rate-limited) a damping change that leaves modes ringing longer than MAX_T60_S."""
        if name == "damping" and inst.bank.slowed:
            self.stats.ring_limited += 1
            self._log_drop("ring_limited", f"{inst.id}: damping {inst.p.damping0:g} 1/s, {inst.p.damping1:g} s "
                           f"leaves {inst.bank.slowed} modes decaying slower than T60 {MAX_T60_S:g} s: they ring "
                           f"{MAX_T60_S:g} s (the longest the sound service renders)")

    # ------------------------------------------------------ background rebuilds
    def _start_rebuild(self, inst: Instrument, changes: list[_Change]) -> None:
        assert self._worker is not None
        future = self._worker.submit(_apply_changes, inst.detached(), changes, lane=inst.id)  # not behind others'
        self._rebuilds[inst.id] = _Rebuild(inst.p, changes, future)

    def _finish_rebuilds(self) -> list[Outgoing]:
        """Swap in the instruments the worker has finished (cheap: the tables are built); returns rejections,
        sent to the senders of the refused messages."""
        out: list[Outgoing] = []
        for inst_id, job in list(self._rebuilds.items()):
            if not job.future.done():
                continue
            del self._rebuilds[inst_id]
            inst = self.instruments.instruments[inst_id]
            openness_now: float | None = None
            if inst.p is not job.base:  # changed meanwhile
                if not (isinstance(inst, HiHat) and isinstance(job.base, Params)
                        and replace(inst.p, openness=job.base.openness) == job.base):
                    self._start_rebuild(inst, job.changes)  # redo on top
                    continue
                # only the hi-hat's openness (a pedal, a stroke, the plates): the twin is right but for its damping,
                # retuned below (redoing the job would never land while a pedal streams openness)
                openness_now = inst.p.openness
            try:
                twin, refused = job.future.result()
            except Exception as exc:  # noqa: BLE001 - a bug in a rebuild must not stop the sound
                twin, refused = inst, [(c, f"{type(exc).__name__}: {exc}") for c in job.changes]
                log.error("%s: rebuilding its modes failed (%s): parameters unchanged", inst_id, exc, exc_info=exc)
            if twin is not inst and not twin.bank.size and inst.bank.size:
                twin, refused = inst, [(c, "rebuilding its modes left none: parameters unchanged") for c in job.changes]
                log.error("%s: rebuilding its modes left none: parameters unchanged", inst_id)
            if twin is not inst:
                inst.adopt(twin)
            if openness_now is not None and isinstance(inst, HiHat) and inst.p.openness != openness_now:
                inst.retune_openness(openness_now, derived=True)  # no choke: done when it dropped
            for change, reason in refused:
                out += self._reject(change.message, inst_id, reason, change.source or "reply")
            if any(c.name == "damping" for c in job.changes):
                self._note_ring_limit(inst, "damping")
            out += self._start_queued(inst, self._queued.pop(inst_id, []))
        return out

    def _start_queued(self, inst: Instrument, queued: list[_Change]) -> list[Outgoing]:
        """The changes that waited behind a rebuild of ``inst``, in order, on top of what it adopted: the cheap
        ones before the first that rebuilds are applied at once (a job of only those would have nothing to
        build), the rest go to the worker together. Returns the rejections of the cheap ones."""
        out: list[Outgoing] = []
        while queued and queued[0].name in CHEAP_PARAMS:
            change = queued.pop(0)
            try:
                inst.set_param(change.name, **change.values)
            except ParamError as exc:
                out += self._reject(change.message, inst.id, str(exc), change.source or "reply")
        if queued:
            self._start_rebuild(inst, queued)
        return out

    @property
    def rebuilding(self) -> bool:
        """True while a parameter change is being computed in the background (``background_rebuilds``)."""
        return bool(self._rebuilds)

    def _schedule(self, impact: Impact, source: str) -> None:
        if self.scheduler.is_duplicate(source, impact.seq, impact.time):
            self.stats.duplicates += 1
            return
        if self.instruments.resolve(impact.instrument, impact.zone) is None:
            if impact.instrument in self._pedal_ids:
                self.stats.pedal_impacts += 1  # a foot on a footboard: the beater / top plate sound instead
            else:
                self.stats.unknown_instrument += 1
                known = ", ".join(sorted(self.instruments.instruments))
                self._log_drop("unknown_instrument", f"dropped an impact from {source} on {impact.instrument!r}, "
                               f"which the kit does not have (known: {known})")
            return
        if impact.zone not in ZONES:
            self.stats.unknown_zone += 1
            self._log_drop("unknown_zone", f"dropped an impact from {source} on {impact.instrument}: no zone "
                           f"{impact.zone!r} (zones: {', '.join(sorted(ZONES))})")
            return
        if not self._admitted("an impact", source, impact.time, len(self.scheduler)):
            return
        payload = (impact.instrument, impact)
        self.scheduler.push(impact.time, payload, self.next_sample)
        self.stats.late = self.scheduler.late

    def _schedule_press(self, damping: Damping, source: str) -> None:
        """Queue a press or lift for the sample of its time + latency (as impacts are)."""
        if self.press_scheduler.is_duplicate(source, damping.seq, damping.time):
            self.stats.duplicates += 1
            return
        if damping.instrument in self._pedal_ids or (damping.part in PASSIVE_PRESS_PARTS
                                                     and not self._closes_plates(damping)):
            self.stats.press_ignored += 1
            return
        if damping.instrument not in self.instruments.instruments:
            self.stats.press_unknown += 1
            known = ", ".join(sorted(self.instruments.instruments))
            self._log_drop("press_unknown", f"dropped a press from {source} on {damping.instrument!r}, which the "
                           f"kit does not have (known: {known})")
            return
        if not math.isfinite(damping.force) or damping.force > MAX_PRESS_FORCE_N:
            self.stats.press_malformed += 1
            self._log_drop("press_malformed", f"dropped a press from {source} on {damping.instrument}: force "
                           f"{damping.force:g} N (at most {MAX_PRESS_FORCE_N:g} N)")
            return
        if not self._admitted("a press", source, damping.time, len(self.press_scheduler)):
            return
        self.press_scheduler.push(damping.time, damping, self.next_sample)

    def _closes_plates(self, damping: Damping) -> bool:
        """Whether a press of a hi-hat plate part (PASSIVE_PRESS_PARTS) closes a hi-hat of the kit."""
        inst = self.instruments.instruments.get(damping.instrument)
        return damping.state == 1 and isinstance(inst, HiHat)

    def _admitted(self, what: str, source: str, time: float, waiting: int) -> bool:
        """Whether an impact or press (``what``) for rig time ``time`` (s) may wait in its scheduler, which holds
        ``waiting``: not beyond the horizon, not past ``max_pending`` (else counted and logged)."""
        horizon = self.settings.horizon
        if horizon is not None and time - self.now > horizon:
            self.stats.too_early += 1
            self._log_drop("too_early", f"dropped {what} from {source} at rig time {time:.3f} s, "
                           f"{time - self.now:.1f} s ahead of the sound (more than {horizon:g} s: "
                           "is its clock synchronised?)")
            return False
        if self.settings.max_pending is not None and waiting >= self.settings.max_pending:
            self.stats.overload += 1
            self._log_drop("overload", f"dropped {what} from {source}: {waiting} already waiting")
            return False
        return True

    def _press(self, offset: int, damping: Damping) -> None:
        """Hand a press or lift, in time order, to its instrument from sample ``offset`` of this block."""
        inst = self.instruments.instruments[damping.instrument]
        part = damping.part
        if part in PASSIVE_PRESS_PARTS and isinstance(inst, HiHat):  # only the plates meeting get here (state 1)
            inst.set_openness(0.0, self.pool)  # closed: the modes and the sample/synth voices choked, no sound
            self.stats.plate_closes += 1
            return
        self._touched.add(inst.id)
        if damping.state == 0:
            if inst.id not in self._resting.get(part, ()):
                self.stats.stray_lifts += 1
                return
            self._lift(offset, part, inst.id)
            self.stats.lifts += 1
            return
        self._resting.setdefault(part, set()).add(inst.id)
        rate = inst.press_rate(part, float(damping.force))
        inst.press(offset, part, Press(rate, float(damping.r), float(damping.theta)))
        self.stats.presses += 1

    def _lift(self, offset: int, part: str, instrument: str) -> None:
        resting = self._resting[part]
        resting.discard(instrument)
        if not resting:
            del self._resting[part]  # nothing resting: the strike path's check stays one empty-dict test
        self.instruments.instruments[instrument].press(offset, part, None)
        self._touched.add(instrument)

    def _lift_striker(self, offset: int, part: str) -> None:
        """A part that strikes has left whatever it rested on (its lift may be lost, or in another render
        segment): lifted there from the strike's sample, counted as implicit_lifts."""
        for instrument in sorted(self._resting.get(part, ())):
            self._lift(offset, part, instrument)
            self.stats.implicit_lifts += 1

    def _log_drop(self, kind: str, detail: str) -> None:
        """Warn about input not played, at most once per DROP_LOG_INTERVAL_S of rig time for each kind."""
        self._drop_warnings.warn(kind, self.now, detail)

    def _within_budget(self, due: list[tuple[int, tuple[str, Impact]]]) -> list[tuple[int, tuple[str, Impact]]]:
        """The strikes of one block, at most ``max_strikes_per_block``: the loudest, in time order."""
        cap = self.settings.max_strikes_per_block
        if len(due) <= cap:
            return due
        loudest = sorted(range(len(due)), key=lambda i: -due[i][1][1].velocity)[:cap]
        dropped = len(due) - cap
        self.stats.overload += dropped
        self._log_drop("overload", f"{len(due)} strikes due in one block: the {cap} loudest play, {dropped} dropped")
        return [due[i] for i in sorted(loudest)]

    def step(self, now: float) -> list[Outgoing]:
        """Render every block that ends at or before rig time ``now`` (plus ``render_ahead``)."""
        self._set_origin(now)
        out = self._finish_rebuilds() if self._rebuilds else []
        self.render(now + self.settings.render_ahead)
        return out

    def _set_origin(self, now: float) -> None:
        if not self._origin_set:
            self.scheduler.origin = float(now)
            self.press_scheduler.origin = float(now)
            self._origin_set = True

    def clock_stepped(self, step_s: float, now: float) -> list[Outgoing]:
        """Rig time just stepped by ``step_s`` seconds (the clock master restarted: back to its new launch's time;
        ``now``: the new rig time). The node calls this once per step (:meth:`common.clock.RigClock.set_offset`).

        The output goes on without a gap or a burst: the next sample to render is re-anchored to the new rig
        time (the origin moves by the step), so strikes of the new timeline play within the latency instead of
        waiting (late, mostly unheard) until rig time reaches what was already rendered, and a step forward
        does not render the skipped stretch at once. Ringing voices ring on; strikes and presses already queued
        stay on the output sample they were due at (sent for that moment, they play then). The step is kept
        in :meth:`timeline`, which a recording's sidecar gives. Before the first step or message (no origin
        yet) there is nothing to re-anchor.
        """
        del now  # the step alone moves the origin exactly; ``now`` is the Core hook's common argument
        if not self._origin_set or step_s == 0.0:
            return []
        if not self.clock_steps:
            self._first_origin = self.scheduler.origin
        self.scheduler.origin += step_s
        self.press_scheduler.origin = self.scheduler.origin
        self.clock_steps.append((self.next_sample, self.now))
        self.stats.clock_steps += 1
        log.info("sound re-anchored on the rig clock's step of %+.1f s: output sample %d is rig time %.3f s",
                 step_s, self.next_sample, self.now)
        return []

    def timeline(self) -> list[tuple[int, float]]:
        """(output sample, rig time) anchors, in order: sample ``n`` plays rig time ``t + (n - s) / sample_rate``
        for the last anchor ``(s, t)`` with ``s <= n``. One anchor (sample 0 at the origin) unless rig time
        stepped (:meth:`clock_stepped`)."""
        first = self._first_origin if self.clock_steps else self.scheduler.origin
        return [(0, first), *self.clock_steps]

    # ------------------------------------------------------------- render
    def samples_until(self, rig_time: float) -> int:
        """Output sample index of rig time ``rig_time`` (seconds)."""
        return int(math.floor((rig_time - self.scheduler.origin) * self.sample_rate + 1e-6))

    def render(self, until: float) -> F32:
        """Render whole blocks up to rig time ``until`` (seconds); returns them.

        Returns
        -------
        np.ndarray
            float32, shape (n,) for mono or (n, 2) for stereo; n is a multiple of the block size.
        """
        end = self.samples_until(until)
        blocks: list[F32] = []
        while self.next_sample + self.block <= end:
            blocks.append(self.render_block())
        if not blocks:
            shape = (0,) if self.channels == 1 else (0, 2)
            return np.zeros(shape, dtype=np.float32)
        return np.concatenate(blocks, axis=0)

    def _bus_for(self, instrument: str) -> F32:
        buf = self._bus.get(instrument)
        if buf is None:
            buf = np.zeros(self.block, dtype=np.float32)
            self._bus[instrument] = buf
        return buf

    def _apply_openness(self) -> None:
        """The latest /batteur/sound/openness of each hi-hat since the last block, once (a retune, and a choke when
        it dropped)."""
        pending, self._openness = self._openness, {}
        for inst_id, value in pending.items():
            inst = self.instruments.instruments[inst_id]
            if isinstance(inst, HiHat):
                inst.set_openness(value, self.pool, derived=True)  # a pedal's stream: cheap

    def render_block(self) -> F32:
        """Render the next block; returns float32 (block,) or (block, 2)."""
        n = self.block
        start = self.next_sample
        if self._openness:  # before this block's strikes, which set their own openness after it
            self._apply_openness()
        for sample, payload in self._within_budget(self.scheduler.pop_until(start + n)):
            try:
                self._strike(sample - start, payload)
            except Exception as exc:  # noqa: BLE001 - one strike failing must not take the block's others with it
                self._strike_failed(payload, exc)
        if len(self.press_scheduler):
            for sample, damping in self.press_scheduler.pop_until(start + n):
                self._press(sample - start, damping)
        for buf in self._bus.values():
            buf[:] = 0.0
        for inst in self.instruments.instruments.values():
            if inst.sounding:
                try:
                    inst.process(self._bus_for(inst.id))
                except Exception as exc:  # noqa: BLE001 - one instrument failing must not take the others' block
                    self._render_failed(inst.id, exc)
        if self._touched:
            self._follow_presses(self._touched)
            self._touched = set()
        for inst_id, voice_exc in self.pool.render(self._bus_for).items():  # voices that raised, by instrument
            self._render_failed(inst_id, voice_exc)
        for inst_id, buf in self._bus.items():
            if not np.isfinite(buf).all():
                self._silence(inst_id, buf)
        mix = np.zeros((n, self.channels), dtype=np.float32)
        for inst_id, buf in self._bus.items():
            inst = self.instruments.instruments[inst_id]
            g = inst.gain
            if self.channels == 1:
                mix[:, 0] += g * buf
            else:
                left, right = self._pans[inst_id]
                mix[:, 0] += g * left * buf
                mix[:, 1] += g * right * buf
        self._apply_master(mix)
        soft_limit(mix)
        if self._stage is not None:
            mix = self._stage.process(mix)
        else:
            np.clip(mix, -1.0, 1.0, out=mix)
        self.next_sample += n
        self.stats.blocks += 1
        out = mix[:, 0].copy() if self.channels == 1 else mix
        if self.settings.record:
            self._record.append(out)
        if self.on_block is not None:
            self.on_block(out)
        for sink in list(self.sinks):
            try:
                sink(out)
            except Exception as exc:  # noqa: BLE001 - one output failing (a full disk) must not silence the others
                self._drop_sink(sink, exc)
        return out

    def _apply_master(self, mix: F32) -> None:
        """In place: the master gain, before the limiter, so that a boost is limited softly (after it, the final
        clip cut every peak the boost pushed past full scale); a change glides linearly over MASTER_RAMP_S."""
        target = 10.0 ** (self.master_db / 20.0)
        g = self._master_gain
        if g == target:
            if g != 1.0:
                mix *= np.float32(g)
            return
        if target != self._master_glide[0]:  # a new value: glide to it from where the gain is, at a fixed rate
            self._master_glide = (target, (target - g) / (MASTER_RAMP_S * self.sample_rate))
        step = self._master_glide[1]
        ramp = g + step * np.arange(1, mix.shape[0] + 1)
        ramp = np.minimum(ramp, target) if step > 0 else np.maximum(ramp, target)
        mix *= ramp.astype(np.float32)[:, None]
        self._master_gain = float(ramp[-1])

    def _follow_presses(self, instruments: set[str]) -> None:
        """Presses on silent instruments (not processed) apply now; voices (samples, synthesis, noise) of
        ``instruments`` decay by their presses' mean rate from this block."""
        for inst_id in instruments:
            inst = self.instruments.instruments[inst_id]
            try:
                inst.apply_presses()  # nothing left to apply if it was processed
            except Exception as exc:  # noqa: BLE001 - as a failing process(): this instrument only
                self._render_failed(inst_id, exc)
            rate = inst.press_rate_total
            if rate > 0.0:
                self.pool.press_rates[inst_id] = rate
            else:
                self.pool.press_rates.pop(inst_id, None)

    def _drop_sink(self, sink: Sink, exc: Exception) -> None:
        """Stop feeding an output that failed, and close it (a WAV file keeps what it holds so far)."""
        self.sinks.remove(sink)
        name = getattr(sink, "path", type(sink).__name__)
        log.error("sound output %s failed at rig time %.1f s: %s; it was closed, the other outputs go on",
                  name, self.now, exc)
        try:
            sink.close()
        except Exception as close_exc:  # noqa: BLE001
            log.error("sound output %s could not be closed either (%s)", name, close_exc)

    def _silence(self, instrument: str, buf: F32) -> None:
        """Stop an instrument whose output went non-finite: NaN in the mix would ruin every instrument for good."""
        self.instruments.instruments[instrument].silence()
        self.pool.voices = [v for v in self.pool.voices if v.instrument != instrument]
        buf[:] = 0.0
        self.stats.silenced += 1
        self._log_drop("silenced", f"{instrument} produced non-finite samples with its current parameters: "
                       "its ringing was stopped")

    def _render_failed(self, instrument: str, exc: Exception) -> None:
        """An instrument's render (its modes, presses or voices) raised this block: it alone is lost. Its bus is
        zeroed for the block, its ringing, voices and half-done changes dropped (:meth:`Instrument.reset`) so its
        next strike starts clean; counted (``render_errors``, in Health's errors), the first failure of each
        instrument logged with its traceback, later ones rate-limited."""
        self._bus_for(instrument)[:] = 0.0
        self.pool.voices = [v for v in self.pool.voices if v.instrument != instrument]
        try:
            self.instruments.instruments[instrument].reset()
        except Exception as reset_exc:  # noqa: BLE001 - still silenced; its next render may fail and be counted
            log.error("%s: could not be reset after its render failed (%s: %s)", instrument,
                      type(reset_exc).__name__, reset_exc)
        self.stats.render_errors[instrument] += 1
        if self.stats.render_errors[instrument] == 1:
            log.error("%s: its render failed (%s: %s): silenced for this block, the other instruments play; its "
                      "next strike starts afresh (counted in Health's errors)", instrument, type(exc).__name__, exc,
                      exc_info=exc)
        else:
            self._log_drop("render_error", f"{instrument}: its render failed ({type(exc).__name__}: {exc}), "
                           f"silenced; {self.stats.render_errors[instrument]} so far")

    def _strike_failed(self, payload: tuple[str, Impact], exc: Exception) -> None:
        """Count a strike that raised (not played; the block's other strikes play): the first failure of each
        instrument is logged with its traceback, later ones rate-limited."""
        name = payload[0]
        self.stats.strike_errors[name] += 1
        if self.stats.strike_errors[name] == 1:
            log.error("%s: a strike failed, not played (%s: %s); its other strikes may fail too (counted in "
                      "Health's errors and dropped)", name, type(exc).__name__, exc, exc_info=exc)
        else:
            self._log_drop("strike_error", f"{name}: a strike failed, not played ({type(exc).__name__}: {exc}); "
                           f"{self.stats.strike_errors[name]} so far")

    def _strike(self, offset: int, payload: tuple[str, Impact]) -> None:
        name, impact = payload
        resolved = self.instruments.resolve(name, impact.zone, impact.r)
        if resolved is None:
            return
        inst, zone, r = resolved
        if self._resting and impact.part in self._resting:
            self._lift_striker(offset, impact.part)
        if impact.part == "hihat_top":
            zone = "pedal"  # the top plate closing on the bottom one: the foot chick
        strike = Strike(offset, float(impact.velocity), float(impact.impulse), float(r), float(impact.theta),
                        zone, int(impact.seq), float(impact.openness))
        inst.strike(strike, self.pool)
        self.stats.strikes += 1
        played = self.scheduler.origin + (self.next_sample + offset) / self.sample_rate
        self.strike_latencies.append(played - float(impact.time))

    # ------------------------------------------------------------- output
    def recording(self) -> F32:
        """Everything rendered so far (when ``record`` is on)."""
        if not self._record:
            shape = (0,) if self.channels == 1 else (0, 2)
            return np.zeros(shape, dtype=np.float32)
        return np.concatenate(self._record, axis=0)

    def write_wav(self, path: str | Path) -> Path:
        """Write the recording as a 24-bit WAV file (whole or not at all: an earlier file survives a failed
        write); returns the path. ValueError for a name that is not a sound file (.wav, .flac, ...)."""
        p = Path(path)
        fmt = wav_format(p, "wav")
        p.parent.mkdir(parents=True, exist_ok=True)
        audio = self.recording()
        if fmt == "WAV" and audio.size * 3 > WAV_DATA_LIMIT_BYTES:
            fmt = "RF64"  # a RIFF/WAVE header cannot hold the length: the end of the render would be lost to readers
            log.info("%s is over 4 GiB: written as RF64 (a WAV header cannot hold its length)", p)
        data = io.BytesIO()
        sf.write(data, audio, self.sample_rate, subtype="PCM_24", format=fmt)
        write_atomically(p, data.getvalue())
        return p

    @property
    def now(self) -> float:
        """Rig time of the next sample to render, seconds."""
        return self.scheduler.origin + self.next_sample / self.sample_rate

    @property
    def late(self) -> int:
        """Strikes and presses that arrived too late and played (applied) at once."""
        return self.scheduler.late + self.press_scheduler.late

    @property
    def rejected_total(self) -> int:
        """Valid messages refused or impacts not played, total (:attr:`SoundStats.rejected_total`): the node's
        Health counts them as dropped."""
        return self.stats.rejected_total

    @property
    def core_errors(self) -> int:
        """Failures of the core's own (strikes that raised, not played; instruments whose render raised, silenced
        for the block), total: the node's Health adds them to its ``errors``, so ``batteur ls`` shows a drum gone
        silent."""
        return sum(self.stats.strike_errors.values()) + sum(self.stats.render_errors.values())

    @property
    def duplicates(self) -> int:
        """Redundant copies of impacts and presses dropped, total (Health's ``duplicates``)."""
        return self.stats.duplicates

    def sounding_modes(self) -> int:
        """Modes of instruments currently ringing."""
        return sum(i.bank.size for i in self.instruments.instruments.values() if i.sounding)

    def close(self) -> None:
        """Close the sinks, free the pyo server, call :attr:`before_close`, then abandon the rebuilds still running
        (idempotent)."""
        while self.sinks:  # each leaves the list once closed: a close cut short (Ctrl-C) is retried next call
            sink = self.sinks[0]
            try:
                sink.close()
            except Exception as exc:  # noqa: BLE001 - the other outputs are still closed
                log.error("sound output %s could not be closed (%s)", getattr(sink, "path", type(sink).__name__), exc)
            self.sinks.pop(0)
        if self._stage is not None:
            self._stage.close()
            self._stage = None
        if getattr(self, "_openness", None):  # a pedal's last move is kept (--sound-params-out)
            self._apply_openness()
        hook, self.before_close = getattr(self, "before_close", None), None
        if hook is not None:
            try:  # the WAV file is closed already: a wait here (or a second Ctrl-C) cannot lose the take
                hook()
            except Exception as exc:  # noqa: BLE001 - the worker is closed all the same
                log.error("closing the sound core: %s", exc, exc_info=exc)
        worker = getattr(self, "_worker", None)
        if worker is not None:  # a rebuild in flight is abandoned (its child interpreter killed), not waited for
            worker.close()
            self._worker = None
            self._rebuilds.clear()
            self._queued.clear()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


def render_offline(
    impacts: list[Impact],
    duration: float,
    kit: Kit | None = None,
    settings: SoundSettings | None = None,
    wav: str | Path | None = None,
    prepare: Callable[[SoundCore], None] | None = None,
) -> F32:
    """Render impacts (rig times in seconds) for ``duration`` seconds in one call.

    The impacts are handed to a fresh core all at once (as if they had
    arrived early enough), so none is late. Returns float32 audio, shape (n,)
    or (n, 2); also writes ``wav`` when given. ``prepare``: called with the core before the impacts (a sound
    parameters file applied).
    """
    core = SoundCore(settings, kit)
    try:
        if prepare is not None:
            prepare(core)
        for impact in sorted(impacts, key=lambda i: i.time):
            core.handle(impact, core.now, "offline")
        core.render(duration + core.scheduler.origin + core.scheduler.latency)
        if wav is not None:
            core.write_wav(wav)
        return core.recording()
    finally:
        core.close()
