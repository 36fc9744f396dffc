"""A stand-in receiver for tests: prints every unique /batteur/impact it gets as a JSON line.

    python -m tests.impact_listener --port 9400

Prints ``{"event": "ready", "port": N}`` once listening, then
``{"event": "impact", ...fields...}`` per impact (first copy of each
(source, seq)), until SIGTERM or SIGINT.
"""

from __future__ import annotations

import argparse
import json
import signal
import socket
import sys

from common.messages import Impact, decode


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, required=True)
    opts = parser.parse_args()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((opts.host, opts.port))
    sock.settimeout(0.2)
    running = True

    def stop(*_: object) -> None:
        nonlocal running
        running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print(json.dumps({"event": "ready", "port": opts.port}), flush=True)
    seen: set[tuple[str, int]] = set()
    while running:
        try:
            data, source = sock.recvfrom(65535)
        except TimeoutError:
            continue
        for message in decode(data).messages:
            if isinstance(message, Impact) and (source[0], message.seq) not in seen:
                seen.add((source[0], message.seq))
                print(json.dumps({"event": "impact", **message.model_dump(mode="json")}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
