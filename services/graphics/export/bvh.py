"""BVH export: the body's joint hierarchy and one motion frame per pose.

The tree comes from the link names (:func:`services.graphics.skeleton.guess_parents`);
links that are no body part (kit links) are left out. BVH is y-up, so the
Batteur frame (z up, drummer facing +y) is turned, as ``facing`` (``batteur render --bvh-facing``) says
(:data:`Y_UP`): ``+z`` (the default since 8 Dec), ``(x, y, z) -> (-x, z, y)``, the drummer facing +z with his left
at +x, as the glTF of the same render (services/graphics/export/gltf.py ``ROOT_ROTATION``) and CMU's and Mixamo's
clips; or ``-z`` (every file until 8 Dec), ``(x, y, z) -> (x, z, -y)``, facing -z: a CMU or Mixamo clip needs a
half turn about y to match it, and Blender's BVH import shows his back to the front camera. Units are metres by default
(``scale=100`` writes centimetres). Joint offsets are the first frame's
parent-to-child offsets; the root has position and rotation channels, the
other joints rotations only (degrees), or positions too with ``all_positions=True`` (exact even for non-rigid
input). A joint's rotation channels ``A B C`` mean ``R = Ra Rb Rc`` (intrinsic, as Blender and three.js read them).

Each joint has its own channel order (:func:`rotation_orders`), chosen from the joint's range of motion so that its
middle angle stays far from +-90 degrees, where two channels turn about the same axis (gimbal lock: the forearm,
flexed past 90 degrees in ZXY, made steps of 80-100 degrees between frames in two channels that cancelled). For
physics' character that is mostly ``Xrotation Zrotation Yrotation``: its joints turn their child by
``Rx Ry Rz`` in z up, which is ``Rx Rz Ry`` in the file's y up, so each channel is one of the joint's angles
(facing +z, the X channel its x angle negated; facing -z, the Z channel its y angle negated). Other skeletons keep
``Zrotation Xrotation Yrotation``.

The legs of physics' character hang from the throne, not from the pelvis: each thigh turns on its hip mount, a base
fixed on the throne where the hip joint centre is at rest, and the pelvis rocks on the seat point without swinging
them (common/character.py ``HIP_MOUNTS``). So for that character the file has one joint more than the links,
``seat`` (``THRONE_JOINT``): the pelvis' child at the seat point (the pelvis' origin: the seat joint has no offset),
turned back by the pelvis' rotation so that its frame is the throne's (the world's: physics loads every base
unrotated), and the thighs are its children, their offsets the hip mounts' from the seat point. Hung from the
pelvis with the first frame's offsets, the hips swung with the pelvis: when it rocked (the demo's fill) the file
put the legs up to 9.4 cm from physics'. The thighs' rotations are then the hip joints' own (relative to the
throne), and the thighs stay the pelvis' descendants (readers that look for the legs under the hips find them).
(With physics' ``--floating-base`` the trunk's base, pinned to the throne, gives a little and the legs' bases do
not: the thighs are then off by that give.)

Each joint's angles are kept continuous from frame to frame: of the angle sets that give its rotation (any angle plus
whole turns, and ``(a + 180, 180 - b, c + 180)``), the one nearest the previous frame's, so a channel never jumps by
a turn (a forearm turning past 180 degrees read -179 after 179: a tool interpolating the channels spun it all the
way round).

End Sites (where Blender and Maya put the tail of a last bone): for physics' character, a stick's is its tip (the
bead's centre, physics' ``<side>_stick_tip`` link), so the stick bone runs along the stick; a foot's is the ball of
the foot (physics' ``<side>_foot_ball``), so the foot bone points along the foot to the toes. They are the body's
own when the writer is given them (``end_sites``: ``batteur render`` passes those of the body physics built, whose
ball of the foot follows ``--height``, not the shank a ``--skeleton-bvh`` gives). Without them (an export that
does not know the body's geometry, e.g. the viewer's) they are guessed from the character snapshot
(:func:`services.graphics.poser.load_character`), the foot's scaled with the body's shank: exact for a body of the
table's proportions (any ``--height``), off for a skeleton's shank (3.1 cm for 0.52 m shanks on a 1.75 m body).
Other leaves continue their bone by a quarter.
"""

