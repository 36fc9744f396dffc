"""Live recogniser node: plays an audio file (or reads an input device) in real time through
:class:`~services.recogniser.core.LiveRecogniser` and sends each recognised hit as an OSC
:class:`~common.messages.recogniser.DrumHit` over UDP (:class:`common.transport.UdpEndpoint`).
"""

from __future__ import annotations

import asyncio
import importlib.util
import ipaddress
import logging
import os
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from common.core import Outgoing
from common.messages.recogniser import DrumHit
from common.transport import UdpEndpoint, format_address, parse_address
from services.recogniser.audio import (
    MAX_DURATION_S,
    SAMPLE_RATE,
    BandCheck,
    band_limited,
    grid_step,
    load_audio,
    quantum,
)
from services.recogniser.core import LiveRecogniser
from services.recogniser.errors import RecogniserError
from services.recogniser.features import NARROW, full_rate_hz
from services.recogniser.model import Model, load_model
from services.recogniser.transcribe import PEAK, DrumEvent, fill_noise, fill_rms

log = logging.getLogger("batteur.recogniser")

BLOCK = 128
"""Samples per block fed to the core (5.8 ms at 22,050 Hz)."""

LIVE_FULL_RATE_HZ = full_rate_hz(NARROW)
"""The lowest sample rate that fills every band the live path reads (22,050 Hz audio, 48 bands to 10.5 kHz:
:data:`~services.recogniser.features.NARROW`), Hz: about 16.7 kHz. The offline network's 29 kHz is not the live
path's: it reads 22,050 Hz, so a 22,050 Hz take, or one resampled up from it, loses it nothing (the test pattern
played live: the same hits but one), while one sampled at 16 kHz lost most hi-hats (docs/recogniser.md,
"Live mode")."""
LIVE_BAND_CHECK = BandCheck(top_hz=(9000.0, NARROW.f_max_hz), ref_hz=(4000.0, 7500.0), limit_db=-30.0)
"""How the live path tells input holding next to nothing in its top bands, a device's and a file's
(:func:`~services.recogniser.audio.band_limited`): 9 kHz to its top band edge (10.5 kHz) against 4-7.5 kHz, warned
of 30 dB down. The two bands lie either side of the 8 kHz edge of a 16 kHz headset or USB microphone, clear of its
filter's rolloff and skirt: measured the offline way (from 8.4 kHz against 4-10 kHz, which hold them) such input
gave -18 to -40 dB and passed the -45 dB line, though played live it lost most hi-hats. Measured (19 takes: Groove
files and single drums on Batteur's kit, the held-out kit's pattern and samples; as files and as a device's first
3 s): through 16,000 Hz -41 to -58 dB, through 11,025 Hz -34 to -71 dB, all warned; full-band, through 22,050 Hz,
an 11 kHz low-pass (nothing lost live), quiet 16-bit takes: -16.7 dB or above, none (docs/recogniser.md, "Live
mode")."""
INPUT_CHECK_S = 3.0
"""Seconds of a device's input :class:`InputWatch` gathers before its band check and its look at the samples'
grid."""


class InputWatch:
    """What live input arriving block by block (a device) is: its first :data:`INPUT_CHECK_S` not all zeros (digital
    silence is waited out), at ``rate_hz``, are gathered, then given once to
    :func:`~services.recogniser.audio.band_limited` against :data:`LIVE_FULL_RATE_HZ` (``warn`` hears its warning,
    if any, once; ``name`` stands for the file in it) and to :func:`~services.recogniser.audio.grid_step`: input on a
    16- or 8-bit grid (a device giving integers, not resampled nor scaled on the way) has that :attr:`step` until a
    block leaves the grid. The band check is :data:`LIVE_BAND_CHECK`'s: a 16 kHz microphone is warned of."""

    def __init__(self, name: str, warn: Callable[[str], None] | None, rate_hz: int = SAMPLE_RATE,
                 seconds: float = INPUT_CHECK_S) -> None:
        self.name, self.warn, self.rate_hz = name, warn, rate_hz
        self._need = int(seconds * rate_hz)
        self._blocks: list[np.ndarray] = []
        self._have = 0
        self.done = False
        """Whether the checks have been made (once)."""
        self.step: float | None = None
        """The input's quantisation step, full scale 1, once :attr:`done` (None: floats, or not known yet)."""

    def feed(self, block: np.ndarray) -> None:
        """Add mono samples; the checks run on the block that completes :data:`INPUT_CHECK_S`."""
        x = np.nan_to_num(np.asarray(block, np.float32).reshape(-1), nan=0.0, posinf=0.0, neginf=0.0)
        if self.done:
            if self.step and grid_step(x, self.step) is None and np.any(x):
                self.step = None  # not integers after all: from now on as floats
            return
        self._blocks.append(x)
        self._have += x.size
        if self._have < self._need:
            return
        heard = np.concatenate(self._blocks)
        self._blocks, self._have = [], 0
        if not np.any(heard):  # digital silence (a muted or gated input before the drummer plays) passes every
            return  # check: look again at the next INPUT_CHECK_S, or it would pass them for good
        self.done = True
        self.step = grid_step(heard)
        text = band_limited(self.name, heard - np.float32(np.mean(heard)), self.rate_hz, LIVE_FULL_RATE_HZ,
                            LIVE_BAND_CHECK)
        if text and self.warn:
            self.warn(text)


