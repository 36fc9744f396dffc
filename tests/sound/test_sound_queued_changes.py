"""Live changes queued behind a background rebuild (the Pd panel's tension then level, at once): they land on the
rebuilt instrument, which keeps its modes; a strike that fails loses only itself, counted and logged."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from sound_helpers import impact, one_drum_kit, settle

import services.sound.core as core_module
from common.kit import Kit, KitObject
from common.messages import OscMessage
from common.messages.sound import SoundLevel, SoundModel, SoundRadius, SoundTension
from services.sound.core import SoundCore, SoundSettings, _apply_changes, _Change
from services.sound.instruments import Instrument

PANEL = "127.0.0.1:9000"


def _core(background: bool, kit: Kit | None = None) -> SoundCore:
    return SoundCore(SoundSettings(latency=0.01, use_pyo=False, background_rebuilds=background),
                     kit or one_drum_kit())


@pytest.fixture
def live() -> Iterator[SoundCore]:
    core = _core(True)
    yield core
    core.close()


CHEAP_BEHIND = {
    "tension+level": [SoundTension(instrument="drum", value=800.0), SoundLevel(instrument="drum", gain_db=-6.0)],
    "radius+level": [SoundRadius(instrument="drum", value=0.3), SoundLevel(instrument="drum", gain_db=-6.0)],
    "tension+model": [SoundTension(instrument="drum", value=800.0), SoundModel(instrument="drum", model="modal")],
    "tension+level+level": [SoundTension(instrument="drum", value=800.0), SoundLevel(instrument="drum", gain_db=-6.0),
                            SoundLevel(instrument="drum", gain_db=-3.0)],
}


@pytest.mark.parametrize("name", sorted(CHEAP_BEHIND))
def test_a_cheap_change_queued_behind_a_rebuild_lands_on_the_rebuilt_drum(live: SoundCore, name: str) -> None:
    offline = _core(False)
    try:
        for message in CHEAP_BEHIND[name]:
            assert live.handle(message, live.now, PANEL) == []
            assert offline.handle(message, offline.now, PANEL) == []
        assert settle(live) == []
        drum, ref = live.instruments.instruments["drum"], offline.instruments.instruments["drum"]
        # was: the level went to the worker alone, on a detached copy whose (empty) bank nothing rebuilt, and the
        # drum adopted it: no modes, every later strike failing with a broadcast error
        assert drum.bank.size == ref.bank.size > 0
        assert drum.p == ref.p and drum.model == ref.model
        assert np.array_equal(drum.bank.freq, ref.bank.freq)
        for core in (live, offline):
            core.handle(impact(1, core.now), core.now, "t")
            core.render(core.now + 0.2)
        assert live.core_errors == 0 and not live.stats.strike_errors
        tail = live.recording()[-int(0.15 * live.sample_rate):]
        assert np.abs(tail).max() > 1e-3  # the strike sounded
    finally:
        offline.close()


def _change(message: OscMessage, name: str, **values: float | str) -> _Change:
    return _Change(message, PANEL, name, dict(values))


def test_a_worker_job_of_cheap_changes_alone_still_builds_the_twins_modes() -> None:
    core = _core(False)
    try:
        drum = core.instruments.instruments["drum"]
        twin, refused = _apply_changes(drum.detached(), [
            _change(SoundLevel(instrument="drum", gain_db=-6.0), "level", gain_db=-6.0),
            _change(SoundModel(instrument="drum", model="synth"), "model", model="synth")])
        assert refused == []
        # was: the twin's bank stayed the empty one detached() gave it, and adopting it emptied the drum's
        assert twin.bank.size == drum.bank.size > 0
        assert np.array_equal(twin.bank.freq, drum.bank.freq)
        assert twin.p.level_db == -6.0 and twin.model == "synth" and drum.p.level_db != -6.0
    finally:
        core.close()


def _two_drums() -> Kit:
    return Kit(name="two-drums", objects=[
        KitObject(id="kick", kind="membrane", position=(-0.3, 0.5, 0.3), radius=0.26, depth=0.4),
        KitObject(id="snare", kind="membrane", position=(0.3, 0.5, 0.6), radius=0.178, depth=0.14)], events={})


def test_a_failing_strike_loses_only_itself_counted_and_logged(caplog: pytest.LogCaptureFixture) -> None:
    core = _core(False, _two_drums())
    try:
        kick = core.instruments.instruments["kick"]

        def broken(*args: object) -> None:
            raise ValueError("operands could not be broadcast together")

        kick.strike = broken  # type: ignore[method-assign]
        with caplog.at_level(logging.ERROR, logger="batteur.sound"):
            core.handle(impact(1, 0.0, "kick"), 0.0, "t")
            core.handle(impact(2, 0.0, "snare"), 0.0, "t")
            core.render(0.2)  # was: the block's render raised, the snare's strike lost with it
            core.handle(impact(3, core.now, "kick"), core.now, "t")
            core.render(core.now + 0.1)
        assert core.stats.strikes == 1 and core.instruments.instruments["snare"].sounding
        assert np.abs(core.recording()).max() > 1e-3
        assert core.stats.strike_errors == {"kick": 2} and core.core_errors == 2
        assert core.rejected_total == 2  # impacts not played: Health's dropped
        first = [r for r in caplog.records if "a strike failed" in r.getMessage()]
        assert first and first[0].exc_info is not None  # the first one with its traceback
    finally:
        core.close()


def test_a_slow_change_to_one_drum_does_not_hold_up_anothers(monkeypatch: pytest.MonkeyPatch) -> None:
    """The walkthrough's ``modes snare 20000`` then ``radius kick 0.5``: the kick's change landed 11.6 s later, once
    the snare's was done. Here the snare's change is held until the kick's has landed."""
    release = threading.Event()

    def held(twin: Instrument, changes: list[_Change]) -> tuple[Instrument, list[tuple[_Change, str]]]:
        if twin.id == "snare":
            release.wait(60.0)  # a slow change (seconds at 20,000 modes), until the test lets it go
        return _apply_changes(twin, changes)

    monkeypatch.setattr(core_module, "_apply_changes", held)
    core = _core(True, _two_drums())
    try:
        snare, kick = core.instruments.instruments["snare"], core.instruments.instruments["kick"]
        core.handle(SoundTension(instrument="snare", value=5000.0), core.now, PANEL)
        core.handle(SoundLevel(instrument="snare", gain_db=-3.0), core.now, PANEL)  # waits behind the snare's
        core.handle(SoundRadius(instrument="kick", value=0.3), core.now, PANEL)
        deadline = time.monotonic() + 30.0
        while kick.p.radius != 0.3:  # was: queued in the one worker thread behind the snare's change
            assert time.monotonic() < deadline, "the kick's change waited for the snare's"
            core.step(core.now + 0.001)
            time.sleep(0.002)
        assert core.rebuilding and snare.p.tension != 5000.0 and snare.p.level_db != -3.0  # still held
        release.set()
        assert settle(core) == []
        assert (snare.p.tension, snare.p.level_db, kick.p.radius) == (5000.0, -3.0, 0.3)  # in order, each
    finally:
        release.set()
        core.close()
