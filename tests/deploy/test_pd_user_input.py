"""What a Pd user types, and what the patches do with it: a symbol with or without ``symbol``, a number where a
name goes, a choice the panel has not, strikes and notes out of range, a clock pointed nowhere, a folder that is
not there. Each is taken, or refused with a line that names it; nothing is sent that the rig would drop."""

from __future__ import annotations

import asyncio
import importlib
import re
import sys
from pathlib import Path
from typing import Any

import pytest

from common.config import load_settings
from common.core import Outgoing
from common.kit import KITS_DIR, ZONES, load_kit
from common.messages import Impact, OscMessage
from common.messages.graphics import GraphicsCamera, GraphicsMode
from common.messages.interaction import RouteSet
from common.messages.physics import PhysicsGrip
from common.messages.score import GestureStyle, LiveNote, ScoreLoad, ScoreTransport
from common.messages.sound import SoundDamping, SoundModel
from common.runtime import Node
from tests.deploy.pdrun import PD_DIR, PdProcess, Recorder, of, require_pd, services
from tests.ports import free_port
from tests.recording_core import RecordingCore
from tests.waiting import until, wait_for

pytestmark = pytest.mark.timeout(120)


# ---------------------------------------------------------------- the panel's generator


def make_control() -> Any:
    sys.path.insert(0, str(PD_DIR))
    try:
        return importlib.import_module("make_control")
    finally:
        sys.path.remove(str(PD_DIR))


# ---------------------------------------------------------------- the panel: symbols in either form


@pytest.mark.parametrize("chosen", ["bp-instrument crash", "bp-instrument symbol crash"])
def test_an_instrument_chosen_bare_or_with_symbol_gets_its_own_values(chosen: str) -> None:
    """``bp-instrument crash`` (what a ``[; bp-instrument crash(`` box sends) chooses the crash as ``symbol crash``
    does: a damping slider moved next sends the crash's other value. Bare, it used to make ``select: no method for
    'crash'`` 14 times and then send the snare's sigma1 for the crash, overwriting its damping."""
    require_pd()
    crash_sigma1 = make_control().instrument_starts(SoundDamping)["crash"][1]
    with services(1) as (sound,):
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-sound {sound.port}", chosen, "bp-sigma0 2"])
        try:
            got = sound.until(of(SoundDamping), pd)
        finally:
            pd.stop()
    damping = next(m for m in got if isinstance(m, SoundDamping))
    assert (damping.instrument, damping.sigma0) == ("crash", 2.0)
    assert damping.sigma1 == pytest.approx(crash_sigma1, rel=1e-5)
    assert pd.errors() == [], "\n".join(pd.lines)


def test_every_symbol_receive_takes_the_bare_form() -> None:
    """Score file, transport, grip, synthesis model, camera, view, client host: each sent bare (``bp-score NAME``,
    no ``symbol``) reaches its service as it does with ``symbol``, with no Pd error."""
    require_pd()
    with services(4) as (physics, interaction, sound, graphics):
        pd = PdProcess(PD_DIR / "control.pd", sends=[
            "bp-host 127.0.0.1", f"bp-port-physics {physics.port}", f"bp-port-interaction {interaction.port}",
            f"bp-port-sound {sound.port}", f"bp-port-graphics {graphics.port}",
            "bp-score pd-user-input-no-such-score", "bp-transport pause", "bp-grip french", "bp-model sample",
            "bp-camera side", "bp-view-mode preview", "bp-client-host 127.0.0.9", "bp-client-route bang"])
        try:
            scored = physics.until(lambda ms: all(of(k)(ms) for k in (ScoreLoad, ScoreTransport, PhysicsGrip)), pd)
            routed = interaction.until(of(RouteSet), pd)
            modelled = sound.until(of(SoundModel), pd)
            viewed = graphics.until(lambda ms: of(GraphicsCamera)(ms) and of(GraphicsMode)(ms), pd)
        finally:
            pd.stop()
    assert ScoreLoad(path="pd-user-input-no-such-score") in scored
    assert next(m for m in scored if isinstance(m, ScoreTransport)).action == "pause"
    assert next(m for m in scored if isinstance(m, PhysicsGrip)).grip == "french"
    assert next(m for m in routed if isinstance(m, RouteSet)).to == "127.0.0.9:9103"
    assert next(m for m in modelled if isinstance(m, SoundModel)).model_dump() == {"instrument": "snare",
                                                                                  "model": "sample"}
    assert next(m for m in viewed if isinstance(m, GraphicsCamera)).preset == "side"
    assert next(m for m in viewed if isinstance(m, GraphicsMode)).mode == "preview"
    assert pd.errors() == [], "\n".join(pd.lines)


