"""Offline video: frames rendered headless on the CPU (PyBullet's TinyRenderer), encoded with ffmpeg.

:func:`render_video` is the entry point of ``batteur render ... --video``: it
takes the performance's pose sequence, its impacts and the rendered WAV and
writes an MP4 (H.264 + AAC) whose picture is in sync with the sound. The kit
is animated exactly as in the live view (:class:`~services.graphics.scene.KitAnimator`:
heads flash, cymbals swing, the hi-hat opens, pedals move).

Timing: video frame ``i`` is shown at ``i / fps`` seconds into the WAV and
shows the performance at rig time ``audio_start + i / fps - latency``, where
``audio_start`` is the rig time of the WAV's first sample and ``latency`` the
delay the sound service applied to every strike (its latency window; 0 if the
WAV has strikes at their event times). The video lasts as long as the WAV
(rounded up to whole frames).

ffmpeg: the system's (``apt-get install ffmpeg``), else the one shipped by the
``imageio-ffmpeg`` package if installed.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import soundfile
from scipy.spatial.transform import Rotation

from common.kit import Kit, KitObject, load_kit
from common.messages import Impact
from common.quiet_pybullet import BulletClient, pybullet
from services.graphics.camera import camera_eye as orbit_eye
from services.graphics.camera import default_camera
from services.graphics.scene import KitAnimator, object_rotation
from services.graphics.sequence import PoseSequence
from services.graphics.skeleton import guess_parents, kit_link

DEFAULT_CAMERA: dict[str, object] = {key: value for key, value in default_camera().items() if key != "preset"}
"""The view's default camera (the page's front preset, services/graphics/camera.py), so videos frame as the page."""
BODY_RGBA = (0.31, 0.53, 0.78, 1.0)
STICK_RGBA = (0.85, 0.7, 0.48, 1.0)
SHELL_RGBA = (0.55, 0.11, 0.14, 1.0)
HEAD_RGBA = (0.91, 0.89, 0.85, 1.0)
CYMBAL_RGBA = (0.79, 0.64, 0.23, 1.0)
METAL_RGBA = (0.6, 0.6, 0.63, 1.0)
FLASH_RGBA = np.array([1.0, 0.85, 0.35, 1.0])
STICK_GRIP, STICK_TIP = 0.13, 0.2695  # physics' 5A stick: butt and tip along the stick link's +y, metres


def find_ffmpeg() -> str:
    """Path of an ffmpeg executable; ``FileNotFoundError`` with the way to install one."""
    found = shutil.which("ffmpeg")
    if found:
        return found
    try:
        import imageio_ffmpeg  # type: ignore[import-not-found]

        return str(imageio_ffmpeg.get_ffmpeg_exe())
    except (ImportError, RuntimeError):
        raise FileNotFoundError("ffmpeg not found: apt-get install ffmpeg (or pip install imageio-ffmpeg)") from None


def camera_eye(azimuth_deg: float, elevation_deg: float, distance: float,
               target: tuple[float, float, float]) -> np.ndarray:
    """Camera position (3,) metres for an orbit camera (azimuth 0 = in front of the kit, +y; 90 = +x)."""
    return np.asarray(orbit_eye(azimuth_deg, elevation_deg, distance, target))


class QuietClient(BulletClient):
    """A headless (DIRECT) client connected without an options string: with one (the stock client passes ''),
    pybullet prints "argv[0]=" to the process's stdout, into the output of ``batteur render --video``."""

    def __init__(self) -> None:  # the stock __init__'s state, without its options
        self._shapes: dict[Any, Any] = {}
        self._pid = os.getpid()
        self._client = pybullet.connect(pybullet.DIRECT)


@dataclass
class _Part:
    body: int
    rgba: tuple[float, float, float, float]
    flash: float = 0.0


