"""Shipped kits with their objects renamed as a kit designer may (``bassdrum``, ``bd_pedal``, ``hats``...): the ids
change everywhere the kit names them (objects, events' ``object`` and ``pedal``, ``note_objects``,
``left_bass_pedal``); what each object is and where it stands do not."""

from __future__ import annotations

from common.kit import Kit, load_kit

RENAMED = {"kick": "bassdrum", "kick_pedal": "bd_pedal", "kick_pedal_left": "bd_pedal_2", "hihat": "hats",
           "hihat_pedal": "foot_chick", "snare": "sd"}
"""Shipped id -> the designer's."""


def renamed_kit(name: str = "default", names: dict[str, str] | None = None) -> Kit:
    """Shipped kit ``name`` with its ids renamed by ``names`` (default :data:`RENAMED`)."""
    names = RENAMED if names is None else names
    data = load_kit(name, warn=False).model_dump(mode="json")

    def new(old: str | None) -> str | None:
        return None if old is None else names.get(old, old)

    for obj in data["objects"]:
        obj["id"] = new(obj["id"])
    for spec in data["events"].values():
        spec["object"], spec["pedal"] = new(spec["object"]), new(spec["pedal"])
    data["note_objects"] = {pitch: new(obj) for pitch, obj in data["note_objects"].items()}
    data["left_bass_pedal"] = new(data["left_bass_pedal"])
    data["name"] = f"{name}_renamed"
    kit = Kit.model_validate(data)
    assert not {o.id for o in kit.objects} & set(names), "every named object renamed"
    return kit
