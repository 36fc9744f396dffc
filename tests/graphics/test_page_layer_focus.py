"""Keyboard use of the page's layer ticks: Space on the "sticks" tick hid the sticks and sent the keyboard focus to
<body> (every tick was rebuilt on each change), so a keyboard user could not tick the next one or undo."""

from __future__ import annotations

from common.messages.graphics import GraphicsShow, GraphicsTrails

from .conftest import GraphicsNodeProcess, needs_browser, open_page

STICKS = "#layers label:has-text('sticks') input"
FOCUSED = "(() => { const el = document.activeElement; " \
          "return el && el.tagName === 'INPUT' ? el.parentElement.textContent : el.tagName; })()"
"""Page script: the layer name of the focused tick, else the focused element's tag."""


@needs_browser
def test_the_focus_stays_on_a_layer_tick_toggled_with_the_keyboard(synthetic_node: GraphicsNodeProcess) -> None:
    with open_page(synthetic_node.url, 10, 1000, 600, wait_for_status=True) as (page, errors):
        page.focus(STICKS)
        page.keyboard.press("Space")
        assert page.evaluate("window.batteur.view.layers.sticks") is False
        assert page.evaluate(FOCUSED) == "sticks"
        assert page.is_checked(STICKS) is False
        # a view message from the node (another control, then this very layer) updates the ticks, focus kept
        synthetic_node.send(GraphicsTrails(seconds=2.0))
        page.wait_for_function("window.batteur.view.trails === 2", timeout=10000)
        assert page.evaluate(FOCUSED) == "sticks"
        synthetic_node.send(GraphicsShow(layer="sticks", visible=1))
        page.wait_for_function("window.batteur.view.layers.sticks === true", timeout=10000)
        assert page.is_checked(STICKS) is True
        assert page.evaluate(FOCUSED) == "sticks"
        page.keyboard.press("Space")  # still the tick a keyboard user is on: it hides the sticks again
        assert page.evaluate("window.batteur.view.layers.sticks") is False
        assert page.is_checked(STICKS) is False
        assert page.evaluate("document.querySelectorAll('#layers input').length") == 8  # no tick added twice
        assert errors == []
