"""``batteur rig``: start every service as a local process and stop them together.

Each service runs as ``python -m batteur ROLE`` with its own UDP port (base
port + 0 physics, + 1 interaction, + 2 sound, + 3 graphics), the same rig
epoch (so all local nodes share one rig clock), static peers for the others
(so the rig works where loopback has no multicast; ``--no-static-peers``
leaves finding each other to zeroconf alone; ``BATTEUR_PEERS`` in the rig's
environment adds to them, but for the roles the rig starts: :func:`environment_peers`) and, unless ``--no-discovery``,
zeroconf discovery on the given interfaces.
Each service's output lines are prefixed with its role, its stdout on the rig's stdout and its stderr (its log)
on the rig's stderr. Ctrl-C (SIGINT), SIGTERM or SIGHUP
stops every child with SIGTERM, waits up to ``--stop-timeout`` seconds, then
kills what is left; what a service leaves in its process group (planning
processes, a resource tracker) is stopped once it has exited, and the rig reads
output for at most ``DRAIN_S`` more seconds, so no grandchild holding the output
pipe keeps it running. If physics, interaction or sound exits, the others are stopped too; if graphics (the view,
:data:`OPTIONAL_ROLES`) does once it was up (had answered the rig's Hello, or, without ``--score``, still ran when
the rig stopped waiting for it), the rig says so and the others play on, its exit status at the end graphics' code
(0 if it exited with 0, 1 if killed); graphics exiting before it was up, or refusing its options (2), stops the rig as
any service does (a mistake in how it was started fails fast; exit 1 for a 0 then: no script reads it as success).
``--record DIR``: sound records to ``DIR/performance.wav`` (under a hidden part name until it stops; it names the
take only when it stops cleanly, so a take cut short never replaces an earlier one, and stays in its part file,
which the rig names).
The graphics view listens on TCP ``--http-port`` (default 8080; a second rig on
the same machine needs another); its page saves kits and poses into ``--kit-dir`` (off without it).
A ``--ROLE-arg`` may give a service its own ``--host`` (the last wins, as argparse keeps it: the rig's checks,
peers and Hellos take it), never its own ``--kit`` (refused: every service plays the rig's one kit), nor what the rig
gives it (``--port``, ``--epoch``, ``--score``, ...: refused naming the rig's own option, :data:`RIG_GIVES`); the rig
reads these, ``--allow`` and ``--config`` there abbreviated too, as a service's argparse takes them (``--ho``,
``--ki``: :data:`ABBREVIATIONS`).
On Linux the services get SIGTERM when the rig itself dies, even by SIGKILL, so none is left running as an orphan.

``--score FILE`` (a .mid or text score, or ``demo`` for the demo groove of
``batteur demo``) makes the drummer play it live: the physics node gets
``--score FILE --play-at SECONDS`` (it loads the score before it listens and
plans it once its clock runs, so no message can be lost at start-up; the
file's directory becomes its score library, so the Pd panel can load it again
by name). Every service gets the kit of the score's ``kit`` line, or ``--kit`` when given (which wins, as
for ``batteur render``; physics' log then says the score's line is not played). Rig time 0 is ``--start-delay``
seconds after launch; the score starts at rig time ``--play-at``, or, when physics is up only after it (a
loaded machine), as soon as physics can play it from its first note. The rig
sends each service a Hello until it answers with its Health, says what it is
waiting for every few seconds and when all are up (with or without ``--score``: a performer driving the rig over
OSC is told when to start), and, with ``--score``, stops (exit 1) naming the services not up ``--ready-timeout``
seconds after launch (without it, warns and runs on).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import ctypes
import errno
import hashlib
import ipaddress
import os
import re
import shlex
import signal
import socket
import sys
import tempfile
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from batteur.errors import FAILED, USAGE, UsageError, report_error
from common.arg_types import non_negative, positive, seconds, take_negative_values, whole
from common.config import DEFAULT_RIG
from common.input_file import file_problem
from common.output_paths import check_output_dir, point_at_devnull
from common.score.midi_options import add_midi_arguments, midi_read_kwargs, midi_service_args
from common.takes import part_timing, parts_glob

if TYPE_CHECKING:
    from common.kit import Kit
    from common.peers import Peer
    from common.score.events import Score

ROLES = ("physics", "interaction", "sound", "graphics")
DEFAULT_HOST = "127.0.0.1"
"""Where a node listens without ``--host`` (common/config.py), and the rig's default ``--host``."""
PORT_OFFSET = {role: i for i, role in enumerate(ROLES)}
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""Signals that stop the rig: Ctrl-C, kill, and the terminal closing (the services, in their own sessions, would
not get its SIGHUP and would run on as orphans)."""
CLEAN_STOP = (0, -signal.SIGTERM)
"""Exit codes of a service the rig stopped that mean it stopped cleanly: a node stops on SIGTERM with 0; one still
loading (no handler yet) just ends, with nothing to clean up (sound's recording is kept only after a 0)."""
SAID = {"compiling": ("compiling the physics kernels", "physics kernels ready"),
        "stopping": ("was asked to stop while starting", "")}
"""What a service's output says that the rig's messages name: key -> (the text that says it, the text that ends it
or ""). Copies of ``services.physics.precompile.COMPILING`` and :func:`common.runtime.stopped_while_starting`'s (the
rig does not import physics to start it; a test checks the copy)."""
PR_SET_PDEATHSIG = 1
"""Linux prctl option: the signal a process gets when the thread that started it ends."""
EXIT_POLL_S = 0.05
"""Seconds between looks at whether a service has exited."""
GROUP_GRACE_S = 2.0
"""Seconds what is left in an exited service's process group gets between SIGTERM and SIGKILL."""
DRAIN_S = 2.0
"""Seconds the rig still reads a service's output once every service has exited and its process group was
killed: a grandchild that left the group (its own session) may hold the pipe open for good."""
RECORDING = "performance.wav"
"""What sound records to (``--wav DIR/performance.wav``): it writes a hidden part file beside it and gives it this
name only once it has stopped cleanly, so a take cut short never replaces an earlier one; it stays in its part file
(a playable WAV up to its last block), which the rig and the node name."""
READY_POLL_S = 0.5
"""Seconds between Hellos to a service that has not answered one yet (``--score``)."""
READY_PROGRESS_S = 5.0
"""Seconds between the rig's "waiting for ..." lines while its services start."""
OPTIONAL_ROLES = ("graphics",)
"""Services the show goes on without: when one exits once it was up (:meth:`Rig.was_up`: it answered, or ran past
the ready wait), the rig says so and physics, interaction and sound play on (a walkthrough's SIGKILLed view took the
audio down mid-set). Its exit status at the end still says it failed. One that exits before it was up (exit 1 for a
0), or with 2 (it refused its options), stops the rig. Not
sound: the take (``--record``) and what is heard are its; nor physics (the drummer, the clock master) or interaction
(sound's impacts)."""


@dataclass
class ServicePlan:
    """The command line of one service in the rig."""

    role: str
    port: int
    args: list[str] = field(default_factory=list)

    def argv(self) -> list[str]:
        return [sys.executable, "-m", "batteur", self.role, "--port", str(self.port), *self.args]

    @property
    def host(self) -> str:
        """The address the service listens on: its last ``--host`` (argparse keeps the last: a ``--ROLE-arg
        '--host ADDRESS'`` after the rig's own; abbreviated too, ``--ho``), else a node's default, loopback."""
        given = option_values(self.args, "--host")
        return given[-1] if given else DEFAULT_HOST


ABBREVIATIONS = {"--host": "--ho", "--kit": "--k", "--allow": "--a", "--config": "--co", "--port": "--po",
                 "--epoch": "--e", "--role": "--ro", "--score": "--score", "--play-at": "--pl", "--wav": "--w",
                 "--http-port": "--ht", "--kit-dir": "--kit-", "--scene": "--sce", "--strike-period": "--strike-p",
                 "--strike-velocity": "--strike-v", "--drum-channels": "--drum-c", "--drum-map": "--drum-m",
                 "--no-hihat-cc4": "--no-h", "--score-dir": "--score-", "--preview-score": "--preview-s",
                 "--left-handed": "--le", "--rig": "--ri"}
"""The shortest abbreviation of each service option the rig reads in a ``--ROLE-arg`` (:func:`option_uses`). A
service's parser (argparse, allow_abbrev) takes any prefix of a long option that no other of its options shares
(``--ho`` for ``--host``), an exact name first, and refuses an ambiguous one (exit 2). So ``--h`` is no ``--host``
(it is ``--help`` too, in every service); ``--k`` and ``--ki`` are ``--kit`` in physics, interaction and sound and
ambiguous in graphics (``--kit-dir``); ``--co`` and ``--con`` are ``--config`` but in physics (``--control``);
``--po`` is ``--port`` but in physics (``--pose-rate-hz``); ``--score`` has none (``--score-dir``). Each is the
shortest prefix some service takes: a token the rig reads as the option where a service finds it ambiguous changes
nothing, that service refuses it anyway (tests/cli/test_rig_service_options.py checks this table against the
services' parsers)."""

RIG_GIVES = {
    "--port": ("override the UDP port the rig gives {role} (the other services' peers and the rig's Hellos send there)",
               "use batteur rig --base-port (physics on it, interaction, sound and graphics on the next three)"),
    "--epoch": ("override the rig epoch every service shares (their rig clocks would disagree)",
                "use batteur rig --start-delay (rig time 0 that many seconds after launch)"),
    "--role": ("override the role the rig starts {role} in (the other services and the rig's Hellos take it for "
               "{role})", "use batteur rig --services to choose the roles"),
    "--score": ("give {role} a score of its own, which the rig neither checks before anything starts nor waits for "
                "the services to play, nor gives every service the kit of", "use batteur rig --score {value}"),
    "--play-at": ("override the rig time the rig's --score starts at (and that the rig says it starts at)",
                  "use batteur rig --play-at {value}"),
    "--wav": ("override where batteur rig --record has sound record (the rig names the take, or its part file, "
              "there)", "use batteur rig --record DIR alone, or --sound-arg '--wav FILE' without --record"),
    "--http-port": ("override the view's TCP port, which the rig checks is free before anything starts",
                    "use batteur rig --http-port {value}"),
    "--kit-dir": ("override the folder batteur rig --kit-dir gives graphics", "give batteur rig --kit-dir alone"),
    "--scene": ("override the strike scene batteur rig --strike-period gives physics",
                "use batteur rig --strike-period alone"),
    "--strike-period": ("override the strike period batteur rig --strike-period gives physics",
                        "use batteur rig --strike-period {value}"),
    "--strike-velocity": ("override the strike velocity the rig gives physics (its --strike-velocity, default 3)",
                          "use batteur rig --strike-velocity {value}"),
    "--drum-channels": ("override the MIDI channels batteur rig --drum-channels gives {role} (a score read otherwise "
                        "than the rig read it)", "use batteur rig --drum-channels {value}"),
    "--drum-map": ("override the note map batteur rig --drum-map gives {role} (a score read otherwise than the rig "
                   "read it)", "use batteur rig --drum-map {value}"),
    "--no-hihat-cc4": ("turn off the hi-hat pedal batteur rig --hihat-cc4 gives {role} (a score read otherwise than "
                       "the rig read it)", "drop batteur rig --hihat-cc4 to read hi-hat notes as written"),
    "--rig": ("put {role} in another rig than the other services (nodes of another rig ignore each other)",
              "use batteur rig --rig {value} (every service)"),
}
"""The service options a ``--ROLE-arg`` may not give (:func:`refuse_rig_options`), each with what it would do
(``{role}``: the service) and the rig's own option to use instead (``{value}``: the one given). ``--port``,
``--epoch``, ``--role``, ``--score`` (and ``--kit``, with a message of its own) are refused whenever given: the rig
gives each service the first two, starts it in its role, and plays a score only through its own ``--score`` (checked
first, its kit line for every service, the services waited for). The others only where the rig gives that service
the option itself (``--wav`` with ``--record``, a strike option with ``--strike-period``, ...): without the rig's, a
service's own is the user's to give. Not here, so allowed: ``--host`` (where that service listens: the rig's checks,
peers and Hellos take it), ``--peer``, ``--allow`` and ``--interface`` (they add to the rig's, repeatable),
``--log-level``, ``--node-id``, ``--discovery``, and every option the rig does not give."""
ALWAYS_REFUSED = ("--port", "--epoch", "--role", "--score", "--rig")
"""The options of :data:`RIG_GIVES` refused whether or not the rig gave that service one."""
GIVEN_AS = {"--no-hihat-cc4": "--hihat-cc4"}
"""An option of :data:`RIG_GIVES` refused where the rig gives that service this other one: a flag's negation."""
FLAGS = ("--hihat-cc4", "--no-hihat-cc4", "--left-handed")
"""The options :func:`option_uses` reads that take no value."""


def option_uses(args: Sequence[str], flag: str) -> list[tuple[str, str]]:
    """(name as written, value) of each time ``args`` (a service's command line) gives the long option ``flag``, in
    order: ``NAME VALUE`` or ``NAME=VALUE``, NAME being ``flag`` or, for a flag in :data:`ABBREVIATIONS`, an
    abbreviation a service's parser would take for it (``--ho`` for ``--host``); a flag of :data:`FLAGS` has the
    value "" (the next argument is not its)."""
    shortest = ABBREVIATIONS.get(flag, flag)
    uses = []
    for i, arg in enumerate(args):
        name, equals, value = arg.partition("=")
        if len(name) < len(shortest) or not flag.startswith(name):
            continue
        if flag in FLAGS:
            uses.append((name, ""))
        elif equals:
            uses.append((name, value))
        elif i + 1 < len(args):
            uses.append((name, args[i + 1]))
    return uses


def option_values(args: Sequence[str], flag: str) -> list[str]:
    """The values ``args`` gives the long option ``flag`` (or an abbreviation of it), in order
    (:func:`option_uses`)."""
    return [value for _, value in option_uses(args, flag)]


def peer_host(host: str) -> str:
    """The address the rig's services send each other, given the one they listen on (``--host``).

    A wildcard (0.0.0.0, ::) is no address to send to: the kernel delivers such a datagram over loopback, so
    the replies come from 127.0.0.1 (::1), and a clock pong from an address other than its pings' is dropped
    as not from the master. The services are on this machine: loopback then.
    """
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:  # a host name
        return host
    if ip.is_unspecified:
        return "127.0.0.1" if ip.version == 4 else "::1"
    return host


def node_peer_roles(cli_peers: Sequence[str], own: Sequence[str], role: str,
                    environ: Mapping[str, str] | None = None) -> set[str]:
    """The roles of the static peers the ``role`` node started with ``--peer`` values ``cli_peers`` (the rig's and
    its ``--ROLE-arg``'s) and its own arguments ``own`` will hold, resolved as its settings resolve them
    (:func:`common.config.load_settings`): the command line's, else ``BATTEUR_PEERS`` (empty: not set), else its
    config file's (``--config``, else ``BATTEUR_CONFIG``; the role's table over the top level). A list replaces,
    never extends, the one below it. A peer or file the node will refuse counts as none: the node says why."""
    return {peer.role for peer in node_static_peers(cli_peers, own, role, environ)[0]}


def node_static_peers(cli_peers: Sequence[str], own: Sequence[str], role: str,
                      environ: Mapping[str, str] | None = None) -> tuple[list[Peer], str]:
    """The static peers a node will hold, resolved as :func:`node_peer_roles` tells, and where they come from:
    "--peer", "BATTEUR_PEERS" or "its config file FILE" ("" when none)."""
    from common.config import ENV_PREFIX, SettingsError, file_settings, read_config_file
    from common.peers import parse_static_peer

    env = os.environ if environ is None else environ
    specs: Any = list(cli_peers)
    source = "--peer"
    if not specs:
        specs, source = env.get(f"{ENV_PREFIX}PEERS") or None, f"{ENV_PREFIX}PEERS"
    if specs is None:
        config = (option_values(own, "--config") or [env.get(f"{ENV_PREFIX}CONFIG") or ""])[-1]
        try:
            data = read_config_file(config) if config else {}
        except SettingsError:
            data = {}
        specs = file_settings(data, None, role, environ=env).get("peers")  # as load_settings reads the file
        source = f"its config file {config}" if specs else ""
    if isinstance(specs, str):
        specs = specs.split(",")
    peers = []
    for spec in specs if isinstance(specs, list) else []:
        with contextlib.suppress(ValueError):
            peers.append(parse_static_peer(str(spec).strip()))
    return peers, source if peers else ""


def environment_peers(given: Sequence[str], environ: Mapping[str, str] | None = None,
                      started: Collection[str] = ()) -> list[str]:
    """The ``--peer`` values a rig's service also gets from ``BATTEUR_PEERS`` of ``environ`` (None: the rig's
    environment), given ``--peer`` values ``given`` (the rig's static peers and its ``--ROLE-arg``'s): those of its
    peers not among them, in order, but for a peer of a role in ``started`` (the roles the rig starts itself, the
    node's own among them); none when ``given`` is empty (the node reads the variable itself). A node given
    ``--peer`` ignores the variable (a flag replaces the environment's list), so until 8 Dec the rig's own static
    peers, which the user never typed, silently dropped it: ``BATTEUR_PEERS=physics=10.0.0.5:9101 batteur rig
    --services sound,graphics`` left sound without its physics. A started role's peer is left out
    (:func:`left_out_environment_peers` says so): a node sends to every peer of a role and follows the clock of the
    lowest physics node id, so until the day after 8 Dec ``BATTEUR_PEERS=physics=10.0.0.5:9101 batteur rig`` had the
    local services follow that physics, not the rig's, and physics hold a peer of its own role.
    :class:`UsageError` for a peer no node would take."""
    from common.config import ENV_PREFIX
    from common.peers import parse_static_peer

    env = os.environ if environ is None else environ
    value = env.get(f"{ENV_PREFIX}PEERS") or ""
    if not given or not value.strip():
        return []
    have = set()
    for spec in given:
        with contextlib.suppress(ValueError):  # a bad --ROLE-arg peer: the node refuses it, saying why
            have.add(parse_static_peer(spec.strip()).node_id)
    added = []
    for spec in filter(None, (v.strip() for v in value.split(","))):
        try:
            peer = parse_static_peer(spec)
        except ValueError as exc:
            raise UsageError(f"{ENV_PREFIX}PEERS={value}: {exc} (the rig's services take its peers beside the "
                             "ones the rig gives them)") from None
        if peer.node_id not in have and peer.role not in started:
            have.add(peer.node_id)
            added.append(spec)
    return added


def left_out_environment_peers(plans: Sequence[ServicePlan], environ: Mapping[str, str] | None = None) -> str | None:
    """A warning naming the ``BATTEUR_PEERS`` peers of ``environ`` (None: the rig's) that :func:`environment_peers`
    left out of the ``--peer`` the rig gives its services (one given ``--peer``, which ignores the variable): those of
    a role the rig starts itself, at another address than the rig's own service of it; None when there is none."""
    from common.config import ENV_PREFIX
    from common.peers import parse_static_peer
    from common.transport import format_address

    env = os.environ if environ is None else environ
    given = [spec for plan in plans for spec in option_values(plan.args, "--peer")]
    if not given:  # each node reads the variable itself
        return None
    started = {plan.role: plan for plan in plans}
    have = set()
    for spec in given:
        with contextlib.suppress(ValueError):
            have.add(parse_static_peer(spec.strip()).node_id)
    left_out = []
    for spec in filter(None, (v.strip() for v in (env.get(f"{ENV_PREFIX}PEERS") or "").split(","))):
        with contextlib.suppress(ValueError):  # refused by plan_rig already
            peer = parse_static_peer(spec)
            if peer.role in started and peer.node_id not in have:
                left_out.append((spec, peer.role))
    if not left_out:
        return None
    names = ", ".join(spec for spec, _ in left_out)
    roles = list(dict.fromkeys(role for _, role in left_out))
    ours = ", ".join(f"{role} at {format_address(peer_host(started[role].host), started[role].port)}"
                     for role in roles)
    return (f"{ENV_PREFIX}PEERS: {names} left out of the peers the rig gives its services: this rig starts {ours} "
            "itself, and its services would send to both and could follow the other's clock; to play with "
            f"{'that node' if len(left_out) == 1 else 'those nodes'}, leave {' and '.join(roles)} out of --services")


def plan_rig(opts: argparse.Namespace, epoch: float, environ: Mapping[str, str] | None = None) -> list[ServicePlan]:
    """The services to start, each with its port, peers, epoch and own arguments; ``environ``: the environment the
    services inherit (None: the rig's), where a node's ``BATTEUR_PEERS`` or config file may give it peers."""
    roles = [r.strip() for r in opts.services.split(",") if r.strip()]
    unknown = [r for r in roles if r not in ROLES]
    if unknown or not roles:
        named = ", ".join(unknown) or "(none)"
        raise UsageError(f"--services: unknown role(s) {named}; choose from {', '.join(ROLES)}")
    if len(set(roles)) < len(roles):  # two services of a role would share its port; the rig runs one of each
        raise UsageError(f"--services {opts.services}: each role at most once")
    if opts.no_static_peers and opts.no_discovery and len(roles) > 1:
        raise UsageError("--no-static-peers with --no-discovery: the services could not find each other; "
                         "drop one of the two")
    ports = {role: opts.base_port + PORT_OFFSET[role] for role in roles}
    if max(ports.values()) > 65535:
        raise UsageError(f"--base-port {opts.base_port}: {', '.join(roles)} would need UDP ports up to "
                         f"{max(ports.values())}, above 65535")
    own = {role: role_args(role, opts) for role in roles}
    # where each listens: the rig's --host, or the last one its --ROLE-arg gives (as argparse keeps it)
    hosts = {role: ServicePlan(role, ports[role], ["--host", opts.host, *own[role]]).host for role in roles}
    check_families(hosts, opts.host)
    # the rig name the services announce: --rig, else their BATTEUR_RIG (one a service would refuse: not in the id)
    env_rig = (os.environ if environ is None else environ).get("BATTEUR_RIG", "")
    id_rig = getattr(opts, "rig", None) or (env_rig if re.fullmatch(r"[A-Za-z0-9_.-]{1,32}", env_rig) else DEFAULT_RIG)
    plans: list[ServicePlan] = []
    for role in roles:
        args = ["--host", opts.host, "--epoch", repr(epoch), "--node-id", rig_node_id(role, opts.base_port, id_rig)]
        if getattr(opts, "rig", None):  # else the services' own BATTEUR_RIG, or the one shared default
            args += ["--rig", opts.rig]
        if not opts.no_static_peers:
            for other in roles:
                if other != role:
                    args += ["--peer", f"{other}={peer_host(hosts[other])}:{ports[other]}"]
        # BATTEUR_PEERS adds to the --peer the node is given (the rig's, its --ROLE-arg's), which would replace it;
        # not a peer of a role the rig starts (its own service of it is the one to follow): main says which
        given = [*option_values(args, "--peer"), *option_values(own[role], "--peer")]
        for spec in environment_peers(given, environ, started=roles):
            args += ["--peer", spec]
        # A role not started is absent (no "no graphics peer known" every minute) only where no node of it can be
        # expected: with no discovery, or with this service on loopback (a node of it would be one started apart on
        # this machine, still found and sent to), and no static peer of it among those the node will hold: its
        # settings' (node_peer_roles), --peer's, else BATTEUR_PEERS's or its config file's (until the day after
        # 7 Dec only --ROLE-arg's --peer counted: a graphics peer in BATTEUR_PEERS was told absent). Discovery on a
        # LAN may find it on another machine (docs/deployment.md's sound on laptop B): if it fails, the warning says so.
        rig_peers = [args[i + 1] for i, arg in enumerate(args) if arg == "--peer"]
        own_peers = node_peer_roles([*rig_peers, *option_values(own[role], "--peer")], own[role], role, environ)
        try:
            on_loopback = hosts[role] == "localhost" or ipaddress.ip_address(hosts[role]).is_loopback
        except ValueError:  # a host name
            on_loopback = False
        if opts.no_discovery or on_loopback:
            args += [arg for left_out in ROLES if left_out not in roles and left_out not in own_peers
                     for arg in ("--absent", left_out)]
        if opts.no_discovery:
            args += ["--no-discovery"]
        else:
            for interface in filter(None, (i.strip() for i in opts.interfaces.split(","))):
                args += ["--interface", interface]
        if opts.log_level:
            args += ["--log-level", opts.log_level]
        if getattr(opts, "kit", None):  # every service: physics builds it, interaction maps it, sound voices it
            args += ["--kit", opts.kit]
        args += own[role]
        plans.append(ServicePlan(role, ports[role], args))
    return plans


def rig_name(text: str) -> str:
    """A ``--rig`` name: 1-32 letters, digits, ``_ . -`` (it travels in the nodes' zeroconf TXT record)."""
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,32}", text):
        raise argparse.ArgumentTypeError(f"{text!r}: a rig name is 1-32 letters, digits, '_', '.' or '-' (e.g. class2)")
    return text


