"""Generate docs/osc.md, the OSC namespace reference, from the message models.

Run ``python -m common.messages.docs > docs/osc.md`` (or ``batteur docs``);
a test fails when the committed file is stale.
"""

from __future__ import annotations

import argparse
import inspect
import sys
from collections.abc import Sequence

from common.messages.base import OscMessage, WireField, WireKind
from common.messages.codec import MAX_BUNDLE_DEPTH
from common.messages.registry import REGISTRY, MessageRegistry
from common.messages.system import PROTOCOL_VERSION

_TYPE_NAMES = {WireKind.INT: "i", WireKind.FLOAT: "f", WireKind.STR: "s", WireKind.TIME: "i f"}


def _range(f: WireField) -> str:
    """``low .. high``, both taken; a bound the value must not reach is marked ``> low`` or ``< high``."""
    if f.choices:
        return " \\| ".join(f.choices)
    if f.minimum is None and f.maximum is None:
        return ""
    low = "" if f.minimum is None else f"{'> ' if f.exclusive_minimum else ''}{f.minimum:g}"
    high = "" if f.maximum is None else f"{'< ' if f.exclusive_maximum else ''}{f.maximum:g}"
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
            rng = _range(f)
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
        "number as a float: integral floats are accepted for `i` arguments; `h` (int64) and `d` (float64)",
        "are taken as numbers too (an `h` must still fit an `i` argument). Any other type (`T`, `F`, `N`, `I`,",
        "blobs, timetags, ...) is refused as a wrong type. A rig time takes two arguments, whole seconds (`i`)",
        "then the fraction (`f`). Bundles are accepted, nested up to "
        f"{MAX_BUNDLE_DEPTH} deep; their timetags are ignored,",
        "and an empty one (no elements, valid OSC) holds nothing. A bundle whose structure or any message is",
        "malformed (an element size that is not a positive multiple of 4 within its bundle, an element that is",
        "neither a message nor a bundle) is dropped whole, as malformed.",
        "A message that does not match its model is dropped, counted by reason and reported in",
        "`/batteur/health`; a physics, score, sound, interaction or graphics control that does not is also",
        "answered to its sender with that service's refusal (`/batteur/physics/rejected`,",
        "`/batteur/sound/rejected`, `/batteur/interaction/error`, `/batteur/graphics/rejected`), by a node of",
        "that service only, a few a second per sender host at most. A valid control sent to a node of another",
        "service is answered with that node's own refusal naming the service that takes it (counted as",
        "`wrong_node`); an answer is never answered.",
        "",
        "Ranges include both ends (`0 .. 2`: from 0 to 2) unless an end is marked `>` or `<`: `> 0 .. 3600` is",
        "more than 0 and at most 3600. An empty end is unbounded.",
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


def main(argv: Sequence[str] | None = None) -> int:
    argparse.ArgumentParser(
        prog="python -m common.messages.docs",
        description="Print docs/osc.md, the OSC namespace reference, generated from the message models "
                    "(python -m common.messages.docs > docs/osc.md; batteur docs writes the file itself). "
                    "Takes no options.").parse_args(argv)
    sys.stdout.write(render_markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
