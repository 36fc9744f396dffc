"""Interaction messages: impact ends and damping (to sound and graphics), and interaction's controls.

Events (family ``impacts``) complete ``/batteur/impact`` (common/messages/events.py):
interaction sends the impact at the first contact step, with what is known then,
and the final contact figures in ``/batteur/impact/end`` with the same ``seq``
when the contact is over. A stick or hand resting on an instrument is reported
as ``/batteur/damping`` (on, then off), never as a strike.

Controls (family ``control``, addresses ``/batteur/interaction/...``) edit the
mapping and the run-time registered messages live; answers and errors go back
to the sender. An argument spec (``spec``) is one string:

* ``=VALUE``: a constant (int, float or string),
* ``FEATURE``: an impact feature as is (``velocity``, ``r``, ``instrument``, ...),
* ``FEATURE:linear:IN_MIN:IN_MAX:OUT_MIN:OUT_MAX``,
  ``FEATURE:exp:IN_MIN:IN_MAX:OUT_MIN:OUT_MAX[:CURVATURE]``,
  ``FEATURE:table:X0:Y0:X1:Y1...``: a feature through a curve,

optionally followed by ``@i``, ``@f`` or ``@s`` to choose the OSC type sent
(docs/interaction.md).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register

Name = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")]
Target = Annotated[str, Field(min_length=1, max_length=128, description="role name or host:port")]
Text = Annotated[str, Field(max_length=512)]
Spec = Annotated[str, Field(min_length=1, max_length=256)]
Count = Annotated[int, Field(ge=0)]

ImpactKind = Literal["strike", "bounce", "buzz", "dead"]
"""strike: a fresh stroke; bounce: a passive rebound of the previous one; buzz: the
2nd and later rebounds of one stroke; dead: a strike whose stick stays on the instrument."""


# --------------------------------------------------------------------------- events


@register
class ImpactEnd(OscMessage):
    """The final contact figures of an impact, sent when its contact is over.

    Same ``seq`` and ``time`` as the ``/batteur/impact`` it completes; sent
    redundantly like it (receivers de-duplicate on sender, address and seq).
    For a dead stroke the figures cover the strike up to the moment the
    contact was recognised as a press.
    """

    ADDRESS = "/batteur/impact/end"
    FAMILY = Family.IMPACTS

    seq: int = Field(ge=0, description="sequence number of the impact this completes")
    time: RigTime = Field(description="rig time of first contact, seconds")
    instrument: Name = Field(description="kit object id")
    kind: ImpactKind = Field(description="strike, bounce, buzz or dead")
    impulse: float = Field(ge=0, description="total normal impulse, newton-seconds")
    peak_force: float = Field(ge=0, description="peak normal force, newtons")
    duration: float = Field(ge=0, le=1, description="contact duration, seconds")
    part: Name = Field(description="striker part")


@register
class Damping(OscMessage):
    """A striker or hand resting on an instrument (state 1), or lifted off it again (state 0).

    A dead stroke is an impact followed by damping; a stick laid gently on a
    head is damping only. Sent redundantly with its own ``seq`` (copies share
    it and ``time``: receivers de-duplicate on (sender, seq, time)).
    """

    ADDRESS = "/batteur/damping"
    FAMILY = Family.IMPACTS

    seq: int = Field(ge=0, description="damping sequence number (per interaction node)")
    time: RigTime = Field(description="rig time the press was recognised (state 1) or lifted (state 0), seconds")
    instrument: Name = Field(description="kit object id")
    part: Name = Field(description="striker part or hand resting on the instrument")
    state: int = Field(ge=0, le=1, description="1: resting on the instrument, 0: lifted")
    zone: Name = Field(description="zone pressed: centre, edge, rim, bell, bow, ...")
    r: float = Field(ge=0, le=2, description="radial position r/a of the press")
    theta: float = Field(ge=-7, le=7, description="angle of the press in the instrument frame, radians")
    force: float = Field(ge=0, description="mean normal force while resting, newtons (0 when lifted)")


# --------------------------------------------------------------------------- mapping controls


@register
class RouteSet(OscMessage):
    """Send impacts (and their ends and damping) to a role or host:port; create or update the route."""

    ADDRESS = "/batteur/interaction/route/set"
    FAMILY = Family.CONTROL

    to: Target = Field(description="role name or host:port")
    instruments: Text = Field(description="'*' for every instrument, or a comma-separated list of kit object ids")


@register
class RouteRemove(OscMessage):
    """Stop sending impacts to a role or host:port."""

    ADDRESS = "/batteur/interaction/route/remove"
    FAMILY = Family.CONTROL

    to: Target = Field(description="role name or host:port of the route to remove")


@register
class MapSet(OscMessage):
    """Map one field of the impact a route sends from an impact feature through a curve.

    Creates the route for every instrument when it does not exist. ``spec``
    uses the argument spec syntax (module docstring), e.g. ``velocity:exp:0:10:0:5:3``.
    """

    ADDRESS = "/batteur/interaction/map/set"
    FAMILY = Family.CONTROL

    to: Target = Field(description="route: role name or host:port")
    field: Name = Field(description="impact field to set: r, theta, velocity, impulse, peak_force, duration")
    spec: Spec = Field(description="argument spec: FEATURE[:CURVE:...] (see docs/interaction.md)")


@register
class MapClear(OscMessage):
    """Back to the one-to-one physical value for one field of a route ('*': every field)."""

    ADDRESS = "/batteur/interaction/map/clear"
    FAMILY = Family.CONTROL

    to: Target = Field(description="route: role name or host:port")
    field: str = Field(min_length=1, max_length=64, description="impact field, or '*' for every field")


@register
class MapList(OscMessage):
    """Ask for the routes and field maps: one /batteur/interaction/map/info each, then list/end."""

    ADDRESS = "/batteur/interaction/map/list"
    FAMILY = Family.CONTROL


@register
class MapInfo(OscMessage):
    """One route (field and spec empty) or one field map of a route, in answer to map/list."""

    ADDRESS = "/batteur/interaction/map/info"
    FAMILY = Family.CONTROL

    to: Target = Field(description="route: role name or host:port")
    instruments: Text = Field(description="'*' or comma-separated kit object ids")
    field: str = Field(max_length=64, description="impact field mapped ('' for the route itself)")
    spec: str = Field(max_length=256, description="argument spec ('' for the route itself)")


# --------------------------------------------------------------------------- registered messages


@register
class MessageAdd(OscMessage):
    """Register (or replace) a message interaction sends on every matching impact.

    The arguments are built from impact features by the specs (module
    docstring). Persisted in interaction's configuration file.
    """

    ADDRESS = "/batteur/interaction/message/add"
    FAMILY = Family.CONTROL

    name: Name = Field(description="name of the registered message (replaces one of the same name)")
    to: Target = Field(description="role name or host:port")
    address: str = Field(min_length=2, max_length=128, description="OSC address to send, starting with '/'")
    instruments: Text = Field(description="'*' for every instrument, or a comma-separated list of kit object ids")
    when: Literal["onset", "end"] = Field(description="send at first contact (onset) or when the contact ends (end)")
    specs: tuple[str, ...] = Field(description="one argument spec per argument sent")


@register
class MessageRemove(OscMessage):
    """Remove a registered message by name."""

    ADDRESS = "/batteur/interaction/message/remove"
    FAMILY = Family.CONTROL

    name: Name = Field(description="name of the registered message")


@register
class MessageList(OscMessage):
    """Ask for the registered messages: one /batteur/interaction/message/info each, then list/end."""

    ADDRESS = "/batteur/interaction/message/list"
    FAMILY = Family.CONTROL


@register
class MessageInfo(OscMessage):
    """One registered message, in answer to message/list (same arguments as message/add)."""

    ADDRESS = "/batteur/interaction/message/info"
    FAMILY = Family.CONTROL

    name: Name = Field(description="name of the registered message")
    to: Target = Field(description="role name or host:port")
    address: str = Field(min_length=2, max_length=128, description="OSC address sent")
    instruments: Text = Field(description="'*' or comma-separated kit object ids")
    when: Literal["onset", "end"] = Field(description="onset or end")
    specs: tuple[str, ...] = Field(description="argument specs")


@register
class ListEnd(OscMessage):
    """Ends an answer to map/list, message/list or stats/get."""

    ADDRESS = "/batteur/interaction/list/end"
    FAMILY = Family.CONTROL

    what: Literal["map", "message", "stats"] = Field(description="which list ended")
    count: Count = Field(description="number of entries sent")


# --------------------------------------------------------------------------- routing, config, health


@register
class Redundancy(OscMessage):
    """How many times each impact, impact end and damping message is sent, and how far apart."""

    ADDRESS = "/batteur/interaction/redundancy"
    FAMILY = Family.CONTROL

    copies: int = Field(ge=1, le=16, description="copies of each message (1: no redundancy)")
    spacing: float = Field(ge=0, le=0.1, description="time between copies, seconds")


@register
class ImpactTiming(OscMessage):
    """When /batteur/impact is sent: at the first contact step, or when the contact is over (final figures)."""

    ADDRESS = "/batteur/interaction/impact_at"
    FAMILY = Family.CONTROL

    at: Literal["onset", "end"] = Field(description="onset (lowest latency) or end (impulse, force, duration final)")


@register
class ConfigLoad(OscMessage):
    """Replace interaction's configuration by a YAML or JSON file from its configuration directory ('' reloads).

    Only a plain file name is accepted: a path is refused with an error reply.
    """

    ADDRESS = "/batteur/interaction/config/load"
    FAMILY = Family.CONTROL

    path: Text = Field(description="file name in interaction's configuration directory, or '' for its own file")


@register
class ConfigSave(OscMessage):
    """Write interaction's configuration (mapping, registered messages) to its configuration file now."""

    ADDRESS = "/batteur/interaction/config/save"
    FAMILY = Family.CONTROL