class TinyRendererScene:
    """The drummer and the kit as PyBullet visual bodies, rendered with TinyRenderer (CPU, headless)."""

    def __init__(self, names: list[str], first_pose: np.ndarray, kit: Kit, width: int = 640, height: int = 360,
                 camera: dict[str, object] | None = None, fov_deg: float = 45.0) -> None:
        self.width, self.height = width, height
        self.kit = kit
        self.client = QuietClient()
        cam: dict[str, Any] = {**DEFAULT_CAMERA, **(camera or {})}
        tx, ty, tz = (float(v) for v in cam["target"])
        target = (tx, ty, tz)
        self.eye = camera_eye(float(cam["azimuth_deg"]), float(cam["elevation_deg"]), float(cam["distance"]), target)
        self.view = self.client.computeViewMatrix(self.eye.tolist(), list(target), [0, 0, 1])
        self.proj = self.client.computeProjectionMatrixFOV(fov_deg, width / height, 0.05, 30.0)
        self.names = names
        self.parents = guess_parents(names)
        kit_ids = {o.id for o in kit.objects}
        self.links: list[int | None] = []
        self.bones: list[tuple[int, int, int, float] | None] = []  # (body, child, parent, length)
        for i, name in enumerate(names):
            if name in kit_ids or kit_link(name) is not None:  # kit links animate the kit (KitAnimator)
                self.links.append(None)
                self.bones.append(None)
                continue
            stick = "stick" in name
            has_tip = any(self.parents[j] == i and "tip" in n for j, n in enumerate(names))
            if stick and "tip" not in name and not has_tip:  # no tip link: the stick along the link's +y
                self.links.append(self._stick_body())
            else:
                radius = 0.1 if name.endswith("head") else (0.012 if stick else 0.028)
                self.links.append(self._body("sphere", (radius,), STICK_RGBA if stick else HEAD_RGBA))
            parent = self.parents[i]
            if parent >= 0:
                length = float(np.linalg.norm(first_pose[i, :3] - first_pose[parent, :3]))
                if length > 1e-3:
                    thick = 0.008 if stick else 0.03
                    body = self._body("cylinder", (thick, length), STICK_RGBA if stick else BODY_RGBA)
                    self.bones.append((body, i, parent, length))
                    continue
            self.bones.append(None)
        self._body("box", (4.0, 4.0, 0.01), (0.35, 0.36, 0.4, 1.0), (0.0, 0.3, -0.006))  # floor
        self.parts: dict[str, list[_Part]] = {}
        self.moving: dict[str, list[tuple[int, np.ndarray]]] = {}  # object id -> bodies with local offsets
        for obj in kit.objects:
            self._kit_object(obj)

    def _body(self, kind: str, size: tuple[float, ...], rgba: tuple[float, float, float, float],
              position: tuple[float, float, float] = (0.0, 0.0, 0.0),
              orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)) -> int:
        c = self.client
        if kind == "sphere":
            shape = c.createVisualShape(pybullet.GEOM_SPHERE, radius=size[0], rgbaColor=rgba)
        elif kind == "cylinder":
            shape = c.createVisualShape(pybullet.GEOM_CYLINDER, radius=size[0], length=size[1], rgbaColor=rgba)
        else:
            shape = c.createVisualShape(pybullet.GEOM_BOX, halfExtents=[s / 2 for s in size], rgbaColor=rgba)
        return int(c.createMultiBody(baseMass=0, baseVisualShapeIndex=shape, basePosition=position,
                                     baseOrientation=orientation))

    def _stick_body(self) -> int:
        """A stick whose link frame is at the fulcrum with the stick along +y (physics' convention)."""
        shape = self.client.createVisualShape(
            pybullet.GEOM_CYLINDER, radius=0.008, length=STICK_GRIP + STICK_TIP, rgbaColor=STICK_RGBA,
            visualFramePosition=[0.0, (STICK_TIP - STICK_GRIP) / 2, 0.0],
            visualFrameOrientation=list(Rotation.from_euler("x", -90, degrees=True).as_quat()))
        return int(self.client.createMultiBody(baseMass=0, baseVisualShapeIndex=shape))

    def _kit_object(self, obj: KitObject) -> None:
        rot = object_rotation(obj)
        q = tuple(rot.as_quat())
        centre = np.asarray(obj.position)
        parts: list[_Part] = []
        moving: list[tuple[int, np.ndarray]] = []
        if obj.kind == "membrane":
            depth = max(obj.depth, 0.05)
            shell = centre - rot.apply([0, 0, depth / 2 + 0.003])
            self._body("cylinder", (obj.radius, depth), SHELL_RGBA, (shell[0], shell[1], shell[2]), q)
            head = self._body("cylinder", (obj.radius * 0.995, 0.004), HEAD_RGBA, tuple(centre), q)
            parts.append(_Part(head, HEAD_RGBA))
        elif obj.kind in ("cymbal", "hihat", "bell"):
            if obj.kind == "bell":
                body = self._body("box", (obj.radius * 2, obj.radius * 1.4, max(obj.depth, 0.08)), CYMBAL_RGBA,
                                  tuple(centre), q)
            else:
                body = self._body("cylinder", (obj.radius, 0.008), CYMBAL_RGBA, tuple(centre), q)
            parts.append(_Part(body, CYMBAL_RGBA))
            moving.append((body, np.zeros(3)))
            if obj.kind == "hihat":
                self._body("cylinder", (obj.radius, 0.008), CYMBAL_RGBA, tuple(centre - rot.apply([0, 0, 0.012])), q)
        elif obj.kind == "pedal":
            board = self._body("box", (0.09, 0.28, 0.015), METAL_RGBA, tuple(centre), q)
            moving.append((board, np.array([0.0, 0.12, 0.0])))
        elif obj.kind == "throne":
            self._body("cylinder", (obj.radius, 0.08), (0.16, 0.16, 0.19, 1.0), tuple(centre - [0, 0, 0.04]), q)
        if obj.kind not in ("pedal", "membrane") and obj.position[2] > 0.1:
            h = obj.position[2] - 0.02
            self._body("cylinder", (0.008, h), METAL_RGBA, (obj.position[0], obj.position[1], h / 2))
        self.parts[obj.id] = parts
        self.moving[obj.id] = moving

    def update(self, pose: np.ndarray, kit_state: np.ndarray) -> None:
        """Move every body to ``pose`` (L, 7) and the kit to ``kit_state`` (K, 4)."""
        c = self.client
        for i, body in enumerate(self.links):
            if body is not None:
                c.resetBasePositionAndOrientation(body, pose[i, :3].tolist(), pose[i, 3:].tolist())
        z = np.array([0.0, 0.0, 1.0])
        for bone in self.bones:
            if bone is None:
                continue
            body, child, parent, length = bone
            a, b = pose[parent, :3], pose[child, :3]
            d = b - a
            n = float(np.linalg.norm(d))
            if n < 1e-6:
                continue
            axis = np.cross(z, d / n)
            s = float(np.linalg.norm(axis))
            angle = math.atan2(s, float(np.dot(z, d / n)))
            q = Rotation.from_rotvec(axis / s * angle).as_quat() if s > 1e-9 else (
                [0.0, 0.0, 0.0, 1.0] if d[2] > 0 else [1.0, 0.0, 0.0, 0.0])
            c.resetBasePositionAndOrientation(body, ((a + b) / 2).tolist(), list(q))
        for k, obj in enumerate(self.kit.objects):
            flash, sx, sy, extra = kit_state[k]
            for part in self.parts[obj.id]:
                if abs(flash - part.flash) > 0.02:
                    part.flash = float(flash)
                    rgba = np.asarray(part.rgba) * (1 - flash) + FLASH_RGBA * flash
                    c.changeVisualShape(part.body, -1, rgbaColor=rgba.tolist())
            rot = object_rotation(obj)
            if obj.kind == "pedal":
                local = Rotation.from_euler("x", 18 - 16 * extra, degrees=True)
            else:
                local = Rotation.from_rotvec([sx, sy, 0.0])
            for body, offset in self.moving[obj.id]:
                lift = np.array([0.0, 0.0, extra]) if obj.kind == "hihat" else np.zeros(3)
                world = rot * local
                pos = np.asarray(obj.position) + rot.apply(lift) + world.apply(offset)
                c.resetBasePositionAndOrientation(body, pos.tolist(), world.as_quat().tolist())

    def render(self) -> np.ndarray:
        """The current picture, (height, width, 3) uint8 RGB."""
        _, _, rgba, _, _ = self.client.getCameraImage(
            self.width, self.height, self.view, self.proj, renderer=pybullet.ER_TINY_RENDERER, shadow=0,
            lightDirection=[1.5, 2.5, 4.0])
        return np.asarray(rgba, dtype=np.uint8).reshape(self.height, self.width, 4)[:, :, :3]

    def close(self) -> None:
        self.client.disconnect()


