"""Render a score in time segments on several processes (``batteur render --jobs N``).

The rig timeline is cut into segments of ``segment_s`` seconds (boundaries at
whole multiples of it, so the cut never depends on the number of processes).
Each segment runs physics and interaction alone in a worker process, from a
``warmup_s`` lead-in before its start: the drummer starts at rest, joins the
plan there (:meth:`~common.gesture.plan.GesturePlan.from_time`) and is in the
flow of the performance when the segment begins. What the segment sends to
sound and graphics is kept for its own window only, by the rig time a message
is about (an impact's first contact, a pose's instant; otherwise when it was
sent), impacts are numbered again in time order, and the parent process plays
the merged stream into one sound core and one recorder, so the WAV, the
impacts and the motion come out as one performance. A worker is sent only the
part of the plan its segment plays (:func:`segment_plan`).

Ctrl-C: a terminal sends SIGINT to the whole process group. The workers ignore
it from their start (the parent stops their segments through an event), and the
parent acts on it between its own steps (:class:`~batteur.interrupts.DeferredCtrlC`), so the render ends
with its one line and nothing written. SIGTERM likewise (to the parent, or to every process as systemd sends it):
a worker that gets it ends its segment at its next check, and the parent takes a segment so ended for the whole
render's termination (exit 143).

A segmented render is deterministic (the same score and options give the same
files for any number of processes above one) but not identical to a
single-process render: each segment's drummer is a fresh simulation that has
tracked the plan for ``warmup_s`` seconds, not the one that played everything
before. A stick resting on a head across a boundary (damping) is not carried
over: a press whose lift falls in the next segment is lifted by that part's
next strike (sound's implicit lift), and a lift without its press is counted
and ignored.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import multiprocessing
import os
import signal
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from batteur.interrupts import DeferredCtrlC, Terminated
from common.core import Outgoing
from common.gesture.plan import HeadTrajectory, LimbTrajectory
from common.messages import OscMessage
from common.messages.events import Impact
from common.messages.interaction import ImpactEnd

if TYPE_CHECKING:
    from batteur.render import RenderOptions, ScoreRender, StreamedOutputs
    from common.gesture.plan import GesturePlan
    from common.kit import Kit
    from common.score.events import Score
    from common.score.limbs import Assignment

SEGMENT_S = 30.0
"""Default segment length, rig seconds."""
WARMUP_S = 3.0
"""Default lead-in of every segment but the first, seconds: the drummer joins the plan at its start + JOIN_S."""
JOIN_S = 0.5
"""A segment's drummer leaves the rest posture for the plan's knots from this long after the lead-in starts, s."""
OVERHANG_S = 0.25
"""A segment simulates this long past its end, so the impacts that began inside it are completed, seconds."""
PLAN_MARGIN_S = 1.0
"""A segment's worker gets the plan from this long before its lead-in to this long past its ``run_to_s`` (and
the nearest knots outside), seconds: more than its drummer samples, with room."""

Sent = tuple[float, str, str, OscMessage]
"""(rig time sent, seconds; from role; to role; message)."""


@dataclass(frozen=True)
class Segment:
    """One worker's share: it owns what is about rig times in [start_s, end_s) and simulates from ``run_from_s``
    to ``run_to_s`` (seconds)."""

    index: int
    start_s: float
    end_s: float
    run_from_s: float
    run_to_s: float


def plan_segments(duration_s: float, segment_s: float = SEGMENT_S, warmup_s: float = WARMUP_S) -> list[Segment]:
    """Segments covering [0, ``duration_s``): boundaries at multiples of ``segment_s``; a last piece shorter than
    half a segment joins the one before. Raises ``ValueError`` for a length or duration not finite and > 0."""
    if not (math.isfinite(segment_s) and segment_s > 0 and math.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"segment length {segment_s:g} s and duration {duration_s:g} s must be finite and > 0")
    if warmup_s < JOIN_S + 0.5:
        raise ValueError(f"warm-up {warmup_s:g} s is under {JOIN_S + 0.5:g} s: the drummer has no time to join")
    count = max(1, math.floor(duration_s / segment_s + 0.5))
    bounds = [k * segment_s for k in range(count)] + [duration_s]
    return [Segment(k, bounds[k], bounds[k + 1], max(0.0, bounds[k] - warmup_s) if k else 0.0,
                    duration_s if k == count - 1 else min(duration_s, bounds[k + 1] + OVERHANG_S))
            for k in range(count)]


def segment_plan(plan: GesturePlan, segment: Segment, offset_s: float) -> GesturePlan:
    """What ``segment``'s drummer tracks of ``plan`` (``offset_s``: rig time minus plan time, seconds): a later
    segment's plan from its join on (:meth:`~common.gesture.plan.GesturePlan.from_time`), every segment's
    until ``PLAN_MARGIN_S`` past its ``run_to_s``: each limb's knots to the first one after that, the head's
    from the last one before its lead-in (less the margin) to the first one after, the strokes and cymbal
    swings until then, no feasibility issues (physics does not read them). ``start_time`` and ``end_time``
    stay, so rig times map as before. Sampled anywhere in the segment's run, it gives what the whole plan
    gives; a worker given the whole plan held and unpickled all of it (0.6 MB for each second of music)."""
    joined = plan if segment.index == 0 else plan.from_time(segment.run_from_s + JOIN_S - offset_s)
    since = segment.run_from_s - PLAN_MARGIN_S - offset_s
    until = segment.run_to_s + PLAN_MARGIN_S - offset_s
    trajectories = {}
    for limb, traj in joined.trajectories.items():
        end = int(np.searchsorted(traj.times, until, side="right")) + 1  # the first knot after it too
        trajectories[limb] = traj if end >= len(traj.times) else LimbTrajectory(
            limb, traj.times[:end], traj.positions[:end], traj.velocities[:end])
    head = joined.head
    if head is not None:
        first = max(int(np.searchsorted(head.times, since, side="right")) - 1, 0)
        end = int(np.searchsorted(head.times, until, side="right")) + 1
        if first > 0 or end < len(head.times):
            head = HeadTrajectory(head.times[first:end], head.targets[first:end], head.nod[first:end])
    return dataclasses.replace(joined, trajectories=trajectories, head=head, issues=[],
                               strokes=[s for s in joined.strokes if s.time <= until],
                               cymbal_swings=[c for c in joined.cymbal_swings if c.time <= until])


def about_time(message: OscMessage, sent_s: float) -> float:
    """The rig time a message is about, seconds: its own ``time`` field when it has one, else when it was sent."""
    value = getattr(message, "time", None)
    return float(value) if isinstance(value, (int, float)) else sent_s


class _Collector:
    """Stands in for ``ROLE`` in a segment: keeps what it is sent that the segment owns."""

    ROLE: ClassVar[str] = ""
    rate_hz = 0.0

    def __init__(self, segment: Segment, kept: list[Sent]) -> None:
        self.segment = segment
        self.kept = kept

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        if self.segment.start_s <= about_time(message, now) < self.segment.end_s:
            self.kept.append((now, source, self.ROLE, message))
        return []

    def step(self, now: float) -> list[Outgoing]:
        return []


class _SoundCollector(_Collector):
    ROLE = "sound"


class _GraphicsCollector(_Collector):
    ROLE = "graphics"


@dataclass
class SegmentResult:
    """What a worker sends back: the owned messages to sound and graphics, and its counters."""

    index: int
    sent: list[Sent]
    contacts: int
    rejected: dict[str, int]
    cpu_time_s: float
    diverged: int = 0
    settings: dict[str, Any] = field(default_factory=dict)
    pulled: dict[str, int] = field(default_factory=dict)
    """Knots of its part of the plan brought within the body's reach, per limb
    (``common.gesture.reach.pull_into_reach``)."""
    counters: dict[str, int] = field(default_factory=dict)
    """The drummer controller's counters (``batteur.render.controller_counts``: limit violations, torque-saturated
    DOF-steps) grown by the steps in its own window, [start_s, end_s): not its lead-in or overhang, which the
    segments before and after own (empty: no drummer)."""
    warnings: list[str] = field(default_factory=list)
    """The warnings its cores logged (``batteur.render.KEPT_LOGGERS``: physics' joint limits from ``--limits-from``,
    ...), for the parent to say once and keep in report.json (until 8 Dec each worker printed them and report.json
    had none)."""


log = logging.getLogger("batteur.render")


class SegmentStopped(RuntimeError):
    """A segment abandoned because the whole render was (Ctrl-C, or another segment failed)."""


def run_segment(plan: GesturePlan, kit: Kit, opts: RenderOptions, segment: Segment,
                progress: Any = None, stop: Any = None) -> SegmentResult:
    """Simulate one segment (physics and interaction) and keep what it owns; runs in a worker process.

    ``plan``: the whole plan, or :func:`segment_plan`'s part of it for this segment (the same render).
    ``progress``: a queue that gets (segment index, rig seconds simulated) now and then. ``stop``: an event
    that, once set, ends the segment with :class:`SegmentStopped` (checked as often as progress is sent, and
    before it starts): the pool cannot cancel a segment already running or queued to a worker.
    """
    from batteur.render import joint_limits_json, limits_symmetric, offline_interaction_config, start_drummer
    from common.bus import OfflineRunner
    from services.interaction.core import InteractionCore

    cpu = time.process_time()
    if _terminated or (stop is not None and stop.is_set()):
        raise SegmentStopped(f"segment {segment.index} not started: the render was given up")
    offset = opts.settle_s - plan.start_time
    pulled: dict[str, int] = {}
    physics = start_drummer(segment_plan(plan, segment, offset), kit, opts, segment.run_from_s, pulled)
    kept: list[Sent] = []
    counted = _CountingPhysics(physics, segment)
    interaction = InteractionCore(kit=kit, config=offline_interaction_config())
    runner = OfflineRunner([counted, interaction, _SoundCollector(segment, kept), _GraphicsCollector(segment, kept)],
                           start_s=segment.run_from_s)
    last = [segment.run_from_s]

    def report(t: float) -> None:
        if t - last[0] >= 0.5:
            last[0] = t
            if progress is not None:
                progress.put((segment.index, t - segment.run_from_s))
            if _terminated or (stop is not None and stop.is_set()):
                raise SegmentStopped(f"segment {segment.index} given up at rig time {t:.1f} s")

    try:
        runner.run_until(segment.run_to_s, report)
    finally:
        physics.close()
    if progress is not None:
        progress.put((segment.index, segment.run_to_s - segment.run_from_s))
    return SegmentResult(segment.index, kept, counted.contacts, dict(physics.rejected), time.process_time() - cpu,
                         physics.diverged,
                         {"control": physics.settings.control, "grip": physics.settings.grip,
                          "rate_hz": physics.rate_hz, "control_rate_hz": physics.settings.control_rate_hz,
                          "height_m": physics.settings.height_m, "mass_kg": physics.settings.mass_kg,
                          "joint_limits": joint_limits_json(physics),
                          "joint_limits_symmetric": limits_symmetric(physics)}, pulled, counted.counters)


class _CountingPhysics:
    """The physics core, counting the contacts it sends in its segment's window and what its steps there add to
    the controller's counters (:attr:`counters`)."""

    ROLE: ClassVar[str] = "physics"

    def __init__(self, physics: Any, segment: Segment) -> None:
        from batteur.render import controller_counts

        self.physics = physics
        self.segment = segment
        self.rate_hz = physics.rate_hz
        self.contacts = 0
        self._counts: Callable[[Any], dict[str, int]] = controller_counts
        self.counters = {name: 0 for name in controller_counts(physics)}
        """Counter -> its growth over the steps at rig times in the window (a sum over the segments is the
        piece's: each step is one segment's)."""

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        out: list[Outgoing] = self.physics.handle(message, now, source)
        return out

    def step(self, now: float) -> list[Outgoing]:
        owned = self.segment.start_s <= now < self.segment.end_s
        before = self._counts(self.physics) if owned and self.counters else None
        out: list[Outgoing] = self.physics.step(now)
        if before is not None:
            for name, count in self._counts(self.physics).items():
                self.counters[name] += count - before[name]
        for o in out:
            if o.to == "interaction" and self.segment.start_s <= about_time(o.message, now) < self.segment.end_s:
                self.contacts += 1
        return out


