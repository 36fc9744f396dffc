"""The page on a kit whose designer renamed the kick, the snare and the hi-hat (chromium, headless): the node plays
the synthetic drummer on it (``--synthetic`` refused it: 'no object hihat_pedal') and the page colours each drum's
shell by what the kit plays on it, as on the shipped kit (a renamed snare was drawn as a tom, by its id)."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.kit import load_kit, save_kit
from tests.renamed_kits import renamed_kit

from .conftest import GraphicsNodeProcess, needs_browser, open_page

SHIPPED_SHELLS = {"kick": 0x8C1C24, "snare": 0x9AA0AA, "hightom": 0x8C1C24, "midtom": 0x8C1C24,
                  "floortom": 0x8C1C24}
"""The default kit's drum shells as the page draws them (web/src/app.js SHELL_COLOURS)."""


@needs_browser
@pytest.mark.parametrize("renamed", [False, True])
def test_the_renamed_kit_is_played_and_drawn_as_the_shipped_one(tmp_path: Path, renamed: bool) -> None:
    path = tmp_path / "kit.yaml"
    kit = renamed_kit() if renamed else load_kit("default")
    save_kit(kit, path)
    node = GraphicsNodeProcess(tmp_path, extra=["--synthetic", "--clock-master", "self", "--kit", str(path)])
    node.start()
    try:
        with open_page(node.url, 10) as (page, errors):
            shells = page.evaluate("() => window.batteur.shells")
            assert page.evaluate("() => window.batteur.kit.name") == kit.name
            assert errors == []
    finally:
        node.close()
    names = {"kick": "bassdrum", "snare": "sd"} if renamed else {}
    assert shells == {names.get(k, k): colour for k, colour in SHIPPED_SHELLS.items()}
