"""The band analysis a network reads (features.Bands): what the wide bands see, and how model files record it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import resample_poly

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.errors import ModelError
from services.recogniser.framenet import N_OUT, FrameNet, Layer, Network
from services.recogniser.model import Model, load_live, load_model
from services.recogniser.training.frames import SHORT_WINDOW, windows_for

MODEL = Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz"


def _net(bands: F.Bands, seed: int = 0) -> FrameNet:
    rng = np.random.default_rng(seed)

    def w(*shape: int) -> np.ndarray:
        return (rng.standard_normal(shape) / np.sqrt(np.prod(shape[:-1]))).astype(np.float32)

    layers = [Layer("conv2d", w(3, 3, 1, 4), np.zeros(4, np.float32), pool=2),
              Layer("conv2d", w(3, 3, 4, 4), np.zeros(4, np.float32), pool=2),
              Layer("conv1d", w(3, 4 * bands.n // 4, 8), np.zeros(8, np.float32)),
              Layer("conv1d", w(1, 8, N_OUT), np.zeros(N_OUT, np.float32), relu=False)]
    return FrameNet(layers, np.array([0.5] * N_CLASSES + [1.01], np.float32), windows=(bands.samples(F.N_FFT),),
                    hop=round(0.01 * bands.sample_rate), bands=bands)


def test_the_wide_bands_see_what_lies_above_10_5_khz() -> None:
    # a hi-hat's sizzle at 14 kHz: above the narrow analysis's top band, inside the wide one's
    t = np.arange(44100) / 44100
    tone = (0.5 * np.sin(2 * np.pi * 14000 * t)).astype(np.float32)
    spec = F.band_spectrogram(tone, n_fft=2048, hop=441, bands=F.WIDE)
    assert spec.shape == (F.n_frames(len(tone), 441), 56)
    edges = np.geomspace(F.F_MIN_HZ, F.WIDE.f_max_hz, F.WIDE.n + 2)
    loudest = int(np.argmax(spec[50]))
    assert edges[loudest] < 14000 < edges[loudest + 2]  # the band whose triangle holds 14 kHz
    assert edges[loudest] > F.F_MAX_HZ
    # the same 46 ms window gives a steady tone the same band level at either rate
    t22 = np.arange(22050) / 22050
    low = (0.5 * np.sin(2 * np.pi * 1000 * t22)).astype(np.float32)
    low44 = (0.5 * np.sin(2 * np.pi * 1000 * t)).astype(np.float32)
    narrow = F.band_spectrogram(low)[50].max()
    wide = F.band_spectrogram(low44, n_fft=2048, hop=441, bands=F.WIDE)[50].max()
    assert wide == pytest.approx(narrow, abs=0.1)


@pytest.mark.parametrize(("args", "match"), [((4000, 48, 1800.0), "Hz"), ((44100, 50, 18000.0), "multiple of 4"),
                                             ((22050, 48, 12000.0), "half of")])
def test_an_impossible_band_analysis_is_refused(args: tuple[int, int, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        F.Bands(*args)


def test_a_model_file_records_its_band_analysis_and_older_files_read_as_narrow(tmp_path: Path) -> None:
    live, _ = load_live(MODEL)
    Model(_net(F.WIDE), live, {}).save(tmp_path / "wide.npz")
    wide = load_model(tmp_path / "wide.npz").offline
    assert wide.bands == F.WIDE and wide.sample_rate == 44100 and wide.fps == pytest.approx(100.0)
    Model(_net(F.NARROW), live, {}).save(tmp_path / "narrow.npz")
    for name, edit in (("old.npz", lambda m: m["offline"].pop("bands")),  # a file from before 5 Dec
                       ("bad.npz", lambda m: m["offline"].update(bands={"sample_rate": 44100, "n": 50})),
                       ("other.npz", lambda m: m["offline"].update(bands={"sample_rate": 44100, "n": 56,
                                                                          "f_max_hz": 18000.0}))):
        with np.load(tmp_path / "narrow.npz", allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        meta = json.loads(bytes(data["meta"]).decode())
        edit(meta)
        data["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        np.savez_compressed(tmp_path / name, **data)
    assert load_model(tmp_path / "old.npz").offline.bands == F.NARROW
    with pytest.raises(ModelError, match="band analysis"):
        load_model(tmp_path / "bad.npz")
    with pytest.raises(ModelError, match="do not read 56 bands"):  # 48-band weights told they read 56
        load_model(tmp_path / "other.npz")


def test_the_networks_of_an_ensemble_share_their_band_analysis() -> None:
    wide, narrow = _net(F.WIDE), _net(F.NARROW)
    with pytest.raises(ValueError, match="band analysis"):
        FrameNet(wide.layers, wide.thresholds, windows=wide.windows, hop=wide.hop, bands=F.WIDE,
                 members=[Network(narrow.layers, narrow.windows, wide.hop, F.NARROW)])


def test_audio_at_another_rate_is_resampled_to_the_networks() -> None:
    from services.recogniser.transcribe import transcribe

    model = load_model(MODEL)
    rng = np.random.default_rng(5)
    audio = np.zeros(3 * 22050, np.float32)
    for start in (0.5, 1.5, 2.5):  # three noise bursts, decaying
        i = int(start * 22050)
        audio[i : i + 4000] += rng.standard_normal(4000).astype(np.float32) * np.exp(-np.arange(4000) / 600)
    at_22k = transcribe(audio, model, sample_rate=22050)
    twice = resample_poly(audio, 2, 1).astype(np.float32)  # the same audio at 44,100 Hz
    at_44k = transcribe(twice, model, sample_rate=44100)
    assert [e.cls for e in at_22k] == [e.cls for e in at_44k]  # resampled twice: times equal within 1 us
    assert np.allclose([e.time for e in at_22k], [e.time for e in at_44k], atol=1e-6)
    assert sorted({round(e.time, 1) for e in at_22k}) == [0.5, 1.5, 2.5]


def test_the_short_window_parts_two_strikes_20_ms_apart() -> None:
    # two clicks 20 ms apart, frames 10 ms apart: the frame between them lies 10 ms from each
    audio = np.zeros(44100, np.float32)
    audio[[22050, 22050 + 882]] = 1.0
    frame = 50  # sample 22,050 at a hop of 441
    levels = {}
    for w in windows_for(F.WIDE, (SHORT_WINDOW, 1024)):
        spec = F.band_spectrogram(audio, n_fft=w, hop=441, bands=F.WIDE).mean(axis=1)
        levels[w] = spec[frame : frame + 3]
    short, long_ = levels[512], levels[2048]
    assert short[1] < 0.5 * min(short[0], short[2])  # 11.6 ms: a dip between the strikes
    assert long_[1] >= 0.9 * min(long_[0], long_[2])  # 46 ms: one lump
