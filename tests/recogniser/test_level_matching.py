"""Test-time level matching (``FrameNet.level_match``, a reference ``profile`` in the model file): a file's level
is set by its loud frames, not by its single loudest moment, and the model file carries the setting."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.recogniser import features as F
from services.recogniser.errors import ModelError
from services.recogniser.model import Model, load_model
from services.recogniser.transcribe import PEAK, transcribe

from .pattern import Pattern

CLICK_DB = 20.0
"""How far a click after the last note rises above the drums' peak, dB."""


def _notes(events: list, before_s: float) -> list[tuple[float, int]]:
    return [(e.time, e.note) for e in events if e.time < before_s]


def _same(a: list[tuple[float, int]], b: list[tuple[float, int]], within_s: float = 0.005) -> bool:
    return len(a) == len(b) and all(n == m and abs(t - u) <= within_s for (t, n), (u, m) in zip(a, b, strict=True))


def _matched(pattern: Pattern, match: float) -> Model:
    """The shipped model with the clean pattern's own band levels as its reference and ``match``."""
    model = load_model()
    net = model.offline
    net.profile = F.band_levels(net.spectrogram(pattern.audio * (PEAK / float(np.max(np.abs(pattern.audio))))))
    net.level_match = match
    return model


def test_a_loud_click_does_not_cost_notes_with_level_matching(pattern: Pattern) -> None:
    # a microphone bump 20 dB above the drums after the last note: peak normalisation turns every drum 20 dB
    # down; level matching turns them up again, so the notes before the click are the clean file's
    end = max(t for t, _, _ in pattern.notes) + 0.6
    clicked = pattern.audio.copy()
    clicked[int(end * pattern.sample_rate)] = float(np.max(np.abs(pattern.audio))) * 10 ** (CLICK_DB / 20)
    model = _matched(pattern, 1.0)
    clean = _notes(transcribe(pattern.audio, model, sample_rate=pattern.sample_rate), end - 0.1)
    heard = _notes(transcribe(clicked, model, sample_rate=pattern.sample_rate), end - 0.1)
    assert len(clean) >= len(pattern.notes) - 3 and _same(heard, clean), (clean, heard)
    model.offline.level_match = 0.0  # the same model without it: the click costs notes
    unmatched = _notes(transcribe(clicked, model, sample_rate=pattern.sample_rate), end - 0.1)
    assert len(unmatched) < len(clean)


def test_the_shipped_model_reads_files_as_before() -> None:
    net = load_model().offline
    spec = np.random.default_rng(0).random((50, net.bands.n, len(net.inputs))).astype(np.float32)
    assert net.profile is None and net.level_match == 0.0 and net.adapt(spec) is spec


def test_a_gain_before_the_log_keeps_silence_and_moves_loud_bands_by_the_gain() -> None:
    spec = np.array([[0.0, 1.0, 4.0]], np.float32)
    out = F.scale_magnitudes(spec, -1.0)  # 20 dB down
    assert out[0, 0] == 0.0 and 0.0 < out[0, 1] < 1.0 and abs(out[0, 2] - 3.0) < 1e-3


def test_the_model_file_carries_the_profile_and_refuses_bad_ones(tmp_path: Path, pattern: Pattern) -> None:
    model = _matched(pattern, 0.5)
    model.save(tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz").offline
    assert back.profile is not None and model.offline.profile is not None
    assert back.level_match == 0.5 and np.array_equal(back.profile, model.offline.profile)
    spec = model.offline.spectrogram(pattern.audio[: pattern.sample_rate])
    assert np.array_equal(back.adapt(spec), model.offline.adapt(spec))
    assert not np.array_equal(back.adapt(spec), spec)

    model.offline.profile = np.zeros((8, 3), np.float32)  # not the network's bands and windows
    model.save(tmp_path / "shape.npz")
    with pytest.raises(ModelError, match="offline.profile has shape"):
        load_model(tmp_path / "shape.npz")
    model.offline.profile = np.zeros((model.offline.bands.n, 3), np.float32)
    model.offline.level_match = 1.5
    model.save(tmp_path / "match.npz")
    with pytest.raises(ModelError, match="level_match 1.5"):
        load_model(tmp_path / "match.npz")
    model.offline.profile = np.full((model.offline.bands.n, 3), np.nan, np.float32)
    model.offline.level_match = 0.5
    model.save(tmp_path / "nan.npz")
    with pytest.raises(ModelError, match="NaN"):
        load_model(tmp_path / "nan.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as z:  # the setting kept, its profile lost
        arrays = {k: z[k] for k in z.files if k != "offline.profile"}
    np.savez(tmp_path / "lost.npz", **arrays)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="without offline.profile"):
        load_model(tmp_path / "lost.npz")


def test_a_file_saved_without_a_profile_has_no_adaptation_entries(tmp_path: Path) -> None:
    load_model().save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz", allow_pickle=False) as z:
        assert "offline.profile" not in z.files and b"level_match" not in bytes(z["meta"])


def test_the_profile_command_refuses_bad_options_before_rendering(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.training.profile import PROG, main

    with pytest.raises(SystemExit) as exc:  # a bad value: argparse's usage error, 2
        main(["--match", "1.5", "--out", str(tmp_path / "m.npz")])
    assert exc.value.code == 2 and "give a number from 0 to 1" in capsys.readouterr().err
    for argv, why in ((["--out", str(tmp_path / "no" / "m.npz")], "is not a directory"),  # files: 1
                      (["--model", str(tmp_path / "none.npz")], "model file not found")):
        out = argv if "--out" in argv else [*argv, "--out", str(tmp_path / "m.npz")]
        assert main(out) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"{PROG}: error: {argv[0]} ") and why in err and len(err.splitlines()) == 1
    assert not (tmp_path / "m.npz").exists()
