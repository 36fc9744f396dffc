"""Framewise training data: band spectrograms of rendered excerpts and their strikes.

Each excerpt is rendered (:mod:`.excerpts`), turned into the recogniser's band
spectrograms for three analysis windows (:func:`~services.recogniser.features.multi_spectrogram`;
a network's input is some of them) and kept with its true strikes. Targets are made from the strikes when
training (:func:`targets`), so the cache holds only spectra (float16) and strikes.
"""

from __future__ import annotations

import multiprocessing as mp
import shutil
import time
import zipfile
from contextlib import nullcontext
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from services.recogniser import features as F
from services.recogniser.audio import resample
from services.recogniser.classes import N_CLASSES
from services.recogniser.training.excerpts import (
    DRY_P,
    VARY_P,
    Job,
    excerpt_samples,
    jobs,
    prepare,
    render_excerpt,
)
from services.recogniser.training.kits import RENDER_RATE

NEIGHBOUR_TARGET = 0.5
"""Target of the frames next to a strike's frame (target widening: the exact frame is uncertain by half a hop)."""
PROGRESS_EVERY = 250
"""Excerpts between two progress lines while rendering ..."""
PROGRESS_S = 60.0
"""... or seconds, whichever comes first (a validation set of 150 excerpts on one worker takes minutes)."""