def rig_node_id(role: str, base_port: int, rig: str = DEFAULT_RIG) -> str:
    """The node id of the rig's ``role`` service: ``ROLE-HOSTNAME-rigPORT``, ``ROLE-HOSTNAME-RIG-rigPORT`` for a rig
    not of the default name (at most 64 characters: the host part is shortened). Unique per machine (its host name),
    per rig on it (its base port) and per ``--rig``: until 8 Dec it was ``ROLE-rigPORT``, so two classes' rigs on one
    network announced the same names; the second's discovery failed to start. Laptops imaged alike share a host name
    (``ubuntu``): the rig name tells their nodes apart. A host name whose characters were replaced (not letters,
    digits, ``_ . -``) gets a short hash of the raw name: every all-non-ASCII name would otherwise be ``host``."""
    raw = socket.gethostname().split(".")[0]
    host = re.sub(r"[^A-Za-z0-9_.-]+", "-", raw).strip("-.") or "host"
    if host != raw:
        host += "-" + hashlib.blake2s(raw.encode("utf-8", "surrogateescape"), digest_size=3).hexdigest()
    suffix = (f"-{rig}" if rig != DEFAULT_RIG else "") + f"-rig{base_port}"
    return f"{role}-{host}"[: 64 - len(suffix)] + suffix


