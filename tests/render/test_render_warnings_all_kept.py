"""report.json's ``warnings`` holds every warning the render printed, in order (docs/render.md): those of the options
given in vain or sharing what they decide (``--height 1.62 with --skeleton-bvh: ...``, ``--segment`` without
``--jobs``), the kit's load warnings, the score reader's, the grip's and the physics core's (``--limits-from``).
Until 8 Dec the options' warnings and the cores' were printed and missing from report.json.

The render runs as a user runs it (a process of its own, no logging set up), ``--quiet``: every line on its stderr
is a warning.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from common.kit import load_kit, save_kit
from tests.far_kits import china_at
from tests.render.test_render_skeleton_reach import _skeleton

ROOT = Path(__file__).resolve().parents[2]
PREFIX = "batteur render: warning: "


def test_every_warning_printed_is_in_the_report_in_order(tmp_path: Path) -> None:
    score = tmp_path / "tiny.txt"
    score.write_text("tempo 120\nmeter 4/4\nSN |x.x.|\n")
    kit = tmp_path / "edge.yaml"
    save_kit(china_at(load_kit("default"), 1.12), kit)  # a china a short-armed drummer does not reach
    skeleton = _skeleton(tmp_path / "short.bvh", 20, 18, 25, 25)
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "batteur", "render", str(score), "-o", str(out), "--quiet",
                           "--skeleton-bvh", str(skeleton), "--height", "1.62", "--segment", "5", "--grip", "american",
                           "--drum-channels", "10", "--kit", str(kit), "--limits-from", "punch"],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    printed = [line.removeprefix(PREFIX) for line in done.stderr.splitlines() if line.strip()]
    kept = json.loads((out / "report.json").read_text())["warnings"]
    assert kept == printed
    said = "\n".join(kept)
    for each in ("--height 1.62 with --skeleton-bvh", "--segment has no effect", "china", "--drum-channels not used",
                 "american grip", "joint limits from punch"):  # one of each kind was printed
        assert each in said, kept
