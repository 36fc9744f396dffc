"""The files ``batteur render`` writes into its output folder: one list for the render (what it may replace) and
for ``batteur evaluate`` (what is a render's output, not a score), which must not import the render for it."""

from __future__ import annotations

SCORE_OUTPUTS = ("performance.wav", "impacts.csv", "performance.bvh", "report.json")
"""The files every score render writes into its folder (besides the score's and kit file's copies)."""
VIDEO_OUTPUT = "performance.mp4"
"""What ``--video`` adds."""
GLTF_OUTPUT = "performance.glb"
"""What ``--gltf`` adds."""
RENDER_OUTPUTS = (*SCORE_OUTPUTS, VIDEO_OUTPUT, GLTF_OUTPUT)
"""Every file a render writes next to its report.json, none of them a score."""
