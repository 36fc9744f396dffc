"""docs/runtime.md's example ``node.py`` runs as written: a reader copies it to start a service."""

from __future__ import annotations

import argparse
import re
import types
from pathlib import Path

import pytest

from common.config import NodeSettings

RUNTIME_MD = Path(__file__).resolve().parents[2] / "docs" / "runtime.md"


def _example() -> types.ModuleType:
    text = RUNTIME_MD.read_text(encoding="utf-8")
    section = text.split("## Writing `services/<name>/node.py`", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code, "no Python example under 'Writing services/<name>/node.py'"
    module = types.ModuleType("runtime_example")
    exec(compile(code.group(1), str(RUNTIME_MD), "exec"), module.__dict__)
    return module


def test_the_example_builds_its_core_from_its_defaults() -> None:
    example = _example()
    parser = argparse.ArgumentParser()
    example.add_arguments(parser)
    core = example.make_core(NodeSettings(role="sound"), parser.parse_args([]))
    try:
        assert core.settings.latency == NodeSettings().latency_s
    finally:
        core.close()


def test_the_example_refuses_a_bad_option_with_exit_status_2(capsys: pytest.CaptureFixture[str]) -> None:
    example = _example()
    parser = argparse.ArgumentParser()
    example.add_arguments(parser)
    flag = next(o for a in parser._actions for o in a.option_strings if o.startswith("--") and o != "--help")
    assert example.main([flag, "-1", "--no-discovery"]) == 2
    assert capsys.readouterr().err.count("\n") == 1  # one line, no traceback
