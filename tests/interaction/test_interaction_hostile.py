"""Interaction under bad input: broken configuration files, hostile control messages and contact streams.

The project rule: bad input gets a clear one-line error and is counted; it never crashes the node, never
loses other data and never makes memory grow without bound.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from common.core import Outgoing
from common.kit import load_kit
from common.messages import Contact, Impact, decode, encode
from common.messages.interaction import (
    Damping,
    ImpactEnd,
    InteractionError,
    InteractionStats,
    ListEnd,
    MapInfo,
    MapList,
    MapSet,
    MessageAdd,
    MessageInfo,
    MessageList,
    RouteSet,
    StatsGet,
)
from services.interaction import detect, mapping
from services.interaction.config import FileConfigStore, InteractionConfig, RedundancyConfig, load_config
from services.interaction.core import InteractionCore
from services.interaction.node import InteractionSettings, main, make_core
from services.interaction.synthetic import StreamBuilder, dead_stroke, merged, strike

KIT = load_kit("default")


def one_copy_core() -> InteractionCore:
    config = InteractionConfig(redundancy=RedundancyConfig(copies=1), routes=[{"to": "sound"}])  # type: ignore[list-item]
    return InteractionCore(kit=KIT, config=config)


def contact(time: float, step: int, *, part: str = "right_stick_tip", velocity: float = 3.0,
            impulse: float = 0.01, force: float = 10.0, instrument: str = "snare") -> Contact:
    """One contact step as physics sends it (the approach velocity repeated in every step of a contact)."""
    return Contact(time=time, step=step, instrument=instrument, part=part, x=0.0, y=0.0, z=0.0,
                   local_x=0.01, local_y=0.0, local_z=0.0, normal_x=0.0, normal_y=0.0, normal_z=1.0,
                   normal_velocity=velocity, impulse=impulse, normal_force=force)  # fmt: skip


def errors(out: list[Outgoing]) -> list[InteractionError]:
    return [o.message for o in out if isinstance(o.message, InteractionError)]


def played(core: InteractionCore, t0: float, clock_shift: float = 0.0) -> tuple[int, int, int]:
    """Two sticks on two drums, five strokes each held 5 steps (velocity repeated), then a dead stroke:
    (impacts, impact ends, dampings) sent. ``clock_shift``: the receiver's clock minus the physics clock, s."""
    snare = StreamBuilder(KIT, "snare", "right_stick_tip")
    tom = StreamBuilder(KIT, "hightom", "left_stick_tip")
    for i in range(5):
        strike(snare, t0 + 0.1 * i, 3.0, steps=5)
        strike(tom, t0 + 0.1 * i + 0.002, 3.0, steps=5)
    dead_stroke(snare, t0 + 0.8)
    contacts = [c.model_copy(update={"normal_velocity": 3.0}) if c.normal_velocity > 0 else c
                for c in merged(snare, tom)]
    out: list[Outgoing] = []
    by_step: dict[int, list[Contact]] = {}
    for c in contacts:
        by_step.setdefault(c.step, []).append(c)
    first, last = min(by_step), max(by_step) + 50
    for step in range(first, last + 1):
        now = step * 0.001 + clock_shift
        for c in by_step.get(step, ()):
            out.extend(core.handle(c, now, "physics"))
        out.extend(core.step(now))
    kinds = [type(o.message) for o in out]
    return kinds.count(Impact), kinds.count(ImpactEnd), kinds.count(Damping)


