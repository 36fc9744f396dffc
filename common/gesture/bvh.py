"""Minimal BVH (Biovision Hierarchy) reading, writing and forward kinematics.

Reads any BVH with ``ROOT``/``JOINT``/``End Site`` blocks, 3 or 6 channels per
joint, rotations in any Euler order (degrees, intrinsic, as the channel list
says). :func:`forward_kinematics` gives world positions of every joint and end
site per frame, in the file's units and axes (BVH is usually y-up).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from common.datafile import read_text
from common.input_file import file_problem


class BvhError(ValueError):
    """A BVH file that cannot be read; the message names the problem."""


@dataclass
class BvhJoint:
    name: str
    offset: np.ndarray
    channels: list[str]
    parent: int  # -1 for the root
    end_site: np.ndarray | None = None  # offset of the end site, if any
    children: list[int] = field(default_factory=list)


@dataclass
class Bvh:
    """A parsed BVH: joints (root first), frame time (s) and motion (F, total channels)."""

    joints: list[BvhJoint]
    frame_time: float
    motion: np.ndarray

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.frame_time

    def joint_index(self, name: str) -> int:
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise KeyError(f"BVH has no joint {name!r} (joints: {', '.join(j.name for j in self.joints)})")


CHANNEL_NAMES = frozenset(f"{axis}{kind}" for axis in "xyz" for kind in ("position", "rotation"))
"""The channel names a BVH may list (compared lower-case): Xposition ... Zrotation."""
_CHANNEL_SPELLINGS = tuple(f"{axis}{kind}" for kind in ("position", "rotation") for axis in "XYZ")
""":data:`CHANNEL_NAMES` as files spell them, for messages."""


def _line_of(text: str, index: int) -> int:
    """1-based line of token ``index`` of ``text.split()`` (``len`` of it: the line after the last token); scanned
    only for an error's message, so reading a good file costs nothing."""
    last = 0
    for k, token in enumerate(re.finditer(r"\S+", text)):
        if k == index:
            return text.count("\n", 0, token.start()) + 1
        last = token.end()
    return text.count("\n", 0, last) + 1


_STRUCTURE = frozenset(("ROOT", "JOINT", "END", "OFFSET", "CHANNELS", "MOTION", "{", "}"))
"""Words of a BVH's hierarchy: one among a joint's channel names means its CHANNELS count is too high."""


def _channel_problem(tokens: list[str], count_at: int, n: int, k: int, where: str, count_line: int) -> str:
    """What is wrong with the channel names of a ``CHANNELS n`` (token ``count_at``, line ``count_line``) whose
    ``k``-th name (0-based) is not one: the names it lists and the valid ones."""
    listed: list[str] = []
    for token in tokens[count_at + 1:count_at + 1 + n]:
        if token.upper() in _STRUCTURE:
            break
        listed.append(token)
    valid = f"valid names: {' '.join(_CHANNEL_SPELLINGS)}"
    if len(listed) == k:  # the hierarchy goes on after k names: the count is too high
        return (f"{where}: {tokens[count_at + 1 + k]!r} is not a channel name: its CHANNELS {n} (line {count_line}) "
                f"names {k}{' (' + ' '.join(listed) + ')' if listed else ''}; {valid}")
    bad = [repr(t) for t in listed if t.lower() not in CHANNEL_NAMES]
    return (f"{where}: its CHANNELS {n} (line {count_line}) names {' '.join(listed)}: {', '.join(bad)} "
            f"{'is not a channel name' if len(bad) == 1 else 'are not channel names'}; {valid}")


