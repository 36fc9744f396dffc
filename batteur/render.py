"""``batteur render``: run the services' cores together offline and write the results.

Two scenes:

* a score (``batteur render SCORE -o DIR``, MIDI or the text format): the score
  reader and limb distribution (common/score), the gesture planner
  (common/gesture), then the full-dynamics drummer (PhysicsCore scene
  ``drummer``, offline) -> InteractionCore -> SoundCore, wired through
  :class:`common.bus.OfflineRunner` exactly as the rig's nodes are;
* the strike scene (``batteur render --strikes 0.25:3,0.75:1.5 -o DIR``): a
  stick thrown onto one instrument on a schedule (integration smoke test).

Outputs in DIR: ``performance.wav`` (an impact at rig time t heard from t + ``latency_s``; ``--wav-from score``: from
its score time, the file starting at score time 0, bar 1, as heard, :func:`shift_wav`), ``impacts.csv``
(one row per impact, every feature of ``/batteur/impact``, rig times),
``performance.bvh`` (the simulated motion, score mode; frame 0 the WAV's time 0, or with ``--bvh-sync pose``
the first pose), with ``--video``
``performance.mp4`` (the motion rendered headless, the WAV muxed in sync, on its clock;
score mode, needs ffmpeg), with ``--gltf`` ``performance.glb`` (the motion and the kit as one animated glTF 2.0
file at the BVH's rate, on the WAV's clock; score mode), ``report.json`` (what
was rendered, the time offset between score and rig clocks, the planner's
feasibility issues, real-time factor). Everything is staged in a temporary
directory and moved in only when the whole run succeeded: a corrupted score
or a failing run leaves nothing partial.

Clocks: rig time = score time + ``score_offset_s`` (report.json); sound adds
``latency_s`` (each impact is heard at its rig time plus the latency).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import json
import logging
import math
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal, TypeVar, get_args

import numpy as np
import soundfile as sf

from batteur.errors import INTERRUPTED, TERMINATED, USAGE, UsageError, report_error
from batteur.impact_log import ImpactCsvStream, ImpactLog, write_impacts_csv
from batteur.interrupts import DeferredCtrlC, Terminated, sigterm_raises
from batteur.progress import Progress
from batteur.render_outputs import GLTF_OUTPUT, SCORE_OUTPUTS, VIDEO_OUTPUT
from batteur.score_part import bar_part, parse_bars, part_json
from batteur.strike import DEFAULT_STRIKES, parse_strikes, run_strikes
from common.arg_types import take_negative_values
from common.core import Outgoing
from common.gesture.plan import GesturePlan, Grip, Nuance, planned_grip
from common.gesture.reach import pull_into_reach
from common.kit import EventType, Kit, kit_file, load_kit
from common.messages import OscMessage
from common.messages.physics import ControlModeName
from common.output_paths import check_output_dir
from common.score.events import Score, ScoreError
from common.score.hands import HandAlgorithm, Sticking
from common.score.limbs import STATURE_M, Assignment, LimbLengths
from common.score.midi_notes import note_map_json
from common.score.midi_options import add_midi_arguments, midi_read_kwargs
from common.score.summary import score_length
from common.score.text import DEFAULT_KIT, load_score_kit, score_kit

if TYPE_CHECKING:
    from batteur.calibration import Calibration
    from services.graphics.export.bvh import BvhStream
    from services.interaction.config import InteractionConfig
    from services.physics.anthropometry import SkeletonUnits
    from services.physics.core import PhysicsCore

CONTROL_MODES: dict[str, str] = {
    "cartesian": "cartesian",  # DLS IK on the stick tips feeding the PD (the paper's Cartesian tracking)
    "joint": "joint_pd",  # the paper's joint-space PD on open-loop IK of the plan
    **{name: name for name in get_args(ControlModeName)},  # every controller physics offers, by its own name
}
"""``--control`` choice -> PhysicsSettings.control."""

DEFAULT_STRIKE_EVENT = EventType.SNARE.value
"""What the strike scene's stick strikes without ``--event``."""
GRIPS = ("german", "french", "american", "traditional")
"""Physics grips; the planner's gesture database has french and german (others plan as german)."""
GESTURE_GRIPS = tuple(g.value for g in Grip)
"""The grips the planner's gesture database has units for (:func:`grip_warning`)."""
DEFAULT_GRIP = "german"
"""The grip of a render whose options and score name none."""
DEFAULT_NUANCE = Nuance.TENUTO
"""The nuance of a render whose options and score name none."""
DEFAULT_MASS_KG = 73.0
"""The drummer's default mass, kilograms (physics' ``PhysicsSettings.mass_kg``)."""
HEIGHT_RANGE_M = (1.2, 2.2)
"""Accepted ``--height``, metres (physics' ``PhysicsSettings.height_m``: de Leva's table scaled that far)."""
MASS_RANGE_KG = (35.0, 150.0)
"""Accepted ``--mass``, kilograms (physics' ``PhysicsSettings.mass_kg``)."""
BVH_RATE_RANGE = (1.0, 1000.0)
"""Accepted ``--bvh-rate``, Hz."""
BVH_UNITS_PER_METRE = {"m": 1.0, "cm": 100.0}
"""``--bvh-units`` -> performance.bvh's file units per metre."""
BVH_FACINGS: tuple[Literal["+z", "-z"], ...] = ("+z", "-z")
"""``--bvh-facing``: which way the drummer faces in performance.bvh (services/graphics/export/bvh.py ``Y_UP``): +z,
as the glTF and CMU's and Mixamo's clips (the default since 8 Dec), or -z (the files until 8 Dec)."""
MAX_PHYSICS_POSE_HZ = 240.0
"""Physics publishes poses at most this often (``PhysicsSettings.pose_rate_hz``), Hz; a faster BVH is interpolated
between them."""

TEMPO_SCALE_RANGE = (0.1, 10.0)
"""Accepted ``--tempo-scale``: slower stretches the render (and its memory) without bound, faster piles every
note onto the first instant."""
MIN_SEGMENT_S = 1.0
"""Shortest ``--segment``, seconds: each segment's drummer first plays a lead-in of a few seconds."""


class RenderError(RuntimeError):
    """A render that could not be completed (the message says why); nothing is written."""


@dataclass(frozen=True)
class RenderOptions:
    """How to render a score (seconds, m/s)."""

    kit: str | None = DEFAULT_KIT
    """Kit name or file; None: the score's ``kit`` directive (a text score), else :data:`DEFAULT_KIT`
    (:meth:`styled`; ``batteur render`` without ``--kit``)."""
    grip: str | None = None
    """Physics grip (and the planner's, where the gesture database has it); None: the score's ``grip`` directive
    (a text score), else :data:`DEFAULT_GRIP` (:meth:`styled`)."""
    nuance: Nuance | None = None
    """Global nuance of the gestures; None: the score's ``nuance`` directive, else :data:`DEFAULT_NUANCE`."""
    tempo_scale: float = 1.0
    """> 1 plays faster: every score time is divided by it."""
    control: str = "cartesian"
    algorithm: HandAlgorithm = HandAlgorithm.VITERBI
    sticking: Sticking = Sticking.NONE
    """Sticking pattern forced on rolls (``--sticking``; :func:`common.score.hands.apply_sticking`)."""
    latency_s: float = 0.05
    settle_s: float = 0.5
    """Rig time at which the plan starts (the body settles at rest before), seconds."""
    tail_s: float = 1.0
    rate_hz: float = 1000.0
    control_rate_hz: float | None = None
    """Drummer's full control updates per second, Hz (None: the physics default)."""
    pose_rate_hz: float = 60.0
    """Frame rate of performance.bvh, Hz (``--bvh-rate``); physics sends poses at least at 60 Hz
    (:func:`physics_pose_rate`)."""
    bvh_sync: Literal["pose", "wav"] = "wav"
    """performance.bvh's frame 0 (``--bvh-sync``): performance.wav's time 0 (:func:`wav_frame_start`), the first
    pose held until it comes, so every output imported at frame 0 lines up (the default since 7 Dec), or the first
    pose (rig time 1 ms: 3 frames before its sound at 60 Hz, the file before 7 Dec)."""
    bvh_units: Literal["m", "cm"] = "m"
    """performance.bvh's length unit (``--bvh-units``): metres, or centimetres (Maya and MotionBuilder work in
    cm: a metre file comes in 100 times too small there)."""
    bvh_facing: Literal["+z", "-z"] = "+z"
    """Which way the drummer faces in performance.bvh (``--bvh-facing``, :data:`BVH_FACINGS`): +z, as in the glTF
    (the default since 8 Dec), or -z (the files until 8 Dec)."""
    calibration: Path | None = None
    sound_params: Path | None = None
    """A sound parameters file (``--sound-params``: services/sound/params_file.py) the instruments start from."""
    wav_from: Literal["render", "score"] = "render"
    """performance.wav's sample 0 (``--wav-from``): the render's start (rig time 0, the drummer settling before the
    lead-in; report.json's ``score_time_0_wav_s`` says where bar 1 falls), or score time 0 (bar 1, beat 1) as heard:
    the render's WAV trimmed or padded with silence before (:func:`shift_wav`), for a DAW's bar 1."""
    video: bool = False
    """Also write performance.mp4 (services.graphics.video.render_video); needs ffmpeg."""
    video_fps: float = 30.0
    video_size: tuple[int, int] = (640, 360)
    """Video frame width and height, pixels (even)."""
    gltf: bool = False
    """Also write performance.glb (services.graphics.export.gltf.write_gltf) at the BVH's frame rate."""
    jobs: int = 1
    """Processes: 1 renders in one piece; more render time segments in parallel (batteur/segments.py)."""
    segment_s: float = 30.0
    """Length of a segment when ``jobs`` > 1, rig seconds."""
    limits_from: tuple[str, ...] = ()
    """Motion clips the drummer's joint limits come from (BVH files, DeepMimic files or clip names; none: every
    DeepMimic clip)."""
    asymmetric_limits: bool = False
    """With ``limits_from``: each side's own limits as the clips give them, not made mirror-symmetric
    (``PhysicsSettings.asymmetric_limits``)."""
    skeleton_bvh: Path | None = None
    """BVH file whose skeleton gives the drummer's proportions (None: de Leva's table)."""
    skeleton_units: SkeletonUnits = "auto"
    """``skeleton_bvh``'s length unit (``--skeleton-units``): ``auto`` guesses it from the performer its lengths
    make (``services.physics.bvh_motion.read_skeleton``)."""
    height_m: float = STATURE_M
    """The drummer's height, metres (1.2 to 2.2): physics' body (de Leva's segments scaled) and the planner's
    reach."""
    mass_kg: float = DEFAULT_MASS_KG
    """The drummer's mass, kilograms (35 to 150): physics' segment masses and joint strength."""
    midi: dict[str, Any] = field(default_factory=dict)
    """Keyword arguments reading a MIDI score (``--drum-channels``...:
    :func:`common.score.midi_options.midi_read_kwargs`); a text score ignores them."""
    bars: tuple[int, int] | None = None
    """``--bars``: render only these bars (first, last; counted as ``python -m common.score`` counts them) of the
    score, on its clock shifted to start at the first (:func:`batteur.score_part.bar_part`); None: the whole score."""

    def styled(self, score: Score | None = None) -> RenderOptions:
        """These options with the kit, grip and nuance a render of ``score`` plays: those given here, else those
        the score asks for (a text score's ``kit``, ``grip`` and ``nuance`` directives; a MIDI file has none), else
        :data:`DEFAULT_KIT`, :data:`DEFAULT_GRIP` and :data:`DEFAULT_NUANCE`."""
        return self.with_style(*score_style(score)).with_kit(score_kit(score))

    def with_kit(self, asked_kit: str | None) -> RenderOptions:
        """These options with the kit a score asking for ``asked_kit`` plays (None: it does not; see
        :meth:`styled`)."""
        if self.kit is not None:
            return self
        return dataclasses.replace(self, kit=asked_kit or DEFAULT_KIT)

    def with_style(self, asked_grip: str | None, asked_nuance: Nuance | None) -> RenderOptions:
        """:meth:`styled` for a score asking for ``asked_grip`` and ``asked_nuance`` (None: it does not)."""
        grip = self.grip if self.grip is not None else (asked_grip or DEFAULT_GRIP)
        nuance = self.nuance if self.nuance is not None else (asked_nuance or DEFAULT_NUANCE)
        if (grip, nuance) == (self.grip, self.nuance):
            return self
        return dataclasses.replace(self, grip=grip, nuance=nuance)


def score_style(score: Score | None) -> tuple[str | None, Nuance | None]:
    """The grip and nuance ``score`` asks for (a text score's directives), None for those it does not."""
    from common.score.text import TextScore

    if not isinstance(score, TextScore):
        return None, None
    return (None if score.grip is None else score.grip.value), score.nuance


def file_style(path: Path) -> tuple[str | None, Nuance | None]:
    """The grip and nuance the score file ``path`` asks for (a MIDI file: none, and it is not read); raises
    :class:`ScoreError` for a text score that cannot be read."""
    from common.score.text import MIDI_SUFFIXES, read_score

    if path.suffix.lower() in MIDI_SUFFIXES:
        return None, None
    return score_style(read_score(path))


def file_kit(path: Path) -> str | None:
    """The kit the score file ``path`` asks for (:func:`score_kit`; a MIDI file: none, and it is not read); raises
    :class:`ScoreError` for a text score that cannot be read."""
    from common.score.text import MIDI_SUFFIXES, read_score

    if path.suffix.lower() in MIDI_SUFFIXES:
        return None
    return score_kit(read_score(path))


