"""Errors the recogniser reports to its user (clear messages, never a traceback)."""

from __future__ import annotations


class RecogniserError(Exception):
    """Base class: the message is meant for the user."""


class AudioFileError(RecogniserError):
    """The audio file cannot be used: unreadable, empty, silent or too long."""


class ModelError(RecogniserError):
    """The model file is missing or malformed."""
