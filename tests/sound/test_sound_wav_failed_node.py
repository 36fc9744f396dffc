"""A sound node that failed while recording (``keep`` False as its WAV closes) does not name its take: an earlier
take at ``--wav`` stays, and what was recorded stays in the part file (``batteur rig --record`` gives sound the final
name, ``DIR/performance.wav``, and relies on this)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import soundfile as sf

from services.sound.node import WavSink


def test_a_failed_nodes_take_keeps_its_part_name_and_the_earlier_take(tmp_path: Path) -> None:
    wav = tmp_path / "performance.wav"
    earlier = np.linspace(-0.5, 0.5, 1000)
    sf.write(wav, earlier, 48000, subtype="PCM_24")
    sink = WavSink(wav, 48000, 1, lambda: [(0, 0.0)], keep=lambda: False)
    sink(np.full((256, 1), 0.25, dtype=np.float32))
    sink.close()
    (part,) = tmp_path.glob(".performance.wav.*.part")
    # no take's .json either: the part file's timing stays beside it (batteur wav-repair carries it to the take)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([wav.name, part.name, part.name + ".json"])
    assert np.allclose(sf.read(wav)[0], earlier, atol=1e-6)
    assert sf.info(part).frames == 256  # what was recorded, playable
