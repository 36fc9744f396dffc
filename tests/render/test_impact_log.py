"""impacts.csv's rows: each impact completed by its /batteur/impact/end (batteur/impact_log.py)."""

from __future__ import annotations

from pathlib import Path

from batteur.impact_log import ImpactLog, read_impacts_csv
from common.messages import Impact
from common.messages.interaction import ImpactEnd


def _impact(seq: int, time: float) -> Impact:
    return Impact(seq=seq, time=time, instrument="snare", zone="centre", r=0.2, theta=0.0, velocity=3.0,
                  impulse=0.0, peak_force=0.0, duration=0.0, part="left_stick_tip")


def _end(seq: int, time: float, impulse: float = 0.07) -> ImpactEnd:
    return ImpactEnd(seq=seq, time=time, instrument="snare", kind="strike", impulse=impulse, peak_force=40.0,
                     duration=0.004, part="left_stick_tip")


def test_an_impact_end_fills_in_the_figures_its_impact_did_not_know(tmp_path: Path) -> None:
    log = ImpactLog()
    for message in (_impact(0, 1.0), _impact(0, 1.0), _impact(1, 1.5), _end(0, 1.0), _end(0, 1.0)):  # copies
        log.add(message, "interaction")
    log.write_csv(tmp_path / "impacts.csv")
    first, second = read_impacts_csv(tmp_path / "impacts.csv")
    assert (first.impulse, first.peak_force, first.duration) == (0.07, 40.0, 0.004)
    assert (first.velocity, first.part) == (3.0, "left_stick_tip")  # the rest as the impact said
    assert (second.impulse, second.duration) == (0.0, 0.0)  # no end yet: still "not known"


def test_an_end_without_its_impact_is_counted_and_changes_nothing() -> None:
    log = ImpactLog()
    log.add(_impact(0, 1.0), "interaction")
    log.add(_end(5, 2.0), "interaction")  # its impact was lost
    log.add(_end(0, 1.0), "another-interaction")  # another sender's numbering
    log.add(_end(0, 1.2), "interaction")  # a number reused after a restart: not this impact
    assert log.unmatched_ends == 3
    assert log.sorted()[0].impulse == 0.0
