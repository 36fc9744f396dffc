"""The kit editor's **mirror**, twice, as a user meets it (Debian's chromium, Playwright): mirroring a kit for a
left-handed drummer and back saved a kit named ``...-mirrored-mirrored`` whose hit-point angles differed in their
last digit (-1.5708 became -1.5708000000000002), a different file from the kit's."""

from __future__ import annotations

from typing import Any

from common.kit import Kit

from .conftest import GraphicsNodeProcess, needs_browser
from .test_kit_editor import _save, crash_in_editor  # noqa: F401 - the fixture


@needs_browser
def test_mirroring_twice_saves_the_kit_as_it_was(
        crash_in_editor: tuple[Any, GraphicsNodeProcess, Kit]) -> None:  # noqa: F811 - the fixture
    page, node, loaded = crash_in_editor
    page.click("#kit-mirror")
    assert _save(page, node, "left.yaml") == loaded.mirrored()  # once: Kit.mirrored's numbers
    page.click("#kit-mirror")
    back = _save(page, node, "back.yaml")
    assert back == loaded and back.name == loaded.name  # every number, the name without -mirrored
    # the file a user gets: the one the kit was loaded from, byte for byte (both written by save_kit)
    assert (node.tmp / "kits" / "back.yaml").read_bytes() == (node.tmp / "fine.yaml").read_bytes()
