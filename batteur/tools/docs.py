"""``batteur docs``: regenerate docs/osc.md from the message models."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from common.messages.docs import render_markdown
from common.output_paths import check_output_file


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batteur docs", description="Write the OSC reference (Markdown).")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/osc.md"), help="default: docs/osc.md")
    opts = parser.parse_args(argv)
    try:
        check_output_file(opts.output, "-o")
    except ValueError as exc:
        print(f"batteur docs: {exc}", file=sys.stderr)
        return 2
    opts.output.write_text(render_markdown(), encoding="utf-8")
    print(f"wrote {opts.output}")
    return 0
