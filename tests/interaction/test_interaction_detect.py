"""Impact detection on synthetic contact streams: exactly the expected impacts, features to 1 mm and 1 %."""

from __future__ import annotations

import math

import pytest

from common.core import Outgoing
from common.kit import Kit, load_kit
from common.messages import Contact, Impact
from common.messages.interaction import Damping, ImpactEnd
from services.interaction.config import InteractionConfig, RedundancyConfig
from services.interaction.core import InteractionCore
from services.interaction.detect import DetectionConfig, Segmenter
from services.interaction.features import ZoneConfig, polar, zone
from services.interaction.synthetic import (
    StreamBuilder,
    buzz,
    chatter,
    dead_stroke,
    double_stroke,
    drive,
    merged,
    rest,
    strike,
)

KIT = load_kit("default")


def single_copy_core(kit: Kit = KIT) -> InteractionCore:
    """A core sending one copy of each message, to sound only (easier to count)."""
    config = InteractionConfig(redundancy=RedundancyConfig(copies=1), routes=[{"to": "sound"}])  # type: ignore[list-item]
    return InteractionCore(kit=kit, config=config)


def run(contacts: list[Contact]) -> tuple[list[Impact], list[ImpactEnd], list[Damping]]:
    out = [o for _, o in drive(single_copy_core(), contacts)]
    return (
        [o.message for o in out if isinstance(o.message, Impact)],
        [o.message for o in out if isinstance(o.message, ImpactEnd)],
        [o.message for o in out if isinstance(o.message, Damping)],
    )


def test_single_strike_gives_one_impact_with_its_features() -> None:
    b = strike(StreamBuilder(KIT, "snare"), t=1.0, velocity=3.2, at=(0.05, -0.04), steps=5)
    impacts, ends, dampings = run(b.contacts)
    assert len(impacts) == 1 and len(ends) == 1 and dampings == []
    truth = b.truths[0]
    impact, end = impacts[0], ends[0]
    assert impact.time == pytest.approx(1.0, abs=1e-9)
    assert impact.instrument == "snare" and impact.part == "right_stick_tip"
    radius = KIT.object("snare").radius
    # position to 1 mm: r/a and theta back to the local point
    x, y = impact.r * radius * math.cos(impact.theta), impact.r * radius * math.sin(impact.theta)
    assert math.hypot(x - truth.local_x, y - truth.local_y) < 1e-3
    assert impact.velocity == pytest.approx(truth.velocity, rel=0.01)
    assert impact.duration == impact.impulse == impact.peak_force == 0.0  # unknown at onset
    assert end.seq == impact.seq and end.kind == "strike"
    assert end.impulse == pytest.approx(truth.impulse, rel=0.01)
    assert end.peak_force == pytest.approx(truth.peak_force, rel=0.01)
    assert end.duration == pytest.approx(truth.duration, rel=0.01)
    assert impact.zone == "centre"


def test_impact_at_end_carries_every_final_figure() -> None:
    b = strike(StreamBuilder(KIT, "ride"), t=1.0, velocity=2.0, at=(0.1, 0.05), steps=5)
    config = InteractionConfig(impact_at="end", redundancy=RedundancyConfig(copies=1), routes=[{"to": "sound"}])  # type: ignore[list-item]
    out = drive(InteractionCore(kit=KIT, config=config), b.contacts)
    sent = [(t, o.message) for t, o in out if isinstance(o.message, Impact)]
    assert len(sent) == 1
    t, impact = sent[0]
    truth = b.truths[0]
    assert t > 1.0 + truth.duration  # sent once the contact is over...
    assert impact.time == pytest.approx(1.0, abs=1e-9)  # ... stamped with its first contact
    assert impact.velocity == pytest.approx(truth.velocity, rel=0.01)
    assert impact.impulse == pytest.approx(truth.impulse, rel=0.01)
    assert impact.peak_force == pytest.approx(truth.peak_force, rel=0.01)
    assert impact.duration == pytest.approx(truth.duration, rel=0.01)
    assert impact.zone == "bow"


def test_chattering_contact_does_not_retrigger() -> None:
    b = chatter(StreamBuilder(KIT, "snare"), t=0.5, velocity=2.0)
    core = single_copy_core()
    out = [o.message for _, o in drive(core, b.contacts)]
    impacts = [m for m in out if isinstance(m, Impact)]
    ends = [m for m in out if isinstance(m, ImpactEnd)]
    assert len(impacts) == 1 and len(ends) == 1
    assert core.segmenter.stats.chatter == 2
    truth = b.truths[0]
    assert ends[0].impulse == pytest.approx(truth.impulse, rel=0.01)  # chatter steps add to the same impact
    assert ends[0].duration == pytest.approx(0.006, rel=0.01)


