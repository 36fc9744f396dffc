"""``/batteur/graphics/mode preview`` on a node with no preview loaded: the view stays live and the sender is told
why (it was silently ignored, so ``batteur send --replies`` reported it as taken)."""

from __future__ import annotations

from common.messages.graphics import GraphicsMode, GraphicsRejected
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import synthetic_performance


def test_the_preview_mode_without_a_preview_is_refused_to_its_sender_and_the_view_stays_live() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    out = core.handle(GraphicsMode(mode="preview"), 0.0, "127.0.0.1:9")
    assert [(o.to, type(o.message)) for o in out] == [("reply", GraphicsRejected)]
    refusal = out[0].message
    assert isinstance(refusal, GraphicsRejected) and refusal.address == "/batteur/graphics/mode"
    assert "--preview-score" in refusal.reason
    assert core.mode == "live"
    sequence, impacts = synthetic_performance(duration=1.0, rate_hz=30.0)
    core.load_preview(sequence, impacts)
    assert core.handle(GraphicsMode(mode="preview"), 0.1, "127.0.0.1:9") == []  # with one loaded: taken
    assert core.mode == "preview"
