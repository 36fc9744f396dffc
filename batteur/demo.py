"""``batteur demo``: the README's demo, rendered on this machine.

Renders the shipped demo through physics -> interaction -> sound into
``batteur-demo/`` (or ``-o DIR``) and prints where the WAV and report are.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from batteur import render


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="batteur demo", description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("-o", "--output", type=Path, default=Path("batteur-demo"),
                        help="output directory (default: batteur-demo)")
    opts = parser.parse_args(argv)
    strikes = "0.25:2,0.5:3,0.75:2,1.0:4.5,1.25:1.5,1.375:1.5,1.5:5"
    return render.main(["-o", str(opts.output), "--strikes", strikes])