def physics_pose_rate(opts: RenderOptions) -> float:
    """How often physics sends poses, Hz: the BVH's rate, but at least the default 60 Hz (the video draws from the
    same poses: a 24 Hz BVH must not coarsen it) and at most :data:`MAX_PHYSICS_POSE_HZ`; 0: none."""
    if opts.pose_rate_hz <= 0:
        return opts.pose_rate_hz
    return min(max(opts.pose_rate_hz, RenderOptions.pose_rate_hz), MAX_PHYSICS_POSE_HZ)


@dataclass
class ScoreRender:
    """What a score render produced (times: rig seconds unless named otherwise)."""

    score: Score
    assignment: Assignment
    plan: GesturePlan
    impacts: list[Any]
    contacts: int
    audio: np.ndarray
    sample_rate: int
    duration_s: float
    """performance.wav's length (:func:`wav_seconds`): the timeline simulated (:func:`rendered_seconds`) to its
    sound's last whole block."""
    score_offset_s: float
    wall_time_s: float
    poses: Any = None
    physics: dict[str, Any] = field(default_factory=dict)
    impact_count: int | None = None
    """Impacts rendered, when they were streamed to impacts.csv rather than kept in ``impacts`` (None: kept)."""

    @property
    def impacts_total(self) -> int:
        return len(self.impacts) if self.impact_count is None else self.impact_count


def scale_tempo(score: Score, scale: float) -> Score:
    """The score played ``scale`` times faster (every time divided by ``scale``)."""
    if not 0 < scale < math.inf:
        raise ValueError(f"tempo scale must be a positive finite number, got {scale}")
    if scale == 1.0:
        return score
    scaled = dataclasses.replace(
        score,
        events=[dataclasses.replace(e, time=e.time / scale) for e in score.events],
        beats=np.asarray(score.beats, dtype=float) / scale,
        unknown=[dataclasses.replace(u, time=u.time / scale) for u in score.unknown],
        duplicates=[dataclasses.replace(d, time=d.time / scale) for d in score.duplicates],
    )
    for name in ("grip", "nuance", "kit", "kit_line"):  # a text score's directives are attributes, not fields
        if hasattr(score, name):
            setattr(scaled, name, getattr(score, name))
    return scaled


def prepare(path: Path | str, kit: Kit, opts: RenderOptions, calibration: Calibration | None = None,
            progress: Callable[[str, int, int], None] | None = None,
            limbs: LimbLengths | None = None, score: Score | None = None) -> tuple[Score, Assignment, GesturePlan]:
    """Read, distribute and plan a score; raises :class:`ScoreError` for a bad score.

    With a ``calibration`` the notes are shifted (lag anticipation) and their
    velocities remapped before planning; the returned ``score`` keeps the
    written times (what the performance is judged against). The grip and nuance are ``opts.styled(score)``'s (a
    text score's directives unless ``opts`` names them), the reach that of a drummer ``opts.height_m`` tall (with
    ``opts.skeleton_bvh``, its arms and legs: ``limbs`` if the caller read them already, else
    :func:`skeleton_limbs`).
    ``progress``: called with (stage, done, total)
    while a MIDI file is read (stage ``"reading"``, in bytes: ``read_midi``'s progress), its notes are given
    limbs (``"limbs"``, in notes: ``distribute``'s) and planned (``"gestures"``, ``plan_gestures``'); what it
    raises stops the preparation. ``score``: the score of ``path`` read already (:func:`read_scaled`).
    """
    from common.gesture.planner import PlannerConfig, plan_gestures
    from common.score.limbs import distribute

    if score is None:  # a text score's kit object ids name the kit played (--kit's), not its kit line's
        score = read_scaled(path, opts, progress, kit)
    if not score.events:  # the reader's warnings say why (unknown pitches, no drum channel)
        why = "; ".join(w.removeprefix(f"{path}: ").removeprefix(f"{Path(path).name}: ") for w in score.warnings
                        if not w.endswith("no drum events"))
        raise ScoreError(f"{path}: no drum events to play" + (f" ({why})" if why else ""))
    assignment = distribute(score, kit, opts.algorithm, opts.sticking,
                            progress=None if progress is None else functools.partial(progress, "limbs"),
                            height_m=opts.height_m, lengths=limbs if limbs is not None else skeleton_limbs(opts))
    planned = assignment if calibration is None else calibration.apply(assignment, kit)
    style = opts.styled(score)
    grip = planned_grip(style.grip or DEFAULT_GRIP)  # american, traditional: no units, planned german
    plan = plan_gestures(planned, kit, score, PlannerConfig(grip=grip, nuance=style.nuance or DEFAULT_NUANCE),
                         progress=None if progress is None else functools.partial(progress, "gestures"))
    return score, assignment, plan


def read_scaled(path: Path | str, opts: RenderOptions,
                progress: Callable[[str, int, int], None] | None = None, kit: Kit | None = None) -> Score:
    """The score of ``path`` at ``opts.tempo_scale``; ``progress`` as :func:`prepare`'s (stage ``"reading"``).
    ``kit``: the kit a text score's object ids (``crash2``) are looked up in (None: its ``kit`` line's, else the
    default; until 7 Dec ``--kit``'s was not passed, and an id only ``--kit``'s kit has was refused)."""
    from common.score.text import read_score

    reading = None if progress is None else functools.partial(progress, "reading")  # MIDI only: text is quick
    return scale_tempo(read_score(path, kit=kit, progress=reading, **opts.midi), opts.tempo_scale)


def load_render_kit(path: Path | str, opts: RenderOptions, score: Score | None,
                    limbs: LimbLengths | None) -> Kit:
    """The kit a render of ``score`` (at ``path``) plays (:meth:`RenderOptions.styled`), its load warnings naming
    the drummer asked for; a kit the score's ``kit`` line names that cannot be loaded is a :class:`ScoreError`
    naming the line (:func:`common.score.text.load_score_kit`)."""
    return load_score_kit(score, opts.kit, path,
                          lambda name: load_kit(name, height_m=opts.height_m, lengths=limbs))


@dataclass(frozen=True)
class KitCopy:
    """A kit file as a render read it, copied into its folder as ``played-kit<suffix>`` so that ``batteur evaluate
    DIR`` judges the render on the kit it played, wherever it runs from and however the file is edited since (until
    7 Dec only the path as typed was kept: relative to where the render ran). Not ``kit<suffix>`` (renders of 7 Dec):
    a song folder's own hand-edited ``kit.yaml`` was replaced by the copy of another kit rendered into it."""

    source: Path
    """The kit file, absolute (report.json's ``kit_file``)."""
    data: bytes
    """Its contents when the render loaded it."""

    @property
    def name(self) -> str:
        """The copy's name in the render folder (report.json's ``kit_copy``)."""
        return f"played-kit{self.source.suffix}"

    @classmethod
    def of(cls, kit: str | None) -> KitCopy | None:
        """The copy of ``kit`` (a kit name or file, as ``--kit`` or a score's ``kit`` line give it), read now; None
        for a shipped kit's name (no file of the user's) or a file gone since it was loaded."""
        if kit is None or not Path(kit).suffix:
            return None
        source = kit_file(kit)
        try:
            return cls(source, source.read_bytes())
        except OSError:
            return None


class _KeptWarnings(logging.Handler):
    """Keeps the text of each warning logged (:func:`kept_warnings`); ``show``: also prints it on stderr as logging's
    last resort would have (nothing else handles it)."""

    def __init__(self, kept: list[str], show: bool) -> None:
        super().__init__(logging.WARNING)
        self.kept = kept
        self.show = show

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        self.kept.append(message)
        if self.show:
            print(message, file=sys.stderr)


KEPT_LOGGERS = ("common", "batteur")
"""The loggers whose warnings a render keeps (:func:`kept_warnings`): common/'s and the services' cores' (their
loggers are ``batteur.physics``, ``batteur.sound``, ...)."""


@contextlib.contextmanager
def kept_warnings(kept: list[str]) -> Iterator[None]:
    """Append to ``kept`` every warning :data:`KEPT_LOGGERS` log meanwhile: the kit's load warnings (an instrument
    out of reach, struck by no event, ...) a render prints at its start, the cores' while it runs (physics' joint
    limits from ``--limits-from``, sound's latency), for report.json's ``warnings`` (until 7 Dec on the console
    only; until 8 Dec the cores' too). They are shown as before: by the handlers logging has, else on stderr."""
    handlers = []
    for name in KEPT_LOGGERS:
        logger = logging.getLogger(name)
        handler = _KeptWarnings(kept, show=not logger.hasHandlers())
        logger.addHandler(handler)
        handlers.append((logger, handler))
    try:
        yield
    finally:
        for logger, handler in handlers:
            logger.removeHandler(handler)


def grip_warning(grip: str | None) -> str | None:
    """The warning for hands holding ``grip`` that the gestures are not planned with (american, traditional: the
    gesture database has no units for them, :func:`common.gesture.plan.planned_grip`), as the rig's physics node
    logs it; None when they are planned with the hands' grip."""
    hands = grip or DEFAULT_GRIP
    planned = planned_grip(hands).value
    if planned == hands:
        return None
    return (f"the drummer's hands hold the {hands} grip; the gestures are planned with the {planned} grip (the "
            f"gesture database has {' and '.join(GESTURE_GRIPS)} units only)")


class PlanningProgress:
    """The bars of a score render before its simulation, one per stage of :func:`prepare`: ``reading SCORE`` (a MIDI
    file, counted in its bytes, shown in kB or MB), then ``planning SCORE (limbs)`` and ``(gestures)``, counted in
    notes; each line is ended when the next stage begins. On stderr on a terminal, like the render's bar."""

    def __init__(self, name: str, quiet: bool) -> None:
        self.name = name
        self.quiet = quiet
        self.stage: str | None = None
        self.bar: Progress | None = None
        self.scale = 1.0
        """What one unit of the bar is worth in the stage's counts (bytes per kB or MB while reading)."""

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self.bar is None or stage != self.stage:
            self.close()
            self.stage = stage
            self.bar = self._bar(stage, total)
        self.bar.update(done / self.scale)

    def _bar(self, stage: str, total: int) -> Progress:
        enabled = False if self.quiet else None
        if stage != "reading":
            self.scale = 1.0
            return Progress(f"planning {self.name} ({stage})", total, unit="notes", decimals=0, enabled=enabled)
        megabytes = total >= 2**20
        self.scale = 2.0**20 if megabytes else 2.0**10
        return Progress(f"reading {self.name}", total / self.scale, unit="MB" if megabytes else "kB", decimals=1,
                        enabled=enabled)

    def close(self, finished: bool = True) -> None:
        """End the current stage's line (``finished=False``: where it stands, the planning given up)."""
        if self.bar is not None:
            self.bar.close(finished)
            self.bar = None


def rendered_seconds(plan: GesturePlan, opts: RenderOptions) -> float:
    """Length of the render's timeline, seconds: the settle before the plan, the plan, the sound's latency and
    the ring-out after the last note (what the WAV holds and the progress bar counts)."""
    return plan.end_time + (opts.settle_s - plan.start_time) + opts.latency_s + opts.tail_s  # summed as before


def wav_seconds(sound: Any) -> float:
    """The length of the audio ``sound`` (a SoundCore, its sample 0 at rig time 0) rendered, seconds: whole blocks
    (256 samples), so up to a block (5.3 ms) short of the timeline run (:func:`rendered_seconds`). report.json's
    ``duration_s`` and the glTF's and ``--bvh-sync wav`` BVH's last frame follow it (until 7 Dec they followed the
    timeline, up to 5.3 ms past the WAV's end)."""
    return sound.next_sample / sound.sample_rate


def read_render_sound_params(path: Path | None, kit: Kit) -> None:
    """``--sound-params``: ValueError naming the file and the entry for one that cannot be read or names what
    ``kit`` does not have (before the long part of a render)."""
    if path is None:
        return
    from services.sound.params_file import check_against_kit, load_sound_params

    try:
        check_against_kit(load_sound_params(path), kit, path)
    except FileNotFoundError as exc:
        raise ValueError(str(exc)) from None


def apply_render_sound_params(sound: Any, path: Path | None) -> None:
    """``--sound-params`` on a render's sound core (a SoundCore), read again here (a segment's worker too)."""
    if path is None:
        return
    from services.sound.params_file import apply_sound_params, load_sound_params

    apply_sound_params(sound, load_sound_params(path), path)


def run_score(score: Score, assignment: Assignment, plan: GesturePlan, kit: Kit, opts: RenderOptions,
              on_progress: Callable[[float, float], None] | None = None,
              outputs: StreamedOutputs | None = None) -> ScoreRender:
    """Play a gesture plan with the full-dynamics drummer and render its sound (see the module docstring).

    ``outputs``: the WAV, impacts and motion are written there as they are rendered (the result then holds no
    audio, and impacts and poses only if ``outputs.keep``); None: all of it is kept in the result.
    Raises :class:`RenderError` when physics refuses the plan.
    """
    from common.bus import OfflineRunner
    from services.interaction.core import InteractionCore
    from services.sound.core import SoundCore, SoundSettings

    started = time.perf_counter()
    cpu_started = time.process_time()
    pulled: dict[str, int] = {}
    physics = start_drummer(plan, kit, opts, pulled=pulled)
    offset = opts.settle_s - plan.start_time
    interaction = InteractionCore(kit=kit, config=offline_interaction_config())
    sound = SoundCore(SoundSettings(latency=opts.latency_s, origin=0.0, record=outputs is None), kit=kit)
    apply_render_sound_params(sound, opts.sound_params)
    recorder = RecorderCore() if outputs is None else outputs.recorder()
    runner = OfflineRunner([physics, interaction, sound, recorder])
    duration = rendered_seconds(plan, opts)
    try:
        if outputs is not None:
            outputs.attach(sound)
        runner.run_until(duration, None if on_progress is None else (lambda t: on_progress(t, duration)))
        audio = sound.recording()
    finally:
        sound.close()
        physics.close()
    poses, impacts, count = collect(recorder, outputs)
    stats = {"contacts_sent": physics.contacts_sent, "rejected": dict(physics.rejected), "diverged": physics.diverged,
             "control": physics.settings.control, "grip": physics.settings.grip, "rate_hz": physics.rate_hz,
             "control_rate_hz": physics.settings.control_rate_hz, "height_m": physics.settings.height_m,
             "mass_kg": physics.settings.mass_kg, "pulled_into_reach": pulled,
             "joint_limits": joint_limits_json(physics), "joint_limits_symmetric": limits_symmetric(physics),
             **controller_counts(physics),
             "cpu_time_s": round(time.process_time() - cpu_started, 3)}
    return ScoreRender(score, assignment, plan, impacts, physics.contacts_sent, audio, sound.sample_rate,
                       wav_seconds(sound), offset, time.perf_counter() - started, poses, stats, count)


