"""``batteur rig``: services as separate processes finding each other by zeroconf, same impacts as offline.

Runs inside a network namespace the test creates (zeroconf on its loopback
only). The rig plays the physics strike scene; a stand-in graphics receiver
records the impacts interaction sends; the sound node records a WAV.
"""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur.strike import run_strikes
from tests.netns import NetnsLab, require_netns
from tests.test_first_strike import onset_times

PERIOD_S = 0.5
SPEED = 3.0
N_STRIKES = 4
LATENCY_S = 0.05  # the nodes' default latency window
BLOCK = 256


@pytest.mark.netns
@pytest.mark.slow
def test_rig_plays_the_same_impacts_as_offline_and_stops_within_5_s(tmp_path: Path) -> None:
    require_netns()
    with NetnsLab() as lab:
        ns = lab.namespace("rig")
        listener = ns.python("-m", "tests.impact_listener", "--port", "9450")
        listener.expect(lambda e: e["event"] == "ready", timeout=20)
        rig = ns.python(
            "-m", "batteur", "rig", "--services", "physics,interaction,sound", "--no-static-peers",
            "--interfaces", "127.0.0.1", "--base-port", "9401", "--start-delay", "8",
            "--strike-period", str(PERIOD_S), "--strike-velocity", str(SPEED), "--record", str(tmp_path),
            "--interaction-arg", "--peer graphics=127.0.0.1:9450",
        )
        impacts = []
        try:
            for _ in range(N_STRIKES):
                impacts.append(listener.expect(lambda e: e["event"] == "impact", timeout=40))
        except AssertionError as exc:
            rig.stop()
            raise AssertionError(f"{exc}\nrig output:\n" + "\n".join(rig.lines[-60:])) from None
        time.sleep(0.5)  # let sound render the last strike (latency window + a few blocks)
        started = time.monotonic()
        rig.signal(signal.SIGINT)
        code = rig.wait(timeout=10)
        stop_s = time.monotonic() - started
        listener.stop()
    assert code == 0, "\n".join(rig.lines[-40:])
    assert stop_s < 5.0

    offline = run_strikes([(PERIOD_S * (k + 1), SPEED) for k in range(N_STRIKES)], tail_s=0.1).impacts
    assert [i["instrument"] for i in impacts] == [i.instrument for i in offline]
    for live, off in zip(impacts, offline, strict=True):
        assert live["time"] == pytest.approx(off.time, abs=1e-4)
        assert live["velocity"] == pytest.approx(off.velocity, rel=1e-3)
        assert live["r"] == pytest.approx(off.r, abs=1e-4)

    # the strikes are heard: one onset per impact at its time + latency, within one audio block
    audio, sample_rate = sf.read(tmp_path / "performance.wav")
    origin = json.loads((tmp_path / "performance.wav.json").read_text())["origin_rig_time_s"]
    mono = np.mean(audio, axis=1) if audio.ndim > 1 else audio
    heard = [origin + t for t in onset_times(mono, sample_rate)]
    assert len(heard) >= N_STRIKES
    for onset, impact in zip(heard, impacts, strict=False):
        assert abs(onset - (impact["time"] + LATENCY_S)) <= BLOCK / sample_rate
