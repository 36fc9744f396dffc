"""The exit-status convention of every ``batteur`` command (README, "Exit status"): :mod:`common.exit_status`,
where the services and their programs share it; batteur's modules import it from here."""

from __future__ import annotations

from common.exit_status import (
    FAILED,
    INTERRUPTED,
    TERMINATED,
    USAGE,
    InputError,
    UsageError,
    report_error,
    status_for,
)

__all__ = ["FAILED", "INTERRUPTED", "TERMINATED", "USAGE", "InputError", "UsageError", "report_error", "status_for"]
