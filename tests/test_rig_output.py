"""What ``batteur rig`` tells its user: each service's stderr on the rig's stderr (``2>err.log`` catches the
services' warnings), whole lines only; with ``--record``, the file the take ends up in.

A new-user walkthrough found every service line on the rig's stdout, and the sound node saying it recorded to
``out/..performance.part.wav.XXXX.part, renamed out/.performance.part.wav`` when the rig then named it
``out/performance.wav``.
"""

from __future__ import annotations

import asyncio
import io
import logging
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf

from batteur import rig
from tests.ports import free_port

ROOT = Path(__file__).resolve().parents[1]


class Plan(rig.ServicePlan):
    """A stand-in service: ``python -c CODE``."""

    def __init__(self, role: str, code: str) -> None:
        super().__init__(role, 0, [])
        self.code = code

    def argv(self) -> list[str]:
        return [sys.executable, "-c", self.code]


CHATTY = ("import sys\n"
          "print('played a note', flush=True)\n"
          "print('WARNING batteur.sound: late strike', file=sys.stderr, flush=True)\n"
          "sys.stderr.write('cut short')\n")
"""A service that logs a warning to stderr, prints to stdout, and ends with a line cut short (no newline)."""


def test_a_services_stderr_goes_to_the_rigs_stderr_in_whole_lines() -> None:
    out, err = io.StringIO(), io.StringIO()
    the_rig = rig.Rig([Plan("sound", CHATTY)], stop_timeout_s=20, out=out, err=err)
    asyncio.run(the_rig.run(60))  # stops once its service has exited
    # was: every line on stdout, and `batteur rig 2>err.log` caught none of the services' warnings
    assert "[sound] WARNING batteur.sound: late strike\n" in err.getvalue()
    assert "WARNING" not in out.getvalue()
    assert "[sound] played a note\n" in out.getvalue()
    # a last line without its newline is ended, so the next line is not glued to it
    assert "[sound] cut short\n" in err.getvalue()
    assert all(line.startswith(("[", "batteur rig: ")) for line in err.getvalue().splitlines()), err.getvalue()


def test_the_sound_service_is_told_the_recordings_final_name(tmp_path: Path) -> None:
    # the node says "recording to DIR/performance.wav": the name the take ends up with
    opts = rig.build_parser().parse_args(["--record", str(tmp_path)])
    sound_args = rig.role_args("sound", opts)
    assert Path(sound_args[sound_args.index("--wav") + 1]) == tmp_path / rig.RECORDING


def _outputs() -> tuple[rig.Output, rig.Output, io.StringIO, io.StringIO]:
    out, err = io.StringIO(), io.StringIO()
    return rig.Output(out), rig.Output(err), out, err


def _part_with_audio(folder: Path, name: str, frames: int = 256) -> Path:
    """A part file as sound leaves it: a playable WAV holding ``frames`` frames."""
    part = folder / f".{rig.RECORDING}.{name}.part"
    sf.write(part, np.full(frames, 0.25), 48000, subtype="PCM_24", format="WAV")
    return part


def test_a_take_cut_short_never_replaces_an_earlier_recording(tmp_path: Path) -> None:
    out, err, out_text, err_text = _outputs()
    earlier = tmp_path / rig.RECORDING
    earlier.write_bytes(b"an earlier take")
    older = _part_with_audio(tmp_path, "old1")  # an earlier failed run's, already told about then
    before, parts = rig.recording_state(tmp_path), rig.recording_parts(tmp_path)
    # sound killed while it recorded: the earlier take stays, and so does what it was writing into (its part
    # file, a playable WAV up to the last block), named (was: removed, where the node had just named it)
    part = _part_with_audio(tmp_path, "x1y2")
    rig.finish_recording(tmp_path, False, out, err, before, parts)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([rig.RECORDING, older.name, part.name])
    assert earlier.read_bytes() == b"an earlier take"
    assert err_text.getvalue() == (
        f"batteur rig: sound did not stop cleanly: {earlier} not written (the earlier one stays); what it "
        f"recorded, maybe cut short, is in {part} (a WAV file); `batteur wav-repair {part}` names it (-recovered.wav) "
        "with its timing\n")
    assert out_text.getvalue() == ""


def test_a_part_file_without_audio_goes(tmp_path: Path) -> None:
    # sound killed before its first block: nothing to keep, nothing to point at
    out, err, out_text, err_text = _outputs()
    before, parts = rig.recording_state(tmp_path), rig.recording_parts(tmp_path)
    (tmp_path / f".{rig.RECORDING}.e1e2.part").write_bytes(b"")  # as mkstemp makes it
    _part_with_audio(tmp_path, "h1h2", frames=0)  # a header, no frames
    rig.finish_recording(tmp_path, False, out, err, before, parts)
    assert list(tmp_path.iterdir()) == []
    assert err_text.getvalue() == (f"batteur rig: sound did not stop cleanly and recorded nothing "
                                   f"({tmp_path / rig.RECORDING} not written)\n")


