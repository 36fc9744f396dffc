"""The physics node: :class:`~services.physics.core.PhysicsCore` live over UDP, locked to the rig clock.

    batteur physics                                   # the drummer at the default kit, 1 kHz
    batteur physics --scene strike --strike-period 0.5 --strike-velocity 3
    batteur physics --kit double_pedal --left-handed --control joint_pd --grip french
    batteur physics --score groove.mid --play-at 1.0                 # play a score from rig time 1 s
    batteur physics --score-dir ~/scores                              # the score library for /batteur/score/load

Contacts go to ``interaction`` every step while in contact; poses to
``graphics`` at ``--pose-rate-hz``, and while a score plays its bar and beat
(``/batteur/graphics/score_position``) ten times a second. Targets, control mode, gains, grip and
reset arrive as /batteur/physics/... messages (docs/physics.md). Scores arrive as
/batteur/score/... messages (load by name from the ``--score-dir`` library,
transport, live notes, style, tempo: the score player,
services/physics/score_player.py); ``--score FILE`` loads one at start and
``--play-at SECONDS`` plays it from that rig time (the rig's ``--score`` uses
these), without any message.

The node runs :class:`LivePhysicsCore`: score plans (``play``, style and tempo
re-plans, live notes) are computed in a worker process and spliced in at the
first step after they are ready, so the 1 kHz loop never waits for the planner;
messages take effect in arrival order, but a reset drops the plan in flight (its process is
terminated, a spare one plans the next) and acts at once (services/physics/score_player.py,
services/physics/plan_worker.py, docs/physics.md "Background plans"). The first planning process starts before the
scene is built and the node listens (says it is up, answers Hellos) only once it has loaded the planner. A refused
message is answered to its sender with ``/batteur/physics/rejected`` (docs/physics.md "Replies").
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import Field, field_validator, model_validator
from pydantic_settings import NoDecode

from common.config import NodeSettings
from common.core import Outgoing
from common.exit_status import InputError
from common.gesture.bvh import BvhError
from common.input_file import file_problem
from common.kit import EventType, load_kit
from common.messages import Hello, OscMessage
from common.messages.graphics import ScorePosition
from common.messages.physics import ControlModeName, GripName
from common.runtime import Node, run_node
from common.score.events import SCORE_FILE
from common.score.hands import Sticking
from common.score.limbs import LimbLengths
from common.score.midi_notes import DrumMapError
from common.score.midi_options import DRUM_CHANNELS_HELP, DRUM_MAP_HELP, HIHAT_CC4_HELP, midi_setting_kwargs
from services.physics.anthropometry import SkeletonUnits
from services.physics.body_table import body_json, body_summary, body_text
from services.physics.core import PhysicsCore, PhysicsSettings
from services.physics.mocap import ClipError
from services.physics.plan_worker import PlanWorker, PlanWorkers
from services.physics.precompile import COMPILING, kernels_cached, warm_up
from services.physics.score_position import SCORE_POSITION_PERIOD_S, score_position
from services.physics.targets import TargetError

log = logging.getLogger("batteur.physics")


HEIGHT_RANGE_M = (1.2, 2.2)
"""Heights de Leva's table is scaled to, metres (``PhysicsSettings.height_m``'s bounds)."""

RENDER_SPELLINGS = {"height_m": "--height", "mass_kg": "--mass", "control_rate_hz": "--control-rate",
                    "strike_event": "--event"}
"""Setting -> ``batteur render``'s flag for it, which the node takes too (its help names only its own flag, saying
this one): a flag copied from a render's command line was refused (argparse took ``--height`` only as an
abbreviation of ``--height-m``, and ``--event`` not at all)."""


class PhysicsNodeSettings(NodeSettings):
    """Node settings plus the physics service's own (flags, BATTEUR_* variables, settings file keys)."""

    scene: Literal["strike", "drummer"] = Field(default="drummer", description="strike: one stick over one "
                                                "instrument (integration); drummer: the 57-DOF percussionist")
    kit: str = Field(default="default", min_length=1, description="kit name or kit file (YAML or JSON)")
    left_handed: bool = Field(default=False, description="mirror the kit for a left-handed drummer")
    control: ControlModeName = Field(default="cartesian",
                                     description=f"controller at start: {', '.join(get_args(ControlModeName))} "
                                     "(joint: joint_pd, as batteur render; docs/physics.md; /batteur/physics/control "
                                     "switches it live)")
    grip: GripName = Field(default="german", description=f"grip of both hands at start: "
                           f"{', '.join(get_args(GripName))}; scores are planned with it where the gesture "
                           "database has it (french, german), else with german, as batteur render "
                           "(/batteur/physics/grip changes the hands live, /batteur/score/style hands and plan)")
    floating_base: bool = Field(default=False, description=PhysicsSettings.model_fields["floating_base"].description)
    height_m: float = Field(default=1.75, ge=HEIGHT_RANGE_M[0], le=HEIGHT_RANGE_M[1],
                            description="drummer's height, metres (--height too, as batteur render)")
    mass_kg: float = Field(default=73.0, ge=35, le=150,
                           description="drummer's mass, kilograms (--mass too, as batteur render)")
    pose_rate_hz: float = Field(default=60.0, ge=0, le=240, description="pose publishing rate, Hz (0: off)")
    control_rate_hz: float = Field(default=PhysicsSettings.model_fields["control_rate_hz"].default, ge=50,
                                   le=10000, description="drummer: full control updates (IK, inverse dynamics) "
                                   "per second, Hz, at most the step rate (--rate-hz), a whole number of steps apart "
                                   "(300 at 1 kHz runs at 333.3, said at start); torques are corrected at every "
                                   "physics step between (--control-rate too, as batteur render)")
    strike_event: EventType = Field(default=EventType.SNARE, description="strike scene: the event whose hit point "
                                    f"the stick strikes: {', '.join(e.value for e in EventType)} (--event too, "
                                    "as batteur render)")
    strike_period: float = Field(default=0.0, ge=0, le=60,
                                 description="strike scene: strike every this many seconds (0: only on request)")
    strike_velocity: float = Field(default=3.0, gt=0, le=30, description="strike scene: tip speed, m/s")
    score: str = Field(default="", description="drummer: score file (MIDI or text) loaded at start; its "
                       "directory joins the score library")
    play_at: float | None = Field(default=None, ge=0, le=1e6, description="rig time at which --score starts "
                                  "playing (its beginning), seconds (unset: load only)")
    sticking: Literal["none", "single", "double", "paradiddle"] = Field(
        default="none", description="drummer: sticking of the rolls in the scores it plans: none (the hand "
        "assignment's), single, double or paradiddle, as batteur render --sticking (a /batteur/score/style changes "
        "it)")
    drum_channels: str = Field(default="", description=f"--score and the library's MIDI files: {DRUM_CHANNELS_HELP}")
    drum_map: str = Field(default="", description=f"--score and the library's MIDI files, and live notes "
                          f"(/batteur/score/note): {DRUM_MAP_HELP}")
    hihat_cc4: bool = Field(default=False, description=f"--score and the library's MIDI files: {HIHAT_CC4_HELP}")
    score_dir: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="score library directory: /batteur/score/load names are looked up here")
    limits_from: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description=PhysicsSettings.model_fields["limits_from"].description)
    asymmetric_limits: bool = Field(
        default=False, description="with --limits-from: keep each side's own joint limits as the clips give them, "
        "for a performer with a real asymmetry (one side that truly reaches further); by default each left/right "
        "pair is made mirror-symmetric, their common range, as the default limits, since the drummer's posture "
        "drifts toward a wider bound under fast strokes (docs/physics.md, \"Symmetric limits\"); --show-body says "
        "which was used")
    skeleton_bvh: str | None = Field(default=None, description=PhysicsSettings.model_fields["skeleton_bvh"].description)
    skeleton_units: SkeletonUnits = Field(
        default="auto", description=PhysicsSettings.model_fields["skeleton_units"].description)

    @field_validator("control", mode="before")
    @classmethod
    def _render_control_name(cls, value: Any) -> Any:
        """``batteur render --control joint`` names joint_pd: a value copied from a render's command line works."""
        return "joint_pd" if value == "joint" else value

    @field_validator("height_m", mode="before")
    @classmethod
    def _height_in_metres(cls, value: Any) -> Any:
        """A height out of range says its unit, and a height in centimetres what it meant (the bounds' own message
        said "must be at most 2.2 (got '182')")."""
        try:
            height = float(value)
        except (TypeError, ValueError):
            return value  # the field's own message
        low, high = HEIGHT_RANGE_M
        if not low <= height <= high:
            hint = f"; did you mean {height / 100:g} m?" if low * 100 <= height <= high * 100 else ""
            raise ValueError(f"must be {low:g} to {high:g} metres{hint}")
        return value

    @model_validator(mode="after")
    def _control_rate_within_steps(self) -> PhysicsNodeSettings:
        """Control updates are whole numbers of physics steps: a rate above the step rate ran at the step rate while
        the settings said otherwise. Refused only when given: the default (1000 Hz) above a step rate asked for
        (``--rate-hz 500``) is the step rate, as ``--show-settings`` says (until 7 Dec that node did not start)."""
        steps_hz = self.rate_hz or PhysicsSettings.model_fields["rate_hz"].default
        if self.control_rate_hz > steps_hz * (1 + 1e-9) and "control_rate_hz" not in self.model_fields_set:
            self.__dict__["control_rate_hz"] = float(steps_hz)  # not setattr: no validation again, not "given"
        elif self.control_rate_hz > steps_hz * (1 + 1e-9):
            raise ValueError(f"--control-rate-hz {self.control_rate_hz:g} is above the physics step rate, "
                             f"{steps_hz:g} Hz (--rate-hz): control updates come every whole number of steps")
        return self

    @field_validator("score_dir", "limits_from", mode="before")
    @classmethod
    def _comma_lists(cls, value: Any) -> Any:
        """Environment variables and config files may give several entries, comma-separated."""
        if isinstance(value, str):
            return [v.strip() for v in value.split(",") if v.strip()]
        return value


