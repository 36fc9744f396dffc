"""`batteur send` given too few or too many arguments names the ones the message takes: it said only
`wrong_arity: /batteur/sound/master: expected 2 arguments, got 1`, which two left to docs/osc.md."""

from __future__ import annotations

import pytest

from batteur.tools import send


@pytest.mark.parametrize(("args", "takes"), [
    (["/batteur/sound/master", "0.5"], "GAIN_DB REVERB"),
    (["/batteur/score/transport", "play", "0"], "ACTION TIME_WHOLE_S TIME_FRACTION POSITION"),  # a rig time is two
    (["/batteur/hello", "sound", "n1", "1", "9000", "extra"], "ROLE NODE_ID PROTOCOL OSC_PORT"),
])
def test_a_wrong_number_of_arguments_names_those_the_message_takes(args: list[str], takes: str,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    assert send.main([*args, "--to", "127.0.0.1:9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"batteur send: error: wrong_arity: {args[0]}: expected "), err
    assert err.endswith(f"; {args[0]} takes {takes}"), err
