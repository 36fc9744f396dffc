"""The graphics node: the core on the service runtime, plus the view server (HTTP + WebSocket).

``batteur graphics`` runs it: it receives poses, impacts, health and graphics
controls over OSC like every node (``common.runtime``), steps the core at the
view rate and streams frames to every page connected to
``http://HOST:HTTP_PORT/``. ``batteur graphics build`` (re)builds the page
from ``services/graphics/web`` with npm (three.js from the npm registry).

Extra options: ``--http-port``, ``--kit-dir`` (where the editor may save kits
and poses), ``--preview FILE.npz`` (a pose sequence to show instead of the
live stream), ``--preview-score SCORE`` with ``--preview-planner
keyframe|gestures`` (plan a MIDI or text score with the view's kit and show
its kinematic preview, looping; the keyframe strokes follow the editor's
UP/DOWN poses in ``--kit-dir/poses.yaml`` and are re-planned when that file
or the kit changes), ``--preview-rate R`` (play either preview at R times
the planned motion's speed, 0.25 to 2; the page or ``/batteur/graphics/preview_rate`` changes it while it
plays), ``--preview-bars FIRST[-LAST]`` (loop only those bars of the score; the page or
``/batteur/graphics/preview_bars`` changes them while it plays),
``--synthetic`` (feed the synthetic drummer as if physics were running: a demo
without physics).
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError

from common.config import NodeSettings, is_loopback
from common.exit_status import InputError, report_error
from common.kit import Kit, load_kit
from common.kit_help import kit_help
from common.messages import Impact
from common.messages.graphics import GraphicsMode
from common.output_paths import check_output_dir
from common.runtime import Node, run_node
from common.score.midi_notes import DrumMapError
from common.score.midi_options import DRUM_CHANNELS_HELP, DRUM_MAP_HELP, HIHAT_CC4_HELP, midi_setting_kwargs
from services.graphics.core import GraphicsCore, GraphicsSettings
from services.graphics.preview import MAX_RATE, MIN_RATE, ScorePreview, parse_bars, score_preview
from services.graphics.sequence import PoseSequence
from services.graphics.server import ViewServer

WEB_DIR = Path(__file__).parent / "web"
POSES_FILE = "poses.yaml"
"""The pose editor's key poses in ``--kit-dir`` (read by the keyframe preview)."""
WATCH_PERIOD_S = 1.0
"""How often the node checks whether the poses file or the kit changed (seconds)."""

PROGRESS_PERIOD_S = 2.0
"""How often posing a score preview logs its progress (seconds)."""

log = logging.getLogger("batteur.graphics")


class GraphicsNodeSettings(NodeSettings):
    """Node settings plus the graphics service's own."""

    http_port: int = Field(default=8080, ge=0, le=65535, description="HTTP/WebSocket port of the view (0: any)")
    kit: str = Field(default="default", description=kit_help(what="kit name or file to draw"))
    kit_dir: str = Field(default="", description="directory the editor may save kits and poses into ('': no saving)")
    editor: Literal["local", "all", "off"] = Field(
        default="local", description="which pages may use the kit and pose editor (it drives the drummer's posture "
        "and saves files): local: pages opened on this machine, other machines get the view only; all: every page "
        "that reaches --http-port; off: none")
    preview: str = Field(default="", description="pose sequence (.npz) to show instead of the live stream")
    preview_score: str = Field(
        default="", description="score (MIDI or text) to plan with the kit and show as a looping kinematic preview")
    preview_planner: Literal["keyframe", "gestures"] = Field(
        default="keyframe", description="planner of --preview-score: keyframe (the 2001 paper's strokes, shaped "
        "by --kit-dir/poses.yaml if present) or gestures (the gesture planner)")
    preview_rate: float = Field(
        default=1.0, ge=MIN_RATE, le=MAX_RATE, description="playback rate of the preview (--preview-score or "
        "--preview) over its planned motion: 0.5 plays it at half speed (0.25 to 2; the page's rate select and "
        "/batteur/graphics/preview_rate change it while it plays)")
    preview_bars: str = Field(
        default="", description="loop only these bars of --preview-score, from 1 as the status counts them: "
        "3 or 3-4 ('': the whole score, with a pause between laps; the page and /batteur/graphics/preview_bars "
        "change it while it plays)")
    drum_channels: str = Field(default="", description=f"--preview-score's MIDI file: {DRUM_CHANNELS_HELP}")
    drum_map: str = Field(default="", description=f"--preview-score's MIDI file: {DRUM_MAP_HELP}")
    hihat_cc4: bool = Field(default=False, description=f"--preview-score's MIDI file: {HIHAT_CC4_HELP}")
    synthetic: bool = Field(default=False, description="feed the synthetic drummer (demo without physics)")
    view_clock: Literal["auto", "rig"] = Field(
        default="auto", description="auto: follow the clock of the poses; rig: trust the rig clock")


