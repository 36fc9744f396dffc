"""``batteur send /batteur/impact`` with the rig time as one number of seconds and the 11 values an impact had
before 8 Dec (``openness`` appended since) still sends it, with openness -1 (the zone says it); with the 12th value
the openness goes too (before the fix: ``expected 13 arguments, got 11``, the documented form refused)."""

from __future__ import annotations

from batteur.tools.send import relative_times, split_times, typed_args
from common.messages import Contact, Impact

ELEVEN = ["4", "1.5", "hihat", "half", "0.6", "0", "3", "0", "0", "0", "right_stick_tip"]


def test_an_impact_without_openness_in_the_one_number_form_is_sent() -> None:
    impact = Impact.from_args(typed_args(Impact.ADDRESS, ELEVEN))
    assert (impact.seq, impact.time, impact.zone, impact.openness) == (4, 1.5, "half", -1.0)
    assert relative_times(Impact, [ELEVEN[0], "+2", *ELEVEN[2:]]) == {1: 2.0}


def test_an_impact_with_openness_in_the_one_number_form_and_the_wire_form_both_read() -> None:
    assert Impact.from_args(typed_args(Impact.ADDRESS, [*ELEVEN, "0.75"])).openness == 0.75
    wire = ["4", "1", "0.5", *ELEVEN[2:]]  # an older sender's 12 arguments, the time as seconds and fraction
    assert split_times(Impact, wire) is None
    impact = Impact.from_args(typed_args(Impact.ADDRESS, wire))
    assert impact.time == 1.5 and impact.openness == -1.0


def test_a_contact_without_openness_in_the_one_number_form_is_sent_too() -> None:
    texts = ["1.5", "3", "hihat", "right_stick_tip", *["0"] * 8, "1", "0", "0", "0"]  # 16 values
    contact = Contact.from_args(typed_args(Contact.ADDRESS, texts))
    assert contact.time == 1.5 and contact.step == 3 and contact.openness == -1.0
