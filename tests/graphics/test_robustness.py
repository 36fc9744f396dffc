"""The graphics node under bad or unlucky input: restarted peers, malformed poses, hostile pages, bad options."""

from __future__ import annotations

import argparse
import asyncio
import base64
import json
import logging
import os
import socket
import subprocess
import sys
import threading
import types
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from websockets.asyncio.client import connect

from common.kit import load_kit
from common.messages import Health, Impact, Pose, Skeleton
from common.messages.graphics import GraphicsMode
from services.graphics import node as graphics_node
from services.graphics import server as view_server
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import synthetic_performance
from services.graphics.preview import score_preview
from services.graphics.sequence import PoseSequence
from services.graphics.server import ViewServer
from services.graphics.video import render_video
from tests.graphics.conftest import ROOT, needs_ffmpeg

TINY_SCORE = Path(__file__).parent / "tiny_score.txt"
SNARE = [o.id for o in load_kit("default").objects].index("snare")


def _pose(t: float, z: float, links: int = 1) -> Pose:
    return Pose(time=t, layout=1, values=(0.0, 0.0, z, 0.0, 0.0, 0.0, 1.0) * links)


def _impact(seq: int, t: float) -> Impact:
    return Impact(seq=seq, time=t, instrument="snare", zone="centre", r=0.3, theta=0.0, velocity=3.0,
                  impulse=0.0, peak_force=0.0, duration=0.0, part="right_stick_tip")


# --- OSC: restarted peers ---------------------------------------------------------------------
@pytest.mark.parametrize("clock", ["auto", "rig"])
def test_a_restarted_physics_is_shown_not_hidden_behind_its_old_poses(clock: str) -> None:
    """Physics restarts (its clock begins again at 0, same skeleton): the view follows the new poses."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock=clock))  # type: ignore[arg-type]
    core.handle(Skeleton(layout=1, names=("pelvis",)), 0.0, "physics")
    local = 0.0
    for k in range(120):  # the first run, rig time 100..102 s, pelvis at 1 m
        local = 100 + k / 60
        core.handle(_pose(local, 1.0), local, "physics")
    core.handle(Skeleton(layout=1, names=("pelvis",)), local, "physics")
    for k in range(120):  # the restarted run, rig time 0..2 s, pelvis at 2 m
        local = local + 1 / 60 if clock == "auto" else k / 60
        core.handle(_pose(k / 60, 2.0), local, "physics")
    frame = core.frame_at(local)
    assert frame is not None and frame.pose[0, 2] == 2.0
    assert core.counters["pose_resets"] == 1


def test_a_single_pose_from_the_far_future_does_not_freeze_the_view() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(Skeleton(layout=1, names=("pelvis",)), 0.0, "physics")
    core.handle(_pose(1e9, 1.0), 0.0, "stray")
    for k in range(60):
        core.handle(_pose(k / 60, 2.0), k / 60, "physics")
    frame = core.frame_at(0.5)
    assert frame is not None and frame.pose[0, 2] == 2.0


def test_impacts_of_a_restarted_interaction_node_flash_the_kit() -> None:
    """Same source address, sequence numbers from 0 again, an earlier clock: new strikes, not duplicates."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    for seq in range(3):
        core.handle(_impact(seq, 100.0 + seq), 100.0 + seq, "127.0.0.1:9102")
    core.handle(_impact(0, 1.0), 1.0, "127.0.0.1:9102")
    core.handle(_impact(0, 1.0), 1.0, "127.0.0.1:9102")  # its redundant copy
    assert core.counters["impacts"] == 4 and core.counters["duplicate_impacts"] == 1
    assert core.animator.state(1.05, None)[SNARE, 0] > 0.5


def test_a_stray_impact_from_the_far_future_does_not_stop_the_flashes() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(_impact(0, 1e9), 0.0, "127.0.0.1:5000")
    core.handle(_impact(0, 1.0), 1.0, "127.0.0.1:9102")
    assert core.animator.state(1.05, None)[SNARE, 0] > 0.5


