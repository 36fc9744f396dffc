"""glTF 2.0 export (binary .glb or .gltf with embedded data) with ``pygltflib``.

The body is a skeleton and a skin (:mod:`services.graphics.export.gltf_skin`): a joint node per body link in the
BVH's tree, animated by its local rotation (linear interpolation, one key per pose), a stick's tip a joint more
(``<stick>_tip``, unanimated, at the bead's centre: what the BVH has as the stick's End Site, so an importer gives
the stick bone its length), and the links' shapes as one mesh skinned to them, weight 1 to their link's joint: a
body link a box along its segment (from its joint to its child joints), a stick a 12-sided rod along its link's +y
from the butt to the tip (:func:`_stick_shape`). Other links (the kit's) are nodes animated by their pose's
translation and rotation. All hang from a root node that turns the Batteur frame (z up, the drummer facing +y) into
glTF's (y up, the asset's front facing +z, as the glTF 2.0 spec has it: the drummer faces +z, the kit in front of
him at +z, his left at +x; :data:`ROOT_ROTATION`). The kit
is added as meshes (cylinders for drums, thin discs for cymbals, boxes for the rest) so
the file shows the whole scene in Blender, three.js or any viewer: static,
except the objects whose motion the sequence carries as physics' kit links
(``kit.ride``: a cymbal's swing, ``kit.hihat.top``: the hi-hat opening,
``kit.kick_pedal.footboard``: a pedal pressed), whose mesh is the child of that
animated link node instead of its box; a bass-drum pedal's beater (``kit.kick_pedal.beater``) is drawn as a rod
and a ball, the stands (``kit.stands``) as rods under the drums and cymbals. Units: metres. Key times are
seconds from ``time_origin`` (a render's: performance.wav's time 0, so the two line up in an animation tool).
Given the impacts, each struck drum head, cymbal or hi-hat top plate gets a thin emissive disc shown at its impacts
(:mod:`services.graphics.export.gltf_flash`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pygltflib
from scipy.spatial.transform import Rotation

from common.kit import (
    STAND_ROD_RADIUS_M,
    Kit,
    KitObject,
    kit_hardware,
    stand_rods,
)
from services.graphics.export import gltf_flash
from services.graphics.export.gltf_skin import Skeleton, continuous_quats
from services.graphics.sequence import PoseSequence, normalize_quats

FLOAT, USHORT, UBYTE = pygltflib.FLOAT, pygltflib.UNSIGNED_SHORT, pygltflib.UNSIGNED_BYTE
ROOT_ROTATION = [0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0]
"""The root node's rotation (x y z w): Batteur's (x, y, z) -> glTF's (-x, z, y), 180 degrees about (0, 1, 1). z up
becomes y up and the drummer, facing +y, faces +z (glTF 2.0: "the front of a glTF asset faces +Z"; Blender's and
three.js's importers follow it). Until 7 Dec it was -90 degrees about x, (x, z, -y): the drummer faced -z, so a
viewer's front view showed his back."""

COLOURS = {
    "body": [0.31, 0.53, 0.78, 1.0], "stick": [0.85, 0.7, 0.48, 1.0], "membrane": [0.55, 0.11, 0.14, 1.0],
    "cymbal": [0.79, 0.64, 0.23, 1.0], "other": [0.6, 0.6, 0.63, 1.0], "felt": [0.88, 0.86, 0.8, 1.0],
}
CYMBAL_DRAWN_THICKNESS_M = 0.01
"""A cymbal's or hi-hat plate's drawn thickness, metres (thicker than physics' 2 mm, to be seen)."""
STICK_TIP_M = 0.2695
"""Fulcrum (the stick link's origin) to the tip bead's centre along the stick link's +y, metres: physics' 5A stick
(services/physics/sticks.py ``StickSpec.tip_offset``), used when the caller gives no End Site for the stick."""
STICK_GRIP_M = 0.13
"""Fulcrum to the butt, metres (``StickSpec.grip_m``)."""
STICK_BEAD_RADIUS_M = 0.0065
"""The tip bead's radius, metres (``StickSpec.tip_radius_m``): the drawn rod ends this far past the tip joint."""
STICK_DIAMETER_M = 0.0146
"""The drawn rod's diameter, metres (twice ``StickSpec.radius_m``)."""



@dataclass(frozen=True)
class GltfInfo:
    """What :func:`write_gltf` wrote: links (body links as joints, kit links as nodes), kit objects drawn, keyframes,
    duration (seconds), kit objects moved by their links (of ``kit_objects``), the skin's joints."""

    links: int
    kit_objects: int
    keyframes: int
    duration: float
    animated_kit_objects: int = 0
    joints: int = 0
    """Joint nodes of the skin (the body links in the BVH's tree, its ``seat`` joint for physics' character, and a
    ``<stick>_tip`` joint per stick whose tip is no link)."""
    flashes: int = 0
    """Struck kit objects drawn with a flash (:mod:`services.graphics.export.gltf_flash`)."""


def _box() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit cube (edge 1) centred on the origin: positions (24, 3), normals (24, 3), indices (36,)."""
    pos: list[np.ndarray] = []
    nor: list[np.ndarray] = []
    idx: list[int] = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            # the face's two other axes, u x v = n (counter-clockwise seen from outside); until 7 Dec the x and y
            # faces took their own normal as a tangent: the "cube" spanned 2 x 2 x 1, four faces misplaced
            u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]
            if sign < 0:
                u, v = v, u
            base = len(pos)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos.append(0.5 * n + 0.5 * a * u + 0.5 * b * v)
                nor.append(n)
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return np.array(pos, np.float32), np.array(nor, np.float32), np.array(idx, np.uint16)


def _cylinder(segments: int = 32) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cylinder of radius 1 along z from -1 to 0 (top face at z=0): positions, normals, indices."""
    pos, nor, idx = [], [], []
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    for k, a in enumerate(angles):  # side
        c, s = math.cos(a), math.sin(a)
        pos += [[c, s, -1.0], [c, s, 0.0]]
        nor += [[c, s, 0.0], [c, s, 0.0]]
        k2 = (k + 1) % segments
        idx += [2 * k, 2 * k2, 2 * k2 + 1, 2 * k, 2 * k2 + 1, 2 * k + 1]
    for z, nz in ((0.0, 1.0), (-1.0, -1.0)):  # caps
        centre = len(pos)
        pos.append([0.0, 0.0, z])
        nor.append([0.0, 0.0, nz])
        for a in angles:
            pos.append([math.cos(a), math.sin(a), z])
            nor.append([0.0, 0.0, nz])
        for k in range(segments):
            a, b = centre + 1 + k, centre + 1 + (k + 1) % segments
            idx += [centre, a, b] if nz > 0 else [centre, b, a]
    return np.array(pos, np.float32), np.array(nor, np.float32), np.array(idx, np.uint16)


def _sphere(rings: int = 10, segments: int = 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sphere of radius 1 centred on the origin: positions, normals (the same), indices."""
    pos = [[0.0, 0.0, 1.0]]
    for i in range(1, rings):
        polar = math.pi * i / rings
        pos += [[math.sin(polar) * math.cos(a), math.sin(polar) * math.sin(a), math.cos(polar)]
                for a in np.linspace(0, 2 * np.pi, segments, endpoint=False)]
    pos.append([0.0, 0.0, -1.0])
    bottom = len(pos) - 1
    idx: list[int] = []
    for k in range(segments):
        k2 = (k + 1) % segments
        idx += [0, 1 + k, 1 + k2]  # top cap
        last = 1 + (rings - 2) * segments
        idx += [bottom, last + k2, last + k]  # bottom cap
        for i in range(rings - 2):
            a, b = 1 + i * segments, 1 + (i + 1) * segments
            idx += [a + k, b + k, b + k2, a + k, b + k2, a + k2]
    array = np.array(pos, np.float32)
    return array, array.copy(), np.array(idx, np.uint16)


class _Builder:
    def __init__(self) -> None:
        self.gltf = pygltflib.GLTF2(asset=pygltflib.Asset(generator="batteur", version="2.0"))
        self.blob = bytearray()

    def view(self, data: bytes, target: int | None = None) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        self.gltf.bufferViews.append(
            pygltflib.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data), target=target))
        self.blob += data
        return len(self.gltf.bufferViews) - 1

    def accessor(self, array: np.ndarray, kind: str, target: int | None = None, bounds: bool = False) -> int:
        component = {np.dtype(np.uint8): UBYTE, np.dtype(np.uint16): USHORT}.get(array.dtype, FLOAT)
        array = np.ascontiguousarray(array, dtype={UBYTE: np.uint8, USHORT: np.uint16}.get(component, np.float32))
        view = self.view(array.tobytes(), target)
        flat = array.reshape(len(array), -1)
        acc = pygltflib.Accessor(bufferView=view, componentType=component, count=len(array), type=kind)
        if bounds:
            acc.min = [float(v) for v in flat.min(axis=0)]
            acc.max = [float(v) for v in flat.max(axis=0)]
        self.gltf.accessors.append(acc)
        return len(self.gltf.accessors) - 1

    def material(self, rgba: list[float], metallic: float = 0.0) -> int:
        self.gltf.materials.append(pygltflib.Material(
            pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(baseColorFactor=rgba, metallicFactor=metallic,
                                                                roughnessFactor=0.6)))
        return len(self.gltf.materials) - 1

    def mesh(self, shape: tuple[np.ndarray, np.ndarray, np.ndarray], material: int) -> int:
        pos, nor, idx = shape
        p = self.accessor(pos, pygltflib.VEC3, pygltflib.ARRAY_BUFFER, bounds=True)
        n = self.accessor(nor, pygltflib.VEC3, pygltflib.ARRAY_BUFFER)
        i = self.accessor(idx, pygltflib.SCALAR, pygltflib.ELEMENT_ARRAY_BUFFER)
        prim = pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=p, NORMAL=n), indices=i,
                                   material=material)
        self.gltf.meshes.append(pygltflib.Mesh(primitives=[prim]))
        return len(self.gltf.meshes) - 1

    def node(self, **kwargs: object) -> int:
        self.gltf.nodes.append(pygltflib.Node(**kwargs))  # type: ignore[arg-type]
        return len(self.gltf.nodes) - 1


def _kit_shape(obj: KitObject, meshes: dict[str, int]) -> tuple[int, list[float]]:
    """The mesh drawing ``obj`` and its scale (metres)."""
    if obj.kind in ("membrane", "throne"):
        return meshes["membrane"], [obj.radius, obj.radius, max(obj.depth, 0.04)]
    if obj.kind in ("cymbal", "hihat"):
        return meshes["cymbal"], [obj.radius, obj.radius, CYMBAL_DRAWN_THICKNESS_M]
    return meshes["other"], [obj.radius * 2, obj.radius * 2, max(obj.depth, 0.02)]


def _kit_node(b: _Builder, obj: KitObject, meshes: dict[str, int]) -> int:
    """A static node drawing ``obj`` where the kit places it."""
    rot = Rotation.from_euler("xyz", obj.rotation_deg, degrees=True).as_quat()
    mesh, scale = _kit_shape(obj, meshes)
    return b.node(name=f"kit_{obj.id}", mesh=mesh, translation=[float(v) for v in obj.position],
                  rotation=[float(v) for v in rot], scale=[float(v) for v in scale])


def kit_links(obj: KitObject) -> dict[str, str]:
    """Physics' kit links (``/batteur/skeleton`` names) that move ``obj``'s mesh -> the mesh node's name: a drum,
    cymbal, bell or throne its own link, the hi-hat its two plates, a pedal its footboard."""
    if obj.kind == "hihat":
        return {f"kit.{obj.id}.top": f"kit_{obj.id}", f"kit.{obj.id}.bottom": f"kit_{obj.id}_bottom"}
    if obj.kind == "pedal":
        return {f"kit.{obj.id}.footboard": f"kit_{obj.id}"}
    return {f"kit.{obj.id}": f"kit_{obj.id}"}


def _relative_to(first: np.ndarray, obj: KitObject) -> tuple[list[float], list[float]]:
    """Translation and rotation (x y z w) placing ``obj``'s static frame in the frame of a link whose first pose
    is ``first`` (7,): a pedal's box hinged on its footboard starts where the static kit has it."""
    link = Rotation.from_quat(normalize_quats(first[3:]))
    rot = link.inv() * Rotation.from_euler("xyz", obj.rotation_deg, degrees=True)
    pos = link.inv().apply(np.asarray(obj.position, dtype=float) - first[:3])
    return [float(v) for v in pos], [float(v) for v in rot.as_quat()]


def _animated_kit(b: _Builder, kit: Kit, sequence: PoseSequence, meshes: dict[str, int]) -> dict[str, int]:
    """Mesh nodes for the kit objects the sequence moves: link name -> mesh node, to be the link's child."""
    names = set(sequence.names)
    out: dict[str, int] = {}
    for obj in kit.objects:
        mesh, scale = _kit_shape(obj, meshes)
        for link, node_name in kit_links(obj).items():
            if link not in names:
                continue
            placed: dict[str, object] = {}
            if obj.kind == "pedal":  # the footboard's frame is its heel's hinge: keep the static box's place
                translation, rotation = _relative_to(sequence.values[0, sequence.index(link)], obj)
                placed = {"translation": translation, "rotation": rotation}
            elif obj.kind == "hihat" and link.endswith(".top"):  # physics' top plate lies above its frame
                placed = {"translation": [0.0, 0.0, scale[2]]}
            out[link] = b.node(name=node_name, mesh=mesh, scale=[float(v) for v in scale], **placed)
    return out


class _KitParts:
    """The meshes of the kit links no kit object draws: a beater's rod and ball, the stands' rods."""

    def __init__(self, b: _Builder, kit: Kit) -> None:
        self.b = b
        self.kit = kit
        self.beaters = {f"kit.{beater.pedal}.beater": beater for beater in kit_hardware(kit).beaters}
        """Beater link name -> the beater physics builds (common/kit.py ``kit_hardware``)."""
        self._meshes: dict[str, int] = {}

    def _mesh(self, name: str) -> int:
        if name not in self._meshes:  # built when first drawn: no unused mesh in the file
            shape, colour = (_sphere(), "felt") if name == "ball" else (_cylinder(12), "other")
            self._meshes[name] = self.b.mesh(shape, self.b.material(COLOURS[colour], metallic=0.5))
        return self._meshes[name]

    def _rod(self, name: str, radius: float, top: np.ndarray, length: float, rotation: Rotation) -> int:
        """A rod of ``length`` (metres) down from ``top`` along ``rotation``'s -z, in its parent link's frame."""
        return self.b.node(name=name, mesh=self._mesh("rod"), translation=[float(v) for v in top],
                           rotation=[float(v) for v in rotation.as_quat()], scale=[radius, radius, length])

    def nodes(self, link: str, first: np.ndarray) -> list[int]:
        """Mesh nodes drawing kit link ``link`` (none for a link not known here), whose first pose is ``first``."""
        frame = Rotation.from_quat(normalize_quats(first[3:]))
        if link == "kit.stands":  # as physics builds them: none under the kick
            kick = self.kit.kick()
            rods = stand_rods(self.kit.objects, None if kick is None else kick.id)
            return [self._rod(f"kit_stand_{k}", STAND_ROD_RADIUS_M, frame.inv().apply(top - first[:3]), height,
                              frame.inv()) for k, (top, height) in enumerate(rods)]
        beater = self.beaters.get(link)
        if beater is not None:  # a rod from the axle along the link's +z to its ball (physics' beater link)
            length = beater.rod_length
            name = link[len("kit."):].replace(".", "_")
            ball = self.b.node(name=f"kit_{name}_ball", mesh=self._mesh("ball"), translation=[0.0, 0.0, length],
                               scale=[beater.ball_radius] * 3)
            return [self._rod(f"kit_{name}", beater.rod_radius, np.array([0.0, 0.0, length]), length,
                              Rotation.identity()), ball]
        return []


def _link_size(name: str, link_size: float) -> float:
    """The edge (metres) of body link ``name``'s cube (a link off the skeleton, a leaf with no End Site): a stick's
    half ``link_size``, a head's 2.5 times."""
    return link_size * (0.5 if "stick" in name else (2.5 if name.endswith("head") else 1.0))


def is_stick(name: str) -> bool:
    """Whether body link ``name`` is a stick (drawn as a rod, given a tip joint), not a stick's tip link."""
    return "stick" in name and not name.endswith("_tip")


Shape = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A mesh: positions (N, 3), normals (N, 3), triangle indices (M,) into them."""


def _along(shape: Shape, start: np.ndarray, end: np.ndarray, width: float, length_axis: int) -> Shape:
    """``shape`` (unit size, its ``length_axis`` from -0.5..0.5 for a box or -1..0 for the cylinder) stretched
    from ``start`` to ``end`` (3,), metres, and scaled by ``width`` across (metres: a box's edge, a cylinder's
    radius). Normals come out unnormalised (:func:`_normalized`)."""
    pos, nor, idx = shape
    d = end - start
    length = float(np.linalg.norm(d))
    scale = np.full(3, width)
    scale[length_axis] = length
    axis = np.zeros(3)
    axis[length_axis] = 1.0
    turn, _ = Rotation.align_vectors([d / length], [axis])
    m = turn.as_matrix()
    local = pos.astype(float) * scale
    local[:, length_axis] -= local[:, length_axis].min()  # from 0 (start) to length (end) along the axis
    return local @ m.T + start, (nor.astype(float) / scale) @ m.T, idx


def _normalized(shape: Shape) -> Shape:
    """``shape`` with unit normals."""
    pos, nor, idx = shape
    return pos, nor / np.linalg.norm(nor, axis=1, keepdims=True), idx


def _stick_shape(tip: np.ndarray) -> Shape:
    """A stick in its link's frame: a 12-sided rod :data:`STICK_DIAMETER_M` across, from the butt
    (:data:`STICK_GRIP_M` behind the fulcrum, the link's origin) to the tip bead's far side (:data:`STICK_BEAD_RADIUS_M`
    past ``tip``, the bead's centre, (3,) metres): physics' 5A stick, 0.406 m."""
    u = tip / np.linalg.norm(tip)
    return _normalized(_along(_cylinder(12), -STICK_GRIP_M * u, tip + STICK_BEAD_RADIUS_M * u,
                              STICK_DIAMETER_M / 2, 2))


def _segment_shape(end: np.ndarray | None, width: float, cube: float) -> Shape:
    """A body link in its frame: a box ``width`` across from its origin to ``end`` (3,), metres (the mean of its child
    joints' offsets, or its End Site); a cube of edge ``cube`` centred on its origin when ``end`` is None or shorter
    than ``width``."""
    if end is None or float(np.linalg.norm(end)) < width:
        pos, nor, idx = _box()
        return pos.astype(float) * cube, nor.astype(float), idx
    return _normalized(_along(_box(), np.zeros(3), np.asarray(end, dtype=float), width, 1))


def _stick_tips(skeleton: Skeleton, end_sites: Mapping[str, np.ndarray]) -> dict[int, np.ndarray]:
    """Stick joint -> its tip (3,), metres in its frame, for each stick that is a leaf of ``skeleton`` (physics'
    sticks: their tips are no link of the pose): the End Site given, else :data:`STICK_TIP_M` along +y."""
    parents = {joint.parent for joint in skeleton.joints}
    out = {}
    for k, joint in enumerate(skeleton.joints):
        if joint.link >= 0 and is_stick(joint.name) and k not in parents:
            given = end_sites.get(joint.name)
            out[k] = np.asarray([0.0, STICK_TIP_M, 0.0] if given is None else given, dtype=float)
    return out


def _joint_shapes(skeleton: Skeleton, sequence: PoseSequence, tips: Mapping[int, np.ndarray],
                  end_sites: Mapping[str, np.ndarray], link_size: float) -> dict[int, Shape]:
    """Joint -> its link's shape in the joint's frame (the links' boxes and sticks; the seat joint has none)."""
    children: dict[int, list[np.ndarray]] = {}
    for joint in skeleton.joints:
        if joint.parent >= 0 and float(np.linalg.norm(joint.translation[0])) > 1e-6:  # the seat: no offset
            children.setdefault(joint.parent, []).append(joint.translation[0])
    out: dict[int, Shape] = {}
    for k, joint in enumerate(skeleton.joints):
        if joint.link < 0:
            continue
        name = sequence.names[joint.link]
        ends = children.get(k)
        if is_stick(name):
            tip = tips.get(k, np.mean(ends, axis=0) if ends else None)
            if tip is not None and float(np.linalg.norm(tip)) > 1e-6:
                out[k] = _stick_shape(np.asarray(tip, dtype=float))
                continue
        end = np.mean(ends, axis=0) if ends else end_sites.get(name)
        out[k] = _segment_shape(None if end is None else np.asarray(end, dtype=float), link_size,
                                _link_size(name, link_size))
    return out


def _skin(b: _Builder, skeleton: Skeleton, sequence: PoseSequence, joint_nodes: list[int],
          tips: Mapping[int, np.ndarray], end_sites: Mapping[str, np.ndarray], link_size: float,
          materials: tuple[int, int]) -> int:
    """The skinned mesh node (a scene root, no transform of its own, as the spec asks) drawing the body links'
    shapes, each vertex weight 1 to its link's joint: one primitive per material (body, stick). ``joint_nodes``:
    the skeleton's joint nodes, then the tips' (``tips``' order), which no vertex is bound to."""
    root = np.eye(4)
    root[:3, :3] = Rotation.from_quat(ROOT_ROTATION).as_matrix()
    bind = skeleton.bind_matrices(root)
    tip_bind = []
    for k, tip in tips.items():
        offset = np.eye(4)
        offset[:3, 3] = tip
        tip_bind.append(bind[k] @ offset)
    bind = np.concatenate([bind, np.array(tip_bind).reshape(-1, 4, 4)])
    parts: list[list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = [[], []]
    shapes = _joint_shapes(skeleton, sequence, tips, end_sites, link_size)
    for k, (pos, nor, idx) in sorted(shapes.items(), key=lambda item: skeleton.joints[item[0]].link):
        m = bind[k]
        parts[1 if "stick" in skeleton.joints[k].name else 0].append(
            (pos @ m[:3, :3].T + m[:3, 3], nor @ m[:3, :3].T, np.full(len(pos), k), idx))
    joint_type = np.uint8 if len(joint_nodes) < 256 else np.uint16
    primitives = []
    for material, meshes in zip(materials, parts, strict=True):
        if not meshes:
            continue
        pos = np.concatenate([p for p, _, _, _ in meshes])
        joints = np.zeros((len(pos), 4), joint_type)
        joints[:, 0] = np.concatenate([j for _, _, j, _ in meshes])
        weights = np.zeros((len(pos), 4), np.float32)
        weights[:, 0] = 1.0
        starts = np.cumsum([0] + [len(p) for p, _, _, _ in meshes[:-1]])
        indices = np.concatenate([i + start for (_, _, _, i), start in zip(meshes, starts, strict=True)])
        attributes = pygltflib.Attributes(
            POSITION=b.accessor(pos, pygltflib.VEC3, pygltflib.ARRAY_BUFFER, bounds=True),
            NORMAL=b.accessor(np.concatenate([n for _, n, _, _ in meshes]), pygltflib.VEC3, pygltflib.ARRAY_BUFFER),
            JOINTS_0=b.accessor(joints, pygltflib.VEC4, pygltflib.ARRAY_BUFFER),
            WEIGHTS_0=b.accessor(weights, pygltflib.VEC4, pygltflib.ARRAY_BUFFER))
        primitives.append(pygltflib.Primitive(attributes=attributes, material=material,
                                              indices=b.accessor(indices.astype(np.uint16), pygltflib.SCALAR,
                                                                 pygltflib.ELEMENT_ARRAY_BUFFER)))
    b.gltf.meshes.append(pygltflib.Mesh(name="body", primitives=primitives))
    inverse = np.linalg.inv(bind).transpose(0, 2, 1).reshape(len(bind), 16)  # column-major, as glTF stores them
    b.gltf.skins.append(pygltflib.Skin(name="drummer", joints=joint_nodes, skeleton=joint_nodes[0],
                                       inverseBindMatrices=b.accessor(inverse, pygltflib.MAT4)))
    return b.node(name="body", mesh=len(b.gltf.meshes) - 1, skin=len(b.gltf.skins) - 1)


def _flashes(b: _Builder, kit: Kit, impacts: Iterable[tuple[float, str]], origin: float, root: int,
             link_node: dict[str, int], membrane_mesh: int) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """A flash disc node per kit object struck in ``impacts`` ((rig time in seconds, kit object id)): a child of
    its moving link's node (the ride, the hi-hat's top plate) or of ``root``. Returns (node, key times, scales)."""
    times = gltf_flash.flash_times(impacts, origin)
    struck = gltf_flash.struck_objects(kit.objects, times)
    if not struck:
        return []
    material = b.material(gltf_flash.FLASH_COLOUR + [1.0])
    b.gltf.materials[material].emissiveFactor = list(gltf_flash.FLASH_COLOUR)
    disc = b.gltf.meshes[membrane_mesh].primitives[0]  # the unit cylinder's accessors, shared
    b.gltf.meshes.append(pygltflib.Mesh(name="flash", primitives=[pygltflib.Primitive(
        attributes=disc.attributes, indices=disc.indices, material=material)]))
    mesh = len(b.gltf.meshes) - 1
    out = []
    for obj in struck:
        link = f"kit.{obj.id}.top" if obj.kind == "hihat" else f"kit.{obj.id}"
        offset = gltf_flash.head_offset(obj, CYMBAL_DRAWN_THICKNESS_M)
        if link in link_node:  # it moves: ride its link, whose frame is the object's (the plate's frame for the top)
            parent, placed = link_node[link], {"translation": [0.0, 0.0, offset]}
        else:
            translation, rotation = gltf_flash.static_place(obj, CYMBAL_DRAWN_THICKNESS_M)
            parent, placed = root, {"translation": translation, "rotation": rotation}
        node = b.node(name=f"flash_{obj.id}", mesh=mesh, scale=[gltf_flash.HIDDEN_SCALE] * 3, **placed)
        b.gltf.nodes[parent].children = [*(b.gltf.nodes[parent].children or []), node]
        key_times, scales = gltf_flash.scale_keys(times[obj.id], gltf_flash.full_scale(obj))
        out.append((node, key_times, scales))
    return out


def write_gltf(sequence: PoseSequence, path: Path, kit: Kit | None = None, link_size: float = 0.05,
               time_origin: float | None = None, impacts: Iterable[tuple[float, str]] | None = None,
               end_sites: Mapping[str, Iterable[float]] | None = None) -> GltfInfo:
    """Write ``sequence`` (and ``kit``: static, or moved by its kit links in ``sequence``) as glTF 2.0: ``.glb``
    binary, or ``.gltf`` with embedded data. ``link_size``: the body links' boxes' width, metres. ``time_origin``:
    the rig time (seconds) of the file's time 0 (None: the first pose's); no pose may come before it. ``impacts``
    ((rig time in seconds, kit object id), with ``kit``): each struck object's head flashes at its impacts
    (:mod:`services.graphics.export.gltf_flash`). ``end_sites``: leaf link -> its tip, metres in the link's frame
    (z up), as :func:`services.graphics.export.bvh.write_bvh`'s: a stick's tip joint (default :data:`STICK_TIP_M`
    along +y) and a leaf's box (a foot's to the ball of the foot; default a cube)."""
    origin = float(sequence.times[0]) if time_origin is None else time_origin
    if sequence.times[0] < origin:
        raise ValueError(f"the first pose ({sequence.times[0]:g} s) comes before the file's time 0 ({origin:g} s)")
    sites = {} if end_sites is None else {link: np.asarray(list(v), dtype=float) for link, v in end_sites.items()}
    b = _Builder()
    box = _box()
    body_mat = b.material(COLOURS["body"])
    stick_mat = b.material(COLOURS["stick"])
    box_meshes: dict[int, int] = {}  # material -> a box of it, for a body link off the skeleton (built when used)
    meshes: dict[str, int] = {}
    animated: dict[str, int] = {}
    parts = None if kit is None else _KitParts(b, kit)
    if kit is not None:
        meshes = {
            "membrane": b.mesh(_cylinder(), b.material(COLOURS["membrane"])),
            "cymbal": b.mesh(_cylinder(), b.material(COLOURS["cymbal"], metallic=0.8)),
            "other": b.mesh(box, b.material(COLOURS["other"], metallic=0.5)),
        }
        animated = _animated_kit(b, kit, sequence, meshes)
    skeleton = Skeleton.of(sequence)
    joint_of = {} if skeleton is None else skeleton.links  # body link -> its joint: drawn by the skin
    link_nodes: list[int] = []
    rigid: list[int] = []  # the links that stay nodes animated by their pose (the kit's, a body link off the tree)
    first = sequence.values[0]
    for i, name in enumerate(sequence.names):
        if i in joint_of:
            continue
        if name in animated:  # a kit link: the kit object's mesh instead of a box
            mesh_nodes = [animated[name]]
        elif name.startswith("kit."):  # a beater, the stands: drawn as they are, else not at all (no body box)
            mesh_nodes = [] if parts is None else parts.nodes(name, first[i])
        else:
            material = stick_mat if "stick" in name else body_mat
            if material not in box_meshes:
                box_meshes[material] = b.mesh(box, material)
            mesh_nodes = [b.node(name=f"{name}_mesh", mesh=box_meshes[material],
                                 scale=[_link_size(name, link_size)] * 3)]
        rigid.append(i)
        link_nodes.append(b.node(name=name, children=mesh_nodes or None,
                                 translation=[float(v) for v in first[i, :3]],
                                 rotation=[float(v) for v in normalize_quats(first[i, 3:])]))
    joint_nodes: list[int] = []
    if skeleton is not None:
        for joint in skeleton.joints:
            joint_nodes.append(b.node(name=joint.name, translation=[float(v) for v in joint.translation[0]],
                                      rotation=[float(v) for v in joint.rotation[0]]))
            if joint.parent >= 0:
                parent = b.gltf.nodes[joint_nodes[joint.parent]]
                parent.children = [*(parent.children or []), joint_nodes[-1]]
    tips = {} if skeleton is None else _stick_tips(skeleton, sites)
    for k, tip in tips.items():  # a joint at each stick's tip (no key: it stays there), the stick bone's tail
        stick = b.gltf.nodes[joint_nodes[k]]
        joint_nodes.append(b.node(name=f"{stick.name}_tip", translation=[float(v) for v in tip]))
        stick.children = [*(stick.children or []), joint_nodes[-1]]
    kit_nodes = []
    animated_ids = set()
    if kit is not None:
        animated_ids = {obj.id for obj in kit.objects if any(link in animated for link in kit_links(obj))}
        kit_nodes = [_kit_node(b, obj, meshes) for obj in kit.objects if obj.id not in animated_ids]
    root = b.node(name="batteur", rotation=ROOT_ROTATION, children=joint_nodes[:1] + link_nodes + kit_nodes)
    scene_nodes = [root]
    if skeleton is not None and joint_of:
        scene_nodes.append(_skin(b, skeleton, sequence, joint_nodes, tips, sites, link_size, (body_mat, stick_mat)))
    flashes = []
    if kit is not None and impacts is not None:
        link_node = {sequence.names[i]: node for i, node in zip(rigid, link_nodes, strict=True)}
        flashes = _flashes(b, kit, impacts, origin, root, link_node, meshes["membrane"])
    b.gltf.scenes.append(pygltflib.Scene(name="performance", nodes=scene_nodes))
    b.gltf.scene = 0

    times = (sequence.times - origin).astype(np.float32)
    t_acc = b.accessor(times, pygltflib.SCALAR, bounds=True)
    samplers, channels = [], []
    tracks: list[tuple[int, np.ndarray, str]] = []  # (node, key values, path)
    for i, node in zip(rigid, link_nodes, strict=True):
        tracks += [(node, sequence.values[:, i, :3], "translation"),
                   (node, continuous_quats(sequence.values[:, i, 3:]), "rotation")]
    if skeleton is not None:
        for joint, node in zip(skeleton.joints, joint_nodes[:len(skeleton.joints)], strict=True):
            if joint.moves:
                tracks.append((node, joint.translation, "translation"))
            tracks.append((node, joint.rotation, "rotation"))
    for node, values, target in tracks:
        kind = pygltflib.VEC3 if target == "translation" else pygltflib.VEC4
        samplers.append(pygltflib.AnimationSampler(input=t_acc, output=b.accessor(values, kind),
                                                   interpolation="LINEAR"))
        channels.append(pygltflib.AnimationChannel(sampler=len(samplers) - 1,
                                                   target=pygltflib.AnimationChannelTarget(node=node, path=target)))
    for node, key_times, scales in flashes:  # on and off at once: STEP
        samplers.append(pygltflib.AnimationSampler(input=b.accessor(key_times, pygltflib.SCALAR, bounds=True),
                                                   output=b.accessor(scales, pygltflib.VEC3), interpolation="STEP"))
        channels.append(pygltflib.AnimationChannel(sampler=len(samplers) - 1,
                                                   target=pygltflib.AnimationChannelTarget(node=node, path="scale")))
    b.gltf.animations.append(pygltflib.Animation(name="performance", samplers=samplers, channels=channels))
    b.gltf.buffers.append(pygltflib.Buffer(byteLength=len(b.blob)))
    b.gltf.set_binary_blob(bytes(b.blob))
    if path.suffix.lower() == ".glb":
        b.gltf.save_binary(str(path))
    else:
        b.gltf.convert_buffers(pygltflib.BufferFormat.DATAURI)
        b.gltf.save_json(str(path))
    return GltfInfo(len(link_nodes) + len(joint_of), len(kit_nodes) + len(animated_ids), len(times),
                    float(times[-1]), len(animated_ids), len(joint_nodes), len(flashes))
