"""The offline network: NumPy inference, its decision rule, the model file, and (with PyTorch) the export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.recogniser import features as F
from services.recogniser.audio import SAMPLE_RATE
from services.recogniser.classes import N_CLASSES
from services.recogniser.errors import ModelError
from services.recogniser.framenet import N_OUT, FrameNet, Layer, Network
from services.recogniser.model import Model, load_live, load_model
from services.recogniser.transcribe import strikes


def _random_net(seed: int = 0, windows: tuple[int, ...] = (F.N_FFT,)) -> FrameNet:
    rng = np.random.default_rng(seed)

    def w(*shape: int) -> np.ndarray:
        return (rng.standard_normal(shape) / np.sqrt(np.prod(shape[:-1]))).astype(np.float32)

    layers = [Layer("conv2d", w(3, 3, len(windows), 4), np.zeros(4, np.float32), pool=2),
              Layer("conv2d", w(3, 3, 4, 4), np.zeros(4, np.float32), pool=2),
              Layer("conv1d", w(3, 4 * F.N_BANDS // 4, 8), np.zeros(8, np.float32)),
              Layer("conv1d", w(3, 8, 8), np.zeros(8, np.float32), dilation=2, residual=True),
              Layer("conv1d", w(1, 8, N_OUT), np.zeros(N_OUT, np.float32), relu=False)]
    return FrameNet(layers, np.array([0.5] * N_CLASSES + [1.01], np.float32), windows=windows)


def test_output_does_not_depend_on_chunking_and_context_is_bounded() -> None:
    net = _random_net()
    assert net.margin == 1 + 1 + 1 + 2
    spec = np.random.default_rng(1).random((300, F.N_BANDS)).astype(np.float32) * 3
    out = net.forward(spec)
    assert out.shape == (300, N_OUT) and np.all((out >= 0) & (out <= 1))
    assert np.allclose(out, net.forward(spec, chunk_frames=37), atol=1e-6)
    changed = spec.copy()
    changed[150] += 1.0  # a change at frame 150 reaches only frames within the network's margin
    diff = np.flatnonzero(np.abs(net.forward(changed) - out).max(axis=1) > 0)
    assert diff.min() >= 150 - net.margin and diff.max() <= 150 + net.margin


def test_peaks_are_local_maxima_above_threshold_first_of_equals() -> None:
    net = _random_net()
    act = np.array([0.0, 0.6, 0.6, 0.1, 0.4, 0.9, 0.2, 0.7, 0.3], np.float32)
    assert net.peaks(act, 0.5).tolist() == [1, 5, 7]
    net.peak_frames = 2
    assert net.peaks(act, 0.5).tolist() == [1, 5]


def test_detect_classes_and_the_onset_output() -> None:
    net = _random_net()
    out = np.zeros((20, N_OUT), np.float32)
    out[3, 0] = 0.9  # kick at frame 3
    out[3, N_CLASSES] = 0.9  # its onset peak: nothing added
    out[10, [1, 2]] = [0.3, 0.45]  # no class sure ...
    out[10, N_CLASSES] = 0.8  # ... but a strike: of the most probable class, closed hi-hat
    out[:, N_CLASSES + 1 :] = 0.5
    assert [(t, c) for t, c, _, _ in net.detect(out)] == [(3, 0)]  # onset output unused (threshold 1.01)
    net.thresholds[N_CLASSES] = 0.7
    found = net.detect(out)
    assert [(t, c) for t, c, _, _ in found] == [(3, 0), (10, 2)]
    assert all(v == 64 for _, _, v, _ in found)
    times = [e.time for e in strikes(net, out)]
    assert np.allclose(times, [3 / F.FPS, 10 / F.FPS])


def test_input_spectrograms_of_several_windows() -> None:
    net = _random_net(5, windows=(512, 1024, 2048))
    t = np.arange(int(0.5 * SAMPLE_RATE)) / SAMPLE_RATE
    audio = (0.5 * np.sin(2 * np.pi * 440 * t) * (t > 0.2)).astype(np.float32)
    spec = net.spectrogram(audio)
    assert spec.shape == (F.n_frames(len(audio)), F.N_BANDS, 3)
    assert np.array_equal(spec[:, :, 1], F.band_spectrogram(audio))  # the 1,024-sample channel
    onset = int(0.2 * F.FPS)
    # frames are centred alike: the short window hears the tone start later and the long one earlier
    first = [int(np.argmax(spec[:, :, c].max(axis=1) > 1.0)) for c in range(3)]
    assert first[2] < first[1] < first[0] <= onset + 2
    assert net.forward(spec).shape == (len(spec), N_OUT)


def test_frames_of_5_ms_are_the_10_ms_frames_and_those_between() -> None:
    t = np.arange(int(0.7 * SAMPLE_RATE)) / SAMPLE_RATE
    audio = (0.5 * np.sin(2 * np.pi * 220 * t) * np.exp(-8 * np.maximum(0, t - 0.3)) * (t > 0.3)).astype(np.float32)
    fine = F.multi_spectrogram(audio, (512, 1024), hop=F.HOP // 2)
    coarse = F.multi_spectrogram(audio, (512, 1024))
    assert len(fine) == F.n_frames(len(audio), F.HOP // 2) and len(fine) in (2 * len(coarse) - 1, 2 * len(coarse))
    assert np.allclose(fine[::2][: len(coarse)], coarse, atol=1e-5)  # frame 2k at 5 ms is frame k at 10 ms
    assert np.allclose(F.frame_times(3, F.HOP // 2), [0.0, 0.005, 0.01], atol=1e-4)


def test_a_network_of_5_ms_frames_reads_its_frames_and_gives_times_in_seconds(tmp_path: Path) -> None:
    live, _ = load_live(Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz")
    net = _random_net(12)
    net.hop = F.HOP // 2
    assert net.fps == pytest.approx(2 * F.FPS)
    audio = np.zeros(SAMPLE_RATE, np.float32)
    assert len(net.spectrogram(audio)) == F.n_frames(SAMPLE_RATE, F.HOP // 2)  # 201 frames for 1 s
    out = np.zeros((200, N_OUT), np.float32)
    out[100, 0] = 0.9  # a kick at frame 100 of 5 ms: 0.5 s
    assert [e.time for e in strikes(net, out)] == pytest.approx([100 / (2 * F.FPS)])
    Model(net, live, {}).save(tmp_path / "m.npz")
    assert load_model(tmp_path / "m.npz").offline.hop == F.HOP // 2
    net.hop = 5  # a corrupt or foreign file: refused with a clear error, not read as 0.2 ms frames
    Model(net, live, {}).save(tmp_path / "bad.npz")
    with pytest.raises(ModelError, match="5 samples apart"):
        load_model(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="share their frames"):
        FrameNet(net.layers, net.thresholds, members=[Network(net.layers, net.windows, F.HOP // 2)])


def test_model_file_round_trip(tmp_path: Path) -> None:
    live, _ = load_live(Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz")
    net = _random_net(2, windows=(512, 2048))
    net.thresholds[:] = np.linspace(0.1, 0.9, N_CLASSES + 1)
    net.chord_s, net.peak_frames = 0.03, 2
    Model(net, live, {"trained_on": ["x"]}).save(tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz")
    spec = np.random.default_rng(3).random((120, F.N_BANDS, 2)).astype(np.float32)
    assert np.array_equal(back.offline.forward(spec), net.forward(spec))
    assert np.array_equal(back.offline.thresholds, net.thresholds)
    assert (back.offline.chord_s, back.offline.peak_frames, back.offline.windows) == (0.03, 2, (512, 2048))
    assert back.offline.hop == F.HOP  # 10 ms frames, as every file written before the hop was recorded
    assert np.array_equal(back.live.weights[0], live.weights[0])


def test_an_ensemble_averages_its_networks_and_may_be_stored_in_half_precision(tmp_path: Path) -> None:
    live, _ = load_live(Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz")
    a, b = _random_net(6, windows=(1024,)), _random_net(7, windows=(512, 2048))
    both = FrameNet(a.layers, a.thresholds.copy(), windows=a.windows, members=[Network(b.layers, b.windows)])
    assert both.inputs == (512, 1024, 2048)
    spec = np.random.default_rng(8).random((150, F.N_BANDS, 3)).astype(np.float32)
    mean = 0.5 * (a.forward(spec[:, :, 1]) + b.forward(spec[:, :, [0, 2]]))
    assert np.allclose(both.forward(spec, chunk_frames=64), mean, atol=1e-6)
    Model(both, live, {}).save(tmp_path / "half.npz", half=True)
    back = load_model(tmp_path / "half.npz").offline
    assert back.inputs == both.inputs and len(back.members) == 1
    assert back.members[0].layers[0].w.dtype == np.float32  # computed in float32
    assert 0 < np.abs(back.forward(spec) - mean).max() < 1e-2  # rounded, not lost


@pytest.mark.parametrize("dilations", [(2, 4, 8, 16), (2, 4, 8, 16, 32, 64)])
def test_export_computes_what_the_torch_network_computes(dilations: tuple[int, ...]) -> None:
    torch = pytest.importorskip("torch")  # training-only dependency
    from services.recogniser.training.net import Net, export

    torch.manual_seed(0)
    net = Net(windows=(512, 1024), dilations=dilations)
    for m in net.modules():  # non-trivial batch statistics, so the folding is exercised
        if isinstance(m, torch.nn.BatchNorm1d | torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-1, 1)
            m.running_var.uniform_(0.5, 2.0)
            m.weight.data.uniform_(0.5, 1.5)
            m.bias.data.uniform_(-0.5, 0.5)
    net.eval()
    fn = export(net)
    assert fn.margin == net.margin
    spec = np.random.default_rng(4).random((200, F.N_BANDS, 2)).astype(np.float32) * 2
    m = fn.margin
    pad = np.zeros((m, F.N_BANDS, 2), np.float32)
    padded = np.concatenate([pad, spec, pad])
    with torch.no_grad():
        ref = torch.sigmoid(net(torch.from_numpy(padded)[None]))[0].numpy().T[m:-m]
    assert np.abs(fn.forward(spec) - ref).max() < 1e-4


def test_the_trainer_makes_an_ensemble_of_model_files_and_tunes_it(tmp_path: Path) -> None:
    pytest.importorskip("torch")  # the trainer's module imports it
    from services.recogniser.training.frames import FrameSet
    from services.recogniser.training.train_net import ensemble

    live, _ = load_live(Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz")
    a, b = _random_net(9, windows=(1024,)), _random_net(10, windows=(512, 2048))
    Model(a, live, {"width": 8, "windows": [1024]}).save(tmp_path / "a.npz")
    Model(b, live, {"width": 8, "windows": [512, 2048]}).save(tmp_path / "b.npz")
    rng = np.random.default_rng(11)
    spec = rng.random((2 * 200, F.N_BANDS, 3)).astype(np.float16)
    hits = np.array([[e, t, c, 100] for e in (0, 1) for t, c in ((0.5, 0), (1.0, 1), (1.5, 2))], np.float64)
    val = FrameSet(spec, np.array([0, 200, 400]), hits, (512, 1024, 2048))
    both = ensemble([tmp_path / "a.npz", tmp_path / "b.npz"], val)
    assert both.offline.inputs == (512, 1024, 2048) and len(both.offline.networks) == 2
    x = val.excerpt(0).astype(np.float32)
    assert np.allclose(both.offline.forward(x), 0.5 * (a.forward(x[:, :, [1]]) + b.forward(x[:, :, [0, 2]])),
                       atol=1e-6)
    th = both.offline.thresholds
    assert th.shape == (N_CLASSES + 1,) and np.all((th >= 0.1) & (th <= 1.01))
    assert [m["file"] for m in both.meta["ensemble_of"]] == ["a.npz", "b.npz"]
    assert both.meta["ensemble_of"][1]["windows"] == [512, 2048]