def check_families(hosts: Mapping[str, str], rig_host: str) -> None:
    """Raise UsageError when ``hosts`` (role -> the address it listens on) mix IPv4 and IPv6 addresses: a service
    on one could not send to one on the other (a host name is left to the services to resolve)."""
    versions = {}
    for role, host in hosts.items():
        with contextlib.suppress(ValueError):
            versions[role] = ipaddress.ip_address(host).version
    if len(set(versions.values())) > 1:
        named = ", ".join(f"{role} on {hosts[role]}" for role in versions)
        raise UsageError(f"--host {rig_host} and a --ROLE-arg --host mix IPv4 and IPv6 ({named}): the services could "
                         "not send to each other; give them addresses of one kind")


def asking_host(plans: Sequence[ServicePlan]) -> str:
    """Where the rig's asking socket (:class:`ReadyWait`) listens: :func:`peer_host` of the first service's address,
    preferring one given as an IP address. A socket of one family cannot send to the other, and its Hellos were lost
    without a word (``--host 127.0.0.1 --physics-arg '--host ::1'``: physics never up); :func:`check_families`
    leaves the services one family. Without a ``--ROLE-arg --host``: :func:`peer_host` of the rig's ``--host``."""
    hosts = [peer_host(plan.host) for plan in plans]
    for host in hosts:
        with contextlib.suppress(ValueError):
            ipaddress.ip_address(host)
            return host
    return hosts[0]


def role_args(role: str, opts: argparse.Namespace) -> list[str]:
    """Arguments specific to one role: what to play, where to record, plus pass-through."""
    args: list[str] = []
    if role == "physics":
        if getattr(opts, "score", None):
            args += ["--score", str(Path(opts.score).resolve()), "--play-at", repr(opts.play_at)]
        if opts.strike_period:
            args += ["--scene", "strike", "--strike-period", repr(opts.strike_period),
                     "--strike-velocity", repr(opts.strike_velocity)]
    if role in ("physics", "graphics"):  # they read scores: --score and the library, --preview-score
        args += midi_service_args(opts)
    if role == "sound" and opts.record:
        args += ["--wav", str(Path(opts.record) / RECORDING)]
    if role == "graphics":
        args += ["--http-port", str(opts.http_port)]
    if role == "graphics" and getattr(opts, "kit_dir", None):
        args += ["--kit-dir", str(Path(opts.kit_dir).resolve())]
    extra = [arg for item in getattr(opts, f"{role}_arg") or [] for arg in _split_role_arg(role, item)]
    refuse_rig_options(role, args, extra)
    return args + extra


def _split_role_arg(role: str, item: str) -> list[str]:
    """One ``--ROLE-arg`` value split as a shell would (``--sound-params '/tmp/a b/p.yaml'``: one path; until 7 Dec
    split on spaces, so a path with one could not be given); UsageError for an unclosed quote."""
    try:
        return shlex.split(item)
    except ValueError as exc:
        raise UsageError(f"--{role}-arg {item!r}: {exc.args[0].lower()} (it is split as a shell would)") from None


def refuse_rig_options(role: str, given: Sequence[str], extra: Sequence[str]) -> None:
    """Raise UsageError when ``extra`` (``--ROLE-arg`` of ``role``) gives an option the rig gives that service
    (``given``: its role's own; :data:`RIG_GIVES`), abbreviated too, as its argparse reads it: the last wins, so the
    service's would silently override the rig's, and its peers, the rig's checks and Hellos and the other services
    would talk to another port or play another score than the rig's."""
    kits = option_uses(extra, "--kit")
    if kits:
        # refused, not warned: every service plays the rig's one kit (physics strikes it, sound voices it, graphics
        # draws it, interaction maps it); one given its own would hit drums the others do not have or place, in
        # silence but for a warning lost among four services' start-up lines. --kit gives it to all.
        name, kit = kits[-1]
        raise UsageError(f"--{role}-arg: {_as_written(name, '--kit')} {kit} would give {role} a kit of its own, "
                         f"another than the other services'; give every service that kit with the rig's --kit {kit}")
    mirrored = option_uses(extra, "--left-handed") if role == "physics" else []  # only physics has it
    if mirrored:
        # refused as --kit is: physics would strike the kit mirrored while graphics draws it, interaction maps it
        # and sound voices it unmirrored (until 7 Dec accepted)
        raise UsageError(f"--{role}-arg: {_as_written(mirrored[-1][0], '--left-handed')} would mirror the kit "
                         f"{role} plays but not the one the other services draw, map and voice; give every service "
                         "a mirrored kit with the rig's --kit left_handed (the default kit mirrored; a kit file of "
                         "your own: its mirrored copy, Kit.mirrored(), docs/score-format.md \"Kits\")")
    for flag, (what, instead) in RIG_GIVES.items():
        uses = option_uses(extra, flag)
        if uses and (flag in ALWAYS_REFUSED or option_uses(given, GIVEN_AS.get(flag, flag))):
            name, value = uses[-1]
            written = " ".join(filter(None, (_as_written(name, flag), value)))
            raise UsageError(f"--{role}-arg: {written} would {what.format(role=role)}; "
                             f"{instead.format(value=value)}")


