"""``batteur evaluate``'s table keeps long score names apart: Groove MIDI files' names run past the first column
and differ at their end (``..._beat_3-4.mid`` vs ``..._fill_3-4.mid``)."""

from __future__ import annotations

from typing import Any

from batteur import evaluate

SESSION = "drummer1_session2_1_latin-chacarera_157_"


def figures() -> dict[str, Any]:
    """One row's figures, as FileResult.summary() gives them (the table's columns)."""
    return {"notes": 10, "f_measure": {"10ms": 0.5, "25ms": 0.9}, "precision": {"25ms": 0.9},
            "recall": {"25ms": 0.9}, "timing_ms": {"median_abs": 3.0, "p95_abs": 9.0, "median_signed": -1.0},
            "spearman": 0.8, "spearman_within_sound": None, "spurious": 1, "missed": [], "planner_flags": 0,
            "real_time_factor": 1.5}


def labels(names: list[str]) -> list[str]:
    lines = evaluate.format_table([(name, figures()) for name in names]).splitlines()[1:]
    width = lines[0].index(" 10 ")  # the label column ends where the notes column starts
    return [line[:width].rstrip() for line in lines]


def test_two_long_names_differing_at_their_end_get_two_labels() -> None:
    names = [f"{SESSION}beat_3-4.mid", f"{SESSION}fill_3-4.mid"]
    beat, fill = labels(names)
    assert beat != fill
    assert beat.endswith("beat_3-4.mid") and fill.endswith("fill_3-4.mid")


def test_a_label_too_long_for_the_widest_column_keeps_its_start_and_end() -> None:
    name = f"renders-of-the-second-evaluation ({SESSION}beat_3-4.mid)"
    (label,) = labels([name])
    assert len(label) < len(name)
    assert label.startswith("renders-of") and label.endswith("beat_3-4.mid)") and "..." in label


def test_the_rows_stay_aligned_whatever_the_labels() -> None:
    table = evaluate.format_table([(name, figures()) for name in ("ALL", f"{SESSION}beat_3-4.mid", "x" * 90)])
    assert len({len(line) for line in table.splitlines()}) == 1, table


def test_short_labels_keep_the_28_character_column() -> None:
    header = evaluate.format_table([("groove.mid", figures())]).splitlines()[0]
    assert header.index("notes") == 28 + 1 + len(" notes") - len("notes")


def test_the_timing_columns_say_their_unit_and_line_up_with_their_figures() -> None:
    """The timing columns named no unit (only the summary line below the table said ms)."""
    head, row = evaluate.format_table([("groove.mid", figures())]).splitlines()
    for name, value in (("med|e| ms", "3.00"), ("p95|e| ms", "9.00"), ("bias ms", "-1.00")):
        end = head.index(name) + len(name)  # right-aligned: a figure ends where its column's name does
        assert row[:end].endswith(value), (name, head, row)
