"""A misspelt required key in a kit file is named: `positon:` for `position:` was refused as
`objects.1.position: Field required (and 1 more)`, the typo itself hidden in the "1 more"."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.kit import KITS_DIR, load_kit


def test_a_misspelt_required_key_names_the_typo(tmp_path: Path) -> None:
    text = (KITS_DIR / "default.yaml").read_text()
    assert "id: snare, kind: membrane, position:" in text
    kit = tmp_path / "kit.yaml"
    kit.write_text(text.replace("id: snare, kind: membrane, position:", "id: snare, kind: membrane, positon:"))
    with pytest.raises(ValueError) as refused:
        load_kit(kit)
    assert "objects.1 (snare): 'positon' is not a key here ('position' is missing: misspelt?)" in str(refused.value)


def test_a_missing_key_alone_is_still_said_missing(tmp_path: Path) -> None:
    text = (KITS_DIR / "default.yaml").read_text()
    kit = tmp_path / "kit.yaml"
    kit.write_text(text.replace("kind: membrane, position: [-0.08, 0.38, 0.64], ", "kind: membrane, "))
    with pytest.raises(ValueError, match=r"objects\.1 \(snare\)\.position: Field required"):
        load_kit(kit)