def render_frames(sequence: PoseSequence, impacts: list[Impact], times: np.ndarray, kit: Kit | None = None,
                  width: int = 640, height: int = 360, camera: dict[str, object] | None = None,
                  on_frame: Callable[[int, np.ndarray], None] | None = None) -> int:
    """Render the performance at rig ``times`` (F,) seconds; each frame goes to ``on_frame(i, rgb)``.

    Returns the number of frames rendered.
    """
    kit = kit or load_kit("default")
    scene = TinyRendererScene(sequence.names, sequence.values[0], kit, width, height, camera)
    animator = KitAnimator(kit)
    animator.bind(sequence.names)
    pending = sorted(impacts, key=lambda i: i.time)
    nxt = 0
    try:
        for i, t in enumerate(times):
            while nxt < len(pending) and pending[nxt].time <= t:
                animator.add(pending[nxt])
                nxt += 1
            pose = sequence.sample(float(t))
            scene.update(pose, animator.state(float(t), pose))
            rgb = scene.render()
            if on_frame is not None:
                on_frame(i, rgb)
    finally:
        scene.close()
    return len(times)


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`render_video` wrote: path, frames, frame rate (Hz), duration (seconds), size."""

    path: Path
    frames: int
    fps: float
    duration: float
    width: int
    height: int


def render_video(sequence: PoseSequence, impacts: list[Impact], wav_path: Path | None, out_dir: Path,
                 kit: Kit | None = None, fps: float = 30.0, width: int = 640, height: int = 360,
                 audio_start: float = 0.0, latency: float = 0.0, camera: dict[str, object] | None = None,
                 name: str = "performance.mp4",
                 on_progress: Callable[[int, int], None] | None = None) -> VideoInfo:
    """Write ``out_dir/performance.mp4``: the performance rendered headless, the WAV muxed in sync.

    The file appears only when complete: a failed or interrupted render leaves any previous one as it was.

    Parameters
    ----------
    sequence : PoseSequence
        Link poses of the performance (rig time, seconds).
    impacts : list of Impact
        Strikes (rig time): heads flash, cymbals swing.
    wav_path : Path or None
        The rendered audio. None: a silent video as long as the pose sequence.
    out_dir : Path
        Output directory (created).
    kit : Kit, optional
        The kit that was played (default kit if omitted).
    fps : float
        Video frame rate, Hz.
    width, height : int
        Frame size, pixels (even numbers for H.264 4:2:0).
    audio_start : float
        Rig time of the WAV's first sample, seconds.
    latency : float
        Delay of every strike in the WAV relative to its rig time, seconds (the sound's latency window).
    camera : dict, optional
        ``azimuth_deg``, ``elevation_deg``, ``distance`` (metres), ``target`` (x, y, z metres).
    on_progress : callable, optional
        Called with (frames written, total frames) after every frame.

    Raises ``FileNotFoundError`` (no ffmpeg), ``ValueError`` (odd frame size) and ``RuntimeError`` (ffmpeg failed).
    """
    if width % 2 or height % 2:
        raise ValueError("width and height must be even for H.264")
    ffmpeg = find_ffmpeg()
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / name
    partial = out.with_name(f".{out.stem}.partial{out.suffix}")  # renamed to ``out`` only when complete
    if wav_path is not None:
        duration = float(soundfile.info(str(wav_path)).duration)
    else:
        duration = float(sequence.times[-1] - audio_start + latency)
    frames = max(1, math.ceil(duration * fps - 1e-9))
    times = audio_start + np.arange(frames) / fps - latency
    command = [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}",
               "-framerate", f"{fps:g}", "-i", "pipe:0"]
    if wav_path is not None:
        command += ["-i", str(wav_path), "-map", "0:v", "-map", "1:a", "-c:a", "aac", "-b:a", "192k"]
    command += ["-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p", "-r", f"{fps:g}",
                "-movflags", "+faststart", str(partial)]
    try:
        _encode(command, sequence, impacts, times, kit, width, height, camera, on_progress)
        partial.replace(out)
    except BaseException:  # Ctrl-C too: ffmpeg would finish a truncated file that looks like the take
        partial.unlink(missing_ok=True)
        raise
    return VideoInfo(out, frames, fps, frames / fps, width, height)


def _encode(command: list[str], sequence: PoseSequence, impacts: list[Impact], times: np.ndarray, kit: Kit | None,
            width: int, height: int, camera: dict[str, object] | None,
            on_progress: Callable[[int, int], None] | None) -> None:
    """Render the frames at rig ``times`` into ffmpeg running ``command``; ``RuntimeError`` if it fails."""
    frames = len(times)
    proc = subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdin is not None

    def write(i: int, rgb: np.ndarray) -> None:
        proc.stdin.write(np.ascontiguousarray(rgb).tobytes())  # type: ignore[union-attr]
        if on_progress is not None:
            on_progress(i + 1, frames)

    broken = False
    try:
        render_frames(sequence, impacts, times, kit, width, height, camera, write)
    except BrokenPipeError:  # ffmpeg stopped reading: its exit status and message say why
        broken = True
    except BaseException:  # the video is abandoned (Ctrl-C, a failure): no need for ffmpeg to finish it
        proc.kill()
        raise
    finally:
        try:
            proc.stdin.close()
        except BrokenPipeError:
            broken = True
        stderr = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
        code = proc.wait()
    if code != 0 or broken:
        raise RuntimeError(f"ffmpeg failed (exit status {code}): {stderr.strip()[-800:] or 'no message'}")
