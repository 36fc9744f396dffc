"""What the control panel's sliders and number boxes show: the value the panel keeps (or last sent) for them.

A control whose message carries several values (the camera, the tip-height plot, master gain and reverb, the
damping pair, the transport's position, each destination's port) keeps every value in a pack and sends the others
as they are when one is moved. Its slider and number box must show what the pack starts with: a camera slider
showing 0 while the pack holds the view's 18 degrees tells the user something the panel does not send. A slider
whose message carries its value alone (tempo, latency window, trails, picture delay) shows what the service starts
with; the sound rows (level, radius, tension, density, modes, thickness, position sensitivity, snares, openness,
air loading, damping, second head, stick, resonances: in the panel's [pd sound] sub-patch) show the chosen
instrument's values.
"""

from __future__ import annotations

import math
import re
import socket
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from common.messages import decode, parse_packet
from common.messages.score import ScoreDynamics, ScoreLoad, ScoreTransport, TempoScale
from services.graphics.camera import default_camera
from tests.deploy.pdrun import PD_DIR, PdProcess, require_pd
from tests.ports import free_port

pytestmark = pytest.mark.timeout(120)

BOX = re.compile(r"^#X obj \d+ \d+ (hsl|nbx) ")

PER_INSTRUMENT = {"bp-level": ("level", "level_db"), "bp-radius": ("radius", "radius"),
                  "bp-tension": ("tension", "tension"), "bp-density": ("density", "density"),
                  "bp-modes": ("n_modes", "n_modes"), "bp-sigma0": ("damping", "damping0"),
                  "bp-sigma1": ("damping", "damping1"), "bp-thickness": ("thickness", "thickness"),
                  "bp-position-sensitivity": ("position", "position"), "bp-snares": ("snares", "snares"),
                  "bp-openness": ("openness", "openness"), "bp-air": ("air_loading", "air_loading"),
                  "bp-second-head-gain": ("second_head", "second_head"),
                  "bp-second-head-ratio": ("second_head", "reso_ratio"), "bp-stick-mass": ("stick", "stick_mass"),
                  "bp-stick-stiffness": ("stick", "stick_stiffness"),
                  "bp-stick-exponent": ("stick", "stick_exponent"),
                  **{f"bp-resonance-{k}": ("resonances", f"resonances {k}") for k in range(1, 9)}}
"""The sound rows that act on the chosen instrument: control -> (the sound service's parameter, its Params field;
``resonances K``: the gain of mode K, 1 beyond the instrument's list)."""


def _instrument_values(name: str) -> dict[str, float]:
    """What the sound service starts instrument ``name`` of the default kit with, by control; 0 for a parameter
    the instrument does not have (tension and density of a cymbal), which the service refuses."""
    from common.kit import load_kit
    from services.sound.instruments import KIND_PARAMS, default_params

    obj = next(obj for obj in load_kit("default").objects if obj.id == name)
    params = default_params(obj)

    def value(field: str) -> float:
        if field.startswith("resonances "):
            mode = int(field.split()[1])
            return float(params.resonances[mode - 1]) if mode <= len(params.resonances) else 1.0
        return float(getattr(params, field))

    return {control: value(field) if param in KIND_PARAMS[obj.kind] else 0.0
            for control, (param, field) in PER_INSTRUMENT.items()}


def _tempo_at_start() -> float:
    """The tempo factor the physics node's score player starts with (a stand-in core: it reads only settings)."""
    from common.kit import load_kit
    from services.physics.core import PhysicsSettings
    from services.physics.score_player import ScorePlayer

    core: Any = SimpleNamespace(settings=PhysicsSettings(), kit=load_kit("default", warn=False))
    return float(ScorePlayer(core).tempo)


def _dynamics_at_start() -> float:
    """The velocity factor the physics node's score player starts with (a stand-in core, as for the tempo)."""
    from common.kit import load_kit
    from services.physics.core import PhysicsSettings
    from services.physics.score_player import ScorePlayer

    core: Any = SimpleNamespace(settings=PhysicsSettings(), kit=load_kit("default", warn=False))
    return float(ScorePlayer(core).dynamics)


