"""The shipped model, stored as plain arrays (.npz) and run with NumPy.

Two variants: ``offline``, the framewise convolutional network of
:mod:`services.recogniser.framenet` (its layer weights and per-output thresholds),
and ``live``, a small multi-label MLP classifying each candidate onset from a
short context (<= 50 ms latency): the input standardisation, the layer weights,
per-class decision thresholds and a linear velocity regressor per class. JSON
metadata holds the class names, the network's layer layout, context offsets,
onset threshold and timing offsets. The live MLP may have one output more than
there are classes: the probability that the candidate is a strike of any class
(see :meth:`Classifier.decide`).
It is loaded with ``allow_pickle=False``: no code is ever unpickled.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.input_file import NO_SUCH_FILE, file_problem
from common.output_paths import write_atomically
from services.recogniser.classes import CLASS_NAMES, N_CLASSES
from services.recogniser.errors import ModelError
from services.recogniser.features import HOP, HOP_RANGE, N_FFT, NARROW, Bands, n_features
from services.recogniser.framenet import N_OUT, FrameNet, Layer, Network

MODEL_PATH = Path(__file__).parent / "models" / "recogniser.npz"
"""The model shipped with Batteur."""

FORMAT = "batteur-recogniser/2"


@dataclass
class Classifier:
    """The live MLP.

    ``offsets``: context frames relative to the onset frame; ``delta``: onset
    peak-picking threshold; ``time_offset_s``: added to onset frame times.
    ``weights[i]`` has shape (n_in, n_out) for layer i (ReLU between, sigmoid out).
    ``vel_w`` (n_features + 1, N_CLASSES): velocity / 127 from standardised features.
    ``thresholds`` has one entry per output; with an onset output (``N_CLASSES + 1`` outputs),
    the last output and threshold are those of "any strike" (see :meth:`decide`).
    """

    offsets: tuple[int, ...]
    delta: float
    time_offset_s: float
    mean: np.ndarray
    scale: np.ndarray
    weights: list[np.ndarray]
    biases: list[np.ndarray]
    thresholds: np.ndarray
    vel_w: np.ndarray

    @property
    def n_features(self) -> int:
        return int(self.mean.shape[0])

    def standardise(self, features: np.ndarray) -> np.ndarray:
        return ((features - self.mean) / self.scale).astype(np.float32)

    @property
    def has_onset_output(self) -> bool:
        return int(self.weights[-1].shape[1]) == N_CLASSES + 1

    def probabilities(self, features: np.ndarray) -> np.ndarray:
        """Output probabilities, shape (n, N_CLASSES) or (n, N_CLASSES + 1) with the onset output,
        for raw features of shape (n, n_features)."""
        h = self.standardise(features)
        for i, (w, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ w + b
            if i < len(self.weights) - 1:
                h = np.maximum(h, 0.0)
        return (1.0 / (1.0 + np.exp(-np.clip(h, -60, 60)))).astype(np.float32)

    def decide(self, prob: np.ndarray) -> np.ndarray:
        """Which classes are struck at each candidate, boolean (n, N_CLASSES), from :meth:`probabilities`.

        A class is struck when its probability reaches its threshold. With an onset
        output, a candidate whose onset probability reaches its threshold but no class
        does is still a strike: of the most probable class (not the highest probability / threshold,
        which would favour the rare classes whose thresholds are low).
        """
        hit = prob[:, :N_CLASSES] >= self.thresholds[:N_CLASSES]
        if self.has_onset_output:
            lone = (prob[:, N_CLASSES] >= self.thresholds[N_CLASSES]) & ~hit.any(axis=1)
            best = np.argmax(prob[:, :N_CLASSES], axis=1)
            hit[np.flatnonzero(lone), best[lone]] = True
        return hit

    def velocities(self, features: np.ndarray) -> np.ndarray:
        """MIDI velocities (1..127) per class, shape (n, N_CLASSES)."""
        z = self.standardise(features)
        v = z @ self.vel_w[:-1] + self.vel_w[-1]
        return np.clip(np.rint(v * 127.0), 1, 127).astype(int)


@dataclass
class Model:
    """The offline network, the live classifier and the metadata."""

    offline: FrameNet
    live: Classifier
    meta: dict

    def save(self, path: str | Path, half: bool = False) -> None:
        """Write the model to exactly ``path`` (NumPy alone would add '.npz' to another name), whole or not at all
        (a Ctrl-C or a full disk leaves an earlier file as it was); ``half``: the offline networks' weights as
        float16 (half the size; they are computed in float32 when loaded)."""
        arrays: dict[str, np.ndarray] = {}
        c = self.live
        arrays["live.mean"] = c.mean
        arrays["live.scale"] = c.scale
        arrays["live.thresholds"] = c.thresholds
        arrays["live.vel_w"] = c.vel_w
        for i, (w, b) in enumerate(zip(c.weights, c.biases, strict=True)):
            arrays[f"live.w{i}"] = w.astype(np.float32)
            arrays[f"live.b{i}"] = b.astype(np.float32)
        net = self.offline
        arrays["offline.thresholds"] = net.thresholds.astype(np.float32)
        if net.profile is not None:
            arrays["offline.profile"] = net.profile.astype(np.float32)
        dtype = np.float16 if half else np.float32
        for k, member in enumerate(net.networks):
            prefix = "offline" if k == 0 else f"offline.m{k}"
            for i, la in enumerate(member.layers):
                arrays[f"{prefix}.w{i}"] = la.w.astype(dtype)
                arrays[f"{prefix}.b{i}"] = la.b.astype(dtype)
        meta = dict(self.meta)
        adapt = {} if net.profile is None else {"level_match": net.level_match}  # files without: as before
        meta.update(
            format=FORMAT,
            classes=list(CLASS_NAMES),
            offline={"kind": "framenet", "peak_frames": net.peak_frames, "time_offset_s": net.time_offset_s,
                     "chord_s": net.chord_s, "snap_frames": net.snap_frames, "hihat_snare": net.hihat_snare,
                     "subframe": net.subframe, "hop": net.hop,
                     "bands": {"sample_rate": net.bands.sample_rate, "n": net.bands.n,
                               "f_max_hz": net.bands.f_max_hz},
                     "windows": list(net.windows), "layers": _layout(net.layers),
                     "members": [{"windows": list(m.windows), "layers": _layout(m.layers)} for m in net.members],
                     **adapt},
            live={"offsets": list(c.offsets), "delta": c.delta, "time_offset_s": c.time_offset_s,
                  "layers": len(c.weights)},
        )
        arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        packed = io.BytesIO()
        np.savez_compressed(packed, **arrays)  # type: ignore[arg-type]
        write_atomically(Path(path), packed.getvalue())


def _layout(layers: list[Layer]) -> list[dict]:
    return [{"kind": la.kind, "dilation": la.dilation, "pool": la.pool, "relu": la.relu, "residual": la.residual}
            for la in layers]


LIVE_FORMATS = ("batteur-recogniser/1", FORMAT)
"""Formats whose live classifier :func:`load_live` reads (its arrays did not change)."""


def _read(path: str | Path, formats: tuple[str, ...]) -> tuple[Path, dict[str, np.ndarray], dict]:
    p = Path(path)
    problem = file_problem(p, "a recogniser model file (.npz)")
    if problem == NO_SUCH_FILE:
        raise ModelError(f"{p}: model file not found (train one with services/recogniser/training/train_net.py)")
    if problem is not None:  # a pipe is never opened: is_zipfile would wait for a writer for ever
        raise ModelError(f"{p}: {problem}")
    if not zipfile.is_zipfile(p):  # else NumPy would report it as pickled data it refuses to load
        raise ModelError(f"{p}: not a Batteur recogniser model: not an .npz archive")
    try:
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        meta = json.loads(bytes(data["meta"]).decode())
    except Exception as exc:
        raise ModelError(f"{p}: not a Batteur recogniser model: {exc}") from exc
    if meta.get("format") not in formats:
        raise ModelError(f"{p}: unknown model format {meta.get('format')!r}, expected {FORMAT!r}")
    if tuple(meta.get("classes", ())) != CLASS_NAMES:
        raise ModelError(f"{p}: model classes {meta.get('classes')} differ from {list(CLASS_NAMES)}")
    for name, array in data.items():  # a training run that diverged: every transcription would be garbage
        if array.dtype.kind == "f" and not np.all(np.isfinite(array)):
            raise ModelError(f"{p}: {name} holds NaN or infinite values (written by a training run that diverged?)")
    return p, data, meta


def _layers(data: dict[str, np.ndarray], prefix: str, layout: list[dict]) -> list[Layer]:
    return [Layer(str(la["kind"]), data[f"{prefix}.w{i}"].astype(np.float32), data[f"{prefix}.b{i}"].astype(np.float32),
                  int(la["dilation"]), int(la["pool"]), bool(la["relu"]), bool(la["residual"]))
            for i, la in enumerate(layout)]


def _network(p: Path, data: dict[str, np.ndarray], m: dict) -> FrameNet:
    hop = int(m.get("hop", HOP))  # files made before the hop was recorded: 10 ms frames
    if not HOP_RANGE[0] <= hop <= HOP_RANGE[1]:
        raise ModelError(f"{p}: offline network frames {hop} samples apart (expected {HOP_RANGE[0]}..{HOP_RANGE[1]})")
    try:  # files made before the band analysis was recorded: 22,050 Hz, 48 bands to 10.5 kHz
        b = m.get("bands")
        bands = NARROW if b is None else Bands(int(b["sample_rate"]), int(b["n"]), float(b["f_max_hz"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{p}: offline network band analysis {m.get('bands')!r}: {exc}") from exc
    members = [Network(_layers(data, f"offline.m{k + 1}", mm["layers"]), tuple(int(w) for w in mm["windows"]), hop,
                       bands)
               for k, mm in enumerate(m.get("members", []))]
    net = FrameNet(_layers(data, "offline", m["layers"]), data["offline.thresholds"].astype(np.float32),
                   int(m["peak_frames"]), float(m["time_offset_s"]), float(m["chord_s"]),
                   tuple(int(w) for w in m.get("windows", [N_FFT])), members,
                   int(m.get("snap_frames", 0)), float(m.get("hihat_snare", 0.0)),  # 0: files made before these
                   bool(m.get("subframe", False)), hop, bands)
    for n in net.networks:
        if not n.layers or n.layers[0].w.shape[2] != len(n.windows) or n.layers[-1].w.shape[-1] != N_OUT:
            raise ModelError(f"{p}: offline network layer shapes do not match")
        if not _reads_bands(n.layers, bands.n):
            raise ModelError(f"{p}: offline network layers do not read {bands.n} bands")
    if net.thresholds.shape != (N_CLASSES + 1,):
        raise ModelError(f"{p}: offline network has {net.thresholds.shape[0]} thresholds, expected {N_CLASSES + 1}")
    _adaptation(p, data, m, net)
    return net


def _adaptation(p: Path, data: dict[str, np.ndarray], m: dict, net: FrameNet) -> None:
    """Set ``net``'s test-time level matching from the file (none in files without ``offline.profile``)."""
    profile = data.get("offline.profile")
    try:
        match = float(m.get("level_match", 0.0))
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{p}: offline level_match {m.get('level_match')!r}: {exc}") from exc
    if not 0.0 <= match <= 1.0:
        raise ModelError(f"{p}: offline level_match {match:g} (expected 0..1)")
    if profile is None:
        if match > 0.0:
            raise ModelError(f"{p}: offline level_match {match:g} without offline.profile")
        return
    want = (net.bands.n, len(net.inputs))
    if profile.shape != want:
        raise ModelError(f"{p}: offline.profile has shape {profile.shape}, expected {want} (bands, input windows)")
    net.profile, net.level_match = profile.astype(np.float32), match


