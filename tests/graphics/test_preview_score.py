"""`batteur graphics --preview-score`: a score planned (keyframe or gesture planner) and shown, no physics.

Through ``services.graphics.preview.score_preview`` (what the node calls), the node's re-planner, and the
node as a subprocess on loopback (the page's WebSocket sees the preview's strikes; a bad score exits 2).
"""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from websockets.asyncio.client import connect

from common.gesture.keyframe import DELTA
from common.gesture.keyposes import KeyPose, KeyPoses
from common.kit import EventType, Kit, Limb, load_kit
from common.messages.graphics import GraphicsMode
from common.score.events import ScoreError
from common.score.text import read_score
from services.graphics.core import GraphicsCore
from services.graphics.figure import LINK_NAMES
from services.graphics.node import GraphicsNodeSettings, _watch_preview, make_core
from services.graphics.preview import score_preview
from tests.graphics.conftest import ROOT, GraphicsNodeProcess

KIT = load_kit()
BAR = """# one bar of rock: hi-hat eighths, snare on 2 and 4 (accented), kick on 1 and 3
tempo 120
meter 4/4
HH |xxxxxxxx|
SN |..X...X.|
BD |x...x...|
"""
LIFT = np.array([0.05, -0.12, 0.25])
"""The saved UP pose's stick tip: back toward the drummer and up from the DOWN pose (not the head's normal)."""


@pytest.fixture
def bar(tmp_path: Path) -> Path:
    path = tmp_path / "bar.txt"
    path.write_text(BAR, encoding="utf-8")
    return path


def _expected(path: Path) -> set[tuple[str, float]]:
    """(kit object, note time) of every note of the score."""
    return {(KIT.object_for(e.event).id, round(e.time, 3)) for e in read_score(path).events}


def _effector(limb: Limb) -> str:
    return f"{limb.value.split('_')[0]}_{'stick_tip' if 'hand' in limb.value else 'toe'}"


def _save_snare_poses(path: Path, limb: Limb) -> None:
    down = np.array([0.0, 0.4, 0.7])
    KeyPoses(poses={
        f"SNARE.{limb.value}.DOWN": KeyPose(effectors={limb: tuple(down)}),  # type: ignore[dict-item]
        f"SNARE.{limb.value}.UP": KeyPose(effectors={limb: tuple(down + LIFT)}),  # type: ignore[dict-item]
    }).save(path)


@pytest.mark.parametrize("planner", ["keyframe", "gestures"])
def test_contacts_at_the_note_times_on_the_right_instruments(bar: Path, planner: str) -> None:
    preview = score_preview(bar, KIT, planner)  # type: ignore[arg-type]
    assert preview.sequence.names == LINK_NAMES
    assert len(preview.impacts) == 12
    assert {(i.instrument, round(i.time, 3)) for i in preview.impacts} == _expected(bar)
    assert preview.sequence.times[0] == pytest.approx(-1.0) and preview.sequence.times[-1] >= 1.75
    for s in preview.plan.strokes:  # the stick tip (ball of the foot) is on the instrument's hit point then
        tip = preview.sequence.sample(s.time)[LINK_NAMES.index(_effector(s.limb)), :3]
        target = np.array(KIT.effector_target(s.event, s.limb)[0])
        assert np.linalg.norm(tip - target) < 0.01, (s.event, s.limb, s.time)
    # the view shows them: the snare flashes just after its first note, not before
    core = GraphicsCore(kit=KIT)
    core.load_preview(preview.sequence, preview.impacts, now=0.0)
    snare = [o.id for o in KIT.objects].index("snare")
    start = preview.sequence.times[0]
    for t, lit in ((0.45, False), (0.52, True)):
        frame = core.frame_at(t - start)
        assert frame is not None and bool(frame.kit[snare, 0] > 0.3) is lit, t
        assert ("snare" in [h[4] for h in frame.hits]) is lit