class Progress:
    """Progress lines of a rendering of ``n`` excerpts: every :data:`PROGRESS_EVERY` excerpts or
    :data:`PROGRESS_S` seconds."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.t0 = self.last = time.monotonic()

    def done(self, k: int) -> None:
        """``k`` excerpts are rendered."""
        now = time.monotonic()
        if k < self.n and (k % PROGRESS_EVERY == 0 or now - self.last >= PROGRESS_S):
            self.last = now
            print(f"  rendered {k}/{self.n} excerpts, {now - self.t0:.0f} s", flush=True)
WINDOWS = (512, 1024, 2048)
"""Analysis windows rendered into the frame sets by default, samples at 22,050 Hz (23, 46 and 93 ms); a network
uses any of them. At another analysis rate the windows last as long (:func:`windows_for`)."""
SHORT_WINDOW = 256
"""A shorter window a frame set may also hold, samples at 22,050 Hz (11.6 ms: two strikes 20 ms apart are apart
in it; its bins are 86 Hz wide, so the lowest bands share bins)."""


def windows_for(bands: F.Bands, windows: tuple[int, ...] = WINDOWS) -> tuple[int, ...]:
    """``windows`` (samples at 22,050 Hz) in samples at ``bands.sample_rate``: the same durations."""
    return tuple(bands.samples(w) for w in windows)


def default_hop(bands: F.Bands) -> int:
    """Samples at ``bands.sample_rate`` between frames 10 ms apart (220 at 22,050 Hz, 441 at 44,100 Hz)."""
    return round(0.01 * bands.sample_rate)


@dataclass
class FrameSet:
    """Spectra of several excerpts, concatenated.

    spec : (n_frames, bands.n, len(windows)) float16, excerpt ``e`` is rows ``starts[e]:starts[e + 1]``
    starts : (n_excerpts + 1,) row offsets
    hits : (k, 4) float64: excerpt index, time s (from the excerpt's start), class index, MIDI velocity
    windows : the analysis window of each channel of ``spec``, samples at ``bands.sample_rate``
    hop : samples between frames (at ``bands.sample_rate``)
    bands : the band analysis of the spectra
    """

    spec: np.ndarray
    starts: np.ndarray
    hits: np.ndarray
    windows: tuple[int, ...] = WINDOWS
    hop: int = F.HOP
    bands: F.Bands = F.NARROW

    @property
    def fps(self) -> float:
        """Frames per second."""
        return self.bands.sample_rate / self.hop

    @property
    def n_excerpts(self) -> int:
        return len(self.starts) - 1

    def excerpt(self, e: int, windows: tuple[int, ...] | None = None) -> np.ndarray:
        """Spectra of excerpt ``e`` (frames, bands.n, len(windows)) for these windows (default: all)."""
        x = self.spec[self.starts[e] : self.starts[e + 1]]
        return x if windows is None or windows == self.windows else x[:, :, [self.windows.index(w) for w in windows]]

    def excerpt_hits(self, e: int) -> np.ndarray:
        return self.hits[self.hits[:, 0] == e]

    def save(self, path: Path) -> None:
        """Write to ``path`` (starts, hits, windows) and ``path`` + '.spec.npy' (unless the spectra already are
        a memory map of that file), which :meth:`load` maps into memory (processes share it)."""
        spec_path = Path(f"{path}.spec.npy")
        if not (isinstance(self.spec, np.memmap) and Path(str(self.spec.filename)) == spec_path.resolve()):
            np.save(spec_path, self.spec)
        b = self.bands
        part = Path(path).with_name(f".{Path(path).name}.part.npz")  # renamed when whole: a Ctrl-C while writing
        np.savez(part, starts=self.starts, hits=self.hits, windows=np.asarray(self.windows), hop=self.hop,
                 bands=np.array([b.sample_rate, b.n, b.f_max_hz]))  # leaves no cache that later runs trust
        part.replace(path)

    @staticmethod
    def load_cached(path: Path) -> FrameSet | None:
        """The frame set cached at ``path``, or None when there is none or it cannot be read whole (a file
        deleted or cut short: it is rendered again, saying so, rather than failing every later run)."""
        if not path.exists():
            return None
        try:
            data = FrameSet.load(path)
            if data.starts[-1] != len(data.spec) or data.spec.shape[1:] != (data.bands.n, len(data.windows)):
                raise ValueError(f"{len(data.spec)} frames of shape {data.spec.shape[1:]}, expected "
                                 f"{data.starts[-1]} of ({data.bands.n}, {len(data.windows)})")
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            print(f"the cached {path} cannot be read ({exc}): rendering it again", flush=True)
            return None
        return data

    @staticmethod
    def load(path: Path) -> FrameSet:
        with np.load(path) as z:
            starts, hits, windows = z["starts"], z["hits"], tuple(int(w) for w in z["windows"])
            hop = int(z["hop"]) if "hop" in z.files else F.HOP  # caches written before the hop was recorded
            b = z["bands"] if "bands" in z.files else None  # ... or the band analysis (22,050 Hz, 48 bands)
        bands = F.NARROW if b is None else F.Bands(int(b[0]), int(b[1]), float(b[2]))
        return FrameSet(np.load(f"{path}.spec.npy", mmap_mode="r"), starts, hits, windows, hop, bands)


def _at_rate(audio: np.ndarray, bands: F.Bands) -> np.ndarray:
    """Rendered audio (at :data:`~.kits.RENDER_RATE`) at the band analysis's rate."""
    return audio if bands.sample_rate == RENDER_RATE else resample(audio, RENDER_RATE, bands.sample_rate)


def _one(job: Job, hop: int, bands: F.Bands, windows: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    audio, hits = render_excerpt(job)
    spec = F.multi_spectrogram(_at_rate(audio, bands), windows, hop=hop, bands=bands)
    return spec.astype(np.float16), np.array([[h.time, h.cls, h.velocity] for h in hits], np.float64).reshape(-1, 3)


def make_frames(n: int, seed: int, workers: int, kits: tuple[str, ...], dry_p: float = DRY_P,
                variety: bool = False, path: Path | None = None, vary_p: float = VARY_P, hop: int = F.HOP,
                by_duration: bool = False, quiet_hihat_p: float = 0.0, bands: F.Bands = F.NARROW,
                windows_22k: tuple[int, ...] = WINDOWS) -> FrameSet:
    """Render ``n`` excerpts with ``kits`` (a share ``dry_p`` dry; ``variety``: see :class:`.excerpts.Job`;
    ``by_duration``, ``quiet_hihat_p``: see :func:`.excerpts.jobs`) into a :class:`FrameSet` of the band
    analysis ``bands``, frames ``hop`` samples apart (at its rate), the windows ``windows_22k`` (samples at
    22,050 Hz, :func:`windows_for`), and save it to ``path`` if given (the spectra are written as they come,
    never all held)."""
    per = F.n_frames(len(_at_rate(np.zeros(excerpt_samples(), np.float32), bands)), hop)
    windows = windows_for(bands, windows_22k)
    shape = (n * per, bands.n, len(windows))
    if path is not None:
        _require_space(Path(path).parent, int(np.prod(shape)) * 2)  # float16
    prepare(kits)
    todo = jobs(n, seed, kits, dry_p, variety, vary_p, by_duration, quiet_hihat_p)
    one = partial(_one, hop=hop, bands=bands, windows=windows)
    print(f"rendering {n} excerpts" + (f" into {path}" if path is not None else "") + " ...", flush=True)
    spec = (np.lib.format.open_memmap(f"{path}.spec.npy", mode="w+", dtype=np.float16, shape=shape)
            if path is not None else np.empty(shape, np.float16))
    hits = []
    progress = Progress(n)
    with mp.Pool(workers) if workers > 1 else nullcontext() as pool:
        results = pool.imap(one, todo, chunksize=4) if pool is not None else map(one, todo)
        for e, (s, h) in enumerate(results):
            assert len(s) == per, (len(s), per)
            spec[e * per : (e + 1) * per] = s
            hits.append(np.column_stack([np.full(len(h), e, np.float64), h]))
            progress.done(e + 1)
    data = FrameSet(spec, np.arange(n + 1, dtype=np.int64) * per, np.concatenate(hits), windows, hop, bands)
    if path is not None:
        spec.flush()  # type: ignore[union-attr]
        data.save(path)
    return data


class CacheFullError(RuntimeError):
    """The cache's file system has no room for the spectra about to be rendered."""


def _require_space(directory: Path, n_bytes: int) -> None:
    """Raise :class:`CacheFullError` unless ``directory`` has ``n_bytes`` free: the spectra are written through a
    memory map, which a full disk stops with SIGBUS (a crash without a message) midway through the rendering."""
    free = shutil.disk_usage(directory).free
    if free < n_bytes:
        raise CacheFullError(f"the cache {directory} has {free / 2**30:.1f} GiB free, the spectra of these "
                             f"excerpts need {n_bytes / 2**30:.1f} GiB (give --cache on a larger disk, or fewer "
                             "excerpts)")


ONSET_MERGE_S = 0.02
"""Strikes within this of an onset's first strike are one onset, seconds: how the benchmark, the trainer's tuning
and ``train_net --onset-merge`` count class-agnostic onsets."""


def onset_times(times: np.ndarray, merge_s: float) -> np.ndarray:
    """Onsets of strikes at ``times`` (seconds): sorted, a strike within ``merge_s`` (seconds) after the first
    strike of an onset belongs to it (:data:`ONSET_MERGE_S`: how the benchmark and the trainer's tuning count
    onsets). Returns the onsets' times (seconds, the first strike's)."""
    out: list[float] = []
    for t in np.sort(times):
        if not out or t - out[-1] > merge_s:
            out.append(float(t))
    return np.asarray(out, np.float64)


def targets(n_frames: int, hits: np.ndarray, neighbour: float = NEIGHBOUR_TARGET, fps: float = F.FPS,
            onset_merge_s: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame targets of one excerpt from its hits (rows: time s, class, velocity; or :class:`FrameSet` rows),
    ``fps`` frames per second.

    Returns
    -------
    act : (n_frames, N_CLASSES + 1) float32, 1 at each strike's nearest frame, ``neighbour`` (0..1, default
        :data:`NEIGHBOUR_TARGET`) at the frames beside it; the last column is "a strike of any class", or with
        ``onset_merge_s`` (seconds) "an onset": strikes within it of an onset's first strike are that onset
        (:func:`onset_times`), so the onset output peaks once per onset as the benchmark counts onsets
    vel : (n_frames, N_CLASSES) float32, velocity / 127 at strike frames
    vel_mask : (n_frames, N_CLASSES) bool, where ``vel`` is defined
    """
    h = hits[:, -3:]
    act = np.zeros((n_frames, N_CLASSES + 1), np.float32)
    vel = np.zeros((n_frames, N_CLASSES), np.float32)
    mask = np.zeros((n_frames, N_CLASSES), bool)
    frame = np.rint(h[:, 0] * fps).astype(int)
    cls = h[:, 1].astype(int)
    ok = (frame >= 0) & (frame < n_frames)
    frame, cls, v = frame[ok], cls[ok], h[ok, 2]
    onset = frame
    if onset_merge_s is not None:
        onset = np.rint(onset_times(h[ok, 0], onset_merge_s) * fps).astype(int)
    for d in (-1, 1):
        f = np.clip(frame + d, 0, n_frames - 1)
        act[f, cls] = np.maximum(act[f, cls], neighbour)
        f = np.clip(onset + d, 0, n_frames - 1)
        act[f, N_CLASSES] = np.maximum(act[f, N_CLASSES], neighbour)
    act[frame, cls] = 1.0
    act[onset, N_CLASSES] = 1.0
    vel[frame, cls] = np.maximum(vel[frame, cls], v / 127.0)
    mask[frame, cls] = True
    return act, vel, mask


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
