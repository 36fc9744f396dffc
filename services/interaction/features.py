"""Where on an instrument a contact is: r/a, theta and the zone, from the kit model.

Positions come in the instrument's own frame (metres, +z the playing surface
normal, common/kit.py). Zones by object kind:

========  ===========================================================
membrane  ``rim`` within ``rim_margin`` of the edge or beyond it,
          ``edge`` from ``membrane_edge_r``, else ``centre``
cymbal    ``bell`` inside the bell radius, ``edge`` from
          ``cymbal_edge_r``, else ``bow``
hihat     from how open its plates were at the contact (the contact's
          ``openness``, physics' simulated gap): ``open`` from
          ``hihat_open_from``, ``half`` from ``hihat_half_from``, else
          ``closed``; a contact without it (-1: an older physics): as
          a cymbal
bell      ``edge`` (the mouth) from ``bell_edge_r``, else ``centre``
pedal     ``centre``
========  ===========================================================

A hi-hat impact also carries how open the hat sounds (:func:`hihat_openness`:
the gap mapped linearly from 0 at ``hihat_openness_from`` to 1 at
``hihat_openness_full``), which the sound plays as it is from that stroke on
(services/sound/instruments.py ``HiHat``); a sender without it (-1: a Pd
patch, an older interaction) has its ``open``/``half``/``closed`` played at
openness 1, 0.5, 0. Either way the openness comes from the simulated hi-hat,
never from the score.
"""

from __future__ import annotations

import math
from typing import Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

from common.kit import KitObject

R_MAX = 2.0
"""Largest r/a an impact carries (the Impact message's range)."""


class ZoneConfig(BaseModel):
    """Zone boundaries. Radii as r/a (0 centre, 1 edge) unless in metres."""

    model_config = ConfigDict(extra="forbid")

    membrane_edge_r: float = Field(default=0.75, ge=0, le=1, description="membrane edge zone starts here, r/a")
    rim_margin: float = Field(default=0.006, ge=0, le=0.05, description="rim: this close to the edge, metres")
    cymbal_edge_r: float = Field(default=0.85, ge=0, le=1, description="cymbal edge zone starts here, r/a")
    bell_edge_r: float = Field(default=0.85, ge=0, le=1, description="cowbell mouth zone starts here, r/a")
    hihat_half_from: float = Field(default=0.02, ge=0, le=1,
                                   description="a hi-hat stroke is half open from this openness (the plates' gap "
                                               "above first touch over 25 mm: 0.02 is 0.5 mm), else closed")
    hihat_open_from: float = Field(default=0.06, ge=0, le=1,
                                   description="... and open from this openness (0.06: 1.5 mm; the planner's "
                                               "open note parts the plates about 10 mm on the default kit, 0.41)")
    hihat_openness_from: float = Field(default=0.02, ge=0, lt=1,
                                       description="the openness a hi-hat impact carries for the sound "
                                                   "(hihat_openness): 0 up to this gap (0.02: 0.5 mm, where the "
                                                   "zone stops being closed, so a closed stroke sounds closed) ...")
    hihat_openness_full: float = Field(default=0.06, gt=0, le=1,
                                       description="... rising linearly to 1 (fully open) at this gap (0.06: 1.5 "
                                                   "mm, where the zone becomes open) and beyond")

    @model_validator(mode="after")
    def _openness_map_rises(self) -> Self:
        if self.hihat_openness_full <= self.hihat_openness_from:
            raise ValueError(f"hihat_openness_full ({self.hihat_openness_full:g}) must be above "
                             f"hihat_openness_from ({self.hihat_openness_from:g}): the openness rises with the gap")
        return self


def polar(obj: KitObject, local_x: float, local_y: float) -> tuple[float, float]:
    """Strike position as (r/a, theta).

    Parameters
    ----------
    obj : the kit object struck (its ``radius`` a, metres)
    local_x, local_y : position in the object's frame, metres

    Returns
    -------
    r : float in [0, 2], distance from the centre over the radius (clipped at 2)
    theta : float in [-pi, pi], radians, from the object's local +x towards +y
    """
    distance = math.hypot(local_x, local_y)
    r = min(distance / obj.radius, R_MAX)
    theta = math.atan2(local_y, local_x) if distance > 0 else 0.0
    return r, theta


def zone(obj: KitObject, r: float, zones: ZoneConfig, openness: float = -1.0) -> str:
    """The zone name of a strike at r/a ``r`` on ``obj`` (module docstring); ``openness``: a hi-hat's at the
    contact (0 closed ... 1; negative: not known)."""
    if obj.kind == "hihat" and openness >= 0.0:
        if openness >= zones.hihat_open_from:
            return "open"
        return "half" if openness >= zones.hihat_half_from else "closed"
    if obj.kind == "membrane":
        if r * obj.radius >= obj.radius - zones.rim_margin:
            return "rim"
        return "edge" if r >= zones.membrane_edge_r else "centre"
    if obj.kind in ("cymbal", "hihat"):
        if obj.bell_radius > 0 and r * obj.radius <= obj.bell_radius:
            return "bell"
        return "edge" if r >= zones.cymbal_edge_r else "bow"
    if obj.kind == "bell":
        return "edge" if r >= zones.bell_edge_r else "centre"
    return "centre"


def hihat_openness(obj: KitObject, gap: float, zones: ZoneConfig) -> float:
    """How open a stroke on ``obj`` sounds, 0 closed ... 1 open, from the plates' gap at its contact (the
    contact's ``openness``: the gap above first touch over 25 mm): 0 up to ``zones.hihat_openness_from``, 1 from
    ``zones.hihat_openness_full``, linear between; -1 (not given: the sound goes by the zone) for another kind or
    a gap not known (negative: an older physics' contact).

    The gap is not the openness as heard: the stick pushes the top plate down, so at a gap of a millimetre or so
    the plates still meet under it and damp each other, and past that they ring free: the planner's open note
    (0.41 of 25 mm) is a fully open hat, not a 41 % one (a modelling choice, set in ZoneConfig).
    """
    if obj.kind != "hihat" or gap < 0.0:
        return -1.0
    low, high = zones.hihat_openness_from, zones.hihat_openness_full
    return min(max((gap - low) / (high - low), 0.0), 1.0)


PLAYABLE_KINDS = frozenset({"membrane", "cymbal", "hihat", "bell", "pedal"})
"""Object kinds whose contacts can be impacts (the throne and stands are not instruments)."""