def test_saved_up_down_poses_change_the_keyframe_motion(bar: Path, tmp_path: Path) -> None:
    base = score_preview(bar, KIT, "keyframe", poses=tmp_path / "poses.yaml")  # no file yet: built-in strokes
    assert base.poses is None
    snares = [s for s in base.plan.strokes if s.event == EventType.SNARE]
    limb = snares[0].limb
    _save_snare_poses(tmp_path / "poses.yaml", limb)
    shaped = score_preview(bar, KIT, "keyframe", poses=tmp_path / "poses.yaml")
    assert shaped.poses == tmp_path / "poses.yaml" and "UP/DOWN poses" in shaped.summary()
    tip = LINK_NAMES.index(_effector(limb))
    target = np.array(KIT.effector_target(EventType.SNARE, limb)[0])
    for s in snares:  # accented notes: the before frame is the UP pose's lift itself
        before = shaped.sequence.sample(s.time - DELTA)[tip, :3]
        assert np.linalg.norm(before - (target + LIFT)) < 0.005
        assert np.linalg.norm(before - base.sequence.sample(s.time - DELTA)[tip, :3]) > 0.05
        assert np.linalg.norm(shaped.sequence.sample(s.time)[tip, :3] - target) < 0.01  # still hits the snare
    assert [(i.instrument, i.time) for i in shaped.impacts] == [(i.instrument, i.time) for i in base.impacts]
    # the gesture planner does not read key poses
    assert score_preview(bar, KIT, "gestures", poses=tmp_path / "poses.yaml").poses is None
    (tmp_path / "poses.yaml").write_text("SNARE.left_hand.UP: {joints: {no_such_joint: [1, 2, 3]}}\n")
    with pytest.raises(ScoreError, match="poses.yaml: not a valid poses file"):
        score_preview(bar, KIT, "keyframe", poses=tmp_path / "poses.yaml")