def merge(results: list[SegmentResult]) -> list[Sent]:
    """Every segment's owned messages in time order, their sequence numbers made unique again.

    An impact and its end share a number (as interaction sends them); other numbered messages (damping) keep
    a sequence of their own.
    """
    merger = _Merger()
    for r in results:
        merger.add(r)
    return merger.release(math.inf)


class _Merger:
    """:func:`merge` in pieces, as the segments come: segment ``k``'s messages are all sent at or after its
    ``run_from_s``, so once segments 0..k-1 are in, every message sent before segment ``k``'s ``run_from_s`` is
    known and can be played; only the later ones are held (the lead-in and overhang of a segment or two)."""

    def __init__(self) -> None:
        self._held: list[tuple[float, int, int, str, str, OscMessage]] = []
        self._numbers: dict[tuple[int, str, str, int], int] = {}
        self._counters: dict[tuple[str, str], int] = {}
        self.peak_held = 0
        """Most messages held at once (not yet released)."""

    def add(self, result: SegmentResult) -> None:
        self._held += [(now, result.index, k, source, to, m) for k, (now, source, to, m) in enumerate(result.sent)]
        self.peak_held = max(self.peak_held, len(self._held))

    def release(self, before_s: float) -> list[Sent]:
        """The held messages sent before ``before_s`` (rig seconds), in time order, numbered again."""
        self._held.sort(key=lambda e: (e[0], e[1], e[2]))
        cut = next((i for i, e in enumerate(self._held) if e[0] >= before_s), len(self._held))
        stream, self._held = self._held[:cut], self._held[cut:]
        out: list[Sent] = []
        for now, index, _, source, to, message in stream:
            seq = getattr(message, "seq", None)
            if isinstance(seq, int):
                family = "impact" if isinstance(message, (Impact, ImpactEnd)) else type(message).__name__
                key = (index, source, family, seq)
                if key not in self._numbers:
                    self._numbers[key] = self._counters.get((source, family), 0)
                    self._counters[(source, family)] = self._numbers[key] + 1
                message = message.model_copy(update={"seq": self._numbers[key]})
            out.append((now, source, to, message))
        return out


