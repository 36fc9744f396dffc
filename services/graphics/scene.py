"""Kit animation from impacts and poses: heads flash, cymbals swing, the hi-hat opens, pedals move.

Computed in Python so the live page and the offline video animate the kit
identically. For each kit object, :func:`kit_state` gives four numbers:

* ``flash`` 0..1: brightness of a head or cymbal just struck, decaying
  exponentially (time constant :data:`FLASH_TAU` seconds);
* ``swing_x, swing_y``: rotation vector (radians) in the object's local
  frame: the cymbal swing of Kragtwijk et al. (2001),
  ``eta**t * alpha_max * sin(beta t)`` after each strike, about the axis that
  tips the struck edge down, summed over strikes;
* ``extra``: for the hi-hat the gap between its cymbals (metres), for a pedal
  how far it is pressed (0 up .. 1 down), otherwise 0.

Kit links published by physics (``kit.<id>``, ``kit.<id>.top``,
``kit.<id>.footboard``; :func:`services.graphics.skeleton.kit_link`) override
this: the swing is then the link's rotation in the object's frame, the hi-hat
gap the top cymbal's height above the bottom one, and a pedal's press its
footboard angle (22 degrees at rest, 0 pressed).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from common.kit import EventType, Kit, KitObject, kit_hardware
from common.messages import Impact
from services.graphics.sequence import normalize_quats
from services.graphics.skeleton import canonical, kit_link

FLASH_TAU = 0.12  # seconds
SWING_ETA = 0.15  # amplitude factor per second
SWING_BETA = 2 * math.pi * 1.6  # rad/s
SWING_PER_MPS = 0.035  # alpha_max per m/s of strike velocity, radians
SWING_MAX = 0.3  # radians
HIHAT_MAX_GAP = 0.025  # metres, fully open (as the physics kit's hi-hat)
PEDAL_TRAVEL = 0.05  # metres of foot travel from up to down
FOOTBOARD_REST_DEG = 22.0  # physics footboard angle at rest (0: pressed flat)
HISTORY = 6.0  # seconds of impacts kept


def object_rotation(obj: KitObject) -> Rotation:
    """Rotation from the object's local frame (+z = surface normal) to the world frame."""
    return Rotation.from_euler("xyz", obj.rotation_deg, degrees=True)


def link_rotation(q: np.ndarray) -> Rotation:
    """Rotation of a link's quaternion (x y z w); a zero one (a broken sender or file) is the identity."""
    return Rotation.from_quat(normalize_quats(q))


def impact_point(obj: KitObject, r: float, theta: float) -> np.ndarray:
    """World position (3,) metres of a strike at ``r`` (r/a) and ``theta`` (radians) on ``obj``."""
    local = np.array([r * obj.radius * math.cos(theta), r * obj.radius * math.sin(theta), 0.0])
    return np.asarray(obj.position) + object_rotation(obj).apply(local)


@dataclass
class PedalBinding:
    """Which foot link drives which pedal, and the lowest height seen (fully pressed)."""

    link: int
    low: float = math.inf