def _reads_bands(layers: list[Layer], n_bands: int) -> bool:
    """Whether the 2-D layers' pooling divides ``n_bands`` input bands and the first time convolution reads
    what they leave (channels x bands per frame)."""
    bands, channels = n_bands, 0
    for la in layers:
        if la.kind != "conv2d":
            return int(la.w.shape[1]) == channels * bands
        channels = int(la.w.shape[3])
        if bands % la.pool:
            return False
        bands //= la.pool
    return False


def _classifier(p: Path, data: dict[str, np.ndarray], m: dict, name: str) -> Classifier:
    n_layers = int(m["layers"])
    c = Classifier(
        offsets=tuple(int(o) for o in m["offsets"]),
        delta=float(m["delta"]),
        time_offset_s=float(m["time_offset_s"]),
        mean=data[f"{name}.mean"].astype(np.float32),
        scale=data[f"{name}.scale"].astype(np.float32),
        weights=[data[f"{name}.w{i}"].astype(np.float32) for i in range(n_layers)],
        biases=[data[f"{name}.b{i}"].astype(np.float32) for i in range(n_layers)],
        thresholds=data[f"{name}.thresholds"].astype(np.float32),
        vel_w=data[f"{name}.vel_w"].astype(np.float32),
    )
    if c.weights[-1].shape[1] not in (N_CLASSES, N_CLASSES + 1) or c.weights[0].shape[0] != c.n_features:
        raise ModelError(f"{p}: {name} layer shapes do not match")
    if c.thresholds.shape != (c.weights[-1].shape[1],):
        raise ModelError(f"{p}: {name} has {c.thresholds.shape[0]} thresholds for {c.weights[-1].shape[1]} outputs")
    if c.n_features != n_features(c.offsets):
        raise ModelError(f"{p}: {name} expects {c.n_features} features, this version computes "
                         f"{n_features(c.offsets)} (retrain the model)")
    return c


def load_model(path: str | Path = MODEL_PATH) -> Model:
    """Read a model file written by :meth:`Model.save`.

    Raises
    ------
    ModelError
        missing file, wrong format, or classes that differ from :data:`CLASS_NAMES`.
    """
    p, data, meta = _read(path, (FORMAT,))
    try:
        return Model(offline=_network(p, data, meta["offline"]), live=_classifier(p, data, meta["live"], "live"),
                     meta=meta)
    except KeyError as exc:
        raise ModelError(f"{p}: missing array {exc}") from exc


def load_live(path: str | Path) -> tuple[Classifier, dict]:
    """Only the live classifier of a model file (of this or the previous format) and the file's metadata."""
    p, data, meta = _read(path, LIVE_FORMATS)
    try:
        return _classifier(p, data, meta["live"], "live"), meta
    except KeyError as exc:
        raise ModelError(f"{p}: missing array {exc}") from exc
