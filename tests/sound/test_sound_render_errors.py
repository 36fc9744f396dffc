"""An instrument whose render raises (its modes, presses or voices) loses its own block only: the other drums play
on, it is silenced, reset, counted, and its next strike plays."""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np
import pytest
from sound_helpers import impact

from common.kit import Kit, KitObject
from common.messages import Impact
from common.messages.interaction import Damping
from common.messages.sound import SoundModel
from services.sound.core import SoundCore, SoundSettings

BLOCK = 256
FAULT_BLOCK = 24  # the kick's render raises once in this block, 128 ms in (a multiple of the bank's 8-block prune)


def _kit() -> Kit:
    return Kit(name="two-drums", objects=[
        KitObject(id="kick", kind="membrane", position=(-0.3, 0.5, 0.3), radius=0.26, depth=0.4),
        KitObject(id="snare", kind="membrane", position=(0.3, 0.5, 0.6), radius=0.178, depth=0.14)], events={})


def _render(impacts: list[Impact], kick_model: str = "modal", fault: Callable[[SoundCore], None] | None = None,
            presses: list[Damping] = ()) -> tuple[np.ndarray, SoundCore]:
    """60 blocks of the two drums (no pyo stage: the mix is the buses' sum), ``fault`` armed before the fault block."""
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False), _kit())
    core.handle(SoundModel(instrument="kick", model=kick_model), 0.0, "t")
    for message in [*impacts, *presses]:
        core.handle(message, 0.0, "t")
    core.render(FAULT_BLOCK * BLOCK / 48000)
    if fault is not None:
        fault(core)
    core.render(60 * BLOCK / 48000)  # was: the fault block's render raised, every drum's block lost with it
    core.close()
    return core.recording(), core


def _process_raises_once(core: SoundCore) -> None:
    kick = core.instruments.instruments["kick"]
    process = kick.process

    def broken(out: np.ndarray) -> None:
        kick.process = process  # type: ignore[method-assign]
        out += 0.5  # half-written before it raised: the block must not keep it
        raise ValueError("operands could not be broadcast together")

    kick.process = broken  # type: ignore[method-assign]


def _voice_raises_once(core: SoundCore) -> None:
    voices = [v for v in core.pool.voices if v.instrument == "kick"]
    assert voices  # the synth strike's voice, still sounding

    def broken(n: int) -> np.ndarray:
        raise IndexError("index 2048 is out of bounds")

    voices[0].generate = broken  # type: ignore[method-assign]


def _presses_raise_once(core: SoundCore) -> None:
    kick = core.instruments.instruments["kick"]
    apply = kick.apply_presses

    def broken() -> None:
        kick.apply_presses = apply  # type: ignore[method-assign]
        raise ValueError("decay has 190 modes, bank has 195")

    kick.apply_presses = broken  # type: ignore[method-assign]


@pytest.mark.parametrize(("kick_model", "fault"), [("modal", _process_raises_once), ("synth", _voice_raises_once),
                                                   ("modal", _presses_raise_once)],
                         ids=["process", "voice", "presses"])
def test_a_failing_instrument_loses_only_its_own_block(kick_model: str, fault: Callable[[SoundCore], None],
                                                       caplog: pytest.LogCaptureFixture) -> None:
    t_fault = FAULT_BLOCK * BLOCK / 48000
    kick_first = impact(1, 0.0, "kick", velocity=2.0)
    kick_next = impact(4, t_fault + 0.05, "kick", velocity=2.0)
    snares = [impact(2, 0.03, "snare", velocity=1.5), impact(3, t_fault + 0.0004, "snare", velocity=1.0)]
    presses = []
    if fault is _presses_raise_once:  # a stick laid on the kick in the fault block: its presses are applied there
        presses = [Damping(seq=9, time=t_fault + 0.001, instrument="kick", part="left_stick_tip", state=1,
                           zone="centre", force=2.0, r=0.5, theta=0.0)]
    with caplog.at_level(logging.ERROR, logger="batteur.sound"):
        faulty, core = _render([kick_first, *snares, kick_next], kick_model, fault, presses)
    # the same strikes without the fault, the kick's first (silenced by it) left out
    clean, _ = _render([*snares, kick_next], kick_model, None, presses)
    start = FAULT_BLOCK * BLOCK
    assert np.max(np.abs(clean[start:])) > 0.01  # the snare rings through the fault block
    # the snare's samples in the fault block and after, and the kick's next strike, as if nothing had failed
    np.testing.assert_array_equal(faulty[start:], clean[start:])
    assert np.max(np.abs(faulty[:start])) > 0.01 and np.any(faulty[:start] != clean[:start])  # the first kick played
    assert core.stats.render_errors == {"kick": 1} and core.core_errors == 1
    assert core.stats.strikes == 4 and not core.stats.strike_errors
    first = [r for r in caplog.records if "its render failed" in r.getMessage()]
    assert len(first) == 1 and first[0].exc_info is not None  # logged once, with its traceback


def test_an_instrument_failing_every_block_is_counted_and_the_others_play() -> None:
    core = SoundCore(SoundSettings(latency=0.0, use_pyo=False), _kit())
    try:
        kick = core.instruments.instruments["kick"]

        def broken(out: np.ndarray) -> None:
            raise ValueError("a bad bank")

        kick.process = broken  # type: ignore[method-assign]
        for n in range(5):  # each strike fails in its block: silenced again, counted again
            core.handle(impact(2 * n + 1, n * 0.05, "kick"), 0.0, "t")
            core.handle(impact(2 * n + 2, n * 0.05, "snare"), 0.0, "t")
        core.render(0.3)
        assert core.next_sample == core.samples_until(0.3) // BLOCK * BLOCK  # was: stuck at the first failure
        assert core.stats.render_errors == {"kick": 5} and core.core_errors == 5
        assert np.max(np.abs(core.recording())) > 0.01
    finally:
        core.close()
