"""Node configuration: CLI flags > environment (``BATTEUR_*``) > config file > defaults.

:class:`NodeSettings` is a pydantic-settings model. :func:`load_settings` takes
the values given on the command line (only those the user typed) and an
optional YAML or TOML config file, and merges them with the environment::

    BATTEUR_PORT=9001 BATTEUR_PEERS="sound=10.0.0.5:9000,graphics=[::1]:9100" batteur physics
    batteur physics --config rig.yaml --port 9001 --peer sound=10.0.0.5:9000

List settings (``peers``, ``interfaces``, ``allow``) are comma-separated in
environment variables, repeated flags on the command line and lists in files.
An empty environment variable (``BATTEUR_PLAY_AT=``) is taken as not set.
A bad value raises :class:`SettingsError` with one readable line per problem.
"""

from __future__ import annotations

import ipaddress
import os
import re
import socket
import time
from collections.abc import Mapping, Sequence
from contextvars import ContextVar
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import Field, ValidationError, ValidationInfo, field_validator, model_validator
from pydantic_settings import (
    BaseSettings,
    InitSettingsSource,
    NoDecode,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
)

from common.datafile import error_message, parse_file
from common.input_file import file_problem
from common.peers import Peer, parse_static_peer
from common.transport import MAX_UDP_PAYLOAD, SERVICE_ROLES

ENV_PREFIX = "BATTEUR_"
DEFAULT_RIG = "batteur"
"""The rig name of a node given none (``--rig`` / BATTEUR_RIG): one shared name, so the nodes of a rig spread over
two machines find each other with no flag; two rigs on one network give each its own."""
LOOPBACK_NETWORKS = ("127.0.0.0/8", "::1/128")
ABSENT_ROLES = (*SERVICE_ROLES, "recogniser")
"""The roles ``--absent`` takes: the nodes' (services/recogniser's too)."""

FLAG_NAMES = {"peers": "--peer", "interfaces": "--interface"}
"""Command-line flags whose name is not ``--`` + the setting name with dashes."""


def flag_name(setting: str) -> str:
    """The command-line flag of a setting (``peers`` -> ``--peer``)."""
    return FLAG_NAMES.get(setting, "--" + setting.replace("_", "-"))


_config_file_data: ContextVar[dict[str, Any] | None] = ContextVar("_config_file_data", default=None)


class SettingsError(ValueError):
    """Invalid configuration, with a message meant for the user (one line per problem)."""


class ConfigFileError(SettingsError):
    """A config file that cannot be used at all (missing, unreadable, not YAML/TOML, not a mapping), as opposed to
    values in it that are refused: a file the command cannot use (exit status 1, common/exit_status.py)."""


def default_node_id(role: str) -> str:
    """``role-hostname-pid``, restricted to the characters a node id may hold, at most 64."""
    host = re.sub(r"[^A-Za-z0-9_.-]+", "-", socket.gethostname().split(".")[0]) or "host"
    return f"{role}-{host}-{os.getpid()}"[:64]


def _split_list(value: Any) -> Any:
    if isinstance(value, str):
        return [item.strip() for item in value.split(",") if item.strip()]
    return value


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) only listens on the loopback interface."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def off_loopback_problem(host: str, allow: Sequence[object]) -> str:
    """Why a node may not listen on ``host`` with the allow-list ``allow`` ("" if it may): off loopback it needs the
    networks allowed to send to it. The node's own check, and ``batteur rig``'s before it starts any service."""
    if is_loopback(host) or allow:
        return ""
    return (f"host {host} listens off loopback: give the networks allowed to send to this node "
            "with --allow NETWORK (or BATTEUR_ALLOW), e.g. --allow 192.168.1.0/24; --allow 0.0.0.0/0 accepts anyone")


