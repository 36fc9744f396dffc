"""``batteur docs``: regenerate docs/osc.md from the message models."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from batteur.errors import report_error
from common.messages.docs import render_markdown
from common.output_paths import check_output_file, write_atomically

PROG = "batteur docs"
DEFAULT_OUTPUT = Path("docs/osc.md")
"""Where the reference goes without -o: the checkout's, relative to the top of it (the current folder)."""


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description="Write the OSC reference (Markdown).")
    parser.add_argument("-o", "--output", type=Path, default=None, metavar="PATH",
                        help="default: docs/osc.md, run at the top of a Batteur checkout")
    opts = parser.parse_args(argv)
    output: Path = DEFAULT_OUTPUT if opts.output is None else opts.output
    try:
        check_output_file(output, "-o")
    except ValueError as exc:  # a path it cannot write: 1
        hint = " (run batteur docs at the top of a Batteur checkout, or give -o PATH)" if opts.output is None else ""
        return report_error(PROG, f"{exc}{hint}")
    try:  # whole or not at all: a full disk or Ctrl-C leaves the earlier reference
        write_atomically(output, render_markdown().encode("utf-8"))
    except OSError as exc:
        return report_error(PROG, f"-o {output}: cannot write it ({exc.strerror or exc})")
    print(f"wrote {output}")
    return 0
