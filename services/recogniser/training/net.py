"""The framewise network in PyTorch (training only) and its export to :class:`~services.recogniser.framenet.FrameNet`.

Layer for layer the same computation as the NumPy inference in
:mod:`services.recogniser.framenet` (batch normalisation folded into the weights
on export; dropout is a no-op there).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from torch import nn
from torch.nn import functional as TF

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.framenet import N_OUT, FrameNet, Layer, Network
from services.recogniser.training.defaults import DILATIONS  # the trainer's --help shows it without PyTorch


class Net(nn.Module):
    """Input (batch, t, bands.n, len(windows)) band spectra of the analysis ``windows`` (samples), or
    (batch, t, bands.n) with one window, frames ``hop`` samples apart (both at ``bands.sample_rate``); output
    (batch, N_OUT, t) logits."""

    def __init__(self, c1: int = 16, c2: int = 32, width: int = 128, dilations: tuple[int, ...] = DILATIONS,
                 dropout: float = 0.2, windows: tuple[int, ...] = (F.N_FFT,), hop: int = F.HOP,
                 bands: F.Bands = F.NARROW) -> None:
        super().__init__()
        self.windows = windows
        self.hop = hop
        self.bands = bands
        self.conv1 = nn.Conv2d(len(windows), c1, 3, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(c1)
        self.conv2 = nn.Conv2d(c1, c2, 3, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(c2)
        self.bands_out = bands.n // 4
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
    return FrameNet(layers, np.asarray(th, np.float32), windows=net.windows, subframe=True, hop=net.hop,
                    bands=net.bands)


def batch_norms(net: Net) -> list[nn.BatchNorm1d | nn.BatchNorm2d]:
    """The network's batch normalisations in order (each follows one convolution)."""
    return [net.bn1, net.bn2, net.bn_t1, *(bn for bn in net.bn_res if isinstance(bn, nn.BatchNorm1d))]


def from_export(fn: FrameNet | Network, dropout: float = 0.2) -> Net:
    """A :class:`Net` that computes (in eval mode) what the exported network ``fn`` (its first network, if an
    ensemble) computes: the folded convolution weights go back into the convolutions and each batch
    normalisation starts as the identity (mean 0, variance 1 - eps, scale 1, shift: the folded bias).
    Before training on it, call :func:`calibrate` so its batch statistics start where they will be.

    Raises ValueError when the layers are not of :class:`Net`'s layout (two 2-D convolutions, one time
    convolution, residual dilated ones, a 1x1 head)."""
    layers = fn.layers
    kinds = [la.kind for la in layers]
    if len(layers) < 4 or kinds[:3] != ["conv2d", "conv2d", "conv1d"] or not all(la.residual for la in layers[3:-1]):
        raise ValueError(f"not a network of the trainer's layout: layers {kinds}")
    c1, c2, width = int(layers[0].w.shape[3]), int(layers[1].w.shape[3]), int(layers[2].w.shape[2])
    net = Net(c1=c1, c2=c2, width=width, dilations=tuple(la.dilation for la in layers[3:-1]), dropout=dropout,
              windows=tuple(fn.windows), hop=fn.hop, bands=fn.bands)
    convs = [net.conv1, net.conv2, net.t1, *net.res]
    bns = batch_norms(net)
    with torch.no_grad():
        for la, conv, bn in zip(layers[:-1], convs, bns, strict=True):
            order = (3, 2, 0, 1) if la.kind == "conv2d" else (2, 1, 0)
            w = torch.from_numpy(np.ascontiguousarray(la.w.transpose(order), np.float32))
            if w.shape != conv.weight.shape:
                raise ValueError(f"layer shape {tuple(w.shape)} where the trainer's network has "
                                 f"{tuple(conv.weight.shape)}")
            conv.weight.copy_(w)
            assert bn.running_mean is not None and bn.running_var is not None
            bn.running_mean.zero_()
            bn.running_var.fill_(1.0 - bn.eps)
            bn.weight.fill_(1.0)
            bn.bias.copy_(torch.from_numpy(la.b.astype(np.float32)))
        head = layers[-1]
        assert net.head.bias is not None
        net.head.weight.copy_(torch.from_numpy(np.ascontiguousarray(head.w.transpose(2, 1, 0), np.float32)))
        net.head.bias.copy_(torch.from_numpy(head.b.astype(np.float32)))
    net.eval()
    return net


