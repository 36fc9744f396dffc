"""The interaction core: contacts in; impacts, impact ends, damping and registered messages out.

Deterministic and event-driven: :meth:`InteractionCore.handle` turns each
``/batteur/contact`` into what can be sent at once (an impact at its first
contact step), and :meth:`InteractionCore.step`, called at ``rate_hz``, ends
silent contacts (impact ends, damping off) and sends the redundant copies
that are due. Control messages (``/batteur/interaction/...``) edit routes,
field maps, registered messages and redundancy live; answers and errors go
back to the sender ("reply").

What an impact carries when (docs/interaction.md):

* ``/batteur/impact`` leaves at the first contact step (``impact_at: onset``,
  the default): time, instrument, zone, r/a, theta, part and the approach
  velocity are final; ``impulse``, ``peak_force`` and ``duration`` are 0, "not
  known yet". With ``impact_at: end`` it leaves when the contact is over, every
  figure final.
* ``/batteur/impact/end`` (same seq) leaves when the contact is over, with
  the total impulse, the peak force and the duration, and the impact's kind.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable, Collection, Mapping
from typing import ClassVar, Literal, Protocol

import numpy as np
from pydantic import ValidationError

from common.core import Outgoing
from common.kit import Kit, load_kit
from common.messages import Contact, Impact, OscMessage
from common.messages.interaction import (
    ConfigLoad,
    ConfigSave,
    Damping,
    ImpactEnd,
    ImpactTiming,
    InstrumentStats,
    InteractionError,
    InteractionStats,
    ListEnd,
    MapClear,
    MapInfo,
    MapList,
    MapSet,
    MessageAdd,
    MessageInfo,
    MessageList,
    MessageRemove,
    Redundancy,
    RouteRemove,
    RouteSet,
    StatsGet,
)
from services.interaction.config import InteractionConfig, RedundancyConfig
from services.interaction.detect import (
    DampingChange,
    ImpactFeatures,
    ImpactFinal,
    ImpactOnset,
    Segmenter,
    SegmentEvent,
)
from services.interaction.features import PLAYABLE_KINDS
from services.interaction.mapping import (
    MAPPABLE_FIELDS,
    ArgSpec,
    MappingError,
    RegisteredMessage,
    Route,
    format_instruments,
    parse_instruments,
)
from services.interaction.routing import RedundantScheduler, registered_message

MAX_STEP_HZ = 1000.0
"""Fastest step rate the core asks for (redundant copies and contact ends need no more)."""
ROLE_NAME = re.compile(r"[a-z][a-z0-9_-]*")
"""What a role name can be (a Hello's role, ``common.messages.system.Role``): a target without a port that is not
one (``127.0.0.1``, ``synth.local``), or is ``localhost``, is a host whose port is missing."""


class ConfigStore(Protocol):
    """Where the configuration is persisted (the node gives a file; tests may give anything)."""

    def load(self, path: str = "") -> InteractionConfig: ...

    def save(self, config: InteractionConfig) -> None: ...


class InteractionCore:
    """Contacts -> impacts -> mapped messages to sound, graphics and registered targets.

    Parameters
    ----------
    kit : the kit (default: the shipped ``default`` kit)
    config : detection, redundancy, routes, registered messages (default: one-to-one to sound and graphics)
    seq_start : first sequence number; a node passes a fresh value at each start so that
        receivers' de-duplication sees a restart
    store : where configuration changes are persisted (None: not persisted)
    """

    ROLE: ClassVar[str] = "interaction"

    def __init__(
        self,
        kit: Kit | None = None,
        config: InteractionConfig | None = None,
        seq_start: int = 0,
        store: ConfigStore | None = None,
    ) -> None:
        self.kit = kit if kit is not None else load_kit("default")
        self.config = config if config is not None else InteractionConfig()
        self.store = store
        self.segmenter = Segmenter(self.kit, self.config.detection, seq_start=seq_start)
        self.scheduler = RedundantScheduler()
        self.mapping_errors = 0
        self.control_errors = 0
        self.rejected_total = 0
        """Control messages refused (answered with an error), total: the node's Health counts them as dropped."""
        self.impacts_sent = 0
        self.latencies: deque[float] = deque(maxlen=10_000)
        self.on_config_error: Callable[[str], None] | None = None
        self.reachable_roles: Callable[[], Collection[str]] | None = None
        """Set by the node: the roles it can ever send to (those discovery looks for, and its peers'). A route or
        registered message added over OSC to another role is refused (no node of it would get a message); None
        (offline, tests): any role is taken."""
        self.rate_hz = self._rate_for(self.config)
        self._controls: dict[type[OscMessage], Callable[[OscMessage, float], list[Outgoing]]] = {
            RouteSet: self._route_set,
            RouteRemove: self._route_remove,
            MapSet: self._map_set,
            MapClear: self._map_clear,
            MapList: self._map_list,
            MessageAdd: self._message_add,
            MessageRemove: self._message_remove,
            MessageList: self._message_list,
            Redundancy: self._redundancy,
            ImpactTiming: self._impact_timing,
            ConfigLoad: self._config_load,
            ConfigSave: self._config_save,
            StatsGet: self._stats_get,
        }

    # ------------------------------------------------------------------ Core protocol

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        """React to a contact or a control message received at rig time ``now`` (seconds)."""
        if isinstance(message, Contact):
            return self._dispatch(self.segmenter.contact(message, now), now)
        control = self._controls.get(type(message))
        if control is None:
            return []  # impacts from another interaction node, hellos, health...: not ours
        try:
            return control(message, now)
        except (MappingError, ValidationError, ValueError, OSError) as exc:
            self.control_errors += 1
            self.rejected_total += 1
            return [Outgoing(InteractionError(request=message.ADDRESS, detail=_short(exc)), "reply")]

    def step(self, now: float) -> list[Outgoing]:
        """End silent contacts and send the redundant copies due by rig time ``now`` (seconds)."""
        out = self._dispatch(self.segmenter.advance(now), now)
        out.extend(self.scheduler.due(now))
        return out

    # ------------------------------------------------------------------ impacts out

    def _dispatch(self, events: list[SegmentEvent], now: float) -> list[Outgoing]:
        out: list[Outgoing] = []
        for event in events:
            if isinstance(event, ImpactOnset):
                self.impacts_sent += 1
                if self.config.impact_at == "onset":
                    self.latencies.append(max(now - event.contact_time, 0.0))
                    out.extend(self._impact_out(event.impact, now))
                out.extend(self._registered_out(event.impact, "onset", now))
            elif isinstance(event, ImpactFinal):
                if self.config.impact_at == "end":
                    self.latencies.append(max(now - event.impact.time, 0.0))
                    out.extend(self._impact_out(event.impact, now))
                out.extend(self._impact_end_out(event.impact, now))
                out.extend(self._registered_out(event.impact, "end", now))
            else:
                out.extend(self._damping_out(event, now))
        return out

    def _send(self, message: OscMessage, to: str, now: float, copies: int | None = None) -> list[Outgoing]:
        red = self.config.redundancy
        return self.scheduler.send(Outgoing(message, to), now, copies or red.copies, red.spacing)

    def _mapped(self, route: Route, impact: ImpactFeatures, name: str) -> float:
        physical = float(getattr(impact, name))
        spec = route.fields.get(name)
        if spec is None:
            return physical
        try:
            value = spec.evaluate(impact)
        except (MappingError, KeyError, ValueError) as exc:
            self.mapping_errors += 1
            if self.on_config_error is not None:
                self.on_config_error(f"route {route.to} field {name}: {exc}")
            return physical
        if isinstance(value, str):  # refused by Route's validator; kept for safety
            self.mapping_errors += 1
            return physical
        low, high = MAPPABLE_FIELDS[name]
        clamped = min(max(float(value), low), high)
        if clamped != value:
            self.mapping_errors += 1
        return clamped

    def _impact_out(self, impact: ImpactFeatures, now: float) -> list[Outgoing]:
        out: list[Outgoing] = []
        for route in self.config.routes:
            if not route.matches(impact.instrument):
                continue
            message = Impact(
                seq=impact.seq,
                time=impact.time,
                instrument=impact.instrument,
                zone=impact.zone,
                r=self._mapped(route, impact, "r"),
                theta=self._mapped(route, impact, "theta"),
                velocity=self._mapped(route, impact, "velocity"),
                impulse=self._mapped(route, impact, "impulse"),
                peak_force=self._mapped(route, impact, "peak_force"),
                duration=self._mapped(route, impact, "duration"),
                part=impact.part,
                openness=impact.openness,
            )
            out.extend(self._send(message, route.to, now))
        return out

    def _impact_end_out(self, impact: ImpactFeatures, now: float) -> list[Outgoing]:
        out: list[Outgoing] = []
        for route in self.config.routes:
            if not route.ends or not route.matches(impact.instrument):
                continue
            message = ImpactEnd(
                seq=impact.seq,
                time=impact.time,
                instrument=impact.instrument,
                kind=impact.kind,
                impulse=self._mapped(route, impact, "impulse"),
                peak_force=self._mapped(route, impact, "peak_force"),
                duration=self._mapped(route, impact, "duration"),
                part=impact.part,
            )
            out.extend(self._send(message, route.to, now))
        return out

    def _damping_out(self, event: DampingChange, now: float) -> list[Outgoing]:
        message = Damping(
            seq=event.seq,
            time=event.time,
            instrument=event.instrument,
            part=event.part,
            state=event.state,
            zone=event.zone,
            r=event.r,
            theta=event.theta,
            force=max(event.force, 0.0),
        )
        out: list[Outgoing] = []
        for route in self.config.routes:
            if route.ends and route.matches(event.instrument):
                out.extend(self._send(message, route.to, now))
        return out

    def _registered_out(self, impact: ImpactFeatures, when: str, now: float) -> list[Outgoing]:
        out: list[Outgoing] = []
        for registered in self.config.messages:
            if registered.when != when or not registered.matches(impact.instrument):
                continue
            try:
                args = registered.build(impact)
            except (MappingError, KeyError, ValueError) as exc:
                self.mapping_errors += 1
                if self.on_config_error is not None:
                    self.on_config_error(f"registered message {registered.name}: {exc}")
                continue
            message = registered_message(registered.address, args)
            out.extend(self._send(message, registered.to, now, copies=registered.repeat))
        return out

    # ------------------------------------------------------------------ configuration

    def set_config(self, config: InteractionConfig, persist: bool = True) -> None:
        """Replace the whole configuration (detection thresholds apply to contacts from now on).

        Saved first: when the file cannot be written (OSError) nothing changes, as the error reply says.
        """
        if persist and self.store is not None:
            self.store.save(config)
        self.config = config
        self.segmenter.config = config.detection
        self.rate_hz = self._rate_for(config)

    def _changed(self, **update: object) -> None:
        self.set_config(InteractionConfig.model_validate({**self.config.model_dump(), **update}))

    @staticmethod
    def _rate_for(config: InteractionConfig) -> float:
        """Step often enough for the copies' spacing and for ending contacts on time, at most 1 kHz."""
        wanted = 1.0 / config.detection.retrigger_gap
        if config.redundancy.copies > 1 and config.redundancy.spacing > 0:
            wanted = max(wanted, 1.0 / config.redundancy.spacing)
        return min(wanted, MAX_STEP_HZ)

    def _playable(self) -> list[str]:
        return [o.id for o in self.kit.objects if o.kind in PLAYABLE_KINDS]

    def _instruments(self, text: str) -> list[str]:
        """The instrument list of a route or registered message; ValueError naming any the kit cannot play
        (a typo would make the route silently never match)."""
        names = parse_instruments(text)
        playable = self._playable()
        unknown = [n for n in names if n not in playable]
        if unknown:
            raise ValueError(f"no instrument {', '.join(map(repr, unknown))} in kit {self.kit.name!r} "
                             f"(it has: {', '.join(playable)})")
        return names

    def unplayable_instruments(self) -> list[str]:
        """Routes and registered messages of the configuration naming instruments the kit cannot play, one
        line each (a configuration file may come from another kit, so this is for a warning, not an error)."""
        playable = self._playable()
        owners = [(f"route to {r.to}", r.instruments) for r in self.config.routes]
        owners += [(f"registered message {m.name}", m.instruments) for m in self.config.messages]
        lines = []
        for owner, names in owners:
            unknown = [n for n in names if n not in playable]
            if unknown:
                lines.append(f"{owner}: no instrument {', '.join(map(repr, unknown))} in kit {self.kit.name!r}")
        return lines

    def _check_role(self, to: str) -> None:
        """ValueError when ``to`` is a role this node can never send to (see :attr:`reachable_roles`): it would
        be taken and saved, and its messages silently go nowhere; or when it is a host without its port (no role
        is named so: told as a missing port, not as a role to add with --peer)."""
        if ":" in to or to.startswith("["):  # a HOST:PORT is always reachable
            return
        if not ROLE_NAME.fullmatch(to) or to == "localhost":
            raise ValueError(f"{to!r} has no port: give {to}:PORT, the port your program listens on (or a role "
                             "name: sound, graphics, ...)")
        if self.reachable_roles is None:
            return
        roles = sorted(set(self.reachable_roles()))
        if to in roles:
            return
        known = f"the roles it can reach are {', '.join(roles)}" if roles else "it reaches no role"
        raise ValueError(f"no {to!r} node can be reached: {known} (found by discovery or given with --peer); "
                         f"give your tool's HOST:PORT, or start interaction with --peer {to}=HOST:PORT")

    def _route_set(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, RouteSet)
        routes = [r.model_dump() for r in self.config.routes]
        instruments = self._instruments(message.instruments)
        for route in routes:
            if route["to"] == message.to:
                route["instruments"] = instruments
                break
        else:
            added = Route(to=message.to, instruments=instruments)  # a target no route may have is refused first
            self._check_role(added.to)
            routes.append(added.model_dump())
        self._changed(routes=routes)
        return []

    def _route_remove(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, RouteRemove)
        routes = [r.model_dump() for r in self.config.routes if r.to != message.to]
        if len(routes) == len(self.config.routes):
            raise ValueError(f"no route to {message.to!r}")
        self._changed(routes=routes)
        return []

    def _map_set(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, MapSet)
        if message.field not in MAPPABLE_FIELDS:
            raise ValueError(f"field {message.field!r} cannot be mapped (mappable: {', '.join(MAPPABLE_FIELDS)})")
        spec = ArgSpec.parse(message.spec)
        routes = [r.model_dump() for r in self.config.routes]
        for route in routes:
            if route["to"] == message.to:
                route["fields"][message.field] = spec.model_dump()
                break
        else:
            added = Route(to=message.to, fields={message.field: spec})
            self._check_role(added.to)
            routes.append(added.model_dump())
        self._changed(routes=routes)
        return []

    def _map_clear(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, MapClear)
        routes = [r.model_dump() for r in self.config.routes]
        for route in routes:
            if route["to"] == message.to:
                if message.field == "*":
                    route["fields"] = {}
                elif route["fields"].pop(message.field, None) is None:
                    raise ValueError(f"route {message.to!r} does not map {message.field!r}")
                break
        else:
            raise ValueError(f"no route to {message.to!r}")
        self._changed(routes=routes)
        return []

    def _map_list(self, message: OscMessage, now: float) -> list[Outgoing]:
        listing = _Listing(MapList.ADDRESS)
        for route in self.config.routes:
            instruments = format_instruments(route.instruments)
            entries = [("", "")] + [(name, spec.to_spec()) for name, spec in route.fields.items()]
            for name, spec in entries:
                fields = {"to": route.to, "instruments": instruments, "field": name, "spec": spec}
                listing.add(MapInfo, fields, f"route {route.to} field {name or '-'}")
        self.control_errors += len(listing.refused)
        return listing.replies("map")

    def _message_add(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, MessageAdd)
        registered = RegisteredMessage(
            name=message.name,
            to=message.to,
            address=message.address,
            instruments=self._instruments(message.instruments),
            when=message.when,
            args=[ArgSpec.parse(text) for text in message.specs],
        )
        self._check_role(registered.to)
        messages = [m.model_dump() for m in self.config.messages if m.name != message.name]
        messages.append(registered.model_dump())
        self._changed(messages=messages)
        return []

    def _message_remove(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, MessageRemove)
        messages = [m.model_dump() for m in self.config.messages if m.name != message.name]
        if len(messages) == len(self.config.messages):
            raise ValueError(f"no registered message named {message.name!r}")
        self._changed(messages=messages)
        return []

    def _message_list(self, message: OscMessage, now: float) -> list[Outgoing]:
        listing = _Listing(MessageList.ADDRESS)
        for m in self.config.messages:
            fields = {"name": m.name, "to": m.to, "address": m.address,
                      "instruments": format_instruments(m.instruments), "when": m.when,
                      "specs": tuple(spec.to_spec() for spec in m.args)}
            listing.add(MessageInfo, fields, f"registered message {m.name}")
        self.control_errors += len(listing.refused)
        return listing.replies("message")

    def _redundancy(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, Redundancy)
        self._changed(redundancy=RedundancyConfig(copies=message.copies, spacing=message.spacing).model_dump())
        return []

    def _impact_timing(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, ImpactTiming)
        self._changed(impact_at=message.at)
        return []

    def _config_load(self, message: OscMessage, now: float) -> list[Outgoing]:
        assert isinstance(message, ConfigLoad)
        if self.store is None:
            raise ValueError("interaction runs without a configuration file")
        self.set_config(self.store.load(message.path), persist=bool(message.path))
        return []

    def _config_save(self, message: OscMessage, now: float) -> list[Outgoing]:
        if self.store is None:
            raise ValueError("interaction runs without a configuration file")
        self.store.save(self.config)
        return []

    # ------------------------------------------------------------------ health

    def latency_percentiles(self) -> tuple[float, float, float]:
        """Rig time from contact step to impact out: (p50, p99, max), seconds, over the last 10,000 impacts."""
        if not self.latencies:
            return (0.0, 0.0, 0.0)
        values = np.fromiter(self.latencies, float)
        p50, p99 = np.percentile(values, [50, 99])
        return (float(p50), float(p99), float(values.max()))

    def stats_message(self, now: float) -> InteractionStats:
        """The counters since start as one message."""
        det = self.segmenter.stats
        p50, p99, worst = self.latency_percentiles()
        return InteractionStats(
            time=now,
            contacts=det.contacts,
            impacts=self.impacts_sent,
            chatter=det.chatter,
            touches=det.touches,
            dampings=det.dampings,
            unknown_instrument=det.unknown_instrument,
            mapping_errors=self.mapping_errors,
            copies_sent=self.scheduler.copies_sent,
            latency_p50=p50,
            latency_p99=p99,
            latency_max=worst,
            out_of_order=det.out_of_order,
            dropped_contacts=det.dropped,
            clock_resets=det.clock_resets,
            duplicate_contacts=det.duplicates,
        )

    def instrument_stats(self) -> list[InstrumentStats]:
        """Per-instrument counts of finished impacts and presses."""
        return [
            InstrumentStats(
                instrument=name,
                strikes=counts["strike"],
                bounces=counts["bounce"],
                buzz=counts["buzz"],
                dead=counts["dead"],
                dampings=counts["damping"],
            )
            for name, counts in sorted(self.segmenter.stats.by_instrument.items())
        ]

    def _stats_get(self, message: OscMessage, now: float) -> list[Outgoing]:
        out = [Outgoing(self.stats_message(now), "reply")]
        out += [Outgoing(m, "reply") for m in self.instrument_stats()]
        out.append(Outgoing(ListEnd(what="stats", count=len(out)), "reply"))
        return out


class _Listing:
    """The answers to map/list or message/list. An entry the configuration file allows but an OSC reply cannot
    carry (a long table, a long instrument list) gets an error of its own; the rest is listed all the same."""

    def __init__(self, request: str) -> None:
        self.request = request
        self.infos: list[OscMessage] = []
        self.refused: list[InteractionError] = []

    def add(self, cls: type[OscMessage], fields: Mapping[str, object], what: str) -> None:
        try:
            self.infos.append(cls.model_validate(fields))
        except ValidationError as exc:
            detail = _short(f"{what} cannot be listed over OSC: {_short(exc)}")
            self.refused.append(InteractionError(request=self.request, detail=detail))

    def replies(self, what: Literal["map", "message"]) -> list[Outgoing]:
        """Every entry, the errors, then list/end with the number of entries."""
        messages = [*self.infos, *self.refused, ListEnd(what=what, count=len(self.infos))]
        return [Outgoing(m, "reply") for m in messages]


def _short(exc: BaseException | str) -> str:
    text = str(exc)
    if isinstance(exc, ValidationError):
        errors = exc.errors()
        if errors:
            first = errors[0]
            where = ".".join(str(p) for p in first.get("loc", ()))
            text = f"{where}: {first.get('msg')}" if where else str(first.get("msg"))
    text = " ".join(text.split())
    return text[:500]
