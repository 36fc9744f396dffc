"""``batteur docs``: regenerate docs/osc.md from the message models."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from batteur.errors import report_error
from common.messages.docs import render_markdown
from common.output_paths import check_output_file


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batteur docs", description="Write the OSC reference (Markdown).")
    parser.add_argument("-o", "--output", type=Path, default=Path("docs/osc.md"), help="default: docs/osc.md")
    opts = parser.parse_args(argv)
    try:
        check_output_file(opts.output, "-o")
        opts.output.write_text(render_markdown(), encoding="utf-8")
    except ValueError as exc:  # a path it cannot write: 1
        return report_error("batteur docs", exc)
    except OSError as exc:  # the write itself failed (a full disk)
        return report_error("batteur docs", f"-o {opts.output}: cannot write it ({exc.strerror or exc})")
    print(f"wrote {opts.output}")
    return 0