def controller_counts(physics: PhysicsCore) -> dict[str, int]:
    """report.json's ``physics.limit_violations`` (joints outside their quaternion ellipsoid, summed over the
    control updates) and ``physics.torque_saturated`` (DOF whose torque was clipped to its limit, summed over the
    physics steps): :class:`services.physics.control.Controller`'s counters; none for a scene without a drummer."""
    controller = getattr(physics.scene, "controller", None)
    if controller is None:
        return {}
    return {"limit_violations": controller.limit_violations, "torque_saturated": controller.torque_saturated}


def joint_limits_json(physics: PhysicsCore) -> dict[str, Any] | None:
    """report.json's ``physics.joint_limits``: joint -> the formulation its limits have (``euler+quaternion``,
    ``euler``: the box alone, e.g. an ellipsoid dropped for the playing posture), their source and each DOF's
    (:meth:`services.physics.limits.JointLimits.formulations`); None for a scene without a drummer."""
    limits = getattr(physics.scene, "limits", None)
    return None if limits is None else limits.formulations()


def limits_symmetric(physics: PhysicsCore) -> bool | None:
    """report.json's ``physics.joint_limits_symmetric``: whether each left/right pair's joint limits were made
    mirror-symmetric (the default limits always; ``--limits-from`` clips unless ``--asymmetric-limits``); None for
    a scene without a drummer."""
    limits = getattr(physics.scene, "limits", None)
    return None if limits is None else bool(limits.symmetric)


def collect(recorder: RecorderCore, outputs: StreamedOutputs | None) -> tuple[Any, list[Any], int | None]:
    """After the run: (poses, impacts, impact count if streamed), the streamed outputs finished."""
    if outputs is not None:
        count = outputs.finish()
        if not outputs.keep:
            return None, [], count
    else:
        count = None
    try:
        poses = recorder.poses.sequence()
    except ValueError:
        poses = None
    return poses, recorder.impacts.sorted(), count


def start_drummer(plan: GesturePlan, kit: Kit, opts: RenderOptions, start_s: float = 0.0,
                  pulled: dict[str, int] | None = None) -> PhysicsCore:
    """The offline drummer of ``opts``, its clock at rig time ``start_s`` (seconds), tracking ``plan`` (whose
    ``start_time`` is at rig time ``opts.settle_s``), its hands holding ``opts.styled()``'s grip (resolve the
    score's first: :meth:`RenderOptions.styled`). Knots beyond the body's reach (an instrument too far for a small
    drummer) are brought within it (:func:`common.gesture.reach.pull_into_reach`; counted per limb in ``pulled``):
    the notes there are missed, not the whole render. Raises :class:`RenderError` when physics refuses the plan."""
    from services.physics.core import PhysicsCore, PhysicsSettings
    from services.physics.targets import TargetError

    control_rate_hz = opts.control_rate_hz
    if control_rate_hz is None:  # not `or`: 0 Hz is refused by the physics settings, not taken as the default
        control_rate_hz = PhysicsSettings.model_fields["control_rate_hz"].default
    physics = PhysicsCore(scene="drummer", kit=kit, control=CONTROL_MODES[opts.control], grip=opts.styled().grip,
                          rate_hz=opts.rate_hz, pose_rate_hz=physics_pose_rate(opts), control_rate_hz=control_rate_hz,
                          height_m=opts.height_m, mass_kg=opts.mass_kg, limits_from=opts.limits_from,
                          asymmetric_limits=opts.asymmetric_limits,
                          skeleton_bvh=None if opts.skeleton_bvh is None else str(opts.skeleton_bvh),
                          skeleton_units=opts.skeleton_units)
    physics.time_offset = start_s
    reach = getattr(physics.scene, "reach", None)
    if reach is not None:
        plan, counts = pull_into_reach(plan, reach)
        if pulled is not None:
            pulled.update(counts)
    try:
        physics.load_plan(plan, opts.settle_s)
    except TargetError as exc:
        physics.close()
        raise RenderError(f"physics refused the gesture plan: {exc}") from exc
    return physics


def offline_interaction_config() -> InteractionConfig:
    """Interaction's default configuration, each message sent once: the in-memory bus loses nothing, and the
    rig's redundant copies (5 of every impact) were most of a render's messages (sound and the recorder kept
    the first copy of each anyway)."""
    from services.interaction.config import InteractionConfig, RedundancyConfig

    return InteractionConfig(redundancy=RedundancyConfig(copies=1))


class RecorderCore:
    """Stands in for graphics in an offline render: records the poses and impacts sent to ``graphics``.

    A core rather than a bus tap, so each message is decoded once (a tap decodes all traffic again).
    """

    ROLE: ClassVar[str] = "graphics"
    rate_hz = 0.0

    def __init__(self, impacts_csv: ImpactCsvStream | None = None, bvh: BvhStream | None = None,
                 keep: bool = True) -> None:
        """``impacts_csv``, ``bvh``: where impacts and poses are streamed; ``keep``: also keep them in memory
        (``impacts``, ``poses``), for the video."""
        from services.graphics.recorder import PerformanceRecorder

        self.poses = PerformanceRecorder(keep_poses=keep, on_skeleton=None if bvh is None else bvh.restart,
                                         on_pose=None if bvh is None else bvh.add)
        self.impacts = ImpactLog()
        self.impacts_csv = impacts_csv
        self.keep = keep

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if self.impacts_csv is None:
            taken = self.impacts.add(message, source)
        else:
            taken = self.impacts_csv.add(message, now, source)
            if taken and self.keep:
                self.impacts.add(message, source)
        if not taken:
            self.poses.record(message, source)
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []


def wav_container(frames: int, channels: int) -> str:
    """The libsndfile format for a 24-bit performance.wav of ``frames`` samples per channel: ``"WAV"``, or
    ``"RF64"`` when the samples pass what a WAV header's 32-bit sizes describe (4 GiB: 8.3 h of the render's
    48 kHz mono), where the end of the audio would be lost to readers."""
    from services.sound.core import WAV_DATA_LIMIT_BYTES

    return "RF64" if frames * channels * 3 > WAV_DATA_LIMIT_BYTES else "WAV"


def say_rf64(path: Path, frames: int, sample_rate: int, prog: str = "batteur render") -> str:
    """One warning line on stderr, naming the command ``prog``: ``path`` is written as RF64 (see
    :func:`wav_container`); returns the warning (for report.json's ``warnings``)."""
    warning = (f"{path.name} will hold {frames / sample_rate / 3600:.1f} h of audio, more than a WAV file can "
               "describe (4 GiB): written as RF64")
    print(f"{prog}: warning: {warning}", file=sys.stderr)
    return warning


class WavStream:
    """performance.wav (24-bit PCM) written as sound renders it (``SoundCore.on_block``), a second at a time:
    libsndfile's cost per call made block-sized writes (64 samples) 3 % of a render.

    ``planned_frames``: the samples per channel the render will write, known before it starts; past the WAV
    limit the file is RF64 (:func:`wav_container`: ``format``), else a plain WAV.
    """

    BUFFER_S = 1.0
    """Audio gathered before each write, seconds."""

    def __init__(self, path: Path, sample_rate: int, channels: int, planned_frames: int = 0) -> None:
        self.path = path
        self.sample_rate = sample_rate
        """Samples per second, Hz."""
        self.frames = 0
        """Samples taken (per channel)."""
        self.written = 0
        """Samples in the file so far (per channel)."""
        size = max(1, round(sample_rate * self.BUFFER_S))
        self._buffer = np.empty(size if channels == 1 else (size, channels), dtype=np.float32)
        self._fill = 0
        self.format = wav_container(planned_frames, channels)
        """libsndfile's format of the file: "WAV" or "RF64"."""
        self._file: sf.SoundFile | None = sf.SoundFile(path, "w", sample_rate, channels, subtype="PCM_24",
                                                       format=self.format)

    @property
    def buffer_frames(self) -> int:
        """Samples the stream holds at most (per channel)."""
        return len(self._buffer)

    def write(self, block: np.ndarray) -> None:
        n = len(block)
        if self._fill + n > len(self._buffer):
            self._flush()
        if n > len(self._buffer):
            self._write(block)
        else:
            self._buffer[self._fill:self._fill + n] = block
            self._fill += n
        self.frames += n

    def _flush(self) -> None:
        if self._fill:
            self._write(self._buffer[:self._fill])
            self._fill = 0

    def _write(self, samples: np.ndarray) -> None:
        if self._file is None:
            raise ValueError(f"{self.path}: written to after it was closed")
        self._file.write(samples)
        self.written += len(samples)

    def close(self) -> None:
        """Write what is gathered and complete the header (idempotent)."""
        if self._file is not None:
            try:
                self._flush()
            finally:
                self._file.close()
                self._file = None


class StreamedOutputs:
    """performance.wav, impacts.csv and performance.bvh written into ``folder`` while the render goes on, so a
    render's memory does not grow with the piece (a 1-hour piece kept them all: 4 GB).

    ``bvh_rate_hz``: the BVH's frame rate (None: the poses' median interval, known only at the end: the poses
    are kept and :func:`write_rest` writes the BVH). ``keep``: also keep the impacts and poses in memory (the
    video draws them). ``planned_s``: the render's length, seconds (:func:`rendered_seconds`): a WAV that would
    pass 4 GiB is written as RF64 (said by ``prog``, the command rendering). ``bvh_start_s``: rig time of the
    BVH's frame 0, seconds (None: the first pose's), and its last frame's then: at ``bvh_start_s`` + the WAV's
    length (``--bvh-sync wav``: the BVH on the WAV's clock ends where the WAV does, as the glTF; until 7 Dec it went
    on to the last pose, 50 ms, the latency, past it); None: the last pose's. ``end_sites``: the BVH's End Sites,
    those of the body physics builds (:func:`body_end_sites`; None: the writer's guess from its snapshot).
    ``wav_cut_s``: the seconds ``--wav-from score`` cuts from the WAV's start once it is written (negative: silence
    it adds), so that the BVH on the WAV's clock still ends where the WAV does.
    """

    def __init__(self, folder: Path, bvh_rate_hz: float | None, keep: bool = False, planned_s: float = 0.0,
                 prog: str = "batteur render", bvh_start_s: float | None = None,
                 end_sites: dict[str, tuple[float, float, float]] | None = None, wav_cut_s: float = 0.0,
                 bvh_scale: float = 1.0, warnings: list[str] | None = None,
                 bvh_facing: Literal["+z", "-z"] = "+z") -> None:
        """``warnings``: where the RF64 warning is kept once said (report.json's ``warnings``); ``bvh_facing``: which
        way the drummer faces in the BVH (:data:`BVH_FACINGS`)."""
        from services.graphics.export.bvh import BvhStream

        self.folder = folder
        self.warnings = warnings
        self.bvh_start_s = bvh_start_s
        self.wav_cut_s = wav_cut_s
        self.planned_s = planned_s
        self.prog = prog
        self.keep = keep or bvh_rate_hz is None
        self.bvh_rate_hz = bvh_rate_hz
        self.wav: WavStream | None = None
        self.impacts = ImpactCsvStream(folder / "impacts.csv")
        self.end_sites = end_sites
        self.bvh = None if bvh_rate_hz is None else BvhStream(folder / "performance.bvh", bvh_rate_hz,
                                                              start=bvh_start_s, end_sites=end_sites,
                                                              scale=bvh_scale,  # file units per metre
                                                              facing=bvh_facing)
        self.bvh_frames: int | None = None
        """Frames of the streamed BVH once finished (None: no file)."""
        self._recorder: RecorderCore | None = None

    def attach(self, sound: Any) -> None:
        """Write what ``sound`` (a SoundCore) renders into performance.wav (RF64 past 4 GiB, said on stderr)."""
        frames = math.ceil(self.planned_s * sound.sample_rate) + sound.block  # sound renders whole blocks
        self.wav = WavStream(self.folder / "performance.wav", sound.sample_rate, sound.channels, frames)
        if self.wav.format == "RF64":
            said = say_rf64(self.wav.path, frames, sound.sample_rate, self.prog)
            if self.warnings is not None:
                self.warnings.append(said)
        sound.on_block = self.wav.write

    def recorder(self) -> RecorderCore:
        """The recorder whose impacts and poses are streamed here."""
        self._recorder = RecorderCore(self.impacts, self.bvh, keep=self.keep)
        return self._recorder

    def finish(self) -> int:
        """Complete the files; returns the impacts written."""
        if self.wav is None:
            raise RuntimeError("no sound was attached to the streamed outputs")
        self.wav.close()
        count = self.impacts.finish()
        if self.bvh is not None:
            end = (None if self.bvh_start_s is None
                   else self.bvh_start_s + (self.wav.frames / self.wav.sample_rate - self.wav_cut_s))
            self.bvh_frames = self.bvh.finish(end=end)
        return count

    def close(self) -> None:
        """Close every file (a render given up; the staging directory is removed with them)."""
        if self.wav is not None:
            self.wav.close()
        self.impacts.close()
        if self.bvh is not None:
            self.bvh.close()