# --- OSC: malformed poses ---------------------------------------------------------------------
def test_zero_quaternions_do_not_stop_the_frames() -> None:
    """A pose with (0, 0, 0, 0) orientations (a broken sender) on the kit links physics publishes."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    names = ("pelvis", "kit.hihat_pedal.footboard", "kit.crash", "kit.hihat.top")
    core.handle(Skeleton(layout=1, names=names), 0.0, "physics")
    core.handle(Pose(time=0.0, layout=1, values=(0.0,) * 7 * len(names)), 0.0, "physics")
    core.take_page_messages()
    core.step(0.5)  # the newest pose is held
    frames = [m for m in core.take_page_messages() if m["type"] == "frame"]
    assert len(frames) == 1
    json.dumps(frames[0], allow_nan=False)


# --- WebSocket: hostile pages -----------------------------------------------------------------
def test_deeply_nested_json_is_an_error_reply_and_counted() -> None:
    server = ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")))
    reply = server.handle_page_message("[" * 100_000)
    assert reply is not None and reply["ok"] is False and "nested" in reply["error"]
    assert server.counters["page_errors"] == 1


def _stalled_client(port: int) -> socket.socket:
    """A WebSocket client that completes the handshake and then never reads (a frozen tab, a slow link)."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                 f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode())
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101")
    return sock


async def _clients(server: ViewServer, count: int) -> None:
    """Wait until ``count`` pages are connected (a bound, so a broken server fails instead of hanging)."""
    async def wait() -> None:
        while len(server.clients) < count:
            await asyncio.sleep(0.01)

    await asyncio.wait_for(wait(), 30)


def test_a_page_that_does_not_read_skips_frames_instead_of_piling_them_up() -> None:
    async def main() -> None:
        core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
        server = ViewServer(core)
        port = await server.start("127.0.0.1", 0)
        stalled = await asyncio.to_thread(_stalled_client, port)
        try:
            async with connect(f"ws://127.0.0.1:{port}/ws") as reader:
                await _clients(server, 2)
                frame = {"type": "frame", "p": [0.1234] * 4000}  # about 40 kB
                for _ in range(400):  # 16 MB for each page
                    server.broadcast([frame])
                    await asyncio.sleep(0)
                server.broadcast([{"type": "status", "last": True}])
                backlogs = [c.transport.get_write_buffer_size() for c in server.clients]
                assert max(backlogs) <= view_server.MAX_BACKLOG + 100_000
                assert server.counters["skipped_frames"] > 0
                while True:  # the page that reads still gets everything that is not a frame
                    message = json.loads(await asyncio.wait_for(reader.recv(), 30))
                    if message["type"] == "status" and message.get("last"):
                        break
        finally:
            stalled.close()
            await server.close()

    asyncio.run(main())


# --- command line -----------------------------------------------------------------------------
@pytest.mark.parametrize("rate", ["1000", "0.5"])
def test_a_view_rate_out_of_range_is_one_clear_line(rate: str, capsys: pytest.CaptureFixture[str]) -> None:
    code = graphics_node.main(["--no-discovery", "--no-oscquery", "--rate-hz", rate])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "--rate-hz" in err and "240" in err, err


