"""The score preview's rate and bar range, live over OSC (``/batteur/graphics/preview_rate``, ``preview_bars``)
and from the page (``preview_bars``).

``--preview-rate`` and ``--preview-bars`` were taken only at start and only the page's speed select changed the
rate: a Pd or OSC user could do neither. Both are now typed controls, applied from where the motion is (no jump),
refused with a reply and counted when they cannot be applied.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from types import SimpleNamespace

import pytest

from common.config import NodeSettings
from common.kit import Kit, load_kit
from common.messages import DropReason, MessageError, OscMessage
from common.messages.graphics import GraphicsPreviewBars, GraphicsPreviewRate, GraphicsRejected
from common.runtime import Node
from common.transport import UdpEndpoint
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.figure import synthetic_performance
from services.graphics.node import GraphicsNodeSettings, _watch_preview, make_core
from services.graphics.preview import LOOP_PAUSE_S, bar_span, score_preview
from services.graphics.server import ViewServer
from tests.graphics.conftest import GraphicsNodeProcess, needs_browser, open_page
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

KIT = load_kit()
THREE_BARS = """# three bars of rock at 120 bpm: a bar is 2 s
tempo 120
meter 4/4
HH |xxxxxxxx|xxxxxxxx|xxxxxxxx|
SN |..X...X.|..X...X.|..X...X.|
BD |x...x...|x...x...|x...x...|
"""
SOURCE = "127.0.0.1:9"


@pytest.fixture(scope="module")
def score(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("scores") / "three.txt"
    path.write_text(THREE_BARS, encoding="utf-8")
    return path


@pytest.fixture
def core(score: Path) -> GraphicsCore:
    """A core showing the three bars from rig time 10 (motion time -1: a second before the first note), rate 1."""
    preview = score_preview(score, KIT)
    core = GraphicsCore(GraphicsSettings(latency=0.0), kit=KIT)
    core.load_preview(preview.sequence, preview.impacts, now=10.0, score=preview.score, rate=1.0)
    core.take_page_messages()
    return core


def _refusal(out: list, address: str) -> str:  # type: ignore[type-arg]
    assert [(o.to, type(o.message)) for o in out] == [("reply", GraphicsRejected)]
    message = out[0].message
    assert isinstance(message, GraphicsRejected) and message.address == address
    return message.reason


def test_an_osc_rate_plays_the_preview_slower_from_where_it_is(core: GraphicsCore) -> None:
    clock = core.preview_clock
    assert clock.position(12.0) == pytest.approx(1.0)
    assert core.handle(GraphicsPreviewRate(rate=0.5), 12.0, SOURCE) == []
    assert clock.rate == 0.5 and clock.position(12.0) == pytest.approx(1.0)  # no jump
    assert clock.position(14.0) == pytest.approx(2.0)
    view = core.take_page_messages()[-1]
    assert view["control"] == "preview_rate" and view["preview_rate"] == 0.5  # every page's select follows
    assert core.status(14.0)["preview"]["rate"] == 0.5 and core.rejected_total == 0


@pytest.mark.parametrize(("model", "args", "why"), [
    (GraphicsPreviewRate, [3.0], "rate: must be at most 2"),
    (GraphicsPreviewRate, [0.1], "rate: must be at least 0.25"),
    (GraphicsPreviewBars, [4, 3], "bars 4 to 3: bars count from 1 and the range must not end before it starts"),
    (GraphicsPreviewBars, [0, 2], "bars 0 to 2"),
])
def test_a_rate_or_range_out_of_range_is_refused_when_decoded(model: type[OscMessage], args: list[float],
                                                             why: str) -> None:
    with pytest.raises(MessageError, match=why) as err:
        model.from_args(args)
    assert err.value.reason is DropReason.OUT_OF_RANGE


def test_bars_loop_from_where_the_motion_is_or_from_their_first_bar(core: GraphicsCore, score: Path) -> None:
    clock = core.preview_clock
    bar1, bar2 = (bar_span(core.preview_score, b, b) for b in (1, 2))  # type: ignore[arg-type]
    assert bar1 == pytest.approx((0.0, 2.0)) and bar2 == pytest.approx((2.0, 4.0))
    # at motion time 1 (bar 1): bar 2 alone does not hold it, so the loop starts at bar 2's start
    assert core.handle(GraphicsPreviewBars(first=2, last=2), 12.0, SOURCE) == []
    assert clock.position(12.0) == pytest.approx(2.0) and core.preview_bars == (2, 2)
    assert clock.position(13.5) == pytest.approx(3.5)
    assert clock.position(14.5) == pytest.approx(2.5)  # looped with no pause
    assert core.status(14.5)["score"]["bar"] == 1  # the status counts bars from 0: bar 2 from 1
    view = core.take_page_messages()[-1]
    assert view["control"] == "preview_bars" and view["preview_bars"] == [2, 2]
    # bars 1 to 2 hold motion time 2.5: it goes on from there (no jump)
    assert core.handle(GraphicsPreviewBars(first=1, last=2), 14.5, SOURCE) == []
    assert clock.position(14.5) == pytest.approx(2.5) and clock.position(16.0) == pytest.approx(0.0)
    strokes = core.preview_counts(16.0)
    assert strokes is not None and strokes["strokes"] == 24 and strokes["laps"] == 1
    # 0 0: the whole score again, from where it is, with the pause between laps
    assert core.handle(GraphicsPreviewBars(first=0, last=0), 16.0, SOURCE) == []
    assert core.preview_bars is None and clock.position(16.0) == pytest.approx(0.0)
    assert clock.pause == LOOP_PAUSE_S and clock.start == pytest.approx(-1.0)
    assert core.take_page_messages()[-1]["preview_bars"] == "all"
    assert core.rejected_total == 0


def test_bars_the_score_lacks_or_no_score_are_refused_to_the_sender_and_counted(core: GraphicsCore) -> None:
    clock = core.preview_clock
    reason = _refusal(core.handle(GraphicsPreviewBars(first=5, last=6), 12.0, SOURCE),
                      "/batteur/graphics/preview_bars")
    assert reason == "bars 5 to 6: the score has 3 bars (three.txt)"
    assert core.preview_bars is None and clock.position(12.0) == pytest.approx(1.0)  # the preview plays on
    assert core.counters["preview_refused"] == 1 and core.rejected_total == 1
    # a range starting inside the score but ending past it is refused too (until 7 Dec only its first bar was
    # checked and the loop was cut at the end without a word)
    reason = _refusal(core.handle(GraphicsPreviewBars(first=2, last=5), 12.0, SOURCE),
                      "/batteur/graphics/preview_bars")
    assert reason == "bars 2 to 5: the score has 3 bars (three.txt)"
    assert core.preview_bars is None and clock.position(12.0) == pytest.approx(1.0)
    assert core.handle(GraphicsPreviewBars(first=2, last=3), 12.0, SOURCE) == []  # its last bar: played
    assert core.preview_bars == (2, 3)
    core.handle(GraphicsPreviewBars(first=0, last=0), 12.0, SOURCE)
    assert core.rejected_total == 2
    # a pose sequence file has no score: no bars, but a rate
    sequence, impacts = synthetic_performance(duration=1.0, rate_hz=30.0)
    core.load_preview(sequence, impacts, now=20.0)
    assert "no score preview is loaded" in _refusal(
        core.handle(GraphicsPreviewBars(first=1, last=1), 20.0, SOURCE), "/batteur/graphics/preview_bars")
    assert core.view_json()["preview_bars"] is None  # the page offers no bars
    assert core.handle(GraphicsPreviewRate(rate=2.0), 20.0, SOURCE) == []
    assert core.rejected_total == 3


def test_without_a_preview_rate_and_bars_are_refused_and_counted() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0), kit=KIT)
    assert "no preview is loaded" in _refusal(core.handle(GraphicsPreviewRate(rate=0.5), 0.0, SOURCE),
                                              "/batteur/graphics/preview_rate")
    assert "--preview-score" in _refusal(core.handle(GraphicsPreviewBars(first=1, last=1), 0.0, SOURCE),
                                         "/batteur/graphics/preview_bars")
    assert core.counters["preview_refused"] == 2 and core.rejected_total == 2 and core.mode == "live"


def test_the_node_answers_and_counts_refused_rates_and_bars(core: GraphicsCore) -> None:
    async def scenario() -> None:
        node = Node(core, NodeSettings(role="graphics", discovery=False, oscquery=False, clock_master="self"))
        await node.start()
        client = await UdpEndpoint.open("127.0.0.1")
        replies: list[OscMessage] = []
        client.set_handler(lambda message, source: replies.append(message))
        try:
            assert node.endpoint is not None
            to = node.endpoint.local_address
            before = node.health()
            client.send_raw("/batteur/graphics/preview_rate", [3.0], to)  # out of range: refused when decoded
            client.send(GraphicsPreviewBars(first=7, last=8), to)  # past the score: refused by the core
            client.send(GraphicsPreviewRate(rate=0.75), to)
            await wait_for(lambda: len(replies) >= 2 and core.preview_clock.rate == 0.75, 10.0)
            reasons = sorted(m.reason for m in replies if isinstance(m, GraphicsRejected))
            assert len(reasons) == 2 and "bars 7 to 8" in reasons[0] and "rate: must be at most 2" in reasons[1]
            assert node.endpoint.stats.drops_by_reason().get("out_of_range") == 1
            assert core.counters["preview_refused"] == 1
            assert node.health().dropped - before.dropped == 2
        finally:
            client.close()
            await node.stop()

    asyncio.run(scenario())


def test_the_page_sets_a_bar_range_and_a_bad_one_is_refused(core: GraphicsCore) -> None:
    server = ViewServer(core, clock=lambda: 12.0)
    assert server.handle_page_message('{"type": "preview_bars", "first": 2, "last": 3}') is None
    assert core.preview_bars == (2, 3) and core.preview_clock.position(12.0) == pytest.approx(2.0)
    for raw, why in (('{"type": "preview_bars", "first": 3, "last": 2}', "bars 3 to 2"),
                     ('{"type": "preview_bars", "first": "x", "last": 2}', "first: expected a number"),
                     ('{"type": "preview_bars", "first": 9, "last": 9}', "the score has 3 bars"),
                     ('{"type": "preview_bars", "first": 2, "last": 5}', "bars 2 to 5: the score has 3 bars")):
        reply = server.handle_page_message(raw)
        # a reply of its own (not the editor's "saved"), with the node's view: the page's boxes show 2 to 3 again
        assert reply is not None and reply["type"] == "refused" and reply["control"] == "preview_bars", reply
        assert why in reply["error"] and reply["view"]["preview_bars"] == [2, 3], reply
    reply = server.handle_page_message('{"type": "preview_rate", "rate": 5}')
    assert reply is not None and reply["type"] == "refused" and reply["control"] == "preview_rate"
    assert "rate" in reply["error"] and reply["view"]["preview_rate"] == 1.0
    assert server.counters["page_errors"] == 5 and core.preview_bars == (2, 3)
    assert server.handle_page_message('{"type": "preview_bars", "first": 0, "last": 0}') is None
    assert core.preview_bars is None


def test_a_replanned_preview_keeps_the_bars_and_rate_chosen_live(score: Path) -> None:
    settings = GraphicsNodeSettings(preview_score=str(score), preview_bars="1")
    core = make_core(settings, SimpleNamespace())  # type: ignore[arg-type]
    assert core.preview_bars == (1, 1)
    core.handle(GraphicsPreviewBars(first=2, last=3), 5.0, SOURCE)
    core.handle(GraphicsPreviewRate(rate=0.5), 5.0, SOURCE)
    node = SimpleNamespace(clock=SimpleNamespace(now=lambda: 6.0))

    async def main() -> None:
        task = asyncio.create_task(_watch_preview(node, core, settings, period=0.02))  # type: ignore[arg-type]
        try:
            await asyncio.sleep(0.1)
            core.set_kit(Kit.model_validate(KIT.model_dump(mode="json")))  # a kit saved: re-planned
            await wait_for(lambda: core.counters.get("preview_replans") == 1, 60.0)
        finally:
            task.cancel()

    asyncio.run(main())
    assert core.preview_bars == (2, 3) and core.preview_clock.rate == 0.5
    assert core.preview_clock.start == pytest.approx(2.0) and core.preview_clock.pause == 0.0


STATUS = "() => document.getElementById('status-body').innerText"


@needs_browser
def test_the_page_loops_bars_and_follows_the_rate_and_bars_sent_over_osc(score: Path, tmp_path: Path) -> None:
    node = GraphicsNodeProcess(tmp_path, latency=0.0, extra=[
        "--no-oscquery", "--preview-score", str(score), "--clock-master", "self"])
    node.start()
    try:
        with open_page(node.url, 5, 1000, 600, wait_for_status=True) as (page, errors):
            assert page.is_visible("#preview-bars-box")
            assert (page.input_value("#preview-first"), page.input_value("#preview-last")) == ("", "")  # all
            page.fill("#preview-first", "3")
            page.press("#preview-first", "Tab")  # committed: sent; the last bar follows the first
            page.wait_for_function("document.getElementById('preview-last').value === '3'", timeout=30000)
            page.wait_for_function(f"({STATUS})().includes('bar 3 beat')", timeout=30000)
            # a rate and bars sent over OSC: every page's controls follow (0.6 then 0.7: neither in the list)
            for rate in (0.6, 0.7):
                node.send(GraphicsPreviewRate(rate=rate))
                page.wait_for_function(f"document.getElementById('preview-rate').value === '{rate}'",
                                       timeout=30000)
            node.send(GraphicsPreviewBars(first=1, last=2))
            page.wait_for_function("document.getElementById('preview-first').value === '1' && "
                                   "document.getElementById('preview-last').value === '2'", timeout=30000)
            # a range past the score's end: refused beside the boxes, which show the node's range again
            page.fill("#preview-last", "5")
            page.press("#preview-last", "Tab")
            page.wait_for_function("!document.getElementById('preview-msg').classList.contains('hidden')",
                                   timeout=30000)
            assert page.inner_text("#preview-msg") == "bars refused: bars 1 to 5: the score has 3 bars (three.txt)"
            assert (page.input_value("#preview-first"), page.input_value("#preview-last")) == ("1", "2")
            assert page.inner_text("#editor-msg") == ""  # not in the hidden editor's save line
            msg, toolbar = (page.evaluate("id => { const r = document.getElementById(id).getBoundingClientRect();"
                                          " return [r.left, r.top, r.right, r.bottom]; }", i)
                            for i in ("preview-msg", "toolbar"))
            assert toolbar[0] <= msg[0] and msg[2] <= toolbar[2] and msg[3] <= toolbar[3] and msg[2] > msg[0]
            page.click("#preview-all")
            page.wait_for_function("document.getElementById('preview-last').value === ''", timeout=30000)
            assert page.is_hidden("#preview-msg")  # the next range sent clears it
            boxes = page.evaluate("ids => ids.map(id => { const r = document.getElementById(id)"
                                  ".getBoundingClientRect(); return [r.left, r.top, r.right, r.bottom]; })",
                                  ["toolbar", "preview-bars-box"])
            toolbar, bars = boxes
            assert toolbar[0] <= bars[0] and bars[2] <= toolbar[2] and bars[3] <= toolbar[3]
            assert errors == []
    finally:
        node.close()