def widen(net: Net, c1: int, c2: int, width: int, seed: int = 0) -> Net:
    """A copy of ``net`` with ``c1`` and ``c2`` channels in its 2-D convolutions and ``width`` in its time
    convolutions (each at least ``net``'s), computing in eval mode what ``net`` computes: the added channels
    start from PyTorch's random initialisation (drawn from ``seed``), and every weight by which an existing
    channel or the head reads an added one is zero (so the added channels first learn through those weights).
    The batch normalisations of the added channels start as the identity; call :func:`calibrate` before
    training.

    Raises ValueError when a size is smaller than ``net``'s."""
    old = (net.conv1.out_channels, net.conv2.out_channels, net.t1.out_channels)
    if c1 < old[0] or c2 < old[1] or width < old[2]:
        raise ValueError(f"a network of {old[0]}, {old[1]} and {old[2]} channels cannot narrow to "
                         f"{c1}, {c2} and {width}")
    with torch.random.fork_rng():  # the caller's random state is left as it was
        torch.manual_seed(seed)
        wide = Net(c1=c1, c2=c2, width=width, dilations=net.dilations, dropout=net.drop.p, windows=net.windows,
                   hop=net.hop, bands=net.bands)
    bands_out = net.bands_out
    # (old convolution, new one, channels it reads that existed before, of the new ones' total)
    pairs: list[tuple[nn.Module, nn.Module, int]] = [
        (net.conv1, wide.conv1, net.conv1.in_channels),
        (net.conv2, wide.conv2, old[0]),
        (net.t1, wide.t1, old[1] * bands_out),  # channel-major flattening: the old channels' bands come first
        *((a, b, old[2]) for a, b in zip(net.res, wide.res, strict=True)),
        (net.head, wide.head, old[2]),
    ]
    with torch.no_grad():
        for a, b, reads in pairs:
            assert isinstance(a, nn.Conv1d | nn.Conv2d) and isinstance(b, nn.Conv1d | nn.Conv2d)
            n_out = a.out_channels
            b.weight[:n_out].zero_()
            b.weight[:n_out, :reads] = a.weight
            if a.bias is not None and b.bias is not None:
                b.bias[:n_out] = a.bias
        for a_bn, b_bn in zip(batch_norms(net), batch_norms(wide), strict=True):
            n = a_bn.num_features
            assert a_bn.running_mean is not None and a_bn.running_var is not None
            assert b_bn.running_mean is not None and b_bn.running_var is not None
            b_bn.weight[:n] = a_bn.weight
            b_bn.bias[:n] = a_bn.bias
            b_bn.running_mean[:n] = a_bn.running_mean
            b_bn.running_var[:n] = a_bn.running_var
    wide.eval()
    return wide


def calibrate(net: Net, inputs: list[torch.Tensor]) -> None:
    """Give each batch normalisation of ``net`` the per-channel mean m and variance v of its inputs over the
    spectra ``inputs`` (each (batch, t, N_BANDS, windows)) as running statistics, with scale sqrt(v + eps) and
    shift + m, so the eval-mode function is unchanged (to rounding) and training-mode batch statistics start
    near the running ones (a network from :func:`from_export` would otherwise be renormalised when training)."""
    bns = batch_norms(net)
    sums: dict[int, list[torch.Tensor]] = {}

    def hook(k: int) -> Callable[[nn.Module, tuple[torch.Tensor, ...]], None]:
        def record(_module: nn.Module, args: tuple[torch.Tensor, ...]) -> None:
            x = args[0].transpose(0, 1).reshape(args[0].shape[1], -1).double()  # (channels, everything else)
            s = sums.setdefault(k, [torch.zeros(x.shape[0], dtype=torch.float64)] * 2 + [torch.zeros(())])
            sums[k] = [s[0] + x.sum(1), s[1] + (x * x).sum(1), s[2] + x.shape[1]]
        return record

    handles = [bn.register_forward_pre_hook(hook(k)) for k, bn in enumerate(bns)]
    net.eval()
    with torch.no_grad():
        for x in inputs:
            net(x)
        for h in handles:
            h.remove()
        for k, bn in enumerate(bns):
            total, squares, n = sums[k]
            mean = total / n
            var = (squares / n - mean * mean).clamp_min(0.0)
            assert bn.running_mean is not None and bn.running_var is not None
            # g (x - m0) / s0 + b == g' (x - m) / s + b' for g' = g s / s0, b' = b + g (m - m0) / s0
            ratio = bn.weight.double() / torch.sqrt(bn.running_var.double() + bn.eps)
            bn.bias.add_((ratio * (mean - bn.running_mean.double())).float())
            bn.weight.copy_((ratio * torch.sqrt(var + bn.eps)).float())
            bn.running_mean.copy_(mean.float())
            bn.running_var.copy_(var.float())


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
