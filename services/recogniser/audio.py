"""Reading audio files for transcription: any sample rate, mono or stereo.

Files are read with soundfile (WAV, FLAC, OGG/Vorbis, AIFF, ...), mixed down
to mono and resampled to the rate asked for (default :data:`SAMPLE_RATE`) with a polyphase filter
(:func:`scipy.signal.resample_poly`).
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import scipy.fft
import soundfile as sf
from scipy.signal import resample_poly

from common.input_file import file_problem
from common.score.events import MAX_SCORE_BYTES, looks_like_text, starts_as_midi, unicode_bom
from common.score.text import parse_text
from services.recogniser.errors import AudioFileError

SAMPLE_RATE = 22050
"""Sample rate of the live path and the default of :func:`load_audio`, Hz (the offline network reads audio at its
own rate, :attr:`~services.recogniser.framenet.FrameNet.sample_rate`: 44,100 Hz for the shipped one)."""

MAX_DURATION_S = 3600.0
"""Longest file accepted by default, seconds (one hour)."""
MIN_DURATION_S = 0.01
"""Shorter files are refused as too short: one analysis frame (the recognisers' frames are 10 ms), seconds."""

SILENCE_PEAK = 10 ** (-70 / 20)
"""A file whose peak is below this (-70 dBFS) is called silent."""


RESAMPLE_BLOCK = 1 << 20
"""Input samples resampled at a time (about 22 s at 48 kHz): the filter runs in float64, so resampling an hour at
once held float64 copies of it in and out (nearly 4 times the float32 audio: 2.7 GB at 48 kHz), a block about
16 MB."""


def resample(signal: np.ndarray, sr_in: int, sr_out: int = SAMPLE_RATE, block: int = RESAMPLE_BLOCK) -> np.ndarray:
    """Resample a mono signal, ``block`` input samples at a time: the same samples as one
    :func:`scipy.signal.resample_poly` over it all (each block is filtered with enough of its neighbours on
    either side, and starts where the filter's phase does), in a fraction of the memory.

    Parameters
    ----------
    signal : np.ndarray [shape=(n,)]
    sr_in, sr_out : int, Hz
    block : input samples filtered at a time (rounded to a whole number of the ratio's periods)

    Returns
    -------
    np.ndarray [shape=(ceil(n * sr_out / sr_in),), dtype=float32]
    """
    if sr_in == sr_out:
        return np.asarray(signal, dtype=np.float32)
    ratio = Fraction(sr_out, sr_in).limit_denominator(2000)
    up, down = ratio.numerator, ratio.denominator
    n = len(signal)
    n_out = n * up // down + bool(n * up % down)
    # resample_poly's filter reaches 10 * max(up, down) upsampled samples each way: context in input samples,
    # a whole number of periods so that each block's outputs are the whole signal's
    context = (-(-(10 * max(up, down) // up + 2) // down) + 1) * down
    step = max(1, block // down) * down
    out = np.empty(n_out, dtype=np.float32)
    for start in range(0, n, step):
        a, b = max(0, start - context), min(n, start + step + context)
        part = resample_poly(np.asarray(signal[a:b], dtype=np.float64), up, down)
        first, stop = start * up // down, min(n_out, (start + step) * up // down)
        skip = (start - a) * up // down
        out[first:stop] = part[skip : skip + stop - first]
    return out


def to_mono(data: np.ndarray) -> np.ndarray:
    """Average the channels of a (n,) or (n, channels) array to shape (n,)."""
    if data.ndim == 1:
        return data
    return np.mean(data, axis=1)


_SHORT_DATA = re.compile(r"^\s*(?:data|SSND)\s*:\s*(\d+)\s*\(should be (\d+)\)", re.MULTILINE)
"""libsndfile's log line for a WAV data (AIFF SSND) chunk shorter than its header says (a recording cut off)."""

_OGG_CUT = "Last page lacks an end-of-stream bit"
"""libsndfile's log line for an Ogg stream that stops without its last page (a recording cut off)."""


def truncation(extra_info: str) -> str | None:
    """Why the file holds less audio than its header announces (from soundfile's ``info().extra_info``), or None."""
    if _OGG_CUT in (extra_info or ""):
        return "its Ogg stream stops without its end mark (truncated?)"
    found = _SHORT_DATA.search(extra_info or "")
    if found is None or int(found.group(2)) >= int(found.group(1)):
        return None
    return f"shorter than its header says ({found.group(2)} of {found.group(1)} data bytes: truncated?)"


_DATA_SIZE = re.compile(r"^data\s*:\s*(\d+)\s*$", re.MULTILINE)
"""libsndfile's log line for a WAV data chunk whose size it takes as given."""

_FILE_LENGTH = re.compile(r"^Length\s*:\s*(\d+)", re.MULTILINE)
"""libsndfile's log line for the file's size in bytes."""

_NOT_A_CHUNK = re.compile(r"Unknown chunk marker|> file length")
"""libsndfile's log for bytes that are not a chunk (an unprintable marker, a size past the file's end)."""


def unread_tail(extra_info: str) -> str | None:
    """Why audio after the WAV data chunk is not read (its header says less than the file holds, as a recorder
    that updates the header now and then leaves it when it stops abruptly), or None."""
    text = extra_info or ""
    found, length = _DATA_SIZE.search(text), _FILE_LENGTH.search(text)
    if found is None or length is None or not _NOT_A_CHUNK.search(text, found.end()):
        return None
    return (f"its header gives the audio {found.group(1)} bytes of the file's {length.group(1)}, and what follows "
            "is not a WAV chunk (a header not updated when the recording stopped?): the rest is not read")


def _unfinished(extra_info: str, path: Path) -> str | None:
    """The error for a WAV whose header says 0 bytes of audio while the file holds more (a take still recording
    when its recorder exited: Pd's writesf~), else None."""
    found, length = _DATA_SIZE.search(extra_info or ""), _FILE_LENGTH.search(extra_info or "")
    if found is None or length is None or int(found.group(1)) != 0 or int(length.group(1)) <= 1024:
        return None
    return (f"{path}: its header says it holds no audio (0 samples), yet the file is {length.group(1)} bytes: a "
            f"recording cut short? `batteur wav-repair {path}` gives it the length it holds")


DECODE_BLOCK = 4096
"""Frames read at a time when a file's decoding fails part way, to keep what comes before."""


def _decodable_start(path: Path, failure: Exception) -> tuple[np.ndarray, int]:
    """The audio of ``path`` up to where decoding fails (a FLAC file cut off loses its decoder's sync there), and
    its sample rate; :class:`AudioFileError` naming ``failure`` if nothing decodes."""
    blocks: list[np.ndarray] = []
    try:
        with sf.SoundFile(str(path)) as f:
            rate = f.samplerate
            while len(block := f.read(DECODE_BLOCK, dtype="float32", always_2d=False)):
                blocks.append(block)
    except Exception:  # where the decoding stops: what came before is kept
        pass
    if not blocks:
        raise AudioFileError(f"{path}: cannot decode the audio: {failure}") from failure
    return np.concatenate(blocks), rate


TEXT_SAMPLE_BYTES = 4096
"""Bytes of a file soundfile cannot open looked at to tell text (:func:`~common.score.events.looks_like_text`)."""


def _is_text_score(path: Path, head: bytes) -> bool:
    """Whether ``path``, text starting with ``head``, is a score in the text format: the score reader parses it and
    finds notes in it (a score with an error, or without notes, is not told from other text)."""
    bom = unicode_bom(head)
    try:
        if path.stat().st_size > MAX_SCORE_BYTES:
            return False
        text = path.read_bytes().decode(bom[0] if bom else "utf-8-sig")
        return bool(parse_text(text, source=str(path)).events)
    except (OSError, ValueError):  # ScoreError and UnicodeDecodeError are ValueErrors
        return False


def _not_audio(path: Path) -> str | None:
    """What ``path``, which soundfile cannot open, is instead, with what to do, said after the path; None when
    nothing is known of it. A score (MIDI or the text format: given to transcribe in place of a take of it) is
    said to be one, and how to hear it; libsndfile said only "Format not recognised"."""
    try:
        with path.open("rb") as f:
            head = f.read(TEXT_SAMPLE_BYTES)
    except OSError:
        return None
    arg = shlex.quote(str(path))  # the commands said can be pasted whatever the file's name
    if starts_as_midi(head):
        return f"this is a MIDI file (a score), not audio: `batteur render {arg} -o DIR` plays it"
    if not head:
        return "the file is empty (0 bytes)"
    if not looks_like_text(head):
        return None
    if _is_text_score(path, head):
        return (f"this is a score in Batteur's text format, not audio: to hear it, `batteur render {arg} -o DIR`; "
                f"to compare a student's take with it, `batteur compare {arg} TAKE`")
    return "not a readable audio file (WAV, FLAC, OGG...): it is a text file"


INTEGER_BITS = {"PCM_S8": 8, "PCM_U8": 8, "PCM_16": 16, "PCM_24": 24, "PCM_32": 32}
"""Bits per sample of the soundfile subtypes that store linear integers (WAV, AIFF, FLAC...)."""


def quantum(path: str | Path) -> float | None:
    """The quantisation step of the audio file ``path``, full scale 1 (a 16-bit file: 2**-15), or None for a file
    stored otherwise (floats, MP3, Ogg Vorbis, A-law ...; one soundfile cannot read)."""
    try:
        bits = INTEGER_BITS.get(sf.info(str(path)).subtype)
    except Exception:  # soundfile raises several types; load_audio has said what is wrong with the file
        return None
    return None if bits is None else 2.0 ** (1 - bits)


GRID_BITS = (8, 16)
"""Integer sizes :func:`grid_step` recognises, bits (24-bit samples are not told from floats: float32 holds
them all on a finer grid, and a 24-bit take is never quiet for its bits)."""


def grid_step(samples: np.ndarray, step: float | None = None) -> float | None:
    """The quantisation step of float samples that are all integers of :data:`GRID_BITS` bits scaled to full
    scale 1 (multiples of 2**-7 or 2**-15: what PortAudio gives for an integer device), the coarsest that fits,
    or None (off every grid, or all zero: nothing to tell); ``step``: only that grid is tried."""
    x = np.asarray(samples, np.float64)
    if not np.any(x):
        return None
    for q in (step,) if step else (2.0 ** (1 - bits) for bits in GRID_BITS):
        if np.array_equal(x / q, np.round(x / q)):
            return q
    return None


COMMON_RATES_HZ = (22050, 24000, 32000, 44100, 48000, 88200, 96000, 192000)
"""Sample rates recorders offer, Hz: the warning for a file sampled too slowly names the lowest that is enough for
the path that warns (offline, about 29 kHz: 32,000 Hz; live, about 16.7 kHz: 22,050 Hz, the rate it reads)."""


def low_rate(path: Path | str, rate_hz: int, full_rate_hz: float) -> str | None:
    """The warning for a file sampled at ``rate_hz``, below ``full_rate_hz`` (the lowest rate that fills every band
    the recogniser reads: :func:`~services.recogniser.features.full_rate_hz`), or None. Such a file holds nothing
    in the top bands, where hi-hats and cymbals are heard over snares: on a Batteur render of a rock groove
    resampled to 22,050 Hz the hi-hat F-measure fell from 0.83 to 0.69 (docs/recogniser.md, "What it does")."""
    if rate_hz >= full_rate_hz:
        return None
    enough = next((r for r in COMMON_RATES_HZ if r >= full_rate_hz), None)
    advice = f" (record at {enough:,} Hz or more if you can)" if enough else ""
    return (f"{path}: sampled at {rate_hz:,} Hz, it holds nothing above {rate_hz / 2:,.0f} Hz, where the recogniser "
            f"tells hi-hats and cymbals from snares: expect hi-hats missed or heard as other drums{advice}")


CONTENT_FRAME = 2048
"""Samples per frame of :func:`top_band_level`."""
CONTENT_HOP = 4096
"""Samples between the starts of :func:`top_band_level`'s frames: every other frame's length, half the file read
(a strike rings over several frames; 0.5 s for 10 minutes at 48 kHz, against 2.7 s for every sample in float64)."""
CONTENT_REF_HZ = (4000.0, 10000.0)
"""The band :func:`top_band_level` compares the top bands with, Hz: below any rate's edge a recorder uses, and
where snares, hi-hats and cymbals all sound."""
CONTENT_TOP_HZ = 18000.0
"""The highest frequency :func:`top_band_level` looks at, Hz (the shipped analysis's top band edge)."""
CONTENT_LOUD = 0.1
"""The fraction of frames, the loudest, that :func:`top_band_level` averages (a quiet tail's noise is not music)."""
BAND_LIMITED_DB = -45.0
"""A file whose top bands are this far below its :data:`CONTENT_REF_HZ` band (:func:`top_band_level`), dB, is
warned of as holding nothing there: measured on Batteur's renders and the held-out kit's samples (5 s, 44.1 and
48 kHz), resampled to 22,050 Hz and back with scipy's resampler: -52 to -85 dB; the same full-band: -18 to +7 dB
with hi-hats or snares, -23 and -33 dB for a kick alone (docs/recogniser.md, "What it does")."""


def top_band_level(mono: np.ndarray, rate_hz: int, low_hz: float, block: int = 512, high_hz: float = CONTENT_TOP_HZ,
                   ref_hz: tuple[float, float] = CONTENT_REF_HZ) -> float | None:
    """The power density from ``low_hz`` to ``high_hz`` (or near half of ``rate_hz``) relative to that of ``ref_hz``,
    over the :data:`CONTENT_LOUD` loudest frames of :data:`CONTENT_FRAME` samples (:data:`CONTENT_HOP` apart), dB;
    None when it cannot be told (too short a file, too low a rate, nothing in the reference band). A recording
    resampled up from 22,050 Hz keeps its low rate's empty top, which the declared rate hides (``block``: frames
    transformed at a time, bounding memory)."""
    top_hz = min(high_hz, 0.49 * rate_hz)
    if len(mono) < CONTENT_FRAME or top_hz <= low_hz:
        return None
    f = np.fft.rfftfreq(CONTENT_FRAME, 1.0 / rate_hz)
    ref, top = (f >= ref_hz[0]) & (f < ref_hz[1]), (f >= low_hz) & (f < top_hz)
    frames = np.lib.stride_tricks.sliding_window_view(mono, CONTENT_FRAME)[::CONTENT_HOP]
    win = np.hanning(CONTENT_FRAME).astype(np.float32)
    sums = np.empty((len(frames), 3), np.float64)  # per frame: all bins, reference band, top band
    for a in range(0, len(frames), block):
        power = np.abs(scipy.fft.rfft(frames[a : a + block] * win, axis=1)) ** 2  # float32, unlike numpy's
        sums[a : a + block] = np.stack([power.sum(1), power[:, ref].sum(1), power[:, top].sum(1)], axis=1)
    loud = sums[np.argsort(sums[:, 0])[-max(1, int(np.ceil(CONTENT_LOUD * len(sums)))) :]]
    ref_density, top_density = loud[:, 1].sum() / ref.sum(), loud[:, 2].sum() / top.sum()
    if ref_density <= 0.0:
        return None
    return 10.0 * float(np.log10(max(top_density / ref_density, 1e-30)))


@dataclass(frozen=True)
class BandCheck:
    """How :func:`band_limited` measures a path's top bands when the path's own are not the offline ones: the power
    density of ``top_hz`` against that of ``ref_hz`` (:func:`top_band_level`), warned of below ``limit_db``."""

    top_hz: tuple[float, float]
    """The band that must not be empty, Hz: a band the path reads, above the edge of the rates it warns of."""
    ref_hz: tuple[float, float]
    """The band it is compared with, Hz: below that edge, where snares, hi-hats and cymbals sound."""
    limit_db: float
    """Audio whose ``top_hz`` is this far below its ``ref_hz``, or further, is warned of, dB."""


def band_limited(path: Path | str, mono: np.ndarray, rate_hz: int, full_rate_hz: float,
                 check: BandCheck | None = None) -> str | None:
    """The warning for a file sampled fast enough (``rate_hz`` at least ``full_rate_hz``) whose audio yet holds next
    to nothing above half of ``full_rate_hz`` (:func:`top_band_level` below :data:`BAND_LIMITED_DB`): a recording
    made at a lower rate and resampled up transcribes as one at its own rate does (the held-out kit's test
    pattern through 22,050 Hz and back to 44,100 Hz: the same notes as at 22,050 Hz), or None. ``path``: the file,
    or the name of the live input (:class:`~services.recogniser.node.InputWatch`). ``check``: measure that way
    instead (the live path's, :data:`~services.recogniser.node.LIVE_BAND_CHECK`; None: from half of
    ``full_rate_hz`` up, against :data:`CONTENT_REF_HZ`, below :data:`BAND_LIMITED_DB`, as offline)."""
    if rate_hz < full_rate_hz:
        return None  # low_rate's warning
    if check is None:
        check = BandCheck((full_rate_hz / 2, CONTENT_TOP_HZ), CONTENT_REF_HZ, BAND_LIMITED_DB)
    level = top_band_level(mono, rate_hz, check.top_hz[0], high_hz=check.top_hz[1], ref_hz=check.ref_hz)
    if level is None or level >= check.limit_db:
        return None
    enough = next((r for r in COMMON_RATES_HZ if r >= full_rate_hz), None)
    advice = f" (record at {enough:,} Hz or more if you can)" if enough else ""
    return (f"{path}: it holds next to nothing above {full_rate_hz / 2000:.1f} kHz ({-level:.0f} dB below its "
            f"{check.ref_hz[0] / 1000:g}-{check.ref_hz[1] / 1000:g} kHz content), where the recogniser tells "
            f"hi-hats and cymbals from snares: recorded at a lower rate and resampled up to {rate_hz:,} Hz? expect "
            f"hi-hats missed or heard as other drums{advice}")


def load_audio(path: str | Path, max_duration_s: float = MAX_DURATION_S, sample_rate: int = SAMPLE_RATE,
               warn: Callable[[str], None] | None = None, full_rate_hz: float | None = None,
               band_check: BandCheck | None = None) -> np.ndarray:
    """Read an audio file as mono float32 at ``sample_rate`` Hz (default :data:`SAMPLE_RATE`).

    The mean (a DC offset) is removed: it is inaudible, yet it would count in the silence test and the
    peak the audio is scaled by, and the step from the silence around the file would sound like a kick.

    Parameters
    ----------
    path : audio file (WAV, FLAC, OGG, ...)
    max_duration_s : longer files are refused, seconds
    warn : called with a message naming the file when it is usable but suspect (truncated; sampled below
        ``full_rate_hz``, or holding next to nothing above half of it: :func:`band_limited`)
    full_rate_hz : the lowest sample rate that fills every band of the caller's analysis, Hz (None: not checked)
    band_check : how :func:`band_limited` measures the top bands (None: the offline way)

    Returns
    -------
    np.ndarray [shape=(n,), dtype=float32], zero mean

    Raises
    ------
    AudioFileError
        the file is missing, not a regular file (a FIFO), unreadable, empty, silent or longer than
        ``max_duration_s``.
    """
    p = Path(path)
    # a FIFO or a device: opening it waits for a writer (or reads for ever), and the file is opened twice
    problem = file_problem(p, "an audio file", give="an audio file saved to disk (WAV, FLAC, OGG...)")
    if problem is not None:
        raise AudioFileError(f"{p}: {problem}")
    try:  # libsndfile says only "System error" when it may not read the file
        p.open("rb").close()
    except OSError as exc:
        raise AudioFileError(f"{p}: cannot read the file ({exc.strerror or exc})") from None
    try:
        info = sf.info(str(p))
    except Exception as exc:  # soundfile raises several types (LibsndfileError, RuntimeError, TypeError)
        said = _not_audio(p)  # libsndfile's "Format not recognised" says nothing of what to do
        if said is not None:
            raise AudioFileError(f"{p}: {said}") from None
        raise AudioFileError(f"{p}: not a readable audio file (WAV, FLAC, OGG...): {exc}") from exc
    if info.frames <= 0 or info.samplerate <= 0:
        raise AudioFileError(_unfinished(info.extra_info, p) or f"{p}: the file holds no audio (0 samples)")
    duration = info.frames / info.samplerate
    if 0 < info.frames < MIN_DURATION_S * info.samplerate:  # its one sample would otherwise be called silent
        samples = f"{info.frames} sample{'' if info.frames == 1 else 's'}"
        raise AudioFileError(f"{p}: too short to transcribe: {samples} ({duration * 1000:.3g} ms); the minimum is "
                             f"{MIN_DURATION_S * 1000:g} ms, one analysis frame")
    if duration > max_duration_s:
        raise AudioFileError(
            f"{p}: {duration:.4g} s long, over the limit of {max_duration_s:.4g} s "
            "(cut the file, or raise the limit with --max-duration)"
        )
    try:
        data, sr = sf.read(str(p), dtype="float32", always_2d=False)
    except Exception as exc:
        data, sr = _decodable_start(p, exc)
        if warn:
            warn(f"{p}: cannot decode the audio after {len(data) / sr:.4g} s ({exc}: cut off?)")
    mono = to_mono(np.asarray(data, dtype=np.float32))
    if mono.size == 0:
        raise AudioFileError(f"{p}: the file holds no audio (0 samples)")
    if not np.all(np.isfinite(mono)):
        raise AudioFileError(f"{p}: the audio holds NaN or infinite samples")
    offset = float(np.mean(mono, dtype=np.float64))
    mono -= np.float32(offset)  # in place, and the peak without |mono|: an hour at 48 kHz is 0.7 GB a copy
    if max(float(mono.max()), -float(mono.min())) < SILENCE_PEAK:
        dc = f" but for a constant offset of {offset:.3g}" if abs(offset) >= SILENCE_PEAK else ""
        if data.ndim > 1 and float(np.max(np.abs(data - np.mean(data, axis=0)))) >= SILENCE_PEAK:
            dc = " once its channels are mixed: they cancel (one channel's polarity inverted?)"
        raise AudioFileError(f"{p}: the audio is silent{dc} (peak below -70 dBFS); nothing to transcribe")
    short = truncation(info.extra_info) or unread_tail(info.extra_info)
    if short and warn:
        warn(f"{p}: {short}; transcribing the {len(mono) / sr:.4g} s it holds")
    if full_rate_hz is not None and warn:
        slow = low_rate(p, int(sr), full_rate_hz) or band_limited(p, mono, int(sr), full_rate_hz, band_check)
        if slow:
            warn(slow)
    return resample(mono, int(sr), sample_rate)
