"""The demo command renders a Groove MIDI file on the full kit into a WAV file."""

from __future__ import annotations

import io
import resource
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import mido
import numpy as np
import pytest
import soundfile as sf

from common.kit import load_kit
from common.messages import Impact
from services.sound.demo import DEFAULT_MIDI, PROG, impacts_from_midi, main
from tests.score.midi_files import KEY_C, riff_chunk, riff_midi, with_key

ROOT = Path(__file__).resolve().parents[2]


def test_groove_midi_becomes_impacts_on_kit_objects() -> None:
    kit = load_kit("default")
    impacts = impacts_from_midi(DEFAULT_MIDI, kit, max_seconds=4.0)
    ids = {o.id for o in kit.objects}
    assert len(impacts) > 20
    assert all(i.instrument in ids for i in impacts)
    assert {"kick", "snare", "hihat"} <= {i.instrument for i in impacts}
    assert [i.time for i in impacts] == sorted(i.time for i in impacts)


def test_demo_writes_a_listenable_stereo_wav(tmp_path: Path) -> None:
    out = tmp_path / "groove.wav"
    assert main(["-o", str(out), "--seconds", "2", "--reverb", "0.1"]) == 0
    audio, rate = sf.read(out)
    assert rate == 48000 and audio.ndim == 2 and audio.shape[1] == 2
    assert 0.05 < np.max(np.abs(audio)) <= 1.0
    assert np.all(np.isfinite(audio))


def test_broken_inputs_and_outputs_are_named_and_nothing_is_written(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    truncated = tmp_path / "cut.mid"
    truncated.write_bytes(DEFAULT_MIDI.read_bytes()[:60])
    not_midi = tmp_path / "notes.txt"
    not_midi.write_text("kick snare")  # read as a text score, which it is not
    noise = tmp_path / "noise.mid"
    noise.write_bytes(bytes(range(256)))
    out = tmp_path / "groove.wav"
    for args, says in ((["--midi", str(truncated)], "cut.mid: truncated MIDI file"),
                       (["--midi", str(not_midi)], "notes.txt: line 1: unknown directive 'kick'"),
                       (["--score", str(noise)], "noise.mid: not a valid Standard MIDI File"),
                       (["-o", str(not_midi / "g.wav")], "notes.txt is a file, not a folder"),
                       (["-o", str(tmp_path / "no" / "g.wav")], "does not exist"),
                       (["-o", str(tmp_path)], "is a directory, not a file")):
        assert main(["-o", str(out), *args]) == 1  # a file it cannot use
        assert says in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("args, says", [
    (["--reverb", "2"], "argument --reverb: '2': give a number from 0 to 1"),  # was a pydantic traceback
    (["--reverb", "nan"], "argument --reverb: 'nan': give a number from 0 to 1"),
    (["--seconds", "nan"], "argument --seconds: 'nan': give a positive number"),  # was: the whole file, silently
    (["--seconds", "-1"], "argument --seconds: '-1': give a positive number"),
])
def test_out_of_range_numbers_are_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                                               says: str) -> None:
    out = tmp_path / "groove.wav"
    with pytest.raises(SystemExit) as stop:
        main(["-o", str(out), *args])
    assert stop.value.code == 2 and says in capsys.readouterr().err
    assert not out.exists()


