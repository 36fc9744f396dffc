"""A live core whose loop falls far behind has its drummer's targets jump back toward the rig clock over the strokes
between (``PhysicsCore._catch_up_targets``, past ``MAX_TARGET_LAG_S``). Until 7 Dec the live notes of those strokes
were lost without a word: no ``/batteur/physics/rejected`` to their sender, no count. Each is now refused to its
sender ("skipped: physics fell behind"), and every note dropped so (live or a score's) is counted late
(``ScorePlayer.late_notes``, Health's ``late``; ``skipped_notes`` by kind) and said in the jump's warning.

Deterministic: a live core stepped by a clock that stalls once for 1.2 s (as tests/physics/test_live_lag_*.py).
"""

from __future__ import annotations

import logging

import pytest

from common.kit import load_kit
from common.messages import Contact
from common.messages.physics import PhysicsRejected
from common.messages.score import LiveNote
from services.physics.core import PhysicsCore

SENDER = "127.0.0.1:9"
HIGH_TOM, SNARE = 48, 38
STALL_AT_MS, STALL_MS = 2000, 1200
"""The loop comes back 1.2 s late once, at rig time 2 s: the targets trail by 1.15 s, past the bound, and jump."""


@pytest.mark.slow  # 5 s of drummer simulation: 5-20 s
def test_live_notes_whose_strokes_a_jump_drops_are_refused_to_their_senders_and_counted(
        caplog: pytest.LogCaptureFixture) -> None:
    core = PhysicsCore(scene="drummer", kit=load_kit("default"), grip="german", pose_rate_hz=0, mode="live")
    try:
        for k in range(1, 201):
            core.step(k / 1000)
        notes = [1.0 + 0.25 * k for k in range(16)]
        instrument = {t: ("snare" if k % 2 else "hightom") for k, t in enumerate(notes)}
        for k, t in enumerate(notes):
            note = LiveNote(time=t, pitch=SNARE if k % 2 else HIGH_TOM, velocity=100, channel=10)
            assert not core.handle(note, core.time, SENDER)  # accepted
        contacts: list[Contact] = []
        replies: list[tuple[str, str]] = []
        now_ms = round(core.time * 1000)
        with caplog.at_level(logging.WARNING, logger="batteur.physics"):
            while now_ms < 5000:
                now_ms += STALL_MS + 1 if now_ms == STALL_AT_MS else 1
                for o in core.step(now_ms / 1000):
                    if isinstance(o.message, Contact):
                        contacts.append(o.message)
                    elif isinstance(o.message, PhysicsRejected):
                        replies.append((o.to, o.message.reason))
        refused = [t for t in notes if any(f"at {t:.3f} s skipped: physics fell behind" in r for _, r in replies)]
        played = [t for t in notes if any(c.instrument == instrument[t] and abs(c.time - t) <= 0.03 for c in contacts)]
        assert refused == [2.25, 2.5, 2.75, 3.0], replies  # were lost without a word (2.0 struck at 2.000 s)
        assert sorted(played + refused) == notes  # every note played or refused
        assert all(to == SENDER for to, _ in replies) and len(replies) == len(refused)
        status = core.score_player.status()
        assert status["skipped_notes"] == {"live": 4} and status["late_notes"] == 4
        assert core.skipped_steps > 0 and core.late == 4  # Health's late: the notes, not the steps skipped
        said = [r.getMessage() for r in caplog.records if "the strokes between dropped" in r.getMessage()]
        assert said and "with 4 live notes (each refused to its sender) and 0 score notes" in said[0], said
        # said plainly first (how far behind, what the user hears, what to do) as the skip's and the bound's; it
        # began "physics targets 1150 ms behind the rig clock: jumped ..."
        plain, detail = said[0].split(" (detail: ")
        assert plain.startswith("physics is ") and plain.endswith(
            " ms behind real time: the drummer's hands jump to catch up and the notes between are skipped; give "
            "physics a less loaded machine, a lower --control-rate-hz (e.g. 500), or fewer programs on its CPU "
            "core"), plain
        assert detail.startswith("the targets jumped ") and "toward the rig clock" in detail, detail
        assert detail.endswith("; docs/physics.md, 'When physics falls behind')"), detail
    finally:
        core.close()
