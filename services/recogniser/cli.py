"""``batteur transcribe``: audio file -> Standard MIDI File of drum notes (and live OSC hits)."""

from __future__ import annotations

import argparse
import asyncio
import collections
import contextlib
import logging
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from common.arg_types import positive, seconds, take_negative_values
from common.exit_status import USAGE
from common.output_paths import check_output_file
from common.transport import parse_address
from services.recogniser.audio import MAX_DURATION_S, SILENCE_PEAK
from services.recogniser.classes import CLASSES
from services.recogniser.errors import AudioFileError, RecogniserError
from services.recogniser.midi import TEMPO_RANGE_BPM
from services.recogniser.model import MODEL_PATH, load_model
from services.recogniser.tempo import RANGE_BPM, estimate_tempo
from services.recogniser.transcribe import DrumEvent, transcribe_file

DESCRIPTION = """\
Transcribe a drum recording into a General MIDI drum file (channel 10).

Reads WAV, FLAC, OGG, AIFF, MP3 (any channels, mixed to mono; any sample rate,
but below 32 kHz the hi-hats are heard worse, with --live below 22,050 Hz: a
warning says so), finds every strike of kick, snare, closed or open hi-hat,
high/mid/floor tom, crash or ride with a small convolutional network scoring
each 10 ms frame, gives each a velocity, and writes a Standard MIDI File that
`batteur render` can play.

With --live the file is played in real time through the live recogniser
(multi-band SuperFlux onsets, each classified from a short context) and each
hit is sent as OSC /batteur/recogniser/hit to --to HOST:PORT (about 35 ms
after its onset); --device listens to an audio input instead of a file.
Something must listen at HOST:PORT: no Batteur service acts on the hits, and
`batteur echo` subscribes at a node. To watch them, start any node and send
the hits to it (a warning says when a destination refuses them):
  batteur interaction --port 9900 --no-discovery --interaction-config none
  batteur echo --node 127.0.0.1:9900 /batteur/recogniser/hit
  batteur transcribe groove.wav --live --to 127.0.0.1:9900
"""

EPILOG = """\
notes written: kick 36, snare 38, closed hi-hat 42, open hi-hat 46, high tom 48,
mid tom 45, floor tom 43, crash 49, ride 51.

examples:
  batteur transcribe groove.wav -o groove.mid
  batteur transcribe take.flac -o take.mid --tempo 96
  batteur transcribe take.wav -o take.mid --overwrite      # replace an earlier take.mid
  batteur transcribe groove.wav --live --to 127.0.0.1:9900 -o heard.mid
"""

DEFAULT_TEMPO_BPM = 120.0
"""The tempo written when none is given and the strikes give none, BPM (MIDI's own default)."""
LONG_FILE_S = 60.0
"""Files longer than this show a progress line, seconds."""
WARNING = "batteur transcribe: warning:"
"""How a warning begins, as the other commands' do (its errors: ``batteur transcribe: error:``)."""