def _client_port() -> int:
    """The port the Pd sound client listens on when not told otherwise: the [f PORT] its listen message is made from
    (pd/sound-client.pd)."""
    found = re.findall(r"^#X obj \d+ \d+ f (\d+);$", (PD_DIR / "sound-client.pd").read_text(encoding="utf-8"),
                       re.MULTILINE)
    assert len(found) == 1, found
    return int(found[0])


def _kept_values() -> dict[str, float]:
    """What the panel keeps at load for each control (by receive name), from the sources the services start with:
    compose.yaml's ports, the score player's tempo, the view's default camera, plot, trails and delay (the node's
    latency window), ``batteur sound``'s latency window and master, the default kit's snare (the instrument chosen
    at load), position 0, and the port the Pd sound client listens on (the INTERACTION section routes there)."""
    from common.config import NodeSettings
    from services.graphics.core import ViewSettings
    from services.graphics.node import GraphicsNodeSettings
    from services.sound.core import SoundSettings
    from services.sound.node import SoundNodeSettings

    camera = default_camera()
    view = ViewSettings()
    return {
        "bp-port-physics": 9101, "bp-port-interaction": 9102, "bp-port-sound": 9103, "bp-port-graphics": 9104,
        "bp-port-score": 9101, "bp-position": 0.0, "bp-tempo": _tempo_at_start(),
        "bp-dynamics": _dynamics_at_start(),
        **_instrument_values("snare"),
        "bp-latency": NodeSettings.model_fields["latency_s"].default,
        "bp-master": SoundSettings.model_fields["master_db"].default,
        "bp-reverb": SoundNodeSettings.model_fields["reverb"].default,
        "bp-azimuth": camera["azimuth_deg"], "bp-elevation": camera["elevation_deg"],
        "bp-distance": camera["distance"], "bp-target-x": camera["target"][0], "bp-target-y": camera["target"][1],
        "bp-target-z": camera["target"][2], "bp-trails": view.trails,
        "bp-plot-window": view.plot["window"], "bp-plot-zmin": view.plot["z_min"], "bp-plot-zmax": view.plot["z_max"],
        "bp-view-latency": GraphicsNodeSettings.model_fields["latency_s"].default,
        "bp-preview-rate": GraphicsNodeSettings.model_fields["preview_rate"].default,
        "bp-preview-first": 1, "bp-preview-last": 1,  # the bars the pack starts with: bar 1 (the score's first)
        "bp-loop-first": 1, "bp-loop-last": 1,  # the loop's bars the stores start with (sent by [loop( only)
        "bp-client-port": _client_port(),
    }


class Box:
    """One slider (``hsl``) or number box (``nbx``) of the panel: its key (``CANVAS-INDEX``: the canvas it is in,
    0 the panel's own, 1.. its sub-patches in file order, and its object index there), range and receive name."""

    def __init__(self, index: str, tokens: list[str]) -> None:
        self.index = index
        self.kind = tokens[4]
        self.lo, self.hi = float(tokens[7]), float(tokens[8])
        self.log = tokens[9] == "1"
        self.receive = tokens[12]
        self.name = self.receive  # a number box with no receive name is named after the slider that feeds it

    @property
    def control(self) -> str:
        """The receive name of the control (the slider's, for its number box)."""
        return self.name.removesuffix(" (number box)")

    def tolerance(self, value: float) -> float:
        """How far the value read back may be from ``value``: a slider holds its position in 1/100 pixel (of
        159), a number box the float itself (printed with 6 digits)."""
        if self.kind == "nbx":
            return 1e-5 * max(abs(value), 1e-9)
        steps = 100 * 159
        if self.log:
            return value * (math.exp(math.log(self.hi / self.lo) / steps) - 1)
        return (self.hi - self.lo) / steps