def parse_bvh(text: str, name: str = "<bvh>") -> Bvh:
    """Parse BVH text. Raises :class:`BvhError` naming the problem and where it is: ``line N`` (1-based, the
    file's lines), ``frame N`` (1-based, the first motion line is frame 1)."""
    tokens = text.split()
    pos = 0

    def at(index: int) -> str:
        return f"{name}: line {_line_of(text, index)}"

    def take() -> str:
        nonlocal pos
        if pos >= len(tokens):
            if not tokens:  # nothing at all: not a truncated file
                raise BvhError(f"{name}: empty file (a BVH starts with HIERARCHY)")
            raise BvhError(f"{name}: file ended early (truncated hierarchy or motion)")
        pos += 1
        return tokens[pos - 1]

    def expect(word: str) -> None:
        got = take()
        if got.upper() != word.upper():
            note = closed_note() if word == "MOTION" else ""
            raise BvhError(f"{at(pos - 1)}: expected {word!r}, found {got!r}{note}")

    def number(kind: type[float] | type[int] = float) -> float:
        word = take()
        try:
            return kind(word)
        except ValueError:
            raise BvhError(f"{at(pos - 1)}: expected {'a number' if kind is float else 'a whole number'}, "
                           f"found {word!r}") from None

    joints: list[BvhJoint] = []
    opened: list[int] = []  # token index of each joint's name, for messages
    root_closed: list[int] = []  # token index of the '}' that closed the root

    def closed_note() -> str:  # what MOTION missing after the hierarchy most likely means
        if root_closed:
            return f" (the root's block closed at line {_line_of(text, root_closed[0])}: an extra '}}' above?)"
        return ""

    expect("HIERARCHY")
    stack: list[int] = []
    word = take()
    if word.upper() != "ROOT":
        raise BvhError(f"{at(pos - 1)}: expected ROOT, found {word!r}")
    while True:
        if word.upper() in ("ROOT", "JOINT"):
            jname = take()
            opened.append(pos - 1)
            expect("{")
            expect("OFFSET")
            offset = np.array([number() for _ in range(3)])
            expect("CHANNELS")
            count_at = pos
            n = int(number(int))
            if not 0 <= n <= 6:
                raise BvhError(f"{at(count_at)}: joint {jname} has CHANNELS {n}: 0 to 6 expected")
            channels = []
            for k in range(n):
                channel = take()
                if channel.lower() not in CHANNEL_NAMES:
                    raise BvhError(_channel_problem(tokens, count_at, n, k, f"{at(pos - 1)}: joint {jname}",
                                                    _line_of(text, count_at)))
                channels.append(channel)
            parent = stack[-1] if stack else -1
            joints.append(BvhJoint(jname, offset, channels, parent))
            if parent >= 0:
                joints[parent].children.append(len(joints) - 1)
            stack.append(len(joints) - 1)
        elif word.upper() == "END":
            expect("Site")
            expect("{")
            expect("OFFSET")
            joints[stack[-1]].end_site = np.array([number() for _ in range(3)])
            expect("}")
        elif word == "}":
            stack.pop()
            if not stack:
                root_closed.append(pos - 1)
                break
        elif word.upper() == "MOTION":
            still = ", ".join(f"{joints[i].name} (line {_line_of(text, opened[i])})" for i in stack)
            raise BvhError(f"{at(pos - 1)}: MOTION before the hierarchy is closed: a '}}' is missing; still open: "
                           f"{still}")
        else:
            raise BvhError(f"{at(pos - 1)}: unexpected {word!r} in hierarchy (in joint {joints[stack[-1]].name}, "
                           f"line {_line_of(text, opened[stack[-1]])})")
        word = take()
    expect("MOTION")
    expect("Frames:")
    frames_at = pos
    frames = int(number(int))
    expect("Frame")
    expect("Time:")
    frame_time = float(number())
    if frames < 0:
        raise BvhError(f"{at(frames_at)}: Frames: {frames} is negative")
    width = sum(len(j.channels) for j in joints)
    values = tokens[pos:]
    if len(values) < frames * width:
        raise BvhError(f"{name}: truncated motion: {frames} frames x {width} channels announced, {len(values)} "
                       f"values found{_short_line(text, pos, width)}")
    try:
        motion = np.array(values[: frames * width], dtype=float).reshape(frames, width)
    except ValueError:
        k = next(i for i, v in enumerate(values[: frames * width]) if not _is_number(v))
        raise BvhError(f"{at(pos + k)}: motion frame {k // width + 1} of {frames}, channel {k % width + 1} "
                       f"({_channel(joints, k % width)}): {values[k]!r} is not a number") from None
    if not (frame_time > 0 and np.isfinite(frame_time)):  # "nan" and "inf" parse as floats
        raise BvhError(f"{name}: frame time must be a positive number of seconds, got {frame_time}")
    bad = [j.name for j in joints if not np.all(np.isfinite(j.offset))]
    if bad:
        raise BvhError(f"{name}: offset of joint {bad[0]} is not finite")
    if not np.all(np.isfinite(motion)):
        frame, column = (int(v) for v in np.argwhere(~np.isfinite(motion))[0])
        raise BvhError(f"{at(pos + frame * width + column)}: motion frame {frame + 1} of {frames} (frames counted "
                       f"from 1), channel {column + 1} ({_channel(joints, column)}) holds a value that is not finite "
                       f"({values[frame * width + column]!r})")
    return Bvh(joints, frame_time, motion)


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _channel(joints: list[BvhJoint], column: int) -> str:
    """``joint channel`` of motion column ``column`` (0-based)."""
    for j in joints:
        if column < len(j.channels):
            return f"{j.name} {j.channels[column]}"
        column -= len(j.channels)
    return "?"


