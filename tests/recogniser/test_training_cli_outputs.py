"""A trainer whose model file cannot be written at the end of its run says so in one line with exit status 1
(README, "Exit status"), rather than a traceback after an hour of work.

``--out`` is checked when the run starts; here its folder goes away while the excerpts "render" (stand-ins), so
the write at the end fails as on a disk that filled up. The ``--retune`` runs need neither PyTorch nor
scikit-learn, so the trainers' dependency checks are passed over: these run where they are not installed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from services.recogniser.model import MODEL_PATH
from services.recogniser.training.dataset import Examples

pytest.importorskip("mir_eval")  # the trainers' threshold choice imports it


def _out(tmp_path: Path) -> Path:
    folder = tmp_path / "models"
    folder.mkdir()
    return folder / "m.npz"


def test_train_net_s_model_that_cannot_be_written_at_the_end_is_1(monkeypatch: pytest.MonkeyPatch,
                                                                  tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.training import train_net, tune

    out = _out(tmp_path)

    def rendered(*args: object, **kwargs: object) -> object:  # --out's folder goes away meanwhile
        out.parent.rmdir()
        return object()

    monkeypatch.setattr(train_net, "import_or_say", lambda modules, prog: True)  # --retune does without PyTorch
    monkeypatch.setattr(train_net, "kits_installed", lambda prog: True)
    monkeypatch.setattr(train_net, "frames", rendered)
    monkeypatch.setattr(tune, "choose", lambda net, val, rules=False: None)  # the thresholds: not what is tested
    status = train_net.main(["--retune", str(MODEL_PATH), "--out", str(out), "--cache", str(tmp_path / "c")])
    assert status == 1  # was an OSError traceback
    assert capsys.readouterr().err == (f"{train_net.PROG}: error: --out {out}: cannot write it (No such file or "
                                       "directory); nothing written\n")
    assert not out.parent.exists()


def test_train_s_model_that_cannot_be_written_at_the_end_is_1(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.model import load_model
    from services.recogniser.training import train

    out = _out(tmp_path)
    features = load_model(MODEL_PATH).live.mean.shape[0]

    def rendered(*args: object) -> Examples:  # --out's folder goes away meanwhile
        out.parent.rmdir()
        z = np.zeros((1, 9), np.float32)
        return Examples(np.zeros((1, features), np.float32), z, z, np.zeros(1), 0, np.zeros(1), np.zeros(1, int),
                        np.zeros((0, 3)))

    monkeypatch.setattr(train, "import_or_say", lambda modules, prog: True)  # --retune does without scikit-learn
    monkeypatch.setattr(train, "kits_installed", lambda prog: True)
    monkeypatch.setattr(train, "_examples", rendered)
    monkeypatch.setattr(train, "choose_thresholds", lambda prob, val: np.full(prob.shape[1], 0.5, np.float32))
    status = train.main(["--retune", str(MODEL_PATH), "--out", str(out), "--cache", str(tmp_path / "c")])
    assert status == 1  # was an OSError traceback
    assert capsys.readouterr().err == (f"{train.PROG}: error: --out {out}: cannot write it (No such file or "
                                       "directory); nothing written\n")
