"""RatedWarnings: one warning per kind per interval, the ones held back said with the next."""

from __future__ import annotations

import logging

import pytest

from common.rated_log import RatedWarnings


def test_each_kind_is_logged_once_per_interval_and_says_how_many_were_held(caplog: pytest.LogCaptureFixture) -> None:
    log = logging.getLogger("test.rated")
    warnings = RatedWarnings(log, 1.0)
    with caplog.at_level(logging.WARNING, logger="test.rated"):
        said = [warnings.warn("a", t, "bad %s", t) for t in (0.0, 0.2, 0.5, 0.9)]
        said.append(warnings.warn("b", 0.9, "other"))  # another kind has its own interval
        said.append(warnings.warn("a", 1.0, "bad again"))
    assert said == [True, False, False, False, True, True]
    assert [r.getMessage() for r in caplog.records] == ["bad 0.0", "other",
                                                        "bad again (+3 more since the last report)"]


def test_a_clock_that_went_back_logs_at_once(caplog: pytest.LogCaptureFixture) -> None:
    """A core's rig time jumps back on a clock resync or a new render: its next refusal is not held for long."""
    warnings = RatedWarnings(logging.getLogger("test.rated"), 5.0)
    with caplog.at_level(logging.WARNING, logger="test.rated"):
        assert warnings.warn("a", 10.0, "first")
        assert warnings.warn("a", 2.0, "after the clock went back")


def test_arguments_are_formatted_only_when_logged() -> None:
    class Loud:
        def __str__(self) -> str:
            raise AssertionError("formatted though held back")

    warnings = RatedWarnings(logging.getLogger("test.rated"), 1.0)
    warnings.warn("a", 0.0, "first")
    assert not warnings.warn("a", 0.5, "%s", Loud())
