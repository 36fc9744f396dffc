"""The Pd sound client is a static peer of interaction: it gets Health and, from a node whose clock master is
another node, /batteur/clock/status at 1 Hz. It must ignore both (no error, no 'batteur-bad'), and play on."""

from __future__ import annotations

from pathlib import Path

from common.messages import ClockStatus, Health, encode
from tests.deploy.pdrun import require_pd
from tests.deploy.test_pd_qa import sound_client


def test_the_sound_client_ignores_health_and_clock_status(tmp_path: Path) -> None:
    require_pd()
    status = ClockStatus(node_id="interaction-1", synced=1, offset_s=0.0123, uncertainty_s=0.0001,
                         round_trip_s=0.0004, samples=32, rejected=0, outliers=0, steps=0, foreign_pongs=0,
                         master="physics-1")
    health = Health(node_id="interaction-1", role="interaction", protocol=1, time=12.5, rate_hz=0.0,
                    target_rate_hz=0.0, overruns=0, messages_in=10, messages_out=20, dropped=0, dropped_malformed=0,
                    dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=2)
    with sound_client(tmp_path) as client:
        for _ in range(3):
            client.send(encode(health))
            client.send(encode(status))
        client.sync()  # a marker impact, played after everything sent before it
        assert client.bad() == []
        assert client.pd.errors() == [], "\n".join(client.pd.lines)
