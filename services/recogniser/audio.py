"""Reading audio files for transcription: any sample rate, mono or stereo.

Files are read with soundfile (WAV, FLAC, OGG/Vorbis, AIFF, ...), mixed down
to mono and resampled to the rate asked for (default :data:`SAMPLE_RATE`) with a polyphase filter
(:func:`scipy.signal.resample_poly`).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
import soundfile as sf
from scipy.signal import resample_poly

from common.input_file import file_problem
from common.score.events import starts_as_midi
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


def _is_midi(path: Path) -> bool:
    """Whether ``path`` starts as a Standard MIDI File (``MThd``) or a RIFF MIDI file (``RIFF`` ... ``RMID``)."""
    try:
        with path.open("rb") as f:
            head = f.read(12)
    except OSError:
        return False
    return starts_as_midi(head)


COMMON_RATES_HZ = (32000, 44100, 48000, 88200, 96000, 192000)
"""Sample rates recorders offer, Hz: the warning for a file sampled too slowly names the lowest that is enough."""


def low_rate(path: Path, rate_hz: int, full_rate_hz: float) -> str | None:
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


def load_audio(path: str | Path, max_duration_s: float = MAX_DURATION_S, sample_rate: int = SAMPLE_RATE,
               warn: Callable[[str], None] | None = None, full_rate_hz: float | None = None) -> np.ndarray:
    """Read an audio file as mono float32 at ``sample_rate`` Hz (default :data:`SAMPLE_RATE`).

    The mean (a DC offset) is removed: it is inaudible, yet it would count in the silence test and the
    peak the audio is scaled by, and the step from the silence around the file would sound like a kick.

    Parameters
    ----------
    path : audio file (WAV, FLAC, OGG, ...)
    max_duration_s : longer files are refused, seconds
    warn : called with a message naming the file when it is usable but suspect (truncated; sampled below
        ``full_rate_hz``)
    full_rate_hz : the lowest sample rate that fills every band of the caller's analysis, Hz (None: not checked)

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
        if _is_midi(p):  # libsndfile's "Format not recognised" says nothing of what to do
            raise AudioFileError(f"{p}: this is a MIDI file (a score), not audio: `batteur render {p} -o DIR` "
                                 "plays it") from None
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
    slow = low_rate(p, int(sr), full_rate_hz) if full_rate_hz is not None else None
    if slow and warn:
        warn(slow)
    return resample(mono, int(sr), sample_rate)