class _Replay:
    """Sends recorded messages again at the rig times they were sent, as role ``ROLE``; messages are added
    (:meth:`extend`) before the run reaches their time."""

    ROLE: ClassVar[str] = ""

    def __init__(self, sent: list[Sent], rate_hz: float) -> None:
        self.rate_hz = rate_hz
        self._queue: deque[tuple[float, str, OscMessage]] = deque()
        self.extend(sent)

    def extend(self, sent: list[Sent]) -> None:
        self._queue.extend((now, to, m) for now, source, to, m in sent if source == self.ROLE)

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        return []

    def step(self, now: float) -> list[Outgoing]:
        out: list[Outgoing] = []
        queue = self._queue
        while queue and queue[0][0] <= now + 1e-9:
            _, to, message = queue.popleft()
            out.append(Outgoing(message, to))
        return out


class _PhysicsReplay(_Replay):
    ROLE = "physics"


class _InteractionReplay(_Replay):
    ROLE = "interaction"


def _segment_result(future: Future[SegmentResult]) -> SegmentResult:
    """A finished segment's result; one stopped before the parent gave the render up was stopped by its worker's
    SIGTERM (:func:`_note_sigterm`): the render is terminated, :class:`Terminated`."""
    try:
        return future.result()
    except SegmentStopped:
        raise Terminated from None


