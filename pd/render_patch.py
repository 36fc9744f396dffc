"""Draw a Pure Data patch file as a PNG, the way Pd's editor lays it out (for docs/pd.md).

    python pd/render_patch.py pd/control.pd docs/img/pd-control.png
    python pd/render_patch.py --canvas sound pd/control.pd docs/img/pd-control-sound.png   # its [pd sound]

No Pd GUI or X server needed: the .pd file gives every box's position and text, and every
connection. Boxes are sized from their text (Pd's 12-point font is about 7 pixels a character),
GUI objects from their own size arguments; inlets and outlets are counted from the connections.
A PNG keeps the SHA-256 of the patch it was drawn from (``--check`` compares it with the patch as
it is now; tests/deploy/test_pd_walkthrough.py does so for the pictures of docs/pd.md).
"""

from __future__ import annotations

import argparse
import hashlib
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont
from PIL.PngImagePlugin import PngInfo

CHAR_W = 7
LINE_H = 16
MAX_CHARS = 60
SOURCE_KEY = "batteur-patch-sha256"
"""PNG text chunk holding the SHA-256 (hex) of the patch file a picture was drawn from."""


@dataclass
class Box:
    kind: str  # obj, msg, text, gui, atom
    x: int
    y: int
    text: str
    w: int = 0
    h: int = 0
    chars: int = 0  # wrap width in characters (", f N" in the file); 0: the default


def _unescape(text: str) -> str:
    return text.replace("\\$", "$").replace(" \\,", ",").replace(" \\;", ";").replace("\\,", ",").replace("\\;", ";")


class PatchError(ValueError):
    """The file is not a Pure Data patch this script can read."""


def parse(path: Path, canvas: str = "") -> tuple[list[Box], list[tuple[int, int, int, int]], tuple[int, int]]:
    """The boxes, connections and window size of the patch's main canvas, or of its first sub-patch
    ``[pd CANVAS]`` (a sub-patch of the main canvas); PatchError when there is no such sub-patch."""
    content = path.read_text(encoding="utf-8")
    if not content.startswith("#N canvas"):
        raise PatchError(f"{path} is not a Pure Data patch (a .pd file starts with '#N canvas')")
    records = [r.strip() for r in re.split(r"(?<!\\);\s*\n", content) if r.strip()]
    boxes: list[Box] = []
    connects: list[tuple[int, int, int, int]] = []
    size = (800, 600)
    depth = 0
    drawn = 0 if canvas else 1  # the depth of the canvas drawn (0: not found yet)
    for rec in records:
        parts = rec.split(None, 4)
        if rec.startswith("#N canvas"):
            depth += 1
            fields = parts[4].split() if len(parts) > 4 else []
            if depth == 1 and not canvas or depth == 2 and not drawn and fields[2:3] == [canvas]:
                drawn = depth
                size = (int(fields[0]), int(fields[1]))
            continue
        if rec.startswith("#X restore"):
            depth -= 1
            if depth == drawn:  # a subpatch is one box of its parent, [pd NAME]: it counts in the connections
                boxes.append(Box("obj", int(parts[2]), int(parts[3]), _unescape(parts[4].rstrip(";"))
                                 if len(parts) > 4 else "pd"))
            elif depth + 1 == drawn:  # the sub-patch drawn is closed: the rest is its parent's
                break
            continue
        if depth != drawn or not rec.startswith("#X "):
            continue
        kind = parts[1]
        if kind == "connect":
            a, o, b, i = (int(v) for v in rec.split()[2:6])
            connects.append((a, o, b, i))
            continue
        if kind in ("obj", "msg", "text", "floatatom", "symbolatom"):
            x, y = int(parts[2]), int(parts[3])
            raw = parts[4].rstrip(";") if len(parts) > 4 else ""
            chars = 0
            found = re.search(r"(?<!\\), f (\d+)$", raw)
            if found:
                chars = int(found.group(1))
                raw = raw[: found.start()]
            text = _unescape(raw)
            if kind == "obj" and text.split(" ")[0] in ("hsl", "nbx", "bng", "tgl", "hradio", "vsl"):
                boxes.append(_gui(x, y, text))
            elif kind in ("floatatom", "symbolatom"):
                width = int(text.split()[0]) if text else 5
                receive = text.split()[5] if len(text.split()) > 5 else "-"
                boxes.append(Box("atom", x, y, receive if receive != "-" else "", width * CHAR_W + 4, LINE_H + 2))
            else:
                boxes.append(Box(kind, x, y, text, chars=chars))
    if not drawn:
        raise PatchError(f"{path} has no sub-patch [pd {canvas}] in its main canvas")
    return boxes, connects, size


