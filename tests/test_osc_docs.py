"""docs/osc.md is generated from the models and must not go stale."""

from pathlib import Path

from common.messages import REGISTRY
from common.messages.docs import render_markdown

DOC = Path(__file__).resolve().parent.parent / "docs" / "osc.md"


def test_osc_reference_is_up_to_date() -> None:
    assert DOC.read_text(encoding="utf-8") == render_markdown(), (
        "docs/osc.md is stale: run `python -m common.messages.docs > docs/osc.md`"
    )


def test_every_registered_address_is_documented() -> None:
    text = DOC.read_text(encoding="utf-8")
    for model in REGISTRY:
        assert f"### `{model.ADDRESS}`" in text
