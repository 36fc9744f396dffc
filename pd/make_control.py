"""Write pd/control.pd, Batteur's control panel for Pure Data vanilla (0.51+).

The panel is generated so its wiring stays consistent with the message models
(common/messages): every control below names the model it sends, and the
generator checks each one's OSC address and the kind of each argument (symbol, number,
whole number) against the model.
Run ``python pd/make_control.py`` after changing it (``--output PATH`` writes
elsewhere, ``--check`` only compares); tests/deploy/test_pd.py checks that the
file on disk is what this script writes.
"""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, get_args

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from common.messages import REGISTRY, OscMessage, WireKind  # noqa: E402
from common.messages.graphics import (  # noqa: E402
    GraphicsCamera,
    GraphicsLatency,
    GraphicsMode,
    GraphicsPlot,
    GraphicsPreviewBars,
    GraphicsPreviewRate,
    GraphicsRejected,
    GraphicsShow,
    GraphicsTrails,
    Layer,
)
from common.messages.interaction import InteractionError, RouteRemove, RouteSet  # noqa: E402
from common.messages.physics import PhysicsControlMode, PhysicsGrip, PhysicsRejected, PhysicsReset  # noqa: E402
from common.messages.score import (  # noqa: E402
    GestureStyle,
    ScoreDynamics,
    ScoreLoad,
    ScoreLoop,
    ScoreTransport,
    TempoScale,
)
from common.messages.sound import (  # noqa: E402
    SoundAirLoading,
    SoundDamping,
    SoundDensity,
    SoundLatency,
    SoundLevel,
    SoundMaster,
    SoundModel,
    SoundModes,
    SoundOpenness,
    SoundPosition,
    SoundRadius,
    SoundRejected,
    SoundResonances,
    SoundSecondHead,
    SoundSnares,
    SoundStick,
    SoundTension,
    SoundThickness,
)
from services.graphics.camera import PRESETS, camera_for, default_camera  # noqa: E402


def _master_defaults() -> tuple[float, float]:
    """(master gain dB, reverb 0..1) of a sound service started by ``batteur sound`` or ``batteur rig``."""
    from services.sound.core import SoundSettings
    from services.sound.node import SoundNodeSettings

    return (float(SoundSettings.model_fields["master_db"].default),
            float(SoundNodeSettings.model_fields["reverb"].default))


MASTER_DEFAULTS = _master_defaults()


def _tempo_default() -> float:
    """The tempo factor the physics node's score player starts with (services/physics/score_player.py)."""
    from services.physics.score_player import START_TEMPO

    return START_TEMPO


def _dynamics_default() -> float:
    """The velocity factor the physics node's score player starts with (services/physics/score_player.py)."""
    from services.physics.score_player import START_DYNAMICS

    return START_DYNAMICS


def _style_defaults() -> tuple[str, str, str, str]:
    """(grip, nuance, hand assignment, sticking) the physics node's score player plans with at start: the node's
    ``--grip`` as planned (``planned_grip``) and the score player's own start style."""
    from common.gesture.plan import planned_grip
    from services.physics.node import PhysicsNodeSettings
    from services.physics.score_player import START_ALGORITHM, START_NUANCE, START_STICKING

    grip = planned_grip(PhysicsNodeSettings.model_fields["grip"].default)
    return grip.value, START_NUANCE.value, START_ALGORITHM.value, START_STICKING.value


def _latency_defaults() -> tuple[float, float]:
    """(latency window s, picture delay s) of ``batteur sound`` and ``batteur graphics`` (and ``batteur rig``) at
    start: each node's ``--latency-s``, which the sound core schedules strikes by and the view delays its picture by."""
    from common.config import NodeSettings
    from services.graphics.node import GraphicsNodeSettings

    return (float(NodeSettings.model_fields["latency_s"].default),
            float(GraphicsNodeSettings.model_fields["latency_s"].default))


def _preview_rate_default() -> float:
    """The score preview's playback rate ``batteur graphics`` starts with (``--preview-rate``)."""
    from services.graphics.node import GraphicsNodeSettings

    return float(GraphicsNodeSettings.model_fields["preview_rate"].default)


def _trails_default() -> float:
    """The trails' length, seconds, the view starts with (services/graphics/core.py)."""
    from services.graphics.core import ViewSettings

    return float(ViewSettings().trails)


PARAMS_FIELDS = {"level": ("level_db",), "damping": ("damping0", "damping1"),
                 "stick": ("stick_mass", "stick_stiffness", "stick_exponent"),
                 "second_head": ("second_head", "reso_ratio")}
"""The instrument Params fields of a sound parameter not named after them (services/sound/instruments.py)."""


@functools.cache
def _kit_params() -> dict[str, tuple[str, Any]]:
    """instrument: (kind, Params) a sound service started with ``--kit default`` builds it with."""
    from common.kit import load_kit
    from services.sound.instruments import default_params

    return {obj.id: (obj.kind, default_params(obj)) for obj in load_kit("default").objects}


def instrument_starts(model: type[OscMessage]) -> dict[str, tuple[float, ...] | None]:
    """instrument: the values of the parameter ``model`` sets (in the message's order) a sound service starts it
    with on the default kit; None for an instrument without that parameter (tension of a cymbal: refused)."""
    from services.sound.core import PARAM_MESSAGES
    from services.sound.instruments import KIND_PARAMS

    param = PARAM_MESSAGES[model][0]
    starts: dict[str, tuple[float, ...] | None] = {}
    for name in INSTRUMENTS:
        kind, params = _kit_params()[name]
        fields = PARAMS_FIELDS.get(param, (param,))
        if param not in KIND_PARAMS[kind]:
            starts[name] = None
        elif param == "resonances":  # the first modes' gains: 1 for a mode the kit's list does not reach
            gains = tuple(float(g) for g in params.resonances[:RESONANCE_MODES])
            starts[name] = gains + (1.0,) * (RESONANCE_MODES - len(gains))
        else:
            starts[name] = tuple(float(getattr(params, f)) for f in fields)
    return starts


OUT = Path(__file__).with_name("control.pd")
SOUND_CLIENT = Path(__file__).with_name("sound-client.pd")


def _client_port() -> int:
    """The UDP port the Pd sound client (pd/sound-client.pd) listens on when not told otherwise: its ``[f PORT]``."""
    import re

    found = re.findall(r"^#X obj \d+ \d+ f (\d+);$", SOUND_CLIENT.read_text(encoding="utf-8"), re.MULTILINE)
    if len(found) != 1:
        raise SystemExit(f"{SOUND_CLIENT}: expected one [f PORT] (the port it listens on), found {found}")
    return int(found[0])


CLIENT_HOST = "127.0.0.1"
"""Where the INTERACTION section's route sends impacts by default, as the interaction node sees it: this machine
(the Pd sound client listens on loopback unless told ``sc-host``)."""
CLIENT_PORT = _client_port()
PORTS = {"physics": 9101, "interaction": 9102, "sound": 9103, "graphics": 9104, "score": 9101}
"""Default UDP port of each destination (compose.yaml's ports). Score messages go where the physics node's score
player is: the score port follows the physics port until it is set on its own (``bp-port-score``)."""
INSTRUMENTS = ("kick", "snare", "hightom", "midtom", "floortom", "hihat", "crash", "ride", "splash", "china",
               "cowbell")
COLORS = "-262144 -1 -1"
TEMPO_DEFAULT = _tempo_default()
DYNAMICS_DEFAULT = _dynamics_default()
LATENCY_DEFAULTS = _latency_defaults()
TRAILS_DEFAULT = _trails_default()


def esc(text: str) -> str:
    """Escape a Pd atom text: dollars, commas and semicolons."""
    return text.replace("$", "\\$").replace(",", " \\,").replace(";", " \\;")


