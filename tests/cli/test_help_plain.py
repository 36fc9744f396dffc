"""Every ``batteur COMMAND --help`` is plain text: no Sphinx markup (double backquotes, ``:class:`` and the like)
shown to the user as it is written in a docstring."""

from __future__ import annotations

import re

import pytest

from batteur import cli

MARKUP = re.compile(r"``|:(?:class|func|meth|mod|data|attr|obj|exc|ref|doc):")
"""Sphinx/reST markup: double backquotes and cross-reference roles."""


@pytest.mark.parametrize("command", sorted(cli.COMMANDS))
def test_every_command_has_help_without_docstring_markup(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        cli.main([command, "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "usage:" in out and "--help" in out
    assert not MARKUP.search(out), f"batteur {command} --help shows markup: {MARKUP.findall(out)}\n{out}"


def test_top_level_help_shows_no_docstring_markup(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    assert not MARKUP.search(capsys.readouterr().out)


def test_graphics_build_help_explains_and_builds_nothing(monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """``batteur graphics build --help`` ran npm ci and the page build before (it ignored --help)."""
    from services.graphics import node

    monkeypatch.setattr(node, "build_assets", lambda *a, **k: pytest.fail("built on --help"))
    with pytest.raises(SystemExit) as done:
        node.main(["build", "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "npm ci" in out and not MARKUP.search(out)
    with pytest.raises(SystemExit) as done:
        node.main(["build", "--nope"])
    assert done.value.code == 2