def test_a_busy_http_port_is_named_as_the_http_port(tmp_path: Path) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        proc = subprocess.run(
            [sys.executable, "-m", "services.graphics.node", "--no-discovery", "--no-oscquery",
             "--clock-master", "self", "--log-level", "ERROR", "--http-port", str(port)],
            cwd=ROOT, capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"--http-port {port}" in lines[0], proc.stderr


# --- long work shows progress -----------------------------------------------------------------
def test_posing_a_score_preview_reports_progress() -> None:
    calls: list[tuple[int, int]] = []
    preview = score_preview(TINY_SCORE, load_kit("default"), on_progress=lambda done, total: calls.append((done,
                                                                                                         total)))
    total = len(preview.sequence.times)
    assert calls[-1] == (total, total)
    assert [done for done, _ in calls] == sorted(done for done, _ in calls) and len(calls) >= 10


def test_the_node_says_what_it_is_planning_and_how_far_it_got(caplog: pytest.LogCaptureFixture) -> None:
    ticks = iter(range(0, 10_000, 3))  # a clock that moves 3 s per look: every progress call is reported
    settings = graphics_node.GraphicsNodeSettings(preview_score=str(TINY_SCORE), discovery=False)
    with caplog.at_level(logging.INFO, logger="batteur.graphics"):
        graphics_node.plan_score_preview(settings, load_kit("default"), clock=lambda: float(next(ticks)))
    text = [r.getMessage() for r in caplog.records]
    assert "posing" in text[0] and str(TINY_SCORE) in text[0]
    assert any("100%" in line for line in text[1:]), text


def test_a_preview_file_with_zero_quaternions_still_plays(tmp_path: Path) -> None:
    """``--preview FILE.npz`` written by another tool with (0, 0, 0, 0) orientations on kit links."""
    names = ["pelvis", "kit.hihat_pedal.footboard", "kit.crash"]
    PoseSequence(names, np.array([0.0, 1.0]), np.zeros((2, 3, 7))).save(tmp_path / "zeros.npz")
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.load_preview(PoseSequence.load(tmp_path / "zeros.npz"))
    core.take_page_messages()
    core.step(0.0)  # the sequence's first pose, as stored
    assert [m["type"] for m in core.take_page_messages()].count("frame") == 1


def test_saving_a_kit_over_the_saved_poses_is_refused(tmp_path: Path) -> None:
    """The kit file name typed as ``poses.yaml`` (or any file that is not a kit) must not wipe that file."""
    server = ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")), kit_dir=tmp_path)
    assert server.handle_page_message(json.dumps({"type": "save_pose", "name": "SNARE.right_hand.UP"}))["ok"]  # type: ignore[index]
    poses = (tmp_path / "poses.yaml").read_text()
    kit = load_kit().model_dump(mode="json")
    reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": "poses.yaml", "kit": kit}))
    assert reply is not None and reply["ok"] is False and "not a kit" in reply["error"]
    assert (tmp_path / "poses.yaml").read_text() == poses
    reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": "mine.yaml", "kit": kit}))
    assert reply is not None and reply["ok"] is True
    reply = server.handle_page_message(json.dumps({"type": "save_kit", "file": "mine.yaml", "kit": kit}))
    assert reply is not None and reply["ok"] is True  # a kit may replace a kit


def test_ctrl_c_does_not_wait_ten_seconds_for_a_frozen_page() -> None:
    """Closing waits for each page's close handshake; a frozen one must not hold the node's exit up for long."""
    async def main() -> None:
        server = ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")))
        port = await server.start("127.0.0.1", 0)
        stalled = await asyncio.to_thread(_stalled_client, port)
        try:
            await _clients(server, 1)
            assert all(c.close_timeout is not None and c.close_timeout <= 1.0 for c in server.clients)
        finally:
            stalled.close()
            await server.close()

    asyncio.run(main())


# --- offline video ----------------------------------------------------------------------------
@needs_ffmpeg
def test_an_interrupted_video_leaves_no_partial_file_and_keeps_the_old_one(tmp_path: Path) -> None:
    """Ctrl-C (or any failure) during ``render_video``: the previous video is intact, no truncated MP4 left."""
    sequence, impacts = synthetic_performance(duration=1.0, rate_hz=30.0)
    old = tmp_path / "performance.mp4"
    old.write_bytes(b"the video of yesterday's take")

    def interrupt(done: int, total: int) -> None:
        if done == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_video(sequence, impacts, None, tmp_path, fps=30, width=160, height=90, on_progress=interrupt)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["performance.mp4"]
    assert old.read_bytes() == b"the video of yesterday's take"
    info = render_video(sequence, impacts, None, tmp_path, fps=30, width=160, height=90)
    assert info.path == old and old.stat().st_size > 1000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["performance.mp4"]


@pytest.mark.parametrize(("arrays", "why"), [
    ({"times": np.zeros((2, 2)), "values": np.zeros((2, 1, 7))}, "times must be a list"),
    ({"times": np.array(0.0), "values": np.zeros((1, 1, 7))}, "times must be a list"),
    ({"times": np.array([0.0, np.inf]), "values": np.zeros((2, 1, 7))}, "times must be finite"),
    ({"names": np.array([["pelvis", "head"]])}, "names must be a list"),
])
def test_a_malformed_preview_file_is_refused_at_start(arrays: dict[str, np.ndarray], why: str,
                                                       tmp_path: Path) -> None:
    """Hand-made ``--preview`` files: one clear error before the node starts, not a view failing every frame."""
    data = {"names": np.array(["pelvis"]), "times": np.array([0.0, 1.0]), "values": np.zeros((2, 1, 7)), **arrays}
    np.savez(tmp_path / "odd.npz", **data)
    settings = graphics_node.GraphicsNodeSettings(preview=str(tmp_path / "odd.npz"), discovery=False)
    with pytest.raises(ValueError, match=why) as error:
        graphics_node.make_core(settings, argparse.Namespace())
    assert str(error.value).startswith("--preview: ") and "\n" not in str(error.value)


def test_synthetic_on_a_kit_without_the_groove_instruments_is_a_start_error(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--synthetic --kit mine.yaml`` with no crash cymbal: one line and exit 2, not a traceback once running."""
    kit = load_kit("default").model_dump(mode="json")
    keep = {"kick", "snare", "hihat", "kick_pedal", "hihat_pedal", "throne"}
    kit["objects"] = [o for o in kit["objects"] if o["id"] in keep]
    kit["events"] = {e: v for e, v in kit["events"].items() if v["object"] in keep}
    (tmp_path / "small.yaml").write_text(yaml.safe_dump(kit, sort_keys=False))
    load_kit(tmp_path / "small.yaml")  # a valid kit
    code = graphics_node.main(["--no-discovery", "--no-oscquery", "--http-port", "0", "--synthetic",
                               "--kit", str(tmp_path / "small.yaml")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "--synthetic" in err and "CRASH" in err, err


def test_a_flood_of_node_ids_does_not_grow_the_status_table_without_bound() -> None:
    """Health from thousands of made-up node ids (a broken tool): memory stays bounded, real nodes stay listed."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))

    def health(node_id: str, role: str, t: float) -> Health:
        return Health(node_id=node_id, role=role, protocol=1, time=t, rate_hz=60.0, target_rate_hz=60.0, overruns=0,
                      messages_in=0, messages_out=0, dropped=0, dropped_malformed=0, dropped_unknown=0,
                      dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=0)

    for k in range(5000):
        core.handle(health(f"bogus-{k}", "bogus", 1.0), 1.0, "127.0.0.1:5000")
    core.handle(health("sound-1", "sound", 2.0), 2.0, "127.0.0.1:9103")
    assert len(core.nodes) <= 1000
    assert "sound-1" in [n["id"] for n in core.status(2.0)["nodes"]]


def test_bad_page_messages_and_skipped_frames_are_counted_where_users_look() -> None:
    """``/api/status`` carries the view server's counters (page errors, skipped frames), not only the core's."""
    async def main() -> None:
        server = ViewServer(GraphicsCore(GraphicsSettings(latency=0.0, clock="rig")))
        port = await server.start("127.0.0.1", 0)
        try:
            server.handle_page_message("not json")
            text = await asyncio.to_thread(
                lambda: urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status", timeout=10).read())
            status = json.loads(text)
            assert status["server"]["page_errors"] == 1 and status["server"]["skipped_frames"] == 0
        finally:
            await server.close()

    asyncio.run(main())


class _Page:
    """What the page does with the core's messages: keeps the newest skeleton, draws frames that match it."""

    def __init__(self, messages: list[dict[str, Any]]) -> None:
        self.names: list[str] = []
        self.drawn: list[int] = []  # link count of every frame drawn
        self.take(messages)

    def take(self, messages: list[dict[str, Any]]) -> None:
        for m in messages:
            if m["type"] == "skeleton":
                self.names = m["names"]
            elif m["type"] == "frame" and len(m["p"]) == 7 * len(self.names):  # app.js drops the others
                self.drawn.append(len(self.names))


def test_switching_between_preview_and_live_with_physics_running_keeps_drawing() -> None:
    """``--preview-score`` while physics runs (it re-sends its skeleton), ``/batteur/graphics/mode`` back and forth."""
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    sequence, impacts = synthetic_performance(duration=2.0, rate_hz=30.0)
    core.load_preview(sequence, impacts)
    page = _Page(core.take_page_messages())
    live = ("pelvis", "head", "kit.crash")
    for k, mode in enumerate(["preview", "live", "preview"]):
        t = 0.1 + k
        core.handle(Skeleton(layout=3, names=live), t, "physics")  # physics re-sends it every few seconds
        core.handle(Pose(time=t, layout=3, values=(0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0) * 3), t, "physics")
        core.apply_control(GraphicsMode(mode=mode))  # type: ignore[arg-type]
        core.step(t + 0.01)
        page.take(core.take_page_messages())
        assert page.drawn[-1:] == [len(sequence.names) if mode == "preview" else len(live)], (mode, page.drawn)
        late_page = _Page(core.welcome())  # a page opened now
        core.step(t + 0.02)
        late_page.take(core.take_page_messages())
        assert late_page.drawn, mode


def test_the_printed_view_address_is_a_usable_url_on_ipv6(tmp_path: Path) -> None:
    """``--host ::1``: the line users copy into the browser must be ``http://[::1]:PORT/``."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "services.graphics.node", "--no-discovery", "--no-oscquery", "--clock-master", "self",
         "--log-level", "ERROR", "--host", "::1", "--http-port", "0"],
        cwd=ROOT, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        line = proc.stderr.readline()
        assert line.startswith("graphics view: http://[::1]:"), line
        port = int(line.rsplit(":", 1)[1].strip().rstrip("/"))
        with socket.create_connection(("::1", port), timeout=5):  # the printed port is the one listening
            pass
    finally:
        proc.terminate()
        proc.wait(20)


def test_ctrl_c_during_a_replan_stops_the_planning_thread(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The node stops while re-planning a long score: the thread must give up, or exit waits for the whole plan."""
    seen: dict[str, bool] = {}
    planning = threading.Event()

    def slow_plan(settings: object, kit: object, cancel: threading.Event | None = None) -> object:
        planning.set()
        seen["cancelled"] = cancel is not None and cancel.wait(30)
        raise ValueError("gave up")

    monkeypatch.setattr(graphics_node, "plan_score_preview", slow_plan)
    settings = graphics_node.GraphicsNodeSettings(preview_score=str(TINY_SCORE), kit_dir=str(tmp_path),
                                                  discovery=False)
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    node = types.SimpleNamespace(clock=types.SimpleNamespace(now=lambda: 0.0))

    async def main() -> None:
        task = asyncio.create_task(graphics_node._watch_preview(node, core, settings, period=0.01))  # type: ignore[arg-type]
        poses = tmp_path / "poses.yaml"
        poses.write_text("{}\n")
        for stamp in range(1_000_000, 1_003_000):  # the editor saves poses until the watcher re-plans
            os.utime(poses, (stamp, stamp))
            if await asyncio.to_thread(planning.wait, 0.05):
                break
        task.cancel()  # Ctrl-C: the node cancels its tasks
        with pytest.raises(asyncio.CancelledError):
            await task

    asyncio.run(main())  # returns once the planning thread has returned (asyncio.run joins it)
    assert seen == {"cancelled": True}


def test_a_cancelled_plan_stops_at_the_next_pose() -> None:
    cancel = threading.Event()
    cancel.set()
    settings = graphics_node.GraphicsNodeSettings(preview_score=str(TINY_SCORE), discovery=False)
    with pytest.raises(graphics_node.PlanCancelled):
        graphics_node.plan_score_preview(settings, load_kit("default"), cancel=cancel)