def test_a_choice_the_panel_has_not_is_refused_and_not_kept() -> None:
    """``bp-grip symbol blah`` is printed as ``batteur-panel-bad`` naming it and not kept: the next style change
    (``bp-nuance symbol accent``) carries the grip the panel had, not blah (which the rig used to refuse with every
    later style change). A number where a name goes is refused naming the number, never sent as ``float``."""
    require_pd()
    with services(2) as (physics, sound):
        pd = PdProcess(PD_DIR / "control.pd", sends=[
            f"bp-port-physics {physics.port}", f"bp-port-sound {sound.port}", "bp-grip symbol blah", "bp-grip 3",
            "bp-instrument 7", "bp-nuance symbol accent", "bp-model sample"])
        try:
            got = physics.until(of(GestureStyle), pd)
            sound.until(of(SoundModel), pd)
            pd.wait_for(lambda _: len(pd.printed("batteur-panel-bad")) >= 3)
        finally:
            pd.stop()
    styles = [m for m in got if isinstance(m, GestureStyle)]
    assert [(s.grip, s.nuance) for s in styles] == [(make_control()._style_defaults()[0], "accent")]
    assert [m for m in got if isinstance(m, PhysicsGrip)] == []
    assert next(m for m in sound.received if isinstance(m, SoundModel)).instrument == "snare"
    bad = [" ".join(line) for line in pd.printed("batteur-panel-bad")]
    assert any(line.startswith("bp-grip") and "got blah" in line for line in bad), bad
    assert any(line.startswith("bp-grip") and "number 3" in line for line in bad), bad
    assert any(line.startswith("bp-instrument") and "number 7" in line for line in bad), bad
    assert pd.errors() == [], "\n".join(pd.lines)


# ---------------------------------------------------------------- [batteur-strike], [batteur-clock]


class Arrivals(Recorder):
    """A recorded core noting the node's rig time at each message (``ROLE`` set per instance)."""

    def __init__(self, core: Any, role: str) -> None:
        super().__init__(core)
        self.role = role
        self.at: list[tuple[OscMessage, float]] = []

    @property
    def ROLE(self) -> str:  # type: ignore[override]  # the node reads it from the instance
        return self.role

    def handle(self, message: OscMessage, now: float, source: str) -> list[Outgoing]:
        self.at.append((message, now))
        return super().handle(message, now, source)


def node_for(core: Any, role: str) -> Node:
    return Node(core, load_settings({"role": role, "discovery": False,  # type: ignore[arg-type]
                                     "clock_master": "self", "oscquery": False}))


def patch(folder: Path, name: str, boxes: list[str], connects: list[tuple[int, int, int, int]]) -> Path:
    """A user's patch: ``boxes`` one under the other (object box texts; ``msg:TEXT`` a message box), ``connects``
    (box, outlet, box, inlet)."""
    lines = ["#N canvas 0 0 600 600 12;"]
    for k, text in enumerate(boxes):
        kind, text = ("msg", text[4:]) if text.startswith("msg:") else ("obj", text)
        lines.append(f"#X {kind} 20 {20 + 30 * k} {text};")
    lines += [f"#X connect {a} {outlet} {b} {inlet};" for a, outlet, b, inlet in connects]
    path = folder / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