class LivePhysicsCore(PhysicsCore):
    """:class:`PhysicsCore` as the live node runs it: background score plans.

    Every message but ``Hello`` goes through the score player's FIFO (:meth:`ScorePlayer.submit`): with no plan in
    flight it acts at once as in :class:`PhysicsCore`; a message that plans starts its plan in the worker (a
    process by default; ``planner="thread"``: a thread, which shares the interpreter lock with the loop);
    while one is in flight, the messages after it wait and act, in order, once it is spliced (a reset drops it,
    stops computing it and acts at once). Refusals found while a plan is applied are answered from :meth:`step`.
    Each step first splices a plan that is ready (:meth:`ScorePlayer.pump`). ``close`` stops the worker without
    waiting for it. Offline (``PhysicsCore``) nothing of this runs: plans are computed in the handler, renders are
    deterministic.
    """

    def __init__(self, settings: PhysicsSettings | None = None, *, planner: PlanWorker = "process",
                 **kwargs: Any) -> None:
        scene = kwargs.get("scene", (settings or PhysicsSettings()).scene)
        # the strike scene plays no scores: no worker; the drummer's first one starts (and loads) while the scene
        # is built, not after: :meth:`wait_loaded`
        workers = PlanWorkers(planner) if scene == "drummer" else None
        built = False
        try:
            super().__init__(settings, **kwargs)
            built = True
            if workers is not None:
                self.score_player.start_background(self.handle_counted, workers)
        except BaseException:  # a bad setting, a node stopped while starting (StoppedWhileStarting): processes stop
            if workers is not None:
                workers.close()
            if built:
                self.close()
            raise
        self._position_sent = -math.inf
        """Rig time the score's position was last looked at (and sent, if one plays), seconds."""
        self._counts_said: tuple[float, int, int] | None = None
        """(rig time s, limit violations, torque-saturated DOF-steps) when the controller's counters were last
        logged (:meth:`_say_counts`)."""

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if isinstance(message, Hello) or not self.score_player.background:  # Hello changes nothing: at once
            return super().handle(message, now, source)
        try:
            out = self.score_player.submit(message, now, source)
        except (TargetError, ValueError) as exc:
            self.reject(message, source, exc, now)
            out = []
        return out + self._take_replies()  # this message's refusal, and any of those that waited behind a plan

    def step(self, now: float) -> list[Outgoing]:
        self.score_player.pump(now)
        out = super().step(now)
        if now - self._position_sent >= SCORE_POSITION_PERIOD_S:  # looked at ten times a second, not every step
            self._position_sent = now
            position = self._score_position(now)
            if position is not None:
                out.append(Outgoing(position, "graphics"))
            self._say_counts(now)
            flush = getattr(self.scene, "flush_switches", None)  # a stream of live switches: its latest said
            if flush is not None:
                flush(now)
        return out

    def _say_counts(self, now: float) -> None:
        """Log the controller's counters (not in Health) every ``COUNTS_LOG_PERIOD_S`` of rig time ``now`` (s) in
        which they grew: joint limits left and torques at their limit (docs/physics.md, "Counters")."""
        controller = getattr(self.scene, "controller", None)
        if controller is None:
            return
        counts = (controller.limit_violations, controller.torque_saturated)
        if self._counts_said is None:
            self._counts_said = (now, *counts)
            return
        since, violations, saturated = self._counts_said
        if now - since < COUNTS_LOG_PERIOD_S:
            return
        self._counts_said = (now, *counts)
        if counts != (violations, saturated):
            log.info("physics controller over the last %.0f s: %d limit violations (joint-updates outside their "
                     "ellipsoid), %d torque-saturated DOF-steps (%d and %d since the start)", now - since,
                     counts[0] - violations, counts[1] - saturated, *counts)

    def _score_position(self, now: float) -> ScorePosition | None:
        """Where the playing score is at rig time ``now`` (s); None while no score plays (or past its plan, or
        past a stop or pause)."""
        player = self.score_player
        clock = player.clock(now)
        score = player.playing_score  # not the loaded one: a score loaded while another plays is for the next play
        if score is None or clock is None:
            return None
        return score_position(score, clock, now)

    def wait_loaded(self, timeout_s: float | None = None) -> bool:
        """Block until the planning worker has loaded the planner (True; or a strike scene: none), False after
        ``timeout_s`` seconds."""
        return self.score_player.wait_loaded(timeout_s)

    def close(self) -> None:
        self.score_player.close()
        super().close()


