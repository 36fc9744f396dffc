"""The kit editor's **mirror** saves the file ``Kit.mirrored`` does (Debian's chromium, Playwright): the page's
JSON has no -0, so its mirrored kit was saved with ``0.0`` where Python's mirrored kit file held ``-0.0`` (every
object at x = 0 or with pitch or yaw 0): two files for one kit."""

from __future__ import annotations

from typing import Any

from common.kit import Kit, save_kit

from .conftest import GraphicsNodeProcess, needs_browser
from .test_kit_editor import _save, crash_in_editor  # noqa: F401 - the fixture


@needs_browser
def test_the_page_and_python_write_the_same_mirrored_kit_file(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    page, node, loaded = crash_in_editor
    page.click("#kit-mirror")
    _save(page, node, "left.yaml")
    save_kit(loaded.mirrored(), node.tmp / "python-left.yaml")
    assert (node.tmp / "kits" / "left.yaml").read_bytes() == (node.tmp / "python-left.yaml").read_bytes()