BAD_STRIKES = {
    "tabla 3 0.3": "instrument tabla is not an object of the shipped kits",
    "snare 300 0.3": "velocity 300 is not in 0..100",
    "snare -1 0.3": "velocity -1 is not in 0..100",
    "snare 3 2.5": "position 2.5 is not in 0..2",
    "snare 3 0.3 rimm": "zone rimm is not one of",
    "snare x 0.3": "velocity x is not a number",
    "snare 3 0.3 rim extra": "(3 or 4 atoms) - not sent: snare 3 0.3 rim extra",
    "7 3 0.3": "instrument 7 is a number",
}


def test_a_strike_the_service_would_refuse_is_refused_by_the_abstraction_with_its_reason(tmp_path: Path) -> None:
    """The sound service answers no impact (a stream: docs/osc.md), so [batteur-strike] checks what it can before
    sending, prints each refusal as ``batteur-strike-bad`` with the reason, and sends nothing of it: only the
    good strike reaches the service. ``[batteur-strike 0 any]`` lets a name of a kit of your own through."""
    require_pd()
    core = RecordingCore("sound")

    async def main() -> PdProcess:
        node = node_for(core, "sound")
        await node.start()
        try:
            assert node.endpoint is not None
            user = patch(tmp_path, "strikes.pd", [f"batteur-clock 127.0.0.1 {node.endpoint.port}", "r t-strike",
                                                  "batteur-strike", "r t-any", "batteur-strike 0 any"],
                         [(1, 0, 2, 0), (3, 0, 4, 0)])
            sends = [f"t-strike {s}" for s in BAD_STRIKES] + ["t-strike snare 3 0.3 rim", "t-any my_gong 2 0.5"]
            pd = PdProcess(user, sends=sends, extra=["-path", str(PD_DIR)])
            try:
                await wait_for(lambda: len([m for m in core.handled if isinstance(m, Impact)]) >= 2, timeout=20)
                await asyncio.sleep(0.3)  # anything sent before the good strikes has arrived too
            finally:
                pd.stop()
        finally:
            await node.stop()
        return pd

    pd = asyncio.run(main())
    impacts = [m for m in core.handled if isinstance(m, Impact)]
    assert [(i.instrument, i.velocity, i.zone) for i in impacts] == [("snare", 3.0, "rim"), ("my_gong", 2.0, "centre")]
    bad = [" ".join(line) for line in pd.printed("batteur-strike-bad")]
    for strike, reason in BAD_STRIKES.items():
        assert sum(reason in line for line in bad) == 1, (strike, bad)
    assert len(bad) == len(BAD_STRIKES), bad
    assert pd.errors() == [], "\n".join(pd.lines)


def test_the_strikes_checks_are_the_shipped_kits_instruments_and_the_services_zones() -> None:
    """The names [batteur-strike] takes are every instrument the sound service plays with a shipped kit, and its
    zones the service's (common/kit.py ZONES): a check that drifted would refuse a strike the service plays."""
    from services.sound.core import SoundCore, SoundSettings

    instruments: set[str] = set()
    for kit in sorted(p.stem for p in KITS_DIR.glob("*.yaml")):
        core = SoundCore(SoundSettings(use_pyo=False), kit=load_kit(kit, warn=False))
        instruments |= set(core.instruments.instruments)
    selects = re.findall(r"^#X obj \d+ \d+ select ([^;]*);$", (PD_DIR / "batteur-strike.pd").read_text(), re.M)
    assert [set(s.split()) for s in selects] == [instruments, set(ZONES)]