def _short_line(text: str, first: int, width: int) -> str:
    """Where a truncated motion lost its values: the first motion line (from token ``first``) that does not hold
    ``width`` values, for the message ("" when every line does: the file just ends early)."""
    line = _line_of(text, first)
    for k, row in enumerate(text.split("\n")[line - 1:]):
        count = len(row.split())
        if count not in (0, width):
            return f"; line {line + k} holds {count} values, not {width}"
    return ""


def read_bvh(path: str | Path) -> Bvh:
    """The BVH file at ``path``; :class:`BvhError` (a ``ValueError``) naming the file for one that cannot be read,
    and for a path that is not a regular file (a folder, ``/dev/null``, a pipe: never opened, as a pipe without a
    writer would block)."""
    p = Path(path)
    problem = file_problem(p, "a BVH file")  # a folder or a device was "no such file" until 6 Dec
    if problem is not None:
        raise BvhError(f"{p}: {problem}")
    try:
        text = read_text(p)
    except ValueError as exc:  # a binary file: a BVH is text
        raise BvhError(f"{p}: not a BVH text file ({exc})") from None
    return parse_bvh(text, str(p))


def _num(v: float) -> str:
    text = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def write_bvh(bvh: Bvh) -> str:
    """BVH text of ``bvh`` (motion values with 3 decimals, trailing zeros trimmed)."""
    lines = ["HIERARCHY"]

    def emit(i: int, depth: int) -> None:
        j = bvh.joints[i]
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.5f}' for v in j.offset)}")
        lines.append(f"{pad}  CHANNELS {len(j.channels)} {' '.join(j.channels)}")
        for c in j.children:
            emit(c, depth + 1)
        if j.end_site is not None:
            lines.append(f"{pad}  End Site")
            lines.append(f"{pad}  {{")
            lines.append(f"{pad}    OFFSET {' '.join(f'{v:.5f}' for v in j.end_site)}")
            lines.append(f"{pad}  }}")
        lines.append(f"{pad}}}")

    emit(0, 0)
    lines.append("MOTION")
    lines.append(f"Frames: {len(bvh.motion)}")
    lines.append(f"Frame Time: {bvh.frame_time:.6f}")
    lines.extend(" ".join(_num(v) for v in row) for row in bvh.motion)
    return "\n".join(lines) + "\n"


def world_frames(bvh: Bvh) -> tuple[list[Rotation], list[np.ndarray]]:
    """Every joint's world orientation (a Rotation of length F) and position (F, 3), in file order.

    A joint's frame is its parent's turned by its rotation channels (degrees, intrinsic, in channel order); at
    zero rotation every frame is aligned with the file's axes (the rest pose of the offsets).
    """
    frames = len(bvh.motion)
    rots: list[Rotation] = []
    pos: list[np.ndarray] = []
    col = 0
    for j in bvh.joints:
        block = bvh.motion[:, col : col + len(j.channels)]
        col += len(j.channels)
        translation = np.zeros((frames, 3))
        axes = ""
        angles = []
        for k, ch in enumerate(j.channels):
            c = ch.lower()
            if c.endswith("position"):
                translation[:, "xyz".index(c[0])] = block[:, k]
            elif c.endswith("rotation"):
                axes += c[0].upper()
                angles.append(block[:, k])
        local = Rotation.from_euler(axes, np.stack(angles, axis=1), degrees=True) if axes else Rotation.identity(frames)
        if j.parent < 0:
            p = j.offset + translation
            r = local
        else:
            pr, pp = rots[j.parent], pos[j.parent]
            p = pp + pr.apply(np.tile(j.offset, (frames, 1)) + translation)
            r = pr * local
        rots.append(r)
        pos.append(p)
    return rots, pos


def rest_positions(bvh: Bvh) -> np.ndarray:
    """(J, 3) joint positions of the rest pose (every rotation zero, the root at its offset), file units."""
    out = np.zeros((len(bvh.joints), 3))
    for i, j in enumerate(bvh.joints):
        out[i] = j.offset + (out[j.parent] if j.parent >= 0 else 0.0)
    return out


def forward_kinematics(bvh: Bvh) -> dict[str, np.ndarray]:
    """World positions (F, 3) of every joint and of each end site (named ``<joint>_end``)."""
    frames = len(bvh.motion)
    rots, pos = world_frames(bvh)
    out: dict[str, np.ndarray] = {}
    for j, r, p in zip(bvh.joints, rots, pos, strict=True):
        out[j.name] = p
        if j.end_site is not None:
            out[f"{j.name}_end"] = p + r.apply(np.tile(j.end_site, (frames, 1)))
    return out
