"""The interaction node: :class:`~services.interaction.core.InteractionCore` live over UDP.

    batteur interaction --peer sound=127.0.0.1:9000 --interaction-config rig/interaction.yaml

Loads the kit and interaction's configuration file (mapping, registered
messages, redundancy, detection thresholds) and writes the file back whenever
a client changes it over OSC. Sequence numbers start from the wall clock in
milliseconds, so after a restart they keep growing and receivers'
de-duplication never mistakes new impacts for old copies.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from pydantic import Field

from common.config import NodeSettings
from common.exit_status import InputError
from common.kit import load_kit
from common.rated_log import RatedWarnings
from common.runtime import Node, run_node
from services.interaction.config import FileConfigStore, InteractionConfig
from services.interaction.core import InteractionCore
from services.interaction.detect import SEQ_LIMIT

log = logging.getLogger("batteur.interaction")


class InteractionSettings(NodeSettings):
    """Node settings plus interaction's own (flags, BATTEUR_* variables, settings file keys)."""

    interaction_config: str = Field(
        default="",
        description="interaction configuration file, YAML or JSON (mapping, registered messages); "
        "'' : $XDG_CONFIG_HOME/batteur/interaction.yaml, 'none': start from the defaults and persist nothing",
    )
    kit: str = Field(default="default", min_length=1, description="kit name or kit file (YAML or JSON)")


def config_path(setting: str) -> Path | None:
    """Where the configuration lives: the setting, the per-user default, or None for 'none'."""
    if setting == "none":
        return None
    if setting:
        return Path(setting).expanduser()
    base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    return base / "batteur" / "interaction.yaml"


def make_core(settings: NodeSettings, extra: argparse.Namespace) -> InteractionCore:
    """Build the core from the settings; InputError (a ValueError; printed, exit 1) for a kit or configuration
    file it cannot use (missing kit, unreadable, corrupt or not valid, a directory)."""
    if not isinstance(settings, InteractionSettings):
        settings = InteractionSettings.model_validate(settings.model_dump())
    try:
        kit = load_kit(settings.kit)
    except (FileNotFoundError, ValueError) as exc:  # missing, or not a kit
        raise InputError(str(exc)) from None
    path = config_path(settings.interaction_config)
    store: FileConfigStore | None = None
    if path is None:
        config = InteractionConfig()
    else:
        store = FileConfigStore(path)
        try:
            config = store.load_or_default()
        except OSError as exc:
            raise InputError(f"cannot read {path}: {exc}") from None
        except ValueError as exc:  # not valid, or a directory: a file it cannot use, as a kit that is not one
            raise InputError(str(exc)) from None
        log.info("interaction configuration: %s (%s)", path, "loaded" if path.is_file() else "defaults")
    seq_start = int(time.time() * 1000) % SEQ_LIMIT
    core = InteractionCore(kit=kit, config=config, seq_start=seq_start, store=store)
    for problem in core.unplayable_instruments():
        log.warning("%s: %s (never matches)", path, problem)
    core.on_config_error = _rate_limited_warning(5.0)
    return core


def _rate_limited_warning(interval_s: float) -> Callable[[str], None]:
    """A logger of mapping errors that writes at most one line per ``interval_s`` seconds."""
    warnings = RatedWarnings(log, interval_s)

    def warn(text: str) -> None:
        warnings.warn("mapping", time.monotonic(), "mapping: %s", text)

    return warn


async def report_stats(node: Node, interval_s: float = 30.0) -> None:
    """Log interaction's counters every ``interval_s`` seconds while impacts keep coming (an idle node logs nothing)."""
    last = 0
    while True:
        await asyncio.sleep(interval_s)
        core = node.core
        if not isinstance(core, InteractionCore) or core.impacts_sent == last:
            continue
        last = core.impacts_sent
        s = core.stats_message(node.clock.now())
        log.info(
            "%d contacts, %d impacts (%d chatter merged, %d touches, %d dampings), %d mapping errors, "
            "latency p50 %.2f ms p99 %.2f ms",
            s.contacts, s.impacts, s.chatter, s.touches, s.dampings, s.mapping_errors,
            s.latency_p50 * 1e3, s.latency_p99 * 1e3,
        )  # fmt: skip


def reachable_roles(node: Node) -> set[str]:
    """The roles ``node`` can send to: its peers' (static ones included) and, with discovery running, the roles
    it looks for; no other role is ever added to its peer table."""
    roles = {peer.role for peer in node.peers.all()}
    if node.discovery is not None:
        roles.update(node.browse_roles)
    return roles


def _setup(node: Node) -> None:
    if isinstance(node.core, InteractionCore):
        node.core.reachable_roles = lambda: reachable_roles(node)
    node.spawn(report_stats(node), "interaction stats")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the interaction node until SIGINT/SIGTERM; the exit code of :func:`common.runtime.run_node`."""
    return run_node(
        "interaction",
        make_core,
        argv,
        description="Run the interaction service: contacts -> impacts -> sound, graphics and registered messages.",
        settings_cls=InteractionSettings,
        setup=_setup,
    )


if __name__ == "__main__":
    raise SystemExit(main())