def _numeric(annotation: Any) -> bool:
    """Whether a setting's type takes numbers only: int, float, a Literal of numbers, or one of them or None."""
    if annotation in (int, float):
        return True
    args = get_args(annotation)
    if get_origin(annotation) is Literal:
        return all(isinstance(a, int | float) and not isinstance(a, bool) for a in args)
    if get_origin(annotation) in (Union, UnionType):
        kinds = [a for a in args if a is not type(None)]
        return bool(kinds) and all(_numeric(a) for a in kinds)
    return False


class NodeSettings(BaseSettings):
    """Settings of one service node (all services share these; a service may add flags of its own)."""

    # env_ignore_empty: an empty BATTEUR_<NAME> means not set, as most tools take it, so compose.yaml can pass
    # ${BATTEUR_PLAY_AT:-} (the default, or the file's value, applies); it was parsed and refused ('' is no number)
    model_config = SettingsConfigDict(env_prefix=ENV_PREFIX, extra="forbid", validate_default=True,
                                      env_ignore_empty=True)

    role: str = Field(default="node", pattern=r"^[a-z][a-z0-9_-]*$", max_length=32,
                      description="service role (physics, interaction, sound, graphics, ...)")
    node_id: str = Field(default="", pattern=r"^[A-Za-z0-9_.:-]*$", max_length=64,
                         description="unique id of this node (default: ROLE-HOSTNAME-PID)")
    host: str = Field(default="127.0.0.1", min_length=1,
                      description="address to listen on; 127.0.0.1 keeps the node on this machine, "
                      "0.0.0.0 or :: listens on the LAN (then --allow is required)")
    port: int = Field(default=0, ge=0, le=65535, description="UDP port to receive OSC on (0: any free port)")
    peers: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="static peers ROLE=HOST:PORT; override discovery for their role")
    absent: Annotated[list[str], NoDecode] = Field(
        default_factory=list, description="a role left out on purpose (batteur rig gives each role it does not "
        "start): messages to it are counted in Health as unroutable but not warned about")
    discovery: bool = Field(default=True, description="register and browse with zeroconf")
    interfaces: Annotated[list[str], NoDecode] = Field(
        default_factory=lambda: ["127.0.0.1"],
        description="interfaces zeroconf uses: addresses, names (eth0) or 'all' (default: loopback)",
    )
    rig: str = Field(default=DEFAULT_RIG, pattern=r"^[A-Za-z0-9_.-]{1,32}$",
                     description="name of the rig this node belongs to, carried in its zeroconf record: nodes of "
                     "another rig on the network are ignored (two classes on one network: a name each, "
                     "docs/deployment.md)")
    discovery_ttl_s: int = Field(default=30, ge=1, le=3600,
                                 description="TTL of this node's zeroconf records, seconds: how long a node that dies "
                                 "without a goodbye lingers at its peers")
    rate_hz: float | None = Field(default=None, gt=0, le=100_000,
                                  description="step rate of the core, Hz (default: the core's own)")
    epoch: float = Field(default_factory=time.time, ge=0,
                         description="rig epoch, Unix seconds (default: now); give every node of a rig the same")
    clock_master: str = Field(default="physics", pattern=r"^[a-z][a-z0-9_-]*$",
                              description="role whose clock is the rig clock, or 'self'")
    latency_s: float = Field(default=0.05, ge=0, le=5,
                             description="latency window, seconds: sound plays and graphics shows events this late")
    allow: Annotated[list[ipaddress.IPv4Network | ipaddress.IPv6Network], NoDecode] = Field(
        default_factory=list, description="networks allowed to send to this node, e.g. 192.168.1.0/24 "
        "(required when listening off loopback; loopback is always allowed)")
    max_rate: float | None = Field(default=None, gt=0,
                                   description="messages per second accepted from one source, a bundle counting each "
                                   "message it holds (default: no limit)")
    log_level: Literal["DEBUG", "INFO", "WARNING", "ERROR"] = Field(default="INFO", description="logging level")
    oscquery: bool = Field(default=True, description="serve the OSC namespace over OSCQuery (HTTP + WebSocket) "
                           "and advertise it as _oscjson._tcp")
    oscquery_port: int = Field(default=0, ge=0, le=65535,
                               description="TCP port of the OSCQuery server (0: any free port)")
    max_datagram: int = Field(default=MAX_UDP_PAYLOAD, ge=512, le=MAX_UDP_PAYLOAD,
                              description="largest datagram sent or accepted, bytes")

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        file_data = _config_file_data.get() or {}
        return (init_settings, env_settings, InitSettingsSource(settings_cls, init_kwargs=file_data))

    @field_validator("*", mode="before")
    @classmethod
    def _no_true_or_false_for_a_number(cls, value: Any, info: ValidationInfo) -> Any:
        """A settings file's ``channels: true`` or ``height_m: yes`` is no number, in every node's settings
        (pydantic takes true as 1: a sound node went mono, silently)."""
        if isinstance(value, bool) and info.field_name is not None and _numeric(
                cls.model_fields[info.field_name].annotation):
            raise ValueError(f"a number, not {str(value).lower()}")
        return value

    @field_validator("peers", "interfaces", "absent", mode="before")
    @classmethod
    def _lists(cls, value: Any) -> Any:
        return _split_list(value)

    @field_validator("allow", mode="before")
    @classmethod
    def _networks(cls, value: Any) -> Any:
        items = _split_list(value)
        if not isinstance(items, list):
            return items
        out = []
        for item in items:
            try:
                out.append(ipaddress.ip_network(item, strict=False) if isinstance(item, str) else item)
            except ValueError:
                raise ValueError(f"{item!r} is not an IP network (e.g. 192.168.1.0/24, 10.0.0.7, fd00::/8)") from None
        return out

    @field_validator("log_level", mode="before")
    @classmethod
    def _upper(cls, value: Any) -> Any:
        return value.upper() if isinstance(value, str) else value

    @field_validator("peers")
    @classmethod
    def _check_peers(cls, value: list[str]) -> list[str]:
        for spec in value:
            parse_static_peer(spec)  # ValueError -> a validation error naming the bad peer
        return value

    @field_validator("absent")
    @classmethod
    def _check_roles(cls, value: list[str]) -> list[str]:
        unknown = [role for role in value if role not in ABSENT_ROLES]
        if unknown:  # a misspelt role silenced nothing, and said nothing (until 7 Dec)
            raise ValueError(f"{', '.join(map(repr, unknown))}: no such role (one of {', '.join(ABSENT_ROLES)})")
        return list(dict.fromkeys(value))  # once each, in order

    @field_validator("interfaces")
    @classmethod
    def _check_interfaces(cls, value: list[str]) -> list[str]:
        if not value:
            raise ValueError("give at least one interface (127.0.0.1 for loopback only)")
        for item in value:
            try:
                ipaddress.ip_address(item)
            except ValueError:
                if not re.fullmatch(r"[A-Za-z0-9_.:@-]{1,64}", item):
                    raise ValueError(f"interface {item!r} is neither an IP address nor an interface name") from None
        return value

    @model_validator(mode="after")
    def _complete(self) -> NodeSettings:
        if not self.node_id:
            self.node_id = default_node_id(self.role)
        problem = off_loopback_problem(self.host, self.allow)
        if problem:
            raise ValueError(problem)
        return self

    @property
    def static_peers(self) -> list[Peer]:
        """The ``peers`` setting as :class:`~common.peers.Peer` objects."""
        return [parse_static_peer(spec) for spec in self.peers]

    @property
    def allow_networks(self) -> list[ipaddress.IPv4Network | ipaddress.IPv6Network] | None:
        """Networks the transport accepts: None (anyone) on loopback, else ``allow`` plus loopback."""
        if is_loopback(self.host):
            return None
        return list(self.allow) + [ipaddress.ip_network(n) for n in LOOPBACK_NETWORKS]


