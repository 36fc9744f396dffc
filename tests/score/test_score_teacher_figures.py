"""What a music teacher writing exercises met (7 Dec): `swing` or `crescendo` called an unknown directive without the
directives or how to write the figure, `repeat` after a rest or `at` lines silently replaying the block before them
(not the rest), `repeat 2` with no block before it told it needs "a count >= 1", `at 0 SN 100` (a MIDI velocity)
told only that 100 is outside [0, 1], `grip american` refused without saying the renderer takes it, and `batteur
evaluate --help` naming a `--skeleton-bvh` it does not have."""

from __future__ import annotations

import pytest

from batteur.evaluate import build_parser as evaluate_parser
from batteur.render import build_parser as render_parser
from common.score.events import ScoreError
from common.score.text import parse_text


@pytest.mark.parametrize(("line", "hint"), [
    ("swing 60", "triplet cells"),
    ("shuffle", "triplet cells"),
    ("crescendo", "digits 1-9"),
    ("dim", "digits 1-9"),
    ("accelerando", "one tempo line a bar"),
    ("wobble 3", "the directives are tempo, meter"),
])
def test_an_unknown_directive_lists_the_directives_and_how_to_write_the_figure(line: str, hint: str) -> None:
    with pytest.raises(ScoreError) as info:
        parse_text(f"tempo 100\nSN |x.x.|\n{line}\n")
    message = str(info.value)
    assert message.startswith(f"line 3: unknown directive {line.split()[0]!r}")
    assert hint in message and "docs/score-format.md" in message


@pytest.mark.parametrize("between", ["rest 2", "at 1 SN"])
def test_a_repeat_after_a_rest_or_at_line_says_it_plays_the_block_only(between: str) -> None:
    score = parse_text(f"tempo 60\nBD |x...|\n{between}\nrepeat 1\n")
    assert [w for w in score.warnings if "line 4: repeat plays the grid block of line 2 again" in w
            and f"not the {between.split()[0]} line" in w], score.warnings
    assert [round(e.time, 6) for e in score.events if e.event.name == "BASS"] == [0.0, 4.0 + (2 if "rest" in between
                                                                                               else 0)]


def test_a_repeat_straight_after_its_block_or_another_repeat_does_not_warn() -> None:
    score = parse_text("tempo 60\nBD |x...|\nrepeat 1\ntempo 90\nrepeat 2\n")
    assert not [w for w in score.warnings if "repeat" in w]


def test_a_repeat_with_no_block_before_it_says_so_not_that_its_count_is_wrong() -> None:
    with pytest.raises(ScoreError) as info:
        parse_text("tempo 100\nat 0 SN\nrest\nrepeat 2\n")
    assert "line 4: repeat 2 plays the last grid block again, and there is none before it" in str(info.value)
    assert ">= 1" not in str(info.value)
    with pytest.raises(ScoreError, match="line 3: repeat needs a count of 1 or more"):
        parse_text("tempo 100\nSN |x.x.|\nrepeat 0\n")


def test_a_midi_velocity_on_an_at_line_is_told_how_velocities_are_written() -> None:
    with pytest.raises(ScoreError) as info:
        parse_text("tempo 100\nat 0 SN 100\n")
    assert "line 2: velocity 100 outside 0 to 1" in str(info.value)
    assert "not MIDI's 0-127" in str(info.value) and "0.79" in str(info.value)


def test_a_grip_only_the_renderer_takes_says_where_to_give_it() -> None:
    with pytest.raises(ScoreError) as info:
        parse_text("tempo 100\ngrip american\nSN |x.x.|\n")
    assert "write grip french or german" in str(info.value)
    assert "batteur render --grip american" in str(info.value)


def test_evaluate_help_does_not_name_an_option_evaluate_does_not_have() -> None:
    assert "skeleton-bvh" not in evaluate_parser().format_help()
    assert "skeleton-bvh the skeleton gives" in " ".join(render_parser().format_help().split())