def make_core(settings: NodeSettings, extra: argparse.Namespace) -> PhysicsCore:
    """Build the core (live mode); ValueError (printed, exit 2) for a bad setting, InputError (exit 1) for a kit,
    score, clip or BVH file it cannot use."""
    if not isinstance(settings, PhysicsNodeSettings):
        settings = PhysicsNodeSettings.model_validate(settings.model_dump())
    if settings.play_at is not None and not settings.score:
        raise ValueError("--play-at needs --score")
    if settings.score and settings.scene != "drummer":
        raise ValueError("--score needs the drummer scene")
    try:  # bad channels: ValueError (exit 2); a map it cannot use: 1, as a kit
        midi = midi_setting_kwargs(settings.drum_channels, settings.drum_map, settings.hihat_cc4)
    except DrumMapError as exc:
        raise InputError(str(exc)) from None
    problem = file_problem(Path(settings.score).expanduser(), SCORE_FILE) if settings.score else None
    if problem is not None:  # a folder, a device, a pipe: said, never opened (a pipe would hold the node for ever)
        raise InputError(f"score {settings.score}: {problem}")
    if settings.skeleton_bvh:  # a skeleton without a joint found by name was de Leva's body, silently
        from services.physics.bvh_motion import read_skeleton, stature_warning, usable_segment_lengths

        try:
            usable_segment_lengths(settings.skeleton_bvh, settings.skeleton_units)
            reading = read_skeleton(settings.skeleton_bvh, settings.skeleton_units)
        except (OSError, ValueError) as exc:  # batteur render's --skeleton-bvh message (the node's name no option)
            raise InputError(str(exc)) from None
        # the unit the file was read in and the performer it implies, said once (as batteur render's warning): a
        # skeleton read in the wrong unit builds a giant or a dwarf, and the node said nothing of it
        stature = reading.stature_m
        tall = "no performer's height (no limb found)" if stature is None else f"a {stature:g} m performer's"
        log.info("skeleton %s read in %s; its lengths are %s (the hands, feet and head and the body's place over "
                 "the throne are the %g m drummer's of --height-m)", settings.skeleton_bvh, reading.unit_words,
                 tall, settings.height_m)
        if (outside := stature_warning(reading)) is not None:  # a unit given: built, and said
            # the setting, not an option: BATTEUR_SKELETON_UNITS or a config file may have given it
            log.warning("skeleton units %s: %s", settings.skeleton_units, outside)
    elif settings.skeleton_units != "auto":
        log.warning("--skeleton-units has no effect without --skeleton-bvh")
    try:  # a kit file it cannot use (missing or not a kit): 1, found before the core's slow start; loaded once,
        # so its warnings are logged once and name this drummer's reach (a skeleton's, as the planner's)
        kit = load_kit(settings.kit, height_m=settings.height_m, lengths=_skeleton_limbs(settings))
    except (FileNotFoundError, ValueError) as exc:
        raise InputError(str(exc)) from None
    try:
        core_settings = PhysicsSettings(
            scene=settings.scene,
            mode="live",
            rate_hz=settings.rate_hz or 1000.0,
            pose_rate_hz=settings.pose_rate_hz,
            control_rate_hz=settings.control_rate_hz,
            kit=settings.kit,
            left_handed=settings.left_handed,
            strike_event=settings.strike_event,
            control=settings.control,
            floating_base=settings.floating_base,
            grip=settings.grip,
            height_m=settings.height_m,
            mass_kg=settings.mass_kg,
            strike_period_s=settings.strike_period,
            strike_velocity=settings.strike_velocity,
            limits_from=tuple(settings.limits_from),
            asymmetric_limits=settings.asymmetric_limits,
            skeleton_bvh=settings.skeleton_bvh,
            skeleton_units=settings.skeleton_units,
        )
        if settings.asymmetric_limits and not settings.limits_from:
            log.warning("--asymmetric-limits has no effect without --limits-from (the default limits are always "
                        "mirror-symmetric)")
        if getattr(extra, "show_body", None):  # offline: no planning process
            _show_body(PhysicsCore(core_settings.model_copy(update={"mode": "offline"}), kit=kit), extra.show_body)
        core = LivePhysicsCore(core_settings, kit=kit)
    except (FileNotFoundError, BvhError, ClipError) as exc:  # a kit, clip or BVH file not there or unreadable
        raise InputError(str(exc)) from None
    from services.physics.drummer import DrummerScene  # loaded by the drummer's core already

    if isinstance(core.scene, DrummerScene):
        log.info("%s", body_summary(core.scene))
    try:
        core.score_player.midi = midi
        _prepare(core, settings)
        _wait_for_planner(core)
    except ValueError as exc:  # the --score file: not a score it can read
        core.close()
        raise InputError(str(exc)) from None
    except BaseException:  # a node stopped while starting (StoppedWhileStarting): its planning processes stop
        core.close()
        raise
    return core


