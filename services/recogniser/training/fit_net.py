"""Fitting the framewise network (PyTorch, CPU) on a :class:`~services.recogniser.training.frames.FrameSet`.

Random crops of excerpts are the batches; the loss is taken only on each crop's
central frames, whose whole context lies inside the crop (so no crop edge is seen
as silence). Loss: binary cross-entropy of the class and onset activations
against widened targets (:func:`~services.recogniser.training.frames.targets`),
plus the squared velocity error at strike frames. The state with the lowest
validation-kit loss is kept. Crops are augmented on the spectrum (gain, EQ, band shift).
Negative frames of a class where another class is struck can weigh more (confusions).
"""

from __future__ import annotations

import time

import numpy as np
import torch
from torch.nn import functional as TF

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.training.defaults import DILATIONS, HARD_WEIGHT  # shown by --help without PyTorch
from services.recogniser.training.frames import NEIGHBOUR_TARGET, FrameSet, targets
from services.recogniser.training.net import Net, calibrate

CROP_S = 4.0
"""Length of a crop whose loss counts, seconds (400 frames of 10 ms)."""
VAL_CROP_S = 10.0
"""Length of the consecutive crops the validation loss is taken on, seconds."""
BATCH = 16
"""Crops per batch."""
VEL_WEIGHT = 2.0
"""Weight of the velocity error relative to the activation loss."""
EQ_P = 0.5
"""Share of crops given a random gain and a smooth random EQ curve (on the spectrum, exactly as on the audio)."""
EQ_DB = 6.0
"""Range of that gain and of each of the curve's three cosine terms, +- dB."""
SHIFT_P = 0.2
"""Share of crops shifted up or down by one band (about two semitones)."""


