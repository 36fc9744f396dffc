"""``batteur rig``: start every service as a local process and stop them together.

Each service runs as ``python -m batteur ROLE`` with its own UDP port (base
port + 0 physics, + 1 interaction, + 2 sound, + 3 graphics), the same rig
epoch (so all local nodes share one rig clock), static peers for the others
(so the rig works where loopback has no multicast; ``--no-static-peers``
leaves finding each other to zeroconf alone) and, unless ``--no-discovery``,
zeroconf discovery on the given interfaces.
Output lines are prefixed with the role. Ctrl-C (SIGINT) or SIGTERM stops
every child with SIGINT, waits up to ``--stop-timeout`` seconds, then kills
what is left. If one service exits, the others are stopped too.

``--score FILE`` (a .mid or text score, or ``demo`` for the demo groove of
``batteur demo``) makes the drummer play it live: the physics node gets
``--score FILE --play-at SECONDS`` (it loads the score before it listens and
plans it once its clock runs, so no message can be lost at start-up; the
file's directory becomes its score library, so the Pd panel can load it again
by name). Rig time 0 is ``--start-delay`` seconds after launch; the score
starts at rig time ``--play-at``.
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from common.output_paths import check_output_dir

ROLES = ("physics", "interaction", "sound", "graphics")
PORT_OFFSET = {role: i for i, role in enumerate(ROLES)}


@dataclass
class ServicePlan:
    """The command line of one service in the rig."""

    role: str
    port: int
    args: list[str] = field(default_factory=list)

    def argv(self) -> list[str]:
        return [sys.executable, "-m", "batteur", self.role, "--port", str(self.port), *self.args]


def plan_rig(opts: argparse.Namespace, epoch: float) -> list[ServicePlan]:
    """The services to start, each with its port, peers, epoch and own arguments."""
    roles = [r.strip() for r in opts.services.split(",") if r.strip()]
    unknown = [r for r in roles if r not in ROLES]
    if unknown or not roles:
        named = ", ".join(unknown) or "(none)"
        raise ValueError(f"--services: unknown role(s) {named}; choose from {', '.join(ROLES)}")
    ports = {role: opts.base_port + PORT_OFFSET[role] for role in roles}
    plans: list[ServicePlan] = []
    for role in roles:
        args = ["--host", opts.host, "--epoch", repr(epoch), "--node-id", f"{role}-rig{opts.base_port}"]
        if not opts.no_static_peers:
            for other in roles:
                if other != role:
                    args += ["--peer", f"{other}={opts.host}:{ports[other]}"]
        if opts.no_discovery:
            args += ["--no-discovery"]
        else:
            for interface in filter(None, (i.strip() for i in opts.interfaces.split(","))):
                args += ["--interface", interface]
        if opts.log_level:
            args += ["--log-level", opts.log_level]
        args += role_args(role, opts)
        plans.append(ServicePlan(role, ports[role], args))
    return plans


def role_args(role: str, opts: argparse.Namespace) -> list[str]:
    """Arguments specific to one role: what to play, where to record, plus pass-through."""
    args: list[str] = []
    if role == "physics":
        if getattr(opts, "score", None):
            args += ["--score", str(Path(opts.score).resolve()), "--play-at", repr(opts.play_at)]
        if opts.strike_period:
            args += ["--scene", "strike", "--strike-period", repr(opts.strike_period),
                     "--strike-velocity", repr(opts.strike_velocity)]
    if role == "sound" and opts.record:
        args += ["--wav", str(Path(opts.record) / "performance.wav")]
    for item in getattr(opts, f"{role}_arg") or []:
        args += item.split()
    return args


class Rig:
    """Runs the planned services and stops them together."""

    def __init__(self, plans: list[ServicePlan], stop_timeout_s: float) -> None:
        self.plans = plans
        self.stop_timeout_s = stop_timeout_s
        self.procs: dict[str, asyncio.subprocess.Process] = {}
        self.stopping = asyncio.Event()
        self.exit_codes: dict[str, int] = {}

    async def _pump(self, role: str, stream: asyncio.StreamReader | None) -> None:
        if stream is None:
            return
        width = max(len(p.role) for p in self.plans)
        while line := await stream.readline():
            sys.stdout.write(f"[{role:<{width}}] {line.decode(errors='replace')}")
            sys.stdout.flush()

    async def _watch(self, role: str, proc: asyncio.subprocess.Process) -> None:
        code = await proc.wait()
        self.exit_codes[role] = code
        if not self.stopping.is_set():
            print(f"batteur rig: {role} exited with code {code}; stopping the rig", file=sys.stderr)
            self.stopping.set()

    async def run(self, duration_s: float | None) -> int:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self.stopping.set)
        tasks: list[asyncio.Task[None]] = []
        for plan in self.plans:
            proc = await asyncio.create_subprocess_exec(
                *plan.argv(), stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.STDOUT,
                start_new_session=True,  # Ctrl-C reaches the rig only; the rig stops the children in order
            )
            self.procs[plan.role] = proc
            print(f"batteur rig: started {plan.role} (pid {proc.pid}) on UDP port {plan.port}", flush=True)
            tasks.append(asyncio.create_task(self._pump(plan.role, proc.stdout)))
            tasks.append(asyncio.create_task(self._watch(plan.role, proc)))
        try:
            if duration_s is None:
                await self.stopping.wait()
            else:
                await asyncio.wait_for(self.stopping.wait(), timeout=duration_s)
        except TimeoutError:
            pass
        self.stopping.set()
        await self.stop()
        await asyncio.gather(*tasks, return_exceptions=True)
        failed = {role: code for role, code in self.exit_codes.items() if code not in (0, -signal.SIGINT)}
        return 1 if failed else 0

    async def stop(self) -> None:
        """SIGINT every child, wait up to the stop timeout, then SIGKILL the rest."""
        for proc in self.procs.values():
            if proc.returncode is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + self.stop_timeout_s
        for role, proc in self.procs.items():
            remaining = max(0.0, deadline - time.monotonic())
            try:
                await asyncio.wait_for(proc.wait(), timeout=remaining)
            except TimeoutError:
                print(f"batteur rig: {role} did not stop in {self.stop_timeout_s:g} s; killing it", file=sys.stderr)
                proc.kill()
                await proc.wait()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="batteur rig",
        description="Start the Batteur services as local processes (the embedded default rig). "
        "Ctrl-C stops them all.",
    )
    parser.add_argument("--services", default=",".join(ROLES), help="comma-separated roles to start (default: all)")
    parser.add_argument("--base-port", type=int, default=9101,
                        help="UDP port of physics; interaction, sound, graphics take the next ones (default 9101)")
    parser.add_argument("--host", default="127.0.0.1", help="address the services listen on (default 127.0.0.1)")
    parser.add_argument("--no-discovery", action="store_true", help="static peers only, no zeroconf")
    parser.add_argument("--no-static-peers", action="store_true",
                        help="find each other by zeroconf only (needs multicast on the interfaces)")
    parser.add_argument("--interfaces", default="", help="comma-separated interfaces for zeroconf (default: loopback)")
    parser.add_argument("--start-delay", type=float, default=3.0,
                        help="seconds between launch and rig time 0, so every service is up (default 3)")
    parser.add_argument("--duration", type=float, default=None,
                        help="stop after this many seconds of wall time (default: run until Ctrl-C)")
    parser.add_argument("--stop-timeout", type=float, default=4.0,
                        help="seconds to wait for services to stop before killing them (default 4)")
    parser.add_argument("--record", type=Path, default=None, help="directory for performance.wav (sound output)")
    parser.add_argument("--strike-period", type=float, default=0.0,
                        help="strike scene instead of a score: a strike every this many seconds of rig time")
    parser.add_argument("--strike-velocity", type=float, default=3.0, help="strike scene: tip speed, m/s (default 3)")
    parser.add_argument("--score", default=None, metavar="FILE",
                        help="the drummer plays this score live (.mid or text score; 'demo': the groove of "
                        "batteur demo)")
    parser.add_argument("--play-at", type=float, default=1.0,
                        help="rig time at which --score starts, seconds after rig time 0 (default 1)")
    parser.add_argument("--log-level", default="", help="log level for every service (default: theirs)")
    for role in ROLES:
        parser.add_argument(f"--{role}-arg", action="append", metavar="ARGS",
                            help=f"extra arguments for {role} (repeatable; split on spaces)")
    return parser


def check_score(opts: argparse.Namespace) -> None:
    """Raise ValueError for a --score the rig cannot play (missing, broken or empty file, strike scene, no
    physics)."""
    if opts.score is None:
        return
    if opts.strike_period:
        raise ValueError("--score and --strike-period exclude each other (the drummer or the strike scene)")
    roles = [r.strip() for r in opts.services.split(",")]
    if "physics" not in roles:
        raise ValueError("--score needs the physics service (--services)")
    if not Path(opts.score).is_file():
        raise ValueError(f"--score {opts.score}: no such file")
    if opts.play_at < 0:
        raise ValueError("--play-at must be >= 0 (rig seconds)")
    from common.score.text import read_score

    if not read_score(opts.score).events:  # ScoreError (a ValueError) for a broken file, before any service starts
        raise ValueError(f"--score {opts.score}: no drum events to play")


def main(argv: Sequence[str] | None = None) -> int:
    opts = build_parser().parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="batteur-rig-") as tmp:
        if opts.score == "demo" and not Path("demo").exists():
            from batteur.demo import DEMO_GROOVE

            opts.score = str(Path(tmp) / "demo-groove.txt")
            Path(opts.score).write_text(DEMO_GROOVE, encoding="utf-8")
        epoch = time.time() + opts.start_delay
        try:
            check_score(opts)
            if opts.record:
                check_output_dir(Path(opts.record), "--record")
            plans = plan_rig(opts, epoch)
        except ValueError as exc:
            print(f"batteur rig: {exc}", file=sys.stderr)
            return 2
        if opts.record:
            Path(opts.record).mkdir(parents=True, exist_ok=True)
        if opts.score:
            print(f"batteur rig: the drummer plays {opts.score} from rig time {opts.play_at:g} s "
                  f"({opts.start_delay + opts.play_at:g} s after launch)", flush=True)
        return asyncio.run(Rig(plans, opts.stop_timeout).run(opts.duration))
