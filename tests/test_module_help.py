"""Every module one can run (``python -m MODULE``: a top-level ``if __name__ == "__main__":`` or a package's
``__main__.py``) in common/, services/, batteur/, bench/, pd/ and tests/ answers ``--help``: exit 0, a usage line on
stdout, and nothing written in the checkout (tracked or untracked files git does not ignore) nor in the folder it
ran in.

Found by scanning the tree, so a new module is covered. Until 7 Dec ``python -m tests.graphics.character_snapshot
--help`` rewrote services/graphics/character.json (a few values differ in the 6th decimal between machines),
``python -m common.messages.docs --help`` printed all of docs/osc.md, ``python -m services.physics.precompile
--help`` compiled the physics kernels and ``bench/live_stream_lag.py --help`` ran its minute of benchmark.

Each module runs as a subprocess (one that ignored ``--help`` would do its real work: not in the test's process),
as ``python -m`` runs it, with an audit hook (:func:`sys.addaudithook`) noting every file it opens for writing,
renames, removes or creates: what it writes itself, not what someone editing the checkout meanwhile does (a ``git
status`` taken before and after would count that), and a file rewritten with the same bytes too (which ``git
status`` does not show: character.json was one only on some machines). What C code (pyo's) or a program it starts
writes is not seen by the hook: the folder it ran in is checked as well.

The parts of the recogniser's trainers (``not_a_command``) are no commands: run, even with ``--help``, they exit 2
naming the commands that train (tests/recogniser/test_training_cli_inputs.py), and are checked for that here.
:data:`COVERED`: modules whose ``--help`` another test runs already, left out here as they are slow to start (their
imports: 1.5-5 s each, on one core).
"""

from __future__ import annotations

import ast
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("common", "services", "batteur", "bench", "pd", "tests")

pytestmark = pytest.mark.timeout(300)

COVERED = {
    "services.physics.node": "tests/cli/test_help_plain.py",  # batteur COMMAND --help, each command
    "services.sound.node": "tests/cli/test_help_plain.py",
    "services.recogniser.cli": "tests/cli/test_help_plain.py",
    "services.sound.demo": "tests/sound/test_sound_demo_interrupt.py",
    "common.gesture.synth": "tests/gesture/test_gesture_plans.py",
    "pd.make_control": "tests/deploy/test_pd_qa.py",
    "bench.physics_contact": "tests/test_bench_cli.py",
    "bench.sound_decay": "tests/test_bench_cli.py",
    "bench.sound_latency": "tests/test_bench_cli.py",
    "bench.live_replan": "tests/test_bench_cli.py",
    "services.recogniser.training.train": "tests/recogniser/test_training_cli_inputs.py",
    "services.recogniser.training.tune": "tests/recogniser/test_training_cli_inputs.py",
    "services.recogniser.training.render": "tests/recogniser/test_training_cli_inputs.py",
    "services.recogniser.training.excerpts": "tests/recogniser/test_training_cli_inputs.py",
    "services.recogniser.training.soundfont": "tests/recogniser/test_training_cli_inputs.py",
}
"""Module -> the test that runs its ``--help`` already (left out here: slow to start)."""

LAUNCH = """
import os, runpy, sys
log = os.open(os.environ.pop("BATTEUR_TEST_WRITES"), os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)
WRITING = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC
FIRST = {"open", "os.remove", "os.rmdir", "os.mkdir", "os.truncate", "shutil.rmtree", "os.utime"}
SECOND = {"os.rename", "os.link", "os.symlink", "shutil.copyfile", "shutil.copytree"}
def note(event, args):
    try:
        if event == "open" and not (isinstance(args[2], int) and args[2] & WRITING):
            return
        path = args[0] if event in FIRST else args[1] if event in SECOND else None
        if isinstance(path, (str, bytes)):
            os.write(log, (os.path.abspath(os.fsdecode(path)) + chr(10)).encode("utf-8", "surrogateescape"))
    except Exception:
        pass
sys.addaudithook(note)
module = sys.argv[1]
sys.argv = [module, *sys.argv[2:]]
runpy.run_module(module, run_name="__main__", alter_sys=True)
"""
"""Runs ``sys.argv[1]`` as ``python -m`` does, noting in $BATTEUR_TEST_WRITES each path written, one a line."""


def _is_main_guard(node: ast.stmt) -> bool:
    """``if __name__ == "__main__":`` (either order of the two sides)."""
    if not isinstance(node, ast.If) or not isinstance(node.test, ast.Compare) or len(node.test.comparators) != 1:
        return False
    sides = [node.test.left, node.test.comparators[0]]
    return (isinstance(node.test.ops[0], ast.Eq)
            and any(isinstance(s, ast.Name) and s.id == "__name__" for s in sides)
            and any(isinstance(s, ast.Constant) and s.value == "__main__" for s in sides))


