"""The services' own commands follow the ``batteur`` commands' convention (README, "Exit status";
common/exit_status.py): 2 for a setting or option refused, 1 for a file they cannot use or a port they cannot
bind, 130 for Ctrl-C; the error line is ``PROG: error: MESSAGE``.

The nodes' cases run ``run_node`` (common/runtime.py) with a core that does nothing, so no service is started:
what is tested is how the runtime reports what a service's ``make_core`` raises."""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from common.config import NodeSettings
from common.exit_status import InputError
from common.runtime import run_node
from tests.cli.test_exit_statuses import run
from tests.null_core import NullCore

ROOT = Path(__file__).resolve().parents[2]
QUIET = ["--no-discovery", "--no-oscquery"]
"""A node on loopback only: no zeroconf, no OSCQuery server."""


@pytest.fixture(autouse=True)
def sigint_kept() -> Iterator[None]:
    """SIGINT's handler as it was after each test (a node installs its own while it starts)."""
    handler = signal.getsignal(signal.SIGINT)
    yield
    signal.signal(signal.SIGINT, handler)


def _last_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    return lines[-1] if lines else ""


def _raising(exc: BaseException):  # noqa: ANN202 - a make_core
    def make_core(settings: NodeSettings, extra: argparse.Namespace) -> NullCore:
        raise exc

    return make_core