def test_fast_rebound_after_a_one_step_gap_is_still_chatter() -> None:
    """Even a fast re-contact within the retrigger gap belongs to the same strike."""
    b = StreamBuilder(KIT, "floortom")
    b.pulse(1.0, 3.0, steps=3)
    b.pulse(1.004, 2.9, steps=2, truth=False)  # one missing step (t = 1.003), back at 1.004
    impacts, ends, _ = run(b.contacts)
    assert len(impacts) == 1 and len(ends) == 1


def test_contact_sliding_from_tip_to_shaft_stays_one_impact() -> None:
    """Physics names the part from where the stick touches; a rimshot's contact can move along the stick."""
    tip = StreamBuilder(KIT, "snare", "left_stick_tip")
    tip.pulse(1.0, 3.0, steps=2)
    shaft = StreamBuilder(KIT, "snare", "left_stick_shaft")
    shaft.pulse(1.002, 3.0, steps=3, truth=False)  # physics repeats the episode's approach speed
    other = strike(StreamBuilder(KIT, "snare", "right_stick_shaft"), t=1.003, velocity=1.0)
    impacts, ends, _ = run(merged(tip, shaft, other))
    assert [(i.part, round(i.velocity, 3)) for i in impacts] == [("left_stick_tip", 3.0), ("right_stick_shaft", 1.0)]
    assert ends[0].duration == pytest.approx(0.005, rel=0.01)


def test_double_stroke_20_ms_apart_gives_two_strikes() -> None:
    b = double_stroke(StreamBuilder(KIT, "snare", "left_stick_tip"), t=2.0, velocity=3.0, gap=0.020)
    impacts, ends, _ = run(b.contacts)
    assert [round(i.time, 6) for i in impacts] == [2.0, 2.02]
    assert [e.kind for e in ends] == ["strike", "strike"]
    assert [i.velocity for i in impacts] == pytest.approx([3.0, 2.85], rel=0.01)
    assert len({i.seq for i in impacts}) == 2


def test_a_stick_falling_back_onto_the_head_it_just_struck_is_part_of_that_stroke() -> None:
    """The retrigger mask: a slow re-contact 12 ms after a strike is the stroke's own rebound touch (no impact);
    the same touch later than the mask, or a fast one inside it, is a strike of its own."""
    b = strike(StreamBuilder(KIT, "snare", "left_stick_tip"), t=1.0, velocity=3.0)
    b = strike(b, t=1.012, velocity=0.6)  # falls back at a fifth of the speed
    b = strike(b, t=2.0, velocity=3.0)
    b = strike(b, t=2.045, velocity=0.6)  # after the mask: a (soft) strike of its own
    b = strike(b, t=3.0, velocity=3.0)
    b = strike(b, t=3.015, velocity=2.5)  # a double stroke inside the mask
    segmenter = Segmenter(KIT)
    onsets = [round(e.impact.time, 3) for c in b.contacts for e in segmenter.contact(c, c.time)
              if hasattr(e, "impact") and not e.impact.final]
    assert onsets == [1.0, 2.0, 2.045, 3.0, 3.015]
    assert segmenter.stats.masked == 1


def test_buzz_roll_gives_one_impact_per_rebound_then_damping() -> None:
    left = StreamBuilder(KIT, "snare", "left_stick_tip")
    right = StreamBuilder(KIT, "snare", "right_stick_tip")
    expected = 0
    for n in range(4):  # four buzz strokes, alternating hands, 150 ms apart
        expected += buzz(left if n % 2 == 0 else right, t=1.0 + 0.15 * n, velocity=2.0, interval=0.008)
    impacts, ends, dampings = run(merged(left, right))
    assert expected == 4 * 8
    assert len(impacts) == expected
    kinds = [e.kind for e in sorted(ends, key=lambda e: e.time)]
    assert kinds[:8] == ["strike", "bounce"] + ["buzz"] * 6
    assert kinds.count("strike") == 4
    # each buzz stroke ends with the stick resting: damping on then off, per stroke
    assert [d.state for d in dampings] == [1, 0] * 4
    assert all(i.velocity >= 0.05 for i in impacts)