OBJECT = re.compile(r"^#X (obj|msg|text|floatatom|symbolatom|restore) ")
"""A line that makes an object of its canvas (numbered in order for its canvas's connections; ``restore`` closes a
sub-patch, which is one object of its parent)."""


def _probed(tmp_path: Path) -> tuple[Path, list[Box], list[str]]:
    """A copy of the panel in which every slider and number box (in its sub-patches too) sends what it outputs to
    ``probe-KEY`` (printed as ``shown-KEY`` by a probe patch) and to nothing else (its wires are cut: a bang sends
    no OSC and a slider does not overwrite its number box); a box with no receive name gets ``poke-KEY``. Returns
    the copy, its boxes and the -send messages that bang each one (number boxes first)."""
    lines = (PD_DIR / "control.pd").read_text(encoding="utf-8").splitlines()
    boxes: dict[str, Box] = {}
    wires: list[tuple[int, str, str]] = []  # (line, from, to) of each connection, as box keys
    canvases, counts = [0], [0]  # the canvases open at this line (innermost last), each one's objects so far
    for number, line in enumerate(lines):
        if line.startswith("#N canvas"):
            if number:
                canvases.append(len(counts))
                counts.append(0)
            continue
        canvas = canvases[-1]
        if line.startswith("#X restore"):
            canvases.pop()
            canvas = canvases[-1]
        if wire := re.match(r"^#X connect (\d+) (\d+) (\d+) ", line):
            wires.append((number, f"{canvas}-{wire[1]}", f"{canvas}-{wire[3]}" if wire[2] == "0" else ""))
            continue
        if not OBJECT.match(line):
            continue
        key = f"{canvas}-{counts[canvas]}"
        counts[canvas] += 1
        if BOX.match(line):
            tokens = line.split(" ")
            boxes[key] = Box(key, tokens)
            tokens[11] = f"probe-{key}"
            if tokens[12] == "empty":
                tokens[12] = f"poke-{key}"
            lines[number] = " ".join(tokens)
    for number, source, target in wires:
        if source in boxes and target in boxes and re.match(r"^#X connect \d+ 0 \d+ 0;$", lines[number]):
            feeder, fed = boxes[source], boxes[target]
            if fed.receive == "empty":
                fed.name = f"{feeder.receive} (number box)"
    cut = {number for number, source, _ in wires if source in boxes}
    kept = [line for number, line in enumerate(lines) if number not in cut]
    panel = tmp_path / "control.pd"
    panel.write_text("\n".join(kept) + "\n", encoding="utf-8")
    probe = ["#N canvas 0 0 400 300 12;"]
    for index in boxes:
        probe += [f"#X obj 10 10 r probe-{index};", f"#X obj 10 35 print shown-{index};"]
    probe += [f"#X connect {2 * k} 0 {2 * k + 1} 0;" for k in range(len(boxes))]
    (tmp_path / "probe.pd").write_text("\n".join(probe) + "\n", encoding="utf-8")
    order = sorted(boxes.values(), key=lambda box: box.kind != "nbx")
    bangs = [f"{box.receive if box.receive != 'empty' else f'poke-{box.index}'} bang" for box in order]
    return panel, list(boxes.values()), bangs


Shown = tuple[list[Box], list[dict[str, float]]]
"""The panel's boxes, and what each shows (by index) after each round."""


def _shown(tmp_path: Path, chosen: tuple[str, ...] = (), receive: str = "bp-instrument") -> Shown:
    """The panel's boxes and what each shows (by index): at load, then after choosing each of ``chosen`` in turn
    (an instrument, or with ``receive="bp-camera"`` a camera preset)."""
    require_pd()
    panel, boxes, bangs = _probed(tmp_path)
    sends = [*bangs]
    for name in chosen:
        sends += [f"{receive} symbol {name}", *bangs]
    rounds = 1 + len(chosen)
    pd = PdProcess(panel, sends=sends, extra=["-open", str(tmp_path / "probe.pd")])
    try:
        pd.wait_for(lambda _: all(len(pd.printed(f"shown-{box.index}")) >= rounds for box in boxes))
    finally:
        pd.stop()
    assert pd.errors() == [], "\n".join(pd.lines)
    shown = [{box.index: float(pd.printed(f"shown-{box.index}")[k][0]) for box in boxes} for k in range(rounds)]
    return boxes, shown


