"""Generate docs/osc.md, the OSC namespace reference, from the message models.

Run ``python -m common.messages.docs > docs/osc.md`` (or ``batteur docs``);
a test fails when the committed file is stale.
"""

from __future__ import annotations

import inspect
import sys

from common.messages.base import OscMessage, WireKind
from common.messages.registry import REGISTRY, MessageRegistry
from common.messages.system import PROTOCOL_VERSION

_TYPE_NAMES = {WireKind.INT: "i", WireKind.FLOAT: "f", WireKind.STR: "s", WireKind.TIME: "i f"}


def _range(minimum: float | None, maximum: float | None, choices: tuple[str, ...] | None) -> str:
    if choices:
        return " \\| ".join(choices)
    if minimum is None and maximum is None:
        return ""
    low = "" if minimum is None else f"{minimum:g}"
    high = "" if maximum is None else f"{maximum:g}"
    return f"{low} .. {high}"


def _model_section(model: type[OscMessage]) -> list[str]:
    doc = inspect.cleandoc(model.__doc__ or "").strip()
    lines = [f"### `{model.ADDRESS}`", "", f"Family: {model.FAMILY.value}. Type tags: `,{model.type_tags()}`.", ""]
    if doc:
        lines += [doc, ""]
    fields = model.wire_fields()
    if fields:
        lines += ["| # | argument | type | range | meaning |", "| --- | --- | --- | --- | --- |"]
        position = 1
        for f in fields:
            if f.kind is WireKind.TIME:
                index = f"{position}-{position + 1}"
                position += 2
                meaning = f"{f.description} (whole seconds, then fraction)"
            else:
                index = f"{position}{'..' if f.variadic else ''}"
                position += 1
                meaning = f.description + (" (repeated to the end)" if f.variadic else "")
            rng = _range(f.minimum, f.maximum, f.choices)
            lines.append(f"| {index} | {f.name} | {_TYPE_NAMES[f.kind]} | {rng} | {meaning} |")
        lines.append("")
    else:
        lines += ["No arguments.", ""]
    return lines


def render_markdown(registry: MessageRegistry = REGISTRY) -> str:
    """The whole OSC reference as Markdown."""
    lines = [
        "# OSC namespace",
        "",
        "Generated from the message models in `common/messages/` by `python -m common.messages.docs`;",
        "do not edit by hand (a test fails when this file is stale).",
        "",
        f"Protocol version: {PROTOCOL_VERSION}. Arguments are OSC `i` (int32), `f` (float32) and `s` (string),",
        "so Pure Data vanilla's [oscformat]/[oscparse] can build and parse every message. Pd sends every",
        "number as a float: integral floats are accepted for `i` arguments. A rig time takes two arguments,",
        "whole seconds (`i`) then the fraction (`f`). Bundles are accepted; their timetags are ignored.",
        "A message that does not match its model is dropped, counted by reason and reported in",
        "`/batteur/health`; a physics, score, sound, interaction or graphics control that does not is also",
        "answered to its sender with that service's refusal (`/batteur/physics/rejected`,",
        "`/batteur/sound/rejected`, `/batteur/interaction/error`, `/batteur/graphics/rejected`), by a node of",
        "that service only, a few a second per sender host at most.",
        "",
    ]
    families: dict[str, list[type[OscMessage]]] = {}
    for model in registry:
        families.setdefault(model.FAMILY.value, []).append(model)
    for family in sorted(families):
        lines += [f"## {family.capitalize()}", ""]
        for model in families[family]:
            lines += _model_section(model)
    return "\n".join(lines).rstrip() + "\n"


def main() -> int:
    sys.stdout.write(render_markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