def test_dead_stroke_is_one_impact_then_damping_not_more_strikes() -> None:
    b = dead_stroke(StreamBuilder(KIT, "hightom"), t=0.3, velocity=2.5, hold=0.2)
    impacts, ends, dampings = run(b.contacts)
    assert len(impacts) == 1
    assert [e.kind for e in ends] == ["dead"]
    assert [d.state for d in dampings] == [1, 0]
    on, off = dampings
    assert on.time == pytest.approx(0.3 + 0.025, abs=0.0015)  # recognised after press_after
    assert off.time == pytest.approx(0.3 + 0.004 + 0.2, abs=0.0015)
    assert on.force > 0 and off.force == 0
    assert ends[0].duration < 0.03


def test_resting_stick_is_damping_only() -> None:
    b = rest(StreamBuilder(KIT, "snare"), t=0.1, duration=0.3)
    impacts, ends, dampings = run(b.contacts)
    assert impacts == [] and ends == []
    assert [d.state for d in dampings] == [1, 0]


def test_slow_touch_is_not_a_strike() -> None:
    b = StreamBuilder(KIT, "snare")
    b.pulse(0.2, 0.02, steps=3)  # under strike_velocity_min
    impacts, _, dampings = run(b.contacts)
    assert impacts == [] and dampings == []


def test_a_hihat_let_down_slowly_is_silent_but_a_stick_as_slow_strikes() -> None:
    """The top plate's own slowest strike (part_velocity_min): the foot letting the hi-hat down is no chick."""
    slow_close = strike(StreamBuilder(KIT, "hihat", "hihat_top"), t=1.0, velocity=0.07)
    chick = strike(StreamBuilder(KIT, "hihat", "hihat_top"), t=2.0, velocity=0.2)
    soft_stick = strike(StreamBuilder(KIT, "snare", "left_stick_tip"), t=1.0, velocity=0.07)
    impacts, _, _ = run(merged(slow_close, chick, soft_stick))
    assert [(round(i.time, 3), i.part) for i in impacts] == [(1.0, "left_stick_tip"), (2.0, "hihat_top")]


def test_two_sticks_at_once_are_two_impacts_and_tracks_do_not_interfere() -> None:
    left = strike(StreamBuilder(KIT, "snare", "left_stick_tip"), t=1.0, velocity=2.0)
    right = strike(StreamBuilder(KIT, "snare", "right_stick_tip"), t=1.001, velocity=2.5, at=(-0.05, 0.0))
    kick = strike(StreamBuilder(KIT, "kick", "kick_beater"), t=1.0, velocity=1.5)
    impacts, ends, _ = run(merged(left, right, kick))
    assert sorted((i.instrument, i.part) for i in impacts) == [
        ("kick", "kick_beater"),
        ("snare", "left_stick_tip"),
        ("snare", "right_stick_tip"),
    ]
    assert len(ends) == 3


def test_hihat_plates_rattling_after_a_stick_stroke_are_not_a_strike_but_a_pedal_chick_is() -> None:
    """Physics reports the plates meeting as hihat_rattle when the foot is not closing the pedal (a stick knocked
    them together) and as hihat_top when it is (a chick): the rattle is no impact, the chick is one, even right
    after a stick stroke (an open hi-hat closed by the foot 30 ms later)."""
    stick = strike(StreamBuilder(KIT, "hihat", "right_stick_tip"), t=1.0, velocity=3.0)
    rattle = strike(StreamBuilder(KIT, "hihat", "hihat_rattle"), t=1.008, velocity=0.3)  # plates knocked together
    chick = strike(StreamBuilder(KIT, "hihat", "hihat_top"), t=1.5, velocity=0.3)  # the foot closes the hi-hat
    impacts, _, _ = run(merged(stick, rattle, chick))
    assert [(round(i.time, 3), i.part) for i in impacts] == [(1.0, "right_stick_tip"), (1.5, "hihat_top")]
    open_hit = strike(StreamBuilder(KIT, "hihat", "right_stick_tip"), t=1.0, velocity=3.0)
    closed_at_once = strike(StreamBuilder(KIT, "hihat", "hihat_top"), t=1.03, velocity=0.3)
    assert len(run(merged(open_hit, closed_at_once))[0]) == 2


def test_unknown_instrument_and_throne_are_counted_not_impacts() -> None:
    segmenter = Segmenter(KIT)
    base = strike(StreamBuilder(KIT, "snare"), t=0.0).contacts[0]
    assert segmenter.contact(base.model_copy(update={"instrument": "gong"}), 0.0) == []
    assert segmenter.contact(base.model_copy(update={"instrument": "throne"}), 0.0) == []
    assert segmenter.stats.unknown_instrument == 1 and segmenter.stats.ignored == 1


