"""A kit holding instruments the drummer cannot play loads with a warning naming each one and why."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from common.gesture.plan import IssueReason
from common.kit import KITS_DIR, EventType, KitObject, load_kit, save_kit
from common.score.events import DrumEvent, Score
from common.score.limbs import distribute


def _odd_kit(tmp_path: Path) -> Path:
    """The default kit with its crash 2.5 m to the right, a second china no event or pitch strikes and a stand
    instead of the cowbell."""
    kit = load_kit("default")
    objects = [o.model_copy(update={"position": (2.5, 0.6, 1.4)}) if o.id == "crash" else o for o in kit.objects
               if o.id != "cowbell"]
    objects.append(KitObject(id="china2", kind="cymbal", position=(-0.5, 0.5, 1.2), radius=0.2))
    objects.append(KitObject(id="stand1", kind="stand", position=(0.3, 0.5, 0.9), radius=0.05))
    events = dict(kit.events)
    events[EventType.COWBELL] = events[EventType.COWBELL].model_copy(update={"object": "stand1"})
    path = tmp_path / "odd.yaml"
    save_kit(kit.model_copy(update={"objects": objects, "events": events}), path)
    return path


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and r.name == "common.kit"]


def test_each_unplayable_instrument_is_named_once_with_why(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path = _odd_kit(tmp_path)
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        kit = load_kit(path)  # still loads: the rest of the kit plays
    said = _warnings(caplog)
    assert all(line.startswith(f"kit file {str(path)!r}: ") for line in said)  # was: no word
    # the crash moved 2.9 m right: its pair_preference entries are stale (tests/score/test_kit_designer_files.py)
    assert len([line for line in said if ": pair_preference: " in line]) == 1
    said = [line for line in said if ": pair_preference: " not in line]
    assert len(said) == 3
    crash, china2, stand = said
    assert "crash: out of both hands' reach (CRASH 2." in crash and "a hand reaching 1.15 m" in crash
    assert "china2 (cymbal): no event type or note_objects pitch strikes it" in china2
    assert "stand1: COWBELL strikes it, but it is a stand, which no stick strikes" in stand
    # what the warning says of the crash is what the planner then finds on each of its notes
    score = Score(events=[DrumEvent(0.0, EventType.CRASH, 0.8), DrumEvent(1.0, EventType.CRASH, 0.8)])
    flagged = [i.note_index for i in distribute(score, kit).issues if i.reason == IssueReason.UNREACHABLE]
    assert flagged == [0, 1]


@pytest.mark.parametrize("name", sorted(p.stem for p in KITS_DIR.glob("*.yaml")))
def test_the_shipped_kits_load_without_a_warning(name: str, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        load_kit(name)
    assert _warnings(caplog) == []
