"""--help names each value for what it is, as render's do (PORT, SECONDS, DIR), not argparse's upper-cased option
name (BASE_PORT, START_DELAY); `batteur demo -o` is a DIR, as `batteur render -o`."""

from __future__ import annotations

import argparse

from batteur import demo, rig


def _value_options(parser: argparse.ArgumentParser) -> dict[str, str]:
    """option -> its metavar as --help shows it, for the options taking one value without choices."""
    shown: dict[str, str] = {}
    for action in parser._actions:
        if action.option_strings and action.nargs is None and action.choices is None \
                and not isinstance(action, (argparse._StoreTrueAction, argparse._HelpAction)):
            shown[action.option_strings[-1]] = str(action.metavar or action.dest.upper())
    return shown


def test_rig_values_are_named_for_what_they_are() -> None:
    shown = _value_options(rig.build_parser())
    for option in ("--base-port", "--http-port"):
        assert shown[option] == "PORT"
    for option in ("--start-delay", "--duration", "--stop-timeout", "--strike-period", "--play-at",
                   "--ready-timeout"):
        assert shown[option] == "SECONDS"
    assert not [m for m in shown.values() if "_" in m]  # no dest names: BASE_PORT, START_DELAY


def test_demo_output_is_a_dir_as_renders(capsys: object) -> None:
    try:
        demo.main(["--help"])
    except SystemExit:
        pass
    text = capsys.readouterr().out  # type: ignore[attr-defined]
    assert "-o DIR" in text and "OUTPUT" not in text