def _calls(node: ast.AST, name: str) -> bool:
    return any(isinstance(n, ast.Call) and name in (getattr(n.func, "id", None), getattr(n.func, "attr", None))
               for n in ast.walk(node))


def _imports(tree: ast.Module, package: str) -> bool:
    """Whether the module imports ``package`` at its top level (not in a function)."""
    for node in tree.body:
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == package for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == package:
            return True
    return False


def runnable_modules() -> list[tuple[str, str, list[str]]]:
    """(module, kind, top-level imports that may be missing) of every runnable module; kind is "command", or
    "part" for a part of the trainers that says it is no command. A guard inside a string (a test's script) is none:
    only the module's own top-level statements count."""
    found = []
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            guards = [n for n in tree.body if _is_main_guard(n)]
            if path.name != "__main__.py" and not guards:
                continue
            parts = path.relative_to(ROOT).with_suffix("").parts
            module = ".".join(parts[:-1] if path.name == "__main__.py" else parts)
            kind = "part" if any(_calls(g, "not_a_command") for g in guards) else "command"
            found.append((module, kind, [p for p in ("torch",) if _imports(tree, p)]))
    return found


MODULES = runnable_modules()


def _in_checkout(paths: set[str]) -> list[str]:
    """The paths in the checkout that git does not ignore (without git: all but __pycache__'s)."""
    inside = sorted(p for p in paths if Path(p).is_relative_to(ROOT) and "__pycache__" not in Path(p).parts)
    if not inside or shutil.which("git") is None or not (ROOT / ".git").exists():
        return inside
    done = subprocess.run(["git", "-C", str(ROOT), "check-ignore", "--stdin"], input="\n".join(inside),
                          capture_output=True, text=True, timeout=60)
    ignored = set(done.stdout.splitlines())
    return [p for p in inside if p not in ignored]


def test_the_scan_finds_the_modules_it_should() -> None:
    """The scan itself: the known commands of each kind are found, a guard in a test's script string is not."""
    kinds = {module: kind for module, kind, _ in MODULES}
    assert kinds["batteur"] == kinds["common.score"] == "command"  # packages' __main__.py
    assert kinds["tests.graphics.character_snapshot"] == kinds["bench.live_stream_lag"] == "command"
    assert kinds["services.recogniser.training.tune"] == "part"
    assert "tests.test_runtime" not in kinds and "tests.physics.test_plan_reset" not in kinds  # guards in strings
    assert "tests.test_module_help" not in kinds


def test_the_modules_left_out_are_runnable_and_their_help_tested_elsewhere() -> None:
    """:data:`COVERED` names modules the scan finds, and tests that run their --help (or their command's)."""
    found = {module for module, _, _ in MODULES}
    for module, test in COVERED.items():
        assert module in found, f"{module} is no runnable module any more: drop it from COVERED"
        text = (ROOT / test).read_text(encoding="utf-8")
        assert "--help" in text, test
        assert module.rsplit(".", 1)[-1] in text or "cli.COMMANDS" in text, (module, test)


@pytest.mark.parametrize(("module", "kind", "needs"), [m for m in MODULES if m[0] not in COVERED],
                         ids=[m for m, _, _ in MODULES if m not in COVERED])
def test_help_explains_and_writes_nothing(module: str, kind: str, needs: list[str], tmp_path: Path) -> None:
    for package in needs:  # the trainers' network needs PyTorch, an optional extra
        if importlib.util.find_spec(package) is None:
            pytest.skip(f"{module} imports {package}, not installed")
    cwd, writes = tmp_path / "cwd", tmp_path / "writes.txt"
    cwd.mkdir()
    env = {**os.environ, "BATTEUR_TEST_WRITES": str(writes),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    done = subprocess.run([sys.executable, "-c", LAUNCH, module, "--help"], cwd=cwd, env=env,
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=240)
    written = set(writes.read_text(encoding="utf-8").splitlines()) if writes.exists() else set()
    assert not _in_checkout(written), f"python -m {module} --help wrote {_in_checkout(written)}"
    assert not [p for p in written if Path(p).is_relative_to(cwd)], f"python -m {module} --help wrote {written}"
    assert not list(cwd.iterdir())
    assert "Traceback" not in done.stderr, done.stderr
    if kind == "part":
        assert done.returncode == 2, (done.stdout, done.stderr)
        assert "not a command" in done.stderr and "services.recogniser.training.train_net" in done.stderr
        return
    assert done.returncode == 0, (done.stdout, done.stderr)
    assert "usage:" in done.stdout, done.stdout
