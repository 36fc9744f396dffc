"""Pd users striking the sound service directly: ``[batteur-clock]`` keeps the rig time from clock pings and
``[batteur-strike]`` stamps each impact with it, so the sound service plays every strike on schedule (none late),
where a strike stamped ``0 0`` ("now") always arrives after its time and is counted late."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.config import load_settings
from common.core import Outgoing
from common.messages import Impact, OscMessage
from common.runtime import Node
from tests.deploy.pdrun import PD_DIR, PdProcess, require_pd
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

STRIKES = 8
WINDOW_S = 0.2
"""The sound core's latency window in these tests, seconds."""


class TimedSound:
    """A real stepping sound core (no pyo) that notes the rig time each impact arrived at."""

    ROLE = "sound"

    def __init__(self) -> None:
        from services.sound.core import SoundCore, SoundSettings

        # a wide window: a test process stalled for tens of ms (a busy CI machine) makes no strike late
        self.core = SoundCore(SoundSettings(use_pyo=False, latency=WINDOW_S, origin=None))  # as the node starts it
        self.rate_hz = self.core.rate_hz
        self.arrivals: list[tuple[Impact, float]] = []

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Impact):
            self.arrivals.append((message, now))
        out: list[Outgoing] = self.core.handle(message, now, source)
        return out

    def step(self, now: float) -> list[Outgoing]:
        out: list[Outgoing] = self.core.step(now)
        return out

    def __getattr__(self, name: str) -> Any:  # health figures and hooks the node asks the core for
        return getattr(self.core, name)


def strike_patch(folder: Path, port: int, latency_ms: float) -> Path:
    """A user's patch: a clock following the sound node, and STRIKES snare strikes 0.1 s apart once it has had
    time to sync (the clock pings at load, then every 0.5 s)."""
    patch = folder / "strikes.pd"
    patch.write_text(f"""#N canvas 0 0 600 400 12;
#X obj 10 10 batteur-clock 127.0.0.1 {port};
#X obj 10 40 print batteur-test-rtt;
#X obj 200 10 loadbang;
#X obj 200 40 delay 1200;
#X obj 200 70 metro 100;
#X obj 200 100 f;
#X obj 240 100 + 1;
#X obj 200 130 moses {STRIKES};
#X msg 200 160 snare 3 0.3;
#X obj 200 190 batteur-strike {latency_ms:g};
#X msg 300 160 stop;
#X obj 10 70 r batteur-clock-send;
#X obj 10 100 print batteur-test-sent;
#X connect 0 1 1 0;
#X connect 2 0 3 0;
#X connect 3 0 4 0;
#X connect 4 0 5 0;
#X connect 5 0 6 0;
#X connect 6 0 5 1;
#X connect 5 0 7 0;
#X connect 7 0 8 0;
#X connect 8 0 9 0;
#X connect 7 1 10 0;
#X connect 10 0 4 0;
""")
    return patch


@pytest.mark.parametrize(("latency_ms", "rig_age_s"), [(0.0, 0.0), (30.0, 0.0), (0.0, 2 * 86400.0)])
def test_strikes_through_the_abstraction_play_on_schedule(tmp_path: Path, latency_ms: float,
                                                          rig_age_s: float) -> None:
    """Strikes on schedule, stamped ``latency_ms`` ahead; also on a rig two days old (``rig_age_s``), where one
    32-bit float resolves 15.6 ms of rig time: the abstractions keep whole seconds and the fraction apart."""
    require_pd()
    sound = TimedSound()

    async def main() -> PdProcess:
        node = Node(sound, load_settings({"role": "sound", "discovery": False,  # type: ignore[arg-type]
                                          "clock_master": "self", "oscquery": False,
                                          "epoch": time.time() - rig_age_s}))
        await node.start()
        try:
            assert node.endpoint is not None
            pd = PdProcess(strike_patch(tmp_path, node.endpoint.port, latency_ms), extra=["-path", str(PD_DIR)])
            try:
                await wait_for(lambda: len(sound.arrivals) >= STRIKES, timeout=20)
                await asyncio.sleep(0.3)  # past every strike's time + latency: all rendered
            finally:
                pd.stop()
        finally:
            await node.stop()
        return pd

    pd = asyncio.run(main())
    assert pd.errors() == [], "\n".join(pd.lines)
    assert pd.printed("batteur-test-rtt"), "the clock never used a pong:\n" + "\n".join(pd.lines)
    impacts = [impact for impact, _ in sound.arrivals]
    assert [i.instrument for i in impacts] == ["snare"] * STRIKES
    assert len({i.seq for i in impacts}) == STRIKES  # numbered: none taken for a copy of another
    # stamped with the rig time it was struck at (+ the chosen latency): each arrives after that moment (a
    # loopback datagram takes well under 10 ms; a stall of the test process only delays arrivals, so the
    # quickest is the clock's error), never stamped for later than struck + latency
    delays = [arrived - (impact.time - latency_ms / 1e3) for impact, arrived in sound.arrivals]
    assert -0.005 < min(delays) < 0.02, delays
    assert sound.core.stats.strikes == STRIKES
    assert sound.core.late == 0, sound.core.scheduler.lateness
    # the strikes sit 0.1 s apart on the rig clock, as Pd's metro struck them
    gaps = [b.time - a.time for a, b in zip(impacts, impacts[1:], strict=False)]
    # (within a re-sync's step: each pong used may move the offset by a few ms on a busy machine)
    assert all(g == pytest.approx(0.1, abs=0.01) for g in gaps), gaps
    if rig_age_s:
        # finer than one 32-bit float: at 2 days one resolves 1/64 s, and every stamp would be a float32
        assert any(float(np.float32(i.time)) != i.time for i in impacts), [i.time for i in impacts]