def feed_device(core: LiveRecogniser, watch: InputWatch, block: np.ndarray,
                rng: np.random.Generator) -> list[Outgoing]:
    """Give a device's block to ``watch`` and to ``core`` (its input gain following the running peak); a quiet
    input on an integer grid (:attr:`InputWatch.step`) gets the file path's noise fill first
    (:func:`~services.recogniser.transcribe.fill_rms` of the core's running peak: the level the gain raises)."""
    watch.feed(block)
    if watch.step and (rms := fill_rms(core.peak, watch.step)):
        block = block + np.float32(rms) * rng.standard_normal(len(block), dtype=np.float32)
    return core.feed(block)


@dataclass
class LiveReport:
    """What a live run did. Latencies: wall time of sending minus wall time the onset was played, seconds."""

    hits: list[DrumHit] = field(default_factory=list)
    latencies_s: list[float] = field(default_factory=list)
    sent: int = 0
    duration_s: float = 0.0
    unreachable: dict[str, str] = field(default_factory=dict)
    """Destination ``host:port`` (as given) -> why hits sent there were lost, as the kernel reported it for one of them
    ("Connection refused": an ICMP port unreachable, nothing listens on that port); each destination once."""

    def events(self) -> list[DrumEvent]:
        """The hits as offline events (times from the start of the audio)."""
        from services.recogniser.classes import class_of_note

        out = []
        for h in self.hits:
            c = class_of_note(h.note)
            if c is not None:
                out.append(DrumEvent(h.time, c, h.velocity, h.confidence))
        return out


def check_targets(targets: Sequence[str]) -> list[tuple[str, int]]:
    """Parse ``host:port`` destinations and resolve their hosts to addresses; raise RecogniserError on a bad
    one (an unknown host would otherwise be dropped by the endpoint at every hit while the run reports them sent)."""
    out = []
    for t in targets:
        try:
            host, port = parse_address(t)
        except ValueError as exc:
            raise RecogniserError(f"--to {t}: {exc}") from exc
        try:
            infos = socket.getaddrinfo(host, port, socket.AF_UNSPEC, socket.SOCK_DGRAM)
        except (OSError, UnicodeError) as exc:
            raise RecogniserError(f"--to {t}: cannot resolve host {host!r}: {getattr(exc, 'strerror', None) or exc}"
                                  ) from exc
        v4 = [i for i in infos if i[0] == socket.AF_INET]  # as before for names: IPv4 first (localhost)
        out.append((str((v4 or infos)[0][4][0]).split("%")[0], port))
    return out


def bind_address(dests: Sequence[tuple[str, int]]) -> str:
    """The local address to send to ``dests`` (resolved by :func:`check_targets`) from: the loopback when every
    one is local (nothing listens on the network), else every interface, IPv6 and IPv4 if any is IPv6 (a socket
    bound to 127.0.0.1 cannot reach another machine, nor an IPv4 socket an IPv6 host)."""
    ips = [ipaddress.ip_address(host) for host, _ in dests]
    v6 = any(ip.version == 6 and getattr(ip, "ipv4_mapped", None) is None for ip in ips)
    if all(ip.is_loopback for ip in ips):
        return "::1" if v6 and all(ip.version == 6 for ip in ips) else ("::" if v6 else "127.0.0.1")
    return "::" if v6 else "0.0.0.0"


