"""Command lines of the benchmarks (bench/*.py): a bad option value is a usage error (exit 2) naming the option,
found before any long work starts, never a traceback after it; every script answers ``--help``.

The scripts are imported from their files and only their argument parsing is run (nothing is measured, nothing
touches the network)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
_loaded: dict[str, ModuleType] = {}


def bench(name: str) -> ModuleType:
    """bench/<name>.py as a module (loaded once; its ``main`` is not run)."""
    if name not in _loaded:
        spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCH / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # dataclasses in the scripts look their module up
        spec.loader.exec_module(module)
        _loaded[name] = module
    return _loaded[name]


def _repo_env() -> dict[str, str]:
    """The environment for a script run as a subprocess: the repository importable, installed or not."""
    import os

    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(BENCH.parent),
                                                                       os.environ.get("PYTHONPATH")]))}


def refused(capsys: pytest.CaptureFixture[str], parse: Any, argv: list[str]) -> str:
    """Run ``parse(argv)``; it must stop with a usage error (exit 2); returns what it printed on stderr."""
    with pytest.raises(SystemExit) as stop:
        parse(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2, err
    assert "usage:" in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("name", ["physics_contact", "sound_decay", "sound_latency"])
def test_the_scripts_without_options_answer_help_instead_of_running(name: str,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """They had no parser: ``--help`` (or a typo) ran the whole benchmark."""
    with pytest.raises(SystemExit) as stop:
        bench(name).main(["--help"])
    assert stop.value.code == 0 and "usage:" in capsys.readouterr().out
    refused(capsys, bench(name).main, ["--seconds", "3"])


def test_physics_contact_survives_a_stick_that_stays_on_the_head(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stick still on the head at the last simulated step has no rebound to measure: was a KeyError ending the
    run (a 1 m/s stroke on the strike scene's hi-hat, then standing open, stuck in its plate)."""
    from common.kit import EventType

    module = bench("physics_contact")
    monkeypatch.setattr(module, "STEPS", 50)  # the throw ends while the stick, on the snare from step 49, is on it
    steps, _, rebound, _, _ = module.measure(EventType.SNARE, 1.0)
    assert steps > 0 and math.isnan(rebound)
    monkeypatch.setattr(module, "STEPS", 120)
    assert not math.isnan(module.measure(EventType.SNARE, 1.0)[2])


def test_physics_rtf_refuses_less_than_one_step(capsys: pytest.CaptureFixture[str]) -> None:
    # was a ZeroDivisionError after every case had run
    assert "--seconds" in refused(capsys, bench("physics_rtf").parse_args, ["--seconds", "0.0001"])
    assert bench("physics_rtf").parse_args(["--seconds", "0.001"]).seconds == 0.001