def test_the_node_logs_the_score_readers_warnings(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """What the reader warns of (a hand given to a foot's note) is logged once, as `batteur render` prints it
    (until 7 Dec the preview said nothing of it)."""
    path = tmp_path / "feet.txt"
    path.write_text("tempo 120\nmeter 4/4\nSN |x.x.|\nat 1.5 BD 0.8 R\n", encoding="utf-8")
    with caplog.at_level("WARNING", logger="batteur.graphics"):
        make_core(GraphicsNodeSettings(preview_score=str(path)), SimpleNamespace())  # type: ignore[arg-type]
    said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert said == [f"preview: {path}: line 4: BD is played by a foot; the hand R is ignored"]


def test_bad_scores_are_clear_errors(tmp_path: Path) -> None:
    (tmp_path / "broken.mid").write_bytes(b"MThd\x00\x00\x00\x06\x00")
    (tmp_path / "rests.txt").write_text("tempo 120\nSN |....|\n")
    (tmp_path / "typo.txt").write_text("tempo 120\nXQ |x...|\n")
    for name, why in (("missing.txt", "no such file"), ("broken.mid", "MIDI"), ("rests.txt", "no drum events"),
                      ("typo.txt", "line 2")):
        with pytest.raises(ScoreError, match=why) as err:
            score_preview(tmp_path / name, KIT)
        assert name in str(err.value)
    with pytest.raises(ScoreError, match="planner"):
        score_preview(tmp_path / "rests.txt", KIT, "physics")  # type: ignore[arg-type]


def test_the_node_replans_when_the_editor_saves_a_pose(bar: Path, tmp_path: Path) -> None:
    kits = tmp_path / "kits"
    kits.mkdir()
    settings = GraphicsNodeSettings(preview_score=str(bar), kit_dir=str(kits))
    core = make_core(settings, SimpleNamespace())  # type: ignore[arg-type]
    first = core.preview
    assert core.mode == "preview" and first is not None and len(core.preview_impacts) == 12
    core.apply_control(GraphicsMode(mode="live"))
    node = SimpleNamespace(clock=SimpleNamespace(now=lambda: 5.0))

    async def main() -> None:
        task = asyncio.create_task(_watch_preview(node, core, settings, period=0.05))  # type: ignore[arg-type]
        try:
            await asyncio.sleep(0.2)
            assert core.preview is first  # nothing changed, nothing re-planned
            _save_snare_poses(kits / "poses.yaml", Limb.LEFT_HAND)
            for _ in range(200):
                await asyncio.sleep(0.05)
                if core.counters.get("preview_replans"):
                    break
            assert core.counters.get("preview_replans") == 1 and core.preview is not first
            assert core.mode == "live"  # the view stays where the user put it
            # the editor saves a kit with the snare moved 5 cm to the right: the sticks follow it
            data = KIT.model_dump(mode="json")
            snare = next(o for o in data["objects"] if o["id"] == "snare")
            snare["position"][0] += 0.05
            moved = Kit.model_validate(data)
            core.set_kit(moved)
            for _ in range(200):
                await asyncio.sleep(0.05)
                if core.counters.get("preview_replans") == 2:
                    break
            assert core.counters.get("preview_replans") == 2 and core.preview is not None
            hit = next(i for i in core.preview_impacts if i.instrument == "snare")
            tip = core.preview.sample(hit.time)[LINK_NAMES.index("left_stick_tip"), :3]
            assert np.linalg.norm(tip - np.array(moved.effector_target(EventType.SNARE, Limb.LEFT_HAND)[0])) < 0.01
            assert np.linalg.norm(tip - np.array(KIT.effector_target(EventType.SNARE, Limb.LEFT_HAND)[0])) > 0.04
            (kits / "poses.yaml").write_text("not: [valid")  # a broken hand edit: logged, old preview kept
            shown = core.preview
            for _ in range(200):
                await asyncio.sleep(0.05)
                if core.counters.get("preview_errors"):
                    break
            assert core.counters.get("preview_errors") == 1 and core.preview is shown
            assert not task.done()
        finally:
            task.cancel()

    asyncio.run(main())
    assert core.preview is not None
    assert not np.array_equal(core.preview.values, first.values)


async def _frames(url: str, seconds: float) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(welcome messages, frames) a page receives over ``seconds``."""
    welcome: list[dict[str, Any]] = []
    frames: list[dict[str, Any]] = []
    async with connect(url) as ws:
        loop = asyncio.get_running_loop()
        end = loop.time() + seconds
        while loop.time() < end:
            message = json.loads(await asyncio.wait_for(ws.recv(), 5))
            (frames if message["type"] == "frame" else welcome).append(message)
    return welcome, frames


def test_node_shows_the_score_and_flashes_its_strikes(bar: Path, tmp_path: Path) -> None:
    # its own clock master: no 3 s wait for physics' clock before the core starts
    node = GraphicsNodeProcess(tmp_path, latency=0.0, extra=["--preview-score", str(bar), "--clock-master", "self"])
    node.start()
    try:
        # one loop: 3.75 s of score (1 s before the first note to 1 s after the last) + 0.5 s pause
        welcome, frames = asyncio.run(_frames(f"ws://127.0.0.1:{node.http_port}/ws", 5.0))
    finally:
        node.close()
    kinds = {m["type"]: m for m in welcome}
    assert kinds["view"]["mode"] == "preview" and kinds["skeleton"]["names"] == LINK_NAMES
    seen = {(h[4], round(f["t"] - h[3], 2)) for f in frames for h in f["h"]}
    assert seen == {(obj, round(t, 2)) for obj, t in _expected(bar)}
    snare = [o.id for o in KIT.objects].index("snare")
    flashed = [f for f in frames if any(h[4] == "snare" and h[3] < 0.05 for h in f["h"])]
    assert flashed and all(f["k"][4 * snare] > 0.3 for f in flashed)
    assert "preview of" in (tmp_path / "graphics-node.log").read_text()


def test_cli_bad_score_exits_with_a_clear_error(tmp_path: Path) -> None:
    """A file it cannot use is 1, a setting refused 2 (README, "Exit status")."""
    (tmp_path / "broken.mid").write_bytes(b"MThd\x00\x00\x00\x06\x00")
    cases = [
        (["--preview-score", str(tmp_path / "missing.txt")], "missing.txt: no such file", 1),
        (["--preview-score", str(tmp_path / "broken.mid")], "broken.mid", 1),
        (["--preview-score", str(tmp_path / "broken.mid"), "--preview-planner", "physics"], "preview_planner", 2),
        (["--preview", str(tmp_path / "broken.mid")], "not a pose sequence file (not an .npz archive)", 1),
        (["--kit-dir", str(tmp_path / "broken.mid")], "--kit-dir", 1),
        (["--kit-dir", str(tmp_path / "broken.mid" / "kits")], "broken.mid is a file, not a directory", 1),
    ]
    for extra, message, status in cases:
        result = subprocess.run(
            [sys.executable, "-m", "services.graphics.node", "--no-discovery", "--host", "127.0.0.1", "--port", "0",
             "--http-port", "0", *extra], cwd=ROOT, capture_output=True, text=True, timeout=60)
        assert result.returncode == status, result.stderr
        assert result.stderr.startswith("batteur graphics: error: ") and message in result.stderr, result.stderr
        assert "Traceback" not in result.stderr
