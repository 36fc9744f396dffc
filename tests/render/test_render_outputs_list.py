"""One list of a render's output files (batteur/render_outputs.py) for ``batteur render`` (what it may replace) and
``batteur evaluate`` (a render's file given as a score is refused): evaluate kept its own copy of render's list plus
the video and glTF, which a new output would have had to be added to twice."""

from __future__ import annotations

import subprocess
import sys

from batteur import evaluate, render


def test_evaluate_refuses_every_file_a_render_writes() -> None:
    everything = render.score_outputs(render.RenderOptions(video=True, gltf=True))
    assert sorted(evaluate.RENDER_OUTPUTS) == sorted(everything)


def test_evaluate_reads_the_list_without_importing_the_render() -> None:
    """evaluate imports render only where it renders (0.6 s of imports more for ``batteur evaluate DIR``)."""
    code = "import sys, batteur.evaluate; print('batteur.render' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