from __future__ import annotations

import itertools
import shutil
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from common.character import BASE_LINK, DOF_NAMES, HELD_LINKS, HIP_MOUNTS, JOINT_LINKS
from services.graphics.poser import CharacterInfo, is_character, load_character
from services.graphics.sequence import PoseSequence, interpolate_pose
from services.graphics.skeleton import body_links, guess_parents

BvhFacing = Literal["+z", "-z"]
"""Which way the drummer faces in a BVH file (y up): ``+z`` (the glTF's way) or ``-z`` (the files until 8 Dec)."""
BVH_FACINGS: tuple[BvhFacing, ...] = ("+z", "-z")
DEFAULT_FACING: BvhFacing = "+z"
Y_UP: dict[str, np.ndarray] = {
    "+z": np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]),
    "-z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}
"""Facing -> the matrix mapping Batteur world vectors (z up, the drummer facing +y) to the file's (y up): ``+z``:
(x, y, z) -> (-x, z, y), glTF's (the drummer facing +z, his left at +x); ``-z``: (x, y, z) -> (x, z, -y). The two
differ by a half turn about y, which negates the x and z angle channels and leaves each joint's middle angle's size
as it is: the channel orders (:func:`rotation_orders`, chosen with ``-z``'s) are the same for both facings."""
Z_UP_TO_Y_UP = Y_UP["-z"]
"""``-z``'s matrix, with which the channel orders are chosen (the same for either facing, see :data:`Y_UP`)."""

DEFAULT_ORDER = "ZXY"
"""Rotation channel order of a joint that is not one of physics' character (and of every joint until 7 Dec)."""
ROTATION_ORDERS = ("XZY", "ZXY", "XYZ", "YXZ", "YZX", "ZYX")
"""Channel orders a joint may get, preferred first: XZY, the character's own (its channels are the joint's angles),
then ZXY, the order of other skeletons."""
GIMBAL_MARGIN_DEG = 25.0
"""A joint's order keeps its middle angle at least this far from +-90 degrees over the joint's range of motion
(near +-90 the first and last channels turn about nearly the same axis: small turns of the joint need large,
opposite steps of the two)."""
ROM_SAMPLES = 9
"""Angles sampled per degree of freedom across its limits (9^3 rotations per joint)."""
STICK_PLAY_DEG = 45.0
"""How far a stick turns in the fingers about each of its two fulcrum axes (x, then z), degrees: physics' fulcrum
limits (+-0.8 rad); the snapshot has the stick's rest orientation in the hand, not these limits."""

_JOINT_OF_LINK = {child: joint for joint, (_, child) in JOINT_LINKS.items()}
"""Link -> the joint of physics' character that turns it relative to its parent (the pelvis: ``seat``)."""
THRONE_JOINT = BASE_LINK
"""The joint the file adds for physics' character: the throne's frame at the seat point, the pelvis' child and the
thighs' parent (see the module docstring); named as physics' trunk base, which no pose carries."""
PELVIS_LINK = next(child for parent, child in JOINT_LINKS.values() if parent == BASE_LINK)
"""The link that turns on the seat point (the pelvis): the throne joint's parent, at its origin."""
ON_THRONE = tuple(child for parent, child in JOINT_LINKS.values() if parent in HIP_MOUNTS.values())
"""Links of physics' character whose joint's parent is fixed on the throne (the thighs): the throne joint's
children."""
EndSites = Mapping[str, Sequence[float]]
"""Leaf link -> its End Site: the offset (3,) of its tip, metres, in the link's frame (Batteur's axes, z up)."""


def _y_up(rotations: Rotation) -> Rotation:
    """Batteur-frame rotations (z up) as the file's (y up)."""
    return Rotation.from_matrix(Z_UP_TO_Y_UP @ rotations.as_matrix() @ Z_UP_TO_Y_UP.T)


