"""A node that went quiet (chromium, headless): its row in the status panel kept its last loop rate.

The node keeps a node in its table for 10 s after its last Health (published once a second), so a physics node
that stopped showed "1000/1000 Hz" for ten more seconds, as if it were running. Its row now says *quiet* once three
reports are missed, and shows the rate again when reports come back.
"""

from __future__ import annotations

import threading
import time

from common.messages import PROTOCOL_VERSION, Health

from .conftest import GraphicsNodeProcess, needs_browser, open_page

ROW = """(role) => { const row = [...document.querySelectorAll('#status-body table tr')]
  .find(tr => tr.cells[0] && tr.cells[0].textContent === role); return row ? row.textContent : null; }"""
"""Page script: the text of the status panel's row of the node with this role (null: no such row)."""

AGE = "(role) => (window.batteur.status.nodes.find(n => n.role === role) ?? { age: null }).age"
"""Page script: the age (s) of the newest status' entry of the node with this role (null: not listed)."""


class HealthSender:
    """Sends a physics node's Health four times a second until stopped."""

    def __init__(self, node: GraphicsNodeProcess) -> None:
        self.node = node
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            self.node.send(Health(node_id="physics-quiet", role="physics", protocol=PROTOCOL_VERSION,
                                  time=time.monotonic(), rate_hz=1000.0, target_rate_hz=1000.0, overruns=0,
                                  messages_in=0, messages_out=0, dropped=0, dropped_malformed=0, dropped_unknown=0,
                                  dropped_type=0, dropped_range=0, dropped_other=0, late=0, peers=1))
            time.sleep(0.25)

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(2)


@needs_browser
def test_a_quiet_node_is_shown_quiet_not_at_its_last_rate(graphics_node: GraphicsNodeProcess) -> None:
    sender = HealthSender(graphics_node)
    try:
        with open_page(graphics_node.url, -1, 1000, 600, wait_for_status=True) as (page, errors):
            page.wait_for_function(f"({AGE})('physics') !== null && ({AGE})('physics') < 1", timeout=20000)
            live = page.evaluate(ROW, "physics")
            assert "1000/1000 Hz" in live and "quiet" not in live, live
            sender.stop()
            # wait for what is judged: the node's age past three missed reports (and still listed, under 10 s)
            page.wait_for_function(f"({AGE})('physics') > 3.5", timeout=20000)
            quiet = page.evaluate(ROW, "physics")
            page.screenshot(path=str(graphics_node.tmp / "quiet-node.png"))
            assert quiet is not None and "quiet" in quiet and "Hz" not in quiet, quiet
            sender = HealthSender(graphics_node)
            page.wait_for_function(f"({AGE})('physics') !== null && ({AGE})('physics') < 1", timeout=20000)
            again = page.evaluate(ROW, "physics")
            assert "Hz" in again and "quiet" not in again, again
            assert errors == []
    finally:
        sender.stop()
