"""A sound node killed mid-take (SIGKILL) leaves its take in a hidden part file: its rig-time origin survives beside
it (``.NAME.XXXX.part.json``, written at the first block), ``batteur wav-repair`` makes the part file a take with
that origin in its .json, and a node started again says the part file is there and how to recover it.

Until 7 Dec 2026 the origin was written only when the take was named (a live-set walkthrough lost a 73 s take's
place on the rig clock), wav-repair left a part file "as it is", and a restarted node said nothing of it.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

import batteur.tools.wav_repair as wav_repair
from common.config import load_settings
from services.sound import node
from services.sound.node import WavSink, make_core

ROOT = Path(__file__).resolve().parents[2]
BLOCK = 256
ORIGIN_S = 70.752
"""The rig time of the killed take's first sample."""

WRITER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    import numpy as np
    from services.sound.node import WavSink

    path, blocks, step_at, forever = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4] == "1"
    anchors = [(0, {origin})]
    sink = WavSink(path, 48000, 2, lambda: list(anchors))
    n = 0
    while True:
        if n == step_at:  # the clock master restarted: rig time stepped back 60 s at this block
            anchors.append((n * {block}, anchors[0][1] + n * {block} / 48000 - 60.0))
        ramp = (np.arange(n * {block}, (n + 1) * {block}) % 1000 / 2000).astype(np.float32)
        sink(np.stack([ramp, -ramp], axis=1))
        n += 1
        if n == blocks:
            print("written", flush=True)
            if not forever:
                time.sleep(600)  # killed here, between blocks
