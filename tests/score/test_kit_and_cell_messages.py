"""Kit file and text score errors in plain words: no pydantic "Value error, " or "Input should be ...", the
field and its allowed range said, and a grid cell's allowed characters listed as the ST and NU rows' are."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from common.kit import KITS_DIR, load_kit
from common.score.events import ScoreError
from common.score.text import parse_text


def _kit(tmp_path: Path, change: object) -> str:
    data = yaml.safe_load((KITS_DIR / "default.yaml").read_text())
    change(data)  # type: ignore[operator]
    path = tmp_path / "kit.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError) as refused:
        load_kit(path, warn=False)
    return str(refused.value)


def test_a_kit_check_is_said_without_pydantics_prefix(tmp_path: Path) -> None:
    def drop_cowbell(data: dict) -> None:  # type: ignore[type-arg]
        data["objects"] = [o for o in data["objects"] if o["id"] != "cowbell"]

    message = _kit(tmp_path, drop_cowbell)
    assert "Value error" not in message
    assert message.endswith("is not a valid kit: event COWBELL refers to unknown object 'cowbell'"), message


def test_a_kit_value_out_of_range_says_the_field_and_range(tmp_path: Path) -> None:
    def slow(data: dict) -> None:  # type: ignore[type-arg]
        data["events"]["SNARE"]["min_time_gap"] = 5

    message = _kit(tmp_path, slow)
    assert "Input should" not in message, message
    assert "events.SNARE.min_time_gap: 5 is out of range: more than 0, at most 2" in message, message


def test_a_grid_cell_lists_the_characters_it_takes() -> None:
    with pytest.raises(ScoreError) as refused:
        parse_text("SN |x0x.|\n")
    assert str(refused.value) == ("line 1: cell 2: unknown character '0' (use x, o, X, O, g, a digit 1-9, "
                                  "or '.' or '-' for a rest)")