def _wrong(boxes: list[Box], shown: dict[str, float], expected: dict[str, float]) -> dict[str, tuple[float, float]]:
    """(shown, expected) of each box of a control in ``expected`` that shows another value."""
    wrong = {}
    for box in boxes:
        if box.control not in expected:
            continue
        value = float(expected[box.control])
        if abs(shown[box.index] - value) > box.tolerance(value) + 1e-12:
            wrong[box.name] = (shown[box.index], value)
    return wrong


def test_every_slider_and_number_box_shows_the_value_the_panel_keeps_for_it(tmp_path: Path) -> None:
    """At load each slider and number box shows what the panel would send for it were another value of its message
    moved, or what the service it drives starts with: the ports, position, the snare's sound (level, radius,
    tension, density, modes, damping), master and reverb, the view's camera, plot, trails and picture delay, the
    tempo, the latency window, the score preview's speed and bars. The camera and plot sliders used to show 0 (the
    distance slider its 0.5 end) while
    their packs held 0, 18, 3 m ... and 4 s, 0.5 m, 1.6 m; tempo, the snare's rows, the latency window, trails and
    picture delay showed 0 or their left end (tempo 0.25) instead of 1, 0 dB, 0.178 m ..., 0.05 s, 1 s, 0.05 s."""
    boxes, (shown,) = _shown(tmp_path)
    expected = _kept_values()
    assert {box.control for box in boxes} == set(expected), \
        "a control the test does not know: what does the panel keep for it?"
    wrong = _wrong(boxes, shown, expected)
    assert wrong == {}, f"(shown, kept) of each control that shows another value than the panel keeps: {wrong}"


CHOSEN = ("kick", "crash", "cowbell", "hihat", "snare")
"""A drum, a cymbal, the bell, the hi-hat, and back to the snare chosen at load."""


def test_choosing_an_instrument_shows_its_values_in_the_sound_rows(tmp_path: Path) -> None:
    """The sound rows act on the chosen instrument: choosing another shows its values (the kit's, as the sound
    service starts it), a cymbal's tension and density 0 (it has none: the service refuses them). The level,
    radius, tension, density and modes rows used to keep showing what they showed before (0 at load)."""
    boxes, shown = _shown(tmp_path, CHOSEN)
    for name, values in zip(CHOSEN, shown[1:], strict=True):
        expected = _instrument_values(name)
        assert {box.control for box in boxes} >= set(expected)
        wrong = _wrong(boxes, values, expected)
        assert wrong == {}, f"{name}: (shown, the instrument's) of each sound row that shows another value: {wrong}"


def _sent_tension(sends: list[str], count: int) -> list[tuple[str, float]]:
    """The (instrument, value) of the first ``count`` tension messages the panel sends to a stand-in sound service
    on a loopback port, driven by ``sends`` (raw OSC: a value the models refuse is seen as sent)."""
    require_pd()
    port = free_port()
    got: list[tuple[str, float]] = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(15)
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-sound {port}", *sends])
        try:
            while len(got) < count:
                try:
                    data = sock.recv(65536)
                except TimeoutError:
                    raise AssertionError(f"got only {got}:\n" + "\n".join(pd.lines)) from None
                got += [(str(m.args[0]), float(m.args[1])) for m in parse_packet(data)
                        if m.address == "/batteur/sound/tension"]
        finally:
            pd.stop()
    return got