""").format(origin=ORIGIN_S, block=BLOCK)


def _killed_take(folder: Path, blocks: int, step_at: int = -1, forever: bool = False, name: str = "take.wav") -> Path:
    """A WavSink recording ``name`` in its own process, killed (SIGKILL) once it has written ``blocks`` blocks
    (``forever``: while it goes on writing); returns its part file."""
    folder.mkdir(exist_ok=True)
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(folder / name), str(blocks), str(step_at),
                             "1" if forever else "0"], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline() == "written\n"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(60)
    (part,) = folder.glob(f".{name}.*.part")
    return part


def _wav_repair(*paths: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "batteur", "wav-repair", *map(str, paths)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def _ramp(frames: int) -> np.ndarray:
    ramp = (np.arange(frames) % 1000 / 2000).astype(np.float32)
    return np.stack([ramp, -ramp], axis=1)


def test_a_killed_takes_origin_survives_and_wav_repair_makes_it_a_take(tmp_path: Path) -> None:
    part = _killed_take(tmp_path / "takes", blocks=40)
    takes = part.parent
    # no take named, and nothing else: the part file and its timing (was: the part file alone)
    assert sorted(p.name for p in takes.iterdir()) == sorted([part.name, part.name + ".json"])
    timing = json.loads((takes / (part.name + ".json")).read_text())
    assert timing["origin_rig_time_s"] == ORIGIN_S and timing["segments"] == [{"frame": 0, "rig_time_s": ORIGIN_S}]
    assert sf.info(str(part)).frames == 40 * BLOCK  # libsndfile's header kept up to date: readable as it is

    run = _wav_repair(takes)  # the folder: every part file left there
    assert (run.returncode, run.stderr) == (0, "")
    take = takes / "take-recovered.wav"
    assert run.stdout == (f"recovered {part} -> take-recovered.wav (0.21 s; rig time origin {ORIGIN_S:.3f} s, in "
                          "take-recovered.wav.json)\n")
    assert sorted(p.name for p in takes.iterdir()) == ["take-recovered.wav", "take-recovered.wav.json"]
    audio, rate = sf.read(take, dtype="float32")
    assert rate == 48000 and audio.shape == (40 * BLOCK, 2)
    assert np.allclose(audio, _ramp(40 * BLOCK), atol=2e-7)  # 24-bit: every block written, in order
    meta = json.loads((takes / "take-recovered.wav.json").read_text())
    assert meta == {"origin_rig_time_s": ORIGIN_S, "sample_rate_hz": 48000, "channels": 2, "frames": 40 * BLOCK,
                    "segments": [{"frame": 0, "rig_time_s": ORIGIN_S}], "recovered_from": part.name}
    assert take.stat().st_mode & 0o044  # readable as any take (the part file was owner-only)


def test_a_take_killed_while_writing_is_recovered_with_what_it_holds(tmp_path: Path) -> None:
    part = _killed_take(tmp_path / "takes", blocks=20, forever=True)
    on_disk = (part.stat().st_size - 112) // 6  # 112-byte header (RF64 auto-downgraded), 6 bytes a frame
    result = wav_repair.recover_part(part)
    assert result.take.name == "take-recovered.wav" and result.origin_rig_time_s == ORIGIN_S
    assert 20 * BLOCK <= result.frames == on_disk == sf.info(str(result.take)).frames
    meta = json.loads(result.take.with_name("take-recovered.wav.json").read_text())
    assert meta["frames"] == result.frames


def test_a_header_a_block_short_is_given_every_whole_frame(tmp_path: Path) -> None:
    # killed between writing a block and updating the header after it: the block is on disk, the header without it
    part = _killed_take(tmp_path / "takes", blocks=10)
    with part.open("ab") as f:
        f.write(np.zeros(BLOCK * 6 + 4, dtype=np.uint8).tobytes())  # a block, and part of a frame
    result = wav_repair.recover_part(part)
    assert (result.header_frames, result.frames) == (10 * BLOCK, 11 * BLOCK)
    assert sf.info(str(result.take)).frames == 11 * BLOCK
    assert result.take.stat().st_size == 112 + 11 * BLOCK * 6  # the partial frame dropped


def test_a_clock_step_in_a_killed_take_is_kept(tmp_path: Path) -> None:
    part = _killed_take(tmp_path / "takes", blocks=30, step_at=12)
    step = {"frame": 12 * BLOCK, "rig_time_s": ORIGIN_S + 12 * BLOCK / 48000 - 60.0}
    timing = json.loads(part.with_name(part.name + ".json").read_text())
    assert timing["segments"] == [{"frame": 0, "rig_time_s": ORIGIN_S}, step]
    result = wav_repair.recover_part(part)
    assert json.loads(result.take.with_name("take-recovered.wav.json").read_text())["segments"] == [
        {"frame": 0, "rig_time_s": ORIGIN_S}, step]


def test_wav_repair_overwrites_nothing_and_says_an_unknown_origin(tmp_path: Path) -> None:
    part = _killed_take(tmp_path / "takes", blocks=10)
    takes = part.parent
    part.with_name(part.name + ".json").unlink()  # a part file left by a node from before its timing was kept
    (takes / "take-recovered.wav").write_bytes(b"someone's file")
    run = _wav_repair(part)
    assert (run.returncode, run.stderr) == (0, "")
    assert run.stdout == (f"recovered {part} -> take-recovered-2.wav (0.05 s; rig time origin unknown: no timing "
                          "beside it (sound nodes keep one since 7 Dec 2026))\n")
    assert (takes / "take-recovered.wav").read_bytes() == b"someone's file"
    assert sf.info(str(takes / "take-recovered-2.wav")).frames == 10 * BLOCK
    assert sorted(p.name for p in takes.iterdir()) == ["take-recovered-2.wav", "take-recovered.wav"]


def test_a_part_file_a_node_is_recording_into_is_left_alone(tmp_path: Path) -> None:
    wav = tmp_path / "take.wav"
    sink = WavSink(wav, 48000, 1, lambda: [(0, 5.0)])
    sink(np.full((BLOCK, 1), 0.25, dtype=np.float32))
    before = sink.part.read_bytes()
    for given in (sink.part, tmp_path):
        run = _wav_repair(given)
        assert run.returncode == 1 and run.stdout == ""
        assert "running sound node" in run.stderr and len(run.stderr.splitlines()) == 1, run.stderr
    assert sink.part.read_bytes() == before
    sink.close()  # the node names its take itself, as before: its .json, and no part file or timing left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["take.wav", "take.wav.json"]
    assert json.loads((tmp_path / "take.wav.json").read_text()) == {
        "origin_rig_time_s": 5.0, "sample_rate_hz": 48000, "channels": 1, "frames": BLOCK,
        "segments": [{"frame": 0, "rig_time_s": 5.0}]}


def test_a_part_file_that_is_no_take_is_refused_in_words(tmp_path: Path) -> None:
    other = tmp_path / "download.part"
    other.write_bytes(b"not ours")
    run = _wav_repair(other)
    assert run.returncode == 1 and run.stdout == ""
    assert run.stderr == (f"batteur wav-repair: error: {other}: not recovered: not a part file a sound node left "
                          "(.NAME.XXXXXXXX.part, NAME a .wav, .rf64, .w64, .aiff, .caf, .au or .flac)\n")
    assert other.read_bytes() == b"not ours"


def test_a_restarted_node_says_once_where_the_killed_take_is(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    part = _killed_take(tmp_path, blocks=10)
    live = WavSink(tmp_path / "other.wav", 48000, 1, lambda: [(0, 0.0)])  # another node still recording: not said
    settings = load_settings({"role": "sound", "discovery": False, "clock_master": "self"})
    extra = argparse.Namespace(kit="default", wav=tmp_path / "take.wav", device="none", model="modal",
                               block_size=256, channels=1, reverb=0.0)
    with caplog.at_level(logging.INFO, logger="batteur.sound"):
        core = make_core(settings, extra)  # the node's start: its own part file is not a leftover either
    try:
        said = [r.getMessage() for r in caplog.records if "wav-repair" in r.getMessage()]
        assert said == [f"a take left unnamed by an earlier sound node that did not stop cleanly (killed or failed) in "
                        f"{tmp_path}: {part.name}; `batteur wav-repair {part}` names it (NAME-recovered.wav) and "
                        "keeps its rig-time origin in its .json"]
    finally:
        core.close()
        live.close()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="batteur.sound"):
        node.say_leftover_parts(tmp_path, None)  # was: nothing said, a new take started beside it
    assert [r.levelno for r in caplog.records] == [logging.WARNING] and part.name in caplog.records[0].getMessage()


def test_an_rf64_part_file_past_4_gib_is_recovered_by_its_ds64_sizes(tmp_path: Path) -> None:
    # a take past 4 GiB is RF64 (its sizes in the ds64 chunk); a small RF64 file stands in, a block short in its header
    part = tmp_path / ".take.wav.abcd1234.part"
    sf.write(part, _ramp(5 * BLOCK), 48000, subtype="PCM_24", format="RF64")
    with part.open("ab") as f:
        f.write(np.zeros(BLOCK * 6, dtype=np.uint8).tobytes())
    result = wav_repair.recover_part(part)
    assert (result.header_frames, result.frames, result.origin_rig_time_s) == (5 * BLOCK, 6 * BLOCK, None)
    info = sf.info(str(result.take))
    assert (info.format, info.frames) == ("RF64", 6 * BLOCK)


def test_a_killed_flac_take_is_refused_with_how_to_decode_it(tmp_path: Path) -> None:
    # a FLAC part's length is written at close: libsndfile read it as 2**63 - 1 frames, and wav-repair named it a
    # take of 192153584101141 s with that in its .json, a file that did not read back
    part = _killed_take(tmp_path / "takes", blocks=40, name="take.flac")
    takes = part.parent
    before = {p.name: p.read_bytes() for p in takes.iterdir()}
    assert sorted(before) == sorted([part.name, part.name + ".json"])  # found as a part file, with its timing
    run = _wav_repair(takes)
    assert (run.returncode, run.stdout) == (1, "")
    assert run.stderr == (
        f"batteur wav-repair: error: {part}: not recovered: a FLAC part's length (and its last frames, still in the "
        "encoder) are written only when the node closes it, and compressed audio cannot be given a header: left as "
        f"it is; `ffmpeg -i {part} {takes / 'take-recovered.wav'}` decodes the frames on disk ({part.name}.json "
        "beside it holds their rig-time origin)\n")
    assert {p.name: p.read_bytes() for p in takes.iterdir()} == before  # nothing written, nothing renamed


@pytest.mark.parametrize("name", ["take.aiff", "take.caf", "take.au", "take.w64"])
def test_a_killed_take_in_another_format_is_found_and_recovered(tmp_path: Path, name: str) -> None:
    part = _killed_take(tmp_path / "takes", blocks=30, name=name)  # was: .aiff/.caf/.au parts not taken for parts
    run = _wav_repair(part.parent)
    assert (run.returncode, run.stderr) == (0, "")
    take = part.parent / f"take-recovered{Path(name).suffix}"
    assert sorted(p.name for p in part.parent.iterdir()) == [take.name, take.name + ".json"]
    audio, rate = sf.read(take, dtype="float32")
    assert rate == 48000 and np.allclose(audio, _ramp(30 * BLOCK), atol=2e-7)
    assert json.loads(take.with_name(take.name + ".json").read_text())["origin_rig_time_s"] == ORIGIN_S


@pytest.mark.parametrize("name", ["take.raw", "take.nist", "take.sd2"])
def test_the_node_refuses_a_format_a_killed_take_could_not_be_recovered_in(tmp_path: Path, name: str) -> None:
    with pytest.raises(ValueError, match=r"give a file ending in \.wav, \.rf64, \.w64, \.aiff, \.caf, \.au, \.flac"):
        WavSink(tmp_path / name, 48000, 2, lambda: [(0, 0.0)])  # was: a headerless RAW part wav-repair cannot read
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("origin", ["NaN", "Infinity", "-Infinity"])
def test_a_non_finite_origin_is_refused_and_deleting_the_timing_recovers_the_audio(tmp_path: Path,
                                                                                   origin: str) -> None:
    part = _killed_take(tmp_path / "takes", blocks=10)
    timing = part.with_name(part.name + ".json")
    timing.write_text(timing.read_text().replace(f'"origin_rig_time_s": {ORIGIN_S}', f'"origin_rig_time_s": {origin}'))
    before = part.read_bytes()
    with pytest.raises(ValueError, match=f"delete {part.name}.json and run it again to recover the audio without "
                       "its rig-time origin") as refused:
        wav_repair.recover_part(part)  # was: a take whose .json said "origin_rig_time_s": NaN
    assert "finite" in str(refused.value)
    assert part.read_bytes() == before and sorted(p.name for p in part.parent.iterdir()) == [part.name, timing.name]
    timing.unlink()  # as the refusal says
    result = wav_repair.recover_part(part)
    assert (result.frames, result.origin_rig_time_s) == (10 * BLOCK, None)
