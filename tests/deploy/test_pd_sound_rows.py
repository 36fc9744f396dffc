"""The control panel's SOUND section (its [pd sound] sub-patch) covers every /batteur/sound/* control: the second
head, the stick and the per-mode resonances too, each sent for the chosen instrument with the arguments its model
takes, its sliders over the model's ranges only."""

from __future__ import annotations

import re
import socket
from collections.abc import Sequence

import pytest

from common.messages import REGISTRY, Family, OscMessage, decode
from common.messages.base import MessageError
from common.messages.sound import (
    SoundLatency,
    SoundMaster,
    SoundRejected,
    SoundResonances,
    SoundSecondHead,
    SoundStick,
)
from common.transport import REFUSAL_ENDINGS, owner_role
from services.sound.core import PARAM_MESSAGES
from tests.deploy.pdrun import PD_DIR, PdProcess, require_pd
from tests.ports import free_port

pytestmark = pytest.mark.timeout(120)

NEW = (SoundSecondHead, SoundStick, SoundResonances)
ONES = (1.0,) * 8
"""The resonance gains of modes 1..8 an instrument of the default kit starts with (its list is empty: all 1)."""


def _kit(name: str) -> tuple[tuple[float, float, float], tuple[float, float]]:
    """((stick mass, stiffness, exponent), (second head gain, ratio)) a sound service starts ``name`` with."""
    from common.kit import load_kit
    from services.sound.instruments import default_params

    p = default_params(next(obj for obj in load_kit("default").objects if obj.id == name))
    assert p.resonances == ()  # the panel's memory starts every mode at 1
    return (p.stick_mass, p.stick_stiffness, p.stick_exponent), (p.second_head, p.reso_ratio)


def _sent(sends: Sequence[str], count: int) -> tuple[list[OscMessage], list[MessageError]]:
    """The first ``count`` messages of ``NEW`` the panel sends to a stand-in sound service (a loopback socket),
    driven by ``sends``, decoded with the rig's message models; and every datagram the models refused."""
    require_pd()
    port = free_port()
    got: list[OscMessage] = []
    refused: list[MessageError] = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", port))
        sock.settimeout(15)
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-sound {port}", *sends])
        try:
            while len(got) + len(refused) < count:
                try:
                    data = sock.recv(65536)
                except TimeoutError:
                    raise AssertionError(f"got only {got}, {refused}:\n" + "\n".join(pd.lines)) from None
                decoded = decode(data)
                got += [m for m in decoded.messages if isinstance(m, NEW)]
                refused += decoded.errors
        finally:
            pd.stop()
    assert pd.errors() == [], "\n".join(pd.lines)
    return got, refused


def sound_controls() -> set[str]:
    """The controls a sound node takes, as the runtime routes them (``common.transport.owner_role``: the control
    family under its address family, its refusals excepted): what the panel's SOUND section is meant to send. A
    model added to common/messages/sound.py with @register is among them, with no list here to update."""
    return {m.ADDRESS for m in REGISTRY if m.FAMILY is Family.CONTROL and owner_role(m.ADDRESS) == "sound"
            and not m.ADDRESS.endswith(REFUSAL_ENDINGS)}


def test_the_panel_has_a_control_for_every_sound_address() -> None:
    """Every control the sound service takes (each registered /batteur/sound/* address but its refusal) has an
    [oscformat] in the panel. It used to have 14 of the 17: no second head, stick or resonances."""
    text = (PD_DIR / "control.pd").read_text(encoding="utf-8")
    sent = {"/" + "/".join(m.split()) for m in re.findall(r" oscformat ([\w ]+);", text)}
    controls = sound_controls()
    missing = sorted(controls - sent)
    assert not missing, (f"the panel's SOUND section sends nothing to {missing}: add a row for each in "
                         "pd/make_control.py (sound_section) and run python3 pd/make_control.py")
    addresses = {m.ADDRESS for m in REGISTRY if m.ADDRESS.startswith("/batteur/sound/")}
    assert addresses - sent == {SoundRejected.ADDRESS}
    # what the sound core applies is among them (the set above is the core's, not empty by a wrong filter)
    applied = {m.ADDRESS for m in (*PARAM_MESSAGES, SoundLatency, SoundMaster)}
    assert applied <= controls == addresses - {SoundRejected.ADDRESS}


