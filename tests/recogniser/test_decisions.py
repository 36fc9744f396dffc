"""Decision rules after the classifier: the onset output, chord grouping, and the kits check of training/bench."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.recogniser.classes import N_CLASSES
from services.recogniser.model import Classifier, load_model
from services.recogniser.training.kits import KitsMissingError, require_kits
from services.recogniser.transcribe import CHORD_S, DrumEvent, group_chords


def _classifier(n_out: int) -> Classifier:
    return Classifier(offsets=(0,), delta=0.1, time_offset_s=0.0, mean=np.zeros(1, np.float32),
                      scale=np.ones(1, np.float32), weights=[np.zeros((1, n_out), np.float32)],
                      biases=[np.zeros(n_out, np.float32)], thresholds=np.full(n_out, 0.5, np.float32),
                      vel_w=np.zeros((2, N_CLASSES), np.float32))


def test_onset_output_keeps_a_strike_no_class_is_sure_of() -> None:
    clf = _classifier(N_CLASSES + 1)
    clf.thresholds[1] = 0.2  # snare: a low threshold
    prob = np.zeros((3, N_CLASSES + 1), np.float32)
    prob[0, [0, 1, N_CLASSES]] = [0.45, 0.19, 0.9]  # a strike, no class sure: the most probable, kick
    prob[1, [0, N_CLASSES]] = [0.45, 0.3]  # not a strike
    prob[2, [0, 2, N_CLASSES]] = [0.7, 0.6, 0.9]  # kick and closed hi-hat: the onset output adds nothing
    hit = clf.decide(prob)
    assert np.flatnonzero(hit[0]).tolist() == [0]
    assert not hit[1].any()
    assert np.flatnonzero(hit[2]).tolist() == [0, 2]


def test_without_onset_output_only_class_thresholds_count() -> None:
    clf = _classifier(N_CLASSES)
    prob = np.full((1, N_CLASSES), 0.4, np.float32)
    prob[0, 3] = 0.6
    assert np.flatnonzero(clf.decide(prob)[0]).tolist() == [3]


def test_chords_share_the_time_of_their_first_strike() -> None:
    near = CHORD_S * 0.99
    events = [DrumEvent(1.0, 0, 100, 0.9), DrumEvent(1.0 + near, 2, 80, 0.8),  # kick + hi-hat: one chord
              DrumEvent(1.0 + near, 0, 60, 0.7),  # a second kick is a second strike, not part of the chord
              DrumEvent(2.0, 1, 90, 0.9), DrumEvent(2.0 + 2 * CHORD_S, 2, 70, 0.9)]  # too far apart: two
    got = [(round(e.time, 6), e.cls) for e in group_chords(events)]
    assert got == [(1.0, 0), (1.0, 2), (round(1.0 + near, 6), 0), (2.0, 1), (round(2.0 + 2 * CHORD_S, 6), 2)]


def test_shipped_model_has_a_threshold_per_output_and_never_saw_the_test_kit() -> None:
    model = load_model()
    clf = model.live
    assert clf.thresholds.shape == (clf.weights[-1].shape[1],)
    assert clf.weights[-1].shape[1] == N_CLASSES + int(clf.has_onset_output)
    assert model.offline.thresholds.shape == (N_CLASSES + 1,)
    assert "The Black Pearl 1.0" not in model.meta["trained_on"]
    assert "The Black Pearl 1.0" not in model.meta.get("live_trained_on", [])
    # the network's thresholds come from a validation kit it was never fitted on (nor the test kit)
    assert not set(model.meta.get("thresholds_from", ())) & {"The Black Pearl 1.0", *model.meta["trained_on"]}


def test_missing_kits_fail_with_an_install_hint(tmp_path: Path) -> None:
    (tmp_path / "Present").mkdir()
    (tmp_path / "Present" / "drumkit.xml").write_text("<drumkit_info/>")
    require_kits(["Present"], root=tmp_path)
    with pytest.raises(KitsMissingError, match="apt-get install hydrogen-drumkits") as err:
        require_kits(["Present", "Absent Kit"], root=tmp_path)
    assert "Absent Kit" in str(err.value) and "Present," not in str(err.value)
    assert "(installed there: Present)" in str(err.value)  # a misspelt kit name shows beside the real ones


def test_thresholds_and_peak_window_are_chosen_on_validation_frames_of_5_ms() -> None:
    from services.recogniser import features as F
    from services.recogniser.framenet import N_OUT, FrameNet
    from services.recogniser.training.frames import FrameSet
    from services.recogniser.training.tune import choose

    hop, n = F.HOP // 2, 1000  # 5 s of 5 ms frames
    fps = F.SAMPLE_RATE / hop
    times = np.arange(0.5, 4.6, 0.25)  # snares every 250 ms
    hits = np.array([[0, t, 1, 100] for t in times], np.float64)
    val = FrameSet(np.zeros((n, F.N_BANDS, 1), np.float16), np.array([0, n]), hits, (F.N_FFT,), hop)
    out = np.zeros((n, N_OUT), np.float32)
    for k, t in enumerate(times):  # loud strikes peak twice 10 ms apart, soft ones once: with +-1 frame no
        f = round(t * fps)        # threshold takes every strike once; with +-2 frames any up to 0.5 does
        out[f : f + 3, 1] = (0.9, 0.3, 0.85) if k % 2 else (0.5, 0.2, 0.0)
    net = FrameNet([], np.full(N_CLASSES + 1, 0.5, np.float32), hop=hop)
    choose(net, val, outs=[out], rules=True)
    assert net.peak_frames == 2 and net.thresholds[1] <= 0.5
    assert net.snap_frames in range(0, 7)  # 0-30 ms of 5 ms frames
