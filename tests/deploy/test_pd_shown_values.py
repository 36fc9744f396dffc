"""What the control panel's sliders and number boxes show at load: the value the panel keeps for them.

A control whose message carries several values (the camera, the tip-height plot, master gain and reverb, the
damping pair, the transport's position, each destination's port) keeps every value in a pack and sends the others
as they are when one is moved. Its slider and number box must show what the pack starts with: a camera slider
showing 0 while the pack holds the view's 18 degrees tells the user something the panel does not send.
"""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path

import pytest

from services.graphics.camera import default_camera
from tests.deploy.pdrun import PD_DIR, PdProcess, require_pd

pytestmark = pytest.mark.timeout(120)

SENT_ALONE = frozenset({"bp-tempo", "bp-level", "bp-radius", "bp-tension", "bp-density", "bp-modes", "bp-latency",
                        "bp-trails", "bp-view-latency"})
"""Sliders whose message carries their value alone: the panel keeps nothing for them, so nothing to show."""

BOX = re.compile(r"^#X obj \d+ \d+ (hsl|nbx) ")


def _kept_values() -> dict[str, float]:
    """What the panel keeps at load for each control (by receive name), from the sources the services start with:
    compose.yaml's ports, the view's default camera and plot, ``batteur sound``'s master, the default kit's damping
    of the snare (the instrument chosen at load), position 0."""
    from common.kit import load_kit
    from services.graphics.core import ViewSettings
    from services.sound.core import SoundSettings
    from services.sound.instruments import default_params
    from services.sound.node import add_arguments

    camera = default_camera()
    plot = ViewSettings().plot
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    snare = default_params(next(obj for obj in load_kit("default").objects if obj.id == "snare"))
    return {
        "bp-port-physics": 9101, "bp-port-interaction": 9102, "bp-port-sound": 9103, "bp-port-graphics": 9104,
        "bp-port-score": 9101, "bp-position": 0.0,
        "bp-sigma0": snare.damping0, "bp-sigma1": snare.damping1,
        "bp-master": SoundSettings.model_fields["master_db"].default, "bp-reverb": parser.get_default("reverb"),
        "bp-azimuth": camera["azimuth_deg"], "bp-elevation": camera["elevation_deg"],
        "bp-distance": camera["distance"], "bp-target-x": camera["target"][0], "bp-target-y": camera["target"][1],
        "bp-target-z": camera["target"][2],
        "bp-plot-window": plot["window"], "bp-plot-zmin": plot["z_min"], "bp-plot-zmax": plot["z_max"],
    }


class Box:
    """One slider (``hsl``) or number box (``nbx``) of the panel: its object index, range and receive name."""

    def __init__(self, index: int, tokens: list[str]) -> None:
        self.index = index
        self.kind = tokens[4]
        self.lo, self.hi = float(tokens[7]), float(tokens[8])
        self.log = tokens[9] == "1"
        self.receive = tokens[12]
        self.name = self.receive  # a number box with no receive name is named after the slider that feeds it

    def tolerance(self, value: float) -> float:
        """How far the value read back may be from ``value``: a slider holds its position in 1/100 pixel (of
        159), a number box the float itself (printed with 6 digits)."""
        if self.kind == "nbx":
            return 1e-5 * max(abs(value), 1e-9)
        steps = 100 * 159
        if self.log:
            return value * (math.exp(math.log(self.hi / self.lo) / steps) - 1)
        return (self.hi - self.lo) / steps


def _probed(tmp_path: Path) -> tuple[Path, list[Box], list[str]]:
    """A copy of the panel in which every slider and number box sends what it outputs to ``probe-INDEX`` (printed
    as ``shown-INDEX`` by a probe patch) and to nothing else (its wires are cut: a bang sends no OSC and a slider
    does not overwrite its number box); a box with no receive name gets ``poke-INDEX``. Returns the copy, its
    boxes and the -send messages that bang each one (number boxes first)."""
    lines = (PD_DIR / "control.pd").read_text(encoding="utf-8").splitlines()
    boxes: dict[int, Box] = {}
    for index, line in enumerate(lines[1:]):
        if BOX.match(line):
            tokens = line.split(" ")
            boxes[index] = Box(index, tokens)
            tokens[11] = f"probe-{index}"
            if tokens[12] == "empty":
                tokens[12] = f"poke-{index}"
            lines[index + 1] = " ".join(tokens)
    for line in lines:
        wire = re.match(r"^#X connect (\d+) 0 (\d+) 0;$", line)
        if wire and int(wire[1]) in boxes and int(wire[2]) in boxes:
            feeder, fed = boxes[int(wire[1])], boxes[int(wire[2])]
            if fed.receive == "empty":
                fed.name = f"{feeder.receive} (number box)"
    kept = [line for line in lines if not ((m := re.match(r"^#X connect (\d+) ", line)) and int(m[1]) in boxes)]
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


def test_every_slider_and_number_box_shows_the_value_the_panel_keeps_for_it(tmp_path: Path) -> None:
    """At load each slider and number box shows what the panel would send for it were another value of its message
    moved: the ports, position, the snare's damping, master and reverb, the view's camera and plot. The camera and
    plot sliders used to show 0 (the distance slider its 0.5 end) while their packs held 0, 18, 3 m ... and 4 s,
    0.5 m, 1.6 m."""
    require_pd()
    panel, boxes, bangs = _probed(tmp_path)
    pd = PdProcess(panel, sends=bangs, extra=["-open", str(tmp_path / "probe.pd")])
    try:
        pd.wait_for(lambda _: all(pd.printed(f"shown-{box.index}") for box in boxes))
    finally:
        pd.stop()
    assert pd.errors() == [], "\n".join(pd.lines)
    expected = _kept_values()
    names = {box.name.removesuffix(" (number box)") for box in boxes}
    assert names == set(expected) | SENT_ALONE, "a control the test does not know: what does the panel keep for it?"
    wrong = {}
    for box in boxes:
        control = box.name.removesuffix(" (number box)")
        if control in SENT_ALONE:
            continue
        shown = float(pd.printed(f"shown-{box.index}")[0][0])
        value = float(expected[control])
        if abs(shown - value) > box.tolerance(value) + 1e-12:
            wrong[box.name] = (shown, value)
    assert wrong == {}, f"(shown, kept) of each control that shows another value than the panel keeps: {wrong}"
