"""``batteur evaluate`` on the command line: the music's duration as report.json gives it, one row per render
folder (named after it), ``--reuse`` only with ``--renders``, and a ``--renders DIR`` it created removed again when
it was given up before any render was kept."""

from __future__ import annotations

import json
import os
import pty
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from batteur import evaluate
from batteur.impact_log import COLUMNS
from tests.render.terminal import read_terminal

ROOT = Path(__file__).resolve().parents[2]
TINY = "tempo 120\nmeter 4/4\nSN |x.x.|\n"
"""One bar, two snare notes."""
WAIT_S = 240.0
"""A bound on each wait of the Ctrl-C test (the bar, the exit), not a measured figure: the machine may be loaded."""


def _fake_render(folder: Path, **report: Any) -> Path:
    """A render directory as `batteur render` writes one (no impacts), its report overridden by ``report``."""
    folder.mkdir(parents=True)
    (folder / "score.txt").write_text(TINY)
    (folder / "impacts.csv").write_text(",".join(COLUMNS) + "\n")
    base = {"scene": "drummer", "score": "tiny.txt", "kit": "default", "grip": "german", "nuance": "tenuto",
            "tempo_scale": 1.0, "control": "cartesian", "calibration": None, "issues": [], "score_offset_s": 1.5,
            "duration_s": 4.0, "music_duration_s": 0.5, "wall_time_s": 2.0, "cpu_time_s": 2.5,
            "real_time_factor": 2.0}
    (folder / "report.json").write_text(json.dumps({**base, **report}))
    return folder