def _log_given_up(futures: dict[Future[SegmentResult], Segment]) -> None:
    """After a render was given up: wait for the segments still running (they end at their next check, as the
    pool's shutdown would wait for them) and log how each ended (given up at which rig time, or played out)."""
    wait(futures)
    for future, segment in sorted(futures.items(), key=lambda item: item[1].index):
        if future.cancelled():
            continue
        error = future.exception()
        if isinstance(error, SegmentStopped):
            log.info("%s", error)
        elif error is None:
            log.info("segment %d played to its end (%.1f s) before it could be given up", segment.index,
                     segment.run_to_s)


_channels: tuple[Any, Any] = (None, None)
"""In a segment worker: the parent's progress queue and stop event (:func:`_start_worker`)."""
_terminated = False
_worker_warnings: list[str] = []
"""In a segment worker: the warnings logged while its current segment runs (:func:`_run_in_worker`)."""
"""In a segment worker: it got SIGTERM (:func:`_note_sigterm`); its segment ends at the next check."""


def _note_sigterm(signum: int, frame: Any) -> None:
    """A worker's SIGTERM: noted, not raised wherever the worker is (a numba kernel, a queue write); not the stop
    event set here either (its lock may be held by the code the handler interrupted)."""
    global _terminated
    _terminated = True


