"""The offline network's decision rule beyond thresholds: class strikes moved to onset-output peaks, strike times
between frames, snare peaks dropped under hi-hat peaks, how the tuner chooses both, and the trainer's options behind
the shipped model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.framenet import N_OUT, FrameNet
from services.recogniser.model import Model, load_live, load_model
from services.recogniser.training import excerpts as ex
from services.recogniser.training.frames import FrameSet
from services.recogniser.training.kits import Instrument, Kit, Layer
from services.recogniser.training.tune import choose
from services.recogniser.transcribe import strikes

from .test_framenet import _random_net

KICK, SNARE, HH, ONSET = 0, 1, 2, N_CLASSES
SHIPPED = Path(__file__).resolve().parents[2] / "services/recogniser/models/recogniser.npz"


def _net() -> FrameNet:
    net = _random_net()
    net.thresholds = np.array([0.5] * N_CLASSES + [1.01], np.float32)
    return net


def _out(frames: int = 60) -> np.ndarray:
    out = np.zeros((frames, N_OUT), np.float32)
    out[:, N_CLASSES + 1 :] = 0.5
    return out


def test_class_strikes_move_to_the_nearest_onset_peak_within_snap_frames() -> None:
    net = _net()
    out = _out()
    out[10, KICK], out[14, HH], out[12, ONSET] = 0.9, 0.8, 0.7  # one strike whose classes peak 40 ms apart
    out[30, SNARE], out[34, ONSET] = 0.9, 0.6  # an onset peak too far away to move to
    out[50, HH], out[52, HH], out[51, ONSET] = 0.7, 0.9, 0.8  # one class twice around one onset peak
    assert [(t, c) for t, c, _, _ in net.detect(out)] == [(10, KICK), (14, HH), (30, SNARE), (50, HH), (52, HH)]
    net.snap_frames = 2
    found = net.detect(out)
    assert [(t, c) for t, c, _, _ in found] == [(12, KICK), (12, HH), (30, SNARE), (51, HH)]
    assert found[-1][3] == pytest.approx(0.9)  # the more probable of the two kept
    assert len({e.time for e in strikes(net, out) if e.time < 0.2}) == 1  # one onset without a chord window
    out[12, ONSET] = 0.05  # below SNAP_MIN: not a place to move to
    assert [(t, c) for t, c, _, _ in net.detect(out)][:2] == [(10, KICK), (14, HH)]


def test_subframe_times_keep_two_strikes_20_to_30_ms_apart_as_two_onsets() -> None:
    net = _net()
    out = _out()
    out[19:22, HH] = 0.5, 0.9, 0.5  # a hi-hat centred on frame 20
    out[21:24, SNARE] = 0.3, 0.9, 0.6  # a snare about 23 ms later, its peak two frames (19.95 ms) on
    frame_s = 1 / F.FPS
    assert len({e.time for e in strikes(net, out)}) == 1  # frame times: one chord of the 20 ms window
    net.subframe = True
    found = net.detect(out)
    assert net.positions(out, found) == pytest.approx([20.0, 22 + 0.5 * (0.3 - 0.6) / (0.3 - 1.8 + 0.6)])
    times = sorted(e.time for e in strikes(net, out))
    assert len(times) == 2 and times[1] - times[0] == pytest.approx((2 + 1 / 6) * frame_s)
    out[21:24, SNARE] = 0.0, 0.9, 0.9  # a two-frame plateau: halfway between its frames
    assert net.positions(out, net.detect(out)).tolist() == [20.0, 22.5]


def test_a_strike_moved_to_an_onset_peak_is_placed_by_the_onset_output() -> None:
    net = _net()
    net.snap_frames, net.subframe = 2, True
    out = _out()
    out[10, KICK], out[13, HH] = 0.9, 0.8  # one strike whose classes peak 30 ms apart
    out[11:14, ONSET] = 0.2, 0.8, 0.6  # the onset output peaks at 12, leaning towards 13
    found = net.detect(out)
    assert [(t, c) for t, c, _, _ in found] == [(12, KICK), (12, HH)]
    lean = 12 + 0.5 * (0.2 - 0.6) / (0.2 - 1.6 + 0.6)
    assert net.positions(out, found) == pytest.approx([lean, lean])
    assert len({e.time for e in strikes(net, out)}) == 1


def test_a_snare_peak_under_a_stronger_hi_hat_peak_is_dropped() -> None:
    net = _net()
    out = _out()
    out[10, SNARE], out[11, HH] = 0.6, 0.8  # a hi-hat also heard as a snare
    out[30, SNARE], out[30, HH] = 0.9, 0.8  # snare and hi-hat struck together
    out[50, SNARE], out[50, HH] = 0.6, 0.45  # hi-hat below its threshold: not a hi-hat peak
    snares = [t for t, c, _, _ in net.detect(out) if c == SNARE]
    assert snares == [10, 30, 50]
    net.hihat_snare = 1.0
    assert [t for t, c, _, _ in net.detect(out) if c == SNARE] == [30, 50]
    net.hihat_snare = 1.2
    assert [t for t, c, _, _ in net.detect(out) if c == SNARE] == [50]
    assert [t for t, c, _, _ in net.detect(out) if c == HH] == [11, 30]  # hi-hats untouched


def test_the_rule_is_stored_in_the_model_file_and_older_files_have_it_off(tmp_path: Path) -> None:
    live, _ = load_live(SHIPPED)
    net = _net()
    net.snap_frames, net.hihat_snare, net.subframe = 3, 0.7, True
    Model(net, live, {}).save(tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz").offline
    assert (back.snap_frames, back.hihat_snare, back.subframe) == (3, 0.7, True)
    with np.load(tmp_path / "m.npz") as z:  # a file written before the rule: no such keys
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(bytes(arrays["meta"]).decode())
    del meta["offline"]["snap_frames"], meta["offline"]["hihat_snare"], meta["offline"]["subframe"]
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(tmp_path / "old.npz", **arrays)  # type: ignore[arg-type]
    old = load_model(tmp_path / "old.npz").offline
    assert (old.snap_frames, old.hihat_snare, old.subframe) == (0, 0.0, False)


def test_the_tuner_moves_strikes_and_drops_snares_when_asked_and_that_raises_the_f_measures() -> None:
    per, n = 400, 4
    outs, hits = [], []
    for e in range(n):
        out = _out(per)
        for k, t in enumerate(range(20, per - 20, 20)):
            frame = t + 2
            if k % 3 == 0:  # kick and hi-hat struck together, their peaks 40 ms apart, the onset between
                out[t, KICK], out[t + 4, HH], out[frame, ONSET] = 0.9, 0.8, 0.9
                hits += [[e, frame / F.FPS, KICK, 100], [e, frame / F.FPS, HH, 100]]
            elif k % 3 == 1:  # a hi-hat alone, also heard as a weaker snare
                out[frame, HH], out[frame, SNARE], out[frame, ONSET] = 0.9, 0.7, 0.9
                hits.append([e, frame / F.FPS, HH, 100])
            else:  # snare and hi-hat together, the snare as sure as the false one above: no threshold parts them
                out[frame, SNARE], out[frame, HH], out[frame, ONSET] = 0.7, 0.5, 0.9
                hits += [[e, frame / F.FPS, SNARE, 100], [e, frame / F.FPS, HH, 100]]
        outs.append(out)
    val = FrameSet(np.zeros((n * per, F.N_BANDS, 1), np.float16), np.arange(n + 1) * per,
                   np.array(hits, np.float64), (1024,))
    net = _net()
    choose(net, val, outs)  # the thresholds only: a new network's rules stay off
    assert (net.snap_frames, net.hihat_snare) == (0, 0.0)
    net.snap_frames, net.hihat_snare = 2, 1.0
    choose(net, val, outs)  # a model retuned without rules keeps its own
    assert (net.snap_frames, net.hihat_snare) == (2, 1.0)
    choose(net, val, outs, rules=True)
    assert net.snap_frames >= 2  # no chord window tried (30 ms at most) joins peaks 40 ms apart
    assert net.hihat_snare in (1.0, 1.3)  # 0.7 < r x 0.9 drops the false snares, 0.7 < r x 0.5 would drop true ones
    snares = [ev for ev in strikes(net, outs[0]) if ev.cls == SNARE]
    assert len(snares) == sum(1 for h in hits if h[0] == 0 and h[2] == SNARE)


def test_a_plain_job_renders_the_kit_unvaried_and_dry(monkeypatch: pytest.MonkeyPatch) -> None:
    varied: list[bool] = []

    def fake_render(notes: list, kit: Kit, rng: np.random.Generator, duration: float | None = None,
                    vary: bool = False, wide: bool = False) -> tuple[np.ndarray, list]:
        varied.append(vary)
        return np.full(100, 0.5, np.float32), []

    monkeypatch.setattr(ex, "render", fake_render)
    monkeypatch.setattr(ex, "read_notes", lambda path: [])
    monkeypatch.setattr(ex, "augment", lambda audio, rng: audio * 0.5)  # augmented audio peaks at 0.25
    layer = Layer(0.0, 1.0, 1.0, np.ones(10, np.float32))
    monkeypatch.setitem(ex._KITS, "one", Kit("one", "test", {"snare": [Instrument("s", "snare", 1.0, [layer])]}))
    peaks = [float(ex.render_excerpt((s, "x.mid", 60.0, ("one",), 1.0, False, 0.0, 0.0))[0].max()) for s in range(40)]
    assert varied == [False] * 40 and peaks == pytest.approx([0.9] * 40)
    varied.clear()
    peaks = [float(ex.render_excerpt((s, "x.mid", 60.0, ("one",), 0.0, False, ex.VARY_P, 0.0))[0].max())
             for s in range(40)]
    assert 20 < sum(varied) < 40 and peaks == pytest.approx([0.25] * 40)


def test_output_weights_read_class_and_onset_names() -> None:
    from services.recogniser.training.train_net import output_weights  # no torch needed to read the option

    assert output_weights(["snare=2", "onset=1.5"]) == {SNARE: 2.0, ONSET: 1.5}
    with pytest.raises(ValueError):
        output_weights(["cowbell=2"])


def test_output_loss_weights() -> None:
    torch = pytest.importorskip("torch")  # training-only dependency
    from services.recogniser.training.fit_net import loss_of
    from services.recogniser.training.net import Net

    torch.manual_seed(0)
    net = Net(c1=2, c2=4, width=8).eval()
    x = torch.rand(2, 60 + 2 * net.margin, F.N_BANDS, 1)
    act = (torch.rand(2, 60, N_CLASSES + 1) > 0.9).float()
    vel, mask = torch.zeros(2, 60, N_CLASSES), torch.zeros(2, 60, N_CLASSES, dtype=torch.bool)
    with torch.no_grad():
        plain = loss_of(net, x, act, vel, mask)
        assert float(loss_of(net, x, act, vel, mask, outputs=torch.ones(N_CLASSES + 1))) == pytest.approx(
            float(plain))
        assert float(loss_of(net, x, act, vel, mask, outputs=torch.full((N_CLASSES + 1,), 2.0))) == pytest.approx(
            2 * float(plain), rel=1e-5)
        snare = torch.ones(N_CLASSES + 1)
        snare[SNARE] = 3.0
        assert float(plain) < float(loss_of(net, x, act, vel, mask, outputs=snare)) < 3 * float(plain)