@dataclass
class Patch:
    lines: list[str] = field(default_factory=list)
    count: int = 0
    connects: list[str] = field(default_factory=list)
    aside_x: int = 2000
    """x of the wiring kept right of the window (:meth:`aside`)"""
    asides: int = 0

    def aside(self) -> tuple[int, int]:
        """The next place right of the window (x from ``aside_x``) for wiring a user never needs to see, two a
        row, 700 x 230 pixels apart."""
        n = self.asides
        self.asides += 1
        return self.aside_x + 700 * (n % 2), 20 + 230 * (n // 2)

    def _add(self, line: str) -> int:
        self.lines.append(line)
        self.count += 1
        return self.count - 1

    def obj(self, x: int, y: int, text: str) -> int:
        return self._add(f"#X obj {x} {y} {esc(text)};")

    def msg(self, x: int, y: int, text: str, width: int = 0) -> int:
        """A message box; ``width`` in characters (0: as wide as its text, up to Pd's 60)."""
        suffix = f", f {width}" if width else ""
        return self._add(f"#X msg {x} {y} {esc(text)}{suffix};")

    def text(self, x: int, y: int, text: str, width: int = 0) -> int:
        """A comment; ``width`` in characters (0: Pd's default, 60)."""
        suffix = f", f {width}" if width else ""
        return self._add(f"#X text {x} {y} {esc(text)}{suffix};")

    def hsl(self, x: int, y: int, lo: float, hi: float, log: bool, receive: str, width: int = 160) -> int:
        return self._add(f"#X obj {x} {y} hsl {width} 15 {lo:g} {hi:g} {int(log)} 0 empty {receive} empty "
                         f"-2 -8 0 10 {COLORS} 0 1;")

    def nbx(self, x: int, y: int, lo: float, hi: float, width: int = 8, receive: str = "empty") -> int:
        return self._add(f"#X obj {x} {y} nbx {width} 14 {lo:g} {hi:g} 0 0 empty {receive} empty 0 -8 0 10 "
                         f"{COLORS} 0 256;")

    def tgl(self, x: int, y: int, receive: str = "empty") -> int:
        return self._add(f"#X obj {x} {y} tgl 17 0 empty {receive} empty 17 7 0 10 {COLORS} 0 1;")

    def bng(self, x: int, y: int, receive: str = "empty") -> int:
        return self._add(f"#X obj {x} {y} bng 17 250 50 0 empty {receive} empty 17 7 0 10 {COLORS};")

    def symbolatom(self, x: int, y: int, width: int, receive: str = "-", send: str = "-") -> int:
        return self._add(f"#X symbolatom {x} {y} {width} 0 0 0 - {receive} {send};")

    def subpatch(self, x: int, y: int, name: str, inner: Patch, window: tuple[int, int]) -> int:
        """A [pd NAME] box holding ``inner`` (closed at load; its window ``window`` pixels): one object here, its
        own objects numbered and wired inside. It talks to this patch by send and receive names only."""
        canvas = f"#N canvas 40 40 {window[0]} {window[1]} {name} 0;"
        return self._add("\n".join([canvas, *inner.lines, *inner.connects, f"#X restore {x} {y} pd {name};"]))

    def connect(self, a: int, outlet: int, b: int, inlet: int) -> None:
        self.connects.append(f"#X connect {a} {outlet} {b} {inlet};")

    def render(self) -> str:
        head = "#N canvas 20 20 1900 1000 12;"
        return "\n".join([head, *self.lines, *self.connects]) + "\n"


ACCEPTS = {WireKind.STR: "s", WireKind.FLOAT: "fi", WireKind.INT: "i"}
"""What the panel may send for each wire kind: ``s`` a symbol, ``f`` any number, ``i`` a whole number (Pd sends
every number as a float; the rig takes a float with an integral value where an int is expected, never a fraction)."""


def wire_signature(model: type[OscMessage]) -> str:
    """The model's wire kinds, one letter per OSC argument (a rig time is two: whole seconds ``i``, fraction ``f``);
    a variadic last field is its kind then ``*`` (any number of them, none included)."""
    return "".join(("if" if f.kind is WireKind.TIME else str(f.kind)) + ("*" if f.variadic else "")
                   for f in model.wire_fields())


def check_sends(model: type[OscMessage], sends: str) -> None:
    """Refuse (SystemExit, naming the control) a control whose address or argument kinds do not fit its model."""
    if REGISTRY.get(model.ADDRESS) is not model:
        raise SystemExit(f"{model.__name__}: {model.ADDRESS} is not the registered address of this model")
    expected = wire_signature(model)
    fixed, tail = (expected[:-2], expected[-2]) if expected.endswith("*") else (expected, "")
    count = len(sends) if tail else len(fixed)  # a variadic tail takes what follows the fixed arguments
    kinds = fixed + tail * (count - len(fixed))
    fits = len(sends) == len(kinds) and len(sends) >= len(fixed) and all(
        sent in ACCEPTS.get(WireKind(kind), kind) for sent, kind in zip(sends, kinds, strict=True))
    if not fits:
        takes = f"{fixed!r} then any number of {tail!r}" if tail else f"{fixed!r} ({len(fixed)})"
        raise SystemExit(f"{model.__name__} ({model.ADDRESS}): the panel sends {sends!r} "
                         f"({len(sends)} arguments), the model takes {takes}: "
                         "s symbol, f number, i whole number")


def sender(p: Patch, x: int, y: int, model: type[OscMessage], role: str, sends: str) -> int:
    """[oscformat ADDRESS] -> [s bp-out-ROLE]; returns the oscformat's index (its inlet takes the argument list).

    ``sends`` names what the control feeding it sends, one letter per argument: ``s`` a symbol, ``f`` a number,
    ``i`` a whole number; it is checked against the model (:func:`check_sends`)."""
    check_sends(model, sends)
    fmt = p.obj(x, y, "oscformat " + " ".join(model.ADDRESS.strip("/").split("/")))
    out = p.obj(x, y + 25, f"s bp-out-{role}")
    p.connect(fmt, 0, out, 0)
    return fmt


PANEL_BAD = "batteur-panel-bad"
"""What the panel prints (Pd's console) for a value it does not send: a number where a symbol goes, a choice that
is not one of its boxes'."""
INSTRUMENT_CHOSEN = "bp-instrument-chosen"
"""The instrument chosen, always as ``symbol NAME`` (bp-instrument takes ``crash`` or ``symbol crash``): what the
SOUND rows read."""
HOST_CHOSEN = "bp-host-chosen"
"""The services' host, always as ``symbol HOST`` (bp-host takes it bare or with ``symbol``)."""


def symbol_in(p: Patch, x: int, y: int, receive: str, values: tuple[str, ...] = ()) -> int:
    """[r RECEIVE] taking a symbol in either form Pd sends it: ``symbol crash`` (``pd -send``, a [symbol( box) and
    bare ``crash`` (a ``[; bp-instrument crash(`` box); returns the object whose outlet gives ``symbol VALUE``.
    A number or a bang is printed as ``batteur-panel-bad`` naming it and goes no further; with ``values``, so is
    a symbol not among them, so the panel keeps (and resends with the other choices) the last one it took."""
    r = p.obj(x, y, f"r {receive}")
    kind = p.obj(x, y + 25, "route float bang")
    p.connect(r, 0, kind, 0)
    takes = f"one of {' '.join(values)}" if values else "a symbol"
    number = p.msg(x + 330, y + 25, f"{receive} takes {takes} and got the number $1 - not sent", 60)
    bang = p.msg(x + 330, y + 75, f"{receive} takes {takes} and got a bang - not sent", 60)
    bad = p.obj(x + 330, y + 195, f"print {PANEL_BAD}")
    p.connect(kind, 0, number, 0)
    p.connect(kind, 1, bang, 0)
    p.connect(number, 0, bad, 0)
    p.connect(bang, 0, bad, 0)
    symbol = p.obj(x, y + 50, "symbol")  # "symbol crash", "crash", "list crash": symbol crash
    p.connect(kind, 2, symbol, 0)
    if not values:
        return symbol
    both = p.obj(x, y + 75, "t s s")  # hold it, then check it: a known value lets it out
    pending = p.obj(x, y + 125, "symbol")
    check = p.obj(x, y + 100, "select " + " ".join(values))
    p.connect(symbol, 0, both, 0)
    p.connect(both, 1, pending, 1)
    p.connect(both, 0, check, 0)
    for k in range(len(values)):
        p.connect(check, k, pending, 0)
    unknown = p.msg(x + 330, y + 125, f"{receive} takes {takes} and got $1 - not sent: the panel keeps the last "
                                      "one it took", 60)
    p.connect(check, len(values), unknown, 0)
    p.connect(unknown, 0, bad, 0)
    return pending


def choices(p: Patch, x: int, y: int, label: str, values: tuple[str, ...], receive: str) -> int:
    """Clickable [symbol VALUE( boxes and [r RECEIVE] (either symbol form, one of ``values`` only:
    :func:`symbol_in`); returns a [symbol] that outputs the choice."""
    p.text(x, y, label)
    store = p.obj(x, y + 60, "symbol")
    r = symbol_in(p, *p.aside(), receive, values)  # the wiring right of the window
    p.connect(r, 0, store, 0)
    cx = x
    for value in values:
        m = p.msg(cx, y + 25, f"symbol {value}")
        p.connect(m, 0, store, 0)
        cx += 12 + 9 * len(f"symbol {value}") // 2 + 40
    return store


def show_at_load(p: Patch, load: int, x: int, y: int, value: float, controls: tuple[int, ...]) -> None:
    """Make ``controls`` (a slider and its number box) show ``value`` from load: the value the panel keeps for
    them (in a pack), or the service's at start for a value sent alone. ``set`` changes what they show and sends
    nothing."""
    shown = p.msg(x, y, f"set {value:g}")
    p.connect(load, 0, shown, 0)
    for control in controls:
        p.connect(shown, 0, control, 0)


def slider_boxes(p: Patch, x: int, y: int, label: str, lo: float, hi: float, log: bool, receive: str,
                 integer: bool = False, shows: tuple[int, float] | None = None) -> tuple[int, tuple[int, int]]:
    """A slider and a number box: (the object whose outlet gives the value, (slider, number box)). ``shows``:
    ([loadbang], value) the service starts with, or the panel keeps for it, shown from load (:func:`show_at_load`)."""
    p.text(x, y, label)
    s = p.hsl(x, y + 22, lo, hi, log, receive)
    n = p.nbx(x + 175, y + 22, lo, hi)
    p.connect(s, 0, n, 0)
    if shows is not None:
        show_at_load(p, shows[0], x + 215, y, shows[1], (s, n))
    if integer:
        i = p.obj(x + 270, y + 22, "i")
        p.connect(n, 0, i, 0)
        return i, (s, n)
    return n, (s, n)


def slider(p: Patch, x: int, y: int, label: str, lo: float, hi: float, log: bool, receive: str,
           integer: bool = False, shows: tuple[int, float] | None = None) -> int:
    """A slider and a number box (:func:`slider_boxes`); returns the object whose outlet gives the value."""
    return slider_boxes(p, x, y, label, lo, hi, log, receive, integer, shows)[0]


def build() -> Patch:
    p = Patch()
    p.text(20, 10, "Batteur control panel (Pure Data vanilla 0.51+). Sends the rig's OSC over UDP to each service: "
                   "set the host and ports below (defaults: this machine and the ports of compose.yaml). Every "
                   "control also has a receive name (bp-...) so other patches can drive it. See docs/pd.md.", 150)
    # ------------------------------------------------------------ destinations
    p.text(20, 70, "destinations: host")
    p.symbolatom(160, 70, 14, "-", "bp-host")  # type a host, press Enter
    ax, ay = p.aside()
    p.connect(symbol_in(p, ax, ay, "bp-host"), 0, p.obj(ax, ay + 160, f"s {HOST_CHOSEN}"), 0)
    load = p.obj(760, 70, "loadbang")
    again = p.bng(460, 70, "bp-connect")
    p.text(485, 70, "(re)connect")
    x = 20
    nets: list[tuple[int, int, int]] = []
    """each [netsend] (index, x, y): the services' refusals come back through it"""
    boxes: dict[str, tuple[int, int]] = {}
    """role: (its port box, the [t b f] that reconnects it)"""
    for role, port in PORTS.items():
        p.text(x, 100, "score (= physics until set)" if role == "score" else role)
        nb = p.nbx(x, 122, 1, 65535, 6, f"bp-port-{role}")
        # the box shows the port in use from the start ("set": nothing is sent, the loadbang connects)
        shown = p.msg(x + 80, 122, f"set {port}")
        p.connect(load, 0, shown, 0)
        p.connect(shown, 0, nb, 0)
        tb = p.obj(x, 150, "t b f")
        boxes[role] = (nb, tb)
        if role != "score":
            p.connect(nb, 0, tb, 0)
        host = p.obj(x + 60, 180, "symbol 127.0.0.1")
        rh = p.obj(x + 60, 150, f"r {HOST_CHOSEN}")
        p.connect(rh, 0, host, 0)
        pk = p.obj(x, 210, f"pack s {port}")
        p.connect(tb, 1, pk, 1)
        p.connect(tb, 0, host, 0)
        p.connect(host, 0, pk, 0)
        p.connect(load, 0, host, 0)
        p.connect(again, 0, host, 0)
        con = p.msg(x, 235, "disconnect, connect $1 $2")
        p.connect(pk, 0, con, 0)
        r = p.obj(x + 110, 265, f"r bp-out-{role}")
        pre = p.obj(x + 110, 290, "list prepend send")
        trim = p.obj(x + 110, 315, "list trim")
        net = p.obj(x, 345, "netsend -u -b")
        p.connect(r, 0, pre, 0)
        p.connect(pre, 0, trim, 0)
        p.connect(trim, 0, net, 0)
        p.connect(con, 0, net, 0)
        nets.append((net, x, 345))
        x += 230
    score_follows_physics(p, x - 215, 265, boxes["physics"][0], *boxes["score"])
    # ------------------------------------------------------------ gesture: grip, nuance, style, mode
    y = 390
    p.text(20, y, "GESTURE (score and physics)")
    grip = choices(p, 20, y + 25, "grip", ("french", "german"), "bp-grip")
    nuance = choices(p, 20, y + 115, "nuance", ("legato", "tenuto", "accent", "vertical_accent", "staccato"),
                     "bp-nuance")
    algo = choices(p, 20, y + 205, "hand assignment", ("simple", "pairwise", "viterbi"), "bp-algorithm")
    stick = choices(p, 20, y + 295, "sticking", ("none", "single", "double", "paradiddle"), "bp-sticking")
    # the style message takes all four: keep them in [symbol]s, send all on any change; they start as the physics
    # node's score player does (_style_defaults), so a first change of one leaves the other three as they were
    stores = []
    fire = p.obj(420, y + 360, "t b b b b")
    for k, (src, default) in enumerate(zip((grip, nuance, algo, stick), _style_defaults(), strict=True)):
        keep = p.obj(420 + 70 * k, y + 390, f"symbol {default}")
        order = p.obj(300, y + 85 + 90 * k, "t b s")  # store first, then send all four
        p.connect(src, 0, order, 0)
        p.connect(order, 1, keep, 1)
        p.connect(order, 0, fire, 0)
        stores.append(keep)
    pack = p.obj(420, y + 420, "pack s s s s")
    for k, keep in enumerate(stores):
        p.connect(fire, k, keep, 0)  # right to left: the hot inlet (grip) last
        p.connect(keep, 0, pack, k)
    p.connect(pack, 0, sender(p, 420, y + 450, GestureStyle, "score", "ssss"), 0)
    # the grip also goes to physics (both hands)
    both = p.obj(620, y + 85, "list prepend both")
    p.connect(grip, 0, both, 0)
    p.connect(both, 0, sender(p, 620, y + 110, PhysicsGrip, "physics", "ss"), 0)
    mode = choices(p, 620, y + 180, "control mode", ("joint_pd", "joint_ct", "cartesian"), "bp-mode")
    p.connect(mode, 0, sender(p, 620, y + 270, PhysicsControlMode, "physics", "s"), 0)
    reset = p.msg(900, y + 25, "0 0")
    p.text(900, y, "reset drummer")
    rr = p.obj(960, y + 25, "r bp-reset")
    p.connect(rr, 0, reset, 0)
    p.connect(reset, 0, sender(p, 900, y + 50, PhysicsReset, "physics", "ii"), 0)
    # ------------------------------------------------------------ score: tempo, load, transport
    y2 = y + 500
    p.text(20, y2, "SCORE")
    tempo, tempo_boxes = slider_boxes(p, 20, y2 + 25, "tempo factor (0.25..4)", 0.25, 4.0, True, "bp-tempo",
                                      shows=(load, TEMPO_DEFAULT))
    p.connect(tempo, 0, sender(p, 20, y2 + 70, TempoScale, "score", "f"), 0)
    lo, hi = field_range(ScoreDynamics, "factor")
    dynamics, dynamics_boxes = slider_boxes(p, 20, y2 + 118, f"dynamics factor ({lo:g}..{hi:g})", lo, hi,
                                            True, "bp-dynamics", shows=(load, DYNAMICS_DEFAULT))
    # its sender beside it: the GRAPHICS section starts just below
    p.connect(dynamics, 0, sender(p, 280, y2 + 140, ScoreDynamics, "score", "f"), 0)
    p.text(330, y2 + 25, "score file (name in the score library \\, or path) - type and press Enter")
    # the box shows what bp-score takes (typing in it sends there; "set": no output, so no loop)
    p.symbolatom(330, y2 + 47, 30, "bp-score-show", "bp-score")
    ax, ay = p.aside()
    path = symbol_in(p, ax, ay, "bp-score")
    p.connect(path, 0, sender(p, 330, y2 + 75, ScoreLoad, "score", "s"), 0)
    show_path = p.msg(ax, ay + 160, "set $1")
    p.connect(path, 0, show_path, 0)
    p.connect(show_path, 0, p.obj(ax, ay + 185, "s bp-score-show"), 0)
    p.text(700, y2 + 25, "position s")
    pos = p.nbx(700, y2 + 47, 0, 100000, 6, "bp-position")
    play = p.msg(790, y2 + 47, "play")
    stop = p.msg(840, y2 + 47, "stop")
    pause = p.msg(890, y2 + 47, "pause")
    rt = symbol_in(p, *p.aside(), "bp-transport", ("play", "stop", "pause"))
    act = p.obj(790, y2 + 75, "symbol")
    for m in (play, stop, pause, rt):
        p.connect(m, 0, act, 0)
    # action, time 0 0 (rig time 0: at once), position
    tp = p.obj(790, y2 + 100, "pack s 0 0 0")
    p.connect(act, 0, tp, 0)
    p.connect(pos, 0, tp, 3)
    p.connect(tp, 0, sender(p, 790, y2 + 125, ScoreTransport, "score", "siif"), 0)
    # ------------------------------------------------------------ sound: a sub-patch of its own
    # (its 28 sliders and their wiring do not fit a laptop screen beside the others: click [pd sound] to open it)
    p.text(1200, 10, "SOUND - each instrument's synthesis, and the whole rig's latency, master gain and reverb: "
                     "click the box below (out of edit mode) to open them", 45)
    p.subpatch(1200, 80, "sound", sound_section(), SOUND_WINDOW)
    graphics_section(p, 20, y2 + 190, load)
    interaction_section(p, 900, 618, load)
    refusals(p, 995, 490, nets)
    loop_section(p, 1100, y2 + 25, load)  # last: the objects before keep their indices
    score_load_resets(p, path, tempo_boxes, dynamics_boxes)  # after it: added on 8 Dec, the others kept theirs
    return p


def score_load_resets(p: Patch, path: int, tempo: tuple[int, int], dynamics: tuple[int, int]) -> None:
    """Show the tempo and dynamics factors each score loaded (``path``: the name ``bp-score`` sends) plays at:
    physics puts them back to as written (``START_TEMPO``, ``START_DYNAMICS``) at every load, so the sliders and
    their number boxes show it too (``set``: nothing sent, a factor moved next is the new score's). Until 8 Dec they
    kept showing the factors of the score before. A load physics refuses keeps its factors: the panel cannot tell."""
    x, y = p.aside()
    for value, controls, dy in ((TEMPO_DEFAULT, tempo, 0), (DYNAMICS_DEFAULT, dynamics, 25)):
        shown = p.msg(x, y + dy, f"set {value:g}")
        p.connect(path, 0, shown, 0)
        for control in controls:
            p.connect(shown, 0, control, 0)


SOUND_WINDOW = (1900, 1000)
"""The [pd sound] window's size, pixels: its controls fit in it (a 1920x1080 laptop screen less its bars)."""
RESONANCE_MODES = 8
"""How many modes' resonance gains the panel sets (modes 1..8 in frequency order; the message may carry more, and
modes beyond those sent keep gain 1)."""
COLUMNS = (20, 650, 1280)
"""x of the [pd sound] window's three columns: a row's wiring reaches 610 px right of its slider."""


def field_range(model: type[OscMessage], name: str) -> tuple[float, float]:
    """(lowest, highest) value the model takes for field ``name`` (for a variadic field: each of its items), so a
    slider over it cannot send a value the rig refuses. SystemExit if the model declares no closed range."""
    import typing

    from pydantic.fields import FieldInfo

    metadata = list(model.model_fields[name].metadata)
    base = typing.get_type_hints(model, include_extras=True)[name]
    if typing.get_origin(base) is typing.Annotated:
        base = get_args(base)[0]
    if typing.get_origin(base) in (tuple, list):  # a variadic tail: the range is its items' (Annotated[float, ...])
        metadata = [c for extra in get_args(get_args(base)[0])[1:]
                    for c in (extra.metadata if isinstance(extra, FieldInfo) else [extra])]
    low = next((float(m.ge) for m in metadata if getattr(m, "ge", None) is not None), None)
    high = next((float(m.le) for m in metadata if getattr(m, "le", None) is not None), None)
    if low is None or high is None:
        raise SystemExit(f"{model.__name__}.{name}: no closed range (ge, le) for a slider to cover")
    return low, high


@dataclass(frozen=True)
class Row:
    """One slider of a sound group: its label, the model field it sets (its range is the model's) and receive name."""

    label: str
    field: str
    receive: str
    log: bool = False


def _span(model: type[OscMessage], row: Row) -> str:
    """A one-value row's label: what it sets and the model's range (``level dB (-80..12)``)."""
    low, high = field_range(model, row.field)
    return f"{row.label} ({low:g}..{high:g})"


def sound_section() -> Patch:
    """The SOUND section, in a sub-patch of its own ([pd sound]): the instrument choice, then every per-instrument
    control (each showing the chosen instrument's values), then the whole rig's latency, master gain and reverb.
    Three columns, each row's wiring to its right, the per-instrument memories beyond the window (x 2000)."""
    p = Patch(aside_x=3400)  # right of the per-instrument memories
    load = p.obj(560, 10, "loadbang")
    xa, xb, xc = COLUMNS
    p.text(xa, 10, "SOUND - instrument:")
    # shows the instrument the controls below act on; typing one in (and Enter) chooses it. The box only
    # displays what bp-instrument says ("set": no output), so choosing never loops back through it.
    p.symbolatom(xa + 160, 10, 10, "bp-instrument-show", "bp-instrument")
    sink = p.obj(xa + 300, 10, "s bp-instrument")
    # either symbol form, or a number refused; the rows read the chosen one, as "symbol NAME" (out of the way,
    # right of the window)
    ax, ay = p.aside()
    shown = symbol_in(p, ax, ay, "bp-instrument")
    p.connect(shown, 0, p.obj(ax, ay + 160, f"s {INSTRUMENT_CHOSEN}"), 0)
    show = p.msg(ax + 250, ay + 160, "set $1")
    p.connect(shown, 0, show, 0)
    p.connect(show, 0, p.obj(ax + 250, ay + 185, "s bp-instrument-show"), 0)
    for k, name in enumerate(INSTRUMENTS):
        m = p.msg(xa + 100 * (k % 6), 40 + 25 * (k // 6), f"symbol {name}")
        p.connect(m, 0, sink, 0)
    init_inst = p.msg(xa + 400, 10, "symbol snare")
    p.connect(load, 0, init_inst, 0)
    p.connect(init_inst, 0, sink, 0)
    memories = iter(range(100))

    def memory(label: str, sent: int, model: type[OscMessage], keeps: tuple[int, ...],
               shown: tuple[tuple[int, ...], ...]) -> tuple[int, int]:
        return instrument_memory(p, 2000, 100 + 340 * next(memories), f"{label} per instrument (starts at the "
                                 "default kit's values)", sent, instrument_starts(model), keeps, shown)

    def per_instrument(x: int, y: int, model: type[OscMessage], source: int, values: str) -> int:
        """[list prepend] with the chosen instrument (from bp-instrument), to the model's sender; returns it."""
        pre = p.obj(x + 360, y, "list prepend")
        r = p.obj(x + 460, y - 25, f"r {INSTRUMENT_CHOSEN}")
        p.connect(r, 0, pre, 1)
        p.connect(source, 0, pre, 0)
        p.connect(pre, 0, sender(p, x + 360, y + 25, model, "sound", "s" + values), 0)
        return pre

    model = choices(p, xa, 100, "synthesis model", ("modal", "sample", "synth"), "bp-model")
    per_instrument(xa, 185, SoundModel, model, "s")
    # one value each: five rows in the first column, five in the second
    rows: list[tuple[type[OscMessage], Row, bool]] = [
        (SoundLevel, Row("level dB", "gain_db", "bp-level"), False),
        (SoundRadius, Row("radius m", "value", "bp-radius"), False),
        (SoundTension, Row("tension N/m", "value", "bp-tension", log=True), False),
        (SoundDensity, Row("density kg/m2", "value", "bp-density", log=True), False),
        (SoundModes, Row("modes", "value", "bp-modes", log=True), True),
        (SoundThickness, Row("thickness m", "value", "bp-thickness"), False),
        (SoundPosition, Row("position sensitivity", "value", "bp-position-sensitivity"), False),
        (SoundSnares, Row("snares", "value", "bp-snares"), False),
        (SoundOpenness, Row("openness", "value", "bp-openness"), False),
        (SoundAirLoading, Row("air loading", "value", "bp-air"), False),
    ]
    for k, (m_, row, integer) in enumerate(rows):
        x, y = (xa, 250 + 80 * k) if k < 5 else (xb, 100 + 80 * (k - 5))
        lo, hi = field_range(m_, row.field)
        src, row_boxes = slider_boxes(p, x, y, _span(m_, row), lo, hi, row.log, row.receive, integer)
        per_instrument(x, y + 22, m_, src, "i" if integer else "f")
        # the boxes show the chosen instrument's value (the snare's at load), kept in the memories
        memory(row.label, src, m_, (), (row_boxes,))
    # several values in one message: each kept per instrument, all sent when one moves
    groups: list[tuple[int, int, str, str, type[OscMessage], tuple[Row, ...]]] = [
        (xa, 650, "damping", "damping: sigma0 1/s, sigma1 s", SoundDamping,
         (Row("sigma0", "sigma0", "bp-sigma0"), Row("sigma1", "sigma1", "bp-sigma1"))),
        (xb, 500, "second head", "second head (drums): gain, tuning ratio", SoundSecondHead,
         (Row("gain", "gain", "bp-second-head-gain"), Row("ratio", "ratio", "bp-second-head-ratio"))),
        (xb, 700, "stick", "stick: mass kg, stiffness N/m^alpha, alpha", SoundStick,
         (Row("kg", "mass", "bp-stick-mass", log=True), Row("N/m^a", "stiffness", "bp-stick-stiffness", log=True),
          Row("alpha", "exponent", "bp-stick-exponent"))),
        (xc, 100, "resonances", f"resonance gain of modes 1..{RESONANCE_MODES} (0..16)", SoundResonances,
         tuple(Row(f"{k + 1}", "gains", f"bp-resonance-{k + 1}") for k in range(RESONANCE_MODES))),
    ]
    for x, y, name, header, m_, group in groups:
        sent, keeps, boxes, pre = slider_group(p, x, y, header, m_, group, per_instrument)
        store, split = memory(name, sent, m_, keeps, boxes)
        if m_ is SoundResonances:  # reset: every mode back to gain 1 (an empty list), shown and kept as ones
            reset = p.bng(x + 400, y, "bp-resonances-reset")
            p.text(x + 422, y, "reset (all 1)")
            check_sends(m_, "s")
            order = p.obj(x + 520, y, "t b b")
            ones = p.msg(x + 470, y + 72 + 25 * len(group), " ".join(["1"] * len(group)))
            p.connect(reset, 0, order, 0)
            p.connect(order, 1, ones, 0)
            p.connect(ones, 0, store, 0)
            p.connect(ones, 0, split, 0)
            p.connect(order, 0, pre, 0)  # a bang: the instrument alone
    # ------------------------------------------------------------ the whole rig
    x, yy = xc, 470
    p.text(x, yy, "SOUND - whole rig")
    lat = slider(p, x, yy + 25, "latency window s (0..0.5)", 0, 0.5, False, "bp-latency",
                 shows=(load, LATENCY_DEFAULTS[0]))
    p.connect(lat, 0, sender(p, x + 300, yy + 47, SoundLatency, "sound", "f"), 0)
    p.text(x, yy + 100, "master gain dB (-80..12) and reverb (0..1)")
    g = p.hsl(x, yy + 122, -80, 12, False, "bp-master")
    gn = p.nbx(x + 175, yy + 122, -80, 12)
    rv = p.hsl(x, yy + 147, 0, 1, False, "bp-reverb")
    rn = p.nbx(x + 175, yy + 147, 0, 1)
    p.connect(g, 0, gn, 0)
    p.connect(rv, 0, rn, 0)
    # the pack starts as the sound service does, so moving one control first keeps the other as it is there
    mp = p.obj(x + 280, yy + 175, f"pack {MASTER_DEFAULTS[0]:g} {MASTER_DEFAULTS[1]:g}")
    for value, controls, row_y in ((MASTER_DEFAULTS[0], (g, gn), 122), (MASTER_DEFAULTS[1], (rv, rn), 147)):
        show_at_load(p, load, x + 380, yy + row_y, value, controls)  # and the controls show it
    t2 = p.obj(x + 280, yy + 147, "t b f")
    p.connect(gn, 0, mp, 0)
    p.connect(rn, 0, t2, 0)
    p.connect(t2, 1, mp, 1)
    p.connect(t2, 0, mp, 0)
    p.connect(mp, 0, sender(p, x + 280, yy + 200, SoundMaster, "sound", "ff"), 0)
    return p


def slider_group(p: Patch, x: int, y: int, header: str, model: type[OscMessage], rows: tuple[Row, ...],
                 per_instrument: Callable[[int, int, type[OscMessage], int, str], int],
                 ) -> tuple[int, tuple[int, ...], tuple[tuple[int, int], ...], int]:
    """The sliders of one message carrying several values (second head, stick, resonances), one under the other,
    each labelled on its right (with its range when the rows set different fields): each value is kept in an [f]
    (per instrument: see :func:`instrument_memory`) and a move of one sends them all, each clipped to its field's
    range in the model (which the sliders cover): a value past a slider's end sent to its receive name, or the 0 an
    instrument without the parameter shows, goes out in range (the service then answers what it refuses, instead
    of the message being dropped unanswered). Returns (the [pack] of the values, the [f]s, each row's (slider,
    number box), the [list prepend] that adds the instrument)."""
    p.text(x, y, header)
    count = len(rows)
    same = len({row.field for row in rows}) == 1  # the resonances: one range, said in the header
    boxes: list[tuple[int, int]] = []
    keeps: list[int] = []
    fire = p.obj(x + 400, y + 22 + 25 * count, "t " + " ".join(["b"] * count))
    pack = p.obj(x + 280, y + 47 + 25 * count, "pack " + " ".join(["f"] * count))
    for k, row in enumerate(rows):
        lo, hi = field_range(model, row.field)
        row_y = y + 22 + 25 * k
        s = p.hsl(x, row_y, lo, hi, row.log, row.receive)
        n = p.nbx(x + 175, row_y, lo, hi)
        p.connect(s, 0, n, 0)
        boxes.append((s, n))
        p.text(x + 250, row_y, row.label if same else f"{row.label} {lo:g}..{hi:g}")
        order = p.obj(x + 400, row_y, "t b f")  # keep it, then send all
        keep = p.obj(x + 450, row_y, "f")
        clip = p.obj(x + 480, row_y, f"clip {lo:g} {hi:g}")
        p.connect(n, 0, order, 0)
        p.connect(order, 1, keep, 1)
        p.connect(order, 0, fire, 0)
        p.connect(fire, k, keep, 0)  # right to left: the first value, the pack's hot inlet, last
        p.connect(keep, 0, clip, 0)
        p.connect(clip, 0, pack, k)
        keeps.append(keep)
    pre = per_instrument(x, y + 72 + 25 * count, model, pack, "f" * count)
    return pack, tuple(keeps), tuple(boxes), pre


def instrument_memory(p: Patch, x: int, y: int, label: str, sent: int, starts: dict[str, tuple[float, ...] | None],
                      keeps: tuple[int, ...], shown: tuple[tuple[int, ...], ...]) -> tuple[int, int]:
    """Remember a sound parameter per instrument: it starts at what a sound service started on the default kit has
    (``starts``, :func:`instrument_starts`), is updated by each value (or list of values) ``sent`` for the chosen
    instrument, and is recalled into ``keeps`` (the [f]s a message of several values is made of, so moving one
    slider keeps the others) and ``shown`` (each value's slider and number box) when an instrument is chosen.
    An instrument without the parameter (None) shows 0 and keeps nothing: the service refuses what is sent.
    Returns (the [list prepend] that stores a sent list for the chosen instrument, the [unpack] that shows one)."""
    p.text(x, y, label)
    store = p.obj(x, y + 25, "list prepend")
    p.connect(sent, 0, store, 0)
    p.connect(p.obj(x + 420, y, f"r {INSTRUMENT_CHOSEN}"), 0, store, 1)
    trim = p.obj(x, y + 50, "list trim")  # "kick S0 S1": routed by its selector
    p.connect(store, 0, trim, 0)
    takes = [name for name, values in starts.items() if values is not None]
    by_name = p.obj(x, y + 75, "route " + " ".join(takes))
    p.connect(trim, 0, by_name, 0)
    chosen = p.obj(x, y + 150, "select " + " ".join(starts))
    p.connect(p.obj(x, y + 125, f"r {INSTRUMENT_CHOSEN}"), 0, chosen, 0)
    count = len(shown)
    split = p.obj(x, y + 285, "unpack " + " ".join("f" * count))
    texts = ["list append " + " ".join(f"{v:g}" for v in ((0.0,) * count if values is None else values))
             for values in starts.values()]
    pitch = max(150, 7 * max(map(len, texts)) + 20)  # side by side, four a row
    for k, ((name, values), text) in enumerate(zip(starts.items(), texts, strict=True)):
        memory = p.obj(x + pitch * (k % 4), y + 200 + 25 * (k // 4), text)
        if values is not None:
            p.connect(by_name, takes.index(name), memory, 1)
        p.connect(chosen, k, memory, 0)
        p.connect(memory, 0, split, 0)
    for k, boxes in enumerate(shown):
        if keeps:
            p.connect(split, k, keeps[k], 1)
        show = p.msg(x + 100 * k, y + 310, "set $1")
        p.connect(split, k, show, 0)
        for box in boxes:
            p.connect(show, 0, box, 0)
    return store, split


def score_follows_physics(p: Patch, x: int, y: int, physics_box: int, score_box: int, score_tb: int) -> None:
    """Score messages go to the physics port (the score player is in the physics node) and the score box shows it,
    until the score port is set on its own (its box or ``bp-port-score``): then it stays where it was set."""
    follow = p.obj(x, y, "spigot 1")
    p.connect(physics_box, 0, follow, 0)
    both = p.obj(x, y + 25, "t f f")  # show first, then reconnect
    p.connect(follow, 0, both, 0)
    show = p.msg(x, y + 50, "set $1")
    p.connect(both, 1, show, 0)
    p.connect(show, 0, score_box, 0)
    p.connect(both, 0, score_tb, 0)
    own = p.obj(x + 50, y, "t f b")  # set on its own: stop following, then reconnect
    p.connect(score_box, 0, own, 0)
    stop = p.msg(x + 50, y + 25, "0")
    p.connect(own, 1, stop, 0)
    p.connect(stop, 0, follow, 1)
    p.connect(own, 0, score_tb, 0)


CAMERA_PRESETS = ("front", "side", "top", "drummer", "orbit", "free")
_DEFAULT_CAMERA = default_camera()
CAMERA_DEFAULTS = {"azimuth": _DEFAULT_CAMERA["azimuth_deg"], "elevation": _DEFAULT_CAMERA["elevation_deg"],
                   "distance": _DEFAULT_CAMERA["distance"],
                   **dict(zip(("target-x", "target-y", "target-z"), _DEFAULT_CAMERA["target"], strict=True))}
"""What the camera pack starts with: the view's default camera (services/graphics/camera.py, the page's front
preset), so a slider moved first (sent as ``free`` with every value so far) keeps the framing the page had."""


def _preset_numbers() -> dict[str, tuple[float, ...]]:
    """Each named preset's numbers in the camera pack's order (azimuth, elevation, distance, target x y z), as the
    view applies them (services/graphics/camera.py; the orbit preset's start): choosing a preset puts them in the
    pack and the sliders, so a slider moved next starts from the view the preset shows, not from the last free one."""
    numbers: dict[str, tuple[float, ...]] = {}
    for name in PRESETS:
        cam = camera_for(name, 0.0, 0.0, 1.0, (0.0, 0.0, 0.0))
        numbers[name] = (round(cam["azimuth_deg"], 2), round(cam["elevation_deg"], 2), round(cam["distance"], 3),
                         *(round(v, 3) for v in cam["target"]))
    return numbers


PRESET_NUMBERS = _preset_numbers()


def _plot_defaults() -> dict[str, float]:
    """The view's tip-height plot at start (services/graphics/core.py): window s, lowest and highest height m."""
    from services.graphics.core import ViewSettings

    plot = ViewSettings().plot
    return {key: plot[key] for key in ("window", "z_min", "z_max")}


PLOT_DEFAULTS = _plot_defaults()
"""What the plot pack starts with, in its order (window, z_min, z_max), and its sliders show."""


def graphics_section(p: Patch, x: int, y: int, load: int) -> None:
    """The 2009 paper's middle panel: camera, what is drawn, trails, tip-height plot, delay, mode, the score
    preview's speed and bars (to graphics)."""
    p.text(x, y, "GRAPHICS - the 3D view (graphics node)")
    # camera: a preset, or free with the orbit angles, distance and target
    preset = choices(p, x, y + 25, "camera preset", CAMERA_PRESETS, "bp-camera")
    cam = p.obj(x + 300, y + 470, "pack s " + " ".join(f"{v:g}" for v in CAMERA_DEFAULTS.values()))
    # a named preset first puts its own numbers in the pack and shows them (set: nothing sent), then is sent
    chosen = p.obj(x + 150, y + 440, "t s s")
    p.connect(preset, 0, chosen, 0)
    p.connect(chosen, 0, cam, 0)
    pick = p.obj(x, y + 500, "sel " + " ".join(PRESET_NUMBERS))
    p.connect(chosen, 1, pick, 0)
    numbers = p.obj(x, y + 660, "unpack f f f f f f")
    for k, values in enumerate(PRESET_NUMBERS.values()):
        m = p.msg(x + 40 * k, y + 530 + 25 * k, " ".join(f"{v:g}" for v in values))
        p.connect(pick, k, m, 0)
        p.connect(m, 0, numbers, 0)
    free = p.msg(x + 300, y + 440, "symbol free")
    p.connect(free, 0, cam, 0)
    rows = [("azimuth deg (-180..180)", -180, 180, False), ("elevation deg (-10..89)", -10, 89, False),
            ("distance m (0.5..10)", 0.5, 10, True), ("target x m (-2..2)", -2, 2, False),
            ("target y m (-2..2)", -2, 2, False), ("target z m (0..2)", 0, 2, False)]
    for k, ((label, lo, hi, log), name) in enumerate(zip(rows, CAMERA_DEFAULTS, strict=True)):
        col, row = k % 2, k // 2
        value, shown = slider_boxes(p, x + 300 * col, y + 120 + 60 * row, label, lo, hi, log, f"bp-{name}",
                                    shows=(load, CAMERA_DEFAULTS[name]))
        order = p.obj(x + 300 * col + 270, y + 142 + 60 * row, "t b f")  # the value first, then send as free
        p.connect(value, 0, order, 0)
        p.connect(order, 1, cam, k + 1)
        p.connect(order, 0, free, 0)
        show = p.msg(x + 300 * col + 215, y + 160 + 60 * row, "set $1")  # a preset's number, shown
        p.connect(numbers, k, cam, k + 1)
        p.connect(numbers, k, show, 0)
        for box in shown:
            p.connect(show, 0, box, 0)
    p.connect(cam, 0, sender(p, x + 300, y + 500, GraphicsCamera, "graphics", "sffffff"), 0)
    # layers: one toggle each, shown at load (the view starts with everything drawn)
    layers: tuple[str, ...] = get_args(Layer)
    p.text(x + 700, y + 25, "show")
    show = sender(p, x + 960, y + 50, GraphicsShow, "graphics", "si")
    init = p.msg(x + 960, y + 110, "; " + "; ".join(f"bp-show-{name} set 1" for name in layers))
    p.connect(load, 0, init, 0)
    for k, name in enumerate(layers):
        t = p.tgl(x + 700, y + 50 + 24 * k, f"bp-show-{name}")
        p.text(x + 722, y + 50 + 24 * k, name)
        pre = p.obj(x + 800, y + 50 + 24 * k, f"list prepend {name}")
        p.connect(t, 0, pre, 0)
        p.connect(pre, 0, show, 0)
    # trails, tip-height plot, delay, mode
    trails = slider(p, x + 700, y + 250, "trails s (0..10; 0 hides)", 0, 10, False, "bp-trails",
                    shows=(load, TRAILS_DEFAULT))
    p.connect(trails, 0, sender(p, x + 1000, y + 272, GraphicsTrails, "graphics", "f"), 0)
    plot = p.obj(x + 1060, y + 510, "pack " + " ".join(f"{v:g}" for v in PLOT_DEFAULTS.values()))
    window = slider(p, x + 700, y + 320, "plot window s (0.5..30)", 0.5, 30, True, "bp-plot-window",
                    shows=(load, PLOT_DEFAULTS["window"]))
    p.connect(window, 0, plot, 0)
    for k, (label, receive, key) in enumerate((("plot lowest height m (-1..3)", "bp-plot-zmin", "z_min"),
                                               ("plot highest height m (-1..3)", "bp-plot-zmax", "z_max"))):
        value = slider(p, x + 700, y + 380 + 60 * k, label, -1, 3, False, receive, shows=(load, PLOT_DEFAULTS[key]))
        order = p.obj(x + 970, y + 402 + 60 * k, "t b f")
        p.connect(value, 0, order, 0)
        p.connect(order, 1, plot, k + 1)
        p.connect(order, 0, plot, 0)
    p.connect(plot, 0, sender(p, x + 1060, y + 540, GraphicsPlot, "graphics", "fff"), 0)
    latency = slider(p, x + 300, y + 320, "picture delay s (0..0.5; = the sound's latency)", 0, 0.5, False,
                     "bp-view-latency", shows=(load, LATENCY_DEFAULTS[1]))
    p.connect(latency, 0, sender(p, x + 300, y + 370, GraphicsLatency, "graphics", "f"), 0)
    mode = choices(p, x, y + 320, "view", ("live", "preview"), "bp-view-mode")
    p.connect(mode, 0, sender(p, x, y + 410, GraphicsMode, "graphics", "s"), 0)
    # the score preview's speed and bar range, live (a node with no score preview refuses them: REFUSALS)
    rate = slider(p, x + 700, y + 560, "preview speed (0.25..2, 1: as planned)", 0.25, 2, False, "bp-preview-rate",
                  shows=(load, _preview_rate_default()))
    p.connect(rate, 0, sender(p, x + 1000, y + 582, GraphicsPreviewRate, "graphics", "f"), 0)
    p.text(x + 700, y + 620, "preview bars: first, last (from 1)")
    bars = p.obj(x + 700, y + 670, "pack 1 1")
    for k, receive in enumerate(("bp-preview-first", "bp-preview-last")):
        box = p.nbx(x + 700 + 90 * k, y + 642, 1, 9999, 5, receive)
        show_at_load(p, load, x + 1030 + 50 * k, y + 700, 1, (box,))  # bar 1, not the box's 0
        whole = p.obj(x + 760 + 90 * k, y + 642, "i")  # the bars are whole numbers
        p.connect(box, 0, whole, 0)
        if k == 0:  # the first bar: the last one moved up to it if below (a range ending first is refused), shown
            first, at_least = p.obj(x + 700, y + 700, "t f f"), p.obj(x + 740, y + 730, "max 1")
            at_most = p.obj(x + 1140, y + 642, "min 1")  # the last bar's side: the first bar so far, kept here
            p.connect(whole, 0, first, 0)
            p.connect(first, 1, at_least, 0)
            p.connect(first, 1, at_most, 1)
            p.connect(at_least, 0, bars, 1)
            p.connect(first, 0, bars, 0)
            shown = p.msg(x + 790, y + 730, "set $1")
            p.connect(at_least, 0, shown, 0)
            first_box = box
        else:  # the last bar: stored, then the pair sent with the first bar moved down to it if above, shown (as
            # the page's boxes do; until 7 Dec the pair was sent as it was, 2 1, and refused)
            order = p.obj(x + 880, y + 670, "t f f")
            p.connect(whole, 0, order, 0)
            p.connect(order, 1, bars, 1)
            p.connect(order, 1, at_least, 1)
            p.connect(order, 0, at_most, 0)
            moved = p.obj(x + 1140, y + 680, "t f f")
            p.connect(at_most, 0, moved, 0)
            p.connect(moved, 1, at_most, 1)  # the first bar as moved, kept (a cold inlet: no loop)
            p.connect(moved, 0, bars, 0)
            shown_first = p.msg(x + 1190, y + 710, "set $1")
            p.connect(moved, 1, shown_first, 0)
            p.connect(shown_first, 0, first_box, 0)
            p.connect(shown, 0, box, 0)
    all_bars = p.msg(x + 880, y + 642, "0 0")  # the whole score again
    p.text(x + 920, y + 642, "whole score")
    p.connect(p.obj(x + 880, y + 700, "r bp-preview-all"), 0, all_bars, 0)
    send_bars = sender(p, x + 700, y + 760, GraphicsPreviewBars, "graphics", "ii")
    p.connect(bars, 0, send_bars, 0)
    p.connect(all_bars, 0, send_bars, 0)


def loop_section(p: Patch, x: int, y: int, load: int) -> None:
    """The playing score's loop (to physics): the bars typed in two boxes (from 1, as the physics log counts them)
    are sent by [loop( (each send re-plans the score: not at every digit typed); [0 0( turns looping off."""
    p.text(x, y, "loop bars (from 1): first, last, then click loop")
    p.text(x + 360, y + 22, "looping off")
    fire = p.obj(x + 180, y + 47, "t b b")
    bars = p.obj(x, y + 105, "pack 1 1")
    for k, receive in enumerate(("bp-loop-first", "bp-loop-last")):
        box = p.nbx(x + 90 * k, y + 22, 1, 9999, 5, receive)
        show_at_load(p, load, x + 470 + 50 * k, y + 22, 1, (box,))  # bar 1, as the store starts, not the box's 0
        whole = p.obj(x + 90 * k, y + 47, "i")  # the bars are whole numbers
        store = p.obj(x + 90 * k, y + 75, "f 1")  # kept until [loop( is clicked
        p.connect(box, 0, whole, 0)
        p.connect(whole, 0, store, 1)
        p.connect(fire, k, store, 0)  # right to left: the last bar into the pack (cold) first, then the first (hot)
        p.connect(store, 0, bars, k)
    loop = p.msg(x + 180, y + 22, "loop")
    p.connect(loop, 0, fire, 0)
    p.connect(p.obj(x + 230, y + 22, "r bp-loop"), 0, fire, 0)
    off = p.msg(x + 320, y + 22, "0 0")
    p.connect(p.obj(x + 320, y + 47, "r bp-loop-off"), 0, off, 0)
    send = sender(p, x, y + 130, ScoreLoop, "score", "ii")
    p.connect(bars, 0, send, 0)
    p.connect(off, 0, send, 0)


def interaction_section(p: Patch, x: int, y: int, load: int) -> None:
    """Route the rig's impacts to the Pd sound client (or remove that route): ``route/set HOST:PORT *`` and
    ``route/remove HOST:PORT`` to interaction, HOST:PORT from the client boxes (defaults: this machine and the
    port the client listens on). The boxes only choose: nothing is sent until a button is pressed. The controls
    sit at (x, y); their wiring below and to the left, between the control mode and the transport."""
    p.text(x, y, "INTERACTION - to the Pd sound client")
    p.text(x, y + 25, "client host")
    # the box shows what bp-client-host holds (typing in it sends there); "set": no output, so no loop
    p.symbolatom(x + 95, y + 25, 14, "bp-client-host-show", "bp-client-host")
    p.text(x, y + 50, "client port")
    port_box = p.nbx(x + 95, y + 50, 1, 65535, 6, "bp-client-port")
    show_at_load(p, load, x + 165, y + 50, CLIENT_PORT, (port_box,))
    route = p.bng(x, y + 77, "bp-client-route")
    p.text(x + 22, y + 77, "route impacts")
    remove = p.bng(x + 135, y + 77, "bp-client-remove")
    p.text(x + 157, y + 77, "remove route")
    wx, wy = x - 190, y + 102  # the wiring
    r_host = symbol_in(p, *p.aside(), "bp-client-host")
    show_host = p.msg(wx + 130, wy, "set $1")
    host_shown = p.obj(wx + 190, wy, "s bp-client-host-show")
    p.connect(r_host, 0, show_host, 0)
    p.connect(show_host, 0, host_shown, 0)
    at_load = p.msg(wx + 350, wy, f"set {CLIENT_HOST}")
    p.connect(load, 0, at_load, 0)
    p.connect(at_load, 0, host_shown, 0)
    # HOST:PORT: the host goes into the format ("set HOST:%d"), then the port through it
    host = p.obj(wx, wy + 25, f"symbol {CLIENT_HOST}")
    p.connect(r_host, 0, host, 1)
    build = p.obj(wx + 140, wy + 25, "t b b")  # the host's format first, then the port through it
    port = p.obj(wx + 200, wy + 25, f"f {CLIENT_PORT}")
    p.connect(port_box, 0, port, 1)
    fmt = p.msg(wx, wy + 50, "set $1:%d")
    p.connect(host, 0, fmt, 0)
    target = p.obj(wx, wy + 75, f"makefilename {CLIENT_HOST}:%d")
    p.connect(fmt, 0, target, 0)
    p.connect(port, 0, target, 0)
    p.connect(build, 1, host, 0)
    p.connect(build, 0, port, 0)
    places = ((wx + 180, wy + 100), (wx, wy + 150))
    controls: tuple[tuple[int, type[OscMessage], str], ...] = ((route, RouteSet, "ss"), (remove, RouteRemove, "s"))
    for k, (button, model, sends) in enumerate(controls):
        cx = wx + 290 + 100 * k
        order = p.obj(cx, wy + 25, "t b b")  # make HOST:PORT, then send it
        p.connect(button, 0, order, 0)
        p.connect(order, 1, build, 0)
        keep = p.obj(cx, wy + 50, "symbol")
        p.connect(target, 0, keep, 1)
        p.connect(order, 0, keep, 0)
        out = sender(p, *places[k], model, "interaction", sends)
        if model is RouteSet:
            every = p.obj(cx, wy + 75, "list append *")  # every instrument
            p.connect(keep, 0, every, 0)
            p.connect(every, 0, out, 0)
        else:
            p.connect(keep, 0, out, 0)


REFUSALS: tuple[type[OscMessage], ...] = (PhysicsRejected, SoundRejected, InteractionError, GraphicsRejected)
"""Each service's answer to a control it refused (docs/osc.md; physics answers for score messages too). It goes
back to the address and port the control came from: the [netsend] that sent it, whose second outlet gives it."""


def check_refusal(model: type[OscMessage]) -> tuple[str, str]:
    """(service, name) of a refusal at /batteur/SERVICE/NAME; SystemExit if the panel could not show it: it shows
    the first argument (the refused address) and the last (why), so every argument must be a symbol."""
    parts = model.ADDRESS.strip("/").split("/")
    signature = wire_signature(model)
    if REGISTRY.get(model.ADDRESS) is not model or len(parts) != 3 or parts[0] != "batteur" or \
            len(signature) < 2 or signature != "s" * len(signature):
        raise SystemExit(f"{model.__name__} ({model.ADDRESS}, {signature!r}): the panel shows refusals at "
                         "/batteur/SERVICE/NAME whose arguments are symbols, the refused address first and the "
                         "reason last")
    return parts[1], parts[2]


def refusals(p: Patch, x: int, y: int, nets: list[tuple[int, int, int]]) -> None:
    """Show the last refusal any service answered (its address and reason), print it to Pd's console as
    ``batteur-rejected ADDRESS REASON`` and send it to ``bp-rejected``; ``nets``: the [netsend]s (index, x, y) it comes
    back to."""
    p.text(x, y, "LAST REFUSAL (address, why)")
    # the display shows what bp-rejected carries (so another patch may show its own there too)
    show = p.obj(x, y + 50, "list prepend set")
    p.connect(p.obj(x, y + 25, "r bp-rejected"), 0, show, 0)
    set_text = p.obj(x + 130, y + 50, "list trim")
    p.connect(show, 0, set_text, 0)
    p.connect(set_text, 0, p.msg(x, y + 80, "none yet", 27), 0)
    for net, nx, ny in nets:
        p.connect(net, 1, p.obj(nx + 110, ny, "s bp-replies"), 0)
    # the parsing sits out of the way, below and right of the other sections
    px, py = 1420, 1480
    parse = p.obj(px, py + 25, "oscparse")
    p.connect(p.obj(px, py, "r bp-replies"), 0, parse, 0)
    trim = p.obj(px, py + 50, "list trim")  # "batteur physics rejected ...": routed by its selector
    p.connect(parse, 0, trim, 0)
    top = p.obj(px, py + 75, "route batteur")
    p.connect(trim, 0, top, 0)
    names = [check_refusal(model) for model in REFUSALS]
    by_service = p.obj(px, py + 100, "route " + " ".join(service for service, _ in names))
    p.connect(top, 0, by_service, 0)
    last = p.obj(px, py + 225, "t l l")
    for k, (model, (_, name)) in enumerate(zip(REFUSALS, names, strict=True)):
        cx = px + 120 * k
        one = p.obj(cx, py + 125, f"route {name}")
        p.connect(by_service, k, one, 0)
        as_list = p.obj(cx, py + 150, "list")  # the refused address came out as the selector: a list again
        p.connect(one, 0, as_list, 0)
        count = len(model.wire_fields())
        if count == 2:
            p.connect(as_list, 0, last, 0)
            continue
        split = p.obj(cx, py + 175, "unpack " + " ".join("s" * count))  # keep the first and the last
        both = p.obj(cx, py + 200, "pack s s")
        p.connect(as_list, 0, split, 0)
        p.connect(split, count - 1, both, 1)
        p.connect(split, 0, both, 0)
        p.connect(both, 0, last, 0)
    p.connect(last, 1, p.obj(px, py + 250, "s bp-rejected"), 0)
    console = p.obj(px + 120, py + 250, "list trim")
    p.connect(last, 0, console, 0)
    p.connect(console, 0, p.obj(px + 120, py + 275, "print batteur-rejected"), 0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python pd/make_control.py",
        description="Write Batteur's Pure Data control panel (pd/control.pd by default), checking every control "
                    "against its message model.")
    parser.add_argument("-o", "--output", type=Path, default=OUT, metavar="PATH",
                        help="where to write the patch (default: %(default)s); '-' writes it to stdout")
    parser.add_argument("--check", action="store_true",
                        help="write nothing: exit 1 if the patch at --output is not what this script writes")
    args = parser.parse_args(argv)
    text = build().render()
    output: Path = args.output
    if args.check:
        try:
            current = output.read_text(encoding="utf-8")
        except OSError as exc:
            print(f"make_control.py: cannot read {output}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        if current != text:
            print(f"{output} is stale: run python pd/make_control.py", file=sys.stderr)
            return 1
        print(f"{output} is up to date")
        return 0
    if str(output) == "-":
        sys.stdout.write(text)
        return 0
    if output.is_dir():
        parser.error(f"--output {output} is a directory; give a file name (e.g. {output / 'control.pd'})")
    try:
        output.write_text(text, encoding="utf-8")
    except OSError as exc:
        parser.error(f"cannot write {output}: {exc.strerror or exc}")
    print(f"wrote {output}")
    if output.resolve() == OUT.resolve():  # docs/pd.md shows it: a test fails until the pictures are redrawn
        print("redraw its pictures in docs/pd.md: python pd/render_patch.py pd/control.pd docs/img/pd-control.png; "
              "python pd/render_patch.py --canvas sound pd/control.pd docs/img/pd-control-sound.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