class KitAnimator:
    """Keeps recent impacts and the pedal bindings; computes the kit state at a display time."""

    def __init__(self, kit: Kit) -> None:
        self.kit = kit
        self.impacts: list[Impact] = []
        self._pedals: dict[str, PedalBinding] = {}
        self._names: list[str] = []
        self._kit_links: dict[str, dict[str, int]] = {}

    def set_kit(self, kit: Kit) -> None:
        self.kit = kit
        self._pedals = {}
        self.bind(self._names)

    def add(self, impact: Impact) -> None:
        """Remember an impact (kept :data:`HISTORY` seconds past the newest one).

        One older than that is not late but from a restarted clock (or the newest was a stray from the
        future): the old impacts are forgotten, else every new one would be dropped at once.
        """
        if self.impacts and impact.time < self.impacts[-1].time - HISTORY:
            self.impacts.clear()
        self.impacts.append(impact)
        if len(self.impacts) > 1 and self.impacts[-2].time > impact.time:
            self.impacts.sort(key=lambda i: i.time)
        newest = self.impacts[-1].time
        while self.impacts and self.impacts[0].time < newest - HISTORY:
            self.impacts.pop(0)

    def bind(self, names: list[str]) -> None:
        """Bind each pedal to the foot that plays it (from the kit's events), for pose-driven pedals."""
        self._names = list(names)
        self._pedals = {}
        self._kit_links = {}
        for i, n in enumerate(names):
            key = kit_link(n)
            if key is not None:
                self._kit_links.setdefault(key[0], {})[key[1]] = i
        feet: dict[str, int] = {}
        for i, n in enumerate(names):
            key = canonical(n)
            if key is None or key[1] not in ("toe", "foot"):
                continue
            if key[1] == "toe" or key[0] not in feet:
                feet[key[0]] = i
        for obj in self.kit.objects:
            if obj.kind != "pedal":
                continue
            side = self._pedal_side(obj)
            if side in feet:
                self._pedals[obj.id] = PedalBinding(feet[side])

    def _pedal_side(self, obj: KitObject) -> str:
        """The foot (``left``/``right``) that plays pedal ``obj``, from the kit's events whatever the ids: the
        hi-hat's (HIHATPEDAL's ``pedal``) and the kick's (BASS's) by their events' preferred feet, a double pedal's
        second footboard by the other foot (as physics plays it); any other by the side it stands on."""
        kit = self.kit
        if obj.id == kit.hihat_pedal():
            return kit.events[EventType.HIHATPEDAL].preferred.value.split("_")[0]
        if obj.id == kit.kick_pedal() or (kit.double_pedal and obj.id == kit.left_bass_pedal
                                          and EventType.BASS in kit.events):
            side = kit.events[EventType.BASS].preferred.value.split("_")[0]
            return side if obj.id == kit.kick_pedal() else ("left" if side == "right" else "right")
        return "left" if obj.position[0] < 0 else "right"

    def state(self, t: float, pose: np.ndarray | None) -> np.ndarray:
        """Kit state (K, 4) at display time ``t`` seconds: flash, swing_x, swing_y, extra per object."""
        objects = self.kit.objects
        index = {o.id: k for k, o in enumerate(objects)}
        out = np.zeros((len(objects), 4))
        for imp in self.impacts:
            dt = t - imp.time
            if dt < 0:
                break
            k = index.get(imp.instrument)
            if k is None:
                continue
            obj = objects[k]
            strength = min(1.0, 0.25 + imp.velocity / 4.0)
            out[k, 0] = max(out[k, 0], strength * math.exp(-dt / FLASH_TAU))
            if obj.kind in ("cymbal", "hihat", "bell"):
                alpha = min(SWING_MAX, SWING_PER_MPS * imp.velocity) * (0.3 if obj.kind != "cymbal" else 1.0)
                angle = SWING_ETA**dt * alpha * math.sin(SWING_BETA * dt)
                out[k, 1] += angle * -math.sin(imp.theta)
                out[k, 2] += angle * math.cos(imp.theta)
        press = self._pedal_press(pose)
        for k, obj in enumerate(objects):
            if obj.kind == "pedal":
                out[k, 3] = press.get(obj.id, self._impact_press(obj, t))
                board = self._kit_links.get(obj.id, {}).get("footboard")
                if pose is not None and board is not None and board < len(pose):
                    local = object_rotation(obj).inv() * link_rotation(pose[board, 3:])
                    angle = abs(math.degrees(local.as_rotvec()[0]))
                    out[k, 3] = float(np.clip(1.0 - angle / FOOTBOARD_REST_DEG, 0.0, 1.0))
        for k, obj in enumerate(objects):
            if obj.kind == "hihat":
                pedal = self.kit.hihat_pedal()  # HIHATPEDAL's footboard, whatever its id
                p = out[index[pedal], 3] if pedal is not None else 0.0
                out[k, 3] = obj.opening * HIHAT_MAX_GAP * (1.0 - p)
        if pose is not None and self._kit_links:
            self._from_kit_links(out, pose)
        return out

    def _from_kit_links(self, out: np.ndarray, pose: np.ndarray) -> None:
        """Swing and hi-hat gap from the kit links physics publishes."""
        for k, obj in enumerate(self.kit.objects):
            links = self._kit_links.get(obj.id)
            if not links:
                continue
            rest = object_rotation(obj)
            base = links.get("")
            if base is not None and base < len(pose):
                local = rest.inv() * link_rotation(pose[base, 3:])
                out[k, 1:3] = local.as_rotvec()[:2]
            top = links.get("top")
            if top is not None and top < len(pose):
                rise = float(np.dot(pose[top, :3] - np.asarray(obj.position), rest.apply([0.0, 0.0, 1.0])))
                out[k, 3] = max(rise, 0.0)

    def _pedal_press(self, pose: np.ndarray | None) -> dict[str, float]:
        if pose is None:
            return {}
        out: dict[str, float] = {}
        for obj_id, binding in self._pedals.items():
            if binding.link >= len(pose):
                continue
            z = float(pose[binding.link, 2])
            binding.low = min(binding.low, z)
            out[obj_id] = float(np.clip(1.0 - (z - binding.low) / PEDAL_TRAVEL, 0.0, 1.0))
        return out

    def _impact_press(self, obj: KitObject, t: float) -> float:
        """Pedal press from impacts alone (no foot link): down around each strike of its drum (a bass pedal's: the
        kick, whatever its id; another pedal's: its own)."""
        kick = self.kit.kick()
        bass = obj.id == self.kit.kick_pedal() or (self.kit.double_pedal and obj.id == self.kit.left_bass_pedal)
        target = kick.id if bass and kick is not None else obj.id
        press = 0.0
        for imp in self.impacts:
            if imp.instrument in (target, obj.id):
                press = max(press, math.exp(-(((t - imp.time) / 0.05) ** 2)))
        return press

    def hits(self, t: float, window: float = 0.5) -> list[tuple[float, float, float, float, str]]:
        """Recent strikes as (x, y, z, age seconds, instrument) for the contact markers."""
        out = []
        for imp in self.impacts:
            age = t - imp.time
            if 0 <= age <= window:
                try:
                    obj = self.kit.object(imp.instrument)
                except KeyError:
                    continue
                x, y, z = impact_point(obj, imp.r, imp.theta)
                out.append((float(x), float(y), float(z), float(age), imp.instrument))
        return out


def kit_json(kit: Kit) -> dict[str, object]:
    """The kit as the page draws it (plain JSON)."""
    return kit.model_dump(mode="json")


def hardware_json(kit: Kit) -> dict[str, object]:
    """The beaters and stand rods physics builds for ``kit`` (``common.kit.kit_hardware``, world metres), as the
    page draws them (plain JSON)."""
    return kit_hardware(kit).model_dump(mode="json")


def objects_of(kit: Kit, kinds: Iterable[str]) -> list[KitObject]:
    wanted = set(kinds)
    return [o for o in kit.objects if o.kind in wanted]