def range_of_motion(link: str, info: CharacterInfo | None = None) -> Rotation | None:
    """Rotations (y up) that ``link`` of physics' character takes relative to its parent in the BVH tree, sampled
    across its joint's limits (``ROM_SAMPLES`` per DOF); None for a link the character does not move.

    A joint turns its child by ``Rx(x) Ry(y) Rz(z)`` from the parent's frame (common/character.py), so the samples
    are those rotations over the limit box of ``info`` (default: the shipped snapshot, physics' default limits).
    The pelvis turns on the seat and a thigh on its hip mount, both the throne's frame, which the file has as the
    world's and as its throne joint's (``THRONE_JOINT``, whose rotation is the pelvis' undone: the pelvis' range
    inverted). A stick (held by its hand, no actuated DOF) takes its rest orientation in the hand (the grip's tilt,
    from the snapshot's rest pose) turned by up to ``STICK_PLAY_DEG`` about its fulcrum's x and z axes.
    """
    info = info or load_character()
    if link == THRONE_JOINT:
        pelvis = range_of_motion(PELVIS_LINK, info)
        return None if pelvis is None else pelvis.inv()
    if link in _JOINT_OF_LINK:
        joint = _JOINT_OF_LINK[link]
        grids = []
        for axis in "xyz":
            k = DOF_NAMES.index(f"{joint}_{axis}")
            grids.append(np.linspace(np.degrees(info.lower[k]), np.degrees(info.upper[k]), ROM_SAMPLES))
        return _y_up(Rotation.from_euler("XYZ", np.array(list(itertools.product(*grids))), degrees=True))
    if link in HELD_LINKS and link in info.names and HELD_LINKS[link] in info.names:
        rest = info.rest
        held, carrier = info.names.index(link), info.names.index(HELD_LINKS[link])
        in_hand = Rotation.from_quat(rest[carrier, 3:]).inv() * Rotation.from_quat(rest[held, 3:])
        play = np.linspace(-STICK_PLAY_DEG, STICK_PLAY_DEG, ROM_SAMPLES)
        turns = Rotation.from_euler("XZ", np.array(list(itertools.product(play, play))), degrees=True)
        return _y_up(in_hand * turns)
    return None


def choose_rotation_order(motion: list[Rotation]) -> str:
    """The channel order for a joint whose range of motion is sampled by ``motion`` (rotations, y up; e.g. both
    sides' of a mirrored pair, so both get the same order).

    The first of ``ROTATION_ORDERS`` whose middle angle stays within 90 - ``GIMBAL_MARGIN_DEG`` degrees of 0 over
    every sample; if none does, the one with the fewest samples beyond that (then the smallest largest middle
    angle, then the preferred)."""
    limit = 90.0 - GIMBAL_MARGIN_DEG
    scored: list[tuple[float, float, int, str]] = []
    for rank, order in enumerate(ROTATION_ORDERS):
        with warnings.catch_warnings():  # gimbal lock: scipy warns, the middle angle is still right
            warnings.simplefilter("ignore", UserWarning)
            middle = np.concatenate([np.abs(r.as_euler(order, degrees=True)[:, 1]) for r in motion])
        worst = float(middle.max())
        if worst <= limit:
            return order
        scored.append((float(np.mean(middle > limit)), worst, rank, order))
    return min(scored)[3]


def _mirror(name: str) -> str | None:
    for a, b in (("left_", "right_"), ("right_", "left_")):
        if name.startswith(a):
            return b + name[len(a):]
    return None


def rotation_orders(names: list[str], info: CharacterInfo | None = None) -> dict[str, str]:
    """Rotation channel order of each body link among ``names`` (link -> e.g. ``"XZY"``, file axes, y up).

    For physics' character (:func:`services.graphics.poser.is_character`) each joint's order is chosen from its
    range of motion (:func:`range_of_motion`, :func:`choose_rotation_order`; a left and a right joint together),
    which depends on the joints' limits and rest orientations only, never on a performance: every file of the
    character has the same header; its throne joint (``THRONE_JOINT``) too. Other skeletons: ``DEFAULT_ORDER``
    for every joint."""
    body = [names[i] for i in body_links(names)]
    if not is_character(names):
        return {name: DEFAULT_ORDER for name in body}
    body.append(THRONE_JOINT)
    info = info or load_character()
    orders: dict[str, str] = {}
    for name in body:
        pair = [n for n in (name, _mirror(name)) if n is not None]
        motion = [m for m in (range_of_motion(n, info) for n in pair) if m is not None]
        orders[name] = choose_rotation_order(motion) if motion else DEFAULT_ORDER
    return orders


