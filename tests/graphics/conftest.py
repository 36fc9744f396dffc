"""Shared helpers for the graphics tests: a graphics node in a subprocess, a headless chromium."""

from __future__ import annotations

import math
import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.messages import OscMessage, decode, encode
from tests.ports import free_port

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-gpu-sandbox",
    "--enable-unsafe-swiftshader",
]


class GraphicsNodeProcess:
    """``python -m services.graphics.node`` on loopback, discovery off, fixed ports (restartable)."""

    def __init__(self, tmp: Path, latency: float = 0.05, extra: list[str] | None = None) -> None:
        self.http_port = free_port(socket.SOCK_STREAM)
        self.osc_port = free_port(socket.SOCK_DGRAM)
        self.tmp = tmp
        self.latency = latency
        self.extra = list(extra or [])
        self.proc: subprocess.Popen[bytes] | None = None
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.http_port}/"

    def command(self) -> list[str]:
        """The node's command line (a subclass may run it another way)."""
        return [sys.executable, "-m", "services.graphics.node", "--no-discovery", "--host", "127.0.0.1",
                "--port", str(self.osc_port), "--http-port", str(self.http_port), "--latency-s", str(self.latency),
                "--kit-dir", str(self.tmp / "kits"), *self.extra]

    def start(self) -> None:
        log = open(self.tmp / "graphics-node.log", "ab")  # noqa: SIM115 - closed with the process
        self.proc = subprocess.Popen(
            self.command(),
            cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError((self.tmp / "graphics-node.log").read_text())
            try:
                with socket.create_connection(("127.0.0.1", self.http_port), timeout=0.2):
                    return
            except OSError:
                time.sleep(0.1)
        raise RuntimeError("graphics node did not start listening")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self.proc = None

    def send(self, message: OscMessage) -> None:
        self.sock.sendto(encode(message), ("127.0.0.1", self.osc_port))

    def close(self) -> None:
        self.stop()
        self.sock.close()


@pytest.fixture
def graphics_node(tmp_path: Path) -> Iterator[GraphicsNodeProcess]:
    node = GraphicsNodeProcess(tmp_path)
    node.start()
    try:
        yield node
    finally:
        node.close()


@pytest.fixture
def synthetic_node(tmp_path: Path) -> Iterator[GraphicsNodeProcess]:
    """A graphics node playing the synthetic drummer (frames flow without physics)."""
    node = GraphicsNodeProcess(tmp_path, extra=["--synthetic", "--clock-master", "self"])
    node.start()
    try:
        yield node
    finally:
        node.close()


def browser_available() -> bool:
    try:
        import playwright  # noqa: F401
    except ImportError:
        return False
    return os.path.exists(CHROMIUM)


needs_browser = pytest.mark.skipif(not browser_available(), reason="needs playwright (PyPI) and /usr/bin/chromium")
needs_ffmpeg = pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="needs ffmpeg (apt-get install ffmpeg)")


def project(point: np.ndarray, eye: np.ndarray, target: np.ndarray, fov_deg: float, width: int,
            height: int) -> tuple[float, float]:
    """Pixel (x, y) of world ``point`` seen by a z-up perspective camera at ``eye`` looking at ``target``."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = point - eye
    x, y, z = rel @ right, rel @ up, rel @ forward
    f = 1.0 / math.tan(math.radians(fov_deg) / 2)
    ndc_x = f * x / z / (width / height)
    ndc_y = f * y / z
    return (ndc_x + 1) / 2 * width, (1 - ndc_y) / 2 * height


def received_from(sock: socket.socket, kind: type, timeout: float = 10.0) -> list[Any]:
    """Messages of ``kind`` that reach ``sock`` (standing in for physics) within ``timeout`` seconds."""
    deadline, out = time.monotonic() + timeout, list[Any]()
    while time.monotonic() < deadline and not out:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            continue
        out = [m for m in decode(data).messages if isinstance(m, kind)]
    return out


@contextmanager
def open_page(url: str, frames: int = 10, width: int = 800, height: int = 450,
              wait_for_status: bool = False) -> Iterator[tuple[Any, list[str]]]:
    """The page in headless chromium once it has drawn more than ``frames`` frames (and, with ``wait_for_status``,
    shown a status): (page, page errors so far)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        page = browser.new_page(viewport={"width": width, "height": height})
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url)
        ready = f"window.batteur && window.batteur.frames > {frames}"
        page.wait_for_function(ready + (" && window.batteur.status" if wait_for_status else ""), timeout=20000)
        try:
            yield page, errors
        finally:
            browser.close()
