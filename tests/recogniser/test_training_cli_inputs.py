"""The trainers' command lines refuse bad input at once, with a one-line error, before anything is rendered.

A run renders for minutes and fits for up to an hour, so a bad number, an output that cannot be written or an
unreadable model file found at the end loses all of it. Every test here stops the trainer where it would start
rendering (``kits_installed`` replaced), so none renders or fits.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest

from services.recogniser.training import dataset, excerpts

ROOT = Path(__file__).resolve().parents[2]
GROOVE_MIDI = ROOT / "tests/data/groove_drummer6_s3_1_rock_90_beat_4-4.mid"
PROG = "python -m services.recogniser.training.train_net"
"""A trainer's name, as its error lines start."""


def _must_not_start(*_: object) -> bool:
    raise AssertionError("the trainer went on to render before refusing its command line")


def _train_net(monkeypatch: pytest.MonkeyPatch, installed: bool = True):  # noqa: ANN202 - the module
    """The offline network's trainer, stopped where it would render; ``installed``: skipped without PyTorch and
    mir_eval (which the trainer needs past its option checks)."""
    if installed:
        pytest.importorskip("torch")  # training-only dependency
        pytest.importorskip("mir_eval")
    from services.recogniser.training import train_net

    monkeypatch.setattr(train_net, "kits_installed", _must_not_start)
    return train_net


def _train(monkeypatch: pytest.MonkeyPatch, installed: bool = True):  # noqa: ANN202 - the module
    """The live classifier's trainer, stopped where it would render; ``installed``: skipped without
    scikit-learn and mir_eval (which the trainer needs past its option checks)."""
    if installed:
        pytest.importorskip("sklearn")  # training-only dependency
        pytest.importorskip("mir_eval")
    from services.recogniser.training import train

    monkeypatch.setattr(train, "kits_installed", _must_not_start)
    return train


def _one_line_error(text: str) -> str:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert "Traceback" not in text
    assert lines and "error:" in lines[-1], text
    return lines[-1]


@pytest.mark.parametrize("option, value", [
    ("--excerpts", "0"), ("--excerpts", "-2"), ("--val-excerpts", "0"), ("--epochs", "0"), ("--epochs", "-3"),
    ("--minutes", "0"), ("--minutes", "-1"), ("--minutes", "nan"), ("--lr", "nan"), ("--lr", "-1"),
    ("--lr", "0"), ("--warmup", "1"), ("--warmup", "-0.1"), ("--threads", "0"), ("--hard", "nan"),
    ("--hard", "-1"), ("--seed", "-1"), ("--workers", "0"),
    # ranges checked once parsed: were status 1, after the files were read
    ("--weight", "snare=nan"), ("--onset-merge", "0.5"), ("--neighbour-target", "1.5"), ("--quiet-hihats", "2"),
    ("--val-quiet-hihats", "-0.5"), ("--hop", "5"), ("--dilations", "0"), ("--width", "4"),
])
def test_train_net_refuses_a_bad_number_before_rendering(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str], option: str,
                                                         value: str) -> None:
    train_net = _train_net(monkeypatch, installed=False)  # the options are checked before PyTorch is imported
    with pytest.raises(SystemExit) as stop:
        train_net.main([option, value, "--out", str(tmp_path / "m.npz"), "--cache", str(tmp_path / "c")])
    assert stop.value.code == 2  # a usage error
    line = _one_line_error(capsys.readouterr().err)
    assert line.startswith(f"{train_net.PROG}: error: ") and option in line and value in line
    assert not (tmp_path / "m.npz").exists()


@pytest.mark.parametrize("weight", ["snare=nan", "snare=-1", "onset=inf"])
def test_train_net_refuses_a_loss_weight_that_is_not_a_finite_number(weight: str) -> None:
    from services.recogniser.training.train_net import output_weights

    with pytest.raises(ValueError, match="finite number"):
        output_weights([weight])
    assert output_weights(["snare=0", "onset=2.5"]) == {1: 0.0, 9: 2.5}


@pytest.mark.parametrize("option, value", [("--excerpts", "0"), ("--val-excerpts", "-1"), ("--seed", "-5")])
def test_train_refuses_a_bad_number_before_rendering(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str], option: str,
                                                     value: str) -> None:
    train = _train(monkeypatch, installed=False)  # the options are checked before scikit-learn is imported
    with pytest.raises(SystemExit) as stop:
        train.main([option, value, "--out", str(tmp_path / "m.npz"), "--cache", str(tmp_path / "c")])
    assert stop.value.code == 2
    assert option in _one_line_error(capsys.readouterr().err)


