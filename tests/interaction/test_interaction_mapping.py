"""Mappings as data: curves, specs, a mapping file changing what sound receives, live edits over OSC."""

from __future__ import annotations

import math
from pathlib import Path
from typing import ClassVar

import pytest

from common.bus import OfflineRunner
from common.core import Outgoing
from common.dedupe import Deduplicator
from common.kit import load_kit
from common.messages import Contact, Impact, OscMessage
from common.messages.interaction import (
    ConfigLoad,
    ImpactEnd,
    InteractionError,
    ListEnd,
    MapClear,
    MapInfo,
    MapList,
    MapSet,
    RouteRemove,
    RouteSet,
)
from services.interaction.config import FileConfigStore, InteractionConfig, load_config, save_config
from services.interaction.core import InteractionCore
from services.interaction.detect import ImpactFeatures
from services.interaction.mapping import ArgSpec, ExpCurve, LinearCurve, MappingError, TableCurve
from services.interaction.synthetic import StreamBuilder, merged, strike

KIT = load_kit("default")


def features(**update: object) -> ImpactFeatures:
    base = ImpactFeatures(
        seq=7, time=1.5, instrument="snare", part="right_stick_tip", zone="centre", kind="strike",
        r=0.3, theta=0.5, x=0.0, y=0.4, z=0.6, local_x=0.05, local_y=0.02, local_z=0.0,
        velocity=2.5, impulse=0.01, peak_force=900.0, duration=0.004,
    )  # fmt: skip
    for key, value in update.items():
        setattr(base, key, value)
    return base


# --------------------------------------------------------------------------- curves and specs


def test_linear_curve_maps_and_clips() -> None:
    curve = LinearCurve(in_range=(0, 10), out_range=(0, 127))
    assert curve(5) == pytest.approx(63.5)
    assert curve(-1) == 0 and curve(20) == 127


def test_exp_curve_endpoints_shape_and_linear_limit() -> None:
    curve = ExpCurve(in_range=(0, 10), out_range=(0, 1), curvature=4)
    assert curve(0) == pytest.approx(0) and curve(10) == pytest.approx(1)
    assert curve(5) == pytest.approx(math.expm1(2) / math.expm1(4))  # slow then fast
    assert curve(5) < 0.5
    flat = ExpCurve(in_range=(0, 10), out_range=(0, 1), curvature=0)
    assert flat(2.5) == pytest.approx(0.25)
    down = ExpCurve(in_range=(0, 10), out_range=(0, 1), curvature=-4)
    assert down(5) > 0.5


def test_table_curve_interpolates_and_holds_the_ends() -> None:
    curve = TableCurve(points=[(0, 1), (0.8, 0.5), (1, 0)])
    assert curve(0.4) == pytest.approx(0.75)
    assert curve(0.9) == pytest.approx(0.25)
    assert curve(-3) == 1 and curve(3) == 0
    with pytest.raises(ValueError):
        TableCurve(points=[(0, 1), (0, 2)])


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("velocity", 2.5),
        ("velocity:linear:0:10:0:127@i", 32),
        ("velocity:exp:0:5:0:1:0", 0.5),
        ("r:table:0:1:0.6:0:1:0", 0.5),
        ("instrument", "snare"),
        ("=42", 42),
        ("=0.5", 0.5),
        ("=hello", "hello"),
        ("velocity@s", "2.5"),
    ],
)
def test_arg_spec_parse_evaluate_and_round_trip(text: str, expected: object) -> None:
    spec = ArgSpec.parse(text)
    value = spec.evaluate(features())
    assert value == pytest.approx(expected) if isinstance(expected, float) else value == expected
    assert type(value) is type(expected)
    again = ArgSpec.parse(spec.to_spec())
    assert again == spec


@pytest.mark.parametrize(
    "text",
    ["speed", "velocity:cubic:0:1:0:1", "velocity:linear:0:1:0", "velocity:linear:1:1:0:1", "instrument:linear:0:1:0:1",
     "velocity@x", "instrument@i", "velocity:table:0:1", "velocity:linear:a:b:c:d", "=99999999999"],
)  # fmt: skip
def test_bad_specs_raise_a_clear_mapping_error(text: str) -> None:
    with pytest.raises(MappingError, match=r"\S"):
        ArgSpec.parse(text)


def test_values_that_cannot_go_on_the_wire_are_mapping_errors() -> None:
    with pytest.raises(MappingError, match="int32"):
        ArgSpec.parse("velocity:linear:0:1:0:1e12@i").evaluate(features())
    assert ArgSpec.parse("=99999999999@f").evaluate(features()) == 99999999999.0