@dataclass(frozen=True)
class BvhInfo:
    """What :func:`write_bvh` wrote.

    Attributes
    ----------
    joints : list of str
        Joint names in file order (the root first); for physics' character also ``THRONE_JOINT``, which is no link.
    frames : int
        Motion frames.
    frame_time : float
        Seconds per frame.
    skipped : list of str
        Links left out (not part of the body tree).
    max_error : float
        Largest distance between a joint placed by the file's forward kinematics (its channels before they are
        rounded to 6 decimals) and its input position, in the file's units (0 up to float rounding for a rigid
        body).
    """

    joints: list[str]
    frames: int
    frame_time: float
    skipped: list[str]
    max_error: float


def joint_tree(names: list[str], parents: list[int],
               body_list: list[int]) -> tuple[int, list[int], dict[int, list[int]]]:
    """The joint tree of the body links ``body_list`` (indices into ``names``; ``parents[i]`` the parent's index,
    -1 for none): its root (a pelvis, root or hips link first), the joints in depth-first order (a BVH's) and each
    joint's children. The BVH and the glTF skin share it, so their joints agree."""
    body = set(body_list)
    roots = [i for i in body if parents[i] < 0]
    if not roots:
        raise ValueError("no body root link (pelvis/root/hips) among the link names")
    root = min(roots, key=lambda i: (0 if "pelvis" in names[i] or "root" in names[i] else 1, i))
    children: dict[int, list[int]] = {i: [] for i in range(len(names))}
    for i, p in enumerate(parents):
        if p >= 0 and i in body:
            children[p].append(i)
    order: list[int] = []
    stack = [root]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children[i]))
    return root, order, {i: children[i] for i in order}