async def open_sender(dests: Sequence[tuple[str, int]], bind: str | None) -> UdpEndpoint:
    """A send-only endpoint (it accepts no datagram) bound to ``bind`` or to :func:`bind_address`."""
    host = bind or bind_address(dests)
    try:
        return await UdpEndpoint.open(host=host, port=0, allow=[])
    except OSError as exc:
        raise RecogniserError(f"cannot open a UDP socket on {host} to send hits: {exc.strerror or exc}") from exc


@dataclass
class Sender:
    """A send-only endpoint for one destination, its socket connected to it: the kernel reports a destination's
    ICMP errors (port unreachable: nothing listens there) only to a connected UDP socket."""

    endpoint: UdpEndpoint
    dest: tuple[str, int]
    name: str
    """The destination as the user gave it (``--to``)."""
    connected: bool

    def lost(self) -> str | None:
        """Why datagrams sent to ``dest`` were lost, if the kernel said so since the last call (else None)."""
        error = self.endpoint.pending_error() if self.connected else 0
        if error:
            return os.strerror(error)
        if self.endpoint.send_errors:  # the event loop's reader took the error first (the endpoint logs it)
            return "a socket error"
        return None


async def open_senders(targets: Sequence[str], dests: Sequence[tuple[str, int]], bind: str | None) -> list[Sender]:
    """One :class:`Sender` per target ``host:port`` and its address ``dests`` (:func:`check_targets`), each
    bound as :func:`open_sender` binds; a socket that cannot be connected still sends, unconnected."""
    senders: list[Sender] = []
    try:
        for name, dest in zip(targets, dests, strict=True):
            endpoint = await open_sender([dest], bind)
            senders.append(Sender(endpoint, dest, name, _connect(endpoint, dest)))
    except BaseException:
        for sender in senders:
            sender.endpoint.close()
        raise
    return senders


def _connect(endpoint: UdpEndpoint, dest: tuple[str, int]) -> bool:
    """Connect ``endpoint``'s socket to ``dest``; whether it could be. Sends still name ``dest`` (a connected UDP
    socket accepts its own peer)."""
    try:
        endpoint.connect(dest)
    except OSError as exc:
        log.debug("hits to %s leave from an unconnected socket: %s", format_address(*dest), exc)
        return False
    return True


async def play_file(
    path: str | Path,
    targets: Sequence[str],
    model: Model | None = None,
    speed: float = 1.0,
    block: int = BLOCK,
    max_duration_s: float = MAX_DURATION_S,
    bind: str | None = None,
    on_hit: Callable[[DrumHit, float], None] | None = None,
    report: LiveReport | None = None,
    warn: Callable[[str], None] | None = None,
) -> LiveReport:
    """Play an audio file in real time (``speed`` times faster) through the live recogniser.

    Each block is fed when its last sample would have been played; each hit is
    sent at once to every target (``host:port``). The input gain is fixed from
    the file's peak, as a level meter set before a take would be. ``bind``: the
    local address to send from (default: :func:`bind_address`). Hits are added to
    ``report`` as they are sent, so a caller stopped by Ctrl-C still has them.
    ``warn`` hears of a suspect file as offline, its rate and content judged against the live path's bands
    (:data:`LIVE_FULL_RATE_HZ`, :data:`LIVE_BAND_CHECK`); a quiet file stored as integers gets the offline path's
    noise fill (:func:`~services.recogniser.transcribe.fill_rms`) before it is played.
    """
    dests = check_targets(targets)
    audio = load_audio(path, max_duration_s=max_duration_s, warn=warn, full_rate_hz=LIVE_FULL_RATE_HZ,
                       band_check=LIVE_BAND_CHECK)
    peak = float(np.max(np.abs(audio)))
    if rms := fill_rms(peak, quantum(path)):  # the gain stays the peak's, as offline
        fill_noise(audio, rms)
    core = LiveRecogniser(model or load_model(), gain=PEAK / peak, start_time=0.0)
    senders = await open_senders(targets, dests, bind)
    report = report if report is not None else LiveReport()
    report.duration_s = len(audio) / SAMPLE_RATE
    t0 = time.perf_counter()
    try:
        for start in range(0, len(audio) + block, block):
            chunk = audio[start : start + block]
            end_s = min(len(audio), start + block) / SAMPLE_RATE
            # always yield, even when behind: Ctrl-C (a task cancellation) is only delivered at an await
            await asyncio.sleep(max(0.0, t0 + end_s / speed - time.perf_counter()))
            out = core.feed(chunk) if len(chunk) else core.flush()
            send_hits(out, senders, report, t0, speed, on_hit)
            if not len(chunk):
                break
    finally:
        close_senders(senders, report)
    return report