def _gui(x: int, y: int, text: str) -> Box:
    args = text.split()
    name = args[0]
    if name == "hsl":
        return Box("gui", x, y, args[7] if args[7] != "empty" else "", int(args[1]), int(args[2]))
    if name == "nbx":
        return Box("gui", x, y, "0", int(args[1]) * CHAR_W + 12, int(args[2]) + 2)
    if name in ("bng", "tgl"):
        return Box("gui", x, y, "o", int(args[1]), int(args[1]))
    return Box("gui", x, y, name, 60, 16)


def _wrap(text: str, width: int) -> list[str]:
    lines: list[str] = []
    current = ""
    for word in text.split(" "):
        if current and len(current) + 1 + len(word) > width:
            lines.append(current)
            current = word
        else:
            current = f"{current} {word}" if current else word
    if current:
        lines.append(current)
    return lines or [""]


def render(src: Path, dst: Path, canvas: str = "") -> None:
    """Draw ``src``'s main canvas (or its sub-patch ``[pd CANVAS]``) into ``dst``, keeping ``src``'s digest."""
    boxes, connects, (width, height) = parse(src, canvas)
    font = ImageFont.load_default()
    for box in boxes:
        if box.kind in ("obj", "msg"):
            lines = _wrap(box.text, MAX_CHARS)
            box.w = max(len(line) for line in lines) * CHAR_W + 8
            box.h = LINE_H * len(lines) + 4
        elif box.kind == "text":
            lines = _wrap(box.text, box.chars or 60)
            box.w = max(len(line) for line in lines) * CHAR_W
            box.h = LINE_H * len(lines)
    right = max([width] + [b.x + b.w + 20 for b in boxes])
    bottom = max([height] + [b.y + b.h + 20 for b in boxes])
    image = Image.new("RGB", (right, bottom), "white")
    draw = ImageDraw.Draw(image)
    outlets: dict[int, int] = {}
    inlets: dict[int, int] = {}
    for a, o, b, i in connects:
        outlets[a] = max(outlets.get(a, 1), o + 1)
        inlets[b] = max(inlets.get(b, 1), i + 1)

    def port_x(box: Box, k: int, n: int) -> int:
        return box.x + (0 if n <= 1 else int(k * (box.w - 7) / (n - 1))) + 3

    for a, o, b, i in connects:
        if a < len(boxes) and b < len(boxes):
            src_box, dst_box = boxes[a], boxes[b]
            start = (port_x(src_box, o, outlets.get(a, 1)), src_box.y + src_box.h)
            end = (port_x(dst_box, i, inlets.get(b, 1)), dst_box.y)
            draw.line([start, end], fill=(70, 70, 70), width=1)
    for index, box in enumerate(boxes):
        if box.kind == "text":
            for k, line in enumerate(_wrap(box.text, box.chars or 60)):
                draw.text((box.x, box.y + k * LINE_H), line, fill=(40, 40, 40), font=font)
            continue
        x0, y0, x1, y1 = box.x, box.y, box.x + box.w, box.y + box.h
        if box.kind == "msg":
            draw.polygon([(x0, y0), (x1 + 4, y0), (x1, y0 + 4), (x1, y1 - 4), (x1 + 4, y1), (x0, y1)],
                         outline="black", fill=(245, 245, 245))
        elif box.kind == "gui":
            draw.rectangle([x0, y0, x1, y1], outline="black", fill=(230, 236, 245))
        elif box.kind == "atom":
            draw.polygon([(x0, y0), (x1 - 4, y0), (x1, y0 + 4), (x1, y1), (x0, y1)], outline="black", fill="white")
        else:
            draw.rectangle([x0, y0, x1, y1], outline="black", fill="white")
        if box.kind in ("obj", "msg"):
            for k, line in enumerate(_wrap(box.text, MAX_CHARS)):
                draw.text((x0 + 4, y0 + 3 + k * LINE_H), line, fill="black", font=font)
        elif box.text:
            draw.text((x0 + 3, y0 + 2), box.text, fill=(60, 60, 60), font=font)
        if box.kind != "text":
            for k in range(outlets.get(index, 0)):
                px = port_x(box, k, outlets[index])
                draw.rectangle([px - 3, y1 - 2, px + 4, y1], fill="black")
            for k in range(inlets.get(index, 0)):
                px = port_x(box, k, inlets[index])
                draw.rectangle([px - 3, y0, px + 4, y0 + 2], fill="black")
    dst.parent.mkdir(parents=True, exist_ok=True)
    info = PngInfo()
    info.add_text(SOURCE_KEY, patch_digest(src))
    image.save(dst, pnginfo=info)  # formats other than PNG ignore the chunk


