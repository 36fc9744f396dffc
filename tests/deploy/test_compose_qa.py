"""What a user of ``docker compose`` relies on, checked without a Docker engine.

* every ``BATTEUR_*`` variable compose.yaml (and the audio override) puts in a container is a setting the
  service reads: a misspelt or unknown name would be ignored without a word;
* the image's numba cache serves a container running as another uid (compose runs sound and pd-sound as
  ``BATTEUR_UID``, the owner of ./out);
* each container stops on its compose stop signal while it is PID 1 (which ignores signals it has no
  handler for), within compose's grace period;
* .ci/run installs on a clean Debian what it then runs.
"""

from __future__ import annotations

import json
import os
import re
import select
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.deploy.pdrun import pd_binary

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "compose.yaml"
AUDIO = ROOT / "docker" / "compose.audio.yaml"
DOCKERFILE = ROOT / "docker" / "Dockerfile"
DOCKERFILE_PD = ROOT / "docker" / "Dockerfile.pd"
ROLES = ("physics", "interaction", "sound", "graphics")
STOP_GRACE_S = 10.0
"""compose's default stop_grace_period: then the container is killed (SIGKILL)."""


def compose_config(*files: Path, profiles: tuple[str, ...] = ()) -> dict[str, Any]:
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.skip("docker-compose is not installed (Debian: apt-get install docker-compose)")
    args = [exe]
    for f in files or (COMPOSE,):
        args += ["-f", str(f)]
    for p in profiles:
        args += ["--profile", p]
    env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    result = subprocess.run([*args, "config"], capture_output=True, text=True, env=env, timeout=60, cwd=str(ROOT),
                            check=False)
    assert result.returncode == 0, result.stderr
    data: dict[str, Any] = yaml.safe_load(result.stdout)
    return data


def _seconds(value: Any, default: float) -> float:
    """A compose duration (``10s``, ``1m30s``, ``500ms``) in seconds."""
    if value is None:
        return default
    units = {"h": 3600.0, "m": 60.0, "s": 1.0, "ms": 1e-3, "us": 1e-6}
    parts = re.findall(r"([\d.]+)(ms|us|h|m|s)", str(value))
    return sum(float(n) * units[u] for n, u in parts) if parts else float(value)


# --------------------------------------------------------------------------- environment variables


@pytest.mark.parametrize("files", [(COMPOSE,), (COMPOSE, AUDIO)], ids=["compose", "compose+audio"])
def test_every_batteur_variable_in_a_container_is_a_setting_of_its_service(files: tuple[Path, ...]) -> None:
    """``batteur ROLE --show-settings`` with the container's command and environment shows a setting for each
    BATTEUR_* variable, with the variable's value (an unknown name would be silently ignored)."""
    services = compose_config(*files, profiles=("pd",))["services"]
    checked = 0
    for name, service in services.items():
        command = [str(a) for a in service.get("command") or []]
        if not command or command[0] not in ROLES:
            continue
        env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
        given = {k: str(v) for k, v in (service.get("environment") or {}).items() if k.startswith("BATTEUR_")}
        env.update(given)
        # discovery off: this machine has no eth0 to check (BATTEUR_INTERFACES is still read and shown)
        result = subprocess.run([sys.executable, "-m", "batteur", *command, "--no-discovery", "--show-settings"],
                                capture_output=True, text=True, env=env, timeout=120, cwd=str(ROOT), check=False)
        assert result.returncode == 0, f"{name}: {result.stderr}"
        shown = json.loads(result.stdout)
        for variable, value in given.items():
            setting = variable.removeprefix("BATTEUR_").lower()
            assert setting in shown, f"{name}: {variable} is not a setting of `batteur {command[0]}`"
            got = shown[setting]
            if isinstance(got, list):
                assert [str(x) for x in got] == [x.strip() for x in value.split(",") if x.strip()], (name, variable)
            elif value:
                assert str(got) == value or (isinstance(got, float) and got == float(value)), (name, variable, got)
            checked += 1
    assert checked >= len(ROLES)


