"""The limb distribution runs with the cyclic garbage collector paused (its objects form no cycles: each full
collection only walked them again, a quarter of a long score's distribution) and leaves it as it was."""

from __future__ import annotations

import gc

import pytest

from common.kit import load_kit
from common.score.limbs import distribute
from common.score.text import parse_text

SCORE = parse_text("tempo 120\nHH |x.x.x.x.|\nSN |..x...x.|\nBD |x...x...|\n")


def test_distribution_pauses_the_collector_and_restores_it() -> None:
    seen: list[bool] = []
    plain = distribute(SCORE, load_kit("default"))
    with_progress = distribute(SCORE, load_kit("default"), progress=lambda done, total: seen.append(gc.isenabled()))
    assert seen and not any(seen)  # paused while it works
    assert gc.isenabled()
    assert with_progress.notes == plain.notes and len(plain.notes) == 8


def test_ctrl_c_during_the_distribution_restores_the_collector() -> None:
    def ctrl_c(done: int, total: int) -> None:
        if done:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        distribute(SCORE, load_kit("default"), progress=ctrl_c)
    assert gc.isenabled()
    gc.disable()
    try:
        distribute(SCORE, load_kit("default"))
        assert not gc.isenabled()  # a caller's choice is kept
    finally:
        gc.enable()
