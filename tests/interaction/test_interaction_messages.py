"""Interaction messages registered at run time: add, build from features, list, remove, persist; health."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.kit import load_kit
from common.messages import Impact, decode, encode
from common.messages.codec import parse_packet
from common.messages.interaction import (
    ImpactTiming,
    InstrumentStats,
    InteractionError,
    InteractionStats,
    ListEnd,
    MessageAdd,
    MessageInfo,
    MessageList,
    MessageRemove,
    Redundancy,
    StatsGet,
)
from services.interaction.config import FileConfigStore, InteractionConfig, RedundancyConfig
from services.interaction.core import InteractionCore
from services.interaction.synthetic import StreamBuilder, dead_stroke, drive, merged, strike

KIT = load_kit("default")


def add(name: str = "pd", when: str = "onset", instruments: str = "*", *specs: str) -> MessageAdd:
    return MessageAdd(
        name=name, to="127.0.0.1:9999", address=f"/{name}/hit", instruments=instruments, when=when,  # type: ignore[arg-type]
        specs=specs or ("instrument", "velocity:linear:0:10:0:127@i", "zone", "=1"),
    )  # fmt: skip


def test_a_registered_message_is_built_from_the_impact_features() -> None:
    core = InteractionCore(kit=KIT)
    assert core.handle(add(), 0.0, "pd") == []
    b = strike(StreamBuilder(KIT, "snare"), t=1.0, velocity=2.5)
    out = [o for o in core.handle(b.contacts[0], 1.0, "physics") if o.to == "127.0.0.1:9999"]
    assert len(out) == 1  # registered messages go out once (receivers may not de-duplicate)
    raw = parse_packet(encode(out[0].message))[0]
    assert raw.address == "/pd/hit"
    assert raw.args == ["snare", 32, "centre", 1]  # 2.5 m/s of 10 -> 31.75 -> 32, as an OSC int


def test_registered_messages_filter_instruments_and_wait_for_the_end_when_asked() -> None:
    core = InteractionCore(kit=KIT)
    core.handle(add("ends", "end", "hightom", "duration", "impulse", "kind"), 0.0, "pd")
    ride = strike(StreamBuilder(KIT, "ride"), t=0.5)
    dead = dead_stroke(StreamBuilder(KIT, "hightom"), t=1.0, hold=0.1)
    out = [o for _, o in drive(core, merged(ride, dead))]
    sent = [parse_packet(encode(o.message))[0] for o in out if o.to == "127.0.0.1:9999"]
    assert len(sent) == 1
    duration, impulse, kind = sent[0].args
    assert kind == "dead" and isinstance(duration, float) and isinstance(impulse, float)
    assert 0 < duration < 0.03 and impulse > 0


def test_registered_messages_are_listed_replaced_removed_and_persisted(tmp_path: Path) -> None:
    store = FileConfigStore(tmp_path / "interaction.yaml")
    core = InteractionCore(kit=KIT, store=store)
    core.handle(add("a"), 0.0, "pd")
    core.handle(add("b", "end", "snare,ride", "velocity:exp:0:10:0:1:3", "=x"), 0.0, "pd")
    core.handle(add("a", "onset", "*", "velocity"), 0.0, "pd")  # same name: replaces
    listing = [o.message for o in core.handle(MessageList(), 0.0, "pd")]
    infos = [m for m in listing if isinstance(m, MessageInfo)]
    assert [(i.name, i.when, i.instruments, i.specs) for i in infos] == [
        ("b", "end", "snare,ride", ("velocity:exp:0:10:0:1:3", "=x")),
        ("a", "onset", "*", ("velocity",)),
    ]
    assert listing[-1] == ListEnd(what="message", count=2)
    # persisted: a restarted interaction has the same registered set
    restarted = InteractionCore(kit=KIT, config=store.load_or_default())
    assert [m.name for m in restarted.config.messages] == ["b", "a"]
    core.handle(MessageRemove(name="b"), 0.0, "pd")
    assert [m.name for m in store.load().messages] == ["a"]
    error = core.handle(MessageRemove(name="b"), 0.0, "pd")[0].message
    assert isinstance(error, InteractionError) and "b" in error.detail


@pytest.mark.parametrize(
    ("address", "specs"),
    [("no-slash", ("velocity",)), ("/ok", ("speed",)), ("/has space", ("velocity",)), ("/ok", ("velocity:linear:1",))],
)
def test_bad_registrations_are_refused_with_a_reason(address: str, specs: tuple[str, ...]) -> None:
    core = InteractionCore(kit=KIT)
    message = MessageAdd(name="x", to="pd", address=address, instruments="*", when="onset", specs=specs)
    out = core.handle(message, 0.0, "pd")
    assert len(out) == 1 and isinstance(out[0].message, InteractionError)
    assert core.config.messages == []


def test_redundancy_is_set_live_and_copies_are_spaced() -> None:
    core = InteractionCore(kit=KIT, config=InteractionConfig(routes=[{"to": "sound"}]))  # type: ignore[list-item]
    core.handle(Redundancy(copies=3, spacing=0.002), 0.0, "pd")
    assert core.config.redundancy == RedundancyConfig(copies=3, spacing=0.002)
    b = strike(StreamBuilder(KIT, "snare"), t=1.0, steps=1)
    times = [t for t, o in drive(core, b.contacts, tail=0.02) if isinstance(o.message, Impact)]
    assert times == pytest.approx([1.0, 1.002, 1.004])


def test_impact_timing_is_set_live() -> None:
    core = InteractionCore(kit=KIT, config=InteractionConfig(routes=[{"to": "sound"}]))  # type: ignore[list-item]
    assert core.handle(ImpactTiming(at="end"), 0.0, "pd") == []
    assert core.config.impact_at == "end"
    b = strike(StreamBuilder(KIT, "snare"), t=1.0)
    assert not any(isinstance(o.message, Impact) for o in core.handle(b.contacts[0], 1.0, "physics"))


def test_stats_count_impacts_per_instrument_and_latency() -> None:
    core = InteractionCore(kit=KIT)
    a = strike(StreamBuilder(KIT, "snare"), t=1.0)
    b = strike(StreamBuilder(KIT, "snare"), t=1.1)
    c = dead_stroke(StreamBuilder(KIT, "ride"), t=1.2, hold=0.1)
    drive(core, merged(a, b, c))
    out = [o.message for o in core.handle(StatsGet(), 2.0, "pd")]
    stats = out[0]
    assert isinstance(stats, InteractionStats)
    assert stats.impacts == 3 and stats.dampings == 1 and stats.mapping_errors == 0
    assert stats.latency_max == 0.0  # offline: handled at the contact's own step time
    per = {m.instrument: m for m in out if isinstance(m, InstrumentStats)}
    assert per["snare"].strikes == 2 and per["ride"].dead == 1 and per["ride"].dampings == 1
    for message in out:  # every answer survives the wire
        assert decode(encode(message)).messages == [message]
