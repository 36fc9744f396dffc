"""The ``batteur`` command: one entry point, a subcommand per job.

Service subcommands (``batteur sound ...``) hand their arguments to the
service's own ``main`` so each service keeps its own ``--help``.
"""

from __future__ import annotations

import argparse
import importlib
import select
import sys
from collections.abc import Callable, Sequence

from batteur.errors import INTERRUPTED, report_error
from common.output_paths import point_at_devnull

# subcommand -> (module with main(argv) -> int, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("batteur.demo", "render the shipped demo groove and print where the WAV and report are"),
    "rig": ("batteur.rig", "start all services as local processes; Ctrl-C stops them together"),
    "render": ("batteur.render", "render a score offline through the same cores as the rig"),
    "evaluate": ("batteur.evaluate", "render scores (or read renders) and measure them against the score"),
    "compare": ("batteur.compare", "a student's take (MIDI or audio) against the exercise: missed, extra, timing"),
    "physics": ("services.physics.node", "run the physics service alone"),
    "interaction": ("services.interaction.node", "run the interaction service alone"),
    "sound": ("services.sound.node", "run the sound service alone (e.g. on a second machine)"),
    "graphics": ("services.graphics.node", "run the graphics service alone"),
    "transcribe": ("services.recogniser.cli", "audio recording -> General MIDI drum file (--live: OSC hits)"),
    "ls": ("batteur.tools.ls", "list nodes discovered on the network (role, address, health, clock)"),
    "echo": ("batteur.tools.echo", "print OSC messages whose address matches a pattern"),
    "send": ("batteur.tools.send", "send one OSC message"),
    "docs": ("batteur.tools.docs", "regenerate docs/osc.md from the message models"),
    "wav-repair": ("batteur.tools.wav_repair", "give WAV or RF64 takes cut short the length they hold"),
}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="batteur",
        description=(
            "Batteur, a virtual percussionist: a simulated drummer plays a score on a simulated kit, "
            "every contact drives modal sound synthesis. Run `batteur COMMAND --help` for a command's options."
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="commands:\n" + "\n".join(f"  {name:<12} {text}" for name, (_, text) in COMMANDS.items()),
    )
    parser.add_argument("command", choices=sorted(COMMANDS), metavar="COMMAND", help="what to run (see below)")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the command's own arguments")
    return parser


def _stdout_gone() -> bool:
    """Whether standard output is a pipe or socket whose reader went away (``batteur compare ... | head``): its
    write end polls as an error or a hang-up. A reader that goes away is a quiet stop, exit 0, not a BrokenPipeError
    traceback."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        # a pipe's write end polls POLLERR, a socket's POLLHUP once its reader has gone
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))
    except (OSError, ValueError, AttributeError):  # no descriptor (a test's capture), or already closed
        return False


def load_command(name: str) -> Callable[[Sequence[str] | None], int]:
    """The ``main`` function of a subcommand's module."""
    module_name, _ = COMMANDS[name]
    module = importlib.import_module(module_name)
    main: Callable[[Sequence[str] | None], int] = module.main
    return main


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        try:
            command = load_command(args.command)
        except ModuleNotFoundError as exc:  # the installation's fault, not the command line's: 1
            return report_error(f"batteur {args.command}", f"not available in this installation ({exc})")
        status = int(command(args.args) or 0)
        sys.stdout.flush()  # here, not at exit: a reader gone by the last flush is a quiet stop too
        return status
    except BrokenPipeError:
        if not _stdout_gone():  # another pipe (a socket, a child's stdin) broke: the command's own failure
            raise
        point_at_devnull(sys.stdout)  # the interpreter's own flush at exit stays quiet
        return 0
    except KeyboardInterrupt:  # Ctrl-C in a command that does not handle it (or while its modules load)
        print(f"\nbatteur {args.command}: interrupted", file=sys.stderr)
        return INTERRUPTED


if __name__ == "__main__":
    raise SystemExit(main())
