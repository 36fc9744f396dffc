"""The physics node's start: how long until it says it is up, and how long after that a live note plays.

    taskset -c 0 python3 bench/physics_start.py                    # quiet
    taskset -c 0 python3 bench/physics_start.py --hogs 2           # two CPU hogs on the same core
    taskset -c 0 python3 bench/physics_start.py --root /tmp/wt     # the node of another tree (before/after)

Starts ``python3 -m services.physics.node`` (from ``--root``; loopback, discovery and OSCQuery off, no poses) with
the rig epoch at its launch, and with this script as its ``interaction`` peer, so its contacts come here. From the
node's "listening on" line (its "up": it answers Hellos from then on) a snare live note is sent every
``--period`` seconds, each ``--lead`` seconds ahead of its rig time, until one is struck (a snare contact at or
after its time). Printed: launch to up (s), up to the first struck note's impact (s), when that note was sent (s
after up), the notes refused before (and the first refusal's reason). The hogs (``--hogs``: busy-looping
processes at normal priority) start before the node and inherit this process's CPUs: run it under ``taskset`` to
share one core. Wall clock, one run: compare runs taken in one sitting.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from common.arg_types import seconds, whole_non_negative
from common.messages import Contact
from common.messages.codec import decode, encode
from common.messages.physics import PhysicsRejected
from common.messages.score import LiveNote

ROOT = Path(__file__).resolve().parents[1]
SNARE = 38
"""GM acoustic snare: the live notes' pitch."""
UP = "listening on"
"""The node's line once it listens (common/runtime.py ``Node.start``)."""


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def run(root: Path, hogs: int, lead_s: float, period_s: float, timeout_s: float) -> dict[str, object]:
    """One start of the node of tree ``root``; returns its figures (seconds, wall clock)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.01)
    here = sock.getsockname()
    port = _free_port()
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(hogs)]
    epoch = time.time()
    launched = time.monotonic()
    command = [sys.executable, "-m", "services.physics.node", "--host", "127.0.0.1", "--port", str(port),
               "--no-discovery", "--no-oscquery", "--pose-rate-hz", "0", "--epoch", repr(epoch),
               "--peer", f"interaction=127.0.0.1:{here[1]}", "--node-id", "physics-start-bench"]
    env = {**os.environ, "PYTHONPATH": str(root)}
    node = subprocess.Popen(command, cwd=root, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    up = threading.Event()
    up_at: list[float] = []
    lines: list[str] = []

    def read() -> None:
        assert node.stderr is not None
        for line in node.stderr:
            lines.append(line)
            if UP in line and not up.is_set():
                up_at.append(time.monotonic())
                up.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    figures: dict[str, object] = {"root": str(root), "hogs": hogs}
    try:
        deadline = launched + timeout_s
        while not up.wait(0.1):
            if node.poll() is not None or time.monotonic() > deadline:
                reader.join(5.0)
                raise SystemExit(f"the node was not up (exit status {node.poll()}):\n{''.join(lines[-20:])}")
        t_up = up_at[0]
        figures["launch_to_up_s"] = t_up - launched
        sent: list[tuple[float, float]] = []  # (wall monotonic sent, rig time of the note)
        refusals: list[str] = []
        struck: tuple[float, float] | None = None  # (wall monotonic, contact rig time)
        events: list[str] = []  # (--verbose) seconds after up, what
        next_send = t_up
        while time.monotonic() - t_up < timeout_s:
            now = time.monotonic()
            if now >= next_send:
                rig = time.time() - epoch
                note = LiveNote(time=rig + lead_s, pitch=SNARE, velocity=100, channel=10)
                sock.sendto(encode(note), ("127.0.0.1", port))
                sent.append((now, note.time))
                next_send = now + period_s
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            arrived = time.monotonic()
            for message in decode(data).messages:
                if isinstance(message, PhysicsRejected) and message.address == LiveNote.ADDRESS:
                    refusals.append(message.reason)
                    events.append(f"{arrived - t_up:7.3f} refused: {message.reason}")
                elif (isinstance(message, Contact) and message.instrument == "snare" and sent
                      and message.time >= sent[0][1] - 0.05 and struck is None):
                    struck = (arrived, message.time)
                    events.append(f"{arrived - t_up:7.3f} snare contact at rig time {message.time:.3f}")
            if struck is not None:
                break
        for wall, rig in sent:
            events.append(f"{wall - t_up:7.3f} sent a note for rig time {rig:.3f}")
        if struck is None:
            figures["first_struck"] = f"none within {timeout_s:g} s"
        else:
            note_sent = min(sent, key=lambda s: abs(s[1] - struck[1]))  # the note it sounds
            figures["up_to_first_impact_s"] = struck[0] - t_up
            figures["first_struck_note_sent_after_up_s"] = note_sent[0] - t_up
        figures["notes_sent"] = len(sent)
        figures["events"] = "\n" + "\n".join(sorted(events))
        figures["notes_refused_before"] = len(refusals)
        if refusals:
            figures["first_refusal"] = refusals[0]
    finally:
        os.killpg(node.pid, signal.SIGINT)
        try:
            node.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(node.pid, signal.SIGKILL)
            node.wait()
        for burner in burners:
            burner.kill()
            burner.wait()
        sock.close()
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--root", type=Path, default=ROOT, help="the tree whose node runs (default: this one)")
    parser.add_argument("--hogs", type=whole_non_negative, default=0,
                        help="busy-looping processes started before the node (default 0)")
    parser.add_argument("--lead", type=seconds, default=0.5, help="each note this far ahead of its rig time, s "
                        "(default 0.5)")
    parser.add_argument("--period", type=seconds, default=0.25, help="a note every this many seconds (default 0.25)")
    parser.add_argument("--verbose", action="store_true", help="also what was sent and received, when")
    parser.add_argument("--timeout", type=seconds, default=180.0, help="give up after this long, s (default 180)")
    opts = parser.parse_args(argv)
    if not (opts.root / "services" / "physics" / "node.py").is_file():
        parser.error(f"--root {opts.root}: no services/physics/node.py there")
    figures = run(opts.root.resolve(), opts.hogs, opts.lead, opts.period, opts.timeout)
    events = figures.pop("events")
    if opts.verbose:
        print(f"seconds after up, what:{events}")
    for key, value in figures.items():
        print(f"{key}: {value:.2f}" if isinstance(value, float) else f"{key}: {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