@register
class StatsGet(OscMessage):
    """Ask for interaction's counters: one stats, one instrument/stats per instrument, then list/end."""

    ADDRESS = "/batteur/interaction/stats/get"
    FAMILY = Family.CONTROL


@register
class InteractionStats(OscMessage):
    """Interaction's counters since start."""

    ADDRESS = "/batteur/interaction/stats"
    FAMILY = Family.HEALTH

    time: RigTime = Field(description="rig time of this report, seconds")
    contacts: Count = Field(description="contact messages handled")
    impacts: Count = Field(description="impacts sent (strikes, bounces, buzz, dead strokes)")
    chatter: Count = Field(description="re-contacts merged into the strike they belong to")
    touches: Count = Field(description="contacts too slow to be a strike")
    dampings: Count = Field(description="presses reported as damping")
    unknown_instrument: Count = Field(description="contacts on an object the kit does not have")
    mapping_errors: Count = Field(description="mapped values that failed or were clamped")
    copies_sent: Count = Field(description="messages sent including redundant copies")
    latency_p50: float = Field(ge=0, description="rig time from contact step to impact out, median, seconds")
    latency_p99: float = Field(ge=0, description="rig time from contact step to impact out, 99th percentile, seconds")
    latency_max: float = Field(ge=0, description="rig time from contact step to impact out, maximum, seconds")
    out_of_order: Count = Field(default=0, description="contact steps older than their contact's last, or late "
                                "steps of a contact already ended (dropped)")
    dropped_contacts: Count = Field(default=0, description="contacts of a new striker refused: too many tracked")
    clock_resets: Count = Field(default=0, description="times the physics clock went back (physics restarted) "
                                "and segmentation started again")
    duplicate_contacts: Count = Field(default=0, description="contact datagrams received twice (dropped, so "
                                      "their impulse is not counted twice)")


@register
class InstrumentStats(OscMessage):
    """Impacts of one instrument since start, in answer to stats/get."""

    ADDRESS = "/batteur/interaction/instrument/stats"
    FAMILY = Family.HEALTH

    instrument: Name = Field(description="kit object id")
    strikes: Count = Field(description="fresh strokes")
    bounces: Count = Field(description="first rebounds")
    buzz: Count = Field(description="further rebounds")
    dead: Count = Field(description="dead strokes")
    dampings: Count = Field(description="presses")


@register
class InteractionError(OscMessage):
    """A control message interaction could not apply, and why (sent back to its sender); also another service's
    control sent to an interaction node, naming the service that takes it."""

    ADDRESS = "/batteur/interaction/error"
    FAMILY = Family.CONTROL

    request: str = Field(max_length=128, description="address of the request that failed")
    detail: Text = Field(description="what was wrong")
