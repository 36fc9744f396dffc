"""``/batteur/score/loop FIRST LAST``: the live drummer repeats bars of the playing score until told otherwise (a
teacher's students play along), then goes on with the rest of the score.

Until 7 Dec only the graphics service's silent preview looped (``/batteur/graphics/preview_bars``);
the physics score player had no loop. The player runs on a bare PhysicsCore (no physics steps: planning only); the
planned notes (``ScorePlayer.events``, rig seconds) and the plans' strokes are what the drummer plays."""

from __future__ import annotations

import functools
import logging
import math
from pathlib import Path

import pytest

from common.kit import EventType, load_kit
from common.messages import MessageError
from common.messages.physics import PhysicsRejected
from common.messages.score import ScoreLoad, ScoreLoop, ScoreTransport, TempoScale
from common.score.bars import MAX_LOOP_PASSES, Timeline, bar_span, counted_bars
from common.score.text import parse_text
from services.physics.core import PhysicsCore
from services.physics.node import LivePhysicsCore
from services.physics.score_player import CLOCKS_KEPT_S, LOOP_AHEAD_S, ScorePlayer
from tests.physics.test_score_load_while_playing import SNARES

SENDER = "127.0.0.1:9"
LOGGER = "batteur.physics.score"
# 120 bpm in 4/4: a bar lasts 2 s; bar 3 alone has a high tom (its downbeat), bar 5 alone a floor tom
FIVE_BARS = """tempo 120
meter 4/4
HH |x.x.x.x.|x.x.x.x.|x.x.x.x.|x.x.x.x.|x.x.x.x.|
SN |........|..x...x.|........|..x...x.|........|
HT |........|........|x.......|........|........|
FT |........|........|........|........|x.......|
BD |x...x...|x...x...|x...x...|x...x...|x...x...|
"""
BAR_S = 2.0
LOOP_S = 2 * BAR_S  # bars 3-4 at tempo x1


def _player(tmp_path: Path, core: PhysicsCore | None = None) -> tuple[PhysicsCore, ScorePlayer]:
    (tmp_path / "five.txt").write_text(FIVE_BARS, encoding="utf-8")
    if core is None:
        core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    player = core.score_player
    player.library = [tmp_path]
    core.handle(ScoreLoad(path="five.txt"), 0.0, SENDER)
    return core, player


def _times(player: ScorePlayer, event: EventType) -> list[float]:
    return [e.time for e in player.events if e.event == event]


def _struck(player: ScorePlayer, event: EventType) -> list[float]:
    """The latest plan's strokes of ``event`` (rig seconds)."""
    assert player.last_plan is not None
    return [s.time for s in player.last_plan.strokes if s.event == event]


def _said(caplog: pytest.LogCaptureFixture, start: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and r.getMessage().startswith(start)]


def test_bars_are_counted_as_compare_counts_them() -> None:
    score = parse_text(FIVE_BARS)
    assert counted_bars(score) == (1, 5)
    assert bar_span(score, 3) == pytest.approx((4.0, 6.0)) and bar_span(score, 5) == pytest.approx((8.0, 10.0))
    with pytest.raises(ValueError, match="bars 1..5"):
        bar_span(score, 6)