COUNTS_LOG_PERIOD_S = 60.0
"""The live node logs the controller's counters (limit violations, torque-saturated DOF-steps) at most this often,
seconds of rig time, and only when they grew."""

PLANNER_LOAD_WAIT_S = 30.0
"""Longest the node waits, once its scene is ready, for its planning process to load the planner before it listens
(says it is up and answers Hellos), seconds: 2-5 s of CPU, 15-36 s measured under a load of 20 while the process was
niced. Past it the node starts anyway, says so, and refuses live notes and ``play`` (a playing score's style and
tempo changes too) with the reason until the load is done (a node that never came up would be worse; the rig gives up
at its ``--ready-timeout``, 60 s)."""


def _wait_for_planner(core: LivePhysicsCore) -> None:
    """Hold the node's start until its planning process can plan (see :data:`PLANNER_LOAD_WAIT_S`): a node that
    said it was up while its processes still loaded refused every note sent meanwhile as late."""
    if not core.score_player.loading:
        return
    started = time.monotonic()
    if not core.wait_loaded(PLANNER_LOAD_WAIT_S):
        log.warning("the planning process has not loaded the planner after %.0f s: starting without it; live "
                    "notes and play are refused until it has (their senders are told why)", PLANNER_LOAD_WAIT_S)
    elif (error := core.score_player.planner_load_error) is not None:
        log.warning("the planning process could not load the planner (%s: %s): plans go to a thread of the node",
                    type(error).__name__, error)
    else:
        log.info("planning process ready (waited %.1f s for it)", time.monotonic() - started)


