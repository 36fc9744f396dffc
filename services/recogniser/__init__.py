"""Percussion recogniser: audio -> drum events -> Standard MIDI File (Kragtwijk et al. 2001, first half).

Offline: :func:`services.recogniser.transcribe.transcribe` (used by ``batteur transcribe``).
Live: :class:`services.recogniser.core.LiveRecogniser` wrapped by :mod:`services.recogniser.node`.
"""