def test_the_audio_override_binds_nothing_missing_from_the_users_home(tmp_path: Path) -> None:
    """Docker creates a missing bind source as a root-owned directory: under the user's home (e.g. a PulseAudio
    cookie on a PipeWire desktop, which has none) that breaks the host's own programs and needs sudo to undo."""
    home = tmp_path / "home"
    home.mkdir()
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.skip("docker-compose is not installed (Debian: apt-get install docker-compose)")
    env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    env["HOME"] = str(home)
    result = subprocess.run([exe, "-f", str(COMPOSE), "-f", str(AUDIO), "config"], capture_output=True, text=True,
                            env=env, timeout=60, cwd=str(ROOT), check=False)
    assert result.returncode == 0, result.stderr
    for name, service in yaml.safe_load(result.stdout)["services"].items():
        for volume in service.get("volumes") or []:
            source = volume.split(":")[0] if isinstance(volume, str) else str(volume.get("source", ""))
            if Path(source).is_relative_to(home):
                assert Path(source).exists(), f"{name}: Docker would create {source} in the user's home"


# --------------------------------------------------------------------------- the numba cache and the uid


def _needs_root_and_setpriv() -> str:
    setpriv = shutil.which("setpriv")
    if os.geteuid() != 0 or setpriv is None:
        pytest.skip("needs root and setpriv (util-linux) to run as another uid")
    return setpriv


def _dockerfile_commands(text: str) -> list[str]:
    """The shell commands of the Dockerfile's RUN instructions (continuation lines joined, split on ``&&``)."""
    joined = re.sub(r"\\\n", " ", text)
    commands: list[str] = []
    for line in joined.splitlines():
        if line.startswith("RUN "):
            commands += [c.strip() for c in line[4:].split("&&")]
    return commands


