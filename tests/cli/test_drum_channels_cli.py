"""``--drum-channels`` on ``batteur render``, ``batteur evaluate`` and ``batteur compare``: the channels chosen are
the ones read (render's score, evaluate's renders and their reuse, compare's exercise and take), a render records
them for ``batteur evaluate DIR``, and a channel out of range is argparse's one-line error."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import mido
import pytest

from batteur import compare, evaluate, render
from batteur.impact_log import COLUMNS

TICKS = 480
"""Ticks per beat; at 120 bpm a beat is 0.5 s."""


def drums_and_wood_block(path: Path) -> Path:
    """A take as a DAW records it: a beat of drums on channel 1 (kick and snare on the beats, 8 notes over 4 beats)
    and a wood block overdub on channel 16 (4 notes), nothing on channel 10. Read by default (no program says it is
    not drums; until 7 Dec its track was named Click, which is now left out: tests/score/test_midi_drum_channels.py),
    left out with --drum-channels 1."""
    mid = mido.MidiFile(type=1, ticks_per_beat=TICKS)
    for title, channel, notes in (("Drums", 0, [(k * TICKS, 36 if k % 2 == 0 else 38) for k in range(8)]),
                                  ("Wood Block", 15, [(k * 2 * TICKS, 76) for k in range(4)])):
        track = mido.MidiTrack([mido.MetaMessage("track_name", name=title)])
        last = 0
        for tick, pitch in notes:
            track.append(mido.Message("note_on", channel=channel, note=pitch, velocity=100, time=tick - last))
            track.append(mido.Message("note_on", channel=channel, note=pitch, velocity=0, time=60))
            last = tick + 60
        mid.tracks.append(track)
    mid.save(path)
    return path


def test_render_reads_the_channels_chosen_and_records_them(tmp_path: Path) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    args = render.build_parser().parse_args([str(path), "-o", str(tmp_path / "out"), "--drum-channels", "1"])
    opts = render.options_from(args)
    assert opts.midi == {"drum_channels": (1,)}
    assert {e.pitch for e in render.read_scaled(path, opts).events} == {36, 38}  # no wood block
    assert {e.pitch for e in render.read_scaled(path, render.RenderOptions()).events} == {36, 38, 76}
    assert render._drum_channels_json(opts) == [1]  # report.json's drum_channels
    assert render._drum_channels_json(render.RenderOptions()) is None


def _render_dir(folder: Path, score: Path, **report: Any) -> Path:
    """A render directory of ``score`` without impacts, as `batteur render` writes one."""
    folder.mkdir()
    (folder / "score.mid").write_bytes(score.read_bytes())
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    base = {"scene": "drummer", "score": str(score), "kit": "default", "grip": "german", "nuance": "tenuto",
            "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [], "score_offset_s": 1.5,
            "duration_s": 4.0, "wall_time_s": 3.0, "cpu_time_s": 3.0, "real_time_factor": 1.3}
    (folder / "report.json").write_text(json.dumps({**base, **report}))
    return folder


def test_evaluate_judges_a_render_against_the_channels_it_played(tmp_path: Path) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    chosen = _render_dir(tmp_path / "chosen", path, drum_channels=[1])
    assert evaluate.evaluate_render_dir(chosen / "score.mid", chosen).notes == 8  # the wood block was not played
    every = _render_dir(tmp_path / "every", path)
    assert evaluate.evaluate_render_dir(every / "score.mid", every).notes == 12
    broken = _render_dir(tmp_path / "broken", path, drum_channels=[0])
    with pytest.raises(ValueError, match="drum_channels must be a list of MIDI channels 1 to 16"):
        evaluate.evaluate_render_dir(broken / "score.mid", broken)


def test_evaluate_renders_with_the_channels_and_reuses_only_a_render_of_them(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    given: list[Any] = []
    monkeypatch.setattr(evaluate, "evaluate_scores", lambda paths, opts, *a, **k: given.append(opts) or [])
    evaluate.main([str(path), "--drum-channels", "1,16", "--quiet"])
    assert given[0].midi == {"drum_channels": (1, 16)}
    opts = render.RenderOptions(midi={"drum_channels": (1,)})
    assert evaluate.reusable(_render_dir(tmp_path / "same", path, drum_channels=[1]), path, opts)
    assert not evaluate.reusable(_render_dir(tmp_path / "every", path), path, opts)
    assert not evaluate.reusable(tmp_path / "same", path, render.RenderOptions())


def test_compare_reads_the_take_from_the_channels_chosen(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    exercise = tmp_path / "exercise.txt"
    exercise.write_text("tempo 120\nmeter 4/4\nSN |....x.......x...|....x.......x...|\n"
                        "BD |x.......x.......|x.......x.......|\n", encoding="utf-8")
    take = drums_and_wood_block(tmp_path / "take.mid")
    assert compare.main([str(exercise), str(take), "--json", "--offset", "0", "--drum-channels", "1"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert (got["played"], got["extra"]) == (8, 0)
    assert compare.main([str(exercise), str(take), "--json", "--offset", "0"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["extra"] == 4  # the wood block, read as cowbells
    assert "channel 16 (4 notes, track Wood Block)" in captured.err and "--drum-channels" in captured.err


@pytest.mark.parametrize("main", [render.main, evaluate.main, compare.main])
def test_a_channel_out_of_range_is_one_error_line(main: Any, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    argv = {render.main: [str(path), "-o", str(tmp_path / "out")], evaluate.main: [str(path)],
            compare.main: [str(path), str(path)]}[main]
    with pytest.raises(SystemExit) as refused:
        main([*argv, "--drum-channels", "1,17"])
    assert refused.value.code == 2
    assert "argument --drum-channels: '1,17': channel 17 is not a MIDI channel, 1 to 16" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