def build_parser(prog: str = "batteur transcribe") -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, description=DESCRIPTION, epilog=EPILOG,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    take_negative_values(p)  # --tempo -1e2: the value's own check says what is wrong with it
    p.add_argument("audio", nargs="?", help="audio file to transcribe (WAV, FLAC, OGG, ...)")
    p.add_argument("-o", "--output", type=Path,
                   help="Standard MIDI File to write, named .mid or .midi (required unless --live)")
    p.add_argument("--tempo", type=float, default=None, help="tempo written to the MIDI file, BPM (default: "
                   f"estimated from the strikes, {RANGE_BPM[0]:g}-{RANGE_BPM[1]:g}; {DEFAULT_TEMPO_BPM:g} when too "
                   "few or too irregular to tell; note times are exact whatever the tempo)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing -o file (without it transcribe "
                   "refuses before reading the audio, naming it)")
    p.add_argument("--max-duration", type=float, default=MAX_DURATION_S,
                   help=f"refuse longer files, seconds (default {MAX_DURATION_S:.0f})")
    p.add_argument("--model", type=Path, default=MODEL_PATH, help="model file (default: the shipped one)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    live = p.add_argument_group("live mode")
    live.add_argument("--live", action="store_true", help="play the file in real time and send hits over OSC to "
                      "--to (a program must listen there: see above)")
    live.add_argument("--device", nargs="?", const="", default=None, metavar="NAME",
                      help="with --live: listen to an audio input device instead of a file (needs sounddevice)")
    live.add_argument("--seconds", type=seconds, default=None, help="with --device: stop after this long, seconds")
    live.add_argument("--to", action="append", default=[], metavar="HOST:PORT",
                      help="send /batteur/recogniser/hit here (repeatable; default 127.0.0.1:9900): a UDP port "
                      "something listens on, e.g. a node's --port, where `batteur echo --node HOST:PORT "
                      "/batteur/recogniser/hit` prints them")
    live.add_argument("--speed", type=positive, default=None, help="with --live and a file: play this much faster "
                      "(default 1)")
    return p


def _summary(events: Sequence[DrumEvent]) -> str:
    counts = collections.Counter(e.cls for e in events)
    return ", ".join(f"{CLASSES[c].name} {counts[c]}" for c in range(len(CLASSES)) if counts[c]) or "none"


def _count(n: int, noun: str) -> str:
    """``1 note``, ``2 notes``, ``0 notes``."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _duration(seconds: float) -> str:
    """An audio length as the summary gives it: ``10.7 s``; below a second in milliseconds (``12.3 ms``)."""
    if seconds >= 1.0:
        return f"{seconds:.1f} s"
    ms = seconds * 1000
    return f"{ms:.0f} ms" if ms >= 100 else f"{ms:.3g} ms"  # .3g would write 999.6 as 1e+03


def _speed(audio_s: float, elapsed_s: float) -> str:
    """`` (21x real time)``; nothing for audio under a second, whose time is mostly the fixed start-up cost."""
    if audio_s < 1.0:
        return ""
    factor = audio_s / max(elapsed_s, 1e-9)
    return f" ({factor:.0f}x real time)" if factor >= 1.0 else f" ({factor:.2g}x real time)"


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``transcribe``; returns the exit status (0 ok, 1 error, 2 usage)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    # where the file went on stdout, as `batteur render`'s "wrote ..." lines; warnings and progress on stderr
    tell = (lambda *a: None) if args.quiet else (lambda *a: print(*a))

    def warn(text: str) -> None:
        say(f"{WARNING} {text}")

    if args.device is None and not args.audio:
        parser.error("give an AUDIO file (or --live --device)")
    if not args.live and args.output is None:
        parser.error("-o/--output SCORE.mid is required (unless --live)")
    for given, option in ((args.device is not None, "--device"), (args.to, "--to"), (args.speed, "--speed"),
                          (args.seconds, "--seconds")):
        if given and not args.live:  # else ignored: a forgotten --live would send nothing, silently
            parser.error(f"{option} needs --live")
    if args.seconds is not None and args.device is None:
        parser.error("--seconds needs --device (a file stops at its end)")
    for target in args.to:  # before the model loads: a usage error (exit 2), not a failure of the run
        try:
            parse_address(target)
        except ValueError as exc:
            parser.error(f"--to {exc}")
    if args.speed is not None and args.device is not None:
        parser.error("--speed plays a file faster; a device plays in real time")
    if not args.max_duration > 0:  # written so NaN fails too (inf: no limit)
        parser.error("--max-duration must be positive")
    if args.tempo is not None and not TEMPO_RANGE_BPM[0] <= args.tempo <= TEMPO_RANGE_BPM[1]:
        parser.error(f"--tempo must be {TEMPO_RANGE_BPM[0]:g}..{TEMPO_RANGE_BPM[1]:g} BPM, got {args.tempo:g}")
    try:
        if args.output is not None:  # before the long part: nothing is lost to a typo
            if args.audio and args.output.resolve() == Path(args.audio).resolve():  # a slip that loses the take
                return _refuse_output(args.output, f"is the audio file to transcribe ({args.audio}); give the MIDI "
                                      f"file another name, ending in {' or '.join(MIDI_SUFFIXES)}")
            try:
                check_output_file(args.output, "-o")
            except ValueError as exc:
                raise RecogniserError(str(exc)) from None
            if _holds_other_data(args.output):  # an earlier take or the model: a typo must not replace it
                raise RecogniserError(f"-o {args.output}: exists and is not a MIDI file (it would be replaced by "
                                      "one); give another name, or remove it first")
            if not _midi_name(args.output):
                return _refuse_output(args.output, "the transcription is a Standard MIDI File; give a name ending "
                                      f"in {' or '.join(MIDI_SUFFIXES)}")
            if not args.overwrite and _existing_file(args.output):  # a user's exercise: as `batteur render` does
                raise RecogniserError(f"-o {args.output}: exists, and the transcription would replace it: move it, "
                                      "give another name, or give --overwrite")
        model = load_model(args.model)
        if args.live:
            return _live(args, model, say)
        shown = [-1]

        def progress(fraction: float) -> None:
            pct = int(fraction * 100)
            if pct // 5 != shown[0] // 5:
                shown[0] = pct
                print(f"\rtranscribing {args.audio}: {pct:3d}%", end="", file=sys.stderr, flush=True)

        import soundfile as sf

        try:  # not a FIFO: opening one waits for a writer (load_audio refuses it)
            seconds_long = sf.info(args.audio).duration if Path(args.audio).is_file() else 0.0
        except Exception:
            seconds_long = 0.0  # load_audio reports the problem
        long_s = seconds_long if seconds_long > LONG_FILE_S else None
        long = long_s is not None and not args.quiet
        if long_s is not None and long_s <= args.max_duration:  # longer: load_audio refuses it unread
            _refuse_silence(args.audio, None if args.quiet else args.audio)
        t0 = time.perf_counter()
        events, duration = transcribe_file(args.audio, model, progress if long else None, args.max_duration, warn)
        elapsed = time.perf_counter() - t0
        if long:
            print(file=sys.stderr)
        tempo = _write(events, args)
        tell(f"{_count(len(events), 'note')} ({_summary(events)}) from {_duration(duration)} of audio "
             f"in {elapsed:.2f} s{_speed(duration, elapsed)}{tempo} -> {args.output}")
        if not events:
            say(f"{WARNING} no drum strike recognised; the MIDI file is empty")
        return 0
    except RecogniserError as exc:
        print(f"batteur transcribe: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # the summary's reader went (`| head -0`): batteur/cli.py's quiet stop, not an error
        raise
    except OSError as exc:
        print(f"batteur transcribe: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # the live path handles its own: it writes what was heard
        print("\nbatteur transcribe: interrupted; nothing written", file=sys.stderr)
        return 130


SCAN_BLOCK = 1 << 20
"""Frames :func:`_refuse_silence` reads at a time (about 24 s at 44.1 kHz)."""


def _refuse_silence(path: str, shown: str | None) -> None:
    """Raise :class:`AudioFileError` for a long file that is silent, as :func:`~services.recogniser.audio.load_audio`
    would, having read it a block at a time and shown how far on stderr (``transcribing FILE: checking for sound
    NN%``, unless ``shown`` is None): a 30-minute silent file took up to a minute of a shared core, nearly all of it
    in load_audio's one read, with nothing printed before "the audio is silent". A file with sound stops the scan at
    its first block louder than silence could be (its whole peak-to-peak over 2 x :data:`SILENCE_PEAK`: then no
    offset makes it silent); a file soundfile cannot read through is left to load_audio. The test is load_audio's:
    the peak of the mono mix less its mean."""
    import soundfile as sf

    lo, hi, total, n = np.inf, -np.inf, 0.0, 0
    ch_lo = ch_hi = ch_sum = None
    printed, step = False, -1
    try:
        with sf.SoundFile(path) as f:
            frames = max(f.frames, 1)
            while len(block := f.read(SCAN_BLOCK, dtype="float32", always_2d=True)):
                mono = block.mean(axis=1)
                lo, hi = min(lo, float(mono.min())), max(hi, float(mono.max()))
                if not (np.isfinite(lo) and np.isfinite(hi)) or hi - lo >= 2 * SILENCE_PEAK:
                    return  # sound (or NaN: load_audio says so)
                total += float(mono.sum(dtype=np.float64))
                n += len(mono)
                b_lo, b_hi, b_sum = block.min(axis=0), block.max(axis=0), block.sum(axis=0, dtype=np.float64)
                ch_lo = b_lo if ch_lo is None else np.minimum(ch_lo, b_lo)
                ch_hi = b_hi if ch_hi is None else np.maximum(ch_hi, b_hi)
                ch_sum = b_sum if ch_sum is None else ch_sum + b_sum
                if shown is not None and (pct := int(100 * n / frames)) // 5 != step:
                    printed, step = True, pct // 5  # every 5 %, as the transcription's own progress
                    print(f"\rtranscribing {shown}: checking for sound {pct:3d}%", end="", file=sys.stderr,
                          flush=True)
    except Exception:
        return  # unreadable through: load_audio reads what decodes, and says why
    finally:
        if printed:
            print(file=sys.stderr)
    if n == 0 or ch_lo is None or ch_hi is None or ch_sum is None:
        return
    mean = total / n
    if max(hi - mean, mean - lo) >= SILENCE_PEAK:
        return
    dc = f" but for a constant offset of {mean:.3g}" if abs(mean) >= SILENCE_PEAK else ""
    ch_mean = ch_sum / n
    if len(ch_mean) > 1 and float(np.max(np.maximum(ch_hi - ch_mean, ch_mean - ch_lo))) >= SILENCE_PEAK:
        dc = " once its channels are mixed: they cancel (one channel's polarity inverted?)"
    raise AudioFileError(f"{path}: the audio is silent{dc} (peak below -70 dBFS); nothing to transcribe")


def _refuse_output(output: Path, why: str) -> int:
    """Refuse ``-o OUTPUT`` for ``why`` in argparse's error line: an option's value that cannot be run as given
    (exit status 2, README "Exit status"), told apart from an output it cannot write (1)."""
    print(f"batteur transcribe: error: -o {output}: {why}", file=sys.stderr)
    return USAGE


def _write(events: Sequence[DrumEvent], args: argparse.Namespace) -> str:
    """Write the MIDI file, a failure (a full disk) reported naming it: no partial file is left. Returns what the
    summary says of its tempo: nothing when ``--tempo`` gave it, else the estimate (:func:`_tempo`)."""
    from services.recogniser.midi import write_midi

    tempo_bpm, said = (args.tempo, "") if args.tempo is not None else _tempo(events)
    try:
        write_midi(events, args.output, tempo_bpm=tempo_bpm)
    except OSError as exc:
        raise RecogniserError(f"-o {args.output}: cannot write the MIDI file: {exc.strerror or exc}") from exc
    return said


def _tempo(events: Sequence[DrumEvent]) -> tuple[float, str]:
    """The tempo written without ``--tempo``, BPM, estimated from the strikes (:func:`estimate_tempo`; else
    :data:`DEFAULT_TEMPO_BPM`), and the summary's words for it: the bars then line up in a DAW, in ``batteur
    render``'s count and as a ``batteur compare`` exercise (a 100 BPM take written at 120 read as 7 bars and 24.2
    beats). Only the tempo meta changes: note times are exact at any tempo."""
    bpm = estimate_tempo([e.time for e in events], [e.velocity for e in events])
    if bpm is None:
        return DEFAULT_TEMPO_BPM, (f", tempo {DEFAULT_TEMPO_BPM:g} bpm (too few or too irregular strikes to "
                                   "estimate one: --tempo BPM sets it)")
    return bpm, f", tempo about {bpm:g} bpm (estimated: --tempo BPM sets it)"


def _existing_file(path: Path) -> bool:
    """Whether ``path`` is a file the transcription would replace (a regular file, or a symlink to none yet);
    /dev/null and other non-files are written in place, never replaced."""
    return path.is_file() or (path.is_symlink() and not path.exists())


MIDI_SUFFIXES = (".mid", ".midi")
"""Names the transcription may be written under: a MIDI file named ``tt.wav`` would be taken for audio."""


def _midi_name(path: Path) -> bool:
    """Whether ``path`` may take the MIDI file: named .mid/.midi, or not a regular file (``/dev/null``)."""
    return path.suffix.lower() in MIDI_SUFFIXES or (path.exists() and not path.is_file())


def _holds_other_data(path: Path) -> bool:
    """Whether ``path`` is a non-empty regular file that is not a Standard MIDI File (an earlier transcription
    is replaced as asked; /dev/null and other non-files are written in place)."""
    try:
        if not path.is_file() or path.stat().st_size == 0:
            return False
        with path.open("rb") as f:
            return f.read(4) != b"MThd"
    except OSError:
        return False  # check_output_file and the write report what is wrong


def _live(args: argparse.Namespace, model: object, say: Callable[[str], None]) -> int:
    from services.recogniser.node import LiveReport, listen_device, play_file

    targets = args.to or ["127.0.0.1:9900"]

    report = LiveReport()  # filled as hits go, so Ctrl-C keeps them
    warned: set[str] = set()

    def warn_unreachable() -> None:
        for target, why in report.unreachable.items():
            if target not in warned:  # once per destination, not per hit
                warned.add(target)
                say(f"{WARNING} --to {target}: the hits sent there are lost ({why}): is anything listening "
                    "on that port? (`batteur transcribe --help` says how to watch them)")

    def on_hit(hit: object, latency: float) -> None:
        if not args.quiet:
            print(f"{hit.time:9.3f} s  {hit.event_type.value:12s} vel {hit.velocity:3d}  "  # type: ignore[attr-defined]
                  f"latency {latency * 1000:5.1f} ms", file=sys.stderr)
        warn_unreachable()

    status = 0
    with _quiet_refusals():
        try:
            if args.device is not None:
                asyncio.run(listen_device(targets, model, args.device or None, args.seconds,  # type: ignore[arg-type]
                                          on_hit=on_hit, report=report, warn=lambda text: say(f"{WARNING} {text}")))
            else:
                asyncio.run(play_file(args.audio, targets, model, speed=args.speed or 1.0,  # type: ignore[arg-type]
                                      max_duration_s=args.max_duration, on_hit=on_hit, report=report,
                                      warn=lambda text: say(f"{WARNING} {text}")))
        except KeyboardInterrupt:  # the way to stop listening to a device; a file stops early
            say("stopped (Ctrl-C)")
            status = 130  # as for any command (README "Exit status"); what was heard is still written
    warn_unreachable()
    lat = np.asarray(report.latencies_s) * 1000
    if not args.quiet:
        stats = (f"latency median {np.median(lat):.1f} ms, 95th percentile {np.percentile(lat, 95):.1f} ms, "
                 f"max {lat.max():.1f} ms") if lat.size else "no hits"
        print(f"{_count(len(report.hits), 'hit')} sent to {', '.join(targets)}; {stats}", file=sys.stderr)
    if args.output is not None:
        events = report.events()
        tempo = _write(events, args)
        if not args.quiet:
            print(f"{_count(len(events), 'note')} ({_summary(events)}){tempo} -> {args.output}")
    return status


@contextlib.contextmanager
def _quiet_refusals() -> Iterator[None]:
    """Keep the transport's "socket error: Connection refused" log lines (one every 5 s) off stderr while hits are
    sent: the live run says it once itself, naming the destination (:func:`_live`)."""
    transport_log = logging.getLogger("batteur.transport")

    def keep(record: logging.LogRecord) -> bool:
        return not (isinstance(record.args, tuple) and any(isinstance(a, ConnectionRefusedError)
                                                           for a in record.args))

    transport_log.addFilter(keep)
    try:
        yield
    finally:
        transport_log.removeFilter(keep)


if __name__ == "__main__":
    raise SystemExit(main())