def test_the_image_numba_cache_serves_a_container_running_as_another_uid(tmp_path: Path) -> None:
    """compose runs sound as ${BATTEUR_UID} (docs: the owner of ./out, often not 1000). numba will not import a
    cached kernel unless it can write into the cache: the image's permission steps on NUMBA_CACHE_DIR, applied
    to a cache owned by the image user (uid 1000), must let uid 1001 import the sound and physics kernels."""
    setpriv = _needs_root_and_setpriv()
    text = DOCKERFILE.read_text()
    match = re.search(r"^ENV NUMBA_CACHE_DIR=(\S+)", text, re.M)
    assert match, "the image compiles its numba kernels into NUMBA_CACHE_DIR"
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    os.chown(cache, 1000, 1000)  # the Dockerfile's chown to the image user
    os.chmod(cache, 0o755)
    os.chmod(tmp_path, 0o755)
    for command in _dockerfile_commands(text):
        words = shlex.split(command)
        if words and words[0] == "chmod" and "$NUMBA_CACHE_DIR" in command:
            args = [str(cache) if w in ("$NUMBA_CACHE_DIR", match.group(1)) else w for w in words[1:]]
            subprocess.run(["chmod", *args], check=True, timeout=30)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BATTEUR_", "NUMBA_"))}
    env.update(NUMBA_CACHE_DIR=str(cache), HOME="/nonexistent", XDG_CACHE_HOME="/nonexistent",
               PYTHONDONTWRITEBYTECODE="1", PYTHONPATH=str(ROOT))
    code = "import services.sound.excitation, services.physics.kernels; print('imported')"
    # uid 1001, allowed to read (not write) everything, like a container user reading the image
    result = subprocess.run([setpriv, "--reuid", "1001", "--regid", "1001", "--clear-groups",
                             "--inh-caps", "+dac_read_search", "--ambient-caps", "+dac_read_search",
                             sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300,
                            cwd=str(tmp_path), check=False)
    assert result.returncode == 0 and "imported" in result.stdout, result.stderr[-2000:]


# --------------------------------------------------------------------------- stopping as PID 1


def _child_of(pid: int) -> int | None:
    try:
        children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    except OSError:
        return None
    return int(children[0]) if children else None


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_pd_sound_stops_on_its_compose_stop_signal_as_pid_1(tmp_path: Path) -> None:
    """The Pd client runs as the container's PID 1: the kernel drops the signals it has no handler for, so
    `docker compose stop` only works if compose sends a signal Pd handles (else: 10 s, then SIGKILL)."""
    pd = pd_binary()
    unshare = shutil.which("unshare")
    if pd is None or unshare is None or os.geteuid() != 0:
        pytest.skip("needs Pure Data, unshare (util-linux) and root for a PID and network namespace")
    service = compose_config(profiles=("pd",))["services"]["pd-sound"]
    stop_signal = signal.Signals[str(service.get("stop_signal", "SIGTERM"))]
    grace = _seconds(service.get("stop_grace_period"), STOP_GRACE_S)
    entry = json.loads(next(x for x in DOCKERFILE_PD.read_text().splitlines()
                            if x.startswith("ENTRYPOINT")).split(None, 1)[1])
    assert entry[0] == "pd"
    out = tmp_path / "out"
    out.mkdir()
    command = [str(a).replace("/out", str(out)).replace("0.0.0.0", "127.0.0.1") for a in service["command"]]
    argv = [pd, *entry[1:], *command[:-1], str(ROOT / "pd" / command[-1])]
    # a private network namespace (loopback only) and PID namespace: exec makes Pd its PID 1
    script = "ip link set lo up && exec " + shlex.join(argv)
    proc = subprocess.Popen([unshare, "--net", "--pid", "--fork", "--kill-child", "sh", "-c", script],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        said = b""
        assert proc.stderr is not None
        # the pipe read as it comes (select, then os.read): a buffered readline kept a second line that came with
        # the first (the take folder's, then the listening one) where select no longer saw it
        while b"batteur-listen" not in said:  # the patch prints it once it listens
            ready, _, _ = select.select([proc.stderr], [], [], 30)
            chunk = os.read(proc.stderr.fileno(), 65536) if ready else b""
            assert chunk, f"Pd did not start listening: {said.decode(errors='replace')}"
            said += chunk
        pid1 = _child_of(proc.pid)
        assert pid1 is not None and _alive(pid1)
        os.kill(pid1, stop_signal)  # what `docker compose stop` sends to the container's PID 1
        deadline = time.monotonic() + grace
        while _alive(pid1) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(pid1), f"Pd (PID 1) ignored {stop_signal.name}: compose would kill it after {grace:g} s"
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=10)
    # `docker run` / `docker stop` of the image alone send the image's STOPSIGNAL: the same one
    image_signal = re.search(r"^STOPSIGNAL (\S+)", DOCKERFILE_PD.read_text(), re.M)
    assert image_signal and signal.Signals[image_signal.group(1)] == stop_signal


# --------------------------------------------------------------------------- .ci/run on a clean Debian


def _apt_packages(script: str) -> set[str]:
    joined = re.sub(r"\\\n", " ", script)
    packages: set[str] = set()
    for line in joined.splitlines():
        if "apt-get install" in line:
            packages |= {w for w in line.split("apt-get install", 1)[1].split() if re.fullmatch(r"[a-z0-9.+-]+", w)}
        for group in re.findall(r"\w+=\(([^)]*)\)", line):  # packages gathered in a bash array
            packages |= set(group.split())
    return packages


def test_ci_installs_on_a_clean_debian_what_it_runs() -> None:
    """A clean Debian 12 has no pip (python3-pip), refuses `pip install` into its python3 (PEP 668: a virtual
    environment, python3-venv) and has no npm: .ci/run must provide each before using it."""
    script = (ROOT / ".ci" / "run").read_text()
    packages = _apt_packages(script)
    assert {"python3-pip", "python3-venv"} <= packages, packages
    assert "npm ci" not in script or {"nodejs", "npm"} <= packages, packages
    assert "EXTERNALLY-MANAGED" in script and "-m venv" in script
    # and still exactly the README's test command
    readme = (ROOT / "README.md").read_text()
    test_command = "python3 -m pip install -e '.[test]' && python3 -m pytest"
    assert test_command in readme and script.rstrip().endswith(test_command)