def test_a_value_sent_for_an_instrument_is_shown_again_when_it_is_chosen_again() -> None:
    """The panel remembers what it sent for each instrument: the kick's tension set to 800 is back (and sent by
    its slider) when the kick is chosen again after the snare, which shows the kit's; a tension sent for the crash
    (refused: a cymbal has none) is not kept, the crash shows 0 again."""
    sends = ["bp-instrument symbol kick", "bp-tension 800", "bp-instrument symbol crash", "bp-tension 500",
             "bp-instrument symbol snare", "bp-tension bang", "bp-instrument symbol kick", "bp-tension bang",
             "bp-instrument symbol crash", "bp-tension bang"]
    snare = _instrument_values("snare")["bp-tension"]
    assert _sent_tension(sends, 5) == [("kick", 800), ("crash", 500), ("snare", pytest.approx(snare, rel=1e-4)),
                                       ("kick", 800), ("crash", 0)]


PRESETS_CHOSEN = ("side", "drummer", "top", "orbit", "front")


def test_choosing_a_camera_preset_shows_its_numbers_in_the_camera_sliders(tmp_path: Path) -> None:
    """A preset puts its own numbers (services/graphics/camera.py, as the view applies them) in the camera sliders
    and the pack, so a slider moved next starts from the view the preset shows. The sliders used to keep the last
    free camera's numbers: after ``side`` (azimuth 90, elevation 12) moving the distance turned the view to the
    front at 18 degrees."""
    from services.graphics.camera import camera_for

    boxes, shown = _shown(tmp_path, PRESETS_CHOSEN, receive="bp-camera")
    for name, values in zip(PRESETS_CHOSEN, shown[1:], strict=True):
        cam = camera_for(name, 0.0, 0.0, 1.0, (0.0, 0.0, 0.0))  # type: ignore[arg-type]
        expected = {"bp-azimuth": cam["azimuth_deg"], "bp-elevation": cam["elevation_deg"],
                    "bp-distance": cam["distance"], "bp-target-x": cam["target"][0],
                    "bp-target-y": cam["target"][1], "bp-target-z": cam["target"][2]}
        wrong = _wrong(boxes, values, {k: round(v, 2 if k in ("bp-azimuth", "bp-elevation") else 3)
                                       for k, v in expected.items()})
        assert wrong == {}, f"{name}: (shown, the preset's) of each camera slider that shows another value: {wrong}"


def test_the_sound_rows_added_for_every_parameter_reach_a_sound_core() -> None:
    """Thickness, position sensitivity, snares, openness and air loading (the panel covered 9 of the 17 sound
    addresses: a cymbal's refusal named /batteur/sound/thickness, which it could not send) arrive at a real sound
    core, for the chosen instrument, and the instruments take them."""
    import asyncio

    from common.messages.sound import SoundAirLoading, SoundOpenness, SoundPosition, SoundSnares, SoundThickness
    from tests.deploy.pdrun import physics_and_sound_nodes
    from tests.waiting import wait_for

    require_pd()

    async def main() -> None:
        async with physics_and_sound_nodes() as rig:
            sound = rig.sound
            sends = [f"bp-port-sound {rig.sound_port}",
                     "bp-instrument symbol crash", "bp-thickness 0.002", "bp-position-sensitivity 0.4",
                     "bp-instrument symbol hihat", "bp-openness 0.8",
                     "bp-instrument symbol snare", "bp-snares 1.5", "bp-air 0.5"]
            pd = PdProcess(PD_DIR / "control.pd", sends=sends)
            try:
                await wait_for(lambda: len(sound.of(SoundAirLoading)) >= 1, timeout=15)
            finally:
                pd.stop()
            assert pd.errors() == [], "\n".join(pd.lines)
            got = [(type(m).__name__, m.instrument, round(m.value, 6)) for m in sound.handled
                   if isinstance(m, (SoundThickness, SoundPosition, SoundSnares, SoundOpenness, SoundAirLoading))]
            assert got == [("SoundThickness", "crash", 0.002), ("SoundPosition", "crash", 0.4),
                           ("SoundOpenness", "hihat", 0.8), ("SoundSnares", "snare", 1.5),
                           ("SoundAirLoading", "snare", 0.5)]
            assert not sound.core.stats.rejected  # each sent to an instrument that has the parameter
            insts = sound.core.instruments.instruments
            sound.core.render(sound.core.now + 0.01)  # openness: applied at the next block (this harness never steps)
            assert insts["crash"].p.thickness == pytest.approx(0.002)
            assert insts["crash"].p.position == pytest.approx(0.4)
            assert insts["hihat"].p.openness == pytest.approx(0.8)
            assert insts["snare"].p.snares == pytest.approx(1.5) and insts["snare"].p.air_loading == pytest.approx(0.5)

    asyncio.run(main())


