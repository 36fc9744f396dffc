"""``batteur send`` takes a message's older wire form (a sender from before its last appended field) as given, not
as the one-number-time form, which has as many values (a Contact's 17 arguments from before ``openness`` were read
as ``step: expected an integer, got 0.5``)."""

from __future__ import annotations

from batteur.tools.send import relative_times, split_times
from common.messages.events import Contact
from common.messages.graphics import ScorePosition

OLD_CONTACT = ["1", "0.5", "3", "snare", "tip", *["0"] * 8, "1", "0", "0", "0"]
"""Time 1.5 s as its whole seconds and fraction, then the 15 fields before ``openness``."""


def test_an_older_senders_wire_form_is_taken_as_given() -> None:
    assert split_times(Contact, OLD_CONTACT) is None  # taken as the wire form: its 17 arguments sent as they are
    assert split_times(ScorePosition, ["12", "0.25", "0", "1", "120"]) is None  # before beat_unit
    assert Contact.from_args([1, 0.5, 3, "snare", "tip", *[0.0] * 8, 1.0, 0.0, 0.0, 0.0]).openness == -1.0
    assert relative_times(ScorePosition, ["12", "0.25", "0", "1", "120"]) == {}


def test_the_one_number_form_still_splits_its_time() -> None:
    assert split_times(ScorePosition, ["12.25", "0", "1", "120", "0.5"]) == ["12", "0.25", "0", "1", "120", "0.5"]
    # a whole-second time reads both ways without a value of the wrong kind: the one-number form, as before
    assert split_times(ScorePosition, ["12", "0", "1", "120", "0.5"]) == ["12", "0.0", "0", "1", "120", "0.5"]
    assert relative_times(ScorePosition, ["+2", "0", "1", "120", "0.5"]) == {0: 2.0}