def read_config_file(path: str | Path) -> dict[str, Any]:
    """Settings from a YAML (``.yaml``/``.yml``) or TOML (``.toml``) file; raise :class:`ConfigFileError`."""
    file = Path(path)
    problem = file_problem(file, "a config file (.yaml or .toml)")
    if problem is not None:  # a pipe is never opened: without a writer it would hold the node for ever
        raise ConfigFileError(f"config file {file}: {problem}")
    try:
        data: Any = parse_file(file)
    except OSError as exc:
        raise ConfigFileError(f"config file {file}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise ConfigFileError(f"config file {file}: {exc}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigFileError(f"config file {file}: expected a mapping of setting names to values")
    return {str(k).replace("-", "_"): v for k, v in data.items()}


def file_settings(from_file: Mapping[str, Any], cli_role: Any = None, default_role: Any = None,
                  settings_cls: type[NodeSettings] = NodeSettings,
                  environ: Mapping[str, str] | None = None) -> dict[str, Any]:
    """What a config file's ``from_file`` (:func:`read_config_file`) sets for one node: its top level, with the table
    of the node's role over it (a shared rig file: ``[sound]`` for the sound node; other roles' tables ignored). The
    role is the command line's ``cli_role``, else ``BATTEUR_ROLE`` (of ``environ``, default the process's), else the
    file's ``role``, else ``default_role``. :func:`load_settings` and ``batteur rig`` (the peers a node will hold)
    both read a file this way."""
    env = os.environ if environ is None else environ
    role = cli_role or env.get(f"{ENV_PREFIX}ROLE") or from_file.get("role") or default_role
    sections = {k: v for k, v in from_file.items() if isinstance(v, dict) and k not in settings_cls.model_fields}
    data = {k: v for k, v in from_file.items() if k not in sections}
    if isinstance(role, str) and role in sections:
        data.update({str(k).replace("-", "_"): v for k, v in sections[role].items()})
    return data


def load_settings(
    cli: Mapping[str, Any] | None = None,
    config_file: str | Path | None = None,
    defaults: Mapping[str, Any] | None = None,
    settings_cls: type[NodeSettings] = NodeSettings,
) -> NodeSettings:
    """Merge the sources into validated settings.

    Parameters
    ----------
    cli : mapping
        Values given on the command line (only those given): highest precedence.
    config_file : path or None
        YAML or TOML file; default: ``$BATTEUR_CONFIG`` if set. Lowest precedence above defaults.
        Top-level keys apply to every node; a table named after a role (``[sound]``, ``sound:``)
        applies to that role's node only and wins over the top level. Other roles' tables are ignored.
    defaults : mapping
        Defaults that replace the class defaults (e.g. ``{"role": "sound"}``), below the config file.

    Raises
    ------
    SettingsError
        With one line per invalid setting.
    """
    if config_file is None:
        config_file = os.environ.get(f"{ENV_PREFIX}CONFIG") or None
    file_data = dict(defaults or {})
    if config_file is not None:
        file_data.update(file_settings(read_config_file(config_file), (cli or {}).get("role"), file_data.get("role"),
                                       settings_cls))
    token = _config_file_data.set(file_data)
    try:
        return settings_cls(**dict(cli or {}))
    except ValidationError as exc:
        raise SettingsError(format_validation_error(exc)) from None
    except ValueError as exc:  # pydantic-settings' own parse errors
        raise SettingsError(str(exc)) from None
    finally:
        _config_file_data.reset(token)


def format_validation_error(exc: ValidationError) -> str:
    """One line per problem: ``setting: message (got value)``."""
    lines = []
    for error in exc.errors():
        where = ".".join(str(p) for p in error.get("loc", ())) or "settings"
        message = error_message(error)
        value = error.get("input")
        got = f" (got {value!r})" if where != "settings" and not isinstance(value, dict) else ""
        name = where.split(".")[0]
        env = f" [{flag_name(name)} / {ENV_PREFIX}{name.upper()}]"
        if where == "settings":
            lines.append(f"invalid settings: {message}")
        else:
            lines.append(f"invalid setting {where}: {message}{got}{env}")
    return "\n".join(lines)