def test_a_strike_without_a_clock_says_what_is_missing(tmp_path: Path) -> None:
    """No [batteur-clock] in the Pd instance: the strike says so (it used to print only ``no such var
    'batteur_clock_synced'``); a clock not connected: the strike says to connect it."""
    require_pd()
    alone = patch(tmp_path, "alone.pd", ["r t-strike", "batteur-strike"], [(0, 0, 1, 0)])
    idle = patch(tmp_path, "idle.pd", ["batteur-clock", "r t-strike", "batteur-strike"], [(1, 0, 2, 0)])
    said = []
    for user in (alone, idle):
        pd = PdProcess(user, sends=["t-strike snare 3 0.3"], extra=["-path", str(PD_DIR)])
        try:
            pd.wait_for(lambda lines: any(line.startswith("batteur-strike-bad") for line in lines))
        finally:
            pd.stop()
        assert pd.errors() == [], "\n".join(pd.lines)
        said.append(" ".join(pd.printed("batteur-strike-bad")[0]))
    assert said[0].startswith("no [batteur-clock] in this Pd instance"), said
    assert said[1].startswith("[batteur-clock] is not connected"), said


def test_a_clock_given_another_node_moves_there_and_one_unanswered_warns(tmp_path: Path) -> None:
    """``connect H P`` while connected moves the clock (it used to print ``netsend: already connected`` and keep
    pinging the old port); pointed at a port where no node answers, it prints ``batteur-clock-warning`` naming it
    (it used to give ``0 0`` forever without a word)."""
    require_pd()
    dead = free_port()  # nothing listens: its pings go unanswered

    async def main() -> PdProcess:
        node = node_for(RecordingCore("sound"), "sound")
        await node.start()
        try:
            assert node.endpoint is not None
            user = patch(tmp_path, "clock.pd", ["r t-clock", "batteur-clock", "print batteur-test-rtt"],
                         [(0, 0, 1, 0), (1, 1, 2, 0)])
            moved = PdProcess(user, sends=[f"t-clock connect 127.0.0.1 {dead}",
                                           f"t-clock connect 127.0.0.1 {node.endpoint.port}"],
                              extra=["-path", str(PD_DIR)])
            try:
                await wait_for(lambda: bool(moved.printed("batteur-test-rtt")), timeout=20)
            finally:
                moved.stop()
            assert moved.errors() == [], "\n".join(moved.lines)
            pd = PdProcess(user, sends=[f"t-clock connect 127.0.0.1 {dead}"], extra=["-path", str(PD_DIR)])
            try:
                pd.wait_for(lambda _: bool(pd.printed("batteur-clock-warning")), timeout=20)
            finally:
                pd.stop()
        finally:
            await node.stop()
        return pd

    pd = asyncio.run(main())
    warning = " ".join(pd.printed("batteur-clock-warning")[0])
    assert warning.startswith(f"no pong from 127.0.0.1 {dead}"), warning
    assert pd.errors() == [], "\n".join(pd.lines)


# ---------------------------------------------------------------- [batteur-note]: live notes from Pd


