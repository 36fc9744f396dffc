"""The Pd control panel hears the services' refusals: each comes back to the [netsend] that sent the refused control
(the sender's address and port) and the panel shows the last one (address, reason) and prints it to Pd's console."""

from __future__ import annotations

import asyncio
import shutil
import socket
from pathlib import Path

import pytest

from common.messages import OscMessage, encode
from common.messages.graphics import GraphicsRejected
from common.messages.interaction import InteractionError
from common.messages.physics import PhysicsControlMode, PhysicsRejected
from common.messages.score import ScoreTransport
from common.messages.sound import SoundRejected, SoundTension
from tests.deploy.pdrun import PD_DIR, PdProcess, physics_and_sound_nodes, require_pd
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(120)

SAVER = """#N canvas 0 0 400 300 12;
#X obj 10 10 r bp-rejected;
#X obj 10 40 t b;
#X obj 10 70 delay 0;
#X msg 10 100 \\; pd-control.pd menusave;
#X connect 0 0 1 0;
#X connect 1 0 2 0;
#X connect 2 0 3 0;
"""
"""A test patch opened beside a copy of the panel: once a refusal has reached the panel (after the panel's own
receivers of bp-rejected have run), it saves the copy, so the test can read what the display box holds."""


def refusals(pd: PdProcess) -> list[tuple[str, str]]:
    """(address, reason) of every ``batteur-rejected`` line the panel printed (Pd escapes spaces, commas and
    semicolons inside a symbol with a backslash)."""
    pd.printed("batteur-rejected")  # reads what Pd said so far
    out = []
    for line in pd.lines:
        if line.startswith("batteur-rejected: "):
            address, _, reason = line[len("batteur-rejected: "):].partition(" ")
            out.append((address, reason.replace("\\", "")))
    return out


def display(patch: Path) -> str:
    """The text of the panel's display box (the message box after ``r bp-rejected``) in a saved patch."""
    lines = patch.read_text(encoding="utf-8").splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith("#X obj") and line.endswith(" r bp-rejected;"))
    box = next(line for line in lines[at:] if line.startswith("#X msg"))
    return box.split(" ", 4)[4].rsplit(", f ", 1)[0]


def test_the_panel_shows_and_prints_each_services_refusal(tmp_path: Path) -> None:
    """A stand-in physics service answers the panel's control with the refusal of each of the four services, sent
    back to the port the control came from: the panel prints each (address and reason) and shows the last."""
    require_pd()
    panel = tmp_path / "control.pd"
    shutil.copy(PD_DIR / "control.pd", panel)
    (tmp_path / "saver.pd").write_text(SAVER, encoding="utf-8")
    answers: list[OscMessage] = [
        PhysicsRejected(address="/batteur/physics/control", reason="no mode; really, none"),
        SoundRejected(address="/batteur/sound/tension", instrument="crash", reason="crash: no tension"),
        InteractionError(request="/batteur/interaction/route/set", detail="bad host"),
        GraphicsRejected(address="/batteur/graphics/mode", reason="no preview loaded"),
    ]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as service:
        service.bind(("127.0.0.1", 0))
        service.settimeout(20)
        port = service.getsockname()[1]
        pd = PdProcess(panel, sends=[f"bp-port-physics {port}", "bp-mode symbol joint_ct"],
                       extra=["-open", str(tmp_path / "saver.pd")])
        try:
            data, sender = service.recvfrom(65536)
            assert data == encode(PhysicsControlMode(mode="joint_ct"))
            for answer in answers:
                service.sendto(encode(answer), sender)
            pd.wait_for(lambda _: len(refusals(pd)) == 4 and any("saved to:" in line for line in pd.lines))
        finally:
            pd.stop()
    assert refusals(pd) == [("/batteur/physics/control", "no mode; really, none"),
                            ("/batteur/sound/tension", "crash: no tension"),
                            ("/batteur/interaction/route/set", "bad host"),
                            ("/batteur/graphics/mode", "no preview loaded")]
    assert pd.errors() == [], "\n".join(pd.lines)
    assert display(panel).replace("\\", "") == "/batteur/graphics/mode no preview loaded"


def test_a_pause_with_nothing_playing_and_a_tension_on_a_cymbal_are_refused_on_the_panel() -> None:
    """Real physics and sound cores as nodes: the panel's pause (nothing plays) and tension on the crash (a cymbal
    has no tension) come back as the services' refusals, printed by the panel."""
    require_pd()

    async def main() -> None:
        async with physics_and_sound_nodes() as rig:
            physics, sound = rig.physics, rig.sound
            sends = [f"bp-port-score {rig.physics_port}", f"bp-port-sound {rig.sound_port}",
                     "bp-transport symbol pause", "bp-instrument symbol crash", "bp-tension 800"]
            pd = PdProcess(PD_DIR / "control.pd", sends=sends)
            try:
                await wait_for(lambda: len(refusals(pd)) >= 2, timeout=15)
            finally:
                pd.stop()
        assert physics.of(ScoreTransport)[-1].action == "pause"
        assert sound.of(SoundTension)[-1].instrument == "crash"
        got = dict(refusals(pd))
        assert "nothing is playing" in got["/batteur/score/transport"]
        assert "'crash' takes no /batteur/sound/tension" in got["/batteur/sound/tension"]

    asyncio.run(main())