def test_second_head_stick_and_resonances_send_what_their_models_take() -> None:
    """Each new slider sends its message for the chosen instrument with every value of it (the others as the
    instrument has them: the default kit's, or what the panel sent for it), typed as its model takes them; the
    resonances' reset sends the instrument alone (every mode back to 1) and the panel keeps ones for it."""
    sends = ["bp-instrument symbol kick", "bp-second-head-gain 0.8", "bp-second-head-ratio 1.3",
             "bp-stick-mass 0.05", "bp-stick-stiffness 1e+06", "bp-stick-exponent 2",
             "bp-resonance-3 4", "bp-resonance-8 0.25", "bp-resonances-reset bang",
             "bp-instrument symbol crash", "bp-stick-exponent 2.5", "bp-resonance-1 0.5",
             "bp-instrument symbol kick", "bp-resonance-2 2", "bp-second-head-ratio 1.5"]
    got, refused = _sent(sends, 12)
    assert refused == []
    kick_stick, kick_head = _kit("kick")
    crash_stick, _ = _kit("crash")
    kick_mass, kick_k = kick_stick[0], kick_stick[1]
    assert [_values(m) for m in got] == [
        ("SoundSecondHead", "kick", pytest.approx((0.8, kick_head[1]))),
        ("SoundSecondHead", "kick", pytest.approx((0.8, 1.3))),
        ("SoundStick", "kick", pytest.approx((0.05, kick_k, 1.5))),
        ("SoundStick", "kick", pytest.approx((0.05, 1e6, 1.5))),
        ("SoundStick", "kick", pytest.approx((0.05, 1e6, 2))),
        ("SoundResonances", "kick", pytest.approx((1, 1, 4, 1, 1, 1, 1, 1))),
        ("SoundResonances", "kick", pytest.approx((1, 1, 4, 1, 1, 1, 1, 0.25))),
        ("SoundResonances", "kick", ()),
        ("SoundStick", "crash", pytest.approx((crash_stick[0], crash_stick[1], 2.5))),
        ("SoundResonances", "crash", pytest.approx((0.5, 1, 1, 1, 1, 1, 1, 1))),
        ("SoundResonances", "kick", pytest.approx((1, 2, 1, 1, 1, 1, 1, 1))),
        ("SoundSecondHead", "kick", pytest.approx((0.8, 1.5))),
    ]
    assert kick_mass != pytest.approx(0.05)  # the kit's mass was replaced by the one sent


def _values(message: OscMessage) -> tuple[str, str, tuple[float, ...]]:
    """(model name, instrument, every value after the instrument) of a sound message."""
    values = message.model_dump()
    instrument = values.pop("instrument")
    flat = [v for value in values.values() for v in (value if isinstance(value, tuple) else (value,))]
    return type(message).__name__, instrument, tuple(flat)


@pytest.mark.parametrize("end", ["above", "below"])
def test_the_new_sliders_cannot_send_a_value_their_model_refuses(end: str) -> None:
    """A value past a slider's end (typed or sent to its receive name) goes out as the end, which the model takes:
    the sliders range over the models' ranges (stick stiffness 1000..1e10, resonance gains 0..16 ...)."""
    far = {"bp-second-head-gain": (5, -1), "bp-second-head-ratio": (5, 0.1), "bp-stick-mass": (10, 0.0001),
           "bp-stick-stiffness": (1e12, 1), "bp-stick-exponent": (9, 0.5), "bp-resonance-5": (100, -3)}
    sends = ["bp-instrument symbol snare", *(f"{name} {values[end == 'below']:g}" for name, values in far.items())]
    got, refused = _sent(sends, len(far))
    assert refused == [], [str(e) for e in refused]
    assert [type(m) for m in got] == [SoundSecondHead] * 2 + [SoundStick] * 3 + [SoundResonances]
    ends = {"above": (2, 2, 2, 1e10, 3, 16), "below": (0, 0.5, 0.002, 1000, 1, 0)}[end]
    values = (got[0].gain, got[1].ratio, got[2].mass, got[3].stiffness, got[4].exponent, got[5].gains[4])
    assert values == pytest.approx(ends, rel=1e-6)


def test_second_head_stick_and_resonances_reach_a_sound_core() -> None:
    """Sent to a real sound core (a node), they are applied to the chosen instrument; the second head moved for
    the crash (a cymbal has none, and shows 0) goes with its ratio clipped into range, so the service refuses it
    saying why instead of the node dropping it unanswered (a ratio of 0 is out of the model's range)."""
    import asyncio

    from tests.deploy.pdrun import physics_and_sound_nodes
    from tests.waiting import wait_for

    require_pd()

    async def main() -> None:
        async with physics_and_sound_nodes() as rig:
            sound = rig.sound
            sends = [f"bp-port-sound {rig.sound_port}", "bp-instrument symbol floortom", "bp-second-head-gain 1.2",
                     "bp-instrument symbol ride", "bp-stick-mass 0.06", "bp-resonance-2 3",
                     "bp-instrument symbol crash", "bp-second-head-gain 1"]
            pd = PdProcess(PD_DIR / "control.pd", sends=sends)
            try:
                await wait_for(lambda: len(sound.of(SoundSecondHead)) >= 2, timeout=15)
            finally:
                pd.stop()
            assert pd.errors() == [], "\n".join(pd.lines)
            assert [(m.instrument, m.ratio) for m in sound.of(SoundSecondHead)][1:] == [("crash", 0.5)]
            assert sound.core.stats.rejected == {SoundSecondHead.ADDRESS: 1}  # the crash's, answered
            for node in rig.nodes:
                assert node.endpoint is not None and node.endpoint.stats.dropped_total == 0
            insts = sound.core.instruments.instruments
            assert insts["floortom"].p.second_head == pytest.approx(1.2)
            assert insts["ride"].p.stick_mass == pytest.approx(0.06)
            assert insts["ride"].p.resonances == pytest.approx((1, 3, 1, 1, 1, 1, 1, 1))
            assert insts["kick"].p.resonances == ()  # only the chosen instrument changed

    asyncio.run(main())