def test_a_live_note_from_pd_reaches_physics_stamped_ahead_and_its_refusal_comes_back(tmp_path: Path) -> None:
    """[batteur-note] sends /batteur/score/note to a real physics core, stamped with the rig time it was played at
    + the lead (400 ms by default); the physics node's refusal (pitch 1 maps to no drum) is printed as
    ``batteur-rejected``. Notes it cannot send right (a note-off, out of range, before the clock has the rig
    time) are printed as ``batteur-note-bad`` with the reason."""
    require_pd()
    from services.physics.core import PhysicsCore

    physics = Arrivals(PhysicsCore(), "physics")

    async def main() -> PdProcess:
        node = node_for(physics, "physics")
        await node.start()
        try:
            assert node.endpoint is not None
            port = node.endpoint.port
            # once the clock has a pong: one note, pitch 1 (the spigot closes after it)
            user = patch(tmp_path, "notes.pd", [f"batteur-clock 127.0.0.1 {port}", "r t-note",
                                                f"batteur-note 127.0.0.1 {port}", "spigot 1", "t b b", "f 1",
                                                "list append 100", "msg:0"],
                         [(1, 0, 2, 0), (0, 1, 3, 0), (3, 0, 4, 0), (4, 1, 7, 0), (7, 0, 3, 1), (4, 0, 5, 0),
                          (5, 0, 6, 0), (6, 0, 2, 0)])
            sends = ["t-note 38", "t-note 38 0", "t-note 200 100", "t-note 38 100 17", "t-note 38 100"]
            pd = PdProcess(user, sends=sends, extra=["-path", str(PD_DIR)])
            try:
                await wait_for(lambda: bool(pd.printed("batteur-rejected")), timeout=60)
            finally:
                pd.stop()
        finally:
            await node.stop()
        return pd

    pd = asyncio.run(main())
    notes = [(m, now) for m, now in physics.at if isinstance(m, LiveNote)]
    assert [(n.pitch, n.velocity, n.channel) for n, _ in notes] == [(1, 100, 10)]
    note, arrived = notes[0]
    # stamped 400 ms after it was played: never later than that (within the clock's error, a fraction of the
    # round trip), and sooner only by the trip from Pd (well under 10 ms on loopback; a stalled test process
    # delays the arrival, not the stamp: wide margin)
    assert 0.3 < note.time - arrived <= 0.41, note.time - arrived
    rejected = " ".join(pd.printed("batteur-rejected")[0]).replace("\\ ", " ")  # Pd writes a space as "\ "
    assert "/batteur/score/note" in rejected and "pitch 1" in rejected, rejected
    bad = [" ".join(line) for line in pd.printed("batteur-note-bad")]
    for reason in ("(2 or 3 numbers) - not sent: 38", "velocity 0 is not a whole number in 1..127",
                   "pitch 200 is not a whole number in 0..127", "channel 17 is not a whole number in 1..16",
                   "[batteur-clock] has no rig time yet"):
        assert sum(reason in line for line in bad) == 1, (reason, bad)
    assert len(bad) == 5, bad
    assert pd.errors() == [], "\n".join(pd.lines)


# ---------------------------------------------------------------- the sound client and its voices


def test_the_sound_clients_folder_is_checked_and_taken_in_either_form(tmp_path: Path) -> None:
    """``sc-dir /path`` (bare) records there; a folder that is not there is refused (``batteur-bad ... dir``) and
    the takes stay in the last folder set, where they used to be announced there and fail in writesf~; a number
    is refused naming it. ``sc-host`` bare is taken too."""
    require_pd()
    takes = tmp_path / "takes"
    takes.mkdir()
    missing = tmp_path / "not-there"
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=[
        f"sc-port {free_port()}", "sc-host 127.0.0.1", f"sc-dir {takes}", f"sc-dir symbol {missing}", "sc-dir 3",
        "sc-record 1"])
    try:
        pd.wait_for(lambda _: bool(pd.printed("batteur-record")))
        assert until(lambda: (takes / "take-1.wav").is_file(), timeout_s=10), pd.lines
    finally:
        pd.stop()
    assert pd.printed("batteur-record") == [["take-1.wav", str(takes)]], pd.lines
    bad = [" ".join(line) for line in pd.printed("batteur-bad")]
    assert bad[0].startswith(f"1 dir {missing} does not exist or is not a folder"), bad
    assert bad[1].startswith("2 dir sc-dir takes a folder") and "number 3" in bad[1], bad
    assert len(bad) == 2, bad
    assert pd.printed("batteur-listen")[0][-1] == "127.0.0.1"
    assert pd.errors() == [], "\n".join(pd.lines)


def test_a_voice_without_its_arguments_says_so(tmp_path: Path) -> None:
    """``[batteur-voice]`` with no arguments plays nothing to hear: it says so (it used to play silence with no
    word); a voice with its seven arguments says nothing."""
    require_pd()
    user = patch(tmp_path, "voices.pd", ["batteur-voice", "batteur-voice snare 190 120 0.8 180 1500 1.5"], [])
    pd = PdProcess(user, extra=["-path", str(PD_DIR), "-send", "pd quit"])
    try:
        pd.popen.wait(timeout=20)
        pd.wait_for(lambda lines: True, timeout=1)
    finally:
        pd.stop()
    said = pd.printed("batteur-voice-bad")
    assert len(said) == 1 and "needs its seven arguments" in " ".join(said[0]), pd.lines