def _show_body(core: PhysicsCore, form: str) -> None:
    """``--show-body``: print the body ``core`` built (a table, or JSON) and exit (0)."""
    from services.physics.drummer import DrummerScene

    try:
        if not isinstance(core.scene, DrummerScene):
            raise ValueError("--show-body needs the drummer scene")
        print(json.dumps(body_json(core.scene), indent=2) if form == "json" else body_text(core.scene))
    finally:
        core.close()
    raise SystemExit(0)


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    for setting, flag in RENDER_SPELLINGS.items():  # the same setting as the node's own flag; its help says so
        parser.add_argument(flag, dest=setting, metavar=setting.upper(), default=argparse.SUPPRESS,
                            help=argparse.SUPPRESS)
    parser.add_argument("--show-body", nargs="?", const="text", choices=("text", "json"), default=None,
                        help="print the drummer's body as these settings build it and exit: segment lengths (m) and "
                        "masses (kg), DOF, per joint torque limit (N m), PD gains and joint limits with their "
                        "source; 'json': as JSON")


def _skeleton_limbs(settings: PhysicsNodeSettings) -> LimbLengths | None:
    """The arms and legs (metres) of the body the core builds from ``--skeleton-bvh``, for the kit's reach warning;
    None without one, or for a file the core refuses (its own error says why, as before)."""
    if not settings.skeleton_bvh:
        return None
    from services.physics.bvh_motion import skeleton_limb_lengths

    try:
        return skeleton_limb_lengths(settings.skeleton_bvh, settings.height_m, settings.mass_kg,
                                     settings.skeleton_units)
    except (OSError, ValueError):
        return None