class _Layout:
    """The BVH hierarchy of a sequence's links, fixed by its first frame, and the motion channels it gives frames
    converted in order (a frame's angles continue from the previous frame's, so frames can be converted in chunks,
    one after the other)."""

    def __init__(self, names: list[str], first_frame: np.ndarray, scale: float, all_positions: bool,
                 end_sites: EndSites | None = None, facing: BvhFacing = DEFAULT_FACING) -> None:
        if facing not in Y_UP:
            raise ValueError(f"BVH facing {facing!r}: {' or '.join(BVH_FACINGS)} expected")
        self.axes = Y_UP[facing]
        """Batteur (z up) to the file's axes (y up), as ``facing`` says (:data:`Y_UP`)."""
        self.end_sites = {} if end_sites is None else {link: np.asarray(offset, dtype=float)
                                                       for link, offset in end_sites.items()}
        """Leaf link -> its End Site given by the caller (metres, the link's frame, z up)."""
        self.parents = guess_parents(names)
        body = body_links(names)
        self.character = load_character() if is_character(names) else None
        """Physics' character snapshot when the skeleton is that character's (its End Sites and orders)."""
        self.throne: int | None = None
        """Index of the throne joint (``THRONE_JOINT``, after the links) for physics' character, else None."""
        self.pelvis = -1
        if self.character is not None and THRONE_JOINT not in names:
            self.throne, self.pelvis = len(names), names.index(PELVIS_LINK)
            names = [*names, THRONE_JOINT]
            self.parents.append(self.pelvis)
            for link in ON_THRONE:
                self.parents[names.index(link)] = self.throne
            body = [*body, self.throne]
        self.names = names
        self.scale = scale
        self.all_positions = all_positions
        self.root, self.order, self.children = joint_tree(names, self.parents, body)
        pos, rots = self._world(first_frame[None])
        self.first = {i: Rotation.from_quat(rots[i].as_quat()[0]) for i in self.order}
        self.offsets: dict[int, np.ndarray] = {}
        for i in self.order:
            self.offsets[i] = (np.zeros(3) if i == self.root
                               else self.first[self.parents[i]].inv().apply(pos[0, i] - pos[0, self.parents[i]]))
        self._previous: dict[int, np.ndarray] = {}
        """Each joint's angles (degrees) in the last frame converted: the next frames continue from them."""
        by_name = rotation_orders(names, self.character)
        self.orders: dict[int, str] = {i: by_name.get(names[i], DEFAULT_ORDER) for i in self.order}
        """Each joint's rotation channel order (intrinsic, file axes), e.g. ``"XZY"``."""
        self.hierarchy: list[str] = ["HIERARCHY"]
        self.channel_order: list[int] = []
        """Links in the order their channels appear in a motion row."""
        self._emit(self.root, 0)

    @classmethod
    def of(cls, names: list[str], first_frame: np.ndarray, scale: float = 1.0, all_positions: bool = False,
           end_sites: EndSites | None = None, facing: BvhFacing = DEFAULT_FACING) -> _Layout:
        return cls(list(names), np.asarray(first_frame, dtype=float), scale, all_positions, end_sites, facing)

    def _world(self, values: np.ndarray) -> tuple[np.ndarray, dict[int, Rotation]]:
        """Positions (N, J, 3) in file units and orientations of the body's joints, y up, of frames ``values``
        (N, L, 7): the links', then the throne joint's (if any: at the pelvis' origin, the world's orientation)."""
        if self.throne is not None:
            throne = np.zeros((len(values), 1, 7))
            throne[:, 0, :3] = values[:, self.pelvis, :3]
            throne[:, 0, 6] = 1.0
            values = np.concatenate([values, throne], axis=1)
        c = self.axes
        pos = values[:, :, :3] @ c.T * self.scale  # (N, L, 3)
        rots = {i: Rotation.from_matrix(c @ Rotation.from_quat(values[:, i, 3:]).as_matrix() @ c.T)
                for i in self.order}
        return pos, rots

    def _emit(self, i: int, depth: int) -> None:
        lines = self.hierarchy
        pad = "  " * depth
        kind = "ROOT" if i == self.root else "JOINT"
        lines.append(f"{pad}{kind} {self.names[i]}")
        lines.append(f"{pad}{{")
        ox, oy, oz = self.offsets[i]
        lines.append(f"{pad}  OFFSET {ox:.6f} {oy:.6f} {oz:.6f}")
        rot = " ".join(f"{axis}rotation" for axis in self.orders[i])
        if i == self.root or self.all_positions:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {rot}")
        else:
            lines.append(f"{pad}  CHANNELS 3 {rot}")
        self.channel_order.append(i)
        if self.children[i]:
            for child in self.children[i]:
                self._emit(child, depth + 1)
        else:
            tip = self.end_site(i)
            lines.append(f"{pad}  End Site")
            lines.append(f"{pad}  {{")
            lines.append(f"{pad}    OFFSET {tip[0]:.6f} {tip[1]:.6f} {tip[2]:.6f}")
            lines.append(f"{pad}  }}")
        lines.append(f"{pad}}}")

    def end_site(self, i: int) -> np.ndarray:
        """The End Site of leaf joint ``i`` in its own frame, file units (see the module docstring): the one given
        (``end_sites``), else for physics' character its snapshot's effector, a body segment's scaled as its bone
        (a guess: the body's real geometry is not known here), else the bone continued by a quarter."""
        name, scale = self.names[i], self.scale
        if name in self.end_sites:
            return np.asarray(self.axes @ self.end_sites[name] * scale, dtype=float)
        info = self.character
        effector = None if info is None else next((offset for link, offset in info.effectors.values()
                                                   if link == name), None)
        if info is not None and effector is not None:
            size = 1.0
            if name not in HELD_LINKS and i != self.root:  # a body segment: as the body's size (a stick: as it is)
                parent = self.names[self.parents[i]]
                if parent in info.names:
                    rest = info.rest
                    shipped = float(np.linalg.norm(rest[info.names.index(name), :3]
                                                   - rest[info.names.index(parent), :3]))
                    size = float(np.linalg.norm(self.offsets[i])) / scale / shipped if shipped > 1e-6 else 1.0
            return np.asarray(self.axes @ effector * size * scale, dtype=float)
        offset = self.offsets[i]
        tip = offset * 0.25 if np.linalg.norm(offset) > 1e-6 else np.array([0.0, 0.05 * scale, 0.0])
        return self.first[i].inv().apply(self.first[self.parents[i]].apply(tip)) if i != self.root else tip

    def header(self, frames: int, frame_time: float) -> list[str]:
        """The file's lines before its motion rows (``frame_time``: seconds)."""
        return [*self.hierarchy, "MOTION", f"Frames: {frames}", f"Frame Time: {frame_time:.8f}"]

    def forward_kinematics(self, motion: np.ndarray) -> dict[int, np.ndarray]:
        """Each joint's position (N, 3), file units, placed by motion rows ``motion`` (N, channels) as a BVH
        reader places it: offsets (or position channels) turned by the parents' rotation channels."""
        world_r: dict[int, Rotation] = {}
        world_p: dict[int, np.ndarray] = {}
        column = 0
        for i in self.channel_order:  # parents before children
            if i == self.root or self.all_positions:
                position, column = motion[:, column:column + 3], column + 3
            else:
                position = np.tile(self.offsets[i], (len(motion), 1))
            local = Rotation.from_euler(self.orders[i], motion[:, column:column + 3], degrees=True)
            column += 3
            if i == self.root:
                world_r[i], world_p[i] = local, np.array(position)
            else:
                p = self.parents[i]
                world_r[i], world_p[i] = world_r[p] * local, world_p[p] + world_r[p].apply(position)
        return world_p

    def motion(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[int, Rotation]]:
        """Motion rows (N, channels) of frames ``values`` (N, L, 7), with their positions and orientations."""
        pos, rots = self._world(values)
        root, parents = self.root, self.parents
        cols: list[np.ndarray] = []
        for i in self.channel_order:
            if i == root or self.all_positions:
                cols.append(pos[:, i] if i == root else rots[parents[i]].inv().apply(pos[:, i] - pos[:, parents[i]]))
            local = rots[i] if i == root else rots[parents[i]].inv() * rots[i]
            with warnings.catch_warnings():  # at gimbal lock scipy picks one of the equivalent angle sets: still exact
                warnings.simplefilter("ignore", UserWarning)
                angles = _continuous(local.as_euler(self.orders[i], degrees=True), self._previous.get(i))
            self._previous[i] = angles[-1]
            cols.append(angles)
        return np.concatenate(cols, axis=1), pos, rots


