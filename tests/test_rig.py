"""``batteur rig``: services as separate processes finding each other by zeroconf, same impacts as offline.

Runs inside a network namespace the test creates (zeroconf on its loopback
only). The rig plays the physics strike scene; a stand-in graphics receiver
records the impacts interaction sends; the sound node records a WAV.
"""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest

from batteur.strike import run_strikes
from tests.netns import NetnsLab, require_netns

PERIOD_S = 0.5
SPEED = 3.0
N_STRIKES = 4


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
            "--interfaces", "127.0.0.1", "--base-port", "9401", "--start-delay", "4",
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
    assert (tmp_path / "performance.wav").stat().st_size > 0
