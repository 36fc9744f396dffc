"""The Groove MIDI Dataset check says which splits a copy holds when the one asked for is not among them."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.recogniser.training.dataset import GrooveMissingError, require_groove


def test_a_split_the_copy_does_not_hold_names_the_ones_it_does(tmp_path: Path) -> None:
    """A copy of the train and validation splits only: asking for the test split said "unpack the dataset so that
    info.csv exists" though info.csv was there."""
    (tmp_path / "a.mid").write_bytes(b"")
    (tmp_path / "b.mid").write_bytes(b"")
    (tmp_path / "info.csv").write_text("midi_filename,split\na.mid,train\nb.mid,validation\n")
    require_groove(("train",), tmp_path)  # held: no error
    with pytest.raises(GrooveMissingError) as caught:
        require_groove(("test",), tmp_path)
    message = str(caught.value)
    assert "no performance of the test split" in message and "train, validation splits" in message
    assert "unpack" not in message
