"""The node's --wav recording: a whole file or none, checked before start, whatever stops the node."""

from __future__ import annotations

import argparse
import json
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from common.config import load_settings
from services.sound.node import main, make_core

ROOT = Path(__file__).resolve().parents[2]
HEADER_BYTES = 112
"""A recording's header: RIFF/WAVE with WAVE_FORMAT_EXTENSIBLE and the JUNK chunk RF64 needs past 4 GiB."""
NODE = [sys.executable, "-m", "services.sound.node", "--no-discovery", "--no-oscquery", "--clock-master", "self",
        "--device", "none", "--port", "0", "--channels", "1"]


def _start_recording(wav: Path, tmp_path: Path) -> subprocess.Popen[bytes]:
    """Start a node recording to ``wav``; return once it has written some audio (50 kB) somewhere in its folder."""
    err = (tmp_path / "node.err").open("w")
    # SIGINT at its default: a suite run in the background ignores it, and so would the child
    proc = subprocess.Popen([*NODE, "--wav", str(wav)], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 90.0
    while not any(p.is_file() and p.stat().st_size > 50_000 for p in wav.parent.iterdir()):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(f"the node did not record: {(tmp_path / 'node.err').read_text()}")
        time.sleep(0.05)
    return proc


def _earlier_take(path: Path) -> np.ndarray:
    audio = np.linspace(-0.5, 0.5, 1000)
    sf.write(path, audio, 48000, subtype="PCM_24")
    return audio


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_or_sigterm_leave_a_whole_wav_with_its_times(tmp_path: Path, sig: signal.Signals) -> None:
    takes = tmp_path / "takes"
    takes.mkdir()
    wav = takes / "take.wav"
    _earlier_take(wav)
    proc = _start_recording(wav, tmp_path)
    proc.send_signal(sig)
    assert proc.wait(60) == 0
    assert sorted(p.name for p in takes.iterdir()) == ["take.wav", "take.wav.json"]  # no part file left
    info = sf.info(wav)
    meta = json.loads((takes / "take.wav.json").read_text())
    assert info.samplerate == 48000 and info.channels == 1 and info.frames == meta["frames"] > 10_000
    assert wav.stat().st_size == HEADER_BYTES + 3 * info.frames  # the header's length is the data's: nothing cut


def test_a_killed_node_leaves_the_earlier_take_untouched(tmp_path: Path) -> None:
    takes = tmp_path / "takes"
    takes.mkdir()
    wav = takes / "take.wav"
    earlier = _earlier_take(wav)
    proc = _start_recording(wav, tmp_path)
    proc.kill()  # no chance to finish the file (SIGKILL, power loss)
    proc.wait(60)
    # was: take.wav rewritten in place, its header still saying 0 frames
    audio, _ = sf.read(wav)
    assert audio.shape == earlier.shape and np.allclose(audio, earlier, atol=1e-6)
    assert not (takes / "take.wav.json").exists()
    # what was recorded is in the part file, whose header says how long it is
    (part,) = takes.glob(".take.wav.*.part")
    info = sf.info(part, verbose=False)
    assert info.frames > 10_000 and 0 <= part.stat().st_size - (HEADER_BYTES + 3 * info.frames) <= 3 * 256  # <= a block


def test_a_wav_name_it_cannot_write_is_refused_before_start(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name in ("take.mp3", "take"):
        # was: a multi-line soundfile error not naming --wav ("Invalid combination of format, subtype and endian")
        assert main(["--no-discovery", "--no-oscquery", "--device", "none", "--wav", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err
        assert f"--wav {tmp_path / name}: give a file ending in .wav" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_a_latency_window_the_sound_cannot_take_is_one_clear_line(capsys: pytest.CaptureFixture[str]) -> None:
    # was: "1 validation error for SoundSettings" and a pydantic message over four lines (nodes take up to 5 s)
    assert main(["--no-discovery", "--no-oscquery", "--device", "none", "--latency-s", "3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "batteur sound: error: --latency-s 3: the sound service plays at most 2 s late (the range of " \
                  "/batteur/sound/latency)"


def test_a_sound_card_that_fails_to_open_is_a_clear_error_and_records_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def no_card(*args: object) -> None:
        raise Exception("Portaudio error in Pa_OpenStream: Invalid device")  # what pyo raises

    monkeypatch.setattr("services.sound.node.audio_device_count", lambda: 1)
    monkeypatch.setattr("services.sound.node.DeviceSink", no_card)
    wav = tmp_path / "take.wav"
    earlier = _earlier_take(wav)
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    extra = argparse.Namespace(kit="default", wav=wav, device="auto", model="modal", block_size=256, channels=1,
                               reverb=0.0)
    # was: a traceback, and the earlier take.wav replaced by an empty file
    says = "--device auto: cannot play on the sound card .*Invalid device.*--device none"
    with pytest.raises(ValueError, match=says):
        make_core(settings, extra)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.wav"]
    assert np.allclose(sf.read(wav)[0], earlier, atol=1e-6)


class _Collect:
    def __init__(self) -> None:
        self.blocks: list[np.ndarray] = []
        self.closed = 0

    def __call__(self, block: np.ndarray) -> None:
        self.blocks.append(block)

    def close(self) -> None:
        self.closed += 1


class _Broken(_Collect):
    path = "take.wav"

    def __call__(self, block: np.ndarray) -> None:
        if len(self.blocks) == 3:
            raise OSError("No space left on device")
        super().__call__(block)


def test_an_output_that_fails_is_closed_and_the_others_play_on(caplog: pytest.LogCaptureFixture) -> None:
    from services.sound.core import SoundCore, SoundSettings

    core = SoundCore(SoundSettings(latency=0.0, record=False))
    broken, card = _Broken(), _Collect()
    core.sinks += [broken, card]
    core.render(0.1)  # 18 blocks
    # was: every block from the 4th on raised out of render (the node's step failed), the sound card got nothing
    assert len(card.blocks) == 18 and len(broken.blocks) == 3 and broken.closed == 1 and core.sinks == [card]
    assert "sound output take.wav failed at rig time 0.0 s: No space left on device; it was closed" in caplog.text
    core.close()


def test_a_full_disk_stops_the_recording_with_what_it_holds(tmp_path: Path) -> None:
    def small_files() -> None:  # in the child: writes past 200 kB fail with EFBIG, as on a full disk
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))

    wav = tmp_path / "take.wav"
    err = tmp_path / "node.err"
    with err.open("w") as err_file:
        proc = subprocess.Popen([*NODE, "--wav", str(wav)], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err_file,
                                preexec_fn=small_files)
        deadline = time.monotonic() + 90.0
        while "failed at rig time" not in err.read_text():
            assert proc.poll() is None and time.monotonic() < deadline, err.read_text()
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(60) == 0
    lines = [line for line in err.read_text().splitlines() if "ERROR" in line]
    # was: "core step failed: LibsndfileError: System error." at every step
    assert len(lines) == 1 and f"sound output {wav} failed" in lines[0] and "Is the disk full?" in lines[0]
    info = sf.info(wav)
    # a whole, readable WAV (the size limit may cut its last frame short)
    assert info.frames > 10_000 and 0 <= wav.stat().st_size - (HEADER_BYTES + 3 * info.frames) < 3


def test_a_close_cut_short_by_a_second_ctrl_c_finishes_on_the_next(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    import services.sound.node as node

    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    wav = tmp_path / "take.wav"
    extra = argparse.Namespace(kit="default", wav=wav, device="none", model="modal", block_size=256, channels=1,
                               reverb=0.0)
    core = make_core(settings, extra)
    core.step(0.0)
    core.step(0.5)
    real_replace = node.os.replace

    def second_ctrl_c(*args: object) -> None:
        monkeypatch.setattr(node.os, "replace", real_replace)
        raise KeyboardInterrupt

    monkeypatch.setattr(node.os, "replace", second_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        core.close()  # the node stopping, cut short between finishing the file and naming it
    core.close()  # what the sound command's own clean-up does next
    # was: nothing more done, the take left under its temporary name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.wav", "take.wav.json"]
    assert sf.info(wav).frames == json.loads((tmp_path / "take.wav.json").read_text())["frames"] > 20_000