BUILD_HELP = ("Install the viewer page's npm packages (npm ci: three.js and the build tools) and build the page "
              "into services/graphics/static (npm run build). Needs npm; the built page is committed, so this is "
              "only needed after changing services/graphics/web.")


def build_assets(web_dir: Path = WEB_DIR) -> int:
    """Install the page's npm packages (three.js) and build it into ``services/graphics/static``."""
    npm = shutil.which("npm")
    if npm is None:
        return report_error("batteur graphics build", "npm is not installed (Debian: apt-get install npm)")
    for command in ([npm, "ci", "--no-audit", "--no-fund"], [npm, "run", "build"]):
        result = subprocess.run(command, cwd=web_dir, check=False)
        if result.returncode != 0:
            return result.returncode
    return 0


def poses_path(settings: GraphicsNodeSettings) -> Path | None:
    """``--kit-dir/poses.yaml`` (None without a kit directory); it need not exist."""
    return Path(settings.kit_dir) / POSES_FILE if settings.kit_dir else None


class PlanCancelled(Exception):
    """Planning the preview was given up (the node is stopping)."""


def plan_score_preview(settings: GraphicsNodeSettings, kit: Kit, clock: Callable[[], float] = time.monotonic,
                       cancel: threading.Event | None = None) -> ScorePreview:
    """Plan ``--preview-score`` with ``kit``; ``ValueError`` (a ScoreError) naming the problem.

    ``cancel`` set (from another thread): :class:`PlanCancelled` at the next pose.

    A long score takes seconds (tens on a busy machine) to pose: once the score is read and planned (a bad
    one is refused before any line is logged) the log says so and, every :data:`PROGRESS_PERIOD_S` seconds of
    ``clock``, how far it got.
    """
    name = settings.preview_score
    last = clock()

    def progress(done: int, total: int) -> None:
        nonlocal last
        if cancel is not None and cancel.is_set():
            raise PlanCancelled
        now = clock()
        if done == 1:
            log.info("preview: posing %s (%s planner): %d poses", name, settings.preview_planner, total)
        elif now - last >= PROGRESS_PERIOD_S:
            last = now
            log.info("preview: posing %s: %d%% (%d/%d poses)", name, 100 * done // total, done, total)

    midi = midi_setting_kwargs(settings.drum_channels, settings.drum_map, settings.hihat_cc4)
    return score_preview(name, kit, settings.preview_planner, poses=poses_path(settings),
                         rate_hz=settings.rate_hz or 60.0, on_progress=progress, midi=midi)


_FLAGS = {"rate_hz": "--rate-hz", "latency": "--latency-s", "kit": "--kit", "clock": "--view-clock"}
"""The command-line flag of each graphics core setting the node sets."""


def _bound(name: str, kind: str) -> float | None:
    """The ``ge``/``le`` bound of a GraphicsSettings field, if it has one."""
    field = GraphicsSettings.model_fields.get(name)
    return next((getattr(m, kind) for m in (field.metadata if field else []) if getattr(m, kind, None) is not None),
                None)


def _settings_error(exc: ValidationError) -> str:
    """``--rate-hz 1000: ... (allowed 1 to 240)`` from the first error of a GraphicsSettings validation."""
    error = exc.errors()[0]
    name = str(error["loc"][0]) if error.get("loc") else ""
    low, high = _bound(name, "ge"), _bound(name, "le")
    allowed = f" (allowed {low:g} to {high:g})" if low is not None and high is not None else ""
    return f"{_FLAGS.get(name, name)} {error.get('input')}: {error['msg'].lower()}{allowed}"


def make_core(settings: NodeSettings, args: argparse.Namespace) -> GraphicsCore:
    """The graphics core, with the preview loaded; ``ValueError`` (exit 2) for a bad setting, ``InputError``
    (exit 1) for a kit, pose sequence, score or poses file it cannot use or a --kit-dir it cannot write in."""
    s = settings if isinstance(settings, GraphicsNodeSettings) else GraphicsNodeSettings(**settings.model_dump())
    if s.preview and s.preview_score:
        raise ValueError("give --preview FILE.npz or --preview-score SCORE, not both")
    if s.preview_bars:
        parse_bars(s.preview_bars)  # its syntax, before a long plan
        if not s.preview_score:
            raise ValueError("--preview-bars loops bars of a score: give --preview-score SCORE with it")
    try:  # before a long plan: bad channels ValueError (exit 2); a map it cannot use: 1, as a kit
        midi_setting_kwargs(s.drum_channels, s.drum_map, s.hihat_cc4)
    except DrumMapError as exc:
        raise InputError(str(exc)) from None
    if s.kit_dir:
        try:
            check_output_dir(Path(s.kit_dir), "--kit-dir")
        except ValueError as exc:  # an output it cannot write: not the command line's fault
            raise InputError(str(exc)) from None
    try:
        view = GraphicsSettings(rate_hz=s.rate_hz or 60.0, latency=s.latency_s, kit=s.kit, clock=s.view_clock)
    except ValidationError as exc:  # one line naming the flag, not pydantic's report
        raise ValueError(_settings_error(exc)) from None
    try:
        kit = load_kit(s.kit)
    except (FileNotFoundError, ValueError) as exc:  # missing, or not a kit
        raise InputError(f"--kit: {exc}") from None
    core = GraphicsCore(view, kit=kit)
    if s.preview:
        try:
            sequence = PoseSequence.load(Path(s.preview))
        except (ValueError, OSError, EOFError) as exc:  # missing, not an .npz, or an .npz of something else
            why = str(exc) if s.preview in str(exc) else f"{s.preview}: not a pose sequence file ({exc})"
            raise InputError(f"--preview: {why}") from None
        core.load_preview(sequence, rate=s.preview_rate)
    if s.preview_score:
        try:  # the planner and pose rate are settings, checked already: what is refused here is a file
            preview = plan_score_preview(s, core.kit)
        except ValueError as exc:  # the score (missing, unreadable, nothing the kit plays) or the poses file
            raise InputError(str(exc)) from None
        for warning in preview.score.warnings:  # the reader's, as `batteur render` prints them; not at each re-plan
            log.warning("preview: %s", warning)
        try:
            core.load_preview(preview.sequence, preview.impacts, score=preview.score, rate=s.preview_rate,
                              bars=parse_bars(s.preview_bars) if s.preview_bars else None)
        except ValueError as exc:  # bars the score does not have: named by the option
            raise ValueError(f"--preview-bars {s.preview_bars}: {exc}") from None
        log.info("preview of %s", preview.summary())
    return core


def own_clock_for_preview(settings: NodeSettings) -> None:
    """A preview (``--preview``, ``--preview-score``) or the synthetic drummer (``--synthetic``) needs no physics:
    the node is its own clock master unless the clock master was set (flag, environment, config file); else it
    waited 3 s for physics at start and warned that rig time would jump."""
    without_physics = isinstance(settings, GraphicsNodeSettings) and bool(
        settings.preview or settings.preview_score or settings.synthetic)
    if without_physics and "clock_master" not in settings.model_fields_set:
        settings.clock_master = "self"


def _preview_inputs(settings: GraphicsNodeSettings, core: GraphicsCore) -> tuple[float | None, Kit]:
    """What the score preview depends on besides the score: the poses file's mtime (None: absent) and the kit."""
    path = poses_path(settings) if settings.preview_planner == "keyframe" else None
    try:
        mtime = path.stat().st_mtime if path is not None else None
    except OSError:
        mtime = None
    return mtime, core.kit


async def _watch_preview(node: Node, core: GraphicsCore, settings: GraphicsNodeSettings,
                         period: float = WATCH_PERIOD_S) -> None:
    """Re-plan the score preview when the editor saves a pose (``poses.yaml`` changes) or a kit.

    The new preview starts from its beginning; the view keeps its mode (live or preview). A file that
    cannot be planned (e.g. a hand-edited poses file that is not valid) is logged and the old preview kept.
    """
    seen = _preview_inputs(settings, core)
    while True:
        await asyncio.sleep(period)
        now_inputs = _preview_inputs(settings, core)
        if now_inputs[0] == seen[0] and now_inputs[1] is seen[1]:
            continue
        seen = now_inputs
        cancel = threading.Event()
        try:
            preview = await asyncio.to_thread(plan_score_preview, settings, now_inputs[1], cancel=cancel)
        except asyncio.CancelledError:  # the node stops: its exit must not wait for a long plan to finish
            cancel.set()
            raise
        except ValueError as exc:
            core.counters["preview_errors"] = core.counters.get("preview_errors", 0) + 1
            log.error("preview not re-planned, keeping the previous one: %s", exc)
            continue
        mode = core.mode
        # at the rate and on the bars chosen last (the page, OSC; not --preview-rate again), with the score's bar
        # and beat
        try:
            core.load_preview(preview.sequence, preview.impacts, now=node.clock.now(), score=preview.score,
                              bars=core.preview_bars)
        except ValueError as exc:  # the edit moved nothing in time; kept safe all the same
            log.error("preview not re-planned, keeping the previous one: %s", exc)
            continue
        if mode == "live":
            core.apply_control(GraphicsMode(mode="live"))
        core.counters["preview_replans"] = core.counters.get("preview_replans", 0) + 1
        log.info("preview re-planned: %s", preview.summary())


def synthetic_groove(kit: Kit, source: str = "") -> tuple[PoseSequence, list[Impact]]:
    """The synthetic drummer's 8 s groove on ``kit`` (from ``--kit source``); ``ValueError`` if it lacks what
    the groove plays (exit 2)."""
    from services.graphics.figure import synthetic_performance

    try:
        return synthetic_performance(duration=8.0, rate_hz=60.0, kit=kit)
    except KeyError as exc:  # the groove plays the default kit's snare, hi-hat, crash, kick...
        missing = getattr(exc.args[0], "value", exc.args[0]) if exc.args else "an instrument"
        raise ValueError(f"--synthetic: kit {source or kit.name!r} has no {missing}, which the synthetic groove plays "
                         "(use a kit that has it, e.g. --kit default)") from None


async def _feed_synthetic(node: Node, core: GraphicsCore, sequence: PoseSequence, impacts: list[Impact]) -> None:
    """Play the synthetic drummer into the core in real time, looping (stands in for physics)."""
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
        build = argparse.ArgumentParser(prog="batteur graphics build", description=BUILD_HELP)
        build.parse_args(args[1:])  # --help prints and exits; anything else is a usage error
        return build_assets()
    holder: dict[str, Any] = {}

    def make(settings: NodeSettings, extra: argparse.Namespace) -> GraphicsCore:
        own_clock_for_preview(settings)
        holder["settings"] = settings
        core = make_core(settings, extra)
        if isinstance(settings, GraphicsNodeSettings) and settings.synthetic:
            # before listening: a kit without the groove's instruments is a start error, not a crash later
            holder["synthetic"] = synthetic_groove(core.kit, settings.kit)
        holder["core"] = core
        return core

    async def setup(node: Node) -> None:
        s: GraphicsNodeSettings = holder["settings"]
        core: GraphicsCore = holder["core"]
        server = ViewServer(core, kit_dir=Path(s.kit_dir) if s.kit_dir else None, clock=node.clock.now,
                            editor=s.editor)
        try:
            await server.start(s.host, s.http_port)
        except OSError as exc:  # asyncio's text names neither the option nor what to do
            raise OSError(exc.errno, f"--http-port {s.http_port}: {os.strerror(exc.errno) if exc.errno else exc} "
                          "(another program listens there? pick another port, or 0 for any)") from None
        host = f"[{s.host}]" if ":" in s.host else s.host  # an IPv6 address needs brackets in a URL
        print(f"graphics view: http://{host}:{server.port}/", file=sys.stderr, flush=True)
        if not is_loopback(s.host):  # served to the network: who gets the editor
            if s.editor == "all":
                log.warning("the view's editor is open to every machine that reaches port %d (--editor all): it "
                            "drives the drummer's posture%s; --editor local keeps it to this machine",
                            server.port, " and saves into --kit-dir" if s.kit_dir else "")
            else:
                log.info("other machines get the view only; the editor is %s (--editor %s)",
                         "for pages opened on this machine" if s.editor == "local" else "off", s.editor)
        node.spawn(server.serve_forever(), "view server")
        if s.synthetic:
            node.spawn(_feed_synthetic(node, core, *holder["synthetic"]), "synthetic drummer")
        if s.preview_score:
            node.spawn(_watch_preview(node, core, s), "preview re-planner")

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
