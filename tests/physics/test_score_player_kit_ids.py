"""The physics node reads a text score's kit object ids in its own kit (``--kit``): the score player read the score
without it until 7 Dec, so a score naming ``crash2`` with no ``kit`` line was refused on a node built
with ``--kit double_pedal`` ("unknown instrument 'crash2'"), though the node plays it on that kit."""

from __future__ import annotations

from pathlib import Path

from common.kit import EventType
from services.physics.core import PhysicsCore


def test_a_text_score_s_object_ids_are_the_node_kit_s(tmp_path: Path) -> None:
    score = tmp_path / "crashes.txt"
    score.write_text("tempo 120\nCR |x...|\ncrash2 |x.x.|\n", encoding="utf-8")  # no kit line
    core = PhysicsCore(scene="strike", kit="double_pedal", pose_rate_hz=0)
    try:
        loaded = core.score_player.load(score, trusted=True)
        assert [(e.event, e.pitch) for e in loaded.events] == [
            (EventType.CRASH, None), (EventType.CRASH, 57), (EventType.CRASH, 57)]  # two crashes at 0: no double
        assert [core.kit.object_for(e.event, e.pitch).id for e in loaded.events] == ["crash", "crash2", "crash2"]
    finally:
        core.close()


def test_live_notes_on_two_objects_of_the_node_kit_are_not_doubles() -> None:
    """Live notes 49 and 57 at once are two crashes on ``double_pedal`` (57 strikes crash2), as a score's are: the
    score player gives its live notes the node's kit (until 7 Dec it merged them by event type)."""
    from common.messages.score import LiveNote

    core = PhysicsCore(scene="strike", kit="double_pedal", pose_rate_hz=0)
    try:
        live = core.score_player.live
        notes = [live.accept(LiveNote(time=5.0, pitch=pitch, velocity=100, channel=10)) for pitch in (49, 57)]
        assert [n is not None for n in notes] == [True, True]
        assert live.duplicates == 0
    finally:
        core.close()
