"""Every command follows one convention (README, "Exit status"): 2 for a command line that cannot be run as given,
1 for an input or output it could not use, 130 for Ctrl-C; the error line is ``PROG: error: MESSAGE`` on stderr.

Each case fails before any simulation, render or network traffic: a script looping over files can tell a bad
call (2) from a bad file (1) whatever the command."""

from __future__ import annotations

import importlib
import signal
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pytest

from batteur import cli
from batteur.calibration import Calibration
from batteur.evaluate import table_legend

Main = Callable[[Sequence[str] | None], int]
MIDI = Path(__file__).resolve().parents[1] / "data" / "groove_drummer6_s3_1_rock_90_beat_4-4.mid"
SOUND_DEMO = "python -m services.sound.demo"
SYNTH = "python -m common.gesture.synth"
NODES = ("physics", "interaction", "sound", "graphics")


def command(name: str) -> tuple[Main, str]:
    """A command's ``main`` and the program name its error lines start with."""
    if name == SOUND_DEMO:
        return importlib.import_module("services.sound.demo").main, name
    if name == SYNTH:
        return importlib.import_module("common.gesture.synth").main, name
    return cli.load_command(name), f"batteur {name}"


def run(name: str, argv: Sequence[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Exit status, last stderr line and the program name of one run (argparse's errors exit by SystemExit)."""
    main, prog = command(name)
    capsys.readouterr()
    try:
        status = main(list(argv))
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    except KeyboardInterrupt:  # caught here: pytest would take it for the user's and stop the session
        pytest.fail(f"Ctrl-C escaped {prog}'s main (a traceback)")
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    return status, lines[-1] if lines else "", prog


@pytest.fixture(autouse=True)
def sigint_kept() -> Iterator[None]:
    """SIGINT's handler as it was after each test (a command may ignore a second Ctrl-C on its way out)."""
    handler = signal.getsignal(signal.SIGINT)
    yield
    signal.signal(signal.SIGINT, handler)


@pytest.fixture
def files(tmp_path: Path) -> dict[str, str]:
    """Inputs that fail: a text file named .mid, a WAV cut in its header, a file where a folder should be."""
    (tmp_path / "bad.mid").write_text("hello\n", encoding="utf-8")
    (tmp_path / "bad.wav").write_bytes(b"RIFF\x24\x00\x00\x00WAVEfmt ")
    (tmp_path / "a_file").write_text("in the way\n", encoding="utf-8")
    return {"bad_mid": str(tmp_path / "bad.mid"), "bad_wav": str(tmp_path / "bad.wav"),
            "missing_mid": str(tmp_path / "missing.mid"), "missing_wav": str(tmp_path / "missing.wav"),
            "blocked": str(tmp_path / "a_file" / "out"), "out": str(tmp_path / "out"),
            "out_mid": str(tmp_path / "out.mid"), "out_wav": str(tmp_path / "out.wav")}


ALL_COMMANDS = [*cli.COMMANDS, SOUND_DEMO, SYNTH]


@pytest.mark.parametrize("name", ALL_COMMANDS)
def test_an_unknown_option_exits_2_with_argparse_s_error_line(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    status, line, prog = run(name, ["--no-such-option"], capsys)
    assert status == 2
    assert line.startswith(f"{prog}: error: ")


BAD_VALUES = [  # an option's value out of range or of the wrong type, found before any file is read
    ("render", ["{missing_mid}", "-o", "{out}", "--tempo-scale", "50"]),
    ("render", ["{missing_mid}", "-o", "{out}", "--jobs", "-1"]),
    ("render", ["--strikes", "1:x", "-o", "{out}"]),
    ("render", ["--strikes", "0.5:2", "-o", "{out}", "--latency", "-1"]),  # was 1: refused by the strike scene
    ("render", ["{missing_mid}", "-o", "{out}", "--height", "99"]),
    ("render", ["{missing_mid}", "-o", "{out}", "--video", "--video-size", "15x15"]),
    ("evaluate", ["{missing_mid}", "--jobs", "-1"]),
    ("evaluate", ["{missing_mid}", "--tempo-scale", "0"]),
    ("compare", ["{missing_mid}", "{missing_wav}", "--tolerance", "-1"]),
    ("demo", ["--control", "no-such-mode"]),
    ("rig", ["--services", "drums", "--no-discovery"]),
    ("rig", ["--score", "{missing_mid}", "--services", "sound", "--no-discovery"]),
    ("rig", ["--record", "{out}", "--services", "physics", "--no-discovery"]),
    ("transcribe", ["{missing_wav}", "-o", "{out_mid}", "--tempo", "0"]),
    ("transcribe", ["{missing_wav}", "-o", "{out_wav}"]),
    ("ls", ["--node", "nowhere"]),
    ("echo", ["no-slash", "--node", "127.0.0.1:9"]),
    ("send", ["/batteur/graphics/latency", "abc", "--to", "127.0.0.1:9"]),
    ("send", ["/no/such/address", "--to", "127.0.0.1:9"]),
    ("wav-repair", []),
    (SOUND_DEMO, ["--reverb", "2", "-o", "{out_wav}"]),
]


@pytest.mark.parametrize(("name", "argv"), BAD_VALUES)
def test_a_bad_option_value_exits_2(name: str, argv: list[str], files: dict[str, str],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    status, line, prog = run(name, [a.format(**files) for a in argv], capsys)
    assert (status, line[:len(prog) + 9]) == (2, f"{prog}: error: ")


MISSING_INPUTS = [
    ("render", ["{missing_mid}", "-o", "{out}"]),
    ("render", ["--strikes", "0.5:2", "--kit", "{missing_mid}", "-o", "{out}"]),
    ("render", ["{missing_mid}", "-o", "{out}", "--calibration", "{missing_wav}"]),
    ("evaluate", ["{missing_mid}"]),
    ("compare", ["{missing_mid}", "{missing_wav}"]),
    ("compare", ["demo", "{missing_wav}"]),
    ("rig", ["--score", "{missing_mid}", "--no-discovery"]),
    ("transcribe", ["{missing_wav}", "-o", "{out_mid}"]),
    ("wav-repair", ["{missing_wav}"]),
    (SOUND_DEMO, ["--midi", "{missing_mid}", "-o", "{out_wav}"]),
    (SOUND_DEMO, ["--kit", "{missing_mid}", "-o", "{out_wav}"]),
]


CORRUPT_INPUTS = [
    ("render", ["{bad_mid}", "-o", "{out}"]),
    ("evaluate", ["{bad_mid}"]),
    ("compare", ["{bad_mid}", "{bad_wav}"]),
    ("compare", ["demo", "{bad_wav}"]),
    ("compare", ["demo", "{bad_mid}"]),
    ("rig", ["--score", "{bad_mid}", "--no-discovery"]),
    ("transcribe", ["{bad_wav}", "-o", "{out_mid}"]),
    ("transcribe", ["{bad_mid}", "-o", "{out_mid}"]),
    ("wav-repair", ["{bad_wav}"]),
    ("wav-repair", ["{bad_mid}"]),
    (SOUND_DEMO, ["--midi", "{bad_mid}", "-o", "{out_wav}"]),
]


UNWRITABLE_OUTPUTS = [  # a path under a file: no folder can be made there, even as root
    ("render", ["{missing_mid}", "-o", "{blocked}"]),
    ("render", ["--strikes", "0.5:2", "-o", "{blocked}"]),
    ("demo", ["-o", "{blocked}"]),
    ("evaluate", ["{missing_mid}", "--renders", "{blocked}"]),
    ("evaluate", ["{missing_mid}", "--fit-calibration", "{blocked}"]),
    ("rig", ["--record", "{blocked}", "--no-discovery"]),
    ("transcribe", ["{missing_wav}", "-o", "{blocked}.mid"]),
    ("docs", ["-o", "{blocked}"]),
    (SOUND_DEMO, ["-o", "{blocked}.wav"]),
    (SYNTH, ["--out", "{blocked}"]),
]


FILES_IT_CANNOT_USE = ([(name, argv, "missing") for name, argv in MISSING_INPUTS]
                       + [(name, argv, "bad.") for name, argv in CORRUPT_INPUTS]
                       + [(name, argv, "a_file") for name, argv in UNWRITABLE_OUTPUTS])
"""(command, arguments, a part of the file's name its error line must hold)."""


@pytest.mark.parametrize(("name", "argv", "named"), FILES_IT_CANNOT_USE)
def test_a_file_it_cannot_use_exits_1_and_is_named(name: str, argv: list[str], named: str, files: dict[str, str],
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """A missing input, an input it cannot read, an output path it cannot write."""
    status, line, prog = run(name, [a.format(**files) for a in argv], capsys)
    assert (status, line[:len(prog) + 9]) == (1, f"{prog}: error: ")
    assert named in line


INTERRUPTIBLE = [  # where the first long step starts: a Ctrl-C there
    ("render", ["{missing_mid}", "-o", "{out}"], "batteur.render.render_score"),
    ("demo", ["-o", "{out}"], "batteur.render.render_score"),
    ("evaluate", ["{missing_mid}"], "batteur.evaluate.evaluate_scores"),
    ("transcribe", ["{missing_wav}", "-o", "{out_mid}"], "services.recogniser.cli.load_model"),
    (SOUND_DEMO, ["--midi", str(MIDI), "-o", "{out_wav}"], "services.sound.demo.read_score"),
    (SYNTH, ["--out", "{out}"], "common.gesture.synth.make_unit"),
]


@pytest.mark.parametrize(("name", "argv", "target"), INTERRUPTIBLE)
def test_ctrl_c_exits_130_with_one_line(name: str, argv: list[str], target: str, files: dict[str, str],
                                        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    command(name)  # imported before it is patched
    monkeypatch.setattr(target, interrupted)
    status, line, prog = run(name, [a.format(**files) for a in argv], capsys)
    assert status == 130
    assert line.startswith(f"{prog}: interrupted")


@pytest.mark.parametrize("name", NODES)
def test_a_node_refuses_a_bad_setting_with_2_as_docs_runtime_says(name: str,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    status, line, prog = run(name, ["--rate-hz", "-5", "--no-discovery"], capsys)
    assert status == 2 and line.startswith(f"{prog}: error: ")  # its line is run_node's (common/runtime.py)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_a_write_that_fails_is_one_line_and_1(capsys: pytest.CaptureFixture[str]) -> None:
    status, line, prog = run("docs", ["-o", "/dev/full"], capsys)  # was a traceback
    assert (status, line) == (1, f"{prog}: error: -o /dev/full: cannot write it (No space left on device)")


def test_a_command_missing_from_the_installation_is_1(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    def not_installed(name: str) -> Main:
        raise ModuleNotFoundError("No module named 'soundfile'")

    monkeypatch.setattr(cli, "load_command", not_installed)
    assert cli.main(["transcribe", "x.wav"]) == 1  # the installation's fault: no command line would run
    assert capsys.readouterr().err.startswith("batteur transcribe: error: not available in this installation")


@pytest.fixture
def evaluated(monkeypatch: pytest.MonkeyPatch) -> Main:
    """``batteur evaluate``'s main with one score's results made up (the renders are not what is tested)."""
    from types import SimpleNamespace

    from batteur import evaluate

    result = SimpleNamespace(name="groove", missed=[], no_drum_notes=0, pairs_25=[], hits=[], summary=lambda: {})
    monkeypatch.setattr(evaluate, "evaluate_scores", lambda *args, **kwargs: [result])
    monkeypatch.setattr(evaluate, "format_table", lambda rows: "THE TABLE")
    monkeypatch.setattr(evaluate, "aggregate", lambda results: {})
    return evaluate.main


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_evaluate_s_calibration_that_cannot_be_written_after_the_renders_is_1(
        evaluated: Main, files: dict[str, str], monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr("batteur.calibration.fit_calibration", lambda *args, **kwargs: Calibration())
    assert evaluated([files["missing_mid"], "--fit-calibration", "/dev/full"]) == 1  # was a traceback
    out, err = capsys.readouterr()
    assert out == f"THE TABLE\n{table_legend()}\n"  # the figures measured are shown all the same
    assert err == "batteur evaluate: error: --fit-calibration /dev/full: cannot write it (No space left on device)\n"


def test_evaluate_s_plots_that_cannot_be_written_after_the_renders_are_1(
        evaluated: Main, files: dict[str, str], monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    plots = Path(files["out"])
    png = plots / "groove_pianoroll.png"

    def read_only(result: object, folder: Path) -> list[Path]:  # what matplotlib raises in a read-only folder
        raise PermissionError(13, "Permission denied", str(png))

    monkeypatch.setattr("batteur.evaluate.plot_result", read_only)
    assert evaluated([files["missing_mid"], "--plots", str(plots)]) == 1  # was a traceback
    out, err = capsys.readouterr()
    assert out == f"THE TABLE\n{table_legend()}\n"
    assert err == f"batteur evaluate: error: --plots {plots}: cannot write {png} (Permission denied)\n"


@pytest.mark.parametrize("prog", ["batteur demo", "batteur evaluate"])
def test_a_score_s_warning_names_the_command_that_renders_it(prog: str, tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import evaluate, render
    from tests.score.midi_files import drum_midi, with_key

    score = tmp_path / "bad_key.mid"
    score.write_bytes(with_key(drum_midi([(0, 4, 4)], [0, 480], key=True), b"\xff\x59\x02\xee\x01"))  # 18 flats

    def interrupted(*args: object) -> float:  # stops the render once the score's warnings are printed
        raise KeyboardInterrupt

    monkeypatch.setattr(render, "rendered_seconds", interrupted)
    if prog == "batteur demo":  # the demo renders through render's main
        assert render.main([str(score), "-o", str(tmp_path / "out"), "--quiet"], prog=prog) == 130
    else:
        assert evaluate.main([str(score), "--quiet"]) == 130
    err = capsys.readouterr().err
    assert f"{prog}: warning: {score}: a key signature that cannot be read ignored" in err
    assert "batteur render:" not in err  # was "batteur render: warning: ..."


def test_the_strike_scene_says_the_drummer_s_options_do_nothing(files: dict[str, str],
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """``--strikes`` plays one stick over one instrument: the drummer's size, motion file and style are ignored,
    and said to be (they were taken in silence, out of range too)."""
    from batteur import render

    args = render.build_parser().parse_args(["--strikes", "0.5:2", "-o", files["out"], "--height", "99",
                                             "--mass", "1", "--bvh-rate", "0", "--grip", "french"])
    warned = render.options_in_vain(args)
    assert [w.split()[0] for w in warned] == ["--height", "--mass", "--bvh-rate", "--grip"]
    assert all(w.endswith("has no effect with --strikes (the strike scene has no drummer)") for w in warned)
    assert render.options_in_vain(render.build_parser().parse_args(["--strikes", "0.5:2", "-o", files["out"]])) == []
