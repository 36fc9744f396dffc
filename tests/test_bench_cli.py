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


def test_graphics_stream_refuses_a_rate_the_graphics_node_refuses(capsys: pytest.CaptureFixture[str]) -> None:
    assert "--rate" in refused(capsys, bench("graphics_stream").parse_args, ["--rate", "1000"])