def test_the_part_file_a_failed_sound_node_names_is_still_there(tmp_path: Path,
                                                                caplog: pytest.LogCaptureFixture) -> None:
    # the node says "what was recorded is in PART" as it closes; the rig, seeing sound did not stop cleanly, then
    # removed every part file: the user was pointed at a file that was gone
    from services.sound.node import WavSink

    out, err, out_text, err_text = _outputs()
    before = rig.recording_state(tmp_path)
    sink = WavSink(tmp_path / rig.RECORDING, 48000, 1, lambda: [(0, 0.0)], keep=lambda: False)  # a node that failed
    sink(np.full((256, 1), 0.25, dtype=np.float32))
    with caplog.at_level(logging.WARNING, logger="batteur.sound"):
        sink.close()
    (said,) = [m for r in caplog.records if r.name == "batteur.sound" and "recorded is in" in (m := r.getMessage())]
    named = Path(said.rsplit("what was recorded is in ", 1)[1])
    rig.finish_recording(tmp_path, False, out, err, before)
    assert named.exists() and sf.info(named).frames == 256
    assert f"is in {named} (a WAV file)" in err_text.getvalue()


def test_the_rig_says_whether_sound_recorded(tmp_path: Path) -> None:
    out, err, out_text, err_text = _outputs()
    (tmp_path / rig.RECORDING).write_bytes(b"an earlier take")
    before = rig.recording_state(tmp_path)
    rig.finish_recording(tmp_path, True, out, err, before)  # sound stopped before it recorded anything
    assert "nothing recorded" in err_text.getvalue() and "recorded" not in out_text.getvalue()
    new = tmp_path / ".new"
    new.write_bytes(b"this take")
    new.replace(tmp_path / rig.RECORDING)  # what sound does as it stops cleanly
    rig.finish_recording(tmp_path, True, out, err, before)
    assert out_text.getvalue() == f"batteur rig: recorded {tmp_path / rig.RECORDING}\n"


def test_the_rig_says_a_take_without_audio_is_empty(tmp_path: Path) -> None:
    """A rig stopped while its nodes started: sound named a 0-frame take (112 bytes, a header) and the rig said
    "recorded" as for a performance."""
    out, err, out_text, err_text = _outputs()
    before = rig.recording_state(tmp_path)
    take = tmp_path / rig.RECORDING
    sf.write(tmp_path / ".new", np.zeros((0, 2)), 48000, subtype="PCM_24", format="WAV")  # as sound closes it
    (tmp_path / ".new").replace(take)
    assert take.stat().st_size > 0 and sf.info(take).frames == 0
    rig.finish_recording(tmp_path, True, out, err, before)
    assert out_text.getvalue() == ""
    assert err_text.getvalue() == (f"batteur rig: the take is empty: {take} holds no audio (0 frames: sound played "
                                   "nothing, stopped before its audio started)\n")
    sf.write(tmp_path / ".new", np.full((256, 2), 0.25), 48000, subtype="PCM_24", format="WAV")  # the next take
    (tmp_path / ".new").replace(take)
    rig.finish_recording(tmp_path, True, out, err)  # before None: any take there is new
    assert out_text.getvalue() == f"batteur rig: recorded {take}\n"


def test_an_empty_take_leaves_an_earlier_one_alone(tmp_path: Path) -> None:
    """Sound stopped cleanly before its first block: the earlier take keeps its name and its audio, no part file or
    .json is left, and the rig says nothing was recorded and the earlier take stays (was: the 0-frame take renamed
    over it, and the rig said only "the take is empty")."""
    from services.sound.node import WavSink

    out, err, out_text, err_text = _outputs()
    take = tmp_path / rig.RECORDING
    earlier = np.full((4800, 2), 0.1)
    sf.write(take, earlier, 48000, subtype="PCM_24")
    (tmp_path / (rig.RECORDING + ".json")).write_text('{"frames": 4800}')
    before = rig.recording_state(tmp_path)
    WavSink(take, 48000, 2, lambda: [(0, 0.0)]).close()
    assert sorted(p.name for p in tmp_path.iterdir()) == [rig.RECORDING, rig.RECORDING + ".json"]
    assert np.allclose(sf.read(take)[0], earlier, atol=1e-6)
    assert (tmp_path / (rig.RECORDING + ".json")).read_text() == '{"frames": 4800}'
    rig.finish_recording(tmp_path, True, out, err, before)
    assert out_text.getvalue() == ""
    assert err_text.getvalue() == ("batteur rig: nothing recorded (sound played nothing: stopped before its audio "
                                   f"started; the earlier take in {tmp_path} stays)\n")
    take.unlink()  # no earlier take: none is made either
    WavSink(take, 48000, 2, lambda: [(0, 0.0)]).close()
    assert not take.exists()
    out, err, out_text, err_text = _outputs()
    rig.finish_recording(tmp_path, True, out, err, None)
    assert err_text.getvalue() == ("batteur rig: nothing recorded (sound played nothing: stopped before its audio "
                                   f"started; {take} not written)\n")


def test_a_sound_node_that_fails_leaves_an_earlier_take_alone(tmp_path: Path) -> None:
    # the rig now gives sound the final name: a node that fails (here: its port is taken) must not name its take
    # (was: the empty take renamed over the earlier one as the node closed)
    wav = tmp_path / rig.RECORDING
    earlier = np.linspace(-0.5, 0.5, 1000)
    sf.write(wav, earlier, 48000, subtype="PCM_24")
    port = free_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", port))
        done = subprocess.run([sys.executable, "-m", "services.sound.node", "--no-discovery", "--no-oscquery",
                               "--clock-master", "self", "--device", "none", "--host", "127.0.0.1", "--port",
                               str(port), "--channels", "1", "--wav", str(wav)],
                              cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert f"recording to {wav} (" in done.stderr  # the final name, as the user will find it
    assert sorted(p.name for p in tmp_path.iterdir()) == [rig.RECORDING]  # no part file, no .json
    assert np.allclose(sf.read(wav)[0], earlier, atol=1e-6)
