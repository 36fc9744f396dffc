"""The graphics node: the core on the service runtime, plus the view server (HTTP + WebSocket).

``batteur graphics`` runs it: it receives poses, impacts, health and graphics
controls over OSC like every node (``common.runtime``), steps the core at the
view rate and streams frames to every page connected to
``http://HOST:HTTP_PORT/``. ``batteur graphics build`` (re)builds the page
from ``services/graphics/web`` with npm (three.js from the npm registry).

Extra options: ``--http-port``, ``--kit-dir`` (where the editor may save kits
and poses), ``--preview FILE.npz`` (a pose sequence to show instead of the
live stream, e.g. the keyframe animation of a score), ``--synthetic`` (feed
the synthetic drummer as if physics were running: a demo without physics).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

from pydantic import Field

from common.config import NodeSettings
from common.runtime import Node, run_node
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.sequence import PoseSequence
from services.graphics.server import ViewServer

WEB_DIR = Path(__file__).parent / "web"


class GraphicsNodeSettings(NodeSettings):
    """Node settings plus the graphics service's own."""

    http_port: int = Field(default=8080, ge=0, le=65535, description="HTTP/WebSocket port of the view (0: any)")
    kit: str = Field(default="default", description="kit name or file to draw")
    kit_dir: str = Field(default="", description="directory the editor may save kits and poses into ('': no saving)")
    preview: str = Field(default="", description="pose sequence (.npz) to show instead of the live stream")
    synthetic: bool = Field(default=False, description="feed the synthetic drummer (demo without physics)")
    view_clock: Literal["auto", "rig"] = Field(
        default="auto", description="auto: follow the clock of the poses; rig: trust the rig clock")


def build_assets(web_dir: Path = WEB_DIR) -> int:
    """Install the page's npm packages (three.js) and build it into ``services/graphics/static``."""
    npm = shutil.which("npm")
    if npm is None:
        print("batteur graphics build: npm is not installed (Debian: apt-get install npm)", file=sys.stderr)
        return 2
    for command in ([npm, "ci", "--no-audit", "--no-fund"], [npm, "run", "build"]):
        result = subprocess.run(command, cwd=web_dir, check=False)
        if result.returncode != 0:
            return result.returncode
    return 0


def make_core(settings: NodeSettings, args: argparse.Namespace) -> GraphicsCore:
    s = settings if isinstance(settings, GraphicsNodeSettings) else GraphicsNodeSettings(**settings.model_dump())
    core = GraphicsCore(GraphicsSettings(rate_hz=s.rate_hz or 60.0, latency=s.latency_s, kit=s.kit, clock=s.view_clock))
    if s.preview:
        core.load_preview(PoseSequence.load(Path(s.preview)))
    return core


async def _feed_synthetic(node: Node, core: GraphicsCore) -> None:
    """Play the synthetic drummer into the core in real time, looping (stands in for physics)."""
    import asyncio

    from services.graphics.figure import synthetic_performance

    sequence, impacts = synthetic_performance(duration=8.0, rate_hz=60.0, kit=core.kit)
    poses = sequence.pose_messages(layout=1)
    core.handle(sequence.skeleton_message(layout=1), node.clock.now(), "synthetic")
    loop_start = node.clock.now()
    span = sequence.duration + 1.0 / 60.0
    sent_pose, sent_impact, lap = 0, 0, 0
    while True:
        now = node.clock.now()
        local = now - loop_start - lap * span
        if local >= span:
            lap, sent_pose, sent_impact = lap + 1, 0, 0
            continue
        offset = loop_start + lap * span
        while sent_pose < len(poses) and poses[sent_pose].time <= local:
            p = poses[sent_pose]
            core.handle(p.model_copy(update={"time": p.time + offset}), now, "synthetic")
            sent_pose += 1
        while sent_impact < len(impacts) and impacts[sent_impact].time <= local:
            imp = impacts[sent_impact]
            core.handle(imp.model_copy(update={"time": imp.time + offset, "seq": imp.seq + lap * 10_000}),
                        now, "synthetic")
            sent_impact += 1
        await asyncio.sleep(1 / 120)


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["build"]:
        return build_assets()
    holder: dict[str, Any] = {}

    def make(settings: NodeSettings, extra: argparse.Namespace) -> GraphicsCore:
        holder["settings"] = settings
        core = make_core(settings, extra)
        holder["core"] = core
        return core

    async def setup(node: Node) -> None:
        s: GraphicsNodeSettings = holder["settings"]
        core: GraphicsCore = holder["core"]
        server = ViewServer(core, kit_dir=Path(s.kit_dir) if s.kit_dir else None, clock=node.clock.now)
        await server.start(s.host, s.http_port)
        print(f"graphics view: http://{s.host}:{server.port}/", file=sys.stderr, flush=True)
        node.spawn(server.serve_forever(), "view server")
        if s.synthetic:
            node.spawn(_feed_synthetic(node, core), "synthetic drummer")

    return run_node(
        "graphics",
        make,
        args,
        description="Batteur graphics: live 3D view in the browser (HTTP + WebSocket). "
        "`batteur graphics build` builds the page with npm.",
        settings_cls=GraphicsNodeSettings,
        setup=setup,
    )


if __name__ == "__main__":
    raise SystemExit(main())
