"""A user's unsaved kit edits in the viewer's editor (Debian's chromium, Playwright), each against the defect it was
written for: the node's kit message (sent on every reconnect, after a node restart, when another page saves)
replaced the page's kit, so an edit went back to the node's value without a word; Enter in the file-name field
did nothing.
"""

from __future__ import annotations

from typing import Any

from common.kit import Kit, load_kit, save_kit

from .conftest import GraphicsNodeProcess, needs_browser
from .test_kit_editor import CRASH, FINE_X_M, ROW_VALUES, _type, crash_in_editor  # noqa: F401 - the fixture

EDITED_X_M = 0.5
"""The crash's position x as the user types it."""
MOVED_Y_M = 0.4321
"""The crash's position y in the kit file the restarted node loads (someone else changed it)."""
NOTICE = "#kit-notice"


def _restart(page: Any, node: GraphicsNodeProcess, kit: Kit | None = None) -> None:
    """Stop the node, save ``kit`` as the file it draws (if given), start it again and wait until the page has
    reconnected and been sent the node's kit (the welcome's first message, before any status)."""
    node.stop()
    page.wait_for_function("!window.batteur.connected", timeout=10000)
    if kit is not None:
        save_kit(kit, node.tmp / "fine.yaml")
    page.evaluate("window.batteur.status = null")
    node.start()
    page.wait_for_function("window.batteur.connected && window.batteur.status", timeout=15000)


def _with_crash(kit: Kit, x: float, y: float) -> Kit:
    data = kit.model_dump(mode="json")
    crash = next(o for o in data["objects"] if o["id"] == "crash")
    crash["position"][0], crash["position"][1] = x, y
    return Kit.model_validate(data)


def _crash_rows(page: Any) -> list[list[str]]:
    return page.eval_on_selector_all("#kit-sliders .slider", ROW_VALUES)


@needs_browser
def test_a_changed_node_kit_waits_while_the_page_has_edits(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """Crash x typed as 0.5 went back to the node's value when the node restarted: the edit is now kept, the
    editor says the node's kit changed, and **load** brings the node's kit (its x and its moved y). A page with no
    edits shows a new kit from the node at once, as before."""
    page, node, loaded = crash_in_editor
    _type(page, 0, str(EDITED_X_M))
    _restart(page, node, _with_crash(loaded, FINE_X_M, MOVED_Y_M))

    assert _crash_rows(page)[0][1:] == [str(EDITED_X_M), str(EDITED_X_M)]
    assert page.evaluate(f"{CRASH}.position[0]") == EDITED_X_M
    assert page.is_visible(NOTICE)
    assert "the node's kit changed" in page.inner_text(NOTICE)

    page.click("#kit-load")
    rows = _crash_rows(page)
    assert rows[0][1:] == [str(FINE_X_M), str(FINE_X_M)] and rows[1][1:] == [str(MOVED_Y_M), str(MOVED_Y_M)]
    assert page.evaluate(f"[{CRASH}.position[0], {CRASH}.position[1]]") == [FINE_X_M, MOVED_Y_M]
    assert not page.is_visible(NOTICE)

    _restart(page, node, _with_crash(loaded, 0.2, MOVED_Y_M))  # no edits now: the node's kit is shown as it comes
    assert _crash_rows(page)[0][1:] == ["0.2", "0.2"]
    assert not page.is_visible(NOTICE)


@needs_browser
def test_edits_survive_a_reconnect_to_the_same_kit_and_a_save_settles_them(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """A restarted node with the kit the edits started from: the edit stays and there is nothing to load (the
    node's kit did not change); saving it makes it the node's kit, so the next reconnect keeps it too."""
    page, node, _ = crash_in_editor
    _type(page, 0, str(EDITED_X_M))
    _restart(page, node)
    assert _crash_rows(page)[0][1:] == [str(EDITED_X_M), str(EDITED_X_M)]
    assert not page.is_visible(NOTICE)

    page.fill("#kit-file", "edited.yaml")
    page.click("#kit-save")
    page.wait_for_function("document.getElementById('editor-msg').textContent.startsWith('saved')", timeout=10000)
    assert not page.is_visible(NOTICE)  # the node's echo of this page's own save is no change to warn about
    assert page.evaluate("JSON.stringify(window.batteur.kit) === JSON.stringify(window.batteur.nodeKit)")


@needs_browser
def test_enter_in_the_file_name_field_saves_the_kit(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    """Enter in the kit file-name field did nothing: it saves, as the **save kit** button does."""
    page, node, _ = crash_in_editor
    _type(page, 0, str(EDITED_X_M))
    page.fill("#kit-file", "entered.yaml")
    page.press("#kit-file", "Enter")
    page.wait_for_function("document.getElementById('editor-msg').textContent.startsWith('saved')", timeout=10000)
    assert load_kit(node.tmp / "kits" / "entered.yaml").object("crash").position[0] == EDITED_X_M
