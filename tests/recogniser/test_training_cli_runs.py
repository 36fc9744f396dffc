"""A training run keeps its work: Ctrl-C while fitting keeps the best network so far, a loss that is not a number
never becomes a model file, and the model file is written whole, at exactly the path given, or not at all.

The runs fit a tiny network on random spectra (``train_net.frames`` replaced), a few seconds each.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from services.recogniser import features as F
from services.recogniser.model import load_model
from services.recogniser.training.dataset import Examples

pytest.importorskip("torch")  # training-only dependency
pytest.importorskip("mir_eval")

from services.recogniser.training import fit_net, train_net  # noqa: E402
from services.recogniser.training.frames import WINDOWS, FrameSet, windows_for  # noqa: E402

TINY = ["--width", "8", "--dilations", "1", "--epochs", "0.5", "--threads", "1", "--workers", "1",
        "--excerpts", "2", "--val-excerpts", "1"]
"""A network and a run small enough for seconds."""


def _frames(n_excerpts: int, seed: int) -> FrameSet:
    """Random wide-band spectra of excerpts of 4 s with a few strikes each (what ``train_net.frames`` gives)."""
    rng = np.random.default_rng(seed)
    per = 400
    spec = (rng.random((n_excerpts * per, F.WIDE.n, len(WINDOWS))) * 2).astype(np.float16)
    hits = np.array([[e, t, c, 90] for e in range(n_excerpts) for t, c in ((0.5, 0), (1.5, 1), (2.5, 2))],
                    np.float64)
    return FrameSet(spec, np.arange(n_excerpts + 1) * per, hits, windows_for(F.WIDE, WINDOWS), 441, F.WIDE)


@pytest.fixture
def offline(monkeypatch: pytest.MonkeyPatch) -> None:
    """``train_net`` on random spectra, as if the kits were installed and the excerpts rendered."""
    monkeypatch.setattr(train_net, "kits_installed", lambda prog: True)
    monkeypatch.setattr(train_net, "frames", lambda cache, name, n, seed, *a, **k: _frames(n, seed))


def _main(argv: list[str]) -> int:
    try:
        return train_net.main(argv)
    except KeyboardInterrupt:
        pytest.fail("Ctrl-C escaped the trainer as a traceback")


def _interrupt_on_call(monkeypatch: pytest.MonkeyPatch, n: int) -> None:
    """Ctrl-C while the ``n``-th training batch is drawn."""
    calls = []
    draw = fit_net.Batches.random

    def random(self: fit_net.Batches, *args: object) -> object:
        calls.append(1)
        if len(calls) == n:
            raise KeyboardInterrupt
        return draw(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(fit_net.Batches, "random", random)


def test_the_model_file_is_written_at_exactly_the_path_given(offline: None, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "model"  # no .npz: NumPy alone would write model.npz
    assert _main([*TINY, "--out", str(out), "--cache", str(tmp_path / "c")]) == 0
    assert load_model(out).meta["width"] == 8
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c", "model"]
    assert f"wrote {out} (" in capsys.readouterr().out


def test_ctrl_c_while_fitting_keeps_the_best_network_so_far(offline: None, monkeypatch: pytest.MonkeyPatch,
                                                            tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _interrupt_on_call(monkeypatch, 2)  # before the first validation (every 250 steps)
    out = tmp_path / "m.npz"
    assert _main([*TINY, "--epochs", "100", "--out", str(out), "--cache", str(tmp_path / "c")]) == 0
    printed = capsys.readouterr().out
    assert "fitting stopped (Ctrl-C at step 2)" in printed and f"wrote {out}" in printed
    assert load_model(out).offline.thresholds.shape == (10,)


def test_ctrl_c_after_a_validation_keeps_the_validated_state(monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    data = _frames(2, 0)
    kept: list[dict] = []
    validate = fit_net.validation_loss

    def remembered(net: fit_net.Net, val: fit_net.Batches, n: int | None = None) -> float:
        kept.append({k: t.clone() for k, t in net.state_dict().items()})
        return validate(net, val, n)

    monkeypatch.setattr(fit_net, "validation_loss", remembered)
    _interrupt_on_call(monkeypatch, 5)  # after the validation at step 2 (and 4)
    try:
        net = fit_net.fit(data, data, epochs=100, seed=0, width=8, dilations=(1,), log_every=2,
                          windows=data.windows)
    except KeyboardInterrupt:
        pytest.fail("Ctrl-C escaped the fitting, losing the fitted network")
    assert "fitting stopped (Ctrl-C at step 5): keeping the state of validation-kit loss" in capsys.readouterr().out
    state = net.state_dict()
    assert any(all(bool((state[k] == t).all()) for k, t in s.items()) for s in kept)  # a validated state


def test_ctrl_c_while_writing_keeps_the_earlier_model_file(offline: None, monkeypatch: pytest.MonkeyPatch,
                                                           tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m.npz"
    out.write_bytes(b"the earlier model")

    def interrupted(*args: object) -> None:  # Ctrl-C with the new file written beside the old, not yet renamed
        raise KeyboardInterrupt

    monkeypatch.setattr("common.output_paths.os.replace", interrupted)
    assert _main([*TINY, "--out", str(out), "--cache", str(tmp_path / "c")]) == 130
    assert out.read_bytes() == b"the earlier model"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c", "m.npz"]  # no partial file left beside it
    assert f"{train_net.PROG}: interrupted: nothing written to {out}" in capsys.readouterr().err


def test_a_loss_that_is_not_a_number_writes_no_model(offline: None, monkeypatch: pytest.MonkeyPatch,
                                                     tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    loss_of: Callable[..., object] = fit_net.loss_of
    monkeypatch.setattr(fit_net, "loss_of", lambda *a, **k: loss_of(*a, **k) * float("nan"))  # diverged
    out = tmp_path / "m.npz"
    assert _main([*TINY, "--out", str(out), "--cache", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{train_net.PROG}: error: the fitting diverged")
    assert "nothing written" in err[0]
    assert not out.exists()


def test_the_live_trainer_shows_progress_while_rendering(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("sklearn")  # training-only dependency
    from services.recogniser.training import frames, train

    def one(job: object) -> Examples:
        z = np.zeros((1, 9), np.float32)
        return Examples(np.zeros((1, 4), np.float32), z, z, np.zeros(1), 0, np.zeros(1), np.zeros(1, int),
                        np.zeros((0, 3)))

    monkeypatch.setattr(train, "prepare", lambda kits: None)
    monkeypatch.setattr(train, "jobs", lambda n, *a: list(range(n)))
    monkeypatch.setattr(train, "_excerpt", one)
    monkeypatch.setattr(frames, "PROGRESS_EVERY", 2)
    ex = train.make_examples(5, 1, 1, ("kit",))
    assert len(ex.y) == 5
    printed = capsys.readouterr().out
    assert "rendering 5 excerpts" in printed and "rendered 2/5 excerpts" in printed
    assert "rendered 1/5" not in printed and "rendered 5/5" not in printed  # the end has its own line
    monkeypatch.setattr(frames, "PROGRESS_S", 0.0)  # a slow rendering: a line at least every minute
    train.make_examples(3, 1, 1, ("kit",))
    assert "rendered 1/3 excerpts" in capsys.readouterr().out


def test_a_cached_frame_set_cut_short_is_rendered_again(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "set.npz"
    _frames(2, 0).save(path)
    whole = FrameSet.load_cached(path)
    assert whole is not None and whole.n_excerpts == 2
    spec = Path(f"{path}.spec.npy")
    spec.write_bytes(spec.read_bytes()[: spec.stat().st_size // 2])  # a disk that filled up, a copy cut short
    assert FrameSet.load_cached(path) is None
    assert f"the cached {path} cannot be read" in capsys.readouterr().out
    path.write_bytes(b"half a zip")
    assert FrameSet.load_cached(path) is None
    assert FrameSet.load_cached(tmp_path / "none.npz") is None


def test_a_cached_live_example_set_cut_short_is_rendered_again(monkeypatch: pytest.MonkeyPatch,
                                                                tmp_path: Path) -> None:
    pytest.importorskip("sklearn")  # training-only dependency
    from services.recogniser.training import train

    cache = tmp_path / "examples.npz"
    cache.write_bytes(b"PK half a zip")
    z = np.zeros((1, 9), np.float32)
    made = Examples(np.zeros((1, 4), np.float32), z, z, np.zeros(1), 0, np.zeros(1), np.zeros(1, int),
                    np.zeros((0, 3)))
    monkeypatch.setattr(train, "make_examples", lambda *a: made)
    assert train._examples(cache, 1, 1, 1, ("kit",)).x_live.shape == (1, 4)
    with np.load(cache) as whole:  # the cache is now whole
        assert whole["x_live"].shape == (1, 4)
    assert [p.name for p in tmp_path.iterdir()] == ["examples.npz"]


def test_a_cache_without_room_is_refused_before_rendering_into_it(monkeypatch: pytest.MonkeyPatch,
                                                                  tmp_path: Path) -> None:
    from services.recogniser.training import frames

    monkeypatch.setattr(frames, "prepare", lambda kits: None)
    monkeypatch.setattr(frames, "jobs", lambda *a, **k: pytest.fail("rendering started on a full disk"))
    monkeypatch.setattr(frames.shutil, "disk_usage", lambda path: type("Usage", (), {"free": 10 * 2**20})())
    with pytest.raises(frames.CacheFullError, match=r"has 0.0 GiB free, the spectra of these excerpts need"):
        frames.make_frames(100, 1, 1, ("kit",), path=tmp_path / "set.npz", bands=F.WIDE,
                           windows_22k=WINDOWS, hop=441)
    assert list(tmp_path.iterdir()) == []  # no memory-mapped file begun


def test_the_trainer_reports_a_full_cache_in_one_line(offline: None, monkeypatch: pytest.MonkeyPatch,
                                                      tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from services.recogniser.training.frames import CacheFullError

    def full(*a: object, **k: object) -> FrameSet:
        raise CacheFullError("the cache /c has 0.1 GiB free, the spectra of these excerpts need 3.2 GiB")

    monkeypatch.setattr(train_net, "frames", full)
    assert _main([*TINY, "--out", str(tmp_path / "m.npz"), "--cache", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{train_net.PROG}: error: the cache /c has 0.1 GiB free")


@pytest.mark.parametrize("options", [["--bands", "narrow"], ["--hop", "220"]])
@pytest.mark.parametrize("what", ["--retune", "--ensemble"])
def test_retuning_a_model_that_reads_other_spectra_is_refused_before_rendering(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str], what: str,
        options: list[str]) -> None:
    shipped = Path(train_net.__file__).parents[1] / "models" / "recogniser.npz"  # read only
    monkeypatch.setattr(train_net, "kits_installed", lambda prog: True)
    monkeypatch.setattr(train_net, "frames", lambda *a, **k: pytest.fail("rendered for a model it cannot tune"))
    out = tmp_path / "m.npz"
    assert _main([*options, what, str(shipped), "--out", str(out), "--cache", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{train_net.PROG}: error: {what} {shipped}: its network reads 56 bands")
    assert "(give --bands wide --hop 441)" in err[0]
    assert not out.exists()
