"""``batteur demo`` refuses to replace a file of the user's in its folder, as render does, and says how to allow it;
its advice, ``--overwrite``, is an option of the demo too (it was render's only: the demo's error named an option
the demo refused)."""

from __future__ import annotations

from pathlib import Path

import pytest

from batteur import demo


def test_the_demo_keeps_a_users_file_and_overwrite_replaces_it(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    mine = tmp_path / "performance.wav"
    mine.write_text("my own take", encoding="utf-8")
    assert demo.main(["-o", str(tmp_path), "--strikes", "--quiet"]) == 1
    assert "--overwrite" in capsys.readouterr().err
    assert mine.read_text(encoding="utf-8") == "my own take"
    assert demo.main(["-o", str(tmp_path), "--strikes", "--quiet", "--overwrite"]) == 0
    assert mine.read_bytes()[:4] == b"RIFF"
