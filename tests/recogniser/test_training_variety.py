"""Training data variety: per-instrument changes and layered instruments keep what the labels say."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, sosfilt

from services.recogniser import features as F
from services.recogniser.classes import N_CLASSES
from services.recogniser.training import excerpts as ex
from services.recogniser.training.excerpts import layered, with_layers
from services.recogniser.training.frames import NEIGHBOUR_TARGET, targets
from services.recogniser.training.kits import RENDER_RATE, Instrument, Kit, Layer
from services.recogniser.training.render import MIN_DECAY_S, Variation


def _burst(seed: int, decay_s: float, length_s: float = 0.6) -> np.ndarray:
    t = np.arange(int(length_s * RENDER_RATE)) / RENDER_RATE
    return (np.random.default_rng(seed).standard_normal(len(t)) * np.exp(-t / decay_s)).astype(np.float32)


def _instrument(kind: str, seed: int) -> Instrument:
    return Instrument(f"{kind} {seed}", kind, 1.0, [Layer(0.0, 0.5, 0.5, _burst(seed, 0.1)),
                                                     Layer(0.5, 1.0, 1.0, _burst(seed + 1, 0.2))])


def test_plain_variation_leaves_the_sample_alone() -> None:
    x = _burst(0, 0.1)
    assert np.array_equal(Variation().apply(x), x)


def test_wide_variation_keeps_the_onset_at_the_start_and_open_cymbals_long() -> None:
    rng = np.random.default_rng(1)
    x = _burst(2, 0.4)
    for kind in ("snare", "hh_closed", "hh_open", "kick", "crash") * 8:
        v = Variation.random_wide(rng, kind)
        y = v.apply(x)
        env = np.abs(y)
        first = int(np.argmax(env > 0.1 * env.max()))
        assert first < int(0.003 * RENDER_RATE), (kind, v)
        assert v.decay_s == 0.0 or v.decay_s >= MIN_DECAY_S.get(kind, 0.0)


def test_snare_wires_add_high_band_noise() -> None:
    x = _burst(3, 0.15)
    x = sosfilt(butter(4, 800, btype="low", fs=RENDER_RATE, output="sos"), x).astype(np.float32)  # a dull snare
    wired = Variation(noise_db=0.0, noise_band=(2000.0, 8000.0), seed=4).apply(x)
    high = butter(4, 2000, btype="high", fs=RENDER_RATE, output="sos")
    assert np.sum(sosfilt(high, wired) ** 2) > 20 * np.sum(sosfilt(high, x) ** 2)


def test_layering_sums_two_instruments_without_changing_the_kits() -> None:
    a, b = _instrument("snare", 10), _instrument("snare", 20)
    both = layered(a, b, np.random.default_rng(5))
    assert [(la.lo, la.hi, la.gain) for la in both.layers] == [(la.lo, la.hi, la.gain) for la in a.layers]
    for la, lb, lab in zip(a.layers, b.layers, both.layers, strict=True):
        n, m = len(la.audio), len(lb.audio)
        assert np.corrcoef(lab.audio[:n], la.audio)[0, 1] > 0.5
        # b sounds at the same velocity, at most 1.5 ms late
        lags = [np.corrcoef(lab.audio[d : d + m - 40], lb.audio[: m - 40])[0, 1]
                for d in range(int(0.0015 * RENDER_RATE) + 1)]
        assert max(lags) > 0.3

    kit = Kit("one", "test", {"snare": [a], "kick": [_instrument("kick", 30)]})
    other = Kit("two", "test", {"snare": [b], "kick": [_instrument("kick", 40)]})
    ex._KITS.update({"one": kit, "two": other})
    try:
        changed = 0
        for seed in range(20):
            out = with_layers(kit, ("one", "two"), np.random.default_rng(seed))
            changed += out.instruments["snare"][0] is not a
            assert kit.instruments["snare"] == [a] and kit.instruments["kick"][0].name == "kick 30"
        assert 0 < changed < 20
    finally:
        del ex._KITS["one"], ex._KITS["two"]


def test_frame_targets_mark_strike_frames_and_their_neighbours_at_the_chosen_level() -> None:
    snare, hihat = 1, 2
    hits = np.array([[10 / F.FPS, hihat, 100], [12 / F.FPS, snare, 64]])  # 20 ms apart: two peaks, one frame between
    act, vel, mask = targets(30, hits)
    assert act[9:14, N_CLASSES].tolist() == [NEIGHBOUR_TARGET, 1.0, NEIGHBOUR_TARGET, 1.0, NEIGHBOUR_TARGET]
    assert act[11, hihat] == act[11, snare] == NEIGHBOUR_TARGET and act[14, hihat] == 0.0
    assert mask[10, hihat] and mask[12, snare] and vel[12, snare] == np.float32(64 / 127)
    sharp, _, _ = targets(30, hits, neighbour=0.2)
    assert sharp[9:14, N_CLASSES].tolist() == [np.float32(0.2), 1.0, np.float32(0.2), 1.0, np.float32(0.2)]


def test_onset_target_marks_one_peak_per_onset_as_the_benchmark_merges_strikes() -> None:
    kick, snare, hihat = 0, 1, 2
    # a kick and a snare 12 ms apart are one onset (within 20 ms of its first strike); the hi-hat 24 ms after
    # the kick starts another
    hits = np.array([[0.100, kick, 100], [0.112, snare, 90], [0.124, hihat, 70], [0.300, snare, 50]])
    act, _, _ = targets(40, hits, fps=100.0, onset_merge_s=0.02)
    assert np.flatnonzero(act[:, N_CLASSES] == 1.0).tolist() == [10, 12, 30]
    assert act[11, N_CLASSES] == NEIGHBOUR_TARGET  # the valley between the two onsets
    every, _, _ = targets(40, hits, fps=100.0)
    assert np.flatnonzero(every[:, N_CLASSES] == 1.0).tolist() == [10, 11, 12, 30]
    assert np.array_equal(act[:, :N_CLASSES], every[:, :N_CLASSES])  # the classes' own targets do not change


def test_at_5_ms_frames_strikes_20_ms_apart_are_four_frames_apart_with_nothing_between() -> None:
    snare, hihat = 1, 2
    hits = np.array([[0.1, hihat, 100], [0.12, snare, 64]])
    act, _, mask = targets(60, hits, fps=2 * F.FPS)
    assert np.flatnonzero(act[:, N_CLASSES] == 1.0).tolist() == [20, 24]
    assert act[22, N_CLASSES] == 0.0  # a valley between the two peaks (at 10 ms frames: a neighbour of both)
    assert mask[20, hihat] and mask[24, snare]


def test_the_network_fits_on_frames_of_5_ms(tmp_path: Path) -> None:
    pytest.importorskip("torch")  # training-only dependency
    from services.recogniser.training.fit_net import fit
    from services.recogniser.training.frames import FrameSet
    from services.recogniser.training.net import export

    rng = np.random.default_rng(3)
    hop = F.HOP // 2
    n = 2 * round(6 * 2 * F.FPS)  # two excerpts of 6 s of 5 ms frames
    spec = (rng.random((n, F.N_BANDS, 1)) * 2).astype(np.float16)
    hits = np.array([[e, t, c, 90] for e in (0, 1) for t, c in ((1.0, 0), (2.0, 1), (3.0, 2))], np.float64)
    data = FrameSet(spec, np.array([0, n // 2, n]), hits, (F.N_FFT,), hop)
    data.save(tmp_path / "d.npz")
    back = FrameSet.load(tmp_path / "d.npz")
    assert back.hop == hop and back.fps == pytest.approx(2 * F.FPS)
    net = fit(back, back, epochs=0.5, seed=0, width=16, dilations=(4, 8), log_every=1)
    fn = export(net)
    assert fn.hop == hop and fn.forward(back.excerpt(0).astype(np.float32)).shape[0] == n // 2
    with pytest.raises(ValueError, match="samples apart"):
        fit(back, FrameSet(spec, np.array([0, n // 2, n]), hits, (F.N_FFT,)), epochs=0.1, seed=0, width=16)


def test_excerpts_by_duration_draw_long_performances_as_often_as_their_seconds(
        monkeypatch: pytest.MonkeyPatch) -> None:
    files = [(Path("beat.mid"), 30.0), (Path("long.mid"), 270.0), (Path("short.mid"), 12.0)]
    durations = {p.name: d for p, d in files}
    monkeypatch.setattr(ex, "groove_files", lambda split: files)

    def share_of_long(by_duration: bool) -> float:
        todo = ex.jobs(4000, 5, ("kit",), by_duration=by_duration)
        drawn = [Path(j[1]).name for j in todo]
        assert "short.mid" not in drawn  # under 20 s: never an excerpt of 30 s
        assert all(j[2] == durations[Path(j[1]).name] for j in todo)  # each job carries its performance's length
        return drawn.count("long.mid") / len(drawn)

    assert share_of_long(False) == pytest.approx(0.5, abs=0.03)  # every performance alike
    assert share_of_long(True) == pytest.approx(0.9, abs=0.03)  # 270 of the 300 seconds
    assert ex.jobs(50, 5, ("kit",), by_duration=True) == ex.jobs(50, 5, ("kit",), by_duration=True)


def test_quiet_hihats_lower_every_hihat_together_and_nothing_else() -> None:
    kinds = ("kick", "snare", "hh_closed", "hh_pedal", "hh_open")
    kit = Kit("k", "CC0", {kind: [_instrument(kind, 10 * i)] for i, kind in enumerate(kinds)})
    quiet = [ex.quiet_hihats(kit, seed, 0.4) for seed in range(400)]
    share = sum(q is not kit for q in quiet) / len(quiet)
    assert share == pytest.approx(0.4, abs=0.07)  # the share asked for, drawn per excerpt
    assert all(ex.quiet_hihats(kit, seed, 0.0) is kit for seed in range(50))
    for q in (q for q in quiet if q is not kit):
        db = [20 * np.log10(q.instruments[kind][0].gain) for kind in ("hh_closed", "hh_pedal", "hh_open")]
        assert db[0] == db[1] == db[2]  # the hi-hats keep their balance with each other
        assert ex.QUIET_HIHAT_DB[0] <= -db[0] <= ex.QUIET_HIHAT_DB[1]
        assert q.instruments["kick"] is kit.instruments["kick"] and q.instruments["snare"] is kit.instruments["snare"]
        assert q.instruments["hh_pedal"][0].layers is kit.instruments["hh_pedal"][0].layers  # same samples
    assert all(kit.instruments[kind][0].gain == 1.0 for kind in kinds)  # the loaded kit is never changed
    assert [q is kit for q in quiet] == [ex.quiet_hihats(kit, s, 0.4) is kit for s in range(400)]  # deterministic