def _as_written(name: str, flag: str) -> str:
    """An option as a ``--ROLE-arg`` gave it: ``flag``, or ``name`` said to be its abbreviation."""
    return flag if name == flag else f"{name} ({flag}, as argparse takes it abbreviated)"


def describe_exit(code: int) -> str:
    """How a service ended, from its exit code (negative: the signal that killed it)."""
    if code >= 0:
        return f"exited with code {code}"
    try:
        return f"was killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"was killed by signal {-code}"


def stop_with_the_rig() -> Callable[[], None] | None:
    """What a child runs before it starts its service, so the service gets SIGTERM when the rig dies, even by
    SIGKILL (Linux's PR_SET_PDEATHSIG; the rig's own handlers cover every other ending). None where there is no
    prctl: there a rig killed with SIGKILL leaves its services running."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl  # looked up here: the child only calls it
    except (OSError, AttributeError):
        return None
    rig_pid = os.getpid()

    def arm() -> None:
        prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        if os.getppid() != rig_pid:  # the rig died before the signal was armed
            os._exit(1)

    return arm


@dataclass(frozen=True)
class ReadyWait:
    """The rig asks every service it started for its Health until all have answered, says what it waits for and
    when they are up, and, with ``--score``, stops (exit 1) when ``timeout_s`` from launch runs out first."""

    timeout_s: float
    """``--ready-timeout``, seconds from launch."""
    host: str
    """Where the rig's asking socket listens (:func:`asking_host`: in its services' address family); each service is
    asked at :func:`peer_host` of its own :attr:`ServicePlan.host`."""
    epoch: float
    """The rig epoch, Unix seconds: rig time is wall time less it, as on the services' clocks (one machine)."""
    play_at_s: float | None
    """``--play-at``: the rig time the score starts at if physics is up by then, seconds; None: no ``--score`` (the
    rig then only says when its services are up, and warns but runs on past the timeout)."""


class _Answers(asyncio.DatagramProtocol):
    """The Health answers of the rig's services (only datagrams from their ports count)."""

    def __init__(self, roles: dict[int, str], epoch: float, up: dict[str, float] | None = None) -> None:
        self.roles = roles
        """UDP port -> role of each service."""
        self.epoch = epoch
        """The rig epoch, Unix seconds."""
        self.up: dict[str, float] = {} if up is None else up
        """Role -> rig time it first answered, seconds (``up``: the :attr:`Rig.up` it fills)."""
        self.heard = asyncio.Event()
        """Set on each new answer; the rig clears it before it waits."""
        self.error: OSError | None = None
        """The socket's last error (:meth:`error_received`); the rig clears it before each Hello it sends."""
        self.unsent: dict[str, tuple[str, str, int]] = {}
        """Role -> (address, why, how many) of the Hellos to it that could not be sent (:meth:`send`)."""
        self.discovery: dict[str, int] = {}
        """Role -> its latest Health's ``discovery`` (off, on, starting, failed): the rig asks one still starting
        again, and its ready line names those whose discovery failed."""

    def error_received(self, exc: Exception) -> None:
        # a send that failed at once (asyncio's sendto calls this within it), or a receive's
        if isinstance(exc, OSError):
            self.error = exc

    def send(self, transport: asyncio.DatagramTransport, data: bytes, role: str, address: tuple[str, int]) -> str:
        """Send ``data`` to ``role`` at ``address``; what the socket said when it could not (a wrong-family or
        unreachable address: EAFNOSUPPORT, ENETUNREACH, EADDRNOTAVAIL, ...), counted in :attr:`unsent`, else ""."""
        from common.transport import format_address

        self.error = None
        transport.sendto(data, address)
        if self.error is None:
            return ""
        why = socket_error(self.error)
        _, _, count = self.unsent.get(role, ("", "", 0))
        self.unsent[role] = (format_address(*address), why, count + 1)
        return why

    def datagram_received(self, data: bytes, addr: tuple[str | Any, int]) -> None:
        from common.messages import Health, decode
        from common.runtime import DISCOVERY_STARTING

        role = self.roles.get(addr[1])
        if role is None or (role in self.up and self.discovery.get(role) != DISCOVERY_STARTING):
            return
        health = next((m for m in decode(data).messages if isinstance(m, Health) and m.role == role), None)
        if health is not None:
            self.discovery[role] = health.discovery
            self.up.setdefault(role, time.time() - self.epoch)
            if health.discovery != DISCOVERY_STARTING:  # else asked again in READY_POLL_S, not at once
                self.heard.set()

    async def wait(self, timeout_s: float) -> None:
        """Until a service answers or ``timeout_s`` seconds have passed."""
        self.heard.clear()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.heard.wait(), max(0.0, timeout_s))


def socket_error(exc: OSError) -> str:
    """What a socket error says, with its errno's name (``Network is unreachable (ENETUNREACH)``; an address of the
    other family, a getaddrinfo error: ``(EAI_ADDRFAMILY)``)."""
    names = errno.errorcode if not isinstance(exc, socket.gaierror) else {
        getattr(socket, name): name for name in dir(socket) if name.startswith("EAI_")}
    name = names.get(exc.errno) if exc.errno is not None else None
    text = exc.strerror or str(exc)
    return f"{text} ({name})" if name else text


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless the count is 1 ("1 Hello", "3 Hellos")."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def up_line(plans: Sequence[ServicePlan], up: Mapping[str, float], elapsed_s: float, play_at_s: float | None,
            environ: Mapping[str, str] | None = None, discovery_failed: Sequence[str] = ()) -> str:
    """:func:`ready_line`, where ``discovery_failed`` names the services whose discovery failed to start: then not
    "ready" but what they cannot do, and what to check (until 8 Dec the rig said "ready" while the second class's
    rig on a network, its node ids those of the first's, found no sound node: its speakers stayed silent)."""
    line = ready_line(plans, up, elapsed_s, play_at_s, environ)
    if not discovery_failed:
        return line
    names = ", ".join(discovery_failed)
    whose = "its" if len(discovery_failed) == 1 else "their"
    warning = (f"; but discovery (zeroconf) failed to start on {names} (see {whose} ERROR line): they find no node "
               "on another machine, only this rig's own services (a node of the same id already on the network? "
               "docs/deployment.md, \"Two classes, two rigs on one network\")")
    return line.replace(": ready;", ": running, not ready;", 1).rstrip("\n") + warning + "\n"


def ready_line(plans: Sequence[ServicePlan], up: Mapping[str, float], elapsed_s: float, play_at_s: float | None,
               environ: Mapping[str, str] | None = None) -> str:
    """What the rig says once every service is up (``up``: role -> rig time it answered, seconds; ``elapsed_s``:
    seconds since launch): with ``--score`` (``play_at_s``), whether one was up only after the score's time;
    without, where to send what to play: physics' address, with a wildcard ``--host`` loopback's and that it
    listens on every interface; physics not in the rig, the static peer its services send to
    (:func:`node_static_peers`: ``--peer``, ``BATTEUR_PEERS``, a config file; ``environ``: the services' environment,
    None: the rig's), else that the rig does not start it (until the day after 7 Dec it said "ready" alone)."""
    from common.transport import format_address

    line = f"batteur rig: services up {elapsed_s:.1f} s after launch (rig time {max(up.values()):.1f} s)"
    if play_at_s is None:
        send = "send /batteur/score/load NAME or /batteur/score/note"
        physics = next((plan for plan in plans if plan.role == "physics"), None)
        if physics is not None:
            local = peer_host(physics.host)
            # a wildcard (0.0.0.0, ::): loopback's address works here only; said so, once
            anywhere = (f"from another machine, this machine's address: --host {physics.host} listens on every "
                        "interface; " if local != physics.host else "")
            return (line + f": ready; {send} to physics at {format_address(local, physics.port)} ({anywhere}"
                    "docs/live-control.md)\n")
        for plan in plans:
            peers, source = node_static_peers(option_values(plan.args, "--peer"), plan.args, plan.role, environ)
            known = next((peer for peer in peers if peer.role == "physics"), None)
            env = os.environ if environ is None else environ
            if known is not None and source == "--peer" and any(  # added to the rig's --peer (environment_peers)
                    spec.strip() == f"{known.role}={format_address(known.host, known.port)}"
                    for spec in (env.get("BATTEUR_PEERS") or "").split(",")):
                source = "BATTEUR_PEERS"
            if known is not None:
                return (line + f": ready; physics is not started by this rig: {send} to it at "
                        f"{format_address(known.host, known.port)} ({plan.role}'s static peer, {source}; "
                        "docs/live-control.md)\n")
        return line + ": ready; physics is not started by this rig (batteur ls lists the nodes it finds)\n"
    late = [role for role, t in up.items() if t > play_at_s]
    if "physics" in late:
        line += (f"; physics only after --play-at {play_at_s:g} s: it starts the score as soon as it can, "
                 "from its first note")
    elif late:
        line += f"; {', '.join(late)} only after --play-at {play_at_s:g} s, when the score started"
    return line + "\n"