class Staging:
    """The render's files written into a temporary directory inside ``output`` and moved in only by
    :meth:`commit`: a run that fails or is interrupted leaves nothing partial (a directory it created is
    removed). A context manager: an exception before :meth:`commit` discards the staging."""

    def __init__(self, output: Path) -> None:
        self.output = output
        self.created = not output.exists()
        output.mkdir(parents=True, exist_ok=True)
        self.path = Path(tempfile.mkdtemp(dir=output, prefix=".render-"))
        self.moved: list[str] = []

    def __enter__(self) -> Staging:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if kind is not None:
            self.discard()

    def commit(self) -> list[Path]:
        """Move every staged file into ``output``, remove those of an earlier render this one does not write."""
        earlier = earlier_outputs(self.output)
        names = sorted(p.name for p in self.path.iterdir())
        for name in names:
            (self.path / name).replace(self.output / name)
            self.moved.append(name)
        for name in sorted(earlier - set(names)):  # an earlier render's video or score copy: not this one's
            (self.output / name).unlink(missing_ok=True)
        self.path.rmdir()
        return [self.output / n for n in names]

    def discard(self) -> None:
        """Remove the staging, and what was moved into a directory this run created (with the directory)."""
        shutil.rmtree(self.path, ignore_errors=True)
        if self.created:
            for name in self.moved:
                (self.output / name).unlink(missing_ok=True)
            try:
                self.output.rmdir()
            except OSError:
                pass


# ---------------------------------------------------------------------- reports and output


def issues_json(plan: GesturePlan, score: Score) -> list[dict[str, Any]]:
    """The planner's feasibility issues, plus notes the score reader did not keep (unknown pitches, doubles)."""
    out: list[dict[str, Any]] = [
        {"note_index": i.note_index, "time_s": round(i.time, 6), "event": i.event.value if i.event else None,
         "reason": i.reason.value, "action": i.action.value, "detail": i.detail}
        for i in plan.issues
    ]
    out += [{"note_index": None, "time_s": round(u.time, 6), "event": None, "reason": "unknown_note",
             "action": "dropped", "detail": u.describe()} for u in score.unknown]
    out += [{"note_index": None, "time_s": round(d.time, 6), "event": d.event.value, "reason": "duplicate",
             "action": "merged", "detail": "double event of the same type within 10 ms"} for d in score.duplicates]
    return out


def score_report(result: ScoreRender, source: str, opts: RenderOptions, warnings: Sequence[str] | None = None,
                 kit_copy: KitCopy | None = None) -> dict[str, Any]:
    """report.json of a score render; the grip and nuance those played (``opts.styled(result.score)``).
    ``warnings``: every warning the render printed, in order (the kit's load warnings, the score reader's, the
    grip's, ...: :func:`render_score`); None: the score reader's alone. ``kit_copy``: the kit file it played, copied
    into the render folder (``kit_file``, absolute, and ``kit_copy``, the copy's name; null for a shipped kit).
    ``issues`` lists the planner's feasibility issues and, with ``note_index`` null, the notes the score reader
    did not keep (``unknown_note``: no drum for the pitch; ``duplicate``: a double merged), each counted apart:
    ``planner_issues``, ``unknown_notes``, ``duplicates``."""
    wall = result.wall_time_s
    cpu = result.physics.get("cpu_time_s")
    music = result.plan.end_time - result.plan.start_time
    style = opts.styled(result.score)
    length = score_length(result.score)
    return {
        "scene": "drummer",
        "score": source,
        "warnings": list(result.score.warnings) if warnings is None else list(warnings),
        "kit": opts.kit,
        "kit_file": None if kit_copy is None else str(kit_copy.source),
        "kit_copy": None if kit_copy is None else kit_copy.name,
        "grip": style.grip,
        "nuance": (style.nuance or DEFAULT_NUANCE).value,
        "height_m": opts.height_m,
        "mass_kg": opts.mass_kg,
        "bvh_rate_hz": opts.pose_rate_hz,
        "tempo_scale": opts.tempo_scale,
        "drum_channels": _drum_channels_json(opts),
        "drum_map": note_map_json(opts.midi.get("note_map")),  # --drum-map's pitches, None: General MIDI
        "hihat_cc4": bool(opts.midi.get("hihat_cc4", False)),  # --hihat-cc4: the pedal applied to the hats
        "control": opts.control,
        "sticking": opts.sticking.value,  # --sticking
        "limits_from": list(opts.limits_from),
        "skeleton_bvh": None if opts.skeleton_bvh is None else str(opts.skeleton_bvh),
        "skeleton_units": opts.skeleton_units,
        "physics": result.physics,
        "calibration": str(opts.calibration) if opts.calibration else None,
        # absolute: the report is read from elsewhere than the shell the render ran in
        "sound_params": str(Path(opts.sound_params).resolve()) if opts.sound_params else None,
        "notes": len(result.score.events),
        "planned_strokes": len(result.plan.strokes),
        "issues": issues_json(result.plan, result.score),
        "planner_issues": len(result.plan.issues),
        "unknown_notes": len(result.score.unknown),
        "duplicates": len(result.score.duplicates),
        "impacts": result.impacts_total,
        "contacts": result.contacts,
        "score_offset_s": result.score_offset_s,
        "latency_s": opts.latency_s,
        "wav_from": opts.wav_from,
        "score_time_0_wav_s": score_time_0_wav_s(result.score_offset_s, opts.latency_s),
        "score_beats": None if length is None else length[0],
        "score_bars": None if length is None else length[1],
        "duration_s": round(result.duration_s, 6),  # performance.wav's length
        "music_duration_s": music,
        "sample_rate_hz": result.sample_rate,
        "wall_time_s": round(wall, 3),
        "real_time_factor": round(result.duration_s / wall, 3) if wall > 0 else None,
        "cpu_time_s": result.physics.get("cpu_time_s"),
        "real_time_factor_cpu": round(result.duration_s / cpu, 3) if cpu else None,
    }


def _drum_channels_json(opts: RenderOptions) -> list[int] | None:
    """report.json's ``drum_channels``: the MIDI channels read as drums (``--drum-channels``), None: the reader's
    choice; ``batteur evaluate`` reads the score of a render directory with them."""
    channels = opts.midi.get("drum_channels")
    return None if channels is None else [int(c) for c in channels]


def write_outputs(output: Path, audio: np.ndarray, sample_rate: int, impacts: list[Any], report: dict[str, Any],
                  poses: Any = None, score: Path | None = None,
                  video: Callable[[Path], dict[str, Any]] | None = None, bvh_rate_hz: float | None = None,
                  units: Literal["m", "cm"] = "m", facing: Literal["+z", "-z"] = "+z") -> list[Path]:
    """Write every output into a staging directory, then move them into ``output`` (nothing partial).

    ``bvh_rate_hz``: the BVH's frame rate (physics' pose rate); None: the poses' median interval, which on the
    1 ms step grid is 17 ms for 60 Hz poses (58.8 frames a second, an odd rate for animation tools). ``units``: the
    BVH's length unit (``--bvh-units``: :data:`BVH_UNITS_PER_METRE`), as the streamed one's; ``facing``: which way
    the drummer faces in it (``--bvh-facing``: :data:`BVH_FACINGS`).

    ``score``: copied in as ``score<suffix>`` so the directory can be evaluated on its own.
    ``video``: called with the staging directory once the WAV is there; writes the video into it and returns
    what ``report["video"]`` lists.
    """
    with Staging(output) as staging:
        wav = staging.path / "performance.wav"
        fmt = wav_container(len(audio), 1 if audio.ndim == 1 else audio.shape[1])
        if fmt == "RF64":
            say_rf64(wav, len(audio), sample_rate)
        sf.write(wav, audio, sample_rate, subtype="PCM_24", format=fmt)
        write_impacts_csv(impacts, staging.path / "impacts.csv")
        write_rest(staging, report, poses, score, video, bvh_rate_hz, units=units, facing=facing)
        return staging.commit()


def write_rest(staging: Staging, report: dict[str, Any], poses: Any = None, score: Path | None = None,
               video: Callable[[Path], dict[str, Any]] | None = None, bvh_rate_hz: float | None = None,
               gltf: Callable[[Path], dict[str, Any]] | None = None,
               end_sites: dict[str, tuple[float, float, float]] | None = None,
               kit_copy: KitCopy | None = None, units: Literal["m", "cm"] = "m",
               facing: Literal["+z", "-z"] = "+z") -> None:
    """The outputs after the WAV and impacts.csv (see :func:`write_outputs`): the BVH of ``poses`` (kept in
    memory; its End Sites ``end_sites``, as :class:`StreamedOutputs`'; in ``units``, :data:`BVH_UNITS_PER_METRE`'s,
    as :class:`StreamedOutputs`' ``bvh_scale``: until 7 Dec always metres; facing ``facing``, as its
    ``bvh_facing``), the video, the glTF (``gltf``: as ``video``, listed as ``report["gltf"]``), the score's copy,
    the kit file's (``kit_copy``) and report.json."""
    if poses is not None:
        from services.graphics.export.bvh import write_bvh

        write_bvh(poses, staging.path / "performance.bvh", rate_hz=bvh_rate_hz, end_sites=end_sites,
                  scale=BVH_UNITS_PER_METRE[units], facing=facing)  # file units per metre
    if video is not None:
        report["video"] = video(staging.path)
    if gltf is not None:
        report["gltf"] = gltf(staging.path)
    if score is not None:
        shutil.copyfile(score, staging.path / f"score{score.suffix}")
    if kit_copy is not None:  # as it was read: the file may have been edited during the render
        (staging.path / kit_copy.name).write_bytes(kit_copy.data)
    (staging.path / "report.json").write_text(json.dumps(report, indent=2), encoding="utf-8")


def check_copies(output: Path, score: Path, kit_copy: KitCopy | None) -> None:
    """Raise :class:`RenderError` when the render would replace, with its copy of the score or the kit file, a file
    in ``output`` that no earlier render of it wrote (:func:`earlier_outputs`) and that holds something else: a
    user's own file is never overwritten (the copy of the kit file the render itself reads is the file again)."""
    earlier = earlier_outputs(output)
    copies = [(f"score{score.suffix}", score, "score")]
    if kit_copy is not None:
        copies.append((kit_copy.name, kit_copy.source, "kit file"))
    for name, source, what in copies:
        there = output / name
        if name in earlier or not there.is_file():
            continue
        try:
            if there.resolve() == source.resolve() or there.read_bytes() == source.read_bytes():
                continue
        except OSError:
            pass
        raise RenderError(f"-o: {there} is not a file an earlier render wrote there, and the render would replace it "
                          f"with its copy of the {what} {source}: move it, render into another folder, or give "
                          "--overwrite")


STRIKE_OUTPUTS = ("performance.wav", "impacts.csv", "report.json")
"""The files a strike-scene render writes into its folder."""


def score_outputs(opts: RenderOptions) -> list[str]:
    """The files a score render of ``opts`` writes into its folder, the copies of the score and kit file aside
    (:func:`check_copies`)."""
    return [*SCORE_OUTPUTS, *([VIDEO_OUTPUT] if opts.video else []), *([GLTF_OUTPUT] if opts.gltf else [])]


def check_outputs(output: Path, names: Sequence[str], overwrite: bool = False) -> None:
    """Raise :class:`RenderError` naming the files among ``names`` that exist in ``output`` and that no earlier
    render of it wrote (:func:`earlier_outputs`: a file of the user's, a cleaned-up performance.bvh), before anything
    is simulated: a render never replaces them (until 7 Dec only the score's and kit file's copies were checked, and
    a user's performance.bvh was replaced without a word). ``overwrite`` (``--overwrite``): replace them."""
    if overwrite:
        return
    earlier = earlier_outputs(output)
    theirs = [output / name for name in names
              if name not in earlier and ((output / name).exists() or (output / name).is_symlink())]
    if not theirs:
        return
    many = len(theirs) > 1
    them = "them" if many else "it"
    raise RenderError(f"-o: {', '.join(str(p) for p in theirs)} {'are not files' if many else 'is not a file'} an "
                      f"earlier render wrote there (no render's report.json there lists {them}), and the render would "
                      f"replace {them}: move {them}, render into another folder, or give --overwrite")


