"""The framewise network in PyTorch (training only) and its export to :class:`~services.recogniser.framenet.FrameNet`.

Layer for layer the same computation as the NumPy inference in
:mod:`services.recogniser.framenet` (batch normalisation folded into the weights
on export; dropout is a no-op there).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.nn import functional as TF

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.framenet import N_OUT, FrameNet, Layer


class Net(nn.Module):
    """Input (batch, t, N_BANDS, len(windows)) band spectra of the analysis ``windows`` (samples), or
    (batch, t, N_BANDS) with one window; output (batch, N_OUT, t) logits."""

    def __init__(self, c1: int = 16, c2: int = 32, width: int = 128, dilations: tuple[int, ...] = (2, 4, 8, 16),
                 dropout: float = 0.2, windows: tuple[int, ...] = (F.N_FFT,)) -> None:
        super().__init__()
        self.windows = windows
        self.conv1 = nn.Conv2d(len(windows), c1, 3, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(c1)
        self.conv2 = nn.Conv2d(c1, c2, 3, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(c2)
        self.bands_out = F.N_BANDS // 4
        self.t1 = nn.Conv1d(c2 * self.bands_out, width, 3, padding=1, bias=False)
        self.bn_t1 = nn.BatchNorm1d(width)
        self.res = nn.ModuleList(nn.Conv1d(width, width, 3, dilation=d, padding=d, bias=False) for d in dilations)
        self.bn_res = nn.ModuleList(nn.BatchNorm1d(width) for _ in dilations)
        self.dilations = dilations
        self.head = nn.Conv1d(width, N_OUT, 1)
        self.drop = nn.Dropout(dropout)

    @property
    def margin(self) -> int:
        """Context frames needed on each side (as :attr:`FrameNet.margin`)."""
        return 2 + 1 + sum(self.dilations)

    def forward(self, spec: torch.Tensor) -> torch.Tensor:
        b, t = spec.shape[:2]
        x = spec[:, None] if spec.dim() == 3 else spec.permute(0, 3, 1, 2)  # (batch, windows, t, bands)
        x = TF.max_pool2d(TF.relu(self.bn1(self.conv1(x))), (1, 2))
        x = TF.max_pool2d(TF.relu(self.bn2(self.conv2(x))), (1, 2))
        x = x.permute(0, 1, 3, 2).reshape(b, -1, t)  # channel-major: channel * bands + band
        x = TF.relu(self.bn_t1(self.t1(self.drop(x))))
        for conv, bn in zip(self.res, self.bn_res, strict=True):
            x = x + TF.relu(bn(conv(self.drop(x))))
        return self.head(self.drop(x))


def _fold(w: torch.Tensor, bn: nn.BatchNorm1d | nn.BatchNorm2d) -> tuple[np.ndarray, np.ndarray]:
    """Convolution weights (c_out first) and bias with a following batch normalisation folded in."""
    assert bn.running_var is not None and bn.running_mean is not None
    s = bn.weight / torch.sqrt(bn.running_var + bn.eps)
    shape = (-1,) + (1,) * (w.dim() - 1)
    return (w * s.reshape(shape)).detach().numpy(), (bn.bias - bn.running_mean * s).detach().numpy()


def export(net: Net, thresholds: np.ndarray | None = None) -> FrameNet:
    """The NumPy form of a trained :class:`Net` (thresholds default to 0.5 per class, onset output unused)."""
    net.eval()
    layers = []
    for conv2d, bn2d in ((net.conv1, net.bn1), (net.conv2, net.bn2)):
        w, b = _fold(conv2d.weight, bn2d)
        layers.append(Layer("conv2d", np.ascontiguousarray(w.transpose(2, 3, 1, 0)), b, pool=2))
    w, b = _fold(net.t1.weight, net.bn_t1)
    layers.append(Layer("conv1d", np.ascontiguousarray(w.transpose(2, 1, 0)), b))
    for conv, bn, d in zip(net.res, net.bn_res, net.dilations, strict=True):
        assert isinstance(conv, nn.Conv1d) and isinstance(bn, nn.BatchNorm1d)
        w, b = _fold(conv.weight, bn)
        layers.append(Layer("conv1d", np.ascontiguousarray(w.transpose(2, 1, 0)), b, dilation=d, residual=True))
    assert net.head.bias is not None
    layers.append(Layer("conv1d", np.ascontiguousarray(net.head.weight.detach().numpy().transpose(2, 1, 0)),
                        net.head.bias.detach().numpy(), relu=False))
    for la in layers:
        la.w = la.w.astype(np.float32)
        la.b = la.b.astype(np.float32)
    th = thresholds if thresholds is not None else np.array([0.5] * N_CLASSES + [1.01], np.float32)
    return FrameNet(layers, np.asarray(th, np.float32), windows=net.windows)
