"""Offline transcription: a rendered pattern gives the right notes; files in other formats agree."""

from __future__ import annotations

from pathlib import Path

import mir_eval
import numpy as np
import soundfile as sf
from scipy.signal import resample_poly

from services.recogniser.audio import load_audio
from services.recogniser.transcribe import transcribe, transcribe_file

from .pattern import RATE, Pattern, load_sample


def _times(events, *names: str) -> np.ndarray:
    return np.array(sorted(e.time for e in events if e.name in names))


def _f(ref: np.ndarray, est: np.ndarray, window: float = 0.05) -> float:
    return float(mir_eval.onset.f_measure(ref, est, window=window)[0]) if len(ref) and len(est) else 0.0


def test_pattern_transcribes_to_the_right_notes(pattern: Pattern) -> None:
    events = transcribe(pattern.audio, sample_rate=pattern.sample_rate)
    # the kit is one the model never saw; the shipped model (recipe 7) gets 0.92 / 0.94 / 0.98 here (the
    # kick: the one at 8.9 s is heard twice, 10 ms apart; recipe 6: 0.96)
    for name in ("kick", "snare", "hihat_closed"):
        f = _f(pattern.times(name), _times(events, name))
        assert f >= 0.8, f"{name}: F = {f:.2f}"
    # the tom fill: its four strikes found on toms (a strike heard as two toms at once is one strike on
    # toms); the open hi-hat found as open
    toms = np.concatenate([pattern.times("tom_high"), pattern.times("tom_floor")])
    assert _f(np.sort(toms), np.unique(_times(events, "tom_high", "tom_mid", "tom_floor"))) == 1.0
    # the open hi-hat is found as open; the shipped networks since recipe 5 (open hi-hats found more often, heard
    # more often where cymbals ring) also hear as open closed hi-hats struck with the opening crash and in its
    # ring (recipe 7: 0.2 s; recipe 6: 0.2, 0.5 s; recipe 5: these and 7.4 s, after the open hi-hat): at most
    # three more
    opened = _times(events, "hihat_open")
    assert len(mir_eval.util.match_events(pattern.times("hihat_open"), opened, 0.05)) == 1 and len(opened) <= 4
    # almost nothing is invented: every recognised time but three is near a played note (the shipped model,
    # recipe 7, like recipe 6, hears a soft closed hi-hat where the file's noise floor starts, at 0 s, a ride in
    # the open hi-hat's ring, 7.21 s, and a soft snare 0.16 s after a closed hi-hat, 1.26 s; recipe 5 made the
    # first two)
    played = np.array([t for t, _, _ in pattern.notes])
    assert sum(np.min(np.abs(played - e.time)) >= 0.05 for e in events) <= 3


def test_onset_times_are_accurate(pattern: Pattern) -> None:
    events = transcribe(pattern.audio, sample_rate=pattern.sample_rate)
    # every kick and snare found (within 50 ms) is within 20 ms of its note; all are found but at most one
    # kick (the kick at 8.9 s, velocity 95 under a high tom at 110: recipe 4 missed it, recipes 5 to 7 find it)
    for name, missed in (("kick", 1), ("snare", 0)):
        ref = pattern.times(name)
        est = _times(events, name)
        found = mir_eval.util.match_events(ref, est, 0.05)
        assert len(found) >= len(ref) - missed, f"{name}: {len(found)} of {len(ref)} found"
        assert all(abs(ref[i] - est[j]) < 0.02 for i, j in found), f"{name} not within 20 ms"


def test_velocity_follows_loudness() -> None:
    kick = load_sample("kick")
    audio = np.zeros(int(6 * RATE), np.float32)
    velocities = [120, 40, 120, 40, 120, 40, 120, 40]
    for i, v in enumerate(velocities):
        start = int((0.2 + 0.6 * i) * RATE)
        audio[start : start + len(kick)] += kick * (v / 127) ** 1.6
    events = [e for e in transcribe(audio * 0.9 / np.max(np.abs(audio)), sample_rate=RATE) if e.name == "kick"]
    assert len(events) == 8
    loud = [e.velocity for e in events[0::2]]
    soft = [e.velocity for e in events[1::2]]
    assert min(loud) > max(soft)


def test_other_rates_and_stereo_give_the_same_notes(tmp_path: Path, pattern: Pattern) -> None:
    mono = tmp_path / "mono.wav"
    sf.write(mono, pattern.audio, pattern.sample_rate)
    stereo48 = tmp_path / "stereo48.flac"
    up = resample_poly(pattern.audio, 160, 147).astype(np.float32)  # 44,100 -> 48,000 Hz
    sf.write(stereo48, np.stack([up, up * 0.8], axis=1), 48000)
    a, dur_a = transcribe_file(mono)
    b, dur_b = transcribe_file(stereo48)
    assert abs(dur_a - dur_b) < 0.01
    assert abs(len(load_audio(stereo48)) - len(load_audio(mono))) <= 1
    ref = _times(a, "kick", "snare")
    assert _f(ref, _times(b, "kick", "snare"), window=0.02) >= 0.95