def _start_worker(progress: Any, stop: Any) -> None:
    """A segment worker's set-up (the pool's initializer): a terminal's Ctrl-C reaches the whole process group,
    and a worker must not stop on it (it printed a ``KeyboardInterrupt`` traceback from wherever it was, and one
    that died left the pool broken): SIGINT is ignored, the parent stops the segments through ``stop``. It was
    blocked from the worker's start (:func:`_sigint_blocked` in the parent, inherited), so a Ctrl-C while the
    worker started up is dropped here."""
    global _channels
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _note_sigterm)  # its segment ends at the next check, the parent says why
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    _channels = (progress, stop)
    from batteur.render import KEPT_LOGGERS, _KeptWarnings

    for name in KEPT_LOGGERS:  # kept for the parent, not printed here (once per worker, and not in report.json)
        logging.getLogger(name).addHandler(_KeptWarnings(_worker_warnings, show=False))


def _run_in_worker(plan: GesturePlan, kit: Kit, opts: RenderOptions, segment: Segment) -> SegmentResult:
    """:func:`run_segment` with the worker's progress queue and stop event, and the warnings logged meanwhile."""
    _worker_warnings.clear()
    result = run_segment(plan, kit, opts, segment, *_channels)
    return dataclasses.replace(result, warnings=list(_worker_warnings))


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """SIGINT and SIGTERM blocked in this thread meanwhile (one sent meanwhile is delivered when it ends): the
    processes and threads started meanwhile inherit the block, so a worker cannot be interrupted (or killed: a dead
    worker breaks the pool) while Python starts in it, before its initializer runs."""
    if not hasattr(signal, "pthread_sigmask"):  # not POSIX
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def default_jobs() -> int:
    """Processes a segmented render uses when asked for all: the CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def run_segmented(score: Score, assignment: Assignment, plan: GesturePlan, kit: Kit, opts: RenderOptions,
                  jobs: int, on_progress: Callable[[float, float], None] | None = None,
                  segment_s: float = SEGMENT_S, warmup_s: float = WARMUP_S,
                  outputs: StreamedOutputs | None = None) -> ScoreRender:
    """:func:`batteur.render.run_score` in segments on ``jobs`` processes (see the module docstring).

    The parent plays each segment's messages into sound and the recorder as soon as the segments before it are
    in, so it holds a few segments' messages, not the piece's; ``outputs``: as for ``run_score``.
    """
    from batteur.render import (
        RecorderCore,
        ScoreRender,
        apply_render_sound_params,
        collect,
        rendered_seconds,
        wav_seconds,
    )
    from common.bus import OfflineRunner
    from services.sound.core import SoundCore, SoundSettings

    started = time.perf_counter()
    cpu_started = time.process_time()
    offset = opts.settle_s - plan.start_time
    duration = rendered_seconds(plan, opts)
    segments = plan_segments(duration, segment_s, warmup_s)
    total = sum(s.run_to_s - s.run_from_s for s in segments)
    sound = SoundCore(SoundSettings(latency=opts.latency_s, origin=0.0, record=outputs is None), kit=kit)
    apply_render_sound_params(sound, opts.sound_params)
    recorder = RecorderCore() if outputs is None else outputs.recorder()
    replays = [_PhysicsReplay([], opts.rate_hz), _InteractionReplay([], opts.rate_hz)]
    runner = OfflineRunner([*replays, sound, recorder])
    play = _Player(segments, replays, runner, duration)
    context = multiprocessing.get_context("spawn")  # PyBullet, pyo and numba do not survive a fork
    try:
        if outputs is not None:
            outputs.attach(sound)
        with DeferredCtrlC() as ctrl_c:  # the segments' Ctrl-C: acted on between the parent's steps (see DeferredCtrlC)
            play.check = ctrl_c.check
            queue, stop = context.Queue(), context.Event()
            with contextlib.ExitStack() as stack:
                with _sigint_blocked():  # inherited by the workers, started as the segments are submitted
                    pool = stack.enter_context(ProcessPoolExecutor(
                        max_workers=max(1, min(jobs, len(segments))), mp_context=context,
                        initializer=_start_worker, initargs=(queue, stop)))
                    futures: dict[Future[SegmentResult], Segment] = {
                        pool.submit(_run_in_worker, segment_plan(plan, s, offset), kit, opts, s): s
                        for s in segments}  # each worker is sent only its part of the plan
                done_s = {s.index: 0.0 for s in segments}
                pending = set(futures)
                try:
                    while pending:
                        ctrl_c.check()
                        finished, pending = wait(pending, timeout=0.25, return_when=FIRST_COMPLETED)
                        while not queue.empty():
                            index, simulated = queue.get_nowait()
                            done_s[index] = simulated
                        if on_progress is not None:  # simulated seconds of all segments, scaled to the piece
                            on_progress(duration * sum(done_s.values()) / total, duration)
                        for future in finished:
                            ctrl_c.check()  # SIGTERM to every process: the parent's own, not the segment's, said
                            play.add(_segment_result(future))  # a worker's error ends the render here
                            del futures[future]  # its messages are the player's now, not kept twice
                        if finished:
                            play.advance()
                        finished = set()  # their results (messages) are the player's: not kept alive by this name
                except BaseException:
                    # the running and queued segments end at their next check (a queued one as it starts), not at
                    # their end; not cancelled: Python 3.11's pool hangs at shutdown if a worker dies after a
                    # cancel (its manager thread fails on the cancelled future)
                    stop.set()
                    _log_given_up(futures)
                    raise
        runner.run_until(duration)
        audio = sound.recording()
    finally:
        sound.close()
    poses, impacts, count = collect(recorder, outputs)
    stats = {"contacts_sent": play.contacts, "rejected": play.rejected, "diverged": play.diverged,
             **play.settings, "pulled_into_reach": play.pulled, **play.counters,
             "cpu_time_s": round(time.process_time() - cpu_started + play.cpu_time_s, 3),
             "segments": {"count": len(segments), "segment_s": segment_s, "warmup_s": warmup_s,
                          "jobs": max(1, min(jobs, len(segments)))}}
    return ScoreRender(score, assignment, plan, impacts, play.contacts, audio, sound.sample_rate, wav_seconds(sound),
                       offset, time.perf_counter() - started, poses, stats, count)


class _Player:
    """Plays the segments' messages into the parent's sound and recorder as far as the segments in allow."""

    def __init__(self, segments: list[Segment], replays: list[_Replay], runner: Any, duration_s: float) -> None:
        self.segments = segments
        self.replays = replays
        self.runner = runner
        self.duration_s = duration_s
        self.merger = _Merger()
        self._waiting: dict[int, SegmentResult] = {}
        self._next = 0  # first segment not merged yet
        self.contacts = 0
        self.diverged = 0
        self.cpu_time_s = 0.0
        self.rejected: dict[str, int] = {}
        self.pulled: dict[str, int] = {}
        self.counters: dict[str, int] = {}
        """The controller's counters (``limit_violations``, ``torque_saturated``), summed over the segments' windows."""
        self.settings: dict[str, Any] = {}
        self.check: Callable[[float], None] | None = None
        """Called at each step of the play (rig seconds): raises to stop it (a Ctrl-C)."""
        self.warned: set[str] = set()
        """The workers' warnings said so far: each segment's cores say the same ones, said once."""

    def add(self, result: SegmentResult) -> None:
        """A segment is done: merge it and those after it that were waiting for it."""
        self._waiting[result.index] = result
        while self._next in self._waiting:
            r = self._waiting.pop(self._next)
            self.merger.add(r)
            self.contacts += r.contacts
            self.diverged += r.diverged
            self.cpu_time_s += r.cpu_time_s
            for kind, n in r.rejected.items():
                self.rejected[kind] = self.rejected.get(kind, 0) + n
            for limb, n in r.pulled.items():  # a knot in two segments' parts of the plan counts in each
                self.pulled[limb] = self.pulled.get(limb, 0) + n
            for name, n in r.counters.items():  # each segment's own window: the sum is the piece's
                self.counters[name] = self.counters.get(name, 0) + n
            if r.index == 0:
                self.settings = r.settings
            for message in r.warnings:  # logged here: the render's kept_warnings prints and keeps it
                if message not in self.warned:
                    self.warned.add(message)
                    log.warning("%s", message)
            self._next += 1

    def advance(self) -> None:
        """Play every message known to be in its final place: those sent before the next segment's start."""
        before = self.segments[self._next].run_from_s if self._next < len(self.segments) else math.inf
        released = self.merger.release(before)
        if released:
            for replay in self.replays:
                replay.extend(released)
        until = min(before - 1e-6, self.duration_s)  # the steps that send only released messages
        if until > self.runner.now:
            self.runner.run_until(until, self.check)