def _outputs(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "a-file").write_text("not a directory")
    (tmp_path / "a-dir").mkdir()
    return {"is not a directory": tmp_path / "missing" / "m.npz",
            "not a directory": tmp_path / "a-file" / "m.npz",
            "is a directory": tmp_path / "a-dir"}


def test_train_net_refuses_an_output_it_cannot_write_before_rendering(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    train_net = _train_net(monkeypatch)
    for why, out in _outputs(tmp_path).items():
        assert train_net.main(["--out", str(out), "--cache", str(tmp_path / "c"), "--excerpts", "1"]) == 1
        line = _one_line_error(capsys.readouterr().err)
        assert line.startswith(f"{train_net.PROG}: error: --out {out}") and why in line
    assert sorted(p.name for p in (tmp_path / "a-dir").iterdir()) == []  # nothing left behind by the check


def test_train_refuses_an_output_it_cannot_write_before_rendering(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    train = _train(monkeypatch)
    out = tmp_path / "missing" / "m.npz"
    assert train.main(["--out", str(out), "--cache", str(tmp_path / "c")]) == 1
    assert _one_line_error(capsys.readouterr().err).startswith(f"{train.PROG}: error: --out {out}")


def test_train_net_refuses_a_cache_it_cannot_make(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    train_net = _train_net(monkeypatch)
    (tmp_path / "a-file").write_text("x")
    cache = tmp_path / "a-file" / "cache"
    assert train_net.main(["--out", str(tmp_path / "m.npz"), "--cache", str(cache)]) == 1
    assert _one_line_error(capsys.readouterr().err).startswith(f"{train_net.PROG}: error: --cache {cache}")


@pytest.mark.parametrize("option", ["--live-from", "--retune", "--ensemble"])
def test_train_net_refuses_an_unreadable_model_file_before_rendering(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str) -> None:
    train_net = _train_net(monkeypatch)
    garbage = tmp_path / "garbage.npz"
    garbage.write_text("not a model")
    assert train_net.main([option, str(garbage), "--out", str(tmp_path / "m.npz"),
                           "--cache", str(tmp_path / "c")]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert line.startswith(f"{train_net.PROG}: error: {option}: {garbage}") and "not a Batteur recogniser model" in line


def test_train_refuses_an_unreadable_offline_model_before_rendering(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    train = _train(monkeypatch)
    assert train.main(["--offline-from", str(tmp_path / "none.npz"), "--out", str(tmp_path / "m.npz"),
                       "--cache", str(tmp_path / "c")]) == 1
    assert "model file not found" in _one_line_error(capsys.readouterr().err)


def _groove(root: Path, midi: dict[str, Path | None]) -> Path:
    """A Groove-like folder: info.csv listing ``midi`` (name -> file copied there, or None: listed, missing)."""
    root.mkdir()
    with open(root / "info.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["midi_filename", "duration", "split"])
        for name, src in midi.items():
            w.writerow([name, "40.0", "train"])
            if src is not None:
                (root / name).write_bytes(src.read_bytes())
    return root


def test_a_missing_groove_dataset_is_refused_before_rendering(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(excerpts, "require_kits", lambda names: None)  # the kits are not what is tested
    monkeypatch.setattr(dataset, "GROOVE_DIR", tmp_path / "nowhere")
    assert not excerpts.kits_installed(PROG)
    line = _one_line_error(capsys.readouterr().err)
    assert line.startswith(f"{PROG}: error: ")  # the trainer's name, as every command's error line
    assert "Groove MIDI Dataset" in line and str(tmp_path / "nowhere" / "info.csv") in line

    monkeypatch.setattr(dataset, "GROOVE_DIR", _groove(tmp_path / "partly", {"a.mid": GROOVE_MIDI, "b.mid": None}))
    assert not excerpts.kits_installed(PROG)
    assert "1 of the 2 Groove MIDI files" in _one_line_error(capsys.readouterr().err)

    monkeypatch.setattr(dataset, "GROOVE_DIR", _groove(tmp_path / "whole", {"a.mid": GROOVE_MIDI}))
    assert excerpts.kits_installed(PROG)


def _run_without(modules: str | tuple[str, ...], trainer: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run a trainer as a program in a Python where ``modules`` (top-level names) cannot be imported."""
    names = (modules,) if isinstance(modules, str) else modules
    code = f"""
import runpy, sys

class Uninstalled:  # as if the modules were not installed (None in sys.modules would confuse SciPy)
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {names!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)

sys.meta_path.insert(0, Uninstalled())
sys.argv = ["{trainer}", *{list(args)!r}]
runpy.run_module("services.recogniser.training.{trainer}", run_name="__main__")
"""
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("module, trainer, names", [
    ("torch", "train_net", ("PyTorch", "pip install torch")),
    ("mir_eval", "train_net", ("mir_eval", "pip install")),
    ("sklearn", "train", ("scikit-learn", "'.[train]'")),
])
def test_a_missing_training_dependency_says_what_to_install(module: str, trainer: str,
                                                            names: tuple[str, ...]) -> None:
    needs = {"train_net": ("torch", "mir_eval"), "train": ("sklearn", "mir_eval")}[trainer]
    if not all(_importable(m) for m in needs if m != module):  # else the trainer names that one first
        pytest.skip(f"{trainer}'s other dependencies are not all installed")
    done = _run_without(module, trainer, "--excerpts", "1")  # a command line it can run: its modules are needed
    assert done.returncode == 1
    line = _one_line_error(done.stderr)
    assert line.startswith(f"python -m services.recogniser.training.{trainer}: error: ")
    assert len(done.stderr.strip().splitlines()) == 1
    assert all(n in line for n in names), line


TRAINING_ONLY = ("torch", "sklearn", "threadpoolctl", "mir_eval")
"""The trainers' dependencies that neither the service nor CI installs."""


@pytest.mark.parametrize("trainer", ["train_net", "train"])
def test_a_trainer_s_help_and_option_checks_need_no_training_dependency(trainer: str) -> None:
    done = _run_without(TRAINING_ONLY, trainer, "--help")  # was "PyTorch is needed ..." with status 1
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert "--seed SEED" in done.stdout and "--out OUT" in done.stdout
    done = _run_without(TRAINING_ONLY, trainer, "--excerpts", "0")
    assert done.returncode == 2  # the command line, refused before what it would need is looked for
    line = _one_line_error(done.stderr)
    assert line.startswith(f"python -m services.recogniser.training.{trainer}: error: ") and "--excerpts" in line


def test_the_trainers_help_explains_the_seed_the_cache_and_the_output(monkeypatch: pytest.MonkeyPatch,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    mains = [_train_net(monkeypatch, installed=False).main, _train(monkeypatch, installed=False).main]
    for main in mains:
        with pytest.raises(SystemExit) as stop:
            main(["--help"])
        assert stop.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "--seed SEED random seed" in text
        assert "--cache CACHE directory where rendered excerpts are kept" in text
        assert "--out OUT model file to write" in text and "default: the shipped model" in text


def _importable(module: str) -> bool:
    try:
        __import__(module)
    except ImportError:
        return False
    return True


@pytest.mark.parametrize("option", ["--init", "--retune", "--ensemble"])
def test_train_net_refuses_a_model_whose_weights_are_not_numbers(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str) -> None:
    train_net = _train_net(monkeypatch)
    from services.recogniser.model import MODEL_PATH, load_model

    model = load_model(MODEL_PATH)  # read only; the damaged copy is written in tmp_path
    model.offline.layers[-1].w[0, 0, 0] = float("nan")  # as a diverged fitting wrote them before
    diverged = tmp_path / "diverged.npz"
    model.save(diverged)
    out = tmp_path / "m.npz"
    assert train_net.main([option, str(diverged), "--out", str(out), "--cache", str(tmp_path / "c")]) == 1
    line = _one_line_error(capsys.readouterr().err)
    assert line.startswith(f"{train_net.PROG}: error: {option}: {diverged}") and "holds NaN or infinite values" in line
    assert not out.exists()


@pytest.mark.parametrize("module", ["tune", "render", "excerpts", "soundfont"])
def test_a_part_of_the_trainers_run_as_a_program_says_which_commands_train(module: str) -> None:
    if module == "tune":
        pytest.importorskip("mir_eval")
    done = subprocess.run([sys.executable, "-m", f"services.recogniser.training.{module}", "--help"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2  # not 0 with no output, as if it had worked
    line = _one_line_error(done.stderr)
    assert line.startswith(f"python -m services.recogniser.training.{module}: error: ")
    assert "services.recogniser.training.train_net" in line and "services.recogniser.training.train " in line