def test_contact_end_uses_the_physics_clock_not_a_late_receiver_clock() -> None:
    """A receiver whose clock runs 20 ms ahead of physics must not cut contacts into pieces."""
    b = StreamBuilder(KIT, "snare")
    b.pulse(1.0, 3.0, steps=6)
    core = single_copy_core()
    out: list[Outgoing] = []
    for c in b.contacts:
        now = c.time + 0.020
        out += core.handle(c, now, "physics")
        out += core.step(now)
    for k in range(30):
        out += core.step(1.03 + k * 0.001)
    assert sum(isinstance(o.message, Impact) for o in out) == 1
    ends = [o.message for o in out if isinstance(o.message, ImpactEnd)]
    assert len(ends) == 1 and ends[0].duration == pytest.approx(0.006, rel=0.01)


def test_a_physics_node_that_falls_behind_mid_contact_does_not_split_the_strike() -> None:
    """Live physics catching up delivers the rest of a contact late: still one impact, not a strike + bounce."""
    b = StreamBuilder(KIT, "snare")
    b.pulse(1.0, 3.0, steps=6)
    core = single_copy_core()
    out: list[Outgoing] = []
    first, rest = b.contacts[:2], b.contacts[2:]
    for c in first:  # on time
        out += core.handle(c, c.time + 0.0005, "physics")
        out += core.step(c.time + 0.0005)
    for k in range(30):  # physics stalls for 30 ms; the receiver's clock ends the contact meanwhile
        out += core.step(first[-1].time + 0.001 * (k + 1))
    for c in rest:  # then the stalled steps arrive in a burst
        out += core.handle(c, 1.04, "physics")
    out += core.step(1.1)
    assert sum(isinstance(o.message, Impact) for o in out) == 1
    assert core.segmenter.stats.reopened == 1


def test_a_contact_earlier_than_the_last_one_is_a_new_strike_not_a_continuation() -> None:
    """After a physics reset time starts again: its first contact is a new impact, not the old one going on."""
    core = single_copy_core()
    out: list[Outgoing] = []
    first = StreamBuilder(KIT, "snare")
    first.pulse(100.0, 3.0, steps=3)
    for c in first.contacts:
        out += core.handle(c, c.time, "physics")
        out += core.step(c.time)
    for k in range(40):  # the receiver's clock ends it
        out += core.step(100.01 + k * 0.001)
    again = StreamBuilder(KIT, "snare")
    again.pulse(1.0, 3.0, steps=3)
    for c in again.contacts:
        out += core.handle(c, 100.1, "physics")
    assert sum(isinstance(o.message, Impact) for o in out) == 2
    assert core.segmenter.stats.reopened == 0


@pytest.mark.parametrize(
    ("instrument", "r", "expected"),
    [
        ("snare", 0.2, "centre"),
        ("snare", 0.8, "edge"),
        ("snare", 0.99, "rim"),
        ("snare", 1.05, "rim"),
        ("ride", 0.1, "bell"),
        ("ride", 0.5, "bow"),
        ("ride", 0.9, "edge"),
        ("hihat", 0.6, "bow"),
        ("cowbell", 0.9, "edge"),
        ("kick_pedal", 0.3, "centre"),
    ],
)
def test_zones_from_the_kit(instrument: str, r: float, expected: str) -> None:
    assert zone(KIT.object(instrument), r, ZoneConfig()) == expected


def test_polar_position_in_the_instrument_frame() -> None:
    snare = KIT.object("snare")
    r, theta = polar(snare, 0.0, snare.radius / 2)
    assert r == pytest.approx(0.5) and theta == pytest.approx(math.pi / 2)
    assert polar(snare, 0.0, 0.0) == (0.0, 0.0)
    assert polar(snare, 5.0, 0.0)[0] == 2.0  # clipped to the Impact's range


def test_thresholds_are_configuration() -> None:
    """A larger retrigger gap turns the 20 ms double stroke into one impact."""
    b = double_stroke(StreamBuilder(KIT, "snare"), t=0.0, gap=0.020)
    config = InteractionConfig(
        detection=DetectionConfig(retrigger_gap=0.05, press_after=1.0),
        redundancy=RedundancyConfig(copies=1),
        routes=[{"to": "sound"}],  # type: ignore[list-item]
    )
    out = drive(InteractionCore(kit=KIT, config=config), b.contacts, tail=0.1)
    assert sum(isinstance(o.message, Impact) for _, o in out) == 1
