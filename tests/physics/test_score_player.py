"""The physics service's score player through the in-memory bus: scores and live notes become impacts.

PhysicsCore(drummer) + InteractionCore (+ a recorder standing in for graphics) run in the OfflineRunner;
score control messages go to ``physics`` through encode/decode as on the rig. A two-bar groove played
with ScoreLoad + ScoreTransport gives the same impacts as ``batteur render`` of the same score; bad
loads are counted and never raise; live notes are planned when they arrive in time and counted (not
played) when they do not; stop cancels what was planned after it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from batteur.render import RecorderCore, RenderOptions, prepare, run_score
from common.bus import OfflineRunner
from common.kit import load_kit
from common.messages.score import GestureStyle, KitSelect, LiveNote, ScoreLoad, ScoreTransport, TempoScale
from services.interaction.core import InteractionCore
from services.physics.core import PhysicsCore, PhysicsSettings

SCORES = Path(__file__).parents[1] / "render"
SCORE = SCORES / "short_groove.txt"
MIDI = Path(__file__).parents[1] / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"
PLAY_AT_S = 1.5
INSTRUMENT = {"HIHATCLOSED": "hihat", "SNARE": "snare", "BASS": "kick"}


def _rig(start_s: float = 0.0, **settings: Any) -> tuple[PhysicsCore, OfflineRunner, RecorderCore, Any]:
    """``start_s``: rig time the runner and the simulation start at, s (the drummer at rest there)."""
    kit = load_kit("default")
    physics = PhysicsCore(scene="drummer", kit=kit, grip="german", pose_rate_hz=0, **settings)
    physics.time_offset = start_s  # else the first step simulates the drummer at rest from rig time 0 up to it
    recorder = RecorderCore()
    runner = OfflineRunner([physics, InteractionCore(kit=kit), recorder], start_s=start_s)
    return physics, runner, recorder, runner.bus.endpoint("control")


def _match(notes: list[tuple[float, str]], impacts: list[Any], tolerance: float) -> list[float | None]:
    """Per note (rig time s, instrument): the signed error of the nearest impact on its instrument, or None."""
    out: list[float | None] = []
    for t, instrument in notes:
        near = [i.time - t for i in impacts if i.instrument == instrument and abs(i.time - t) <= tolerance]
        out.append(min(near, key=abs) if near else None)
    return out


@pytest.fixture(scope="module")
def played() -> dict[str, Any]:
    physics, runner, recorder, control = _rig()
    physics.score_player.library = [SCORES]
    control.send(ScoreLoad(path=SCORE.name), "physics")
    runner.run_until(0.2)
    control.send(ScoreTransport(action="play", time=PLAY_AT_S, position=0.0), "physics")
    plan = physics.score_player.last_plan
    assert plan is not None and physics.score_player.state == "playing"
    runner.run_until(physics.score_player.end_time + 0.3)
    physics.close()
    return {"impacts": recorder.impacts.sorted(), "plan": plan, "status": physics.score_player.status(),
            "rejected": dict(physics.rejected)}


def test_a_played_score_sounds_each_note_on_its_instrument_at_its_time(played: dict[str, Any]) -> None:
    from common.score.text import read_score

    assert played["rejected"] == {} and played["status"]["late_notes"] == 0
    notes = [(PLAY_AT_S + e.time, INSTRUMENT[e.event.value]) for e in read_score(SCORE).events]
    assert len(notes) == 13
    errors = _match(notes, played["impacts"], 0.04)
    assert None not in errors, list(zip(notes, errors, strict=True))
    sticks = [abs(e) for (_, inst), e in zip(notes, errors, strict=True) if inst != "kick" and e is not None]
    assert max(sticks) <= 0.010  # the sticks land within 10 ms (measured: 1-3 ms); kicks within 40 ms


def test_the_live_plan_is_the_render_plan_and_sounds_the_same(played: dict[str, Any]) -> None:
    kit = load_kit("default")
    opts = RenderOptions(settle_s=0.5, tail_s=0.3)
    score, assignment, plan = prepare(SCORE, kit, opts)
    offset = opts.settle_s - plan.start_time
    assert offset == pytest.approx(PLAY_AT_S)  # the render's first note also sounds at 1.5 s
    live = played["plan"]
    assert [(s.limb, s.event, round(s.time, 6)) for s in live.strokes] == \
        [(s.limb, s.event, round(s.time + offset, 6)) for s in plan.strokes]
    offline = run_score(score, assignment, plan, kit, opts).impacts
    # the same notes: each planned note sounds offline and live on its instrument within 5 ms of each other, at
    # a similar speed (soft bounces and plate rattles a few ms after a stroke are chaotic: any two runs that
    # differ at all differ in them, so only the loudest impact near each note is compared)
    assert abs(len(offline) - len(played["impacts"])) <= 2
    for s in plan.strokes:
        t = s.time + offset

        def loudest(impacts: list[Any], near: float = t, instrument: str = s.object_id) -> Any:
            mine = [i for i in impacts if i.instrument == instrument and abs(i.time - near) <= 0.010]
            return max(mine, key=lambda i: i.velocity, default=None)

        off, live = loudest(offline), loudest(played["impacts"])
        assert off is not None and live is not None, f"{s.object_id} at {t:.3f} s: offline {off}, live {live}"
        assert abs(live.time - off.time) <= 0.005
        assert abs(live.velocity - off.velocity) <= 0.25 * off.velocity + 0.1


def test_live_notes_in_time_are_played_late_ones_counted_and_stop_cancels() -> None:
    physics, runner, recorder, control = _rig()
    player = physics.score_player
    prep = player.preparation_s
    assert 0.2 < prep < 0.5  # the shortest gesture unit (0.248 s) plus the splice margin
    # (arrival rig time, note rig time, GM pitch): each arrives 0.35 s ahead, one tom only 0.05 s ahead,
    # and two snares after the stop
    sends = [(0.6, 0.95, 42), (0.6, 0.95, 36), (0.9, 1.25, 42), (1.2, 1.55, 38), (1.2, 1.55, 42),
             (1.5, 1.7, 47), (1.5, 1.85, 42), (1.8, 2.15, 36), (1.8, 2.15, 42), (1.9, 2.6, 38), (2.0, 2.9, 38)]
    for when, t, pitch in sends:
        runner.run_until(when)
        control.send(LiveNote(time=t, pitch=pitch, velocity=100, channel=10), "physics")
    control.send(ScoreTransport(action="stop", time=2.3, position=0.0), "physics")
    control.send(LiveNote(time=3.0, pitch=27, velocity=90, channel=10), "physics")  # no drum: counted
    runner.run_until(3.4)
    status = player.status()
    physics.close()
    impacts = recorder.impacts.sorted()
    assert physics.rejected == {}
    assert status["late_notes"] == 1 and physics.late >= 1  # the tom: reported in Health.late
    assert status["errors"] == {"unknown_pitch": 1}
    played_notes = [(t, INSTRUMENT[{42: "HIHATCLOSED", 36: "BASS", 38: "SNARE"}[p]]) for w, t, p in sends
                    if t - w >= prep and t < 2.3]
    errors = _match(played_notes, impacts, 0.04)
    assert None not in errors, list(zip(played_notes, errors, strict=True))
    assert not [i for i in impacts if i.instrument == "midtom"]  # the late note is not played, not even late
    assert not [i for i in impacts if i.time > 2.45]  # stopped at 2.3: the snares at 2.6 and 2.9 are not played


def test_bad_loads_and_requests_are_counted_and_never_raise(tmp_path: Path) -> None:
    (tmp_path / "good.txt").write_text(SCORE.read_text())
    (tmp_path / "broken.mid").write_bytes(MIDI.read_bytes()[:200])
    (tmp_path / "bad.txt").write_text("tempo 100\nZZ |x...|\n")
    (tmp_path / "empty.txt").write_text("# nothing\ntempo 100\n")
    (tmp_path / "folder.mid").mkdir()
    core = PhysicsCore(PhysicsSettings(scene="strike", mode="live"))
    player = core.score_player
    refused = ["/batteur/physics/rejected"]
    # no library yet: rejected
    assert [o.message.ADDRESS for o in core.handle(ScoreLoad(path="good.txt"), 0.0, "127.0.0.1:9")] == refused
    player.library = [tmp_path]
    core.handle(ScoreLoad(path="good.txt"), 0.0, "127.0.0.1:9")
    assert player.score is not None and len(player.score.events) == 13
    for name in ("broken.mid", "bad.txt", "empty.txt", "folder.mid", "missing.mid", "/etc/passwd", "../x.txt",
                 str(MIDI)):
        assert [o.message.ADDRESS for o in core.handle(ScoreLoad(path=name), 0.0, "127.0.0.1:9")] == refused
    assert core.rejected["ScoreLoad"] == 9
    assert player.errors["score"] == 3 and player.errors["ScoreLoad"] == 6
    assert player.score_path is not None and player.score_path.name == "good.txt"  # the good score stays loaded
    # the strike scene cannot play; another kit needs a restart; style and tempo are taken
    core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, "127.0.0.1:9")
    core.handle(LiveNote(time=1.0, pitch=38, velocity=100, channel=10), 0.0, "127.0.0.1:9")
    core.handle(KitSelect(kit="double_pedal"), 0.0, "127.0.0.1:9")
    core.handle(KitSelect(kit="default"), 0.0, "127.0.0.1:9")
    core.handle(GestureStyle(grip="french", nuance="accent", algorithm="simple", sticking="single"), 0.0, "x:1")
    core.handle(TempoScale(factor=2.0), 0.0, "127.0.0.1:9")
    assert core.rejected["ScoreTransport"] == 1 and core.rejected["LiveNote"] == 1 and core.rejected["KitSelect"] == 1
    assert (player.grip.value, player.nuance.value, player.algorithm.value, player.tempo) == \
        ("french", "accent", "simple", 2.0)
    core.close()


def test_a_midi_score_plays_from_a_position_at_a_tempo() -> None:
    """Position (score seconds as written) and tempo map onto rig time; notes too close to now are counted."""
    physics, runner, _, control = _rig()
    player = physics.score_player
    player.library = [MIDI.parent]
    control.send(ScoreLoad(path=MIDI.name), "physics")
    control.send(TempoScale(factor=2.0), "physics")
    control.send(ScoreTransport(action="play", time=0.0, position=2.0), "physics")  # time 0: "at once"
    plan = player.last_plan
    assert plan is not None and player.score is not None
    written = [e.time for e in player.score.events if e.time >= 2.0]
    at = 0.5 + 0.001 * len(written)  # START_LEAD_S + the planning margin: score position 2 s is at this rig time
    expected = sorted({at + (t - 2.0) / 2 for t in written})[:5]
    assert sorted({s.time for s in plan.strokes})[:5] == pytest.approx(expected)
    runner.run_until(0.4)
    control.send(ScoreTransport(action="play", time=0.5, position=2.0), "physics")  # the first notes too soon
    assert physics.rejected["ScoreTransport"] == 0 and player.late_notes > 0
    late = player.late_notes
    assert plan is not player.last_plan and player.last_plan is not None
    assert player.last_plan.strokes[0].time >= 0.4 + 0.02 + 0.2 + 0.248 - 1e-9  # splice, transition, a unit
    control.send(ScoreTransport(action="play", time=0.5, position=player.score.events[-1].time), "physics")
    assert physics.rejected["ScoreTransport"] == 1 and player.late_notes == late + 1  # nothing left in time
    control.send(ScoreTransport(action="pause", time=0.0, position=0.0), "physics")
    assert player.state == "paused"
    # from a note's own time (sent as a 32-bit float, a little after it): that note plays first, at the given time
    control.send(ScoreTransport(action="play", time=2.0, position=written[4]), "physics")
    assert player.state == "playing" and player.last_plan is not None
    assert player.last_plan.strokes[0].time == pytest.approx(2.0, abs=1e-5)
    physics.close()


def test_a_play_time_already_past_starts_at_once_and_says_how_late(caplog: pytest.LogCaptureFixture) -> None:
    """A node ready only after the rig time it was asked to start at (a slow start) plays the whole score as
    soon as it can, and warns: the notes move later together rather than being lost."""
    physics, runner, _, control = _rig()
    player = physics.score_player
    player.library = [MIDI.parent]
    control.send(ScoreLoad(path=MIDI.name), "physics")
    runner.run_until(0.4)
    with caplog.at_level("WARNING", logger="batteur.physics.score"):
        control.send(ScoreTransport(action="play", time=0.3, position=2.0), "physics")
    assert physics.rejected["ScoreTransport"] == 0 and player.late_notes == 0
    assert player.mapping is not None and player.mapping[0] > 0.4 + 0.5  # START_LEAD_S after now
    assert any("already past" in r.getMessage() and "0.300" in r.getMessage() for r in caplog.records)


def test_a_tempo_change_while_playing_re_times_the_rest_of_the_score() -> None:
    """Notes within the preparation time keep their times; the rest follow the new tempo from there."""
    from common.score.text import read_score

    physics, runner, recorder, control = _rig()
    player = physics.score_player
    player.library = [SCORES]
    control.send(ScoreLoad(path=SCORE.name), "physics")
    control.send(ScoreTransport(action="play", time=PLAY_AT_S, position=0.0), "physics")
    runner.run_until(2.0)
    control.send(TempoScale(factor=0.5), "physics")
    assert player.mapping is not None
    t_c, p_c, tempo = player.mapping
    assert t_c == pytest.approx(2.0 + player.preparation_s) and p_c == pytest.approx(t_c - PLAY_AT_S)
    assert tempo == 0.5
    runner.run_until(3.9)
    physics.close()
    notes = []
    for e in read_score(SCORE).events:
        t = PLAY_AT_S + e.time
        notes.append((t if t < t_c else t_c + (e.time - p_c) / tempo, INSTRUMENT[e.event.value]))
    notes = [n for n in notes if n[0] < 3.8]
    assert len(notes) == 10  # 5 before the change, 5 after (at half speed: 3.13 and 3.73 s)
    errors = _match(notes, recorder.impacts.sorted(), 0.04)
    assert None not in errors, list(zip(notes, errors, strict=True))
    assert physics.rejected == {} and player.late_notes == 0
