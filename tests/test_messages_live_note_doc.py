"""The live note's docstring (docs/osc.md's reference for it) says how early to send a note and how its rig time goes
on the wire: a musician driving the rig from python-osc read neither there (the physics node refuses a note with
less lead than it needs to raise the stick, and a rig time is two arguments, not one float).

The lead is quoted by the name of what the node checks, so it cannot drift from it; the wire form from the model's
own type tags.
"""

from __future__ import annotations

import inspect
import re

from common.messages import WireKind
from common.messages.score import LiveNote
from services.physics import score_player
from services.physics.score_player import ScorePlayer


def doc() -> str:
    return " ".join(inspect.cleandoc(LiveNote.__doc__ or "").split())


def test_it_names_the_least_lead_the_physics_node_takes() -> None:
    text = doc()
    assert "ScorePlayer.preparation_s" in text and isinstance(inspect.getattr_static(ScorePlayer, "preparation_s"),
                                                              property)
    assert "SPLICE_MARGIN_S" in text and hasattr(score_player, "SPLICE_MARGIN_S")
    assert "/batteur/physics/rejected" in text  # what a note sent too late gets
    assert not re.search(r"\b0?\.2\d|\b2\d\d ms", text)  # a number would drift from the node's


def test_it_says_a_rig_time_is_two_arguments() -> None:
    text = doc()
    time_field = next(f for f in LiveNote.wire_fields() if f.name == "time")
    assert time_field.kind is WireKind.TIME
    assert "two OSC arguments" in text and "whole seconds (`i`) then the fraction (`f`)" in text
    tags = " ".join(LiveNote.type_tags())
    assert f"`{tags}`" in text and f"{len(LiveNote.type_tags())} arguments" in text.replace("five", "5")