@pytest.mark.parametrize(("exc", "status"), [
    (FileNotFoundError("no kit file 'kits/mine.yaml'"), 1),  # a kit, score or clip that is not there
    (PermissionError("--wav /take.wav: cannot write it (Permission denied)"), 1),
    (InputError("kit file 'mine.yaml' is not a valid kit: objects: field required"), 1),  # a corrupt file
    (ValueError("--reverb 2.0 is outside 0..1"), 2),  # an option's value: as before
])
def test_what_make_core_raises_gives_the_status_and_one_error_line(exc: Exception, status: int,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # an OSError was a traceback; a refused value's line had no "error:"
    assert run_node("sound", _raising(exc), QUIET) == status
    assert _last_error_line(capsys) == f"batteur sound: error: {exc}"


def test_a_port_in_use_is_1_with_an_error_line(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        status = run_node("sound", lambda settings, extra: NullCore(), [*QUIET, "--port", str(port)])
    assert status == 1
    assert _last_error_line(capsys).startswith(f"batteur sound: error: cannot run the node on 127.0.0.1:{port}: ")


@pytest.mark.parametrize("name", ["missing.yaml", "list.yaml", "broken.toml"])
def test_a_config_file_it_cannot_read_is_1(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "list.yaml").write_text("- port\n- 9000\n", encoding="utf-8")  # YAML, but no settings
    (tmp_path / "broken.toml").write_text("port = \n", encoding="utf-8")
    config = tmp_path / name
    status, line, prog = run("interaction", ["--config", str(config), *QUIET], capsys)
    assert (status, line[:len(prog) + 9]) == (1, f"{prog}: error: ")  # was 2, as a refused value
    assert f"config file {config}" in line


def test_a_value_refused_in_a_config_file_stays_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "rig.yaml"
    config.write_text("rate_hz: -5\n", encoding="utf-8")
    status, line, prog = run("interaction", ["--config", str(config), *QUIET], capsys)
    assert (status, line[:len(prog) + 9]) == (2, f"{prog}: error: ")
    assert "rate_hz" in line


# --------------------------------------------------------------------------- the recogniser's trainers
# (train_net and train need PyTorch and scikit-learn past their option checks: tests/recogniser/
# test_training_cli_inputs.py and test_training_cli_outputs.py cover them; profile and the checks both trainers
# share run without them)


def test_the_trainers_file_checks_name_the_trainer_and_say_error(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.model import load_live
    from services.recogniser.training.excerpts import check_files

    (tmp_path / "a_file").write_text("in the way\n", encoding="utf-8")
    garbage = tmp_path / "garbage.npz"
    garbage.write_text("not a model", encoding="utf-8")
    args = argparse.Namespace(out=tmp_path / "a_file" / "m.npz", cache=tmp_path / "cache")
    prog = "python -m services.recogniser.training.train_net"
    assert not check_files(args, [("--live-from", garbage, load_live)], prog)
    lines = capsys.readouterr().err.splitlines()
    assert [line.split(": ")[:3] for line in lines] == [[prog, "error", f"--out {args.out}"],
                                                        [prog, "error", "--live-from"]]  # was "error: ..."


def test_profile_without_its_data_is_1_with_one_line(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.training import profile
    from services.recogniser.training.kits import KitsMissingError

    def missing(names: object) -> None:
        raise KitsMissingError("hydrogen drum kits not found in /usr/share/hydrogen/data/drumkits: GMRockKit")

    monkeypatch.setattr(profile, "require_kits", missing)
    assert profile.main(["--out", str(tmp_path / "m.npz")]) == 1
    assert capsys.readouterr().err == f"{profile.PROG}: error: hydrogen drum kits not found in " \
                                      "/usr/share/hydrogen/data/drumkits: GMRockKit\n"  # was "error: ..."


def test_profile_interrupted_is_130_with_one_line_and_nothing_written(monkeypatch: pytest.MonkeyPatch,
                                                                      tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.training import profile

    def interrupted(*args: object) -> None:
        raise KeyboardInterrupt

    for name in ("require_kits", "require_more_kits", "require_groove"):  # the data is not what is tested
        monkeypatch.setattr(profile, name, lambda *args: None)
    monkeypatch.setattr(profile, "reference_profile", interrupted)  # Ctrl-C while the excerpts render
    out = tmp_path / "m.npz"
    try:
        status = profile.main(["--out", str(out)])
    except KeyboardInterrupt:  # caught here: pytest would take it for the user's and stop the session
        pytest.fail("Ctrl-C escaped the profile command's main (a traceback)")
    assert status == 130
    assert capsys.readouterr().err == f"{profile.PROG}: interrupted: nothing written to {out}\n"
    assert list(tmp_path.iterdir()) == []


def test_profile_s_model_that_cannot_be_written_at_the_end_is_1(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.model import Model
    from services.recogniser.training import profile

    def full(self: Model, path: Path, half: bool = False) -> None:  # the disk filled while it rendered
        raise OSError(28, "No space left on device")

    for name in ("require_kits", "require_more_kits", "require_groove"):  # the data is not what is tested
        monkeypatch.setattr(profile, name, lambda *args: None)
    monkeypatch.setattr(profile, "reference_profile", lambda net, excerpts, seed: net.profile)
    monkeypatch.setattr(Model, "save", full)
    out = tmp_path / "m.npz"
    assert profile.main(["--out", str(out)]) == 1  # was a traceback
    assert capsys.readouterr().err == (f"{profile.PROG}: error: --out {out}: cannot write it (No space left on "
                                       "device); nothing written\n")


# --------------------------------------------------------------------------- python -m common.gesture.synth


def _mapped(pid: int, library: str, timeout_s: float = 60.0) -> bool:
    """Wait until process ``pid`` has ``library`` (a substring of a path) mapped; False if it ended first."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            if library in Path(f"/proc/{pid}/maps").read_text():
                return True
        except OSError:  # it has ended
            return False
        time.sleep(0.001)
    return False


@pytest.mark.parametrize("library", ["_multiarray_umath", "pydantic_core"])
def test_synth_ctrl_c_while_it_starts_is_one_line_and_130(tmp_path: Path, library: str) -> None:
    out = tmp_path / "units"
    # SIGINT at its default: a suite run in the background ignores it, and so would the child
    proc = subprocess.Popen([sys.executable, "-m", "common.gesture.synth", "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    # while its imports load: NumPy (its first), pydantic (common.datafile's, a second later). Not after a fixed
    # delay: a signal while Python itself starts, before any of the synth's code, is Python's to report
    try:
        assert _mapped(proc.pid, library), f"{library} never loaded"
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:  # nothing left running in its own session
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert "Traceback" not in err and "Exception ignored" not in err, err  # was a KeyboardInterrupt traceback
    if proc.returncode != 0:  # 0: the machine was quick, the units were written before the signal
        assert proc.returncode == 130, err
        assert err.strip().splitlines()[-1] in ("python -m common.gesture.synth: interrupted: nothing written",
                                                "python -m common.gesture.synth: interrupted")


# --------------------------------------------------------------------------- the nodes' own files


@pytest.fixture
def node_files(tmp_path: Path) -> dict[str, str]:
    """A score that is not there, a kit file that is not a kit, a file where --wav's folder should be."""
    (tmp_path / "a_file").write_text("in the way\n", encoding="utf-8")
    (tmp_path / "bad_kit.yaml").write_text("objects: 3\n", encoding="utf-8")
    (tmp_path / "bad_mapping.yaml").write_text("routes: 5\n", encoding="utf-8")  # not an interaction config
    (tmp_path / "a_dir").mkdir()
    return {"missing_mid": str(tmp_path / "missing.mid"), "bad_kit": str(tmp_path / "bad_kit.yaml"),
            "missing_kit": str(tmp_path / "missing_kit.yaml"), "blocked_wav": str(tmp_path / "a_file" / "x.wav"),
            "bad_mapping": str(tmp_path / "bad_mapping.yaml"), "a_dir": str(tmp_path / "a_dir"),
            "blocked_dir": str(tmp_path / "a_file" / "kits")}


NODE_FILES = [  # each refused before the core starts (no physics, no sound)
    ("physics", ["--score", "{missing_mid}"], "missing.mid"),
    ("physics", ["--kit", "{missing_kit}"], "missing_kit.yaml"),
    ("physics", ["--kit", "{bad_kit}"], "bad_kit.yaml"),
    ("sound", ["--kit", "{missing_kit}", "--device", "none"], "missing_kit.yaml"),
    ("sound", ["--kit", "{bad_kit}", "--device", "none"], "bad_kit.yaml"),
    ("sound", ["--wav", "{blocked_wav}", "--device", "none"], "a_file"),
    ("graphics", ["--kit", "{missing_kit}"], "missing_kit.yaml"),
    ("graphics", ["--kit", "{bad_kit}"], "bad_kit.yaml"),
    ("graphics", ["--preview", "{bad_kit}"], "not a pose sequence file"),
    ("graphics", ["--preview-score", "{missing_mid}"], "missing.mid"),
    ("graphics", ["--preview-score", "{bad_kit}"], "bad_kit.yaml"),  # not a score
    ("graphics", ["--kit-dir", "{blocked_dir}"], "a_file is a file"),  # a folder it cannot write in
    ("interaction", ["--kit", "{missing_kit}", "--interaction-config", "none"], "missing_kit.yaml"),
    ("interaction", ["--kit", "{bad_kit}", "--interaction-config", "none"], "bad_kit.yaml"),
    ("interaction", ["--interaction-config", "{bad_mapping}"], "bad_mapping.yaml"),
    ("interaction", ["--interaction-config", "{a_dir}"], "is a folder, not a configuration file"),
]


@pytest.mark.parametrize(("name", "argv", "named"), NODE_FILES)
def test_a_file_a_node_cannot_use_is_1(name: str, argv: list[str], named: str, node_files: dict[str, str],
                                       capsys: pytest.CaptureFixture[str]) -> None:
    status, line, prog = run(name, [*(a.format(**node_files) for a in argv), *QUIET], capsys)
    assert (status, line[:len(prog) + 9]) == (1, f"{prog}: error: ")  # was 2, as a refused value
    assert named in line