def augment_spectrum(x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A crop's band spectra (frames, bands, windows) as if its audio had been filtered and shifted in pitch.

    Band magnitudes are linear in the audio, so a gain per band is exact on the spectrum
    (undoing and redoing the log compression), unlike an offset added to the log values."""
    if rng.random() < EQ_P:
        pos = np.linspace(0.0, 1.0, x.shape[1])
        gain = rng.uniform(-EQ_DB, EQ_DB)
        db = gain + np.sum([rng.uniform(-EQ_DB, EQ_DB) * np.cos(np.pi * k * pos + rng.uniform(0, 6.3))
                            for k in (1, 2, 3)], axis=0)
        lin = (10.0 ** x - 1.0) / F.LOG_MUL
        x = np.log10(1.0 + F.LOG_MUL * lin * 10 ** (db[:, None] / 20)).astype(np.float32)
    if rng.random() < SHIFT_P:
        x = np.concatenate([x[:, :1], x[:, :-1]], axis=1) if rng.random() < 0.5 else \
            np.concatenate([x[:, 1:], x[:, -1:]], axis=1)
    return x


class Batches:
    """Crops of a frame set's spectra of some ``windows`` with their targets (targets made once per excerpt)."""

    def __init__(self, data: FrameSet, margin: int, windows: tuple[int, ...],
                 neighbour: float = NEIGHBOUR_TARGET, onset_merge_s: float | None = None) -> None:
        self.data = data
        self.margin = margin
        self.windows = windows
        self.tgt = [targets(data.starts[e + 1] - data.starts[e], data.excerpt_hits(e), neighbour, data.fps,
                            onset_merge_s) for e in range(data.n_excerpts)]

    def crop(self, e: int, a: int, n: int) -> tuple[np.ndarray, ...]:
        """Input frames a - margin .. a + n + margin (silence outside) and the targets of frames a .. a + n."""
        m = self.margin
        spec = self.data.excerpt(e, self.windows)
        lo, hi = max(0, a - m), min(len(spec), a + n + m)
        x = np.zeros((n + 2 * m, *spec.shape[1:]), np.float32)
        x[lo - (a - m) : hi - (a - m)] = spec[lo:hi]
        act, vel, mask = self.tgt[e]
        return x, act[a : a + n], vel[a : a + n], mask[a : a + n]

    def random(self, rng: np.random.Generator, batch: int, n: int) -> list[torch.Tensor]:
        """A batch of random crops, each spectrum augmented (:func:`augment_spectrum`)."""
        parts = []
        for _ in range(batch):
            e = int(rng.integers(self.data.n_excerpts))
            length = self.data.starts[e + 1] - self.data.starts[e]
            x, *tgt = self.crop(e, int(rng.integers(0, max(1, length - n))), n)
            parts.append((augment_spectrum(x, rng), *tgt))
        return [torch.from_numpy(np.stack(p)) for p in zip(*parts, strict=True)]


def loss_of(net: Net, x: torch.Tensor, act: torch.Tensor, vel: torch.Tensor, mask: torch.Tensor,
            hard: float = 0.0, outputs: torch.Tensor | None = None) -> torch.Tensor:
    """Activation loss (binary cross-entropy; a class's frames with target 0 where another class has a strike
    target above 0 (its frame, and those beside it unless their target is 0) weigh ``1 + hard``; every frame
    of activation ``k`` is further weighted by ``outputs[k]``, shape (N_CLASSES + 1,), the last the onset
    output) plus the velocity loss."""
    m = net.margin
    out = net(x)[:, :, m:-m].transpose(1, 2)  # (batch, frames, N_OUT)
    weight = torch.ones_like(act) if outputs is None else outputs.expand_as(act).clone()
    if hard:
        struck = (act[..., :N_CLASSES] > 0).any(dim=-1, keepdim=True)
        weight[..., :N_CLASSES] *= 1 + hard * ((act[..., :N_CLASSES] == 0) & struck).float()
    loss = TF.binary_cross_entropy_with_logits(out[..., : N_CLASSES + 1], act, weight=weight)
    pred = torch.sigmoid(out[..., N_CLASSES + 1 :])
    if mask.any():
        loss = loss + VEL_WEIGHT * ((pred - vel)[mask] ** 2).mean()
    return loss


def validation_loss(net: Net, val: Batches, n: int | None = None) -> float:
    """Mean loss over the validation excerpts cut into consecutive crops of ``n`` frames (default
    :data:`VAL_CROP_S`)."""
    n = n if n is not None else round(VAL_CROP_S * val.data.fps)
    net.eval()
    total = count = 0.0
    with torch.no_grad():
        for e in range(val.data.n_excerpts):
            length = val.data.starts[e + 1] - val.data.starts[e]
            for a in range(0, length - n + 1, n):
                x, act, vel, mask = (torch.from_numpy(v[None]) for v in val.crop(e, a, n))
                total += float(loss_of(net, x, act, vel, mask))
                count += 1
    net.train()
    return total / max(count, 1)


def fit(train: FrameSet, val: FrameSet, epochs: float, seed: int, lr: float = 2e-3, log_every: int = 250,
        minutes: float | None = None, width: int = 128, front: tuple[int, int] | None = None,
        windows: tuple[int, ...] = (F.N_FFT,),
        hard: float = HARD_WEIGHT, init: Net | None = None, warmup: float = 0.03,
        outputs: dict[int, float] | None = None, neighbour: float = NEIGHBOUR_TARGET,
        dilations: tuple[int, ...] = DILATIONS, onset_merge_s: float | None = None) -> Net:
    """Fit a :class:`Net` on the spectra of ``windows``; ``epochs``: passes over the training frames (fractional
    allowed), or only as many steps as fit in ``minutes``, whichever is fewer. ``hard``: see :func:`loss_of`
    (the validation loss is unweighted). ``outputs``: loss weight of activation ``k`` (class index; N_CLASSES: the
    onset output) where not 1 (e.g. {1: 2.0}: snare errors count twice; the validation loss is unweighted).
    ``neighbour``: the target of the frames beside a strike's (:func:`~.frames.targets`; training and validation).
    ``onset_merge_s``: the onset output's target marks onsets, strikes this close (seconds) being one
    (:func:`~.frames.targets`; default: every strike).
    ``dilations``: of the residual time convolutions (frames), whose sum sets the context each side, and
    ``width`` and ``front``: channels of the time convolutions and of the two 2-D ones (default width/8 and
    width/4), of a new network.
    ``init``: continue from this network (of these ``windows``; e.g. :func:`~.net.from_export` of a model file),
    its batch normalisations first calibrated on 8 training batches (:func:`~.net.calibrate`); it is kept
    unless a fitted state has a lower validation-kit loss.
    Ctrl-C (KeyboardInterrupt) or a training loss that is not a number stops the fitting early, keeping the state
    of the lowest validation-kit loss so far; raises :class:`FitError` when no state has a loss that is a number.
    Learning rate: a linear warm-up to ``lr`` over the first ``warmup`` (share) of the run, then a cosine decay
    to zero; with ``minutes`` the run's progress is the share of the time budget spent (so on a shared machine
    whose speed changes the schedule still ends at zero), else the share of the steps."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    if val.hop != train.hop:
        raise ValueError(f"training frames are {train.hop} samples apart, validation frames {val.hop}")
    if val.bands != train.bands:
        raise ValueError(f"training spectra of {train.bands}, validation spectra of {val.bands}")
    c1, c2 = front if front is not None else (width // 8, width // 4)
    net = init if init is not None else Net(c1=c1, c2=c2, width=width, windows=windows,
                                            dilations=dilations, hop=train.hop, bands=train.bands)
    if net.windows != windows:
        raise ValueError(f"the network reads windows {net.windows}, not {windows}")
    if net.hop != train.hop:
        raise ValueError(f"the network reads frames {net.hop} samples apart, the training set has {train.hop}")
    if net.bands != train.bands:
        raise ValueError(f"the network reads {net.bands}, the training set has {train.bands}")
    crop = round(CROP_S * train.fps)
    tb = Batches(train, net.margin, windows, neighbour, onset_merge_s)
    vb = Batches(val, net.margin, windows, neighbour, onset_merge_s)
    out_w = None
    if outputs:
        out_w = torch.ones(N_CLASSES + 1)
        for k, w in outputs.items():
            out_w[k] = w
    best, best_state = np.inf, None
    if init is not None:
        calibrate(net, [tb.random(np.random.default_rng(seed + 1), BATCH, crop)[0] for _ in range(8)])
        best, best_state = validation_loss(net, vb), {k: t.clone() for k, t in net.state_dict().items()}
        print(f"  initial network: validation-kit loss {best:.4f}", flush=True)
    steps = max(1, int(epochs * len(train.spec) / (BATCH * crop)))
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=1e-4)
    t0, running = time.time(), 0.0
    step = 0
    done = 0.0
    stopped = ""  # why the fitting stopped before its end: Ctrl-C, or a loss that is not a number
    while step < steps and done < 1.0:
        try:
            step += 1
            done = step / steps if minutes is None else max(step / steps, (time.time() - t0) / (minutes * 60))
            rate = done / warmup if done < warmup else 0.5 * (1 + np.cos(np.pi * (done - warmup) / (1 - warmup)))
            for group in opt.param_groups:
                group["lr"] = lr * float(min(1.0, rate))
            x, act, vel, mask = tb.random(rng, BATCH, crop)
            loss = loss_of(net, x, act, vel, mask, hard=hard, outputs=out_w)
            if not torch.isfinite(loss):  # diverged: every later step would be wasted, its state useless
                stopped = f"the training loss is {loss.item()} at step {step} (try a lower --lr)"
                break
            opt.zero_grad()
            loss.backward()
            opt.step()
            running += loss.item()
            last = step == steps or (minutes is not None and time.time() - t0 >= minutes * 60)
            if step % log_every == 0 or last:
                v = validation_loss(net, vb)
                mark = ""
                if v < best:
                    best, best_state, mark = v, {k: t.clone() for k, t in net.state_dict().items()}, " *"
                print(f"  step {step} ({done:.0%}): training loss {running / ((step - 1) % log_every + 1):.4f}, "
                      f"validation-kit loss {v:.4f}{mark} ({time.time() - t0:.0f} s, "
                      f"{step * BATCH * crop / len(train.spec):.2f} epochs)", flush=True)
                running = 0.0
                done = 1.0 if last else done
        except KeyboardInterrupt:  # the user stops the fitting: keep what was fitted so far
            stopped = f"Ctrl-C at step {step}"
            break
    if stopped:
        best_state = _after_stop(net, vb, stopped, best, best_state, diverged=not stopped.startswith("Ctrl-C"))
    if best_state is None:
        raise FitError("no fitted state has a validation-kit loss that is a number (try a lower --lr)")
    net.load_state_dict(best_state)
    net.eval()
    return net


class FitError(RuntimeError):
    """The fitting produced no usable network (its losses are not numbers)."""


def _after_stop(net: Net, vb: Batches, why: str, best: float, best_state: dict[str, torch.Tensor] | None,
                diverged: bool) -> dict[str, torch.Tensor] | None:
    """The state to keep when the fitting stopped early (``why``): the one of the lowest validation-kit loss so
    far, else (none validated yet, and not ``diverged``) the state as it is, if its validation loss is a number."""
    if best_state is not None:
        print(f"  fitting stopped ({why}): keeping the state of validation-kit loss {best:.4f} (Ctrl-C again "
              "before the model is written: nothing written)", flush=True)
        return best_state
    if diverged:
        raise FitError(f"the fitting diverged before any state was validated: {why}")
    print(f"  fitting stopped ({why}) before its first validation: validating the network as it is "
          "(Ctrl-C again: stop without writing anything)", flush=True)
    v = validation_loss(net, vb)
    print(f"  validation-kit loss {v:.4f}", flush=True)
    return {k: t.clone() for k, t in net.state_dict().items()} if np.isfinite(v) else None


if __name__ == "__main__":  # run as a program by mistake: say which commands train
    from services.recogniser.training.options import not_a_command

    not_a_command(__spec__.name)
