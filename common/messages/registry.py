"""One registry mapping OSC addresses to message models.

Encoding and decoding always go through a registry, so an address can only
ever mean one model. Modules that define messages register them with
:func:`register` at import time; ``common.messages`` imports every such module.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TypeVar

from common.messages.base import OscMessage

M = TypeVar("M", bound=type[OscMessage])


class MessageRegistry:
    """Address -> model class. Addresses are unique; re-registering one fails."""

    def __init__(self) -> None:
        self._by_address: dict[str, type[OscMessage]] = {}

    def add(self, model: type[OscMessage]) -> None:
        address = model.ADDRESS
        if not address.startswith("/") or " " in address or "#" in address:
            raise ValueError(f"{model.__name__}: invalid OSC address {address!r}")
        existing = self._by_address.get(address)
        if existing is not None and existing is not model:
            raise ValueError(f"{address} is already registered to {existing.__name__}")
        model.wire_fields()  # fail at import time on fields that cannot go on the wire
        self._by_address[address] = model

    def get(self, address: str) -> type[OscMessage] | None:
        return self._by_address.get(address)

    def __contains__(self, address: str) -> bool:
        return address in self._by_address

    def __iter__(self) -> Iterator[type[OscMessage]]:
        return iter(sorted(self._by_address.values(), key=lambda m: m.ADDRESS))

    def __len__(self) -> int:
        return len(self._by_address)


REGISTRY = MessageRegistry()
"""The registry of every message Batteur defines."""


def register(model: M) -> M:
    """Class decorator: add a message model to :data:`REGISTRY`."""
    REGISTRY.add(model)
    return model
