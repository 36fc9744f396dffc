"""``batteur rig --score``: the drummer plays a two-bar groove live, as separate processes, with sound.

Runs inside a network namespace the test creates (zeroconf on its loopback
only). The rig starts physics (``--score FILE --play-at``), interaction and
sound; a stand-in graphics receiver records the impacts interaction sends.
The drummer's physics runs at about real time on a loaded machine, so the
live node may skip steps: timing tolerances are generous (this checks that
the score is played live, not the accuracy the offline render measures).
"""

from __future__ import annotations

import json
import re
import signal
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from common.score.text import read_score
from tests.netns import NetnsLab, require_netns

SCORE = Path(__file__).parent / "render" / "short_groove.txt"
PLAY_AT_S = 1.0
START_DELAY_S = 8.0
"""Rig time 0 comes this long after launch (the drummer scene takes seconds to build on a loaded machine)."""
TOLERANCE_S = 0.08
"""A note counts as played when an impact on its instrument comes within this of its rig time, seconds."""
INSTRUMENT = {"HIHATCLOSED": "hihat", "SNARE": "snare", "BASS": "kick"}


@pytest.mark.netns
@pytest.mark.slow
def test_rig_plays_a_score_live(tmp_path: Path) -> None:
    require_netns()
    score = read_score(SCORE)
    end = PLAY_AT_S + max(e.time for e in score.events)
    with NetnsLab() as lab:
        ns = lab.namespace("rigscore")
        listener = ns.python("-m", "tests.impact_listener", "--port", "9550")
        listener.expect(lambda e: e["event"] == "ready", timeout=20)
        launched = time.monotonic()
        rig = ns.python(
            "-m", "batteur", "rig", "--services", "physics,interaction,sound", "--interfaces", "127.0.0.1",
            "--base-port", "9501", "--start-delay", str(START_DELAY_S), "--score", str(SCORE),
            "--play-at", str(PLAY_AT_S), "--record", str(tmp_path), "--physics-arg", "--pose-rate-hz 0",
            "--interaction-arg", "--peer graphics=127.0.0.1:9550",
        )
        impacts: list[dict[str, object]] = []
        # rig time t is about launched + START_DELAY_S + t on this clock, later when the machine is loaded (and a
        # physics node ready after --play-at starts the score late): stop 1.5 s after the last impact once there
        # are as many impacts as notes, else at a deadline that leaves room for a late start
        deadline = launched + START_DELAY_S + end + 8.0
        while (remaining := deadline - time.monotonic()) > 0:
            quiet = 1.5 if len(impacts) >= len(score.events) else remaining
            try:
                impacts.append(listener.expect(lambda e: e["event"] == "impact", timeout=min(remaining, quiet)))
            except AssertionError:
                if len(impacts) >= len(score.events):
                    break
        time.sleep(0.5)
        rig.signal(signal.SIGINT)
        code = rig.wait(timeout=10)
        rig.stop()  # joins the output readers
        rig.events()  # every line read so far into rig.lines
        listener.stop()
    output = "\n".join(rig.lines[-80:] + rig.errors[-20:])
    logged = rig.lines + rig.errors  # the services' logs are on the rig's stderr, what they print on its stdout
    assert code == 0, output
    assert any("the drummer plays" in line for line in logged), output
    # the physics node's score player says where the score starts: at --play-at, or later (with a warning)
    # when the node was ready only after it
    started = [m for line in logged if (m := re.search(r"playing short_groove.txt from ([\d.]+) s at rig time "
                                                            r"([\d.]+) s", line))]
    assert started, output
    position, start = float(started[0].group(1)), float(started[0].group(2))
    assert position == 0.0 and start >= PLAY_AT_S - 1e-3, started[0].group(0)
    # a later start is said: the play time already past, or too close to prepare the first note (physics up late:
    # since 7 Dec it says it is up only once its planning process has loaded, seconds on a loaded core)
    assert start == pytest.approx(PLAY_AT_S, abs=1e-3) or any(
        "already past" in line or "too close to prepare its first note" in line for line in logged), output
    notes = [(start + e.time, INSTRUMENT[e.event.value]) for e in score.events]
    played = [(float(i["time"]), str(i["instrument"])) for i in impacts]  # type: ignore[arg-type]
    errors = []
    for t, instrument in notes:
        near = [abs(p - t) for p, inst in played if inst == instrument and abs(p - t) <= TOLERANCE_S]
        if near:
            errors.append(min(near))
    skipped = [int(m.group(1)) for line in logged if (m := re.search(r"\d+ skipped, (\d+) in all", line))]
    print(json.dumps({"notes": len(notes), "matched": len(errors), "impacts": len(played), "start_rig_s": start,
                      "physics_steps_skipped": max(skipped, default=0),
                      "median_abs_error_ms": round(1000 * sorted(errors)[len(errors) // 2], 2) if errors else None,
                      "max_abs_error_ms": round(1000 * max(errors), 2) if errors else None}))
    # most notes are heard on their instrument near their time (the live physics skips steps when it falls
    # behind the rig clock, and then the sticks jump: on a loaded machine some notes are lost; one run with the
    # machine's 2 cores loaded 6-7 deep matched 6 to 13 of the 13 notes, unloaded all 13)
    assert len(errors) >= 0.5 * len(notes), f"{len(errors)}/{len(notes)} notes played; impacts {played}\n{output}"
    assert len({inst for _, inst in played} & {"hihat", "snare", "kick"}) >= 2, played
    audio, _ = sf.read(tmp_path / "performance.wav")
    assert float(np.max(np.abs(audio))) > 0.01  # and heard
