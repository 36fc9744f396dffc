"""``batteur demo``: the README's demo, rendered on this machine.

Renders the shipped demo groove (a rock beat and a fill, :data:`DEMO_GROOVE`)
with the full drummer (planner -> physics -> interaction -> sound, the rig's
cores) into ``batteur-demo/`` (or ``-o DIR``) and prints where the WAV and the
report are. ``--strikes`` renders the strike scene instead (one stick on the
snare, no drummer: a quick check that physics, interaction and sound work).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

from batteur import render

DEMO_GROOVE = """\
# Batteur demo groove: two bars of rock, a fill, a crash (100 bpm, about 7 s)
tempo 100
meter 4/4
HH |x.x.x.x.x.x.x.x.|x.x.x.x.x.x.x.x.|
SN |....X.......X...|....X.......X..g|
BD |x.......x.x.....|x.......x.x.....|

SN |....X...xxxx....|
HT |............xx..|
FT |..............xx|
BD |x.......x.......|

CR |X...|
BD |x...|
"""
"""The demo score (Batteur text format, docs/score-format.md)."""
DESCRIPTION = ("Render the shipped demo groove (two bars of rock, a fill, a crash) with the full drummer (planner -> "
               "physics -> interaction -> sound, the rig's cores) into batteur-demo/ (or -o DIR) and print where "
               "the WAV and the report are.")
"""``--help``'s description: plain text (the module docstring's markup would be shown as it is)."""
PROG = "batteur demo"
"""The command's name in its usage and error lines (the render's own say ``batteur demo`` too)."""


def point_report_at_copy(output: Path) -> None:
    """Make report.json's ``score`` the copy the render wrote beside it (``DIR/score.txt``), not the temporary
    file it was rendered from, deleted since: a reader of the report, or ``batteur evaluate DIR``, finds it."""
    path = output / "report.json"
    report = json.loads(path.read_text(encoding="utf-8"))
    report["score"] = str(output / "score.txt")
    staged = path.with_name(".report.json.demo")
    staged.write_text(json.dumps(report, indent=2), encoding="utf-8")  # as the render writes it
    os.replace(staged, path)  # whole: never a half-written report


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION)
    parser.add_argument("-o", "--output", type=Path, default=Path("batteur-demo"), metavar="DIR",
                        help="output directory (default: batteur-demo)")
    parser.add_argument("--control", default="cartesian", choices=list(render.CONTROL_MODES),
                        help="tracking mode (default: cartesian)")
    parser.add_argument("--strikes", action="store_true", help="render the strike scene instead of the drummer")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace files in DIR that no earlier render wrote (as batteur render --overwrite)")
    opts = parser.parse_args(argv)
    passed = (["--quiet"] if opts.quiet else []) + (["--overwrite"] if opts.overwrite else [])  # on to render
    if opts.strikes:
        strikes = "0.25:2,0.5:3,0.75:2,1.0:4.5,1.25:1.5,1.375:1.5,1.5:5"
        code = render.main(["-o", str(opts.output), "--strikes", strikes, *passed], prog=PROG)
        if code == 0:  # no score: nothing to evaluate against
            print(f"listen: {opts.output / 'performance.wav'}")
            print(f"report: {opts.output / 'report.json'}")
        return code
    with tempfile.TemporaryDirectory(prefix="batteur-demo-") as tmp:
        score = Path(tmp) / "demo-groove.txt"
        score.write_text(DEMO_GROOVE, encoding="utf-8")
        code = render.main([str(score), "-o", str(opts.output), "--control", opts.control, *passed], prog=PROG)
    if code == 0:
        point_report_at_copy(opts.output)
        print(f"listen: {opts.output / 'performance.wav'}")
        print(f"report: {opts.output / 'report.json'} (evaluate it: batteur evaluate {opts.output})")
    return code
