"""Graphics core: delayed, interpolated frames; kit animation; controls; preview; robustness."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pytest

from common.bus import OfflineRunner
from common.core import Outgoing
from common.kit import load_kit
from common.messages import Health, Impact, OscMessage, Pose, Skeleton
from common.messages.graphics import GraphicsCamera, GraphicsLatency, GraphicsMode, GraphicsShow, ScorePosition
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import LINK_NAMES, synthetic_performance
from services.graphics.sequence import PoseSequence

NAMES = ["pelvis", "right_hand"]


def _pose(t: float, x: float, yaw_deg: float = 0.0, layout: int = 1) -> Pose:
    half = math.radians(yaw_deg) / 2
    q = (0.0, 0.0, math.sin(half), math.cos(half))
    return Pose(time=t, layout=layout, values=(0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 1.0, x, 0.3, 1.0, *q))


def _impact(seq: int, t: float, instrument: str = "snare", theta: float = 0.0, velocity: float = 3.0) -> Impact:
    return Impact(seq=seq, time=t, instrument=instrument, zone="centre", r=0.5, theta=theta, velocity=velocity,
                  impulse=0.05, peak_force=300.0, duration=0.004, part="right_stick_tip")


def _core(latency: float = 0.1) -> GraphicsCore:
    core = GraphicsCore(GraphicsSettings(latency=latency, clock="rig"))
    core.handle(Skeleton(layout=1, names=tuple(NAMES)), 0.0, "physics")
    return core


def test_frame_shows_the_pose_one_latency_window_ago_interpolated() -> None:
    core = _core(latency=0.1)
    for k in range(121):  # x = t, 60 Hz, 0..2 s
        core.handle(_pose(k / 60, k / 60), k / 60, "physics")
    frame = core.frame_at(1.0)
    assert frame is not None
    assert frame.time == pytest.approx(0.9)
    assert frame.pose[1, 0] == pytest.approx(0.9, abs=1e-9)
    # between two poses: positions lerp, orientations slerp
    core2 = _core(latency=0.0)
    core2.handle(_pose(0.0, 0.0, yaw_deg=0.0), 0.0, "physics")
    core2.handle(_pose(1.0, 1.0, yaw_deg=90.0), 1.0, "physics")
    mid = core2.frame_at(0.5)
    assert mid is not None
    assert mid.pose[1, 0] == pytest.approx(0.5)
    assert mid.pose[1, 3:] == pytest.approx([0, 0, math.sin(math.radians(22.5)), math.cos(math.radians(22.5))])


def test_holds_the_newest_pose_when_starved_and_counts_it() -> None:
    core = _core(latency=0.0)
    core.handle(_pose(0.0, 0.25), 0.0, "physics")
    frame = core.frame_at(5.0)
    assert frame is not None and frame.pose[1, 0] == pytest.approx(0.25)
    assert core.counters["starved"] == 1


def test_bad_poses_are_counted_not_fatal() -> None:
    core = GraphicsCore(GraphicsSettings(clock="rig"))
    core.handle(_pose(0.0, 0.0), 0.0, "physics")
    assert core.counters["no_skeleton"] == 1
    core.handle(Skeleton(layout=1, names=tuple(NAMES)), 0.0, "physics")
    core.handle(_pose(0.0, 0.0, layout=2), 0.0, "physics")  # another layout
    core.handle(Pose(time=0.0, layout=1, values=(1.0, 2.0, 3.0)), 0.0, "physics")  # wrong length
    assert core.counters["bad_layout"] == 2
    assert core.frame_at(0.0) is None


def test_impacts_flash_after_the_latency_window_and_are_deduplicated() -> None:
    core = _core(latency=0.1)
    for k in range(120):
        core.handle(_pose(k / 60, 0.0), k / 60, "physics")
    snare = [o.id for o in core.kit.objects].index("snare")
    core.handle(_impact(7, 1.0), 1.0, "interaction")
    core.handle(_impact(7, 1.0), 1.0, "interaction")  # redundant copy
    assert core.counters == {**core.counters, "impacts": 1, "duplicate_impacts": 1}
    early = core.frame_at(1.09)
    on_time = core.frame_at(1.11)
    later = core.frame_at(1.6)
    assert early is not None and on_time is not None and later is not None
    assert early.kit[snare, 0] == 0.0
    assert on_time.kit[snare, 0] > 0.8
    assert later.kit[snare, 0] < 0.05
    assert len(on_time.hits) == 1 and on_time.hits[0][4] == "snare"


def test_cymbal_swings_away_from_the_struck_edge_and_decays() -> None:
    core = _core(latency=0.0)
    core.handle(_pose(0.0, 0.0), 0.0, "physics")
    ride = [o.id for o in core.kit.objects].index("ride")
    core.handle(_impact(1, 0.0, "ride", theta=0.0, velocity=4.0), 0.0, "interaction")
    first = core.frame_at(0.1)
    late = core.frame_at(3.0)
    assert first is not None and late is not None
    # struck at theta=0 (local +x edge): rotation about local +y tips that edge down (z of +x goes negative)
    assert first.kit[ride, 1] == pytest.approx(0.0, abs=1e-12)
    assert first.kit[ride, 2] > 0.05
    assert abs(late.kit[ride, 2]) < 0.2 * abs(first.kit[ride, 2])


def test_controls_change_the_view_and_reach_the_page() -> None:
    core = _core()
    core.take_page_messages()
    core.handle(GraphicsShow(layer="trails", visible=0), 0.0, "pd")
    core.handle(GraphicsCamera(preset="free", azimuth_deg=45, elevation_deg=30, distance=2.5, target_x=0.1,
                               target_y=0.2, target_z=0.9), 0.0, "pd")
    core.handle(GraphicsLatency(seconds=0.25), 0.0, "pd")
    core.handle(GraphicsMode(mode="preview"), 0.0, "pd")  # nothing loaded: stays live
    views = [m for m in core.take_page_messages() if m["type"] == "view"]
    assert len(views) == 4
    last = views[-1]
    assert last["layers"]["trails"] is False
    assert last["camera"]["target"] == [0.1, 0.2, 0.9]
    assert last["latency"] == 0.25 and core.latency == 0.25
    assert last["mode"] == "live"


def test_status_lists_nodes_late_strikes_and_score_position() -> None:
    core = _core()
    core.handle(Health(node_id="snd-1", role="sound", protocol=1, time=1.0, rate_hz=750.0, target_rate_hz=750.0,
                       overruns=0, messages_in=10, messages_out=5, dropped=0, dropped_malformed=0,
                       dropped_unknown=0, dropped_type=0, dropped_range=0, dropped_other=0, late=3, peers=2),
                1.0, "127.0.0.1:9000")
    core.handle(ScorePosition(time=1.0, bar=2, beat=1.5, tempo_bpm=120.0), 1.0, "physics")
    core.step(1.5)
    status = [m for m in core.take_page_messages() if m["type"] == "status"][-1]
    assert status["late"] == 3
    assert status["nodes"][0]["role"] == "sound"
    assert status["score"] == {"bar": 2, "beat": 1.5, "tempo_bpm": 120.0, "beat_unit": 1.0}  # no meter: quarters


def test_a_score_position_no_longer_sent_leaves_the_panel() -> None:
    """The player sends ten a second while the score plays; one older than a second is a stopped score."""
    core = _core()
    core.handle(ScorePosition(time=5.0, bar=2, beat=1.5, tempo_bpm=120.0), 1.0, "physics")  # another clock
    assert core.status(1.9)["score"] == {"bar": 2, "beat": 1.5, "tempo_bpm": 120.0, "beat_unit": 1.0}
    assert core.status(2.1)["score"] is None


@pytest.mark.parametrize("offset", [1000.0, 0.3, -0.2])
def test_auto_clock_follows_a_pose_clock_that_is_not_shared(offset: float) -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.1, clock="auto"))
    core.handle(Skeleton(layout=1, names=tuple(NAMES)), 0.0, "physics")
    rng = np.random.default_rng(1)
    for k in range(60):  # physics' clock reads offset + t while ours reads t; poses arrive 0-5 ms late
        core.handle(_pose(offset + k / 60, k / 60), k / 60 + rng.uniform(0, 0.005), "physics")
    frame = core.frame_at(59 / 60 + 0.002)
    assert frame is not None
    assert frame.time == pytest.approx(offset + 59 / 60 - 0.1, abs=0.003)
    assert core.counters["starved"] == 0
    # physics restarts with its clock back at 0: followed at once
    for k in range(10):
        core.handle(_pose(k / 60, 0.0), 2.0 + k / 60, "physics")
    assert core.counters["clock_jumps"] == 1
    assert core.clock_offset == pytest.approx(-2.0, abs=0.01)


def test_preview_plays_a_pose_sequence_and_loops() -> None:
    sequence, impacts = synthetic_performance(duration=1.0)
    core = GraphicsCore(GraphicsSettings(latency=0.0))
    core.load_preview(sequence, impacts, now=10.0)
    assert core.mode == "preview" and core.names == LINK_NAMES
    a = core.frame_at(10.25)
    b = core.frame_at(10.25 + sequence.duration + 0.5)  # one loop later
    assert a is not None and b is not None
    assert np.allclose(a.pose, sequence.sample(0.25))
    assert np.allclose(a.pose, b.pose)
    core.handle(GraphicsMode(mode="live"), 11.0, "pd")
    assert core.frame_at(11.0) is None  # no live poses yet


def test_page_messages_carry_the_whole_pose() -> None:
    core = _core(latency=0.0)
    core.handle(_pose(0.0, 0.5), 0.0, "physics")
    welcome = [m["type"] for m in core.welcome()]
    assert welcome == ["kit", "skeleton", "view"]
    core.take_page_messages()
    sent: list[dict[str, object]] = []
    core.page_sink = sent.extend
    core.step(0.0)
    frame = next(m for m in sent if m["type"] == "frame")
    assert len(frame["p"]) == 7 * len(NAMES)  # type: ignore[arg-type]
    assert len(frame["k"]) == 4 * len(load_kit().objects)  # type: ignore[arg-type]
    assert core.take_page_messages() == []


class _Player:
    """A stand-in physics core: publishes the skeleton once and a synthetic pose at 60 Hz."""

    ROLE: ClassVar[str] = "physics"

    def __init__(self, sequence: PoseSequence) -> None:
        self.rate_hz = 60.0
        self.sequence = sequence
        self.sent_skeleton = False

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        out = []
        if not self.sent_skeleton:
            out.append(Outgoing(self.sequence.skeleton_message(), "graphics"))
            self.sent_skeleton = True
        values = tuple(float(v) for v in self.sequence.sample(now).ravel())
        out.append(Outgoing(Pose(time=now, layout=0, values=values), "graphics"))
        return out


def test_offline_runner_carries_poses_through_the_codec() -> None:
    sequence, _ = synthetic_performance(duration=1.0)
    graphics = GraphicsCore(GraphicsSettings(latency=0.05, clock="rig", rate_hz=30.0))
    runner = OfflineRunner([_Player(sequence), graphics])
    runner.run_until(1.0)
    assert runner.stats("graphics").dropped_total == 0
    assert graphics.counters["poses"] == 61
    frame = graphics.last_frame
    assert frame is not None and frame.time == pytest.approx(0.95)
    assert np.allclose(frame.pose[:, :3], sequence.sample(0.95)[:, :3], atol=1e-4)  # float32 on the wire


def test_recorder_rebuilds_the_sequence_and_impacts_from_the_bus() -> None:
    from services.graphics.recorder import PerformanceRecorder

    sequence, impacts = synthetic_performance(duration=0.5)
    recorder = PerformanceRecorder()
    recorder.record(sequence.skeleton_message())
    for pose in sequence.pose_messages():
        recorder.record(pose, "physics")
        recorder.record(pose, "physics")  # delivered twice
    for imp in impacts + impacts:
        recorder.record(imp, "interaction")
    recorder.record(Pose(time=9.0, layout=5, values=(0.0,)), "physics")
    got = recorder.sequence()
    assert got.names == sequence.names and np.allclose(got.times, sequence.times)
    assert np.allclose(got.values, sequence.values, atol=1e-6)
    assert len(recorder.impacts) == len(impacts) and recorder.dropped == 1


def test_kit_links_from_physics_drive_swing_hihat_and_pedals() -> None:
    """Physics publishes kit.<id>[.part] links: the kit state follows them instead of the impact model."""
    from scipy.spatial.transform import Rotation

    from services.graphics.scene import object_rotation

    kit = load_kit()
    names = ["pelvis", "kit.ride", "kit.hihat.top", "kit.hihat_pedal.footboard", "kit.stands"]
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"), kit=kit)
    core.handle(Skeleton(layout=2, names=tuple(names)), 0.0, "physics")
    ride, hihat, pedal = kit.object("ride"), kit.object("hihat"), kit.object("hihat_pedal")
    tilt = object_rotation(ride) * Rotation.from_rotvec([0.0, 0.08, 0.0])  # swung 0.08 rad about its local y
    top = np.asarray(hihat.position) + object_rotation(hihat).apply([0.0, 0.0, 0.012])  # 12 mm open
    board = object_rotation(pedal) * Rotation.from_euler("x", 11.0, degrees=True)  # half way down
    values = np.array([
        [0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 1.0],
        [*ride.position, *tilt.as_quat()],
        [*top, *object_rotation(hihat).as_quat()],
        [*pedal.position, *board.as_quat()],
        [0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0],
    ])
    core.handle(Pose(time=0.0, layout=2, values=tuple(values.ravel())), 0.0, "physics")
    core.handle(_impact(1, 0.0, "ride", theta=1.0, velocity=5.0), 0.0, "interaction")  # flashes, does not swing
    frame = core.frame_at(0.05)
    assert frame is not None
    ids = [o.id for o in kit.objects]
    assert frame.kit[ids.index("ride"), 1:3] == pytest.approx([0.0, 0.08], abs=1e-9)
    assert frame.kit[ids.index("ride"), 0] > 0.5
    assert frame.kit[ids.index("hihat"), 3] == pytest.approx(0.012, abs=1e-9)
    assert frame.kit[ids.index("hihat_pedal"), 3] == pytest.approx(0.5, abs=1e-6)
