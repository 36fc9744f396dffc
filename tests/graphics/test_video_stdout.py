"""The video path writes nothing to stdout: pybullet's stock client printed "argv[0]=" there for every render
scene, into ``batteur render --video ... | ...``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

SCENE = """
from services.graphics.figure import LINK_NAMES, SyntheticDrummer
from services.graphics.video import TinyRendererScene
drummer = SyntheticDrummer(strokes={}, duration=0.0)
scene = TinyRendererScene(list(LINK_NAMES), drummer.pose(0.0), drummer.kit, 32, 18)
scene.close()
"""


def test_the_video_scene_prints_nothing_to_stdout() -> None:
    # a child process: pybullet writes from C, past Python's sys.stdout, and flushes at exit
    result = subprocess.run([sys.executable, "-c", SCENE], cwd=ROOT, capture_output=True, text=True, timeout=120,
                            check=True)
    assert result.stdout == ""
