"""Warm start: the shipped model's offline network back in PyTorch computes what the NumPy network computes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.recogniser import features as F
from services.recogniser.model import load_model

SHIPPED = Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz"


def test_the_shipped_network_loaded_into_torch_gives_the_numpy_activations() -> None:
    torch = pytest.importorskip("torch")  # training-only dependency
    from services.recogniser.training.net import calibrate
    from services.recogniser.training.train_net import init_net

    fn = load_model(SHIPPED).offline
    net = init_net(SHIPPED, fn.windows, int(fn.layers[2].w.shape[2]), hop=fn.hop, bands=fn.bands)
    rng = np.random.default_rng(12)
    spec = (rng.random((300, fn.bands.n, len(fn.windows))) * 2).astype(np.float32)
    m = fn.margin
    padded = torch.from_numpy(np.concatenate([np.zeros((m, *spec.shape[1:]), np.float32), spec,
                                              np.zeros((m, *spec.shape[1:]), np.float32)]))[None]
    want = fn.forward(spec)

    def torch_out() -> np.ndarray:
        with torch.no_grad():
            return torch.sigmoid(net(padded))[0].numpy().T[m:-m]

    assert net.margin == m and np.abs(torch_out() - want).max() < 1e-4
    # calibrated batch normalisations (running statistics of real inputs) keep the function
    calibrate(net, [torch.from_numpy(spec[None, :200]), torch.from_numpy(spec[None, 100:])])
    var = net.bn_t1.running_var
    assert var is not None and float(var.mean()) != pytest.approx(1.0, abs=1e-3)
    assert np.abs(torch_out() - want).max() < 1e-4


def test_a_warm_start_must_match_the_files_windows_width_dilations_hop_and_bands() -> None:
    pytest.importorskip("torch")
    from services.recogniser.training.train_net import init_net

    fn = load_model(SHIPPED).offline
    windows, hop, bands = fn.windows, fn.hop, fn.bands
    with pytest.raises(ValueError, match="windows"):
        init_net(SHIPPED, windows[:1], 128, hop=hop, bands=bands)
    with pytest.raises(ValueError, match="width"):
        init_net(SHIPPED, windows, 64, hop=hop, bands=bands)
    with pytest.raises(ValueError, match="dilations"):
        init_net(SHIPPED, windows, 128, (2, 4, 8, 16, 32), hop, bands)
    with pytest.raises(ValueError, match="samples apart"):
        init_net(SHIPPED, windows, 128, (2, 4, 8, 16), hop // 2, bands)
    other = F.NARROW if bands != F.NARROW else F.WIDE
    with pytest.raises(ValueError, match="--bands"):
        init_net(SHIPPED, windows, 128, (2, 4, 8, 16), hop, other)


def test_a_warm_start_can_grow_the_network_keeping_its_function() -> None:
    torch = pytest.importorskip("torch")
    from services.recogniser.training.net import export
    from services.recogniser.training.train_net import init_net

    fn = load_model(SHIPPED).offline
    windows, hop, bands = fn.windows, fn.hop, fn.bands
    net = init_net(SHIPPED, windows, 192, hop=hop, bands=bands, seed=3)
    assert (net.conv1.out_channels, net.conv2.out_channels, net.t1.out_channels) == (24, 48, 192)
    grown = export(net, fn.thresholds)
    rng = np.random.default_rng(5)
    spec = (rng.random((200, bands.n, len(windows))) * 2).astype(np.float32)
    assert np.abs(grown.forward(spec) - fn.forward(spec)).max() < 1e-4
    # the added channels compute something (they are not dead), and the same seed draws the same weights
    with torch.no_grad():
        assert float(net.t1.weight[128:].abs().sum()) > 0 and float(net.res[0].weight[:128, 128:].abs().sum()) == 0
    again = init_net(SHIPPED, windows, 192, hop=hop, bands=bands, seed=3)
    assert torch.equal(again.res[2].weight, net.res[2].weight)
    front_only = init_net(SHIPPED, windows, 128, hop=hop, bands=bands, front=(32, 64))
    assert (front_only.conv2.out_channels, front_only.t1.in_channels) == (64, 64 * bands.n // 4)
    assert np.abs(export(front_only, fn.thresholds).forward(spec) - fn.forward(spec)).max() < 1e-4
    with pytest.raises(ValueError, match="not shrink"):
        init_net(SHIPPED, windows, 192, hop=hop, bands=bands, front=(8, 48))
