"""The offline network: NumPy inference, its decision rule, the model file, and (with PyTorch) the export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.framenet import N_OUT, FrameNet, Layer
from services.recogniser.model import Model, load_live, load_model
from services.recogniser.transcribe import strikes


def _random_net(seed: int = 0) -> FrameNet:
    rng = np.random.default_rng(seed)

    def w(*shape: int) -> np.ndarray:
        return (rng.standard_normal(shape) / np.sqrt(np.prod(shape[:-1]))).astype(np.float32)

    layers = [Layer("conv2d", w(3, 3, 1, 4), np.zeros(4, np.float32), pool=2),
              Layer("conv2d", w(3, 3, 4, 4), np.zeros(4, np.float32), pool=2),
              Layer("conv1d", w(3, 4 * F.N_BANDS // 4, 8), np.zeros(8, np.float32)),
              Layer("conv1d", w(3, 8, 8), np.zeros(8, np.float32), dilation=2, residual=True),
              Layer("conv1d", w(1, 8, N_OUT), np.zeros(N_OUT, np.float32), relu=False)]
    return FrameNet(layers, np.array([0.5] * N_CLASSES + [1.01], np.float32))


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


def test_model_file_round_trip(tmp_path: Path) -> None:
    live, _ = load_live(Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz")
    net = _random_net(2)
    net.thresholds[:] = np.linspace(0.1, 0.9, N_CLASSES + 1)
    net.chord_s, net.peak_frames = 0.03, 2
    Model(net, live, {"trained_on": ["x"]}).save(tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz")
    spec = np.random.default_rng(3).random((120, F.N_BANDS)).astype(np.float32)
    assert np.array_equal(back.offline.forward(spec), net.forward(spec))
    assert np.array_equal(back.offline.thresholds, net.thresholds)
    assert (back.offline.chord_s, back.offline.peak_frames) == (0.03, 2)
    assert np.array_equal(back.live.weights[0], live.weights[0])


def test_export_computes_what_the_torch_network_computes() -> None:
    torch = pytest.importorskip("torch")  # training-only dependency
    from services.recogniser.training.net import Net, export

    torch.manual_seed(0)
    net = Net()
    for m in net.modules():  # non-trivial batch statistics, so the folding is exercised
        if isinstance(m, torch.nn.BatchNorm1d | torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-1, 1)
            m.running_var.uniform_(0.5, 2.0)
            m.weight.data.uniform_(0.5, 1.5)
            m.bias.data.uniform_(-0.5, 0.5)
    net.eval()
    fn = export(net)
    assert fn.margin == net.margin
    spec = np.random.default_rng(4).random((200, F.N_BANDS)).astype(np.float32) * 2
    m = fn.margin
    padded = np.concatenate([np.zeros((m, F.N_BANDS), np.float32), spec, np.zeros((m, F.N_BANDS), np.float32)])
    with torch.no_grad():
        ref = torch.sigmoid(net(torch.from_numpy(padded)[None]))[0].numpy().T[m:-m]
    assert np.abs(fn.forward(spec) - ref).max() < 1e-4
