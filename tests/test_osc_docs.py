"""docs/osc.md is generated from the models and must not go stale."""

from pathlib import Path

import pytest
from pydantic import Field

from common.messages import REGISTRY, OscMessage
from common.messages.base import MessageError
from common.messages.docs import render_markdown
from common.messages.registry import MessageRegistry

DOC = Path(__file__).resolve().parent.parent / "docs" / "osc.md"


def test_osc_reference_is_up_to_date() -> None:
    assert DOC.read_text(encoding="utf-8") == render_markdown(), (
        "docs/osc.md is stale: run `python -m common.messages.docs > docs/osc.md`"
    )


def test_every_registered_address_is_documented() -> None:
    text = DOC.read_text(encoding="utf-8")
    for model in REGISTRY:
        assert f"### `{model.ADDRESS}`" in text


def test_a_bound_the_model_refuses_is_marked_so() -> None:
    """docs/osc.md gave /batteur/subscribe's duration_s as ``0 .. 3600``; the model (``gt=0``) refuses 0."""
    class Bounded(OscMessage):
        ADDRESS = "/test/bounded"
        open_both: float = Field(gt=0, lt=1, description="open")
        closed_both: float = Field(ge=0, le=1, description="closed")
        open_low: int = Field(gt=-3, description="low only")
        open_high: float = Field(ge=2, lt=5, description="half open")

    registry = MessageRegistry()
    registry.add(Bounded)
    text = render_markdown(registry)
    assert "| open_both | f | > 0 .. < 1 |" in text
    assert "| closed_both | f | 0 .. 1 |" in text
    assert "| open_low | i | > -3 ..  |" in text
    assert "| open_high | f | 2 .. < 5 |" in text
    assert "`> 0 .. 3600` is" in text  # the notation is explained once, above the tables
    for bad in (0.0, 1.0):  # what is marked excluded is refused
        with pytest.raises(MessageError, match="out_of_range"):
            Bounded.from_args([bad, 0.5, 0, 3.0])
    assert "| duration_s | f | > 0 .. 3600 |" in render_markdown()


def test_the_generator_prints_the_reference_without_arguments_and_explains_on_help(
        capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m common.messages.docs > docs/osc.md`` (the checks' ``| diff -q - docs/osc.md``) still prints the
    reference; ``--help`` printed it too until 7 Dec, as any argument: now it explains, and a typo is refused."""
    from common.messages import docs

    assert docs.main([]) == 0
    assert capsys.readouterr().out == render_markdown()
    with pytest.raises(SystemExit) as done:
        docs.main(["--help"])
    out = capsys.readouterr().out
    assert done.value.code == 0 and "usage:" in out and "### `" not in out
    with pytest.raises(SystemExit) as done:
        docs.main(["--ouput", "x.md"])
    assert done.value.code == 2 and capsys.readouterr().out == ""