def _prepare(core: PhysicsCore, settings: PhysicsNodeSettings) -> None:
    """Load now what the first messages and steps would otherwise wait for (seconds), and ``--score``."""
    player = core.score_player
    player.library = [Path(d).expanduser() for d in settings.score_dir]
    player.sticking = Sticking(settings.sticking)  # before --score's plan
    if settings.scene == "drummer":
        _ = player.preparation_s  # loads the gesture database now (about 1 s), not in the first score message
        # compiles the numba kernels now (or loads them from the cache), not in the first live steps
        if not kernels_cached():  # said first: `batteur rig`'s ready timeout names it (a cold cache took 140 s)
            log.info("%s (no cache yet: the first run after an install or an update; about 10 s, minutes on a "
                     "loaded machine; `python3 -m services.physics.precompile` does it ahead)", COMPILING)
        log.info("physics kernels ready (%.1f s)", warm_up())
    if settings.score:
        player.load(settings.score, trusted=True)  # a command-line path: trusted, unlike a message's
        player.library.append(Path(settings.score).expanduser().resolve().parent)


def start_score(node: Node) -> None:
    """Once the node listens: play ``--score`` from rig time ``--play-at`` (a node up too late for its first note
    starts the whole score later, with its lead-in, and says so at INFO: a scene ready after ``--play-at`` is the
    normal start of a rig on a loaded machine; a score that cannot be played is logged, the node keeps running)."""
    settings, core = node.settings, node.core
    if not isinstance(settings, PhysicsNodeSettings) or not isinstance(core, PhysicsCore):
        return
    if not settings.score or settings.play_at is None:
        return
    try:
        core.score_player.play(settings.play_at, 0.0, node.clock.now(), whole=True, start_up=True)
    except ValueError as exc:
        log.error("cannot play %s: %s", settings.score, exc)


def main(argv: Sequence[str] | None = None) -> int:
    return run_node(
        "physics",
        make_core,
        argv,
        description="Batteur physics: the simulated percussionist and kit (PyBullet), contacts and poses.",
        settings_cls=PhysicsNodeSettings,
        setup=start_score,
        add_arguments=_add_arguments,
    )


if __name__ == "__main__":
    raise SystemExit(main())
