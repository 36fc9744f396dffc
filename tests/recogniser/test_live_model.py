"""Live mode: the streaming core matches the offline onsets, hits come within 50 ms and go out over OSC."""

from __future__ import annotations

import asyncio
from pathlib import Path

import mir_eval
import numpy as np

from common.messages.recogniser import DrumHit
from common.transport import UdpEndpoint
from services.recogniser import features as F
from services.recogniser.audio import SAMPLE_RATE, resample
from services.recogniser.core import LiveRecogniser
from services.recogniser.model import MODEL_PATH, load_model
from services.recogniser.node import play_file
from services.recogniser.transcribe import PEAK

from .pattern import Pattern


def test_shipped_model_is_small_and_plain_arrays() -> None:
    assert MODEL_PATH.stat().st_size < 2_000_000
    with np.load(MODEL_PATH, allow_pickle=False) as z:  # no pickled objects inside
        assert all(z[k].dtype != object for k in z.files)
    model = load_model()
    assert model.live.n_features == F.n_features(model.live.offsets)
    assert "The Black Pearl 1.0" not in model.meta["trained_on"]


def test_streaming_core_finds_the_offline_onsets(pattern: Pattern) -> None:
    model = load_model()
    core = LiveRecogniser(model, gain=1.0)
    emitted: list[tuple[int, DrumHit]] = []
    fed = 0
    audio = resample(pattern.audio, pattern.sample_rate, SAMPLE_RATE)  # the live path's rate
    for start in range(0, len(audio), 128):
        block = audio[start : start + 128]
        fed += len(block)
        emitted += [(fed, o.message) for o in core.feed(block)]  # type: ignore[misc]
    emitted += [(fed, o.message) for o in core.flush()]  # type: ignore[misc]
    spec = F.band_spectrogram(audio * (PEAK / float(np.max(np.abs(audio)))))
    offline = F.pick_onsets(F.superflux(spec), model.live.delta)
    assert core.onsets == offline.tolist()
    # every hit is known within 50 ms of audio after its onset (plus one 128-sample block)
    lat = [n / SAMPLE_RATE - h.time for n, h in emitted[:-3]]
    assert max(lat) <= 0.050 + 128 / SAMPLE_RATE
    assert core.latency_s <= 0.040
    kicks = np.array([h.time for _, h in emitted if h.note == 36])
    f_kick = mir_eval.onset.f_measure(pattern.times("kick"), kicks, window=0.05)[0]
    assert f_kick >= 0.75, f_kick  # the short-context live classifier is weaker than the offline one


def test_live_file_playback_sends_osc(pattern_wav: Path) -> None:
    async def run() -> tuple[list[DrumHit], int]:
        received: list[DrumHit] = []
        rx = await UdpEndpoint.open(host="127.0.0.1", port=0)
        rx.set_handler(lambda m, s: received.append(m) if isinstance(m, DrumHit) else None)
        try:
            report = await play_file(pattern_wav, [rx.local_address], speed=8.0)
            await asyncio.sleep(0.2)
        finally:
            rx.close()
        return received, len(report.hits)

    received, sent = asyncio.run(run())
    assert sent > 40 and len(received) == sent
    assert [h.seq for h in received] == sorted(h.seq for h in received)
    assert {36, 38, 42} <= {h.note for h in received}
