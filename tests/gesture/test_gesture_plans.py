"""Gesture database, planner and keyframe mode: continuity and contacts at every note."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.gesture.bvh import BvhError, parse_bvh, read_bvh, write_bvh
from common.gesture.database import GestureDatabase, default_database, load_unit
from common.gesture.heights import stick_height, stick_speed
from common.gesture.keyframe import plan_keyframes
from common.gesture.plan import GesturePlan, Grip, HeadTrajectory, LimbTrajectory, Nuance
from common.gesture.planner import (
    HIHAT_CLOSE_TAIL_FROM,
    HIHAT_CLOSE_TAIL_M,
    PlannerConfig,
    kick_contact_rise,
    plan_gestures,
)
from common.gesture.synth import UNITS_DIR, make_unit
from common.kit import EventType as E
from common.kit import Limb, foot_target_for_press, load_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute
from common.score.midi import read_midi
from tests.gesture.continuity import largest_jumps

DATA = Path(__file__).parent.parent / "data"
KIT = load_kit()


def _max_speed(plan: GesturePlan) -> float:
    speeds = [
        np.linalg.norm(tr.sample_many(np.arange(tr.start_time, tr.end_time, 5e-4))[1], axis=1).max()
        for tr in plan.trajectories.values()
    ]
    return float(max(speeds))


def _check_contacts(plan: GesturePlan, assignment_times: list[float], moving_in: bool = True) -> None:
    assert sorted(s.time for s in plan.strokes) == pytest.approx(sorted(assignment_times))
    for s in plan.strokes:
        sample = plan.trajectories[s.limb].sample(s.time)
        np.testing.assert_allclose(sample.position, s.target, atol=1e-9)
        if moving_in:  # moving into the surface at contact
            assert float(np.dot(sample.velocity, s.normal)) < 0, s


def test_trajectory_sample_is_hermite_and_validates() -> None:
    traj = LimbTrajectory(Limb.RIGHT_HAND, np.array([0.0, 1.0]), np.zeros((2, 3)), np.array([[1.0, 0, 0], [1.0, 0, 0]]))
    s = traj.sample(0.5)
    assert s.position[0] == pytest.approx(0.0) and s.velocity[0] == pytest.approx(-0.5)
    assert traj.sample(2.0).velocity.tolist() == [0, 0, 0]
    with pytest.raises(ValueError):
        LimbTrajectory(Limb.RIGHT_HAND, np.array([0.0, 0.0]), np.zeros((2, 3)), np.zeros((2, 3)))
    for times in ([0.0, np.nan], [np.nan, 1.0], [0.0, np.inf]):  # NaN passes an order check: refused as such
        with pytest.raises(ValueError, match="finite"):
            LimbTrajectory(Limb.RIGHT_HAND, np.array(times), np.zeros((2, 3)), np.zeros((2, 3)))


@pytest.fixture(scope="module")
def groove() -> Score:
    return read_midi(DATA / "groove_drummer6_s3_1_rock_90_beat_4-4.mid")


@pytest.mark.parametrize("algorithm", ["simple", "pairwise", "viterbi"])
def test_plan_continuous_with_contact_at_every_note(groove: Score, algorithm: str) -> None:
    assignment = distribute(groove, KIT, algorithm)
    plan = plan_gestures(assignment, KIT, groove)
    _check_contacts(plan, [n.time for n in assignment.notes])
    jump_p, jump_v = largest_jumps(plan)
    # across a knot, +-1 ns: a stroke of 6 m/s reversing in 4 ms accelerates at 3,000 m/s^2 (6e-6 m/s per 2 ns)
    assert jump_p < 1e-7
    assert jump_v < 1e-4
    assert _max_speed(plan) < 30.0  # a stick tip, not a bullet
    assert set(plan.trajectories) == set(Limb)
    assert plan.head is not None and plan.head.nod.max() > 0


def test_keyframe_mode_contacts_and_swing(groove: Score) -> None:
    assignment = distribute(groove, KIT)
    plan = plan_keyframes(assignment, KIT, groove)
    assert plan.mode == "keyframe"
    _check_contacts(plan, [n.time for n in assignment.notes], moving_in=False)
    jump_p, jump_v = largest_jumps(plan)
    assert jump_p < 1e-7 and jump_v < 1e-4
    # overlap rule: fast notes get one mid frame, so no frame order problems and all within range
    cym = [s for s in plan.cymbal_swings]
    assert cym, "the groove has cymbal strokes"
    sw = cym[0]
    t = sw.time + np.linspace(0, 2, 400)
    angle = sw.angle(t)
    assert abs(angle).max() <= sw.alpha_max + 1e-12
    assert abs(angle[t > sw.time + 1.5]).max() < 0.1 * sw.alpha_max + 1e-12
    assert sw.angle(sw.time - 0.1) == 0


def test_keyframe_overlap_rule() -> None:
    score = Score([DrumEvent(0.0, E.SNARE, 0.8), DrumEvent(0.12, E.SNARE, 0.8), DrumEvent(1.0, E.SNARE, 0.8)])
    a = distribute(score, KIT, "simple")
    plan = plan_keyframes(a, KIT)
    traj = plan.trajectories[Limb.LEFT_HAND]
    # interval 0.12 < 2 * delta: one mid frame at 0.06 instead of after(0.1)/before(0.02)
    assert np.any(np.isclose(traj.times, 0.06)) and not np.any(np.isclose(traj.times, 0.02))
    assert np.any(np.isclose(traj.times, 0.9))  # the slow stroke keeps its before frame


def test_height_and_rebound_follow_velocity_and_elasticity() -> None:
    assert stick_height(49 / 127) == pytest.approx(0.076, abs=0.002)  # p
    assert stick_height(112 / 127) == pytest.approx(0.30, abs=0.005)  # ff
    assert stick_height(1.0, Nuance.VERTICAL_ACCENT) == pytest.approx(0.40)  # fff, vertical
    assert stick_speed(0.9) > stick_speed(0.3)
    score = Score([DrumEvent(0.0, E.SNARE, 0.3), DrumEvent(1.0, E.SNARE, 0.95), DrumEvent(2.0, E.RIDE, 0.95)])
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    soft, loud, ride = plan.strokes
    assert loud.lift > 2 * soft.lift and loud.velocity > soft.velocity
    # peak height before the loud stroke is its lift (above the target, along the normal)
    traj = plan.trajectories[Limb.LEFT_HAND]
    t = np.linspace(0.05, 0.95, 500)
    height = (traj.sample_many(t)[0] - loud.target) @ loud.normal
    assert height.max() == pytest.approx(loud.lift, rel=0.25)
    assert ride.rebound_velocity / ride.velocity == pytest.approx(KIT.object("ride").elasticity)
    assert loud.rebound_velocity / loud.velocity == pytest.approx(KIT.object("snare").elasticity)


@pytest.mark.parametrize("grip", list(Grip))
def test_config_grip_and_nuance(grip: Grip) -> None:
    score = Score([DrumEvent(0.5 * k, E.SNARE, 0.7) for k in range(4)])
    for nuance in Nuance:
        plan = plan_gestures(distribute(score, KIT), KIT, score, PlannerConfig(grip=grip, nuance=nuance))
        assert {s.nuance for s in plan.strokes} == {nuance}
        assert largest_jumps(plan)[1] < 1e-4


def test_database_covers_grips_nuances_tempi() -> None:
    db = default_database()
    keys = {(u.grip, u.nuance) for u in db.units}
    assert keys == {(g, n) for g in Grip for n in Nuance}
    assert all(u.rate_hz == 250 for u in db.units)
    assert all(0.003 <= u.contact_duration <= 0.006 for u in db.units)
    assert db.select(Grip.FRENCH, Nuance.STACCATO, 0.26).tempo_bpm == 240
    assert db.select(Grip.FRENCH, Nuance.STACCATO, 0.9).tempo_bpm == 60
    # whiplash: the hand (wrist joint) rises before the stick tip
    unit = load_unit(UNITS_DIR / "german_legato_60.bvh")
    assert unit.profile(0.0) == pytest.approx(0.0) and unit.profile(1.0) == pytest.approx(0.0, abs=1e-9)
    # louder nuance, higher unit
    acc = load_unit(UNITS_DIR / "german_vertical_accent_60.bvh")
    assert acc.tip_height.max() > unit.tip_height.max()


def test_whiplash_hand_leads_stick() -> None:
    bvh, meta = make_unit(Grip.GERMAN, Nuance.LEGATO, 60)
    wrist = -bvh.motion[:, 7]
    stick = -bvh.motion[:, 10]
    assert int(np.argmax(wrist[:250])) < int(np.argmax(stick[:250]))
    assert meta["contact_frames"] == [0, 250, 500]


def test_user_bvh_roundtrip_and_contact_detection(tmp_path: Path) -> None:
    bvh, _ = make_unit(Grip.FRENCH, Nuance.TENUTO, 100, cycles=3)
    path = tmp_path / "capture.bvh"
    path.write_text(write_bvh(bvh), encoding="utf-8")
    unit = load_unit(path, grip="french", nuance="tenuto")  # no metadata: contacts found as height minima
    assert len(unit.contact_frames) >= 2
    assert unit.period == pytest.approx(0.6, abs=0.02)
    db = GestureDatabase.load(tmp_path)
    assert len(db.units) == len(default_database().units) + 1
    text = path.read_text(encoding="utf-8")
    with pytest.raises(BvhError, match="truncated"):
        parse_bvh(text[: len(text) // 2])
    with pytest.raises(BvhError, match="expected"):
        parse_bvh("HIERARCHY\nJOINT x")
    with pytest.raises(BvhError, match="no such file"):
        read_bvh(tmp_path / "nope.bvh")
    for meta in ("[1, 2]", "{not json"):
        path.with_suffix(".json").write_text(meta)
        with pytest.raises(BvhError, match="bad metadata JSON"):
            load_unit(path, grip="french", nuance="tenuto")
    binary = tmp_path / "binary.bvh"
    binary.write_bytes(bytes(range(128, 256)))
    with pytest.raises(BvhError, match="binary.bvh: not a BVH text file"):  # was a UnicodeDecodeError
        read_bvh(binary)


def test_text_score_sticking_and_nuance_reach_the_plan() -> None:
    from common.score.text import parse_text

    score = parse_text("tempo 100\nSN |xxxx|\nST |LLRR|\nNU |svat|\nBD |x...|\n")
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    snare = [s for s in plan.strokes if s.event == E.SNARE]
    assert [s.limb for s in snare] == [Limb.LEFT_HAND, Limb.LEFT_HAND, Limb.RIGHT_HAND, Limb.RIGHT_HAND]
    assert [s.nuance for s in snare] == [Nuance.STACCATO, Nuance.VERTICAL_ACCENT, Nuance.ACCENT, Nuance.TENUTO]
    kick = [s for s in plan.strokes if s.event == E.BASS]
    assert kick[0].limb == Limb.RIGHT_FOOT
    # a kick foot's first stroke meets the head above the flat footboard (common.gesture.planner.kick_contact_rise)
    flat = np.array(KIT.object("kick_pedal").position)
    np.testing.assert_allclose(kick[0].target, flat + [0.0, 0.0, kick_contact_rise()])


def test_feet_rest_on_pedals_and_hihat_foot_opens_for_open_notes() -> None:
    score = Score(
        [DrumEvent(0.0, E.BASS, 0.8), DrumEvent(2.0, E.BASS, 0.8), DrumEvent(1.0, E.HIHATOPEN, 0.8),
         DrumEvent(3.0, E.HIHATPEDAL, 0.6)]
    )  # fmt: skip
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    kick = plan.trajectories[Limb.RIGHT_FOOT]
    pedal = np.array(KIT.object("kick_pedal").position)
    # between two kicks 2 s apart the foot rests on the raised footboard (beater off the head), lifting only in
    # the last 0.3 s; it presses the board flat only at the note: made from rest (KICK_REST_GAP_S), the kick passes
    # the beater's contact height at the note time and reaches the flat board at its speed after
    rest = pedal + np.array([0.0, 0.0, PlannerConfig().kick_rest_height])
    np.testing.assert_allclose(kick.sample(1.0).position, rest, atol=2e-3)
    assert kick.sample(1.85).position[2] > rest[2] + 0.01
    second = next(s for s in plan.strokes if s.event == E.BASS and s.time == 2.0)
    np.testing.assert_allclose(kick.sample(2.0).position, pedal + [0.0, 0.0, kick_contact_rise()], atol=1e-9)
    np.testing.assert_allclose(kick.sample(2.0 + kick_contact_rise() / second.velocity).position, pedal, atol=1e-9)
    hat = plan.trajectories[Limb.LEFT_FOOT]
    hat_pedal = np.array(KIT.object("hihat_pedal").position)
    resting = hat.sample(0.5).position[2]
    assert resting < hat_pedal[2] + 0.012  # resting on the pedal: closed
    assert hat.sample(1.0).position[2] == pytest.approx(resting + PlannerConfig().hihat_open_lift, abs=1e-3)  # open
    jump_p, jump_v = largest_jumps(plan)
    assert jump_p < 1e-7 and jump_v < 1e-4


def test_the_softest_chick_closes_faster_than_the_foot_lets_an_open_hihat_down() -> None:
    """Interaction hears a closing of the hi-hat only above a speed (a foot letting the pedal down after an open
    note is silent): the planned chick of the softest pedal note must be well above the let-down's speed where the
    plates can meet. (A lift above HIHAT_CLOSE_TAIL_M first drops quickly, the plates still apart: the foot above
    the height at which the footboard closes them.)"""
    score = Score([DrumEvent(1.0, E.HIHATOPEN, 0.8), DrumEvent(3.0, E.HIHATPEDAL, 0.0)])
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    hat = plan.trajectories[Limb.LEFT_FOOT]
    cfg = PlannerConfig()
    join = 1.12 + (HIHAT_CLOSE_TAIL_FROM * cfg.hihat_close_s if cfg.hihat_open_lift > HIHAT_CLOSE_TAIL_M else 0.0)
    closing = KIT.object("hihat_pedal").position[2] + foot_target_for_press(KIT.hihat_closes_at())
    assert hat.sample(join).position[2] > closing  # the plates still apart where the slow let-down starts
    times = np.arange(join, 1.6, 1e-3)  # the let-down after the open note
    let_down = float(np.max(-hat.sample_many(times)[1][:, 2]))
    chick = float(-hat.sample(3.0).velocity[2])
    assert 0.0 < let_down and chick > 3.0 * let_down, (let_down, chick)


def test_scalar_sample_matches_vectorised(groove: Score) -> None:
    plan = plan_gestures(distribute(groove, KIT), KIT, groove)
    rng = np.random.default_rng(1)
    for traj in plan.trajectories.values():
        ts = np.concatenate([rng.uniform(traj.start_time - 0.5, traj.end_time + 0.5, 200), traj.times[:3]])
        pos, vel = traj.sample_many(ts)
        for k, t in enumerate(ts):
            s = traj.sample(float(t))
            np.testing.assert_allclose(s.position, pos[k], atol=1e-12)
            np.testing.assert_allclose(s.velocity, vel[k], atol=1e-9)


def test_a_hand_falling_from_the_hihat_to_the_snare_is_not_planned_faster_than_an_arm_brakes() -> None:
    """The right hand plays the hi-hat, then a ghost note on the snare 0.17 s later (28 cm lower): the fall is
    spread over the segment, not left to its last 40 %, where it peaked at 6.3 m/s and braked to the stroke's
    0.9 m/s in 40 ms (the arm overshot: the stick hit the head 14 ms early at 4.2 m/s)."""
    from common.gesture.planner import MAX_DESCENT_SHARE
    from common.score.text import parse_text

    score = parse_text(f"tempo 88\nHH |x{'.' * 15}|\nSN |.g{'.' * 14}|\nST |RR{'.' * 14}|\n")  # 16ths: 0.17 s
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    hihat, snare = sorted((s for s in plan.strokes if s.limb == Limb.RIGHT_HAND), key=lambda s: s.time)
    assert snare.event == E.SNARE and snare.time - hihat.time == pytest.approx(0.17, abs=0.005)
    assert hihat.target[2] - snare.target[2] > 0.2
    tr = plan.trajectories[Limb.RIGHT_HAND]
    t = np.linspace(hihat.time, snare.time, 400)  # from the hi-hat contact to the snare contact
    pos, vel = tr.sample_many(t)[:2]
    assert -vel[1:, 2].min() < 5.0  # m/s, past the hi-hat contact itself (it peaked at 6.3)
    # past the contact itself (10 ms), the stick rises off the hi-hat before it falls toward the snare
    lift_off = (t > hihat.time + 0.01) & (t < hihat.time + (1 - MAX_DESCENT_SHARE) * (snare.time - hihat.time))
    assert np.all(pos[lift_off, 2] >= hihat.target[2])


@pytest.mark.parametrize("mode", ["gesture", "keyframe"])
def test_a_stroke_by_the_other_hand_reports_the_point_it_strikes(mode: str) -> None:
    """A flam on the snare: the right hand strikes the snare's off_hand point, and its planned stroke says so (hit
    point, r and theta: what the head looks at and what a Pd patch or the viewer is told)."""
    score = Score([DrumEvent(0.5, E.SNARE, 0.7), DrumEvent(0.53, E.SNARE, 0.9)])
    assignment = distribute(score, KIT)
    plan = plan_gestures(assignment, KIT, score) if mode == "gesture" else plan_keyframes(assignment, KIT, score)
    left, right = sorted(plan.strokes, key=lambda s: s.time)
    assert (left.limb, right.limb) == (Limb.LEFT_HAND, Limb.RIGHT_HAND)
    spec = KIT.spec(E.SNARE)
    assert spec.off_hand is not None
    assert (left.r, left.theta) == (spec.r, spec.theta)
    assert (right.r, right.theta) == spec.off_hand
    for s in (left, right):
        np.testing.assert_allclose(s.hit_point, s.target)
    np.testing.assert_allclose(right.hit_point, KIT.effector_target(E.SNARE, Limb.RIGHT_HAND)[0])
    assert np.linalg.norm(right.hit_point - left.hit_point) > 0.08


def test_head_look_at_interpolates_as_np_interp_and_holds_the_ends() -> None:
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(0.001, 0.3, 200))
    head = HeadTrajectory(times, rng.normal(size=(200, 3)), rng.normal(size=200))
    for t in [*rng.uniform(times[0] - 1.0, times[-1] + 1.0, 500), *times]:
        target, nod = head.sample(float(t))
        expected = [np.interp(t, times, head.targets[:, k]) for k in range(3)]
        assert target.tolist() == expected and nod == np.interp(t, times, head.nod)  # the same bits
    assert head.sample(times[0] - 5.0)[0].tolist() == head.targets[0].tolist()
    assert head.sample(times[-1] + 5.0)[1] == head.nod[-1]


def test_the_unit_builder_explains_on_help_and_writes_where_told(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m common.gesture.synth --help`` rebuilt the shipped units instead of explaining; --out writes
    the same units elsewhere."""
    from common.gesture import synth

    before = {p.name: p.stat().st_mtime_ns for p in UNITS_DIR.iterdir() if p.suffix in (".bvh", ".json")}
    with pytest.raises(SystemExit) as done:
        synth.main(["--help"])
    assert done.value.code == 0 and "--out" in capsys.readouterr().out
    assert {p.name: p.stat().st_mtime_ns for p in UNITS_DIR.iterdir() if p.suffix in (".bvh", ".json")} == before
    assert synth.main(["--out", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(before)
    assert all((tmp_path / name).read_bytes() == (UNITS_DIR / name).read_bytes() for name in before)


def _hihat_notes(gap_s: float, pattern: str) -> Score:
    """Hi-hat notes ``gap_s`` apart from 0.5 s: C closed, O open, P pedal chick."""
    kinds = {"C": (E.HIHATCLOSED, 42), "O": (E.HIHATOPEN, 46), "P": (E.HIHATPEDAL, 44)}
    return Score([DrumEvent(0.5 + gap_s * k, kinds[ch][0], 0.7, pitch=kinds[ch][1]) for k, ch in enumerate(pattern)])


@pytest.mark.parametrize("gap_s", [0.15, 0.125])
def test_the_hihat_foot_opens_after_the_closed_16th_before_an_open_one_and_is_down_for_the_next(gap_s: float) -> None:
    """16ths at 100 and 120 bpm: the pedal lifted at the open note, at rest at the closed note before it, and down
    near it at the closed note after (the plates, which meet about half-way through the let-down, closed: 1.5 cm
    over the rest, the lift of 0.18 s before to 0.32 s after the note took both in, held 7 cm at the one after)."""
    score = _hihat_notes(gap_s, "CCCOCCC")
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    hat = plan.trajectories[Limb.LEFT_FOOT]
    rest = hat.sample(0.3).position[2]
    t_open = 0.5 + 3 * gap_s
    assert hat.sample(t_open).position[2] > rest + 0.04
    assert hat.sample(t_open - gap_s).position[2] < rest + 0.002
    assert hat.sample(t_open + gap_s).position[2] < rest + 0.015
    assert np.all(np.diff(hat.times) > 1e-6)
    jump_p, jump_v = largest_jumps(plan)
    assert jump_p < 1e-7 and jump_v < 1e-4


@pytest.mark.parametrize(("gap_s", "pattern"), [(0.25, "COPC"), (0.5, "COPC"), (0.15, "CCOPCC")])
def test_the_hihat_foot_lifts_for_an_open_note_and_comes_down_into_the_pedal_chick_after_it(
        gap_s: float, pattern: str) -> None:
    """An open note closed by a pedal chick: the pedal lifted at the open note (the lift was skipped with a pedal
    stroke 0.48 s before to 0.63 s after it: played closed), the chick's contact at its time and speed."""
    score = _hihat_notes(gap_s, pattern)
    alone = _hihat_notes(gap_s, pattern.replace("O", "C"))  # the same chick after a closed note
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    hat = plan.trajectories[Limb.LEFT_FOOT]
    t_open = 0.5 + pattern.index("O") * gap_s
    t_chick = t_open + gap_s
    rest = hat.sample(0.3).position[2]
    assert rest + 0.04 < hat.sample(t_open).position[2] < rest + PlannerConfig().hihat_open_lift + 1e-3
    ref = plan_gestures(distribute(alone, KIT), KIT, alone).trajectories[Limb.LEFT_FOOT]
    np.testing.assert_allclose(hat.sample(t_chick).position, ref.sample(t_chick).position, atol=1e-9)
    np.testing.assert_allclose(hat.sample(t_chick).velocity, ref.sample(t_chick).velocity, atol=1e-9)
    assert np.all(np.diff(hat.times) > 1e-6)  # the physics refused a plan with a knot time twice
    jump_p, jump_v = largest_jumps(plan)
    assert jump_p < 1e-7 and jump_v < 1e-4


@pytest.mark.parametrize(("gap_s", "pattern"), [(0.15, "CCOPCC"), (0.2, "OCOCCOCPOOC")])
def test_open_hihat_windows_shaped_by_their_neighbours_keep_the_foot_s_knot_times_apart(
        gap_s: float, pattern: str) -> None:
    """A window's rise starting 10 ms after a closed note, or its let-down ending where the hold after the note and
    the let-down were shortened, fell on a knot of the foot's track (1e-16 s apart): the physics refused the plan
    ("not finite and strictly increasing")."""
    score = _hihat_notes(gap_s, pattern)
    plan = plan_gestures(distribute(score, KIT), KIT, score)
    assert np.all(np.diff(plan.trajectories[Limb.LEFT_FOOT].times) > 1e-6)
