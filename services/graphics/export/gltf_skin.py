"""The glTF export's skeleton and skin (:func:`services.graphics.export.gltf.write_gltf`).

The body's links become joint nodes in the tree of the BVH export (:mod:`services.graphics.export.bvh`: the same
joints, names and parents, built as its ``_Layout`` builds them without the channel orders it also chooses (0.06 s);
physics' character with its ``seat`` joint, ``THRONE_JOINT``), each animated by its
rotation relative to its parent joint (the root, under the file's z-up-to-y-up root node, by its pose in the
Batteur frame, translation and rotation); a joint whose offset from its parent changes (more than
``RIGID_TOLERANCE_M``) gets a translation channel too. A joint's frame is its link's (the seat's: the world's at the
pelvis' origin), so the joint nodes placed by their channels are the link nodes of before. The links' boxes are one
skinned mesh, each vertex bound with weight 1 to its link's joint; the bind pose is the first pose (the joint nodes'
own translation and rotation), the vertices are where that pose puts them (y up), the inverse bind matrices undo it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from services.graphics.export.bvh import ON_THRONE, PELVIS_LINK, THRONE_JOINT, joint_tree
from services.graphics.poser import is_character
from services.graphics.sequence import PoseSequence, normalize_quats
from services.graphics.skeleton import body_links, guess_parents

RIGID_TOLERANCE_M = 1e-6
"""A joint's offset from its parent that moves less than this over the sequence (metres) is held (no channel)."""


def continuous_quats(quats: np.ndarray) -> np.ndarray:
    """Unit quaternions (N, 4), each on the hemisphere of the one before: no long-way slerps between keys."""
    quats = normalize_quats(quats)
    flips = np.cumprod(np.sign(np.r_[1.0, np.sum(quats[1:] * quats[:-1], axis=1)]))
    return quats * np.where(flips[:, None] < 0, -1.0, 1.0)


@dataclass
class Joint:
    """One joint node: its name, parent (index into the skeleton's joints, -1: the root), the link it moves (index
    into the sequence's names; -1: the seat, no link), local translation (N, 3) and rotation (N, 4, x y z w) per
    pose, and whether the translation is animated."""

    name: str
    parent: int
    link: int
    translation: np.ndarray
    rotation: np.ndarray
    moves: bool


class Skeleton:
    """The joints (in the BVH's order: parents first) of a sequence's body links and their local motion."""

    def __init__(self, sequence: PoseSequence) -> None:
        names = list(sequence.names)
        values = sequence.values
        count = len(names)
        parents = guess_parents(names)
        body = body_links(names)
        pos = values[:, :, :3]
        rot = [Rotation.from_quat(normalize_quats(values[:, i, 3:])) for i in range(count)]
        if is_character(names) and THRONE_JOINT not in names:  # the seat joint, as bvh.py's _Layout adds it
            pelvis = names.index(PELVIS_LINK)
            names.append(THRONE_JOINT)
            parents.append(pelvis)
            for thigh in ON_THRONE:
                parents[names.index(thigh)] = count
            body.append(count)
            # the seat: at the pelvis' origin, the world's orientation (the throne's)
            pos = np.concatenate([pos, pos[:, pelvis:pelvis + 1]], axis=1)
            rot.append(Rotation.from_quat(np.tile([0.0, 0.0, 0.0, 1.0], (len(values), 1))))
        root, order, _ = joint_tree(names, parents, body)
        index = {link: k for k, link in enumerate(order)}
        self.joints: list[Joint] = []
        for link in order:
            parent = -1 if link == root else parents[link]
            if parent < 0:
                translation, rotation = pos[:, link], rot[link]
            else:
                translation = rot[parent].inv().apply(pos[:, link] - pos[:, parent])
                rotation = rot[parent].inv() * rot[link]
            moves = parent < 0 or float(np.abs(translation - translation[0]).max()) > RIGID_TOLERANCE_M
            self.joints.append(Joint(names[link], -1 if parent < 0 else index[parent],
                                     link if link < count else -1, np.asarray(translation, dtype=float),
                                     continuous_quats(rotation.as_quat()), moves))
        self.links = {joint.link: k for k, joint in enumerate(self.joints) if joint.link >= 0}
        """Sequence link index -> its joint's index."""

    @classmethod
    def of(cls, sequence: PoseSequence) -> Skeleton | None:
        """The skeleton of ``sequence``'s body, or None when it has no body root (no joints, links stay nodes)."""
        try:
            return cls(sequence)
        except ValueError:
            return None

    def bind_matrices(self, root: np.ndarray) -> np.ndarray:
        """Each joint's global transform (4x4, under the file's root transform ``root``) at the bind pose (the first
        pose): (J, 4, 4)."""
        out = np.zeros((len(self.joints), 4, 4))
        for k, joint in enumerate(self.joints):
            local = np.eye(4)
            local[:3, :3] = Rotation.from_quat(joint.rotation[0]).as_matrix()
            local[:3, 3] = joint.translation[0]
            out[k] = (root if joint.parent < 0 else out[joint.parent]) @ local
        return out