def _continuous(angles: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """Euler angles (N, 3) of one joint, degrees, in any order of three different axes, made continuous: per frame,
    of the sets giving the same rotation (whole turns added to any angle; ``(a + 180, 180 - b, c + 180)``), the
    nearest the previous frame's. The first frame is kept as it is when no ``previous`` (the last frame of the chunk
    before) is given."""
    out = angles.copy()
    prev = None if previous is None else [float(v) for v in previous]
    for k in range(len(out)):
        z, x, y = (float(v) for v in out[k])
        if prev is None:
            prev = [z, x, y]
            continue
        best, best_cost = prev, float("inf")
        for cand in ((z, x, y), (z + 180.0, 180.0 - x, y + 180.0)):
            near = [c + 360.0 * round((p - c) / 360.0) for c, p in zip(cand, prev, strict=True)]
            cost = sum(abs(c - p) for c, p in zip(near, prev, strict=True))
            if cost < best_cost:
                best, best_cost = near, cost
        out[k] = best
        prev = best
    return out


def _rows(motion: np.ndarray) -> list[str]:
    return [" ".join(f"{v:.6f}" for v in row) for row in motion]


def write_bvh(sequence: PoseSequence, path: Path, rate_hz: float | None = None, scale: float = 1.0,
              all_positions: bool = False, start: float | None = None, end: float | None = None,
              end_sites: EndSites | None = None, facing: BvhFacing = DEFAULT_FACING) -> BvhInfo:
    """Write ``sequence`` as a BVH file at ``path``.

    Parameters
    ----------
    sequence : PoseSequence
        World link poses (metres, z up).
    path : Path
        Output file.
    rate_hz : float, optional
        Frame rate; default: the sequence's own (its median pose interval). The sequence is resampled.
    scale : float
        File units per metre (1: metres, 100: centimetres).
    all_positions : bool
        Give every joint position channels too.
    start : float, optional
        Time of frame 0, seconds (default: the first pose's); frames before the first pose hold it.
    end : float, optional
        Time the frames go up to, inclusive, seconds (default: the last pose's); frames past the last pose hold it.
    end_sites : mapping, optional
        Leaf link -> its End Site, metres in the link's frame (z up), e.g. a stick's tip and a foot's ball as
        physics built the body; leaves not given: from the character snapshot, scaled (see the module docstring).
    facing : str
        Which way the drummer faces in the file, y up: ``+z`` (the default, the glTF's) or ``-z`` (the files until
        8 Dec); :data:`Y_UP`.
    """
    if rate_hz is None:
        dt = float(np.median(np.diff(sequence.times))) if len(sequence.times) > 1 else 1 / 60
        rate_hz = 1.0 / dt
    seq = sequence.resample(rate_hz, start=start, end=end)
    layout = _Layout.of(seq.names, seq.values[0], scale, all_positions, end_sites, facing)
    motion, pos, _ = layout.motion(seq.values)
    frame_time = 1.0 / rate_hz
    lines = layout.header(len(seq.times), frame_time)
    lines += _rows(motion)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    # forward kinematics of what was written (its angles, before rounding), against the input (reports non-rigid
    # input, and a channel order the angles were not taken in)
    placed = layout.forward_kinematics(motion)
    error = max(float(np.abs(placed[i] - pos[:, i]).max()) for i in layout.order)
    order = layout.order
    skipped = [n for k, n in enumerate(seq.names) if k not in set(order)]
    return BvhInfo([layout.names[i] for i in order], len(seq.times), frame_time, skipped, error)


class BvhStream:
    """Writes a BVH file as poses arrive, holding a few seconds of them, not the whole motion.

    The same bytes as :func:`write_bvh` given the whole sequence at ``rate_hz`` (and ``start``): frame ``k`` is
    the pose at ``t0 + k / rate_hz`` (``t0``: ``start``, seconds, or by default the first pose's time),
    interpolated as :meth:`PoseSequence.sample` does (frames before the first pose hold it), and the frames up to
    the last pose's time (or :meth:`finish`'s ``end``, as :func:`write_bvh`'s). Motion rows go to ``path`` +
    ``.motion`` (next to ``path``) in chunks of ``chunk_frames``; :meth:`finish` writes the header, whose frame count
    is known only then, and appends them. Poses must come in strictly increasing time (seconds) with the link
    layout given to :meth:`restart`. ``end_sites`` and ``facing``: as :func:`write_bvh`'s.
    """

    def __init__(self, path: Path, rate_hz: float, scale: float = 1.0, all_positions: bool = False,
                 chunk_frames: int = 240, start: float | None = None, end_sites: EndSites | None = None,
                 facing: BvhFacing = DEFAULT_FACING) -> None:
        if not rate_hz > 0:
            raise ValueError(f"BVH frame rate must be > 0 Hz, got {rate_hz}")
        if facing not in Y_UP:
            raise ValueError(f"BVH facing {facing!r}: {' or '.join(BVH_FACINGS)} expected")
        self.facing = facing
        self.path = Path(path)
        self.motion_path = self.path.with_name(self.path.name + ".motion")
        self.rate_hz = rate_hz
        self.scale = scale
        self.all_positions = all_positions
        self.chunk_frames = chunk_frames
        self.start = start
        self.end_sites = end_sites
        self.peak_held_frames = 0
        """Most resampled frames held in memory at once (at most ``chunk_frames``): what the stream keeps."""
        self._file: IO[str] | None = None
        self.restart([])

    def restart(self, names: list[str]) -> None:
        """Start again with these link names (a new skeleton): the frames written so far are dropped."""
        self.names = list(names)
        self._layout: _Layout | None = None
        self._t0 = 0.0
        self._last: tuple[float, np.ndarray] | None = None  # newest pose: (time s, (L, 7))
        self._next = 0  # index of the next frame to produce
        self._frames: list[np.ndarray] = []  # produced, not yet converted and written
        self._written = 0
        self.valid = True
        """False once a pose was not finite (or the names not unique): no file, as PoseSequence refuses them."""
        if len(set(self.names)) != len(self.names):
            self.valid = False
        if self._file is not None:
            self._file.seek(0)
            self._file.truncate()

    @property
    def frames(self) -> int:
        """Frames produced so far."""
        return self._next

    @property
    def start_time(self) -> float | None:
        """Time of frame 0, seconds (None until a pose came)."""
        return None if self._last is None else self._t0

    def add(self, time: float, values: np.ndarray) -> None:
        """The pose (L, 7) at rig time ``time`` (seconds, after the previous pose's)."""
        if not self.valid:
            return
        if not np.all(np.isfinite(values)):
            self.valid = False
            return
        if self._last is None:
            self._t0 = time if self.start is None else self.start
            while self._t0 + self._next / self.rate_hz <= time:  # up to the first pose: itself (sample clamps)
                self._frame(values.copy())
        else:
            t_prev, prev = self._last
            while (t := self._t0 + self._next / self.rate_hz) < time:
                u = (t - t_prev) / (time - t_prev)
                self._frame(interpolate_pose(prev, values, float(u)))
        self._last = (time, values)

    def _frame(self, frame: np.ndarray) -> None:
        self._next += 1
        self._frames.append(frame)
        self.peak_held_frames = max(self.peak_held_frames, len(self._frames))
        if len(self._frames) >= self.chunk_frames:
            self._flush()

    def _flush(self) -> None:
        if not self._frames:
            return
        values = np.stack(self._frames)
        if self._layout is None:
            self._layout = _Layout.of(self.names, values[0], self.scale, self.all_positions, self.end_sites,
                                      self.facing)
        if self._file is None:
            self._file = self.motion_path.open("w+", encoding="utf-8", newline="\n")
        motion, _, _ = self._layout.motion(values)
        self._file.writelines(row + "\n" for row in _rows(motion))
        self._written += len(self._frames)
        self._frames = []

    def finish(self, end: float | None = None) -> int | None:
        """Write the file; returns its frame count (None, and no file, when no valid pose came).

        ``end``: the time (seconds) the frames go up to, inclusive, as :meth:`PoseSequence.resample_times`'
        (frames made past it are left out, the last pose is held up to it); None: the last pose's time."""
        try:
            if self._last is None or not self.valid:
                return None
            t_end, last = self._last
            count = max(1, int(np.floor(((t_end if end is None else end) - self._t0) * self.rate_hz + 1e-9)) + 1)
            if count < self._next and end is None:
                raise RuntimeError(f"BVH stream produced {self._next} frames, more than the {count} of its span")
            while self._next < count:  # at or past the last pose: the last pose (PoseSequence.sample clamps)
                self._frame(last.copy())
            self._flush()
            assert self._layout is not None and self._file is not None
            with self.path.open("w", encoding="utf-8", newline="\n") as out:
                out.write("\n".join(self._layout.header(count, 1.0 / self.rate_hz)) + "\n")
                self._file.seek(0)
                if count == self._written:
                    shutil.copyfileobj(self._file, out)
                else:  # frames past ``end``: one row each
                    out.writelines(itertools.islice(self._file, count))
            return count
        finally:
            self.close()

    def close(self) -> None:
        """Drop the motion rows' file (idempotent; :meth:`finish` does it)."""
        if self._file is not None:
            self._file.close()
            self._file = None
        self.motion_path.unlink(missing_ok=True)
