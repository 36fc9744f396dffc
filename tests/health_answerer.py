"""A UDP "node" in the test's process, on loopback: it answers every Hello with one encoded Health, so that
``batteur ls`` (and anything else that asks a node for its Health) can be tested against a Health of the test's
choosing (fields set, or an older node's shorter one) without starting a node."""

from __future__ import annotations

import socket
import threading

from common.messages import Hello, MessageError, decode


class HealthAnswerer:
    """Answers a Hello with ``packet`` (an encoded Health) from ``host``:``port`` (default 127.0.0.1, any free port;
    ``host`` may be ::1); :meth:`close` stops it."""

    def __init__(self, packet: bytes, host: str = "127.0.0.1", port: int = 0) -> None:
        self.packet = packet
        self.sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.sock.settimeout(0.05)
        self.port: int = self.sock.getsockname()[1]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                data, source = self.sock.recvfrom(65535)
                messages = decode(data).messages
            except (TimeoutError, MessageError):
                continue
            except OSError:
                return
            if any(isinstance(m, Hello) for m in messages):
                self.sock.sendto(self.packet, source[:2])

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.sock.close()
