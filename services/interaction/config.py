"""Interaction's configuration: detection thresholds, redundancy, routes and registered messages.

One pydantic model, stored as YAML (or JSON when the path ends in .json). The
node writes it back whenever a client changes the mapping or the registered
messages over OSC, so the registered set survives a restart.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from common.datafile import one_line, parse_file
from common.input_file import NO_SUCH_FILE, file_problem
from common.output_paths import write_atomically
from services.interaction.detect import DetectionConfig
from services.interaction.mapping import MAX_MESSAGES, MAX_ROUTES, RegisteredMessage, Route, default_routes


class RedundancyConfig(BaseModel):
    """Each impact, impact end and damping message is sent ``copies`` times, ``spacing`` seconds apart."""

    model_config = ConfigDict(extra="forbid")

    copies: int = Field(default=5, ge=1, le=16, description="copies of each message")
    spacing: float = Field(default=0.004, ge=0, le=0.1, description="time between copies, seconds")


class InteractionConfig(BaseModel):
    """Everything interaction can be told, in one file."""

    model_config = ConfigDict(extra="forbid")

    impact_at: Literal["onset", "end"] = Field(
        default="onset",
        description="send /batteur/impact at the first contact step (impulse, peak force, duration 0: unknown) "
        "or when the contact is over (every figure final, later by the contact's duration + retrigger_gap)",
    )
    detection: DetectionConfig = Field(default_factory=DetectionConfig)
    redundancy: RedundancyConfig = Field(default_factory=RedundancyConfig)
    routes: list[Route] = Field(default_factory=default_routes)
    messages: list[RegisteredMessage] = Field(default_factory=list)

    @field_validator("routes")
    @classmethod
    def _unique_routes(cls, value: list[Route]) -> list[Route]:
        targets = [r.to for r in value]
        if len(targets) != len(set(targets)):
            raise ValueError("two routes go to the same target; merge them")
        if len(value) > MAX_ROUTES:
            raise ValueError(f"at most {MAX_ROUTES} routes (remove one first)")
        return value

    @field_validator("messages")
    @classmethod
    def _unique_names(cls, value: list[RegisteredMessage]) -> list[RegisteredMessage]:
        names = [m.name for m in value]
        if len(names) != len(set(names)):
            raise ValueError("registered message names must be unique")
        if len(value) > MAX_MESSAGES:
            raise ValueError(f"at most {MAX_MESSAGES} registered messages (remove one first)")
        return value


CONFIG_FILE = "a configuration file (.yaml or .json)"
"""What :func:`load_config` asks for in place of a folder, a device or a pipe."""


def load_config(path: str | Path) -> InteractionConfig:
    """Read a configuration file (YAML, or JSON by extension).

    Raises ``FileNotFoundError`` when it does not exist and ``ValueError``
    with the reason, on one line, when it is not a valid configuration or not a
    regular file (a folder, a device, a pipe: never opened, as a pipe would hold
    the node for ever waiting for a writer).
    """
    path = Path(path)
    problem = file_problem(path, CONFIG_FILE)
    if problem == NO_SUCH_FILE:
        raise FileNotFoundError(f"{path}: {problem}")
    if problem is not None:
        raise ValueError(f"{path}: {problem}")
    try:
        data = parse_file(path)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    try:
        return InteractionConfig.model_validate(data or {})
    except ValidationError as exc:  # pydantic's report spans lines and links its docs: the first problem
        raise ValueError(f"{path}: {one_line(exc)}") from None


def save_config(config: InteractionConfig, path: str | Path) -> None:
    """Write ``config`` atomically (a temporary file renamed over the old one)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = config.model_dump(mode="json", exclude_none=True)
    as_json = path.suffix.lower() == ".json"  # as parse_file reads it back
    text = json.dumps(data, indent=2) if as_json else yaml.safe_dump(data, sort_keys=False)
    write_atomically(path, text.encode("utf-8"))


class FileConfigStore:
    """Interaction's configuration file: loaded at start, written back on every change.

    Parameters
    ----------
    path : the configuration file (YAML, or JSON by extension)
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def load(self, name: str = "") -> InteractionConfig:
        """Read the file ``name`` from this store's directory, or this store's own file when ``name`` is ''.

        Only a plain file name ending in .yaml, .yml or .json is accepted, so a
        message can never make interaction read outside its configuration
        directory; anything else raises ``ValueError``.
        """
        if not name:
            return load_config(self.path)
        suffix = Path(name).suffix.lower()
        if Path(name).name != name or name in (".", "..") or suffix not in (".yaml", ".yml", ".json"):
            raise ValueError(f"{name!r}: give a file name (.yaml, .yml or .json) in {self.path.parent}, not a path")
        return load_config(self.path.parent / name)

    def save(self, config: InteractionConfig) -> None:
        save_config(config, self.path)

    def load_or_default(self) -> InteractionConfig:
        """This store's file if it exists, else the default configuration.

        Raises ``ValueError`` when the path is a folder, a device or a pipe: nothing could ever be saved there.
        """
        return InteractionConfig() if file_problem(self.path, CONFIG_FILE) == NO_SUCH_FILE else load_config(self.path)