class Output:
    """The rig's lines to one stream. Once the stream is gone (``batteur rig | head``, a closed terminal) lines are
    dropped, so the rig still drains the services' output (a service blocked on a full pipe would not stop) and
    still stops them."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.broken = False

    def write(self, text: str) -> None:
        if self.broken:
            return
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # BrokenPipeError; ValueError: the file was closed
            self.broken = True
            point_at_devnull(self.stream)


class Rig:
    """Runs the planned services and stops them together."""

    LINE_LIMIT = 1 << 20
    """Longest service output line read whole, bytes (a longer one is dropped, reading goes on)."""

    def __init__(self, plans: list[ServicePlan], stop_timeout_s: float,
                 out: TextIO | None = None, err: TextIO | None = None, ready: ReadyWait | None = None) -> None:
        self.plans = plans
        self.ready = ready
        """Wait for the services to be up, and say so (None: the rig does not ask them)."""
        self.gave_up = False
        """The services were not all up within the ready timeout (or could not be asked): the rig stopped."""
        self.stop_timeout_s = stop_timeout_s
        self.out = Output(out or sys.stdout)
        self.err = Output(err or sys.stderr)
        self.procs: dict[str, asyncio.subprocess.Process] = {}
        self.stopping = asyncio.Event()
        self.exit_codes: dict[str, int] = {}
        self.failures: dict[str, int] = {}
        """Services that ended on their own with a non-zero code or could not start, in the order they did."""
        self.lost: dict[str, int] = {}
        """:data:`OPTIONAL_ROLES` that exited on their own while the others played on: role -> exit code."""
        self.up: dict[str, float] = {}
        """Role -> rig time it first answered the rig's Hello, seconds (:meth:`_wait_ready`; empty without
        ``ready``). Only an :data:`OPTIONAL_ROLES` service that was up (or :attr:`past_start`) plays on without it
        when it exits: one that exits before (a typo in ``--graphics-arg``) is a mistake in how the rig was started,
        which stops it."""
        self.past_start: set[str] = set()
        """:data:`OPTIONAL_ROLES` still running when the ready wait ended with the rig running on (no ``--score``:
        past ``--ready-timeout``, or the services could not be asked) without their answer: counted as up, past their
        start (the rig listens no more; until the day after 7 Dec a graphics answering only then, killed mid-show,
        stopped physics, interaction and sound "before it was up")."""
        self.arm_child = stop_with_the_rig()
        self.said: dict[str, set[str]] = {}
        """Role -> what its output said of its start and stop (:data:`SAID`): the rig's timeout and stop messages
        name it (a physics compiling its kernels; a service that said it was stopping yet had not exited)."""

    async def _pump(self, role: str, stream: asyncio.StreamReader | None, to: Output) -> None:
        """Copy a service's output to ``to``, line by line with its role in front (one write each: whole lines)."""
        if stream is None:
            return
        width = max(len(p.role) for p in self.plans)
        while True:
            try:
                line = await stream.readline()
            except ValueError:  # a line over LINE_LIMIT (asyncio drops it); keep reading so the service never blocks
                continue
            if not line:
                return
            text = line.decode(errors="replace")
            for key, (mark, until) in SAID.items():
                if mark in text:
                    self.said.setdefault(role, set()).add(key)
                elif until and until in text:
                    self.said.get(role, set()).discard(key)
            # a last line cut short is ended here, else the next line written would be glued to it
            to.write(f"[{role:<{width}}] {text}" + ("" if text.endswith("\n") else "\n"))

    def was_up(self, role: str) -> bool:
        """Whether ``role`` answered the rig's Hello (:attr:`up`) or ran past the ready wait (:attr:`past_start`)."""
        return role in self.up or role in self.past_start

    def _past_start(self) -> None:
        """The ready wait ends with the rig running on: every :data:`OPTIONAL_ROLES` service still running is past
        its start (:attr:`past_start`)."""
        self.past_start.update(role for role, proc in self.procs.items() if role in OPTIONAL_ROLES
                               and proc.returncode is None and role not in self.exit_codes)

    async def _watch(self, role: str, proc: asyncio.subprocess.Process) -> None:
        code = await exited(proc)
        self.exit_codes[role] = code
        if not self.stopping.is_set():
            if code != 0:
                self.failures.setdefault(role, code)
            running = [r for r, p in self.procs.items() if r != role and p.returncode is None]
            # the view is not worth the show, once it was on: one that ends before it answered the rig's Hello, or
            # refuses its options (2), says the rig was started wrong, which should fail fast (until the day after
            # 7 Dec the others played on, and the rig said its services were up "but graphics, which exited")
            optional = role in OPTIONAL_ROLES and running
            if optional and self.was_up(role) and code != USAGE:
                self.lost[role] = code
                # the code it will exit with: exit_code's, this role's (the first failure: another stops the rig)
                will = f"; it will exit {code if code > 0 else 1}: {role} failed" if code else ""
                self.err.write(f"batteur rig: {role} {describe_exit(code)}; {', '.join(running)} play on without "
                               f"it (Ctrl-C stops the rig{will})\n")
            else:
                why = will = ""
                if optional:  # why this one stops the show where a graphics that was up would not
                    why = " before it was up" if not self.was_up(role) else ""
                    why += " (it refused its options)" if code == USAGE else ""
                    if code == 0:  # not up, yet "success": a script's `batteur rig ... && next` would go on
                        self.failures.setdefault(role, FAILED)
                        will = f" (it will exit {FAILED}: {role} ended before it was up)"
                self.err.write(f"batteur rig: {role} {describe_exit(code)}{why}; stopping the rig{will}\n")
                self.stopping.set()
        await end_group(proc.pid)

    async def _start(self, plan: ServicePlan) -> asyncio.subprocess.Process | None:
        try:
            proc = await asyncio.create_subprocess_exec(
                *plan.argv(), stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
                start_new_session=True,  # Ctrl-C reaches the rig only; the rig stops the children in order
                preexec_fn=self.arm_child,
                limit=self.LINE_LIMIT,
            )
        except OSError as exc:
            self.err.write(f"batteur rig: cannot start {plan.role}: {exc.strerror or exc}; stopping the rig\n")
            self.failures[plan.role] = 1
            self.stopping.set()  # as a service exiting: those started are stopped (they ran on, said nothing more)
            return None
        self.out.write(f"batteur rig: started {plan.role} (pid {proc.pid}) on UDP port {plan.port}\n")
        return proc

    async def run(self, duration_s: float | None) -> int:
        """Start the services, run until a stop signal, ``duration_s`` or a service ending; the exit code."""
        loop = asyncio.get_running_loop()
        launched = time.monotonic()
        for sig in STOP_SIGNALS:
            loop.add_signal_handler(sig, self.stopping.set)
        tasks: list[asyncio.Task[None]] = []
        waiting: asyncio.Task[None] | None = None
        try:  # whatever happens here, the services started are stopped: none is left running
            for plan in self.plans:
                if self.stopping.is_set():  # stopped while starting: start no more
                    break
                proc = await self._start(plan)
                if proc is None:
                    break
                self.procs[plan.role] = proc
                tasks.append(asyncio.create_task(self._pump(plan.role, proc.stdout, self.out)))
                tasks.append(asyncio.create_task(self._pump(plan.role, proc.stderr, self.err)))
                tasks.append(asyncio.create_task(self._watch(plan.role, proc)))
            if self.ready is not None and len(self.procs) == len(self.plans) and not self.stopping.is_set():
                waiting = asyncio.create_task(self._wait_ready(self.ready, launched))
            try:
                await asyncio.wait_for(self.stopping.wait(), timeout=duration_s)
            except TimeoutError:
                pass
        finally:
            self.stopping.set()
            if waiting is not None:
                waiting.cancel()
                await asyncio.gather(waiting, return_exceptions=True)
            await self.stop()
            await self.drain(tasks)
        failed = {role: code for role, code in self.lost.items() if code}
        if failed:  # said again at the end: the line it exited on may be far up a long set's log
            self.err.write("batteur rig: " + "; ".join(f"{role} {describe_exit(code)} during the run"
                                                       for role, code in failed.items()) + "\n")
        return self.exit_code()

    async def _wait_ready(self, ready: ReadyWait, launched: float) -> None:
        """Send each service a Hello every :data:`READY_POLL_S` until it answers with its Health, with a line every
        :data:`READY_PROGRESS_S` naming those not up, and one when all are (a service that exited is waited for no
        more); past ``ready.timeout_s`` from launch (``launched``: ``time.monotonic()`` then), with ``--score`` stop
        the rig with an error naming them, without it warn and run on."""
        from common.messages import PROTOCOL_VERSION, Hello, encode
        from common.messages.system import TOOL_ROLE
        from common.runtime import DISCOVERY_STARTING

        loop = asyncio.get_running_loop()
        roles = {plan.port: plan.role for plan in self.plans}
        try:
            transport, answers = await loop.create_datagram_endpoint(lambda: _Answers(roles, ready.epoch, self.up),
                                                                     local_addr=(ready.host, 0))
        except OSError as exc:
            if ready.play_at_s is None:  # no score waits on them: said, and the rig runs on (as past the timeout)
                self.err.write(f"batteur rig: warning: cannot ask the services whether they are up: "
                               f"{exc.strerror or exc}; the rig runs on (batteur ls tells when they answer)\n")
                # graphics failing at start-up (its HTTP port taken) still stops the rig until the timeout, as when
                # asked; one running then is past its start
                await asyncio.sleep(max(0.0, ready.timeout_s - (time.monotonic() - launched)))
                self._past_start()
                return
            self._give_up(f"cannot ask the services whether they are up: {exc.strerror or exc}")
            return
        try:
            # a tool asking, not a node: the graphics view does not list it
            hello = encode(Hello(role=TOOL_ROLE, node_id="batteur-rig", protocol=PROTOCOL_VERSION,
                                 osc_port=transport.get_extra_info("sockname")[1]))
            next_line = launched + READY_PROGRESS_S
            # a service that exited is waited for no more (it stops the rig: the wait is cancelled)
            # up, and its discovery done starting (registration takes about a second): the ready line says if it failed
            while waiting := [plan for plan in self.plans if plan.role not in self.exit_codes and (
                    plan.role not in answers.up or answers.discovery.get(plan.role) == DISCOVERY_STARTING)]:
                elapsed = time.monotonic() - launched
                names = ", ".join(plan.role for plan in waiting)
                if elapsed >= ready.timeout_s:
                    unsent = "".join(f"; the {counted(count, 'Hello')} to {role} at {address} could not be sent: {why}"
                                     for role, (address, why, count) in answers.unsent.items()
                                     if role not in answers.up)
                    hint = self.ready_hint([plan.role for plan in waiting], ready.timeout_s)
                    if ready.play_at_s is None:  # no score waits on them: said, and the rig runs on
                        self.err.write(f"batteur rig: warning: {names} not up within --ready-timeout "
                                       f"{ready.timeout_s:g} s of launch (no answer to a Hello{unsent}); the rig runs "
                                       f"on (batteur ls tells when they answer){hint}\n")
                        self._past_start()
                        return
                    self._give_up(f"{names} not up within --ready-timeout {ready.timeout_s:g} s of launch (no answer "
                                  f"to a Hello{unsent}); stopping the rig{hint}")
                    return
                if time.monotonic() >= next_line:
                    self.out.write(f"batteur rig: waiting for {names} to start ({elapsed:.0f} s since launch; "
                                   f"--ready-timeout {ready.timeout_s:g} s)\n")
                    next_line += READY_PROGRESS_S
                for plan in waiting:  # where it listens: a service with its own --host (--ROLE-arg) there
                    address = (peer_host(plan.host), plan.port)
                    told = plan.role in answers.unsent
                    why = answers.send(transport, hello, plan.role, address)
                    if why and not told:  # at once, and once a service: it was only "no answer" at the timeout
                        self.err.write(f"batteur rig: warning: cannot send {plan.role} a Hello at "
                                       f"{answers.unsent[plan.role][0]}: {why}; trying until --ready-timeout "
                                       f"{ready.timeout_s:g} s\n")
                await answers.wait(min(READY_POLL_S, ready.timeout_s - elapsed))
        finally:
            transport.close()
        # a service that exited stops the rig (graphics before it was up too: every one left answered)
        if answers.up and not self.stopping.is_set():
            from common.runtime import DISCOVERY_FAILED

            failed = [plan.role for plan in self.plans if answers.discovery.get(plan.role) == DISCOVERY_FAILED]
            self.out.write(up_line(self.plans, answers.up, time.monotonic() - launched, ready.play_at_s,
                                   discovery_failed=failed))

    def ready_hint(self, waiting: Sequence[str], timeout_s: float) -> str:
        """What to do about services not up within ``timeout_s`` (``waiting``: their roles): give them longer, with
        the reason physics' output gave (compiling its kernels: a walkthrough's first run, load 13, took 140 s of
        the 60 s default and said nothing of it)."""
        more = f"--ready-timeout {max(240.0, 4 * timeout_s):g}"
        if "compiling" in self.said.get("physics", set()) and "physics" in waiting:
            return (f". physics was still compiling its kernels (no numba cache yet: the first run after an install "
                    f"or an update; cached after, or done ahead by `python3 -m services.physics.precompile`): give "
                    f"it longer, e.g. {more}")
        first = ", the first run after an install compiling the physics kernels," if "physics" in waiting else ""
        return f". A loaded machine{first} may need longer: e.g. {more}"

    def _give_up(self, reason: str) -> None:
        """Stop the rig over ``reason`` (one error line; exit 1 unless a service failed first)."""
        self.gave_up = True
        self.err.write(f"batteur rig: error: {reason}\n")
        self.stopping.set()

    async def drain(self, tasks: list[asyncio.Task[None]]) -> None:
        """Wait for the output readers, at most :data:`DRAIN_S` seconds (every service has exited), then drop
        them: a grandchild holding a service's output open must not keep the rig running."""
        if not tasks:
            return
        _, pending = await asyncio.wait(tasks, timeout=DRAIN_S)
        for task in pending:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        for proc in self.procs.values():  # the pipes a grandchild still holds: closed on the rig's side
            transport = getattr(proc, "_transport", None)
            if transport is not None:
                transport.close()

    def stopped_cleanly(self, role: str) -> bool:
        """Whether the service ran and stopped cleanly when the rig stopped it."""
        return role not in self.failures and self.exit_codes.get(role) in CLEAN_STOP

    def exit_code(self) -> int:
        """0 when every service stopped cleanly; else the code of the first that failed (2: it refused its
        options), or 1 (it was killed, or the services were not all up within the ready timeout)."""
        failed = [*self.failures.values(), *(c for r, c in self.exit_codes.items() if not self.stopped_cleanly(r)
                                             and r not in self.failures)]
        if not failed:
            return FAILED if self.gave_up else 0
        return failed[0] if failed[0] > 0 else 1

    async def stop(self) -> None:
        """SIGTERM every child, wait up to the stop timeout, then SIGKILL the rest; then end what each left in its
        process group (:func:`end_group`).

        SIGTERM, not SIGINT: a node handles both the same, but a service still loading ends quietly on SIGTERM,
        where SIGINT would print a KeyboardInterrupt traceback (or "Fatal Python error" during interpreter start).
        """
        for proc in self.procs.values():
            if proc.returncode is None:
                with contextlib.suppress(ProcessLookupError):
                    proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + self.stop_timeout_s
        for role, proc in self.procs.items():
            remaining = max(0.0, deadline - time.monotonic())
            try:
                await asyncio.wait_for(exited(proc), timeout=remaining)
            except TimeoutError:
                # what it said agrees with what the rig says (a physics stopped while compiling logged "stopped
                # cleanly" and then the rig "did not stop in 4 s; killing it")
                said = self.said.get(role, set())
                why = (" (it said it was stopping, but had not exited)" if "stopping" in said
                       else " (it was compiling its kernels, which it stops only between two)" if "compiling" in said
                       else "")
                self.err.write(f"batteur rig: {role} did not exit within --stop-timeout {self.stop_timeout_s:g} s of "
                               f"SIGTERM{why}; killing it\n")
                with contextlib.suppress(ProcessLookupError):
                    proc.kill()
                await exited(proc)
        await asyncio.gather(*(end_group(proc.pid) for proc in self.procs.values()))