# --------------------------------------------------------------------------- configuration files


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("routes: 5\n", "routes"),
        ("redundancy: {copies: 0}\n", "redundancy.copies"),
        ("[1, 2]\n", "dictionary"),
        ("detection: {part_velocity_min: {hihat_top: .nan}}\n", "part_velocity_min"),
        ("detection: {part_suffixes: [_tip, '']}\n", "part_suffixes"),  # '' made every part one striker
        ("routes: [{to: sound, fields: {velocity: {feature: velocity, curve: {kind: linear, in_range: [.nan, 1]}}}}]\n",
         "in_range"),
    ],
)
def test_a_bad_configuration_file_is_refused_with_one_line(tmp_path: Path, text: str, where: str,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "interaction.yaml"
    path.write_text(text)
    with pytest.raises(ValueError) as caught:
        load_config(path)
    assert "\n" not in str(caught.value) and where in str(caught.value) and str(path) in str(caught.value)
    assert main(["--no-discovery", "--no-oscquery", "--interaction-config", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and where in err and "errors.pydantic.dev" not in err


def test_a_directory_given_as_the_configuration_file_is_refused(tmp_path: Path) -> None:
    settings = InteractionSettings(interaction_config=str(tmp_path), discovery=False)
    with pytest.raises(ValueError, match="directory"):
        make_core(settings, argparse.Namespace())


def test_a_change_that_cannot_be_saved_changes_nothing(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("")
    core = InteractionCore(kit=KIT, store=FileConfigStore(blocker / "interaction.yaml"))
    before = core.config
    out = core.handle(RouteSet(to="127.0.0.1:9999", instruments="*"), 0.0, "pd")
    assert len(errors(out)) == 1 and core.control_errors == 1
    assert core.config == before  # the error says it failed: it did not half-happen


# --------------------------------------------------------------------------- control messages


@pytest.mark.parametrize(
    "message",
    [
        MapSet(to="sound", field="impulse", spec="=1e39"),  # beyond float32: cannot be sent
        MapSet(to="sound", field="velocity", spec="velocity:linear:nan:1:0:1"),
        MapSet(to="sound", field="velocity", spec="velocity:linear:0:inf:0:1"),
        MapSet(to="sound", field="velocity", spec="velocity@s"),  # a number field sent as a string
        RouteSet(to="127.0.0.1:99999", instruments="*"),
        RouteSet(to="127.0.0.1:", instruments="*"),
        MessageAdd(name="m", to="pd:host:0", address="/x", instruments="*", when="onset", specs=("velocity",)),
        MessageAdd(name="m", to="pd", address="/x", instruments="*", when="onset", specs=("=3e38@f", "=1e39")),
        MessageAdd(name="m", to="pd", address="/x", instruments="*", when="end",
                   specs=("x:linear:0:1:0:1e39",)),
    ],
    ids=lambda m: f"{m.ADDRESS}-{'-'.join(map(str, m.to_args()))}",
)
def test_invalid_edits_are_answered_with_an_error_and_change_nothing(message: object) -> None:
    core = InteractionCore(kit=KIT)
    before = core.config
    out = core.handle(message, 0.0, "pd")  # type: ignore[arg-type]
    assert len(errors(out)) == 1 and core.control_errors == 1
    assert core.config == before


def test_every_message_sent_can_be_encoded_even_for_huge_mapped_or_physical_values() -> None:
    config = InteractionConfig(redundancy=RedundancyConfig(copies=1),
                               routes=[{"to": "sound"}, {"to": "graphics"}])  # type: ignore[list-item]
    core = InteractionCore(kit=KIT, config=config)
    core.handle(MapSet(to="sound", field="peak_force", spec="peak_force:linear:0:1:0:3e38"), 0.0, "pd")
    core.handle(MapSet(to="sound", field="impulse", spec="impulse:table:0:0:1:3e38"), 0.0, "pd")
    core.handle(MessageAdd(name="m", to="pd", address="/m", instruments="*", when="end",
                           specs=("impulse", "peak_force", "impulse@f")), 0.0, "pd")
    assert core.control_errors == 0
    # two steps of a hostile (or broken) physics stream, each with the largest float32 impulse
    out = core.handle(contact(1.0, 1000, impulse=3.4e38, force=3.4e38), 1.0, "physics")
    out += core.handle(contact(1.001, 1001, impulse=3.4e38, force=3.4e38), 1.001, "physics")
    for t in range(1002, 1020):
        out += core.step(t * 0.001)
    assert [o.to for o in out if isinstance(o.message, ImpactEnd)] == ["sound", "graphics"]
    assert [o.to for o in out if o.message.ADDRESS == "/m"] == ["pd"]
    for o in out:
        encode(o.message)  # raised OverflowError in the node's step loop, which stopped the node


def test_routes_and_registered_messages_are_bounded() -> None:
    core = InteractionCore(kit=KIT)
    last: list[Outgoing] = []
    for i in range(mapping.MAX_ROUTES + 10):
        last = core.handle(RouteSet(to=f"127.0.0.1:{10000 + i}", instruments="*"), 0.0, "pd")
    assert len(core.config.routes) == mapping.MAX_ROUTES
    assert "at most" in errors(last)[0].detail
    for i in range(mapping.MAX_MESSAGES + 10):
        last = core.handle(MessageAdd(name=f"m{i}", to="pd", address="/m", instruments="*", when="onset",
                                      specs=("velocity",)), 0.0, "pd")
    assert len(core.config.messages) == mapping.MAX_MESSAGES
    assert "at most" in errors(last)[0].detail
    out = core.handle(MessageAdd(name="m0", to="pd", address="/m", instruments="*", when="onset",
                                 specs=("velocity",) * (mapping.MAX_ARGS + 1)), 0.0, "pd")
    assert "at most" in errors(out)[0].detail
    assert core.control_errors == 12 + 10 + 1  # the default routes (sound, graphics) were there already
    # editing or replacing what exists still works at the limit
    assert core.handle(RouteSet(to="sound", instruments="snare"), 0.0, "pd") == []
    assert core.handle(MessageAdd(name="m0", to="pd", address="/n", instruments="*", when="end",
                                  specs=()), 0.0, "pd") == []


# --------------------------------------------------------------------------- contact streams


def test_a_step_arriving_after_its_contact_ended_makes_no_second_impact() -> None:
    core = one_copy_core()
    out: list[Outgoing] = []
    steps = [contact(1.0 + i * 0.001, 1000 + i) for i in range(4)]
    for c in (steps[0], steps[1], steps[3]):  # step 2 is late
        out += core.handle(c, c.time, "physics") + core.step(c.time)
    for i in range(4, 12):
        out += core.step(1.0 + i * 0.001)
    out += core.handle(steps[2], 1.012, "physics")  # 9 ms late, after the contact's end was sent
    for i in range(13, 40):
        out += core.step(1.0 + i * 0.001)
    assert [type(o.message) for o in out].count(Impact) == 1
    assert core.segmenter.stats.out_of_order == 1
    # ... nor, arriving during the next contact, adds its impulse to that one
    out = core.handle(contact(1.1, 1100, impulse=0.02), 1.1, "physics")
    out += core.handle(steps[1], 1.1005, "physics")
    for i in range(1101, 1120):
        out += core.step(i * 0.001)
    ends = [o.message for o in out if isinstance(o.message, ImpactEnd)]
    assert len(ends) == 1 and ends[0].impulse == pytest.approx(0.02)
    assert core.segmenter.stats.out_of_order == 2
    stats = core.handle(StatsGet(), 1.25, "pd")[0].message  # and a user asking for the counts sees them
    assert isinstance(stats, InteractionStats) and stats.out_of_order == 2
    assert decode(encode(stats)).messages == [stats]  # over the wire too


@pytest.mark.parametrize("clock_shift", [0.0, 900.0], ids=["receiver-follows-physics", "receiver-own-clock"])
def test_physics_restarting_with_an_earlier_clock_is_segmented_as_before(clock_shift: float) -> None:
    fresh = played(one_copy_core(), 5.0)
    assert fresh == (11, 11, 2)
    core = one_copy_core()
    assert played(core, 900.0) == fresh
    # physics restarts: its clock starts again near 0; the receiver's clock either follows it (a clock slave,
    # once synced) or goes on (interaction its own master). Within a few seconds the strokes are what they were.
    played(core, 3.0, clock_shift)
    assert played(core, 6.0, clock_shift) == fresh


def test_one_contact_from_the_far_future_does_not_break_detection() -> None:
    core = one_copy_core()
    core.handle(contact(2.0e9, 5, instrument="crash"), 10.0, "physics")  # a broken or hostile sender
    played(core, 10.0)
    assert played(core, 13.0) == (11, 11, 2)


def test_contacts_of_ever_new_striker_names_do_not_grow_memory() -> None:
    core = one_copy_core()
    for i in range(detect.MAX_TRACKS * 4):
        c = contact(1.0 + i * 1e-5, 1000 + i, part=f"junk{i}", velocity=0.0)
        core.handle(c, c.time, "flood")
    assert core.segmenter.track_count <= detect.MAX_TRACKS
    assert core.segmenter.stats.dropped > 0
    assert played(core, 5.0) == (11, 11, 2)  # the real sticks still play once the flood stops


@pytest.mark.parametrize(
    ("spec", "reason"),
    [
        ("velocty", "unknown impact feature 'velocty'"),  # a typo
        ("velocity:linear:0:0:0:1", "in_range needs two different values"),
        ("instrument:linear:0:1:0:1", "is a string: no curve applies"),
        ("velocity:exp:0:1:0:1:99", "curvature"),
        ("=1e39", "beyond the largest OSC float"),
    ],
)
def test_a_bad_spec_is_answered_with_what_is_wrong(spec: str, reason: str) -> None:
    core = InteractionCore(kit=KIT)
    detail = errors(core.handle(MapSet(to="sound", field="velocity", spec=spec), 0.0, "pd"))[0].detail
    assert reason in detail and "errors.pydantic.dev" not in detail, detail


@pytest.mark.parametrize(
    "message",
    [
        RouteSet(to="sound", instruments="snrae"),  # a typo: the route would silently never match
        RouteSet(to="127.0.0.1:9999", instruments="snare,throne"),  # not an instrument: never an impact
        MessageAdd(name="m", to="pd", address="/x", instruments="snare,floor_tom", when="onset", specs=()),
    ],
    ids=["typo", "throne", "message"],
)
def test_an_instrument_the_kit_does_not_have_is_refused_by_name(message: object) -> None:
    core = InteractionCore(kit=KIT)
    before = core.config
    detail = errors(core.handle(message, 0.0, "pd"))[0].detail  # type: ignore[arg-type]
    assert "snare" not in detail.split("(")[0] and "kit" in detail
    assert core.config == before


def test_a_spec_too_long_for_osc_does_not_hide_the_rest_of_the_map_list() -> None:
    points = [[i / 40, (i / 40) ** 2] for i in range(41)]  # a detailed velocity table, written in the file
    config = InteractionConfig.model_validate({"routes": [
        {"to": "sound", "fields": {"velocity": {"feature": "velocity", "curve": {"kind": "table", "points": points}},
                                   "r": {"feature": "r"}}},
        {"to": "graphics"},
    ]})
    core = InteractionCore(kit=KIT, config=config)
    out = core.handle(MapList(), 0.0, "pd")
    infos = [(o.message.to, o.message.field) for o in out if isinstance(o.message, MapInfo)]
    assert infos == [("sound", ""), ("sound", "r"), ("graphics", "")]
    assert "velocity" in errors(out)[0].detail
    end = out[-1].message
    assert isinstance(end, ListEnd) and end.count == 3


def test_a_registered_message_too_long_to_list_does_not_hide_the_others() -> None:
    config = InteractionConfig.model_validate({"messages": [
        {"name": "wide", "to": "pd", "address": "/w", "instruments": [f"instrument_{i}" for i in range(60)]},
        {"name": "pd", "to": "pd", "address": "/hit", "args": [{"feature": "velocity"}]},
    ]})
    core = InteractionCore(kit=KIT, config=config)
    out = core.handle(MessageList(), 0.0, "pd")
    assert [o.message.name for o in out if isinstance(o.message, MessageInfo)] == ["pd"]
    assert "wide" in errors(out)[0].detail
    end = out[-1].message
    assert isinstance(end, ListEnd) and end.count == 1


def test_a_reordered_step_of_the_current_contact_still_counts() -> None:
    core = one_copy_core()
    out = core.handle(contact(1.0, 1000, impulse=0.01), 1.0, "physics")
    out += core.handle(contact(2.001, 2001, impulse=0.02), 2.001, "physics")  # a new stroke; its first step late
    out += core.handle(contact(2.0, 2000, impulse=0.03), 2.0015, "physics")
    for i in range(2002, 2030):
        out += core.step(i * 0.001)
    ends = [o.message for o in out if isinstance(o.message, ImpactEnd)]
    assert [e.impulse for e in ends] == pytest.approx([0.01, 0.05])
    assert [type(o.message) for o in out].count(Impact) == 2


@pytest.mark.parametrize("name", ["interaction.JSON", "interaction.Json"])
def test_a_json_file_with_an_upper_case_extension_is_written_back_as_json(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_text('{"impact_at": "end"}')
    core = InteractionCore(kit=KIT, config=load_config(path), store=FileConfigStore(path))
    assert core.handle(RouteSet(to="127.0.0.1:9999", instruments="snare"), 0.0, "pd") == []
    again = load_config(path)  # read as JSON by its extension: it must be JSON, or the next start fails
    assert again == core.config and again.impact_at == "end"


def test_the_node_warns_of_instruments_its_kit_does_not_have(tmp_path: Path,
                                                             caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "interaction.yaml"
    path.write_text("routes: [{to: sound, instruments: [snare, snrae]}]\n"
                    "messages: [{name: pd, to: pd, address: /hit, instruments: [flortom]}]\n")
    with caplog.at_level("WARNING", logger="batteur.interaction"):
        make_core(InteractionSettings(interaction_config=str(path), discovery=False), argparse.Namespace())
    warned = " ".join(r.getMessage() for r in caplog.records if r.levelname == "WARNING")
    assert "'snrae'" in warned and "'flortom'" in warned and "'snare'" not in warned


def test_a_contact_datagram_delivered_twice_adds_its_impulse_once() -> None:
    def impulse_of(stream: list[Contact]) -> tuple[float, InteractionStats]:
        core = one_copy_core()
        out: list[Outgoing] = []
        for c in stream:
            out += core.handle(c, c.time, "physics") + core.step(c.time)
        for i in range(10, 40):
            out += core.step(1.0 + i * 0.001)
        ends = [o.message for o in out if isinstance(o.message, ImpactEnd)]
        assert len(ends) == 1 and [type(o.message) for o in out].count(Impact) == 1
        stats = core.handle(StatsGet(), 1.25, "pd")[0].message
        assert isinstance(stats, InteractionStats)
        return ends[0].impulse, stats

    # a strike of three steps; its middle step has two contact points (the stick's tip on the head twice)
    first = contact(1.000, 1000, impulse=0.010)
    point_a = contact(1.001, 1001, impulse=0.004)
    point_b = point_a.model_copy(update={"x": 0.003, "impulse": 0.004})  # another point of the same step
    last = contact(1.002, 1002, impulse=0.002)
    clean, clean_stats = impulse_of([first, point_a, point_b, last])
    assert clean == pytest.approx(0.020)  # both points of a step count
    # the network repeats datagrams: the first step, a point of the middle step, the last one
    repeated, stats = impulse_of([first, first, point_a, point_b, point_a, last, last])
    assert repeated == pytest.approx(clean)
    assert stats.duplicate_contacts == 3 and clean_stats.duplicate_contacts == 0
    assert stats.out_of_order == 0
    assert decode(encode(stats)).messages == [stats]