def earlier_outputs(output: Path) -> set[str]:
    """The files an earlier render wrote in ``output``, from its report.json (none without one).

    A new render removes those it does not write again: a stale score copy would be evaluated against the new
    impacts (``batteur evaluate DIR``), a stale video taken for this performance's. Only what that report
    names is touched, never other files in the folder, nor a 7 Dec render's kit copy ``kit.yaml`` (left in place).
    """
    try:
        report = json.loads((output / "report.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return set()
    if not isinstance(report, dict) or report.get("scene") not in ("drummer", "strike"):
        return set()  # a report.json of the user's, not a render's: it lists nothing a render wrote
    names = {"performance.wav", "impacts.csv", "report.json"}
    if report.get("scene") == "drummer":
        names.add("performance.bvh")
    for entry in (report.get("video"), report.get("gltf")):
        if isinstance(entry, dict) and isinstance(entry.get("file"), str):
            names.add(Path(entry["file"]).name)
    if isinstance(report.get("score"), str):
        names.add(f"score{Path(report['score']).suffix}")
    copy, source = report.get("kit_copy"), report.get("kit_file")
    # the copy's name now (KitCopy.name), never kit<suffix> (renders of 7 Dec): what that render wrote is not known
    # (no digest kept), and a user's own kit file, or that copy edited since, has that name
    if isinstance(copy, str) and Path(copy).name == copy and Path(copy).stem == "played-kit":
        if not (isinstance(source, str) and (output / copy).resolve() == Path(source).resolve()):
            names.add(copy)  # never the kit file itself, rendered beside
    return names


def render_score(path: Path | str, output: Path, opts: RenderOptions, quiet: bool = False,
                 prog: str = "batteur render", overwrite: bool = False,
                 said: Sequence[str] = ()) -> dict[str, Any]:
    """Render a score into ``output`` (see the module docstring); returns the report. ``prog`` names the command
    in its warning lines (``batteur demo`` renders through this). A file in ``output`` the render would replace and
    no earlier render of it wrote is refused before the simulation (:func:`check_outputs`, :func:`check_copies`),
    unless ``overwrite`` (``--overwrite``). ``said``: the warnings the command printed before (its options',
    :func:`options_in_vain`), first in report.json's ``warnings``.

    Raises :class:`ScoreError` (bad score), :class:`RenderError` (physics refused) or ``ValueError``.
    """
    from batteur.calibration import Calibration

    check_output_dir(output, "-o")  # before the long part, as the video's checks
    check_options(opts)
    check_outputs(output, score_outputs(opts), overwrite)  # before the planning too: a long score's takes minutes
    if opts.video:
        check_video(opts)  # before the long part: no ffmpeg, no render
    limbs = skeleton_limbs(opts)  # read once: the kit's warnings and the planner measure the same reach
    warned: list[str] = list(said)  # every warning said, kept for report.json's warnings, in order
    # its warnings name the drummer asked for, with the skeleton's reach when it has one (as the planner's)
    with kept_warnings(warned):
        kit = None if opts.kit is None else load_render_kit(path, opts, None, limbs)  # --kit: before the score
    kit_copy = KitCopy.of(opts.kit)  # the file as loaded: a designer may edit it during the render
    calibration = Calibration.load(opts.calibration) if opts.calibration else None
    planning = PlanningProgress(Path(path).name, quiet)
    try:
        read = None
        if kit is None:  # the score's `kit` line, else the default: read the score first
            read = read_scaled(path, opts, planning)
            planning.close()  # the reading's line ends before the kit's warnings
            with kept_warnings(warned):
                kit = load_render_kit(path, opts, read, limbs)
            kit_copy = KitCopy.of(opts.with_kit(score_kit(read)).kit)
        part: tuple[float, float] | None = None  # where the part (--bars) lies in the whole score, score seconds
        if opts.bars is not None:  # the part alone is planned and simulated
            if read is None:
                read = read_scaled(path, opts, planning, kit)
            read, part_start, part_end = bar_part(read, opts.bars, Path(path).name)
            part = (part_start, part_end)
        with kept_warnings(warned):
            score, assignment, plan = prepare(path, kit, opts, calibration, planning, limbs, read)
    except BaseException:  # a bad score or Ctrl-C: the line ends where it stood, not at 100 %
        planning.close(finished=False)
        raise
    planning.close()
    if not overwrite:
        check_copies(output, Path(path), kit_copy)  # the score's kit known, before the long part
    read_render_sound_params(opts.sound_params, kit)  # the score's kit known, before the long part
    opts = opts.styled(score)  # physics' hands hold the grip the score asked for, as planned
    # the reader's (e.g. a MIDI file without a drum channel, read as drums), then hands the plan has no units for
    for warning in [*score.warnings, *filter(None, [grip_warning(opts.grip)])]:
        warned.append(warning)
        print(f"{prog}: warning: {warning}", file=sys.stderr)
    progress = Progress(f"rendering {Path(path).name}", rendered_seconds(plan, opts), enabled=False if quiet else None)
    finished = False  # a render given up (Ctrl-C, an error) leaves its bar where it stood, not at 100 %
    offset = opts.settle_s - plan.start_time  # rig time of score time 0, as run_score's
    wav_cut_s = score_time_0_wav_s(offset, opts.latency_s) if opts.wav_from == "score" else 0.0
    with Staging(output) as staging:  # the WAV, impacts and motion are written as they are rendered
        outputs = StreamedOutputs(staging.path, opts.pose_rate_hz or None, keep=opts.video or opts.gltf,
                                  planned_s=rendered_seconds(plan, opts), prog=prog,
                                  bvh_start_s=wav_frame_start(opts, offset) if opts.bvh_sync == "wav" else None,
                                  end_sites=body_end_sites(opts), wav_cut_s=wav_cut_s,
                                  bvh_scale=BVH_UNITS_PER_METRE[opts.bvh_units], warnings=warned,
                                  bvh_facing=opts.bvh_facing)
        try:
            with kept_warnings(warned):  # the cores' warnings (physics' joint limits, sound's latency)
                if opts.jobs > 1:
                    from batteur.segments import run_segmented

                    result = run_segmented(score, assignment, plan, kit, opts, opts.jobs, segment_s=opts.segment_s,
                                           on_progress=lambda t, total: progress.update(t), outputs=outputs)
                else:
                    with DeferredCtrlC() as ctrl_c:  # acted on between steps: in a numba kernel it became an error

                        def on_progress(t: float, total: float) -> None:
                            ctrl_c.check()
                            progress.update(t)

                        result = run_score(score, assignment, plan, kit, opts, on_progress=on_progress,
                                           outputs=outputs)
            finished = True
        finally:
            progress.close(finished)
            outputs.close()
        report = score_report(result, str(path), opts, warned, kit_copy)
        report["warnings"] = warned  # the same list: a warning said later (the WAV's cut, the video's) is in it too
        report["bars"] = None if opts.bars is None or part is None else part_json(opts.bars, *part)
        wav_cut = 0
        if opts.wav_from == "score":  # checked before the video and glTF are made: a refusal wastes no more
            wav_cut = round(wav_cut_s * result.sample_rate)
            wav = staging.path / "performance.wav"
            impacts = result.impacts if result.impact_count is None else read_staged_impacts(staging.path)
            cut_warning = check_wav_from_score(impacts, result.score_offset_s, wav_cut, result.sample_rate,
                                               first_sound(wav, wav_cut))
            if cut_warning is not None:
                print(f"{prog}: warning: {cut_warning}", file=sys.stderr)
                warned.append(cut_warning)
            written = round(result.duration_s - wav_cut / result.sample_rate, 6)  # the WAV as shifted below
            # duration_s is performance.wav's length (docs/render.md), not the render's timeline: until 7 Dec it
            # was the uncut WAV's here; wav_duration_s, the same number, kept for readers of earlier reports
            report.update(score_time_0_wav_s=0.0, wav_cut_s=round(wav_cut / result.sample_rate, 6),
                          duration_s=written, wav_duration_s=written)
        if outputs.bvh is not None and outputs.bvh_frames is not None:
            report["bvh"] = bvh_entry(outputs.bvh, outputs.bvh_frames, opts, wav_cut_s)
        video = None
        if opts.video:
            if result.poses is None:
                raise RenderError("--video: physics sent no poses to draw")
            video = video_writer(result, kit, opts, quiet)
        gltf = None
        if opts.gltf:
            if result.poses is None:
                raise RenderError("--gltf: physics sent no poses to export")
            gltf = gltf_writer(result, kit, opts, quiet)
        if wav_cut:  # before the video, which muxes the WAV written (until 7 Dec the uncut one, 1.5 s longer)
            shift_wav(staging.path / "performance.wav", wav_cut, prog)
        kept_poses = result.poses if outputs.bvh is None else None  # else the BVH is written already
        with kept_warnings(warned):  # the video's and glTF's, before report.json is written
            write_rest(staging, report, kept_poses, Path(path), video, bvh_rate_hz=opts.pose_rate_hz or None,
                       gltf=gltf, end_sites=outputs.end_sites, kit_copy=kit_copy, units=opts.bvh_units,
                       facing=opts.bvh_facing)
        staging.commit()
    return report


def read_staged_impacts(folder: Path) -> list[Any]:
    """The impacts streamed into ``folder``'s impacts.csv (rig times), for :func:`check_wav_from_score`."""
    from batteur.impact_log import read_impacts_csv

    return list(read_impacts_csv(folder / "impacts.csv"))


def check_options(opts: RenderOptions) -> None:
    """Raise ``ValueError`` naming the option for a value the render would refuse late: after the simulation
    (the sound's latency in a segmented render), in a worker process, or by running out of memory."""
    from services.physics.core import PhysicsSettings

    low, high = TEMPO_SCALE_RANGE
    if not low <= opts.tempo_scale <= high:  # NaN fails too
        raise UsageError(f"--tempo-scale {opts.tempo_scale:g}: {low:g} to {high:g} (times faster)")
    for option, value, (low, high), unit in (("--height", opts.height_m, HEIGHT_RANGE_M, "m"),
                                             ("--mass", opts.mass_kg, MASS_RANGE_KG, "kg"),
                                             ("--bvh-rate", opts.pose_rate_hz, BVH_RATE_RANGE, "Hz")):
        if not low <= value <= high:  # NaN fails too
            raise UsageError(f"{option} {value:g}: {low:g} to {high:g} {unit}")
    if not (math.isfinite(opts.segment_s) and opts.segment_s >= MIN_SEGMENT_S):
        raise UsageError(f"--segment {opts.segment_s:g}: a length of at least {MIN_SEGMENT_S:g} s (each segment "
                         f"also plays a lead-in, so shorter ones cost more than they share)")
    check_latency(opts.latency_s)
    _check_motion_capture(opts)
    if opts.control_rate_hz is not None:
        low, _ = field_bounds(PhysicsSettings, "control_rate_hz")
        if not low <= opts.control_rate_hz <= opts.rate_hz:  # NaN fails too; faster than a step does nothing
            raise UsageError(f"--control-rate {opts.control_rate_hz:g}: {_nan_words(opts.control_rate_hz)}{low:g} to "
                             f"{opts.rate_hz:g} Hz (physics steps at {opts.rate_hz:g} Hz: the control is updated at "
                             "most once a step)")


def _nan_words(value: float) -> str:
    """``must be a finite number, `` before a range a NaN was refused by (no range takes it), else ''."""
    return "must be a finite number, " if math.isnan(value) else ""


def field_bounds(model: Any, name: str) -> tuple[float, float]:
    """The inclusive bounds (``ge``, ``le``) of the pydantic field ``name`` of ``model``: a range said as the
    other options' are (``--height 1.1: 1.2 to 2.2 m``), from where it is enforced."""
    low, high = -math.inf, math.inf
    for bound in model.model_fields[name].metadata:
        low = float(getattr(bound, "ge", low))
        high = float(getattr(bound, "le", high))
    return low, high


def check_latency(latency_s: float) -> None:
    """Raise :class:`UsageError` for a ``--latency`` (seconds) the sound service refuses (a score render and the
    strike scene alike)."""
    from services.sound.core import SoundSettings

    low, high = field_bounds(SoundSettings, "latency")
    if not low <= latency_s <= high:  # NaN fails too
        raise UsageError(f"--latency {latency_s:g}: {_nan_words(latency_s)}{low:g} to {high:g} s")


def _check_motion_capture(opts: RenderOptions) -> None:
    """Read the clips and skeleton the drummer is built from now (``ValueError`` naming the option): a bad file
    must not wait for the score's planning, and the limits are cached for the render."""
    from services.physics.bvh_motion import usable_segment_lengths
    from services.physics.drummer import cached_clips

    try:
        cached_clips(opts.limits_from)
    except (ValueError, FileNotFoundError) as exc:
        raise ValueError(f"--limits-from: {exc}") from None
    if opts.skeleton_bvh is not None:
        try:  # no joint found by name, proportions no body can have: the physics node refuses them alike
            usable_segment_lengths(opts.skeleton_bvh, opts.skeleton_units)
        except (ValueError, OSError) as exc:
            raise ValueError(f"--skeleton-bvh: {exc}") from None


def skeleton_limbs(opts: RenderOptions) -> LimbLengths | None:
    """The arm and leg of the body physics builds from ``opts.skeleton_bvh``, metres, for the planner's reach
    (None without one: the height's; ``services.physics.bvh_motion.skeleton_limb_lengths``)."""
    if opts.skeleton_bvh is None:
        return None
    from services.physics.bvh_motion import skeleton_limb_lengths

    return skeleton_limb_lengths(opts.skeleton_bvh, opts.height_m, opts.mass_kg, opts.skeleton_units)


def body_end_sites(opts: RenderOptions) -> dict[str, tuple[float, float, float]]:
    """The End Sites of performance.bvh: where physics puts the tips of the body it builds for ``opts`` (its
    ``--height``, ``--mass`` and ``--skeleton-bvh``), link -> offset in the link's frame (metres, z up): a stick's
    bead centre (``<side>_stick_tip``) and a foot's ball (``<side>_foot_ball``, which follows the height, not a
    skeleton's shank: the BVH writer's guess from the snapshot scaled it with the shank, 3 cm off for 0.52 m
    shanks). The body is generated as the drummer scene generates it (:func:`performer_anthropometry`), without a
    simulation."""
    from services.physics.anthropometry import performer_anthropometry
    from services.physics.character import CharacterSpec, build_character

    skeleton = None if opts.skeleton_bvh is None else str(opts.skeleton_bvh)
    model = build_character(CharacterSpec(performer_anthropometry(opts.height_m, opts.mass_kg, skeleton,
                                                                  opts.skeleton_units)))
    fixed = {joint.child: joint for part in model.parts for joint in part.robot.joints if joint.kind == "fixed"}
    sites: dict[str, tuple[float, float, float]] = {}
    for tip in model.tips.values():  # the tips hang on fixed joints from their link (stick, foot)
        x, y, z = fixed[tip].xyz
        sites[fixed[tip].parent] = (float(x), float(y), float(z))
    return sites


def check_video(opts: RenderOptions) -> None:
    """Raise ``FileNotFoundError`` (no ffmpeg) or ``ValueError`` (frame size, rate) before rendering."""
    from services.graphics import video

    width, height = opts.video_size
    if width % 2 or height % 2 or not (16 <= width <= 7680 and 16 <= height <= 4320):
        raise UsageError(f"--video-size {width}x{height}: even numbers, 16x16 to 7680x4320")
    if not 1 <= opts.video_fps <= 240:
        raise UsageError(f"--video-fps {opts.video_fps:g}: 1 to 240 frames per second")
    video.find_ffmpeg()


def video_writer(result: ScoreRender, kit: Kit, opts: RenderOptions, quiet: bool) -> Callable[[Path], dict[str, Any]]:
    """What writes DIR/performance.mp4 in the staging directory (the WAV already there, as written: with
    ``--wav-from score`` cut at score time 0), with a progress bar: on performance.wav's clock, its frame 0 at the
    WAV's time 0 (:func:`wav_frame_start`), the WAV muxed in."""
    from services.graphics import video

    def write(staging: Path) -> dict[str, Any]:
        started = time.perf_counter()
        width, height = opts.video_size
        # render_video's audio_start is the WAV's sample 0 as heard (a strike at rig time t is heard at t + latency):
        # rig time 0 for the render's WAV, score time 0 heard (score_offset_s + latency) for --wav-from score's
        audio_start = wav_frame_start(opts, result.score_offset_s) + opts.latency_s
        progress = Progress("video", 1.0, unit="frames", decimals=0, enabled=False if quiet else None)

        def on_progress(done: int, total: int) -> None:
            progress.total = total
            progress.update(done)

        finished = False
        try:
            info = video.render_video(result.poses, result.impacts, staging / "performance.wav", staging, kit=kit,
                                      fps=opts.video_fps, width=width, height=height, audio_start=audio_start,
                                      latency=opts.latency_s, on_progress=on_progress)
            finished = True
        except (RuntimeError, OSError) as exc:  # ffmpeg failed or died: nothing is written (staging)
            raise RenderError(f"--video: {exc}") from exc
        finally:
            progress.close(finished)
        return {"file": info.path.name, "frames": info.frames, "fps": info.fps, "duration_s": info.duration,
                "width": info.width, "height": info.height, "audio": "performance.wav (AAC)",
                "start_s": round(audio_start - opts.latency_s, 6),  # rig time frame 0 shows
                "wall_time_s": round(time.perf_counter() - started, 3)}

    return write


def bvh_entry(bvh: BvhStream, frames: int, opts: RenderOptions, wav_cut_s: float = 0.0) -> dict[str, Any]:
    """report.json's ``bvh``: the file's frames and where its frame 0 falls in performance.wav (seconds, and
    frames at its rate: how far to shift it in an animation tool to line it up with the WAV); ``wav_cut_s``: the
    seconds ``--wav-from score`` cut from the WAV's start (negative: silence added)."""
    start = bvh.start_time if bvh.start_time is not None else 0.0
    wav_time = start + opts.latency_s - wav_cut_s
    return {"file": "performance.bvh", "frames": frames, "rate_hz": opts.pose_rate_hz, "sync": opts.bvh_sync,
            "units": opts.bvh_units, "facing": opts.bvh_facing,
            "start_s": round(start, 6), "wav_time_s": round(wav_time, 6),
            "wav_offset_frames": round(wav_time * opts.pose_rate_hz, 3)}


def wav_frame_start(opts: RenderOptions, score_offset_s: float) -> float:
    """Rig time (seconds) of a motion file's frame 0 on performance.wav's clock: the WAV's time 0, as each impact
    is heard at its rig time + ``latency_s`` (``--wav-from score``: the rig time of score time 0,
    ``score_offset_s``, heard at the WAV's time 0); frames before the first pose hold it."""
    return score_offset_s if opts.wav_from == "score" else -opts.latency_s


EARLY_IMPACT_S = 0.025
"""How long before score time 0 (seconds) an impact may be heard for ``--wav-from score`` to trim the WAV there
anyway (evaluate's wider window): a note on bar 1's first beat played that little early (the drummer's first impact
is typically 1 ms early), the first milliseconds of its sound cut, said in a warning. An earlier impact would be
lost from the WAV: the render is refused."""


def score_time_0_wav_s(score_offset_s: float, latency_s: float) -> float:
    """Where score time 0 (bar 1, beat 1) is heard in the render's performance.wav, seconds (negative: before its
    start, a score opening with empty bars): its rig time ``score_offset_s`` plus the sound's ``latency_s``."""
    return round(score_offset_s + latency_s, 6)


def bar_one_line(wav_s: float, wav: str = "performance.wav", bar: int = 1) -> str:
    """Where score time 0 (the start of ``bar``: bar 1, or the first of ``--bars``) falls in ``wav`` (``wav_s``,
    seconds; negative: before its start), for a DAW user."""
    if wav_s < 0:
        return f"score time 0 (bar {bar}, beat 1) is {-wav_s:.3f} s before the start of {wav}"
    return f"score time 0 (bar {bar}, beat 1) is at {wav_s:.3f} s in {wav}"


def early_impacts(impacts: Sequence[Any], score_offset_s: float) -> list[Any]:
    """The impacts (rig ``time``, seconds) struck before score time 0 (rig time ``score_offset_s``), earliest
    first: what ``--wav-from score`` trims (a little early, :data:`EARLY_IMPACT_S`) or would lose."""
    return sorted((i for i in impacts if i.time < score_offset_s), key=lambda i: i.time)


def check_wav_from_score(impacts: Sequence[Any], score_offset_s: float, wav_frames_cut: int, sample_rate: int,
                         first_sound_frame: int | None) -> str | None:
    """``--wav-from score``'s check of a finished render: raise :class:`RenderError` when an impact struck more than
    :data:`EARLY_IMPACT_S` before score time 0 (a pick-up, a stroke before bar 1) would be cut from the WAV; else a
    warning when the WAV's sound starts before the cut (``first_sound_frame``, the first non-silent sample of the
    render's WAV, ``wav_frames_cut`` the samples cut), None when only silence is cut."""
    early = early_impacts(impacts, score_offset_s)
    lost = [i for i in early if score_offset_s - i.time > EARLY_IMPACT_S]
    if lost:
        first = lost[0]
        raise RenderError(f"--wav-from score: {len(lost)} impact{'s' if len(lost) > 1 else ''} struck before score "
                          f"time 0 (bar 1, beat 1) would be cut from performance.wav (the first on {first.instrument}"
                          f" {score_offset_s - first.time:.3f} s before it); render without --wav-from score: "
                          "report.json's score_time_0_wav_s says where bar 1 is in the WAV")
    if first_sound_frame is None or first_sound_frame >= wav_frames_cut:
        return None
    cut_ms = (wav_frames_cut - first_sound_frame) / sample_rate * 1000
    if early:
        return (f"--wav-from score: the first impact ({early[0].instrument}) is struck "
                f"{(score_offset_s - early[0].time) * 1000:.1f} ms before score time 0; the first {cut_ms:.1f} ms of "
                "its sound are cut from performance.wav")
    return f"--wav-from score: {cut_ms:.1f} ms of sound before score time 0 are cut from performance.wav"


def first_sound(path: Path, frames: int) -> int | None:
    """The first sample (per channel) of the audio file ``path`` that is not silent among its first ``frames``,
    None if they all are."""
    with sf.SoundFile(path) as wav:
        read = 0
        while read < frames:
            block = wav.read(min(frames - read, 1 << 16), dtype="int32", always_2d=True)
            if not len(block):
                return None
            loud = np.flatnonzero(np.any(block != 0, axis=1))
            if len(loud):
                return read + int(loud[0])
            read += len(block)
    return None


def shift_wav(path: Path, frames: int, prog: str = "batteur render") -> int:
    """Rewrite the WAV ``path`` so that its sample 0 is its sample ``frames`` (negative: ``-frames`` samples of
    silence added before it), the samples themselves unchanged (24-bit PCM read and written as integers; RF64
    when the result needs it, :func:`wav_container`); copied in blocks, so an hour's WAV is not held in memory.
    Returns the new length in samples."""
    block = 1 << 16
    shifted = path.with_name(f".{path.name}.shifted")
    with sf.SoundFile(path) as source:
        total = max(source.frames - frames, 0)
        fmt = wav_container(total, source.channels)
        if fmt == "RF64":
            say_rf64(path, total, source.samplerate, prog)
        with sf.SoundFile(shifted, "w", source.samplerate, source.channels, subtype=source.subtype,
                          format=fmt) as target:
            silence = max(-frames, 0)
            while silence > 0:
                n = min(silence, block)
                target.write(np.zeros((n, source.channels), dtype=np.int32))
                silence -= n
            if frames < source.frames:
                source.seek(max(frames, 0))
                while True:
                    data = source.read(block, dtype="int32", always_2d=True)
                    if not len(data):
                        break
                    target.write(data)
    shifted.replace(path)
    return total


def gltf_writer(result: ScoreRender, kit: Kit, opts: RenderOptions, quiet: bool) -> Callable[[Path], dict[str, Any]]:
    """What writes DIR/performance.glb in the staging directory, with a progress bar: the kept poses resampled at
    the BVH's rate on performance.wav's clock (:func:`wav_frame_start`) and the kit, moved by its kit links."""
    from services.graphics.export.gltf import write_gltf

    def write(staging: Path) -> dict[str, Any]:
        started = time.perf_counter()
        start = wav_frame_start(opts, result.score_offset_s)
        cut_s = score_time_0_wav_s(result.score_offset_s, opts.latency_s) if opts.wav_from == "score" else 0.0
        end = start + (result.duration_s - cut_s)  # the WAV's end; the poses' last 50 ms (at rest) are after it
        times = result.poses.resample_times(opts.pose_rate_hz, start=start, end=end)
        progress = Progress("glTF", len(times), unit="frames", decimals=0, enabled=False if quiet else None)
        finished = False
        try:
            frames = result.poses.resample(opts.pose_rate_hz, start=start, end=end, on_progress=progress.update)
            info = write_gltf(frames, staging / "performance.glb", kit=kit, time_origin=start,
                              impacts=[(impact.time, impact.instrument) for impact in result.impacts],
                              end_sites=body_end_sites(opts))  # the BVH's: the sticks' tip joints, the feet's boxes
            finished = True
        except (OSError, ValueError) as exc:  # a full disk: nothing is written (staging)
            raise RenderError(f"--gltf: {exc}") from exc
        finally:
            progress.close(finished)
        return {"file": "performance.glb", "frames": info.keyframes, "rate_hz": opts.pose_rate_hz,
                "time_0": ("performance.wav's time 0: a pose at rig time t is keyed at t + latency_s"
                           if opts.wav_from == "render" else
                           "performance.wav's time 0 (--wav-from score: score time 0): a pose at rig time t is "
                           "keyed at t - score_offset_s"),
                "start_s": round(float(times[0]), 6), "duration_s": round(info.duration, 6),
                "links": info.links, "kit_objects": info.kit_objects,
                "animated_kit_objects": info.animated_kit_objects,
                "wall_time_s": round(time.perf_counter() - started, 3)}

    return write


# ---------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    from services.physics.anthropometry import SKELETON_UNITS  # de Leva's table: no scipy, no PyBullet

    parser = argparse.ArgumentParser(
        prog="batteur render",
        description="Render a score offline through the same cores as the rig (planner -> physics drummer -> "
        "interaction -> sound). Writes DIR/performance.wav, DIR/impacts.csv, DIR/performance.bvh, "
        "DIR/report.json and a copy of the score as DIR/score.<ext> (its own extension: score.mid, score.txt; "
        "what `batteur evaluate DIR` judges the render against); nothing is written if the run fails. Without "
        "SCORE, --strikes renders the strike scene.",
    )
    take_negative_values(parser)
    parser.add_argument("score", nargs="?", type=Path,
                        help="a Standard MIDI File (.mid, .midi, .smf, .rmi, or any file with a MIDI header) or a "
                        "Batteur text score (docs/score-format.md)")
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="DIR",
                        help="output directory (created if missing)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace files in DIR that no earlier render wrote there (a performance.bvh, "
                        "report.json, score.txt ... of your own); without it the render refuses before simulating, "
                        "naming them (a folder an earlier render made is re-rendered into without it)")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    playing = parser.add_argument_group("the performance")
    add_performance_options(playing, kit_default=None)
    add_midi_arguments(playing)
    playing.add_argument("--bars", default=None, metavar="A-B",
                         help="render only bars A to B of the score (or bar A alone: --bars A), counted as `python -m "
                         "common.score SCORE` counts them (from 1; a pick-up is bar 0): their notes, on the score's "
                         "clock shifted so that bar A starts at score time 0, after the usual settle and 1 s lead-in; "
                         "report.json's bars says the part (default: the whole score)")
    playing.add_argument("--algorithm", default=HandAlgorithm.VITERBI.value,
                         choices=[a.value for a in HandAlgorithm], help="hand assignment algorithm (default: viterbi)")
    playing.add_argument("--calibration", type=Path, default=None, metavar="FILE",
                         help="calibration JSON (from `batteur evaluate --fit-calibration`): lag anticipation and "
                         "velocity map applied to the plan (default: none)")
    playing.add_argument("--latency", type=float, default=0.05, metavar="SECONDS",
                         help="sound latency window, seconds (default 0.05)")
    playing.add_argument("--sound-params", type=Path, default=None, metavar="FILE",
                         help="the instruments' sound parameters (what batteur sound --sound-params-out writes: "
                         "per instrument, what the /batteur/sound/... controls set; docs/sound.md)")
    playing.add_argument("--control-rate", "--control-rate-hz", dest="control_rate", type=float, default=None,
                         metavar="HZ",  # the second spelling: batteur physics's, so a flag copied from it works
                         help="drummer's full control updates (IK, inverse dynamics) per second; the torques are "
                         "corrected at every 1 ms physics step between (default: physics' default, 1000: every "
                         "step)")
    body = parser.add_argument_group("the drummer's body")
    body.add_argument("--limits-from", action="append", default=[], metavar="CLIP",
                      help="motion clip the drummer's joint limits are estimated from (repeatable): a BVH file, a "
                      "DeepMimic clip file or the name of one of pybullet's DeepMimic clips (default: all of "
                      "those); each left/right pair's limits are made mirror-symmetric, their common range, as the "
                      "default ones (--asymmetric-limits keeps each side's own)")
    body.add_argument("--asymmetric-limits", action="store_true",
                      help="with --limits-from: keep each side's own joint limits as the clips give them, for a "
                      "performer with a real asymmetry (one side that truly reaches further); by default a side "
                      "the clips happen to let reach further is cut to the other's range, since the drummer's "
                      "posture drifts toward a wider bound under fast strokes (docs/physics.md, \"Symmetric "
                      "limits\"); report.json's physics.joint_limits_symmetric says which was used")
    body.add_argument("--skeleton-bvh", type=Path, default=None, metavar="FILE",
                      help="BVH file whose skeleton gives the drummer's proportions (arms, legs, neck, shoulder "
                      "height above the hips, shoulder and hip widths), so the simulated performer matches the "
                      "captured one (default: de Leva's table for --height and --mass)")
    body.add_argument("--skeleton-units", choices=SKELETON_UNITS, default="auto",
                      help="length unit of the --skeleton-bvh file (a BVH does not say it): auto (the default) "
                      "guesses it, the unit in which its lengths are a 1.2 to 2.2 m performer's; m, cm, mm or in "
                      "takes the file as that (a child-sized or stylised character, which a guess would read in "
                      "another unit: a 0.68 m one in centimetres is a 1.74 m one in inches), a stature outside "
                      "1.2 to 2.2 m then warned of, not refused")
    add_body_options(body, skeleton=True)
    outputs = parser.add_argument_group("motion, glTF and video outputs")
    outputs.add_argument("--bvh-rate", type=float, default=RenderOptions.pose_rate_hz, metavar="HZ",
                         help="frame rate of DIR/performance.bvh, 1 to 1000 Hz (e.g. 24, 30, 60, 120; default 60); "
                         "the video keeps its own --video-fps")
    outputs.add_argument("--bvh-units", choices=list(BVH_UNITS_PER_METRE), default="m",
                         help="length unit of DIR/performance.bvh: m (default; Blender) or cm (Maya, MotionBuilder)")
    outputs.add_argument("--bvh-facing", choices=list(BVH_FACINGS), default="+z",
                         help="which way the drummer faces in DIR/performance.bvh (y up): +z (default), as in "
                         "DIR/performance.glb and CMU's and Mixamo's clips, his left at +x; or -z, the files "
                         "before 8 Dec (a half turn about y from +z); write --bvh-facing=-z or --bvh-facing -z")
    outputs.add_argument("--bvh-sync", choices=["pose", "wav"], default=None,
                         help="frame 0 of DIR/performance.bvh: wav (the default), DIR/performance.wav's time 0 "
                         "(with --wav-from score, score time 0), the first pose held until it comes, so the BVH, the "
                         "WAV, the glTF and the video imported at frame 0 line up (each strike where it is heard); "
                         "or pose, the first pose (rig time 1 ms, 0.051 s into the WAV: 3 frames early at 60 Hz; "
                         "the file before 7 Dec)")
    outputs.add_argument("--wav-from", choices=["render", "score"], default=None,
                         help="sample 0 of DIR/performance.wav: render, the render's start (the drummer settles "
                         "before its lead-in; the default: where score time 0, bar 1, falls in it is printed and "
                         "in report.json's score_time_0_wav_s), or score, score time 0 (bar 1, beat 1) as heard, "
                         "the silence before trimmed (or added, for a score opening with empty bars), so the WAV "
                         "imported at a DAW's bar 1 lines up with the MIDI file; refused when a stroke before "
                         "bar 1 would be cut. impacts.csv keeps rig times")
    outputs.add_argument("--gltf", action="store_true",
                         help="also write DIR/performance.glb: the motion and the kit (cymbals swing, hi-hat and "
                         "pedals move) as one animated glTF 2.0 file at --bvh-rate, for Blender and other "
                         "animation tools (score mode). The poses are kept in memory for it: about 8 MB a minute "
                         "of music at 60 Hz (0.5 GB an hour), and about 19 MB a minute more while the file is "
                         "written; both grow with --bvh-rate")
    outputs.add_argument("--video", action="store_true",
                         help="also write DIR/performance.mp4: the motion rendered headless (PyBullet "
                         "TinyRenderer) with the WAV muxed in sync (needs ffmpeg; score mode)")
    outputs.add_argument("--video-size", type=_size, metavar="WxH", help="video WIDTHxHEIGHT (default 640x360)")
    outputs.add_argument("--video-fps", type=float, metavar="FPS", help="video frame rate, Hz (default 30)")
    strikes = parser.add_argument_group("the strike scene (instead of a SCORE)")
    strikes.add_argument("--strikes", default=None, metavar="TIME:SPEED,...",
                         help="strike scene instead of a score: TIME:SPEED,... in seconds:m/s "
                         f"(e.g. {','.join(f'{t:g}:{v:g}' for t, v in DEFAULT_STRIKES)})")
    strikes.add_argument("--event", "--strike-event", dest="event", default=None,
                         choices=[e.value for e in EventType if e != EventType.HIHATPEDAL],
                         help=f"strike scene: which kit event the stick strikes (default {DEFAULT_STRIKE_EVENT})")
    jobs = parser.add_argument_group("processes")
    jobs.add_argument("--jobs", type=int, default=1, metavar="N",
                      help="render on N processes (0: one per CPU): the piece is cut into segments of "
                      "--segment seconds, each played by its own drummer from a 3 s lead-in; faster, and the "
                      "same for any N > 1, but not identical to a one-process render (default 1)")
    jobs.add_argument("--segment", type=float, metavar="SECONDS",
                      help="segment length with --jobs above 1, seconds (default 30)")
    return parser


def add_performance_options(parser: argparse._ActionsContainer, kit_default: str | None = DEFAULT_KIT) -> None:
    """``--kit``, ``--grip``, ``--nuance``, ``--sticking``, ``--tempo-scale`` and ``--control`` (render and evaluate;
    a parser or one of its groups). ``kit_default`` None: a score's ``kit`` line, else :data:`DEFAULT_KIT`."""
    from common.kit_help import kit_help

    default = (f"the score's `kit` line, else {DEFAULT_KIT}" if kit_default is None else kit_default)
    parser.add_argument("--kit", default=kit_default, metavar="NAME", help=kit_help(default))
    add_style_options(parser)
    parser.add_argument("--sticking", default=Sticking.NONE.value, choices=[s.value for s in Sticking],
                        help="sticking of rolls (four or more single notes on one drum less than twice its "
                        "minTimeGap apart), led by the drum's preferred hand: single (RLRL), double (RRLL), "
                        "paradiddle (RLRR LRLL), or none: the hand assignment's choice (default; it alternates "
                        "hands on a drum's notes 100 ms apart or closer when the other hand is free)")
    parser.add_argument("--tempo-scale", type=float, default=1.0, metavar="X",
                        help="play this many times faster, 0.1 to 10 (0.5: half tempo; default 1)")
    parser.add_argument("--control", default="cartesian", choices=list(CONTROL_MODES),
                        help="how the drummer tracks the plan: cartesian (damped least-squares IK on the stick "
                        "tips every step, feeding the computed-torque PD; the default), joint (= joint_pd: explicit "
                        "PD on joint targets from open-loop IK of the plan), or a physics controller by name: "
                        "joint_spd (stable PD on joint targets), joint_ct (PD through inverse dynamics: computed "
                        "torque), cartesian_pd (the same IK feeding the explicit PD)")


def add_style_options(parser: argparse._ActionsContainer) -> None:
    """``--grip`` and ``--nuance`` (render and evaluate): None when not given, so a score's own wins then."""
    parser.add_argument("--grip", default=None, choices=GRIPS,
                        help=f"stick grip (default: the score's `grip` directive, else {DEFAULT_GRIP})")
    parser.add_argument("--nuance", default=None, choices=[n.value for n in Nuance],
                        help=f"global playing nuance (default: the score's `nuance` directive, else "
                        f"{DEFAULT_NUANCE.value})")


def add_body_options(parser: argparse._ActionsContainer, skeleton: bool = False) -> None:
    """``--height`` and ``--mass`` (render and evaluate; a parser or one of its groups); ``skeleton``: the parser
    has ``--skeleton-bvh`` (render), which the help then says how it goes with (evaluate's named it, without it)."""
    with_skeleton = "; with --skeleton-bvh the skeleton gives the limbs and the reach, the height the rest"
    # the second spellings are batteur physics's (--height-m, --mass-kg): a flag copied from it works here too;
    # --height's default None: an explicit 1.75 is told
    parser.add_argument("--height", "--height-m", dest="height", type=float, default=None, metavar="METRES",
                        help=f"the drummer's height, {HEIGHT_RANGE_M[0]:g} to {HEIGHT_RANGE_M[1]:g} m: its body "
                        f"(de Leva's segments scaled) and the planner's reach (default {STATURE_M:g}"
                        f"{with_skeleton if skeleton else ''})")
    parser.add_argument("--mass", "--mass-kg", dest="mass", type=float, default=DEFAULT_MASS_KG, metavar="KG",
                        help=f"the drummer's mass, {MASS_RANGE_KG[0]:g} to {MASS_RANGE_KG[1]:g} kg (default "
                        f"{DEFAULT_MASS_KG:g})")


def height_of(args: argparse.Namespace) -> float:
    """``--height`` in metres, :data:`STATURE_M` when not given (None: so that one given beside ``--skeleton-bvh``
    or ``--strikes`` can be told, the default's value too)."""
    return _given(args.height, STATURE_M)


def style_from(args: argparse.Namespace) -> tuple[str | None, Nuance | None]:
    """``--grip`` and ``--nuance`` as given (None: not given)."""
    return args.grip, None if args.nuance is None else Nuance(args.nuance)


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected WIDTHxHEIGHT, e.g. 640x360") from None
    return width, height


def options_from(args: argparse.Namespace) -> RenderOptions:
    grip, nuance = style_from(args)
    return RenderOptions(kit=args.kit, grip=grip, nuance=nuance, tempo_scale=args.tempo_scale,
                         control=args.control, algorithm=HandAlgorithm(args.algorithm),
                         sticking=Sticking(args.sticking), latency_s=args.latency,
                         calibration=args.calibration, sound_params=args.sound_params, video=args.video,
                         video_fps=_given(args.video_fps, 30.0),
                         gltf=args.gltf,
                         video_size=_given(args.video_size, (640, 360)), control_rate_hz=args.control_rate,
                         jobs=resolve_jobs(args.jobs), segment_s=_given(args.segment, 30.0),
                         limits_from=tuple(args.limits_from), asymmetric_limits=args.asymmetric_limits,
                         skeleton_bvh=args.skeleton_bvh, skeleton_units=args.skeleton_units,
                         height_m=height_of(args), mass_kg=args.mass, pose_rate_hz=args.bvh_rate,
                         bvh_units=args.bvh_units, bvh_facing=args.bvh_facing,
                         bvh_sync=_given(args.bvh_sync, RenderOptions.bvh_sync), midi=midi_read_kwargs(args),
                         wav_from=_given(args.wav_from, "render"),
                         bars=None if args.bars is None else parse_bars(args.bars))  # UsageError: one line, exit 2


T = TypeVar("T")


def _given(value: T | None, default: T) -> T:
    """An option's value, or its default when not given (None: so that an option given in vain can be told)."""
    return default if value is None else value


def skeleton_warnings(skeleton: Path, height_m: float | None, units: SkeletonUnits = "auto") -> list[str]:
    """What ``--skeleton-bvh`` with (or without: None) ``--height`` leaves to the height, said at the render's
    start, with the unit the skeleton is read in (``units``: ``--skeleton-units``) and the height of a performer of
    its proportions (``services.physics.bvh_motion.read_skeleton``), and for a unit given, a height outside the
    performers' and what it means for the drummer (``stature_warning``); for a file no body is built from (its
    error follows), only what ``--height`` does."""
    from services.physics.bvh_motion import read_skeleton, stature_warning, usable_segment_lengths

    try:  # a skeleton no body can be built from is refused after the warnings
        usable_segment_lengths(skeleton, units)
        reading = read_skeleton(skeleton, units)
    except (ValueError, OSError):
        reading = None
    outside = None if reading is None else stature_warning(reading)
    said = [] if outside is None else [f"--skeleton-units {units}: {outside}"]
    limbs = ("the skeleton gives the limbs (arms, legs, neck, the shoulders' height above the hips, their widths) "
             "and the planner's reach")
    stature = None if reading is None else reading.stature_m
    tall = "" if stature is None else f", a {stature:g} m performer's,"
    read = "" if reading is None else f"; the skeleton{tall} is read in {reading.unit_words}"
    if height_m is not None:
        return [f"--height {height_m:g} with --skeleton-bvh: {limbs}; --height places the shoulders and hips over "
                f"the throne and sizes the hands, feet and head{read}", *said]
    if reading is None:
        return []
    low, high = HEIGHT_RANGE_M
    if stature is not None and low <= stature <= high:
        hint = f"give --height {stature:g} to size them as the skeleton's"
    else:
        hint = f"give --height (the performer's, {low:g} to {high:g} m) to size them"
    return [f"--skeleton-bvh without --height: {limbs}; the hands, feet and head and the body's place over the "
            f"throne are the default {STATURE_M:g} m drummer's: {hint}{read}", *said]


def options_in_vain(args: argparse.Namespace) -> list[str]:
    """Warnings for options given that do nothing with the others given, or share what they decide with another
    (``--height`` beside ``--skeleton-bvh``)."""
    warnings = []
    if args.event is not None and args.strikes is None:
        warnings.append("--event has no effect without --strikes (a score's notes say what is struck)")
    if args.skeleton_bvh is not None and args.strikes is None:
        warnings.extend(skeleton_warnings(args.skeleton_bvh, args.height, args.skeleton_units))
    if args.skeleton_units != "auto" and args.skeleton_bvh is None:
        warnings.append("--skeleton-units has no effect without --skeleton-bvh")
    if args.asymmetric_limits and not args.limits_from:
        warnings.append("--asymmetric-limits has no effect without --limits-from (the default limits are always "
                        "mirror-symmetric)")
    if args.segment is not None and args.jobs == 1:
        warnings.append("--segment has no effect without --jobs above 1")
    for name, value in (("--video-size", args.video_size), ("--video-fps", args.video_fps)):
        if value is not None and not args.video:
            warnings.append(f"{name} has no effect without --video")
    if args.strikes is not None:  # one stick over one instrument: no drummer, no plan, no motion file
        drummer = (("--height", args.height, None), ("--mass", args.mass, DEFAULT_MASS_KG),
                   ("--bvh-rate", args.bvh_rate, RenderOptions.pose_rate_hz), ("--grip", args.grip, None),
                   ("--bvh-sync", args.bvh_sync, None), ("--wav-from", args.wav_from, None),
                   ("--nuance", args.nuance, None), ("--bvh-units", args.bvh_units, "m"),
                   ("--bvh-facing", args.bvh_facing, "+z"))
        for name, value, default in drummer:
            if value != default:
                warnings.append(f"{name} has no effect with --strikes (the strike scene has no drummer)")
        if args.bars is not None:
            warnings.append("--bars has no effect with --strikes (the strike scene has no score)")
    return warnings


def resolve_jobs(jobs: int) -> int:
    """``--jobs``: 0 means one process per CPU; raises ``ValueError`` for a negative count."""
    if jobs < 0:
        raise UsageError(f"--jobs {jobs}: give 0 (one per CPU) or more")
    if jobs == 0:
        from batteur.segments import default_jobs

        return default_jobs()
    return jobs


def excluded_options(args: argparse.Namespace) -> str | None:
    """Why the scene asked for cannot be run (no scene, or options the scene has nothing for), None if it can: one
    line with exit status 2, as a value out of range (until 7 Dec argparse's whole usage came before it)."""
    if args.score is None and args.strikes is None:
        return "give a SCORE, or --strikes for the strike scene"
    if args.score is not None and args.strikes is not None:
        return "give either a SCORE or --strikes, not both"
    if args.strikes is not None and args.video:
        return "--video renders a SCORE (the strike scene has no body to draw)"
    if args.strikes is not None and args.gltf:
        return "--gltf exports a SCORE's performance (the strike scene has no body to export)"
    return None


def facing_joined(argv: Sequence[str]) -> list[str]:
    """``argv`` with ``--bvh-facing -z`` written ``--bvh-facing=-z``: argparse takes a value starting with a dash
    for an option of its own ("expected one argument")."""
    out: list[str] = []
    for arg in argv:
        if out and out[-1] == "--bvh-facing" and arg in BVH_FACINGS:
            out[-1] = f"--bvh-facing={arg}"
        else:
            out.append(arg)
    return out


def main(argv: Sequence[str] | None = None, prog: str = "batteur render") -> int:
    """Run ``batteur render``; the exit status (batteur/errors.py). ``prog`` names the command in its error lines
    (``batteur demo`` renders through this)."""
    parser = build_parser()
    opts = parser.parse_args(facing_joined(sys.argv[1:] if argv is None else argv))
    refused = excluded_options(opts)
    if refused is not None:  # one line, as an option's value refused (not argparse's usage before it)
        return report_error(prog, refused, USAGE)
    said = options_in_vain(opts)
    for warning in said:
        print(f"{prog}: warning: {warning}", file=sys.stderr)
    try:
        with sigterm_raises():  # SIGTERM (timeout, systemd, a render farm) cleans up as Ctrl-C does
            return _main_strikes(opts, prog, said) if opts.strikes is not None else _main_score(opts, prog, said)
    except Terminated:  # before KeyboardInterrupt, which it is
        print(f"{prog}: terminated (SIGTERM); nothing written to {opts.output}", file=sys.stderr)
        return TERMINATED
    except KeyboardInterrupt:  # Ctrl-C: the outputs are staged, so nothing was written
        print(f"{prog}: interrupted; nothing written to {opts.output}", file=sys.stderr)
        return INTERRUPTED


def _count(n: int, noun: str) -> str:
    """``3 impacts``, ``1 impact`` (until 7 Dec: "1 impacts for 1 notes")."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _main_score(opts: argparse.Namespace, prog: str, said: Sequence[str] = ()) -> int:
    """``said``: the warnings printed before (:func:`options_in_vain`), for report.json's ``warnings``."""
    try:
        report = render_score(opts.score, opts.output, options_from(opts), quiet=opts.quiet, prog=prog,
                              overwrite=opts.overwrite, said=said)
    except (ScoreError, RenderError, ValueError, OSError) as exc:  # UsageError: 2, a file or the render: 1
        return report_error(prog, exc)
    out = opts.output
    print(f"wrote {out / 'performance.wav'} ({report['duration_s']:.1f} s"
          f"{bars_words(report)})")
    first_bar = 1 if report.get("bars") is None else report["bars"]["first"]
    print(bar_one_line(report["score_time_0_wav_s"], bar=first_bar)
          + (" (--wav-from score)" if report["wav_from"] == "score" else
             f"; --wav-from score starts the WAV there, for a DAW's bar {first_bar}"))
    print(f"wrote {out / 'impacts.csv'} ({_count(report['impacts'], 'impact')} for "
          f"{_count(report['notes'], 'note')}, "
          f"{report['planner_issues']} flagged by the planner{unplayed_words(report)})")
    flags = planner_flags_line(report)
    if flags is not None:
        print(flags)
    if "bvh" in report:
        print(f"wrote {out / 'performance.bvh'} ({bvh_words(report)})")
    elif (out / "performance.bvh").exists():
        print(f"wrote {out / 'performance.bvh'}")
    if "video" in report:
        v = report["video"]
        print(f"wrote {out / v['file']} ({v['frames']} frames at {v['fps']:g} fps, {v['width']}x{v['height']})")
    if "gltf" in report:
        g = report["gltf"]
        print(f"wrote {out / g['file']} ({g['frames']} frames at {g['rate_hz']:g} Hz, {g['links']} links, "
              f"{g['kit_objects']} kit objects)")
    print(f"wrote {out / 'report.json'} ({rtf_words(report['real_time_factor'])})")
    return 0


def rtf_words(factor: float | None) -> str:
    """The console's real-time factor, said with what it means (a researcher read ``real-time factor 0.157`` and
    could not tell which way it ran): ``real-time factor 0.49: 0.49 s of audio rendered per wall-clock second``."""
    if factor is None:
        return "real-time factor not measured"
    return f"real-time factor {factor:g}: {factor:g} s of audio rendered per wall-clock second"


def bars_words(report: dict[str, Any]) -> str:
    """``; the score: 8 bars (32 beats)`` for the WAV's line, "" when the score's end is not known."""
    beats, bars = report.get("score_beats"), report.get("score_bars")
    if beats is None or bars is None:
        return ""
    part = report.get("bars")
    if part is not None:  # --bars: the part's length, what was rendered
        which = (f"bar {part['first']}" if part["first"] == part["last"]  # one bar: not "bars 14 to 14"
                 else f"bars {part['first']} to {part['last']}")
        return (f"; {which} of the score ({bars} bar{'' if bars == 1 else 's'}, "
                f"{beats:g} beat{'' if beats == 1 else 's'})")
    return f"; the score: {bars} bar{'' if bars == 1 else 's'} ({beats:g} beat{'' if beats == 1 else 's'})"


def unplayed_words(report: dict[str, Any]) -> str:
    """``; 13 notes not played: no drum for their pitch`` (and doubles merged) for impacts.csv's line, counted
    apart from the planner's flags ("" when there are none)."""
    words = ""
    unknown, doubles = report.get("unknown_notes", 0), report.get("duplicates", 0)
    if unknown:
        many = unknown > 1
        words += f"; {unknown} note{'s' * many} not played: no drum for {'their' if many else 'its'} pitch"
    if doubles:
        words += f"; {doubles} double note{'s' * (doubles > 1)} merged (within 10 ms of another of its drum)"
    return words


def planner_flags_line(report: dict[str, Any]) -> str | None:
    """The planner's flags by reason, and what it did with the notes of each, for the line after impacts.csv's
    (``the planner's flags: too_fast 8 (4 merged, 2 dropped, 2 played anyway); each in report.json's issues``;
    until 7 Dec only report.json said why); None when it flagged nothing. The reader's unknown notes and doubles
    (``note_index`` null) are counted on impacts.csv's line instead."""
    actions: dict[str, dict[str, int]] = {}
    for issue in report.get("issues", []):
        if issue.get("note_index") is None:
            continue
        per_reason = actions.setdefault(str(issue["reason"]), {})
        action = str(issue["action"]).replace("_", " ")
        per_reason[action] = per_reason.get(action, 0) + 1
    if not actions:
        return None
    reasons = []
    for reason, done in actions.items():  # in the order first flagged
        what = ", ".join(f"{n} {action}" for action, n in sorted(done.items(), key=lambda kv: (-kv[1], kv[0])))
        reasons.append(f"{reason} {sum(done.values())} ({what})")
    return f"the planner's flags: {'; '.join(reasons)}; each in report.json's issues"


def bvh_words(report: dict[str, Any]) -> str:
    """performance.bvh's frames, rate and what its frame 0 is (report.json's ``bvh`` entry), for its line (until 7
    Dec the line named the file alone, and the default BVH was 3 frames early against the WAV, unsaid)."""
    entry = report["bvh"]
    head = f"{entry['frames']} frames at {entry['rate_hz']:g} Hz; frame 0 is "
    if entry["sync"] == "wav":
        score = " (score time 0)" if report.get("wav_from") == "score" else ""
        return head + f"performance.wav's time 0{score}: imported at frame 0 the two line up"
    wav_s, shift = entry["wav_time_s"], entry["wav_offset_frames"]
    where = (f"{wav_s:.3f} s into performance.wav" if wav_s >= 0 else
             f"{-wav_s:.3f} s before the start of performance.wav")
    return (head + f"the first pose (--bvh-sync pose), {where}: shift it {shift:g} frames to line it up, or render "
            "with --bvh-sync wav")


def _main_strikes(opts: argparse.Namespace, prog: str, said: Sequence[str] = ()) -> int:
    """``said``: as :func:`_main_score`'s."""
    try:
        strikes = parse_strikes(opts.strikes)
        check_latency(opts.latency)
    except ValueError as exc:
        return report_error(prog, exc, USAGE)
    try:
        kit = load_kit(opts.kit or DEFAULT_KIT)
        check_output_dir(opts.output, "-o")
        check_outputs(opts.output, STRIKE_OUTPUTS, opts.overwrite)
        read_render_sound_params(opts.sound_params, kit)
    except (ValueError, OSError, RenderError) as exc:
        return report_error(prog, exc)
    event = opts.event or DEFAULT_STRIKE_EVENT
    started = time.monotonic()
    progress = Progress("rendering", max(t for t, _ in strikes) + opts.latency + 1.0,
                        enabled=False if opts.quiet else None)
    finished = False
    warned = list(said)
    try:
        with kept_warnings(warned):  # the sound core's (its latency)
            result = run_strikes(strikes, EventType(event), kit, opts.latency,
                                 on_progress=lambda t, total: progress.update(t),
                                 prepare=functools.partial(apply_render_sound_params, path=opts.sound_params))
        finished = True
    except ValueError as exc:
        return report_error(prog, exc)
    finally:
        progress.close(finished)
    elapsed = time.monotonic() - started
    report = {
        "scene": "strike",
        "event": event,
        "warnings": warned,  # every warning the render printed, in order (as a score render's)
        "strikes": [{"time_s": t, "speed_m_s": v} for t, v in strikes],
        "impacts": len(result.impacts),
        "contacts": result.contacts,
        "duration_s": round(result.duration_s, 6),  # performance.wav's length
        "sample_rate_hz": result.sample_rate,
        "latency_s": opts.latency,
        "wall_time_s": round(elapsed, 3),
        "real_time_factor": round(result.duration_s / elapsed, 2) if elapsed > 0 else None,
    }
    write_outputs(opts.output, result.audio, result.sample_rate, result.impacts, report)
    print(f"wrote {opts.output / 'performance.wav'}")
    print(f"wrote {opts.output / 'impacts.csv'} ({len(result.impacts)} impacts)")
    print(f"wrote {opts.output / 'report.json'}")
    return 0