def test_physics_tracking_checks_its_options_before_the_first_case(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("physics_tracking").parse_args
    a_file = tmp_path / "file"
    a_file.write_text("mine")
    assert "--seconds" in refused(capsys, parse, ["--seconds", "0.1"])  # was nan figures (nothing measured)
    assert "no clip 'nosuch'" in refused(capsys, parse, ["--clips", "nosuch"])  # was a traceback after a case
    assert "--control-rate" in refused(capsys, parse, ["--control-rate", "5"])  # was a pydantic traceback
    assert "--out" in refused(capsys, parse, ["--out", str(a_file / "x.png")])  # were tracebacks after the run
    assert "--out" in refused(capsys, parse, ["--out", str(tmp_path / "no" / "x.png")])
    assert "--out" in refused(capsys, parse, ["--out", str(tmp_path / "x.txt")])
    assert a_file.read_text() == "mine"
    assert parse(["--out", str(tmp_path / "x.png"), "--clips", "punch"]).clips == ["punch"]


def test_physics_tracking_says_what_it_runs_and_judges_only_long_enough_runs(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """``--clips none`` is the strokes alone, as its help says (was "no clip 'none'"); a control rate above the
    step rate is refused (ran at 1 kHz), one that is not a whole number of steps is said at its real rate (300 ran
    at 333.3 Hz, printed as 300); a run too short to measure gets no verdict (0.3-0.5 s got one from 0-3 contact
    steps); the contacts column says it counts steps in contact. The cases are stand-ins (nothing simulated): a
    Cartesian tip error of 1 mm and a joint-space one of 3 mm over the measured steps."""
    import numpy as np

    module = bench("physics_tracking")
    parse = module.parse_args
    out_png = ["--out", str(tmp_path / "x.png")]
    assert parse([*out_png, "--clips", "none"]).clips == []
    assert "--control-rate 3000" in refused(capsys, parse, [*out_png, "--control-rate", "3000"])

    def run_case(case: str, control: str, clip: str | None, seconds: float, rate: float) -> Any:
        times = np.arange(round(module.SETTLE_S * 1000), round(seconds * 1000)) / 1000 + 0.001
        error = np.full(len(times), 1.0 if control == "cartesian" else 3.0)
        return module.Result(case, control, times, error, np.zeros(len(times)), contacts=len(times) // 100)

    monkeypatch.setattr(module, "run_case", run_case)
    monkeypatch.setattr(module, "plot", lambda results, path: None)
    module.main([*out_png, "--clips", "none", "--seconds", "0.5", "--control-rate", "300"])
    printed = capsys.readouterr().out
    assert "control updates at 333.3 Hz (every 3 physics steps; 300 Hz asked)" in printed
    assert "contact steps" in printed
    assert "strokes: " in printed and "too short to judge (0.25 s measured" in printed and "the goal" not in printed
    module.main([*out_png, "--clips", "none", "--seconds", "2"])
    printed = capsys.readouterr().out
    assert "control updates at 1000 Hz (every 1 physics steps)" in printed
    assert "-> meets the goal" in printed and "too short" not in printed


def test_evaluate_groove_checks_its_options_before_rendering(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("evaluate_groove").parse_args
    root = tmp_path / "groove"
    root.mkdir()
    (root / "info.csv").write_text("midi_filename,split,duration,beat_type\n")
    a_file = tmp_path / "file"
    a_file.write_text("mine")
    here = ["--root", str(root)]
    assert "--root" in refused(capsys, parse, ["--root", str(tmp_path / "missing")])  # was FileNotFoundError
    assert "bogus" in refused(capsys, parse, [*here, "--controls", "cartesian,bogus"])  # was KeyError mid-run
    assert "--controls" in refused(capsys, parse, [*here, "--controls", ","])  # was an empty run, exit 0
    assert "--calibration" in refused(capsys, parse, [*here, "--calibration", str(tmp_path / "no.json")])
    assert "--json" in refused(capsys, parse, [*here, "--json", str(a_file / "x.json")])  # was after the run
    assert "--renders" in refused(capsys, parse, [*here, "--renders", str(a_file / "r")])
    assert "--reuse" in refused(capsys, parse, [*here, "--reuse"])  # was silently ignored
    assert "--control-rate" in refused(capsys, parse, [*here, "--control-rate", "5"])
    assert a_file.read_text() == "mine"
    assert parse([*here, "--controls", "joint_pd, cartesian"]).controls == ["joint_pd", "cartesian"]


def test_evaluate_groove_shows_progress_with_one_job(monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """With --jobs 1 (the default) a run of hours printed nothing until the end of each control mode."""
    module = bench("evaluate_groove")
    monkeypatch.setattr(module, "evaluate_scores", lambda paths, *args, **kwargs: [f"result {p}" for p in paths])
    files = [(Path("a.mid"), 1.0), (Path("b.mid"), 2.0)]
    assert module._evaluate(files, None, None, False, 1) == ["result a.mid", "result b.mid"]
    err = capsys.readouterr().err
    assert "[1/2] a.mid" in err and "[2/2] b.mid" in err


def test_render_speed_refuses_an_unknown_control_mode(capsys: pytest.CaptureFixture[str]) -> None:
    main = bench("render_speed").main
    assert "--control" in refused(capsys, main, ["--control", "bogus"])  # was a KeyError after the plan
    assert "--control-rate" in refused(capsys, main, ["--control-rate", "5"])  # was a traceback


def test_graphics_video_checks_the_frame_before_rendering(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("graphics_video").parse_args
    assert "--seconds" in refused(capsys, parse, ["--seconds", "0.01"])  # was a ZeroDivisionError
    assert "--width" in refused(capsys, parse, ["--width", "641"])  # was a traceback after rendering the frames
    assert "--width" in refused(capsys, parse, ["--width", "100000", "--height", "100000"])  # was an abort
    assert "--fps" in refused(capsys, parse, ["--fps", "1000"])
    assert "--score" in refused(capsys, parse, ["--score", str(tmp_path / "none.txt")])


def test_interaction_bench_refuses_more_copies_than_the_node_takes(capsys: pytest.CaptureFixture[str]) -> None:
    assert "--copies" in refused(capsys, bench("interaction_bench").parse_args, ["--copies", "17"])


def test_planning_bench_refuses_an_unknown_kit(capsys: pytest.CaptureFixture[str]) -> None:
    assert "--kit nosuch" in refused(capsys, bench("planning_bench").main, ["--kit", "nosuch"])


def test_recogniser_bench_refuses_a_bad_seed_kit_or_model(tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    module = bench("recogniser_bench")
    assert "--seed" in refused(capsys, module.parse_args, ["--seed", "-1"])  # was a numpy ValueError
    if not any(module.DRUMKITS_DIR.glob("*/drumkit.xml")):
        pytest.skip("hydrogen-drumkits not installed")
    assert "installed:" in refused(capsys, module.parse_args, ["--kit", "nosuch"])  # was "install the package"
    not_a_model = tmp_path / "model.npz"
    not_a_model.write_text("mine")
    assert module.main(["--model", str(not_a_model)]) == 1  # a file it cannot use (was a ModelError traceback)
    assert capsys.readouterr().err.startswith(f"{module.build_parser().prog}: error: --model ")


def test_sound_modes_takes_the_sound_service_block_sizes(capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("sound_modes").build_parser().parse_args
    assert "--block" in refused(capsys, parse, ["--block", "100003"])  # a table of modes x block: 80 GB
    assert parse(["--block", "512"]).block == 512


def test_transport_bench_checks_busy_and_rcvbuf(capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("transport_bench").parse_args
    for argv in (["--busy", "-1"], ["--busy", "nan"], ["--busy", "100"]):  # were tracebacks after the pings
        assert "--busy" in refused(capsys, parse, argv)
    for argv in (["--rcvbuf", "-5"], ["--rcvbuf", "99999999999"]):  # a receiver that dies, a parent that waits
        assert "--rcvbuf" in refused(capsys, parse, argv)
    assert parse(["--busy", "0.5"]).busy == 0.5


def test_two_hosts_bench_takes_a_percentage_of_loss(capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("two_hosts_bench").parse_args
    for loss in ("-5", "101"):  # was an nft error after the latency part
        assert "--loss" in refused(capsys, parse, ["--loss", loss])
    assert parse(["--loss", "0"]).loss == 0


def test_two_hosts_bench_refuses_too_few_pings_for_the_relay(capsys: pytest.CaptureFixture[str]) -> None:
    parse = bench("two_hosts_bench").parse_args
    # a quarter go through the relay: --pings 3 sent none there, "no samples" after half a minute of set-up
    assert "--pings" in refused(capsys, parse, ["--pings", "3"])
    assert parse(["--pings", "4"]).pings == 4


def test_graphics_stream_refuses_a_rate_the_graphics_node_refuses(capsys: pytest.CaptureFixture[str]) -> None:
    assert "--rate" in refused(capsys, bench("graphics_stream").parse_args, ["--rate", "1000"])


def _groove(root: Path, rows: list[tuple[str, str]]) -> Path:
    """A made-up Groove MIDI Dataset: info.csv with (midi_filename, split) rows, an empty file for each."""
    root.mkdir()
    lines = ["midi_filename,split,duration"] + [f"{name},{split},10.0" for name, split in rows]
    (root / "info.csv").write_text("\n".join(lines) + "\n")
    for name, _ in rows:
        (root / name).write_bytes(b"")
    return root


def test_recogniser_bench_says_when_the_groove_split_is_missing_or_empty(tmp_path: Path,
                                                                        monkeypatch: pytest.MonkeyPatch,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """No dataset was a FileNotFoundError traceback; a split with no file (this machine's copy has no test split)
    printed "0 Groove test files, 0 s of audio ... 0x real time" and exit 0."""
    from services.recogniser.training import dataset

    module = bench("recogniser_bench")
    if not any(module.DRUMKITS_DIR.glob("*/drumkit.xml")):
        pytest.skip("hydrogen-drumkits not installed")
    prog = module.build_parser().prog
    monkeypatch.setattr(dataset, "GROOVE_DIR", tmp_path / "missing")
    assert module.main(["--files", "1", "--seconds", "1"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{prog}: error: ") and "Groove MIDI Dataset" in err and "Traceback" not in err
    monkeypatch.setattr(dataset, "GROOVE_DIR", _groove(tmp_path / "groove", [("a.mid", "train")]))
    assert module.main(["--split", "test", "--files", "1", "--seconds", "1"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"{prog}: error: ") and "test split" in err


def test_recogniser_bench_says_when_no_note_falls_within_seconds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """--seconds shorter than the files' first notes: was a table of zeros and "0x real time", exit 0."""
    from services.recogniser.training import dataset

    module = bench("recogniser_bench")
    if not any(module.DRUMKITS_DIR.glob("*/drumkit.xml")):
        pytest.skip("hydrogen-drumkits not installed")
    monkeypatch.setattr(dataset, "GROOVE_DIR", _groove(tmp_path / "groove", [("a.mid", "validation")]))
    monkeypatch.setattr(module, "read_notes", lambda path: [module.Note(2.0, 38, 100)])  # the first note at 2 s
    assert module.main(["--files", "1", "--seconds", "0.5"]) == 1
    captured = capsys.readouterr()
    assert "--seconds 0.5" in captured.err and "real time" not in captured.out


def test_sound_modes_refuses_a_run_that_times_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    """--blocks 0 --change-modes 0 --strike-modes 0 printed nothing and exited 0."""
    err = refused(capsys, bench("sound_modes").main, ["--blocks", "0", "--change-modes", "0", "--strike-modes", "0"])
    assert "nothing to time" in err


def test_physics_rtf_states_the_simulated_time_it_ran(tmp_path: Path) -> None:
    """The header rounded --seconds to 0.1 s: "0.0 simulated s per case" for a run of 0.004 s (the whole script, as a
    subprocess: four 1 ms steps per case)."""
    import subprocess

    run = subprocess.run([sys.executable, str(BENCH / "physics_rtf.py"), "--seconds", "0.004"], cwd=tmp_path,
                         env=_repo_env(), capture_output=True, text=True, timeout=240)
    assert run.returncode == 0, run.stderr
    assert "0.004 simulated s per case" in run.stdout.splitlines()[0]


def test_graphics_stream_rates_count_the_poses_sent_not_the_seconds_asked(capsys: pytest.CaptureFixture[str]) -> None:
    """--seconds 0.001 at 60 Hz sends one pose: its frame was divided by 1 ms, "1000 frames/s" and 16 times the
    bytes/s (a real ViewServer on 127.0.0.1 and a WebSocket client, as the script runs them)."""
    import asyncio

    module = bench("graphics_stream")
    sequence, _ = module.synthetic_performance(duration=0.5, rate_hz=60.0)
    ws_rate, fps, osc = asyncio.run(module.measure(list(sequence.names), sequence.values, 0.001, 60.0))
    assert 0 < fps <= 60.0 and osc > 0
    assert ws_rate / fps > 500  # bytes per frame: a JSON frame of 23 links


def test_live_replan_help_gives_the_defaults_and_refuses_two_modes(capsys: pytest.CaptureFixture[str]) -> None:
    main = bench("live_replan").main
    with pytest.raises(SystemExit) as stop:
        main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert stop.value.code == 0
    for default in ("(default both)", "(default 10)", "(default 0.5)", "(default 1)", "(default process"):
        assert default in out  # --mode, --seconds, --period, --lead, --planner: none was given
    assert "--sync" in refused(capsys, main, ["--sync", "--mode", "background"])  # --mode was silently overridden


def test_live_replan_prints_no_nan_planning_time(tmp_path: Path) -> None:
    """The sync mode plans in the handler: its "planning nan ms/note" (a private figure only background plans of
    20 notes or more fill) now says where the planning time is. The whole script, as a subprocess, one live note:
    a window shorter than the loop's stall before it was ``max() arg is an empty sequence`` (no note sent)."""
    import subprocess

    run = subprocess.run([sys.executable, str(BENCH / "live_replan.py"), "--mode", "sync", "--seconds", "0.001",
                          "--lead", "0.5"], cwd=tmp_path, env=_repo_env(), capture_output=True, text=True,
                         timeout=240)
    assert run.returncode == 0, run.stderr
    line = next(line for line in run.stdout.splitlines() if line.lstrip().startswith("sync:"))
    assert "nan" not in line and "planning in the handler" in line


def test_graphics_video_checks_the_score_before_timing_the_frames(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("bad\n")
    # was "batteur render: error: ... unknown directive" after the frames had been rendered and timed
    assert "--score" in refused(capsys, bench("graphics_video").parse_args, ["--score", str(bad)])


def test_graphics_video_prints_no_paths_of_the_deleted_render(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``--score`` renders into a temporary directory: render's "wrote /tmp/tmpXXXX/performance.wav" lines named
    files deleted before the figures were printed. (render.main replaced by one writing what it writes.)"""
    import json

    from batteur import render

    def fake_render(argv: list[str]) -> int:
        out = Path(argv[argv.index("-o") + 1])
        (out / "report.json").write_text(json.dumps({"video": {"frames": 6, "wall_time_s": 0.5, "duration_s": 0.2}}))
        print(f"wrote {out / 'performance.wav'} (0.2 s)")
        return 0

    monkeypatch.setattr(render, "main", fake_render)
    score = Path(__file__).resolve().parent / "graphics" / "tiny_score.txt"
    bench("graphics_video").main(["--seconds", "0.1", "--width", "16", "--height", "16", "--score", str(score)])
    out = capsys.readouterr().out
    assert "wrote" not in out and "6 frames in 0.50 s = 12.0 frames/s" in out


def test_render_speed_names_the_processes_a_render_used(monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """A piece too short to cut ran --jobs 2 on one process: the comparison said "2 processes 1.18x (0.72 of 1)".
    (render_score replaced by one reporting what the render reports.)"""
    module = bench("render_speed")

    def fake_render(score: Path, out: Path, opts: Any, quiet: bool) -> dict[str, Any]:
        segments = None if opts.jobs == 1 else {"jobs": 1, "count": 1, "segment_s": 30.0}
        return {"duration_s": 5.6, "cpu_time_s": 3.0, "notes": 13, "music_duration_s": 4.1, "real_time_factor": 1.7,
                "wall_time_s": 3.3, "physics": {"rate_hz": 1000.0, "segments": segments}}

    monkeypatch.setattr(module, "render_score", fake_render)
    assert module.main(["--seconds", "2", "--jobs", "1,2", "--no-breakdown"]) == 0
    out = capsys.readouterr().out
    assert "1 processes" not in out and "1 process, 1 segment of 30 s" in out
    summary = out.splitlines()[-1]
    assert "2 processes" not in summary and "--jobs 2: 1 process" in summary


def test_render_speed_lets_the_render_show_its_progress(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--seconds 180`` is minutes per --jobs entry: the render ran quiet, nothing shown until the figures (the bar
    is drawn on a terminal's stderr only, as ``batteur render`` draws it)."""
    module = bench("render_speed")
    asked: list[bool] = []

    def fake_render(score: Path, out: Path, opts: Any, quiet: bool) -> dict[str, Any]:
        asked.append(quiet)
        return {"duration_s": 5.6, "cpu_time_s": 3.0, "notes": 13, "music_duration_s": 4.1, "real_time_factor": 1.7,
                "wall_time_s": 3.3, "physics": {"rate_hz": 1000.0, "segments": None}}

    monkeypatch.setattr(module, "render_score", fake_render)
    assert module.main(["--seconds", "2", "--no-breakdown"]) == 0
    assert asked == [False]


def test_interaction_bench_core_part_takes_copies(capsys: pytest.CaptureFixture[str]) -> None:
    """--copies reached the node only: the core-only part ran the default config's 5 copies whatever was asked."""
    module = bench("interaction_bench")
    module.bench_core(3, copies=1)
    assert "2 routes x 1 copies" in capsys.readouterr().out


def test_recogniser_bench_table_leaves_classes_without_strikes_blank(capsys: pytest.CaptureFixture[str]) -> None:
    """A class neither played nor found read "0.000 0.000 0.000", as a class the recogniser missed entirely."""
    module = bench("recogniser_bench")
    hits = [module.Hit(1.0, 0, 100), module.Hit(2.0, 0, 100)]  # two kicks (class 0), both found
    module.table([(hits, [(1.001, 0), (2.002, 0)])])
    rows = {line.split("|")[0].rsplit(None, 1)[0].strip(): line for line in capsys.readouterr().out.splitlines()[1:]}
    assert rows["kick"].split("|")[1].split() == ["1.000", "1.000", "1.000"]
    assert rows["crash"].split("|")[1].split() == ["-", "-", "-"]
