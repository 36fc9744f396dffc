"""One convention for every command's exit status and error line (README, "Exit status").

- 0: done;
- 2 (:data:`USAGE`): the command line cannot be run as given: argparse's usage errors, an option's value out of
  range, options that exclude each other;
- 1 (:data:`FAILED`): an input or output the command could not use (a missing, unreadable or corrupt file, an
  output path that cannot be written, a port in use) or a failure while working;
- 130 (:data:`INTERRUPTED`): Ctrl-C (128 + SIGINT, as a shell reports it);
- 143 (:data:`TERMINATED`): SIGTERM (128 + SIGTERM) where a command stops cleanly on it (``batteur render``,
  ``evaluate``, ``demo``: nothing partial left, one line said), as a shell reports a process SIGTERM ended.

The error line is argparse's: ``PROG: error: MESSAGE`` on standard error, one line. Shared by the ``batteur``
commands (through ``batteur/errors.py``), the service nodes (``common/runtime.py``) and the services' own programs,
which must not import ``batteur/``.
"""

from __future__ import annotations

import sys

FAILED = 1
"""Exit status for an input or output the command could not use, or a failure while working."""
USAGE = 2
"""Exit status for a command line that cannot be run as given (argparse's own status for usage errors)."""
INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT), as a shell reports it."""
TERMINATED = 143
"""Exit status after SIGTERM (128 + SIGTERM) in a command that cleans up on it, as a shell reports it."""


class UsageError(ValueError):
    """An option's value (or a combination of options) the command refuses before it reads or writes anything:
    exit status 2. A ``ValueError``, so that code catching those still does."""


class InputError(ValueError):
    """A file the command cannot use (missing, unreadable, corrupt, unwritable), found by code that otherwise
    raises ``ValueError`` for a refused option: exit status 1 where that code's ``ValueError`` is 2 (a service's
    ``make_core``, docs/runtime.md). A ``ValueError``, so that code catching those still does."""


def status_for(exc: BaseException) -> int:
    """The exit status for a refused run: :data:`USAGE` for a :class:`UsageError`, else :data:`FAILED`."""
    return USAGE if isinstance(exc, UsageError) else FAILED


def report_error(prog: str, error: BaseException | str, status: int | None = None) -> int:
    """Print ``PROG: error: MESSAGE`` on standard error (an exception's message on one line) and return the exit
    status: ``status`` if given, else :func:`status_for` the exception (:data:`FAILED` for a plain message)."""
    from common.datafile import one_line  # pydantic and YAML: loaded only when there is an error to print

    message = error if isinstance(error, str) else one_line(error)
    print(f"{prog}: error: {message}", file=sys.stderr)
    if status is not None:
        return status
    return FAILED if isinstance(error, str) else status_for(error)