def test_an_output_name_that_is_not_a_sound_file_is_refused_before_rendering(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    rendered: list[object] = []
    monkeypatch.setattr("services.sound.demo.render_offline", lambda *a, **k: rendered.append(a))
    for name in ("groove.mp3", "groove"):
        # was: the whole groove rendered, then a soundfile traceback
        assert main(["-o", str(tmp_path / name)]) == 2
        assert f"-o {tmp_path / name}: give a file ending in .wav" in capsys.readouterr().err
    assert rendered == [] and list(tmp_path.iterdir()) == []


def _no_bigger_than(size: int) -> Callable[[], None]:
    def limit() -> None:  # in the child: writes past `size` bytes fail with EFBIG, as on a full disk
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit


def test_a_failed_write_keeps_the_earlier_file(tmp_path: Path) -> None:
    out = tmp_path / "groove.wav"
    sf.write(out, np.zeros(4800), 48000)
    earlier = out.read_bytes()
    run = subprocess.run([sys.executable, "-m", "services.sound.demo", "-o", str(out), "--seconds", "1", "--mono"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300, preexec_fn=_no_bigger_than(65536))
    # was: a traceback, and groove.wav cut to 64 kB of a new render (its header saying more)
    assert run.returncode == 1 and f"error: -o {out}: cannot write it (File too large)" in run.stderr
    assert out.read_bytes() == earlier and sorted(p.name for p in tmp_path.iterdir()) == ["groove.wav"]


def test_ctrl_c_while_rendering_writes_nothing_and_says_so(tmp_path: Path) -> None:
    out = tmp_path / "groove.wav"
    # SIGINT at its default: a suite run in the background ignores it, and so would the child
    proc = subprocess.Popen([sys.executable, "-m", "services.sound.demo", "-o", str(out), "--seconds", "inf"],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.stderr is not None
    line = proc.stderr.readline()
    while line.startswith(f"{PROG}: warning: "):  # the score reader's notices come first
        line = proc.stderr.readline()
    assert line.startswith("rendering ")  # the render has started
    while True:  # as a user would: again if nothing happens (numba swallows one that lands while it compiles)
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(2.0)
            break
        except subprocess.TimeoutExpired:
            continue
    err = proc.stderr.read()
    # was: a KeyboardInterrupt traceback
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == f"{PROG}: interrupted: {out} not written"
    assert list(tmp_path.iterdir()) == []


def _beat() -> bytes:
    """Half a second of drums at 120 bpm on channel 10: kick, closed hi-hat edge (the TD-11's 22), snare, an eighth
    note (0.25 s) apart, after a key signature of C."""
    track = mido.MidiTrack([mido.MetaMessage("key_signature", key="C")])
    for delta, note in ((0, 36), (240, 22), (240, 38)):
        track.append(mido.Message("note_on", channel=9, note=note, velocity=100, time=delta))
    out = io.BytesIO()
    mido.MidiFile(tracks=[track], ticks_per_beat=480).save(file=out)
    return out.getvalue()


def _played(impacts: list[Impact]) -> list[tuple[float, str, str]]:
    return [(round(i.time, 6), i.instrument, i.zone) for i in impacts]


EXPECTED_BEAT = [(0.5, "kick", "centre"), (0.75, "hihat", "closed"), (1.0, "snare", "centre")]
"""What :func:`_beat` plays on the default kit (the demo starts a score 0.5 s in)."""


def test_a_riff_midi_file_plays_as_the_midi_file_it_wraps(tmp_path: Path) -> None:
    kit = load_kit("default")
    smf, rmi = tmp_path / "beat.mid", tmp_path / "beat.rmi"
    smf.write_bytes(_beat())
    rmi.write_bytes(riff_midi(_beat(), riff_chunk(b"LIST", b"INFOINAM\x05\x00\x00\x00Beat\x00")))
    # was "not a readable MIDI file (MThd not found...)": mido reads no RIFF wrapper
    assert _played(impacts_from_midi(rmi, kit)) == _played(impacts_from_midi(smf, kit)) == EXPECTED_BEAT


def test_a_midi_file_with_a_key_signature_mido_refuses_plays_with_a_warning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert _beat().count(KEY_C) == 1
    bad = tmp_path / "bad_key.mid"
    bad.write_bytes(with_key(_beat(), b"\xff\x59\x02\xee\x01"))  # 18 flats
    out = tmp_path / "beat.wav"
    # was exit 2, "not a readable MIDI file (Could not decode key with 18 flats and mode 1)"
    assert main(["-o", str(out), "--midi", str(bad), "--mono", "--reverb", "0"]) == 0
    err = capsys.readouterr().err
    assert f"{PROG}: warning: {bad}: a key signature that cannot be read ignored" in err  # was "warning: ..."
    assert _played(impacts_from_midi(bad, load_kit("default"))) == EXPECTED_BEAT
    audio, rate = sf.read(out)
    assert rate == 48000 and audio.ndim == 1 and np.max(np.abs(audio)) > 0.05


def test_a_text_score_plays_on_the_instruments_it_names(tmp_path: Path) -> None:
    score = tmp_path / "beat.txt"
    score.write_text("tempo 120\nBD |x...|\nSN |..x.|\nRD |.x.x|\n")
    played = _played(impacts_from_midi(score, load_kit("default")))
    assert played == [(0.5, "kick", "centre"), (1.0, "ride", "bow"), (1.5, "snare", "centre"), (2.0, "ride", "bow")]