def patch_digest(patch: Path) -> str:
    """SHA-256 (hex) of a patch file's bytes."""
    return hashlib.sha256(patch.read_bytes()).hexdigest()


def drawn_from(picture: Path) -> str | None:
    """The digest of the patch a PNG was drawn from (:func:`patch_digest`), or None if it does not say."""
    with Image.open(picture) as image:
        value = image.info.get(SOURCE_KEY)
    return value if isinstance(value, str) else None


def check(patch: Path, picture: Path) -> int:
    """0 if ``picture`` was drawn from ``patch`` as it is now, else 1 (with the command that redraws it)."""
    try:
        current = drawn_from(picture) == patch_digest(patch)
    except OSError as exc:
        print(f"render_patch.py: cannot read {exc.filename or picture}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    if not current:
        print(f"{picture} is stale: run python pd/render_patch.py {patch} {picture}", file=sys.stderr)
        return 1
    print(f"{picture} is up to date")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python pd/render_patch.py",
        description="Draw a Pure Data patch file as a picture, the way Pd's editor lays it out (no Pd GUI needed).",
        epilog="example: python pd/render_patch.py pd/control.pd docs/img/pd-control.png")
    parser.add_argument("patch", type=Path, metavar="PATCH.pd", help="the patch file to draw")
    parser.add_argument("out", type=Path, metavar="OUT.png",
                        help="the picture to write (its extension chooses the format: .png, .jpg, ...)")
    parser.add_argument("--canvas", default="", metavar="NAME",
                        help="draw the sub-patch [pd NAME] of the main canvas instead (e.g. sound, the control "
                             "panel's SOUND window)")
    parser.add_argument("--check", action="store_true",
                        help="write nothing: exit 1 if OUT.png was not drawn from PATCH.pd as it is now")
    args = parser.parse_args(argv)
    if args.check:
        return check(args.patch, args.out)
    formats = Image.registered_extensions()
    if args.out.suffix.lower() not in formats:
        parser.error(f"{args.out}: unknown picture format {args.out.suffix or '(no extension)'!r}; "
                     "use .png (or another extension Pillow knows, e.g. .jpg)")
    try:
        render(args.patch, args.out, args.canvas)
    except PatchError as exc:
        parser.error(str(exc))
    except UnicodeDecodeError:
        parser.error(f"{args.patch} is not a Pure Data patch (not text)")
    except (ValueError, IndexError) as exc:
        parser.error(f"{args.patch}: cannot read this patch: {exc}")
    except OSError as exc:
        parser.error(f"{exc.filename or args.patch}: {exc.strerror or exc}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