def test_config_round_trips_through_yaml_and_json(tmp_path: Path) -> None:
    config = InteractionConfig.model_validate(
        {
            "routes": [{"to": "sound", "fields": {"velocity": ArgSpec.parse("velocity:exp:0:10:0:5:3").model_dump()}}],
            "messages": [
                {"name": "pd", "to": "127.0.0.1:9999", "address": "/pd/hit",
                 "args": [ArgSpec.parse(t).model_dump() for t in ("instrument", "velocity:linear:0:10:0:127@i")]}
            ],
        }
    )  # fmt: skip
    for name in ("interaction.yaml", "interaction.json"):
        save_config(config, tmp_path / name)
        assert load_config(tmp_path / name) == config


def test_invalid_config_file_names_the_problem(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("routes:\n  - {to: sound, fields: {colour: {feature: velocity}}}\n")
    with pytest.raises(ValueError, match="colour"):
        load_config(path)
    path.write_bytes(bytes(range(128, 256)))
    with pytest.raises(ValueError, match="bad.yaml: not UTF-8 text"):
        load_config(path)
    path.write_text("routes: [\n")
    with pytest.raises(ValueError, match="bad.yaml: not valid YAML: .* at line 2, column 1$"):
        load_config(path)


# --------------------------------------------------------------------------- through the offline bus


class ContactPlayer:
    """A stand-in physics core replaying synthetic contacts at 1 kHz."""

    ROLE: ClassVar[str] = "physics"
    rate_hz = 1000.0

    def __init__(self, contacts: list[Contact]) -> None:
        self.by_step: dict[int, list[Contact]] = {}
        for c in contacts:
            self.by_step.setdefault(c.step, []).append(c)

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        return [Outgoing(c, "interaction") for c in self.by_step.get(round(now * 1000), [])]


class SoundRecorder:
    """A stand-in sound core: de-duplicates and records what it receives."""

    ROLE: ClassVar[str] = "sound"
    rate_hz = 0.0

    def __init__(self) -> None:
        self.dedupe = Deduplicator()
        self.received: list[OscMessage] = []
        self.copies = 0

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        self.copies += 1
        if self.dedupe.accept_message(source, message):
            self.received.append(message)
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []


def _strokes() -> list[Contact]:
    a = strike(StreamBuilder(KIT, "snare"), t=0.1, velocity=1.0)
    b = strike(StreamBuilder(KIT, "ride", "right_stick_tip"), t=0.2, velocity=4.0)
    c = strike(StreamBuilder(KIT, "kick", "kick_beater"), t=0.3, velocity=2.0)
    return merged(a, b, c)


def _play(config: InteractionConfig) -> SoundRecorder:
    sound = SoundRecorder()
    runner = OfflineRunner([ContactPlayer(_strokes()), InteractionCore(kit=KIT, config=config), sound])
    runner.run_until(0.5)
    return sound


def test_default_mapping_is_one_to_one_and_redundant_copies_are_deduplicated() -> None:
    sound = _play(InteractionConfig())
    impacts = [m for m in sound.received if isinstance(m, Impact)]
    assert [(i.instrument, round(i.velocity, 4)) for i in impacts] == [("snare", 1.0), ("ride", 4.0), ("kick", 2.0)]
    assert sum(isinstance(m, ImpactEnd) for m in sound.received) == 3
    copies = InteractionConfig().redundancy.copies
    assert sound.copies == copies * len(sound.received)  # every copy arrives, one is kept
    assert sound.dedupe.stats.duplicates == (copies - 1) * len(sound.received)


def test_a_mapping_file_changes_what_sound_receives(tmp_path: Path) -> None:
    path = tmp_path / "mapping.yaml"
    path.write_text(
        "routes:\n"
        "  - to: sound\n"
        "    instruments: [snare, ride]\n"
        "    fields:\n"
        "      velocity: {feature: velocity, curve: {kind: exp, in_range: [0, 5], out_range: [0, 10], curvature: 2}}\n"
        "      r: {value: 0.5}\n"
        "  - to: graphics\n",
        encoding="utf-8",
    )
    sound = _play(load_config(path))
    impacts = [m for m in sound.received if isinstance(m, Impact)]
    curve = ExpCurve(in_range=(0, 5), out_range=(0, 10), curvature=2)
    assert [i.instrument for i in impacts] == ["snare", "ride"]  # the kick is no longer routed to sound
    assert [i.velocity for i in impacts] == pytest.approx([curve(1.0), curve(4.0)], rel=1e-5)
    assert all(i.r == 0.5 for i in impacts)


# --------------------------------------------------------------------------- live edits over OSC


def _one_impact(core: InteractionCore, t: float, velocity: float = 2.0) -> Impact:
    b = strike(StreamBuilder(KIT, "snare"), t=t, velocity=velocity)
    out = core.handle(b.contacts[0], t, "physics")
    sound = [o.message for o in out if o.to == "sound" and isinstance(o.message, Impact)]
    assert len(sound) == 1
    return sound[0]


def test_map_set_list_and_clear_over_osc() -> None:
    core = InteractionCore(kit=KIT)
    assert _one_impact(core, 1.0).velocity == pytest.approx(2.0)
    assert core.handle(MapSet(to="sound", field="velocity", spec="velocity:linear:0:4:0:1"), 1.1, "pd") == []
    assert _one_impact(core, 2.0).velocity == pytest.approx(0.5)
    listing = [o for o in core.handle(MapList(), 2.1, "pd")]
    assert all(o.to == "reply" for o in listing)
    infos = [o.message for o in listing if isinstance(o.message, MapInfo)]
    assert ("sound", "velocity", "velocity:linear:0:4:0:1") in [(i.to, i.field, i.spec) for i in infos]
    assert isinstance(listing[-1].message, ListEnd) and listing[-1].message.count == len(infos)
    core.handle(MapClear(to="sound", field="*"), 2.2, "pd")
    assert _one_impact(core, 3.0).velocity == pytest.approx(2.0)


def test_routes_can_be_added_restricted_and_removed_live() -> None:
    core = InteractionCore(kit=KIT)
    core.handle(RouteSet(to="127.0.0.1:7000", instruments="snare"), 0.0, "pd")
    b = strike(StreamBuilder(KIT, "snare"), t=1.0)
    targets = {o.to for o in core.handle(b.contacts[0], 1.0, "physics")}
    assert targets == {"sound", "graphics", "127.0.0.1:7000"}
    core.handle(RouteRemove(to="graphics"), 1.5, "pd")
    b = strike(StreamBuilder(KIT, "ride"), t=2.0)
    out = core.handle(b.contacts[0], 2.0, "physics")  # also ends the snare contact: its ImpactEnd goes out
    assert {o.to for o in out if isinstance(o.message, Impact)} == {"sound"}


def test_bad_control_messages_get_an_error_reply_and_change_nothing() -> None:
    core = InteractionCore(kit=KIT)
    before = core.config
    for message in (
        MapSet(to="sound", field="colour", spec="velocity"),
        MapSet(to="sound", field="velocity", spec="speed"),
        MapSet(to="sound", field="velocity", spec="instrument"),
        MapClear(to="nobody", field="*"),
        RouteRemove(to="nobody"),
        ConfigLoad(path=""),
    ):
        out = core.handle(message, 0.0, "pd")
        assert len(out) == 1 and out[0].to == "reply"
        error = out[0].message
        assert isinstance(error, InteractionError) and error.request == message.ADDRESS and error.detail
    assert core.config == before
    assert core.control_errors == 6
    assert core.rejected_total == 6  # the node's Health counts them as dropped


def test_mapped_value_out_of_the_impact_range_is_clamped_and_counted() -> None:
    core = InteractionCore(kit=KIT)
    core.handle(MapSet(to="sound", field="r", spec="velocity:linear:0:1:0:100"), 0.0, "pd")
    assert _one_impact(core, 1.0).r == 2.0
    assert core.mapping_errors == 1


def test_live_edits_are_persisted_and_reloaded(tmp_path: Path) -> None:
    store = FileConfigStore(tmp_path / "interaction.yaml")
    core = InteractionCore(kit=KIT, store=store)
    core.handle(MapSet(to="sound", field="velocity", spec="velocity:exp:0:10:0:1:3"), 0.0, "pd")
    assert store.path.is_file()
    again = InteractionCore(kit=KIT, config=store.load_or_default())
    assert again.config == core.config
    other = tmp_path / "other.yaml"
    save_config(InteractionConfig(routes=[{"to": "graphics"}]), other)  # type: ignore[list-item]
    assert core.handle(ConfigLoad(path="other.yaml"), 1.0, "pd") == []  # a name in the store's directory
    assert [r.to for r in core.config.routes] == ["graphics"]
    assert [r.to for r in store.load().routes] == ["graphics"]  # loading another file persists it as ours


def test_config_load_refuses_paths_outside_its_directory(tmp_path: Path) -> None:
    store = FileConfigStore(tmp_path / "conf" / "interaction.yaml")
    core = InteractionCore(kit=KIT, store=store)
    before = core.config
    for path in (str(tmp_path / "elsewhere.yaml"), "../interaction.yaml", "/etc/passwd", "sub/x.yaml", "notes.txt"):
        out = core.handle(ConfigLoad(path=path), 1.0, "pd")
        assert len(out) == 1 and isinstance(out[0].message, InteractionError), path
        assert "not a path" in out[0].message.detail
    assert core.config == before