def test_a_score_loaded_shows_its_tempo_and_dynamics_as_written_and_sends_neither(tmp_path: Path) -> None:
    """Physics plays each score loaded at its own tempo and dynamics (the factors back to 1, as written, since 8 Dec):
    ``bp-score`` (the score file box) puts the tempo and dynamics sliders and their number boxes back to what the
    score player starts with, without sending them (the load already did it). Until the day after 8 Dec they kept
    showing x2 and x0.5 while the new score played at x1: the next move of one started from a value not in use."""
    require_pd()
    panel, boxes, bangs = _probed(tmp_path)
    factors = [box for box in boxes if box.control in ("bp-tempo", "bp-dynamics")]
    assert sorted(box.name for box in factors) == ["bp-dynamics", "bp-dynamics (number box)", "bp-tempo",
                                                   "bp-tempo (number box)"]
    moved = {box.index: 2.0 if box.control == "bp-tempo" else 0.5 for box in factors}
    moves = [f"{box.receive if box.receive != 'empty' else f'poke-{box.index}'} {moved[box.index]:g}"
             for box in factors]
    pd = PdProcess(panel, sends=[*moves, *bangs, "bp-score symbol groove", *bangs],
                   extra=["-open", str(tmp_path / "probe.pd")])
    try:  # each moved box prints its move, then what it shows after each round of bangs
        pd.wait_for(lambda _: all(len(pd.printed(f"shown-{box.index}")) >= 2 + (box.index in moved) for box in boxes))
    finally:
        pd.stop()
    assert pd.errors() == [], "\n".join(pd.lines)
    before, after = ({box.index: float(pd.printed(f"shown-{box.index}")[k][0]) for box in boxes} for k in (-2, -1))
    assert _wrong(factors, before, {"bp-tempo": 2.0, "bp-dynamics": 0.5}) == {}  # moved, as a user moves them
    assert _wrong(factors, after, {"bp-tempo": _tempo_at_start(), "bp-dynamics": _dynamics_at_start()}) == {}
    others = [box for box in boxes if box.index not in moved]
    assert _wrong(others, after, {box.control: before[box.index] for box in others}) == {}  # the load moves no other
    # the load sends what it sends and no factor: the score service gets the moves, the load, then the play
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", free_port()))
        sock.settimeout(15)
        pd = PdProcess(PD_DIR / "control.pd", sends=[
            f"bp-port-score {sock.getsockname()[1]}", "bp-tempo 2", "bp-dynamics 0.5", "bp-score symbol groove",
            "bp-transport symbol play"])
        got: list[Any] = []
        try:
            while not any(isinstance(m, ScoreTransport) for m in got):
                try:
                    data = sock.recv(65536)
                except TimeoutError:
                    raise AssertionError(f"got only {got}:\n" + "\n".join(pd.lines)) from None
                got += decode(data).messages
        finally:
            pd.stop()
    assert [(type(m), getattr(m, "factor", getattr(m, "path", None))) for m in got] == [
        (TempoScale, pytest.approx(2.0)), (ScoreDynamics, pytest.approx(0.5)), (ScoreLoad, "groove"),
        (ScoreTransport, None)], got
