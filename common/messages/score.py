"""Score control: live notes and the controls of the score -> gesture pipeline."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from common.messages.base import Family, OscMessage, RigTime
from common.messages.registry import register

Text = Annotated[str, Field(min_length=1, max_length=512)]


@register
class LiveNote(OscMessage):
    """A drum note played live (e.g. from a MIDI controller bridged to OSC), sent to the physics node.

    The pitch maps to a drum event type with the General MIDI drum map (plus the
    Roland TD-11's 22 and 26); unknown pitches are counted and reported.

    Send it at least ``ScorePlayer.preparation_s`` before its rig time (services/physics/score_player.py: the
    shortest stroke of the gesture database plus ``SPLICE_MARGIN_S``, the least time a stroke can be prepared
    in; its value is in the refusal): a note with less lead is not played, only counted late and answered with
    `/batteur/physics/rejected`. Its ``time``, as every rig time, is two OSC arguments: whole seconds (`i`) then
    the fraction (`f`) (a float32 alone loses milliseconds after a few hours), so the message has five
    arguments, `i f i i i`.
    """

    ADDRESS = "/batteur/score/note"
    FAMILY = Family.CONTROL

    time: RigTime = Field(description="rig time the note should sound, seconds")
    pitch: int = Field(ge=0, le=127, description="MIDI note number (GM drum map)")
    velocity: int = Field(ge=0, le=127, description="MIDI velocity (0..127; mapped to 0..1)")
    channel: int = Field(ge=1, le=16, description="MIDI channel, 1-based (10 for GM drums)")


@register
class ScoreLoad(OscMessage):
    """Load a score (Standard MIDI File or Batteur text score) from the receiving node's score library."""

    ADDRESS = "/batteur/score/load"
    FAMILY = Family.CONTROL

    path: Text = Field(description="score file name (or path) inside the receiving node's score library "
                                   "(physics --score-dir); .mid or text")


@register
class ScoreTransport(OscMessage):
    """Start, stop or pause the loaded score."""

    ADDRESS = "/batteur/score/transport"
    FAMILY = Family.CONTROL

    action: Literal["play", "stop", "pause"] = Field(description="transport action")
    time: RigTime = Field(description="rig time at which the action takes effect, seconds")
    position: float = Field(ge=0, description="score position to play from, seconds")


@register
class GestureStyle(OscMessage):
    """Global grip, nuance, hand-assignment algorithm and sticking of the gesture planner."""

    ADDRESS = "/batteur/score/style"
    FAMILY = Family.CONTROL

    grip: Literal["french", "german"] = Field(description="stick grip")
    nuance: Literal["legato", "tenuto", "accent", "vertical_accent", "staccato"] = Field(
        description="global playing nuance (per-note nuances in the score win)"
    )
    algorithm: Literal["simple", "pairwise", "viterbi"] = Field(description="hand-assignment algorithm")
    sticking: Literal["none", "single", "double", "paradiddle"] = Field(description="sticking for rolls")


@register
class TempoScale(OscMessage):
    """Scale the score's tempo (1 = as written)."""

    ADDRESS = "/batteur/score/tempo"
    FAMILY = Family.CONTROL

    factor: float = Field(ge=0.25, le=4.0, description="tempo factor, 0.25..4 (2 = twice as fast)")


@register
class ScoreDynamics(OscMessage):
    """Play the score louder or softer: every score note's velocity times ``factor`` before planning (1 = as
    written), clipped to the loudest (velocity 1, MIDI 127); the strokes are planned faster or slower from it, as
    for a louder or softer written note. Live notes keep the velocity they are sent with."""

    ADDRESS = "/batteur/score/dynamics"
    FAMILY = Family.CONTROL

    factor: float = Field(ge=0.25, le=4.0, description="velocity factor, 0.25..4 (0.5 = half the written "
                                                       "velocity: softer; 2 = twice, up to the loudest: louder)")


@register
class ScoreLoop(OscMessage):
    """Repeat bars ``first``..``last`` of the playing score until told otherwise: when the play reaches the end of
    bar ``last`` it goes on at the start of bar ``first``, on the beat (the loop lasts those bars at the current
    tempo); ``0 0`` turns looping off (the play goes on past ``last`` after the pass in progress). Bars are counted
    from 1 as ``batteur compare`` and the physics logs count them (a pick-up is bar 0 and is not looped). A play
    already past ``last`` jumps back to ``first`` at the end of its bar. Sent while paused or before a ``play``,
    it applies to the next ``play``; a stop, a reset or a new score ends it."""

    ADDRESS = "/batteur/score/loop"
    FAMILY = Family.CONTROL

    first: int = Field(ge=0, description="first bar of the loop, from 1 (0 with last 0: looping off)")
    last: int = Field(ge=0, description="last bar of the loop (at least first; 0 with first 0: looping off)")


@register
class KitSelect(OscMessage):
    """Select the kit by shipped name or file path."""

    ADDRESS = "/batteur/score/kit"
    FAMILY = Family.CONTROL

    kit: Text = Field(description="shipped kit name (default, double_pedal, left_handed) or YAML/JSON path")