async def exited(proc: asyncio.subprocess.Process) -> int:
    """A service's exit code once it has exited. Not ``proc.wait()``: before Python 3.12 that also waits for the
    service's output pipe to close, which a grandchild that outlived it may hold open for good."""
    while proc.returncode is None:
        await asyncio.sleep(EXIT_POLL_S)
    return proc.returncode


async def end_group(pgid: int) -> None:
    """Stop what is left in an exited service's process group (each service leads its own session): children that
    outlived it (planning processes, a resource tracker) would run on as orphans and hold the rig's output pipe.
    SIGTERM first: planning processes end on it, and a resource tracker (which ignores it) then ends by itself,
    once it has removed the semaphores a killed service left; SIGKILL for what is left after
    :data:`GROUP_GRACE_S`."""
    if not signal_group(pgid, signal.SIGTERM):
        return
    deadline = time.monotonic() + GROUP_GRACE_S
    while group_alive(pgid) and time.monotonic() < deadline:
        await asyncio.sleep(EXIT_POLL_S)
    signal_group(pgid, signal.SIGKILL)


def signal_group(pgid: int, sig: int) -> bool:
    """Send ``sig`` to the process group ``pgid``; False when the group is gone."""
    try:
        os.killpg(pgid, sig)
    except ProcessLookupError:
        return False
    except PermissionError:  # a member that is not the rig's user's: nothing the rig can stop
        return False
    return True


def group_alive(pgid: int) -> bool:
    """Whether a live process (not a zombie: an orphan's parent may never reap it) is in the process group."""
    proc = Path("/proc")
    if not proc.is_dir():  # no /proc to tell zombies apart: the group itself
        return signal_group(pgid, 0)
    for stat in proc.glob("[0-9]*/stat"):
        try:
            state, _, group = stat.read_text().rsplit(")", 1)[1].split()[:3]
        except (OSError, IndexError, ValueError):  # gone meanwhile
            continue
        if int(group) == pgid and state != "Z":
            return True
    return False


def port_number(text: str, lowest: int = 1) -> int:
    """A port, ``lowest`` to 65535."""
    value = whole(text)
    if not lowest <= value <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: give a port from {lowest} to 65535")
    return value


def port_or_any(text: str) -> int:
    """A TCP port, 1 to 65535, or 0: any free port."""
    return port_number(text, lowest=0)


def build_parser() -> argparse.ArgumentParser:
    from common.kit_help import kit_help

    parser = argparse.ArgumentParser(
        prog="batteur rig",
        description="Start the Batteur services as local processes (the embedded default rig). "
        "Ctrl-C stops them all; so does any service exiting, but for graphics (the view) once it was up: the others "
        "then play on without it (exit code: 0 after a clean stop, else the failing service's code, or 1 if killed). "
        "It says when every service it started is up.",
    )
    take_negative_values(parser)  # --play-at -1e-3: the value's own check says what is wrong with it
    parser.add_argument("--services", default=",".join(ROLES), metavar="ROLES",
                        help=f"comma-separated roles to start, each at most once (default: {','.join(ROLES)})")
    parser.add_argument("--base-port", type=port_number, default=9101, metavar="PORT",
                        help="UDP port of physics; interaction, sound, graphics take the next three "
                        "(default 9101, so 9101-9104)")
    parser.add_argument("--http-port", type=port_or_any, default=8080, metavar="PORT",
                        help="TCP port of the graphics view in the browser (default 8080; 0: any free port, "
                        "printed by graphics; a second rig on this machine needs another)")
    parser.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                        help="address the services listen on (default 127.0.0.1)")
    parser.add_argument("--no-discovery", action="store_true",
                        help="static peers only, no zeroconf (default: zeroconf on --interfaces too)")
    parser.add_argument("--no-static-peers", action="store_true",
                        help="find each other by zeroconf only (needs multicast on the interfaces; default: each "
                        "service also gets the others' ports, and BATTEUR_PEERS's peers of roles it does not start)")
    parser.add_argument("--interfaces", default="", metavar="ADDRESSES",
                        help="comma-separated addresses or interface names for zeroconf (default: loopback)")
    parser.add_argument("--rig", type=rig_name, default=None, metavar="NAME",
                        help="name of this rig, given to every service (default: BATTEUR_RIG, else one shared "
                        "name): nodes of another rig on the network are ignored; two classes on one network give "
                        "each rig its own name, the same on every laptop of it (docs/deployment.md)")
    parser.add_argument("--start-delay", type=non_negative, default=3.0, metavar="SECONDS",
                        help="seconds between launch and rig time 0 (default 3)")
    parser.add_argument("--duration", type=seconds, default=None, metavar="SECONDS",
                        help="stop after this many seconds of wall time from launch (default: run until Ctrl-C)")
    parser.add_argument("--stop-timeout", type=seconds, default=4.0, metavar="SECONDS",
                        help="seconds to wait for services to stop before killing them (default 4)")
    parser.add_argument("--record", type=Path, default=None, metavar="DIR",
                        help=f"sound writes what it plays to DIR/{RECORDING} (+ .json: rig time of its first "
                        "sample), named so only if sound stops cleanly (else it stays in a hidden part file, "
                        "named); DIR is created (default: no recording)")
    parser.add_argument("--strike-period", type=non_negative, default=0.0, metavar="SECONDS",
                        help="strike scene instead of a score: a strike every this many seconds of rig time "
                        "(default 0: off)")
    parser.add_argument("--strike-velocity", type=positive, default=3.0, metavar="M/S",
                        help="strike scene: tip speed, m/s (default 3)")
    parser.add_argument("--score", default=None, metavar="FILE",
                        help="the drummer plays this score live (.mid or text score; 'demo': the groove of "
                        "batteur demo; default: none, the drummer idles)")
    add_midi_arguments(parser.add_argument_group(
        "MIDI scores", "how physics reads MIDI files (--score's, and those /batteur/score/load loads from its score "
        "library: --score's folder, --physics-arg '--score-dir DIR') and graphics its --preview-score "
        "(--graphics-arg): given to both; --drum-map also maps live notes' pitches (/batteur/score/note, General MIDI "
        "without it); with none of these files --drum-channels and --hihat-cc4 act on nothing (said at start)"))
    parser.add_argument("--kit", default=None, metavar="NAME",
                        help=kit_help("--score's `kit` line, as batteur render reads it, else the default kit",
                                      "kit name or YAML/JSON file for every service")
                        + "; a --ROLE-arg may not give one its own, nor physics --left-handed (give --kit "
                        "left_handed, or a mirrored kit file)")
    parser.add_argument("--kit-dir", type=Path, default=None, metavar="DIR",
                        help="the graphics page's kit and pose editor saves its kits and poses (poses.yaml, which "
                        "graphics' keyframe preview reads) into DIR, created when it first saves; a kit saved there "
                        "plays with --kit DIR/NAME.yaml (default: saving off; the page says so on its save buttons)")
    parser.add_argument("--play-at", type=non_negative, default=1.0, metavar="SECONDS",
                        help="rig time at which --score starts, seconds after rig time 0 (default 1); physics up "
                        "only after it starts the score as soon as it can, from its first note")
    parser.add_argument("--ready-timeout", type=seconds, default=60.0, metavar="SECONDS",
                        help="seconds from launch the services get to be up (to answer a Hello); past it the rig "
                        "names those that are not, and with --score stops with an error (default 60; the first "
                        "run after an install compiles the physics kernels, minutes on a loaded machine: give it 240)")
    parser.add_argument("--log-level", type=str.upper, choices=("DEBUG", "INFO", "WARNING", "ERROR"), default=None,
                        help="log level for every service (default: theirs, INFO)")
    for role in ROLES:
        parser.add_argument(f"--{role}-arg", action="append", metavar="ARGS",
                            help=f"extra arguments for {role}, e.g. --{role}-arg='--log-level DEBUG' (repeatable; "
                            f"split as a shell would: quote a value with spaces, --{role}-arg=\"--wav 'a b.wav'\"; "
                            f"see batteur {role} --help); a --host (or --ho) there is where {role} "
                            "listens; what the rig gives every service (--port, --epoch, --kit, --role) or its "
                            "--score is refused, abbreviated too, naming the rig's own option to use")
    return parser