def send_hits(
    out: Sequence[Outgoing], senders: Sequence[Sender], report: LiveReport, t0: float,
    speed: float, on_hit: Callable[[DrumHit, float], None] | None,
) -> None:
    """Send each detected hit to every target and record it with its latency (seconds since its onset
    was played: ``t0`` is the perf_counter time of audio time 0, ``speed`` the playback speed), and a
    destination that refuses them in ``report.unreachable`` (before ``on_hit`` hears of the hit)."""
    now = time.perf_counter()
    for o in out:
        assert isinstance(o.message, DrumHit)
        for sender in senders:
            sender.endpoint.send(o.message, sender.dest)
            report.sent += 1
        note_unreachable(senders, report)
        latency = now - (t0 + o.message.time / speed)
        report.hits.append(o.message)
        report.latencies_s.append(latency)
        if on_hit:
            on_hit(o.message, latency)


def note_unreachable(senders: Sequence[Sender], report: LiveReport) -> None:
    """Record in ``report`` the destinations the kernel said lost hits, each once (on loopback an ICMP port
    unreachable is pending as soon as the send returns)."""
    for sender in senders:
        if sender.name not in report.unreachable:
            why = sender.lost()
            if why:
                report.unreachable[sender.name] = why


def close_senders(senders: Sequence[Sender], report: LiveReport) -> None:
    """Close the senders, after a last look for a destination that refused (the last hit's send)."""
    note_unreachable(senders, report)
    for sender in senders:
        sender.endpoint.close()


def input_device_available() -> str | None:
    """Why live input from a device cannot run here, or None if it can."""
    if importlib.util.find_spec("sounddevice") is None:
        return "reading an input device needs the 'sounddevice' package (pip install sounddevice)"
    import sounddevice  # type: ignore[import-not-found]

    try:
        devices = sounddevice.query_devices()
    except Exception as exc:  # PortAudio errors
        return f"no audio input device: {exc}"
    if not any(d.get("max_input_channels", 0) > 0 for d in devices):
        return "no audio input device found on this machine"
    return None


async def listen_device(
    targets: Sequence[str], model: Model | None = None, device: str | None = None, seconds: float | None = None,
    bind: str | None = None, on_hit: Callable[[DrumHit, float], None] | None = None,
    report: LiveReport | None = None, warn: Callable[[str], None] | None = None,
) -> LiveReport:
    """Listen to an input device (mono mix, resampled by PortAudio to 22,050 Hz) and send hits (into ``report``
    as they go: Ctrl-C is how an endless listen stops). ``warn`` hears once if its first :data:`INPUT_CHECK_S`
    hold next to nothing in the live path's top bands (:class:`InputWatch`: a device sampling at 16,000 Hz); quiet
    input on an integer grid gets the noise fill (:func:`feed_device`)."""
    problem = input_device_available()
    if problem:
        raise RecogniserError(problem)
    import sounddevice

    dests = check_targets(targets)
    core = LiveRecogniser(model or load_model(), gain=None)
    watch = InputWatch(f"input device {device!r}" if device else "the default input device", warn)
    rng = np.random.default_rng(0)  # the noise fill's, seeded as the file path's
    loop = asyncio.get_running_loop()
    queue: asyncio.Queue[np.ndarray] = asyncio.Queue()

    def callback(indata: np.ndarray, frames: int, time_info: object, status: object) -> None:
        loop.call_soon_threadsafe(queue.put_nowait, indata.mean(axis=1).copy())

    senders = await open_senders(targets, dests, bind)
    report = report if report is not None else LiveReport()
    t0 = time.perf_counter()
    try:
        with sounddevice.InputStream(samplerate=SAMPLE_RATE, blocksize=BLOCK, device=device, channels=1,
                                     dtype="float32", callback=callback):
            while seconds is None or time.perf_counter() - t0 < seconds:
                send_hits(feed_device(core, watch, await queue.get(), rng), senders, report, t0, 1.0, on_hit)
    finally:
        close_senders(senders, report)
        report.duration_s = time.perf_counter() - t0
    return report
