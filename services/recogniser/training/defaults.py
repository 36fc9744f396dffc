"""Defaults of the offline network's trainer that its command line shows, kept apart from the PyTorch code
(:mod:`.net`, :mod:`.fit_net`) so that ``--help`` and the option checks run without PyTorch installed."""

from __future__ import annotations

DILATIONS = (2, 4, 8, 16)
"""Dilations of the residual time convolutions (frames): kernel 3, so each side sees 3 + their sum frames."""
HARD_WEIGHT = 1.0
"""Default extra weight of a class's negative frames where another class is struck (confusions; 0: none)."""