def check_score(opts: argparse.Namespace) -> Score | None:
    """Raise ValueError for a --score the rig cannot play (missing, broken or empty file, strike scene, no
    physics); the score read (None: no --score)."""
    if opts.score is None:
        return None
    if opts.strike_period:
        raise UsageError("--score and --strike-period exclude each other (the drummer or the strike scene)")
    roles = [r.strip() for r in opts.services.split(",")]
    if "physics" not in roles:
        raise UsageError("--score needs the physics service (--services)")
    from common.score.events import SCORE_FILE
    from common.score.text import read_score

    problem = file_problem(Path(opts.score), SCORE_FILE)  # a folder, a device, a pipe: said, never opened
    if problem is not None:
        raise ValueError(f"--score {opts.score}: {problem}")
    # ScoreError (a ValueError) for a broken file, before any service starts; read as physics reads it: a text
    # score's kit object ids (crash2) in --kit's kit when given (until 7 Dec its kit line's, else the default)
    score = read_score(opts.score, kit=_option_kit(opts.kit), **midi_read_kwargs(opts))
    if not score.events:
        raise ValueError(f"--score {opts.score}: no drum events to play")
    return score


def _option_kit(kit: str | None) -> Kit | None:
    """``--kit``'s kit, loaded (None without one); ValueError naming the option for one that cannot be loaded."""
    if kit is None:
        return None
    from common.kit import load_kit

    try:
        return load_kit(kit, warn=False)
    except (FileNotFoundError, ValueError) as exc:
        raise ValueError(f"--kit {kit}: {exc}") from None


def rig_kit(opts: argparse.Namespace, score: Score | None) -> str | None:
    """The kit every service starts with, as ``batteur render`` chooses it: ``--kit`` when given (the score's
    ``kit`` line is then not played; physics' log says so), else the ``kit`` line of ``score`` (a kit file's path
    taken from the score's folder, resolved), else None: the services' own default, the default kit. Raises
    ValueError for a kit that cannot be loaded (a ScoreError naming the line for the score's), before any service
    starts (each would stop on it)."""
    from common.kit import load_kit
    from common.score.events import ScoreError
    from common.score.text import load_score_kit, score_kit

    kit = opts.kit or score_kit(score)
    if kit is None:
        return None
    try:
        load_score_kit(score, opts.kit, opts.score, lambda name: load_kit(name, warn=False))
    except (FileNotFoundError, ValueError) as exc:  # --kit's: said as the option's
        if isinstance(exc, ScoreError):
            raise
        raise ValueError(f"--kit {opts.kit}: {exc}") from None
    if opts.kit is None and Path(kit).suffix:  # the score's kit file: the services' working folder may differ
        return str(Path(kit).resolve())
    return str(kit)


def plan_services(opts: argparse.Namespace, epoch: float) -> list[ServicePlan]:
    """:func:`plan_rig` once ``--score`` is checked (:func:`check_score`) and the kit chosen (:func:`rig_kit`,
    into ``opts.kit``)."""
    check_left_handed_env()
    opts.kit = rig_kit(opts, check_score(opts))
    return plan_rig(opts, epoch)


def check_left_handed_env(environ: Mapping[str, str] | None = None) -> None:
    """Raise :class:`UsageError` when the rig's environment sets BATTEUR_LEFT_HANDED: every service inherits it and
    physics alone reads it, so it would mirror the kit physics plays but not the one the others draw, map and voice
    (refused as ``--physics-arg --left-handed`` is: :func:`refuse_rig_options`; until 7 Dec it went through)."""
    from common.config import ENV_PREFIX

    env = os.environ if environ is None else environ
    value = env.get(f"{ENV_PREFIX}LEFT_HANDED", "").strip().lower()
    if value in ("1", "true", "t", "yes", "y", "on"):
        raise UsageError(f"{ENV_PREFIX}LEFT_HANDED={env[f'{ENV_PREFIX}LEFT_HANDED']} in the rig's environment would "
                         "mirror the kit physics plays but not the one the other services draw, map and voice; unset "
                         "it and give every service a mirrored kit with the rig's --kit left_handed (a kit file of "
                         "your own: its mirrored copy, Kit.mirrored(), docs/score-format.md \"Kits\")")


def check_allow(plans: Sequence[ServicePlan], host: str, environ: Mapping[str, str] | None = None) -> None:
    """Raise UsageError, as a service would refuse to start (exit 2) after the others had started, when it listens
    off loopback (:attr:`ServicePlan.host`: the rig's ``--host``, or its own in ``--ROLE-arg``, which wins) and no
    allow-list reaches it: not BATTEUR_ALLOW (which every service reads), nor its own ``--allow`` (``--ROLE-arg``).
    A config file (BATTEUR_CONFIG, ``--config``) may give one: that service checks it. The message names the
    services without one (``--physics-arg '--allow ...'`` leaves the others on ``--host 0.0.0.0`` without)."""
    from common.config import ENV_PREFIX, off_loopback_problem

    env = os.environ if environ is None else environ
    if env.get(f"{ENV_PREFIX}ALLOW", "").strip(" ,") or env.get(f"{ENV_PREFIX}CONFIG"):
        return
    lacking = [plan for plan in plans if off_loopback_problem(plan.host, [])
               and not any(option_values(plan.args, flag) for flag in ("--allow", "--config"))]
    if not lacking:
        return
    plan = lacking[0]
    problem = off_loopback_problem(plan.host, [])
    if plan.host != host:  # its own --host: said as the option that gave it
        raise UsageError(f"--{plan.role}-arg --host {plan.host}: {problem} (with it in --{plan.role}-arg, or "
                         "BATTEUR_ALLOW for every service of the rig)")
    on_rig_host = [p.role for p in lacking if p.host == host]
    named = ", ".join(on_rig_host)
    each = " and ".join(f"--{role}-arg" for role in on_rig_host)
    raise UsageError(f"{named} without an allow-list: {problem} (--allow in {each}, or for every service of the rig "
                     f"BATTEUR_ALLOW: BATTEUR_ALLOW=192.168.1.0/24 batteur rig --host {host} ...)")


def ignored_options(opts: argparse.Namespace) -> list[str]:
    """Warnings for options the rig was given but cannot use: ``--interfaces`` names zeroconf's interfaces
    (docs/discovery.md), so with ``--no-discovery`` it is ignored, wildcard or not."""
    if opts.no_discovery and opts.interfaces.strip(" ,"):
        return [f"--interfaces {opts.interfaces} is ignored with --no-discovery (it names the interfaces zeroconf "
                "uses; the services find each other by their static peers)"]
    return []


MIDI_READERS = {"physics": "--score-dir", "graphics": "--preview-score"}
"""What makes a service read MIDI files with the rig's MIDI options besides the rig's ``--score``: physics' score
library (``/batteur/score/load``), graphics' preview."""


