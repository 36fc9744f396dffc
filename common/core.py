"""The contract between a service core and whatever runs it.

A core is plain Python: no sockets, no threads, no wall clock. It is stepped
with explicit rig time and returns the messages it wants to send. A node
(``common.runtime``) runs it live over UDP; the offline runner
(``common.bus``) wires cores together in one process. Both deliver the same
typed messages, so the rig and an offline render cannot disagree.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

from common.messages import OscMessage


@dataclass(frozen=True)
class Outgoing:
    """A message a core wants sent.

    ``to`` is a role name (``"sound"``: every known node of that role), or an
    explicit ``"host:port"``; ``"reply"`` answers the sender of the message
    being handled.
    """

    message: OscMessage
    to: str


@runtime_checkable
class Core(Protocol):
    """What every service core provides."""

    ROLE: ClassVar[str]
    """The role this core plays (physics, interaction, sound, graphics)."""

    rate_hz: float
    """How often :meth:`step` wants to be called, Hz (0: only on messages)."""

    # Optional, read by the node's Health when a core has them: ``late`` (service-specific late events, total),
    # ``rejected_total`` (valid messages the core refused, e.g. an unreachable target, total; reported in
    # Health's ``dropped`` and ``dropped_other``) and ``replies_unanswered`` (refusals the core did not send
    # because their sender was over its reply budget, total; Health's ``replies_unanswered``), ``core_errors``
    # (failures the core caught itself, e.g. a strike that raised, total; added to Health's ``errors``) and
    # ``duplicates`` (redundant copies of messages dropped, total; Health's ``duplicates``).

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        """React to one received message. ``now``: rig time, seconds; ``source``: sender."""
        ...

    def step(self, now: float) -> list[Outgoing]:
        """Advance to rig time ``now`` (seconds) and return what to send."""
        ...