def test_a_loop_of_bars_3_4_plays_them_again_on_the_beat_until_turned_off(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
        # bar 3 first sounds at rig 5 s (score 4 s); after bar 4 (rig 9 s) bars 3-4 again, each pass 4 s
        passes = int(LOOP_AHEAD_S // LOOP_S)
        toms = _times(player, EventType.HIGHTOM)
        assert toms == pytest.approx([5.0 + k * LOOP_S for k in range(passes + 1)], abs=1e-3)
        assert _struck(player, EventType.HIGHTOM) == pytest.approx(toms, abs=1e-3)  # planned as strokes too
        assert _times(player, EventType.FLOORTOM) == []  # bar 5 never comes while looping
        for now in (8.9, 9.1, 12.0, 13.1, 13.2):
            player.pump(now)
        clock = player.clock(14.0)  # the view's score position: the written score's, bar 3 beat 3 again
        assert clock is not None and clock[1] == pytest.approx(5.0)
        core.handle(ScoreLoop(first=0, last=0), 15.0, SENDER)  # in the pass of rig 13-17 s: it ends, then bar 5
        for now in (16.9, 17.1, 18.0):
            player.pump(now)
    core.close()
    assert [t for t in _times(player, EventType.HIGHTOM) if t > 15.0] == []  # no pass after the one in progress
    assert _times(player, EventType.FLOORTOM) == pytest.approx([17.0], abs=1e-3)
    assert _struck(player, EventType.FLOORTOM) == pytest.approx([17.0], abs=1e-3)
    assert player.loop is None and core.rejected == {}
    assert _said(caplog, "loop bars 3-4 (4.000 s at tempo x1): from rig 9.000 s, after bar 4, back to score 4.000 "
                 "s, bar 3 beat 1.0")
    said = [m for m in _said(caplog, "loop ") if "asked" not in m and "(4.000 s" not in m]
    assert said == ["loop bars 3-4 starts at rig 9.000 s (pass 1): back to score 4.000 s, bar 3 beat 1.0",
                    "loop bars 3-4 wraps at rig 13.000 s (pass 2): back to score 4.000 s, bar 3 beat 1.0",
                    "loop off: the pass in progress ends at rig 17.000 s, then the rest of the score from score "
                    "8.000 s, bar 5 beat 1.0",
                    "loop bars 3-4 ends at rig 17.000 s: the play goes on at score 8.000 s, bar 5 beat 1.0"]


def test_a_loop_plans_more_passes_before_they_run_out_and_follows_the_tempo(tmp_path: Path) -> None:
    core, player = _player(tmp_path)
    core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
    core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
    first_end = player.end_time
    player.pump(first_end - 30.0)  # passes left for longer than LOOP_EXTEND_S: nothing more yet
    assert player.end_time == first_end
    player.pump(first_end - 15.0)
    assert player.end_time >= first_end - 15.0 + LOOP_AHEAD_S
    toms = _times(player, EventType.HIGHTOM)
    assert (toms[0] - 5.0) % LOOP_S == pytest.approx(0.0, abs=1e-3)  # the passes go on at the same beat
    assert toms == pytest.approx([toms[0] + k * LOOP_S for k in range(len(toms))], abs=1e-3)
    # twice as fast while looping: the pass in progress finishes at the new tempo, then 2 s passes
    now = toms[-3] + 1.0
    core.handle(TempoScale(factor=2.0), now, SENDER)
    assert player.mapping is not None
    t_a, p_a, _ = player.mapping
    assert t_a > now
    loop_start = float(player._timeline.segments[1].at) if player._timeline else 0.0  # noqa: SLF001
    # played seconds: bar 3 of each pass starts a multiple of LOOP_S after the loop's first pass
    next_pass = loop_start + LOOP_S * (int((p_a - loop_start) // LOOP_S) + 1)
    later = [t for t in _times(player, EventType.HIGHTOM) if t > t_a]
    assert later[:4] == pytest.approx([t_a + (next_pass - p_a) / 2.0 + k * LOOP_S / 2.0 for k in range(4)], abs=1e-3)
    assert core.rejected == {}
    core.close()


def test_a_play_past_the_loop_jumps_back_at_its_bars_end_and_a_stop_ends_the_loop(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreLoop(first=2, last=3), 0.0, SENDER)  # stopped: for the next play
        assert player.loop == (2, 3)
        core.handle(ScoreTransport(action="play", time=2.0, position=8.0), 0.0, SENDER)  # bar 5, past bar 3
        # bar 5 once (rig 2-4 s), then bars 2-3 from rig 4 s: bar 3's high tom 2 s into each pass
        assert _times(player, EventType.FLOORTOM) == pytest.approx([2.0], abs=1e-3)
        assert _times(player, EventType.HIGHTOM)[:3] == pytest.approx([6.0, 10.0, 14.0], abs=1e-3)
        core.handle(ScoreTransport(action="stop", time=11.0, position=0.0), 0.0, SENDER)
    core.close()
    assert player.loop is None
    assert _said(caplog, "stop at") == ["stop at rig 11.000 s: score 5.000 s, bar 3 beat 3.0"]
    assert _said(caplog, "loop bars 2-3 ended by the stop")


@pytest.mark.parametrize(("first", "last", "said"), [
    (4, 3, "loop 4 3: the first bar is after the last (0 0 turns looping off)"),
    (3, 6, "loop 3 6: bars outside the score: five.txt has bars 1..5; 0 0 turns looping off"),
    (0, 2, "loop 0 2: bars outside the score: five.txt has bars 1..5; 0 0 turns looping off"),
])
def test_bad_loops_are_refused_and_counted(tmp_path: Path, first: int, last: int, said: str) -> None:
    core, player = _player(tmp_path)
    out = core.handle(ScoreLoop(first=first, last=last), 0.0, SENDER)
    core.close()
    replies = [o.message for o in out if isinstance(o.message, PhysicsRejected)]
    assert [(r.address, r.reason) for r in replies] == [("/batteur/score/loop", said)]
    assert core.rejected["ScoreLoop"] == 1 and player.errors["ScoreLoop"] == 1 and player.loop is None


def test_a_loop_without_a_score_is_refused() -> None:
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    out = core.handle(ScoreLoop(first=1, last=2), 0.0, SENDER)
    core.close()
    assert [o.message.reason for o in out if isinstance(o.message, PhysicsRejected)] == [
        "loop 1 2: no score loaded (send /batteur/score/load first)"]
    assert core.rejected["ScoreLoop"] == 1


def test_negative_bars_are_refused_by_the_transport() -> None:
    with pytest.raises(MessageError, match="out_of_range: /batteur/score/loop: first"):
        ScoreLoop.from_args([-1, 2])


def _live_player(tmp_path: Path) -> tuple[LivePhysicsCore, ScorePlayer]:
    """The live core planning in its worker (a thread), loaded, five.txt loaded (:func:`_player`); close it after."""
    core = LivePhysicsCore(planner="thread", scene="drummer", kit=load_kit("default"), grip="german",
                           pose_rate_hz=0)
    player = core.score_player
    assert player.wait_loaded(120.0) and player.background
    _player(tmp_path, core)
    return core, player


def _settle(player: ScorePlayer, now: float) -> None:
    """Pump ``player`` at rig time ``now`` (s) until no plan is in flight or waiting."""
    player.pump(now)
    while player.busy:
        assert player.wait(60.0)
        player.pump(now)


def test_the_live_node_loops_through_its_background_plans(tmp_path: Path) -> None:
    """The loop and its later passes are planned in the node's worker (here a thread), in their turn."""
    core, player = _live_player(tmp_path)
    try:
        settle = functools.partial(_settle, player)

        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 0.0, SENDER)  # waits behind the play's plan
        settle(0.0)
        first_end = player.end_time
        toms = _times(player, EventType.HIGHTOM)
        assert toms[:3] == pytest.approx([5.5, 9.5, 13.5], abs=1e-3)
        settle(first_end - 15.0)  # more passes, planned in the worker
        assert player.end_time >= first_end - 15.0 + LOOP_AHEAD_S and core.rejected == {}
    finally:
        core.close()


def test_a_second_looped_play_says_its_passes_again(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """Loop, play, stop; loop and play again: the second play's start and wraps are said as the first's (the
    review found the second play said none: what was said was remembered across plays)."""
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreLoop(first=3, last=4), 0.0, SENDER)
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        for k in range(0, 400):
            player.pump(k / 10)
        core.handle(ScoreTransport(action="stop", time=40.0, position=0.0), 40.0, SENDER)
        first = len(_said(caplog, "loop bars 3-4 wraps"))
        caplog.clear()
        core.handle(ScoreLoop(first=3, last=4), 41.0, SENDER)
        core.handle(ScoreTransport(action="play", time=42.0, position=0.0), 41.0, SENDER)
        for k in range(410, 800):
            player.pump(k / 10)
        assert first >= 5
        assert len(_said(caplog, "loop bars 3-4 starts")) == 1
        assert len(_said(caplog, "loop bars 3-4 wraps")) >= 5


# one bar of 16ths at 400 bpm (0.6 s) and a second bar: a tiny loop at a fast tempo
FAST_BAR = """tempo 400
meter 4/4
HH |xxxxxxxxxxxxxxxx|xxxxxxxxxxxxxxxx|
"""
SIXTEENTH_S = 60.0 / 400 / 4


class _Counted(tuple):  # type: ignore[type-arg]
    """A timeline's segments that count how many of them are read (indexed or iterated)."""

    reads = 0

    def __getitem__(self, k):  # type: ignore[no-untyped-def]
        got = super().__getitem__(k)
        _Counted.reads += len(got) if isinstance(k, slice) else 1
        return got

    def __iter__(self):  # type: ignore[no-untyped-def]
        for seg in super().__iter__():
            _Counted.reads += 1
            yield seg


def _fast_loop(tmp_path: Path) -> tuple[PhysicsCore, ScorePlayer]:
    (tmp_path / "fast.txt").write_text(FAST_BAR, encoding="utf-8")
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0)
    player = core.score_player
    player.library = [tmp_path]
    core.handle(ScoreLoad(path="fast.txt"), 0.0, SENDER)
    core.handle(ScoreLoop(first=1, last=1), 0.0, SENDER)
    core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
    return core, player


def test_a_tiny_fast_loop_lays_at_most_the_cap_and_still_extends_on_the_beat(tmp_path: Path) -> None:
    """A bar of 16ths at 400 bpm asked for 60 s laid 100 passes (1,600 notes; x4: 400 passes, 3 s of planning per
    re-plan): at most MAX_LOOP_PASSES now, and more are planned a third of them before they run out, on the beat."""
    core, player = _fast_loop(tmp_path)
    timeline = player._timeline  # noqa: SLF001
    assert timeline is not None
    passes = [seg for seg in timeline.segments if seg.loop is not None]
    assert len(passes) == MAX_LOOP_PASSES  # 16 notes a pass: the passes' cap, not the notes' (2,000 / 16 = 125)
    first_end = player.end_time
    laid_s = MAX_LOOP_PASSES * 16 * SIXTEENTH_S  # 38.4 s: a third of it left (12.8 s) asks for more
    player.pump(timeline.loop_end + 1.0 - laid_s / 3 - 1.0)  # 13.8 s left (LOOP_EXTEND_S would re-plan here)
    assert player.end_time == first_end
    player.pump(timeline.loop_end + 1.0 - laid_s / 3 + 1.0)
    assert player.end_time > first_end + 20.0 and core.rejected == {}
    hats = _times(player, EventType.HIHATCLOSED)
    assert len(hats) > 16 * MAX_LOOP_PASSES
    # on the beat: every 16th from the play's first (rig 1 s) on, the new passes' too (the notes kept start a
    # re-plan's context before)
    start = round((hats[0] - 1.0) / SIXTEENTH_S)
    assert hats == pytest.approx([1.0 + (start + k) * SIXTEENTH_S for k in range(len(hats))], abs=1e-3)
    core.close()


def test_a_loop_costs_a_step_a_few_segments_however_many_passes_are_laid(tmp_path: Path) -> None:
    """The live node pumps at every physics step (1 kHz): saying wraps, checking whether more passes are needed and
    the view's position read a few of the timeline's segments a step, not all (they scanned every segment: ~97 us
    a step with 101 of them, ~230 us with 401)."""
    core, player = _fast_loop(tmp_path)
    timeline = player._timeline  # noqa: SLF001
    assert timeline is not None
    counted = Timeline(timeline.score, _Counted(timeline.segments))
    player._timeline = counted  # noqa: SLF001
    player.pump(0.5)  # once per timeline: its last pass and pass numbers are found
    player.clock(0.5)
    _Counted.reads = 0
    steps = 3000  # 3 s of steps at 1 kHz: five passes
    for k in range(steps):
        now = 1.0 + k / 1000
        player.pump(now)
        player.clock(now)
    bound = 2 * math.ceil(math.log2(len(counted.segments) + 1)) + 8  # two bisections and a few more
    assert _Counted.reads <= bound * steps, _Counted.reads / steps
    core.close()


def _long_loop(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> tuple[list[str], int, list[float]]:
    """Bars 3-4 looped for 300 s (about 7 extensions, a tempo change among them), paused, resumed from the pause's
    position: the log, the most segments a timeline held and the resumed play's notes."""
    core, player = _player(tmp_path)
    most = 0
    caplog.clear()
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
        for k in range(2480):
            now = 2.0 + k / 10
            player.pump(now)
            player.clock(now)
            if player._timeline is not None:  # noqa: SLF001
                most = max(most, len(player._timeline.segments))  # noqa: SLF001
        core.handle(TempoScale(factor=1.25), 250.0, SENDER)  # a re-plan at another tempo on the way
        for k in range(510):
            player.pump(250.0 + k / 10)
        core.handle(ScoreTransport(action="pause", time=301.3, position=0.0), 301.0, SENDER)
        player.pump(302.0)
        said = _said(caplog, "pause at")[0]
        position = float(said.split("score ")[1].split(" s")[0])
        core.handle(ScoreTransport(action="play", time=305.0, position=position), 303.0, SENDER)
    core.close()
    assert core.rejected == {}
    lines = [r.getMessage() for r in caplog.records if r.name == LOGGER and not r.getMessage().startswith("planner")]
    return lines, most, [e.time for e in player.events if e.time >= 305.0]


def test_a_long_loop_keeps_a_bounded_timeline_and_says_the_same(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Each extension laid the loop again from the play's start: the timeline kept every pass played (a long loop's
    re-plans looked through them all, and more each time). Now only the passes from the one before the pass in
    progress are kept: a bounded count, and the log (wraps and their pass numbers, re-plans, the pause's bar and beat,
    the summary) and the resumed play are the same as with every pass kept."""
    lines, most, resumed = _long_loop(tmp_path, caplog)
    bound = LOOP_AHEAD_S / LOOP_S + 4  # the passes laid ahead, the one in progress, the one before, a bar after
    assert most <= bound
    wraps = [m for m in lines if m.startswith("loop bars 3-4 wraps")]
    assert len(wraps) > 60 and [int(m.split("(pass ")[1].split(")")[0]) for m in wraps] == list(
        range(2, len(wraps) + 2))
    monkeypatch.setattr(Timeline, "since", lambda self, played: self)  # every pass kept, as before
    kept, grown, resumed_kept = _long_loop(tmp_path, caplog)
    assert grown > 3 * bound  # the bound above is not one any timeline meets
    assert lines == kept and resumed == pytest.approx(resumed_kept, abs=1e-9)


def test_a_looped_plays_summary_counts_its_passes_as_a_teacher_does(tmp_path: Path,
                                                                    caplog: pytest.LogCaptureFixture) -> None:
    """The end-of-play line said ``254 of 254 notes played`` of a play looping a two-bar loop (every note its passes
    planned): now the notes played and the passes reached, with a pass's notes (bars 1-4 once, 29 notes, then
    passes of bars 3-4, 15 notes each)."""
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
        for k in range(180):
            player.pump(2.0 + k / 10)
        # in pass 3 (rig 17-21 s), bar 4 beat 3.6: 2 of its 15 notes left
        core.handle(ScoreTransport(action="stop", time=20.3, position=0.0), 20.0, SENDER)
        player.pump(22.0)
        # off in pass 2 (rig 13-17 s): it ends, then bar 5 (7 notes) and the end of the score
        core.handle(ScoreTransport(action="play", time=30.0, position=0.0), 29.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 29.5, SENDER)
        core.handle(ScoreLoop(first=0, last=0), 43.0, SENDER)
        player.pump(player.end_time + 0.1)
    core.close()
    assert _said(caplog, "five.txt:") == [
        "five.txt: 72 notes played with 3 passes of bars 3-4 (15 notes a pass); not played: 182 cut by the stop; "
        "stopped at rig 20.300 s: score 7.300 s, bar 4 beat 3.6",
        "five.txt: 66 notes played with 2 passes of bars 3-4 (15 notes a pass); ended after its last note at score "
        "9.500 s, bar 5 beat 4.0"]



def test_a_score_loaded_while_the_playing_one_loops_ends_its_loop_as_loop_off_does(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """The review's repro: a load during pass 2 said "loop bars 3-4 ended by the new score", yet the passes laid
    (~60 s) played on and the play stopped at the last one (bar 5 never played). Now the pass in progress ends, then
    the rest of the score (bar 5, its floor tom), as ``loop 0 0`` would; the new score is for the next play."""
    core, player = _player(tmp_path)
    (tmp_path / "snares.txt").write_text(SNARES, encoding="utf-8")
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
        for k in range(120):
            player.pump(2.0 + k / 10)
        core.handle(ScoreLoad(path="snares.txt"), 14.0, SENDER)  # in pass 2 (rig 13-17 s)
        assert _said(caplog, "loop off: the pass in progress ends at rig 17.000 s, then the rest of the score from "
                     "score 8.000 s, bar 5 beat 1.0")
        assert _times(player, EventType.FLOORTOM) == pytest.approx([17.0])  # bar 5 right after pass 2
        assert player.end_time < 20.0 and player.loop is None
        for k in range(80):
            player.pump(14.0 + k / 10)
    core.close()
    assert core.rejected == {}
    assert _said(caplog, "five.txt:") == [
        "five.txt: 66 notes played with 2 passes of bars 3-4 (15 notes a pass); ended after its last note at score "
        "9.500 s, bar 5 beat 4.0"]


def test_the_live_node_ends_the_playing_scores_loop_at_a_load_in_its_worker(tmp_path: Path) -> None:
    """The same through the node's background plans: the load's re-plan runs in the worker, in its turn."""
    core, player = _live_player(tmp_path)
    try:
        (tmp_path / "snares.txt").write_text(SNARES, encoding="utf-8")
        settle = functools.partial(_settle, player)

        core.handle(ScoreTransport(action="play", time=1.5, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 0.0, SENDER)
        settle(0.0)
        assert player.end_time > 50.0 and not _times(player, EventType.FLOORTOM)
        plans = player.plans
        core.handle(ScoreLoad(path="snares.txt"), 11.0, SENDER)  # in pass 1 (rig 9.5-13.5 s)
        settle(11.0)
        assert player.plans == plans + 1 and core.rejected == {}
        assert _times(player, EventType.FLOORTOM) == pytest.approx([13.5])  # bar 5 right after pass 1
        assert player.end_time < 17.0 and player.score is not None and len(player.score.events) == 12
    finally:
        core.close()


def test_a_play_that_ends_on_a_loops_pass_says_where_it_ended(tmp_path: Path,
                                                              caplog: pytest.LogCaptureFixture) -> None:
    """A looped play that ran to the end of its last laid pass (no more passes planned: here its summary is asked
    without the steps that extend it) ended in bar 4; the summary said the score's last note, in bar 5."""
    core, player = _player(tmp_path)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
        core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
        player.say_ended(player.end_time + 0.1)
    core.close()
    passes = int(LOOP_AHEAD_S // LOOP_S)
    assert _said(caplog, "five.txt:") == [
        f"five.txt: {29 + 15 * passes} notes played with {passes} passes of bars 3-4 (15 notes a pass); ended after "
        f"its last note at score 7.500 s, bar 4 beat 4.0, in pass {passes} of bars 3-4 (the last laid)"]


def test_a_long_loops_re_plans_keep_a_bounded_list_of_clocks(tmp_path: Path,
                                                              caplog: pytest.LogCaptureFixture) -> None:
    """Each re-plan adds its clock (a stop or pause before its anchor is said with the one sounding then); until
    7 Dec none was ever dropped (~90 an hour in a long loop). Those no longer in force before the targets' clock are
    dropped; a pause just after a re-plan is still said with the clock sounding then."""
    core, player = _player(tmp_path)
    core.handle(ScoreTransport(action="play", time=1.0, position=0.0), 0.0, SENDER)
    core.handle(ScoreLoop(first=3, last=4), 1.5, SENDER)
    for k in range(20):
        core.handle(TempoScale(factor=1.0 + 0.001 * (k % 2)), 2.0 + 0.5 * k, SENDER)  # a re-plan each
    assert player.plans == 22
    assert len(player._clocks) <= 2 + int(CLOCKS_KEPT_S / 0.5)  # noqa: SLF001
    anchor = player.mapping
    assert anchor is not None
    with caplog.at_level(logging.INFO, logger=LOGGER):
        player.pause(anchor[0] - 0.05, 11.6)  # before the latest anchor: the clock before it sounds
    core.close()
    (said,) = _said(caplog, "pause at")
    assert "before the score started" not in said