def unread_midi_options(opts: argparse.Namespace, plans: Sequence[ServicePlan],
                        environ: Mapping[str, str] | None = None) -> str | None:
    """A warning when ``--drum-channels`` or ``--hihat-cc4`` was given and nothing will read a MIDI file with them:
    no MIDI ``--score``, no physics score library (``--physics-arg '--score-dir DIR'``, read by
    ``/batteur/score/load``), no graphics ``--preview-score``; live notes (``/batteur/score/note``) are read without
    them. Until 7 Dec they were given to physics and graphics in silence. Not ``--drum-map``: live notes follow it
    (since c6f810b; until 7 Dec this warned that it acted on nothing). A text ``--score``
    (``demo`` too) is read without them: then they act only on the MIDI files ``/batteur/score/load`` may load
    from its folder, said so (until 7 Dec nothing was). A library or a preview given a blank value
    (``--physics-arg=--score-dir=``: none) is none. None when a config file (BATTEUR_CONFIG, ``--config``) or the
    environment may give a library or a preview: those services read it, the rig does not."""
    from common.config import ENV_PREFIX

    given = [f"--drum-channels {','.join(str(c) for c in opts.drum_channels)}"] if opts.drum_channels else []
    given += ["--hihat-cc4"] if opts.hihat_cc4 else []  # --drum-map acts on live notes too: never in vain
    env = os.environ if environ is None else environ
    if not given or (opts.score and _midi_score(opts.score)) or env.get(f"{ENV_PREFIX}CONFIG", "").strip():
        return None
    for plan in plans:
        flag = MIDI_READERS.get(plan.role)
        setting = f"{ENV_PREFIX}{flag[2:].replace('-', '_').upper()}" if flag else ""
        values = [v for f in (flag, "--config") if f for v in option_values(plan.args, f)]
        if flag and (any(v.strip(" ,") for v in values) or env.get(setting, "").strip(" ,")):
            return None
    one = len(given) == 1
    options, it = f"{', '.join(given)} act{'s' * one}", "it" if one else "them"
    readers = ("physics a score library with --physics-arg '--score-dir DIR', or graphics a --preview-score with "
               f"--graphics-arg); live notes (/batteur/score/note) are read without {it}")
    if opts.score:
        return (f"{options} only on MIDI files, and --score {opts.score} is a text score, read without {it}: of "
                f"this rig's scores only MIDI files /batteur/score/load may load from its folder would be read with "
                f"{it} (to read others, give {readers}")
    return (f"{options} on no score: {'it says' if one else 'they say'} how MIDI files are read, and this rig "
            f"reads none (give --score FILE, {readers.replace('library', 'library for /batteur/score/load', 1)}")


def _midi_score(path: str) -> bool:
    """Whether the rig's ``--score`` is read as MIDI, as :func:`common.score.text.read_score` tells (its name, else
    its first bytes); one that cannot be read counts as MIDI (:func:`check_score` has said what is wrong)."""
    from common.score.events import starts_as_midi
    from common.score.text import MIDI_SUFFIXES

    if Path(path).suffix.lower() in MIDI_SUFFIXES:
        return True
    try:
        with open(path, "rb") as f:
            return starts_as_midi(f.read(12))
    except OSError:
        return True


def check_ports(plans: list[ServicePlan], http_port: int = 0) -> None:
    """Raise ValueError when a service could not listen on its UDP port (on its :attr:`ServicePlan.host`), or
    graphics on TCP ``http_port`` (0: any, nothing to check), before any service starts (else the others start, and
    the one that cannot bind stops them)."""
    for plan in plans:
        probe_port(plan.host, plan.port, socket.SOCK_DGRAM, f"UDP port {plan.port} ({plan.role})", "--base-port")
        if plan.role == "graphics" and http_port:
            probe_port(plan.host, http_port, socket.SOCK_STREAM, f"TCP port {http_port} (graphics view)",
                       "--http-port")


def probe_port(host: str, port: int, kind: socket.SocketKind, what: str, option: str) -> None:
    """Raise ValueError unless a socket of ``kind`` can listen on ``host:port``; ``what`` and ``option`` name
    the port and the option that chooses it in the message."""
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=kind)[0]
        with socket.socket(family, kind, proto) as probe:
            if kind == socket.SOCK_STREAM:  # as the view's server binds: a closing connection does not hold it
                probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            probe.bind(address)
    except socket.gaierror as exc:
        raise ValueError(f"--host {host}: {exc.strerror}") from None
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise ValueError(f"{what} on {host} is in use (another rig?); choose another {option}") from None
        raise ValueError(f"--host {host}: cannot listen there ({exc.strerror or exc})") from None


def check_kit_dir(opts: argparse.Namespace) -> None:
    """Raise ValueError for a ``--kit-dir`` graphics could not save in (as graphics would refuse it, exit 1, once
    the others had started), or when no graphics service would save there."""
    if opts.kit_dir is None:
        return
    if "graphics" not in [r.strip() for r in opts.services.split(",")]:
        raise UsageError("--kit-dir needs the graphics service (--services)")
    check_output_dir(Path(opts.kit_dir), "--kit-dir")


def check_record(opts: argparse.Namespace) -> None:
    """Raise ValueError for a --record folder that cannot be written, or when no sound service would record."""
    if opts.record is None:
        return
    if "sound" not in [r.strip() for r in opts.services.split(",")]:
        raise UsageError("--record needs the sound service (--services)")
    check_output_dir(Path(opts.record), "--record")


def make_record_dir(opts: argparse.Namespace) -> None:
    """Create the --record folder (ValueError when it cannot be, e.g. under /proc)."""
    if opts.record is None:
        return
    try:
        Path(opts.record).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--record {opts.record}: cannot create it ({exc.strerror or exc})") from None


RecordingState = tuple[int, int, int] | None
"""(device, inode, modification time in ns) of ``DIR/performance.wav``; None: no such file."""


def recording_state(folder: Path) -> RecordingState:
    """What ``folder``'s recording is now: sound's clean stop names a new file there (a new inode)."""
    try:
        st = (folder / RECORDING).stat()
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_mtime_ns


def recording_parts(folder: Path) -> frozenset[Path]:
    """The part files sound records into (``.performance.wav.XXXX.part``) now in ``folder``: its take until it has
    stopped cleanly and named it; one left by a sound node that did not."""
    return frozenset(folder.glob(parts_glob(RECORDING)))


def _holds_audio(part: Path) -> bool:
    """Whether a part file, or the take sound named, holds a frame (sound keeps its header up to date); True when
    that cannot be told, so nothing recorded is removed or called empty."""
    import soundfile as sf  # only here: the rig starts no sound itself

    try:
        return part.stat().st_size > 0 and sf.info(str(part)).frames > 0
    except FileNotFoundError:
        return False
    except (OSError, RuntimeError):  # soundfile's LibsndfileError is a RuntimeError
        return True


def finish_recording(folder: Path, sound_stopped_cleanly: bool, out: Output, err: Output,
                     before: RecordingState = None, parts_before: frozenset[Path] = frozenset()) -> None:
    """Say where sound's recording is (sound names it itself once it has stopped cleanly; ``before``: the
    recording's :func:`recording_state` at launch). Else an earlier recording stays in place, and what sound
    recorded stays in its part file (``parts_before``: those there at launch, already told about), which the sound
    node names too: said where it is, removed only if it holds no audio."""
    recorded = recording_state(folder) not in (None, before)
    if not sound_stopped_cleanly:
        kept = []
        for part in sorted(recording_parts(folder) - parts_before):
            if _holds_audio(part):
                kept.append(part)
            else:  # killed before its first block: nothing to keep
                part.unlink(missing_ok=True)
                part_timing(part).unlink(missing_ok=True)  # its timing (sound's WavSink)
        where = ", ".join(map(str, kept)) + (" (a WAV file)" if len(kept) == 1 else " (WAV files)")
        if kept:  # a hidden file: the command that names it, with the rig time of its first sample
            one = len(kept) == 1
            where += (f"; `batteur wav-repair {kept[0] if one else folder}` names {'it' if one else 'them'} "
                      f"(-recovered.wav) with {'its' if one else 'their'} timing")
        if recorded and kept:  # named, and then a part file as well: not sound's way, said all the same
            err.write(f"batteur rig: sound did not stop cleanly; it also left, maybe cut short, {where}\n")
        elif kept:
            earlier = " (the earlier one stays)" if recording_state(folder) is not None else ""
            err.write(f"batteur rig: sound did not stop cleanly: {folder / RECORDING} not written{earlier}; what it "
                      f"recorded, maybe cut short, is in {where}\n")
        elif not recorded:
            err.write(f"batteur rig: sound did not stop cleanly and recorded nothing ({folder / RECORDING} not "
                      "written)\n")
        if not recorded:
            return
    if not recorded:  # sound leaves a take of 0 frames unnamed: an earlier one keeps its name
        left = (f"the earlier take in {folder} stays" if recording_state(folder) is not None
                else f"{folder / RECORDING} not written")
        err.write(f"batteur rig: nothing recorded (sound played nothing: stopped before its audio started; {left})\n")
        return
    if not _holds_audio(folder / RECORDING):  # named, but a header only: "recorded" misled (a 112-byte take)
        err.write(f"batteur rig: the take is empty: {folder / RECORDING} holds no audio (0 frames: sound played "
                  "nothing, stopped before its audio started)\n")
        return
    out.write(f"batteur rig: recorded {folder / RECORDING}\n")


async def run_rig(plans: list[ServicePlan], opts: argparse.Namespace, ready: ReadyWait | None = None) -> int:
    """Run the rig (``ready``: wait for the services to be up), then say where the recording is (still under the
    rig's signal handlers)."""
    rig = Rig(plans, opts.stop_timeout, ready=ready)
    before = recording_state(Path(opts.record)) if opts.record is not None else None
    parts = recording_parts(Path(opts.record)) if opts.record is not None else frozenset()
    code = await rig.run(opts.duration)
    if opts.record is not None:  # the WAV is whole only when sound closed it itself
        finish_recording(Path(opts.record), rig.stopped_cleanly("sound") and rig.exit_codes.get("sound") == 0,
                         rig.out, rig.err, before, parts)
    return code


def main(argv: Sequence[str] | None = None) -> int:
    opts = build_parser().parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="batteur-rig-") as tmp:
        if opts.score == "demo" and not Path("demo").is_file():  # a folder named demo is not a score
            from batteur.demo import DEMO_GROOVE

            opts.score = str(Path(tmp) / "demo-groove.txt")
            Path(opts.score).write_text(DEMO_GROOVE, encoding="utf-8")
        epoch = time.time() + opts.start_delay
        try:
            plans = plan_services(opts, epoch)
            check_allow(plans, opts.host)
            check_record(opts)
            check_kit_dir(opts)
            check_ports(plans, opts.http_port)
            make_record_dir(opts)  # last: a refused option leaves no folder behind
        except ValueError as exc:  # UsageError: 2; a score, a folder or a port it cannot use: 1
            return report_error("batteur rig", exc)
        unread = unread_midi_options(opts, plans)
        left_out = left_out_environment_peers(plans)
        for warning in ignored_options(opts) + [w for w in (unread, left_out) if w]:
            print(f"batteur rig: warning: {warning}", file=sys.stderr, flush=True)
        ready = ReadyWait(opts.ready_timeout, asking_host(plans), epoch, opts.play_at if opts.score else None)
        if opts.score:
            print(f"batteur rig: the drummer plays {opts.score} from rig time {opts.play_at:g} s "
                  f"({opts.start_delay + opts.play_at:g} s after launch; later if physics is not up by then)",
                  flush=True)
        return asyncio.run(run_rig(plans, opts, ready))