def test_the_music_duration_is_the_reports_and_the_real_time_factor_its_meaning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """report.json: ``music_duration_s`` the planned music (0.5 s), ``duration_s`` the WAV (lead-in and tail
    included, 4 s) and ``real_time_factor`` duration_s / wall. evaluate gave the WAV's length as the music's."""
    a = _fake_render(tmp_path / "a")
    b = _fake_render(tmp_path / "b", music_duration_s=1.5, duration_s=6.0, wall_time_s=3.0, cpu_time_s=3.5,
                     real_time_factor=2.0)
    assert evaluate.main([str(a), str(b), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [f["music_duration_s"] for f in out["files"]] == [0.5, 1.5]
    assert [f["duration_s"] for f in out["files"]] == [4.0, 6.0]
    agg = out["aggregate"]
    assert agg["music_duration_s"] == 2.0 and agg["duration_s"] == 10.0
    assert agg["real_time_factor"] == 2.0  # (4 + 6) s rendered / (2 + 3) s wall, as each report's
    assert agg["real_time_factor_cpu"] == round(10.0 / 6.0, 3)


def test_renders_of_one_score_are_told_apart_by_their_folders(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """Three renders of fill6.mid were three rows named ``fill6.mid``."""
    folders = [_fake_render(tmp_path / name, score="some/where/fill6.mid") for name in ("o9", "o10", "o11")]
    for folder in folders:
        (folder / "score.txt").rename(folder / "score.mid")
        (folder / "score.mid").write_bytes(_midi_bytes())
    assert evaluate.main([str(f) for f in folders]) == 0
    rows = [line.split("  ")[0] for line in capsys.readouterr().out.splitlines()[1:4]]
    assert rows == ["o9 (fill6.mid)", "o10 (fill6.mid)", "o11 (fill6.mid)"]
    assert evaluate.main([str(f) for f in folders] + ["--json"]) == 0
    names = [f["name"] for f in json.loads(capsys.readouterr().out)["files"]]
    assert names == ["o9 (fill6.mid)", "o10 (fill6.mid)", "o11 (fill6.mid)"]


def test_the_current_folder_is_named_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(_fake_render(tmp_path / "r1"))
    assert evaluate.main([".", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["files"][0]["name"] == "r1 (tiny.txt)"


def _midi_bytes() -> bytes:
    import io

    import mido

    track = mido.MidiTrack([mido.Message("note_on", channel=9, note=38, velocity=100, time=0),
                            mido.Message("note_on", channel=9, note=38, velocity=0, time=240)])
    buffer = io.BytesIO()
    mido.MidiFile(tracks=[track]).save(file=buffer)
    return buffer.getvalue()


def test_plots_of_two_renders_of_one_score_do_not_overwrite_each_other(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    folders = [_fake_render(tmp_path / name) for name in ("first", "second")]
    plots = tmp_path / "plots"
    assert evaluate.main([str(f) for f in folders] + ["--plots", str(plots)]) == 0
    assert sorted(p.name for p in plots.iterdir()) == ["first_pianoroll.png", "first_timing.png",
                                                       "second_pianoroll.png", "second_timing.png"]


def test_reuse_without_renders_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--reuse`` reuses the renders kept in ``--renders DIR``; alone it did nothing, without a word. Exit status 2
    and one line, as render's options that exclude each other (until 7 Dec argparse's whole usage came first)."""
    score = tmp_path / "tiny.txt"
    score.write_text(TINY)
    assert evaluate.main([str(score), "--reuse"]) == 2
    captured = capsys.readouterr()
    assert captured.err == ("batteur evaluate: error: --reuse needs --renders DIR (the folder whose renders it "
                            "reuses)\n") and captured.out == ""


def _interrupting_render(path: Path, out: Path, *args: object, **kwargs: object) -> None:
    """Ctrl-C during a render: its staging made ``out`` (and the folders above) and removed ``out`` again."""
    out.mkdir(parents=True, exist_ok=True)
    out.rmdir()
    raise KeyboardInterrupt


def test_a_renders_folder_given_up_is_removed_only_if_the_evaluation_made_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import batteur.render

    score = tmp_path / "tiny.txt"
    score.write_text(TINY)
    monkeypatch.setattr(batteur.render, "render_score", _interrupting_render)
    made = tmp_path / "new" / "renders"
    assert evaluate.main([str(score), "--renders", str(made)]) == 130
    assert not (tmp_path / "new").exists()  # it and the parent it made
    there = tmp_path / "there"
    there.mkdir()
    assert evaluate.main([str(score), "--renders", str(there)]) == 130
    assert there.is_dir()  # the user's folder, even empty, stays


def test_a_finished_render_is_kept_when_the_next_is_given_up(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """What was rendered before the Ctrl-C stays in ``--renders DIR`` (``--reuse`` takes it up again)."""
    import batteur.render

    first, second = tmp_path / "first.txt", tmp_path / "second.txt"
    first.write_text(TINY)
    second.write_text(TINY)

    def render_first_only(path: Path, out: Path, *args: object, **kwargs: object) -> None:
        if path == second:
            raise KeyboardInterrupt
        _fake_render(out)

    monkeypatch.setattr(batteur.render, "render_score", render_first_only)
    renders = tmp_path / "renders"
    assert evaluate.main([str(first), str(second), "--renders", str(renders)]) == 130
    assert sorted(p.name for p in renders.iterdir()) == ["first"]


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a pty and process groups as on Linux")
def test_ctrl_c_to_the_process_group_leaves_no_renders_folder_behind(tmp_path: Path) -> None:
    """A terminal's Ctrl-C (SIGINT to the process group) while the first score renders: exit 130, and the
    ``--renders`` folder evaluate created is gone (it was left empty)."""
    score = tmp_path / "rock.txt"
    bar = "HH |x.x.x.x.|\nSN |....X...|\nBD |x.......|"
    score.write_text("tempo 100\nmeter 4/4\n" + "\n\n".join([bar] * 60))  # 144 s: never done before the Ctrl-C
    renders = tmp_path / "renders"
    terminal, stderr = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "batteur", "evaluate", str(score), "--renders", str(renders)],
                            cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr,
                            start_new_session=True)  # its own process group, as a shell gives it
    os.close(stderr)
    shown = ""
    try:
        deadline = time.monotonic() + WAIT_S
        while proc.poll() is None and time.monotonic() < deadline and not re.search(r"rendering rock\.txt \[", shown):
            shown += read_terminal(terminal, 0.1)
        assert proc.poll() is None and "rendering rock.txt [" in shown, shown[-2000:]
        assert renders.is_dir()  # the render is under way inside it
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=WAIT_S) == 130
        shown += read_terminal(terminal, 1.0)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        os.close(terminal)
    assert "batteur evaluate: interrupted" in shown and "Traceback" not in shown, shown[-2000:]
    assert not renders.exists()
