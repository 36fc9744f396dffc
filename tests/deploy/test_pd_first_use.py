"""A new user's first session with the Pd patches: the panel's ports, the master section, the sound client's start."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from common.messages import encode_raw
from common.messages.physics import PhysicsControlMode
from common.messages.score import ScoreLoad
from common.messages.sound import SoundDamping, SoundMaster
from tests.deploy.pdrun import PD_DIR, PdProcess, of, own_network, require_pd, services
from tests.ports import free_port, free_ports

pytestmark = pytest.mark.timeout(120)

ROLES = ("physics", "interaction", "sound", "graphics", "score")
NO_SCORE = "pd-first-use-no-such-score"
"""A score name no library holds: were it to reach a real rig on a default port, it would only be refused."""


# ---------------------------------------------------------------- score messages follow the physics port


def test_score_messages_go_to_the_physics_port_a_user_set() -> None:
    """``bp-port-physics N`` alone (the port ``batteur rig --base-port N`` gives physics): the score load reaches N,
    where the physics node's score player is. It used to go to the panel's own score port (9101). (Only a load of a
    score no library holds: a panel that regressed sends nothing a rig on 9101 would act on.)"""
    require_pd()
    with services(1) as (physics,):
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-physics {physics.port}", "bp-mode symbol joint_ct",
                                                     f"bp-score symbol {NO_SCORE}"])
        try:
            got = physics.until(lambda ms: of(ScoreLoad)(ms) and of(PhysicsControlMode)(ms), pd)
        finally:
            pd.stop()
    assert [m for m in got if isinstance(m, ScoreLoad)] == [ScoreLoad(path=NO_SCORE)]
    assert pd.errors() == [], "\n".join(pd.lines)


@pytest.mark.parametrize(("moved", "field"), [("bp-nuance symbol staccato", "nuance"),
                                              ("bp-sticking symbol paradiddle", "sticking")])
def test_one_style_choice_keeps_the_score_players_start_for_the_other_three(moved: str, field: str) -> None:
    """The style message carries all four choices: one changed first sends the other three as a physics node's
    score player starts with them (its ``--grip`` default as planned, and its own start style), not the panel's."""
    from common.gesture.plan import planned_grip
    from common.messages.score import GestureStyle
    from services.physics.node import PhysicsNodeSettings
    from services.physics.score_player import START_ALGORITHM, START_NUANCE, START_STICKING

    require_pd()
    with services(1) as (physics,):
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-physics {physics.port}", moved])
        try:
            got = physics.until(of(GestureStyle), pd)
        finally:
            pd.stop()
    style = next(m for m in got if isinstance(m, GestureStyle))
    start = {"grip": planned_grip(PhysicsNodeSettings.model_fields["grip"].default).value,
             "nuance": START_NUANCE.value, "algorithm": START_ALGORITHM.value, "sticking": START_STICKING.value}
    expected = {**start, field: moved.split()[-1]}
    assert style.model_dump() == expected


@pytest.mark.parametrize("order", ["score-first", "physics-first"])
def test_a_score_port_set_on_its_own_keeps_the_score_there(order: str) -> None:
    """``bp-port-score M`` overrides: the score goes to M, whichever of the two ports is given first."""
    require_pd()
    with services(2) as (physics, score):
        ports = [f"bp-port-physics {physics.port}", f"bp-port-score {score.port}"]
        pd = PdProcess(PD_DIR / "control.pd", sends=[*(ports if order == "physics-first" else ports[::-1]),
                                                     f"bp-score symbol {NO_SCORE}", "bp-mode symbol joint_ct"])
        try:
            score.until(of(ScoreLoad), pd)
            physics.until(of(PhysicsControlMode), pd)
        finally:
            pd.stop()
    assert not of(ScoreLoad)(physics.received), physics.received
    assert not of(PhysicsControlMode)(score.received), score.received


# ---------------------------------------------------------------- the port boxes show the ports in use


def _probed_panel(tmp_path: Path) -> Path:
    """A copy of the panel whose port boxes also send what they output to ``probe-ROLE``, printed as
    ``port-ROLE``: banging a box (``bp-port-ROLE bang``) then prints the value it shows."""
    text = (PD_DIR / "control.pd").read_text(encoding="utf-8")
    for role in ROLES:
        box = f" empty bp-port-{role} empty "
        assert text.count(box) == 1, role
        text = text.replace(box, f" probe-{role} bp-port-{role} empty ")
    panel = tmp_path / "control.pd"
    panel.write_text(text, encoding="utf-8")
    probe = ["#N canvas 0 0 400 300 12;"]
    for k, role in enumerate(ROLES):
        probe += [f"#X obj 10 {10 + 60 * k} r probe-{role};", f"#X obj 10 {35 + 60 * k} print port-{role};"]
    probe += [f"#X connect {2 * k} 0 {2 * k + 1} 0;" for k in range(len(ROLES))]
    (tmp_path / "probe.pd").write_text("\n".join(probe) + "\n", encoding="utf-8")
    return panel


def test_the_port_boxes_show_the_default_ports_at_load(tmp_path: Path) -> None:
    """Each port box shows the port the panel sends to (9101..9104, score with physics), not 0."""
    require_pd()
    panel = _probed_panel(tmp_path)
    pd = PdProcess(panel, sends=[f"bp-port-{role} bang" for role in ROLES], extra=["-open", str(tmp_path / "probe.pd")])
    try:
        pd.wait_for(lambda _: all(pd.printed(f"port-{role}") for role in ROLES))
    finally:
        pd.stop()
    shown = {role: pd.printed(f"port-{role}")[0] for role in ROLES}
    assert shown == {"physics": ["9101"], "interaction": ["9102"], "sound": ["9103"], "graphics": ["9104"],
                     "score": ["9101"]}, "\n".join(pd.lines)


def test_the_score_box_shows_the_physics_port_it_follows(tmp_path: Path) -> None:
    require_pd()
    panel = _probed_panel(tmp_path)
    port = free_port()
    pd = PdProcess(panel, sends=[f"bp-port-physics {port}", "bp-port-score bang"],
                   extra=["-open", str(tmp_path / "probe.pd")])
    try:
        pd.wait_for(lambda _: bool(pd.printed("port-score")))
    finally:
        pd.stop()
    assert pd.printed("port-score") == [[str(port)]], "\n".join(pd.lines)


# ---------------------------------------------------------------- master gain and reverb


def _sound_defaults() -> tuple[float, float]:
    """(master gain dB, reverb) a sound service started by ``batteur sound`` or ``batteur rig`` has."""
    from services.sound.core import SoundSettings
    from services.sound.node import SoundNodeSettings

    return SoundSettings.model_fields["master_db"].default, SoundNodeSettings.model_fields["reverb"].default


@pytest.mark.parametrize(("moved", "value", "kept"), [("bp-master", -6.0, "reverb"), ("bp-reverb", 0.3, "gain_db")])
def test_moving_one_master_control_keeps_the_services_default_for_the_other(moved: str, value: float,
                                                                             kept: str) -> None:
    """The master gain moved first used to send reverb 0, switching the service's reverb (0.1) off."""
    require_pd()
    gain_db, reverb = _sound_defaults()
    with services(1) as (sound,):
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-sound {sound.port}", f"{moved} {value}"])
        try:
            got = sound.until(of(SoundMaster), pd)
        finally:
            pd.stop()
    master = next(m for m in got if isinstance(m, SoundMaster))
    expected = {"reverb": reverb, "gain_db": gain_db}
    assert getattr(master, kept) == pytest.approx(expected[kept], abs=1e-6)
    assert getattr(master, "gain_db" if kept == "reverb" else "reverb") == pytest.approx(value, abs=1e-6)


def _kit_damping(name: str) -> tuple[float, float]:
    """(sigma0, sigma1) a sound service starts ``name`` with on the default kit."""
    from common.kit import load_kit
    from services.sound.instruments import default_params

    params = default_params(next(obj for obj in load_kit("default").objects if obj.id == name))
    return params.damping0, params.damping1


def test_damping_keeps_each_instruments_other_value() -> None:
    """Moving one damping slider sends the other value as the chosen instrument has it: the kit's value until the
    panel sent one for that instrument (it used to send 0, or the value last sent for another instrument)."""
    require_pd()
    sends = ["bp-instrument symbol kick", "bp-sigma0 30", "bp-instrument symbol snare", "bp-sigma1 0.0002",
             "bp-instrument symbol kick", "bp-sigma1 0.0003", "bp-instrument symbol snare", "bp-sigma0 10"]
    with services(1) as (sound,):
        pd = PdProcess(PD_DIR / "control.pd", sends=[f"bp-port-sound {sound.port}", *sends])
        try:
            got = sound.until(lambda ms: sum(isinstance(m, SoundDamping) for m in ms) == 4, pd)
        finally:
            pd.stop()
    damping = [(m.instrument, m.sigma0, m.sigma1) for m in got if isinstance(m, SoundDamping)]
    kick, snare = _kit_damping("kick"), _kit_damping("snare")
    assert damping == [("kick", 30, pytest.approx(kick[1])), ("snare", pytest.approx(snare[0]), pytest.approx(2e-4)),
                       ("kick", 30, pytest.approx(3e-4)), ("snare", 10, pytest.approx(2e-4))]


# ---------------------------------------------------------------- the sound client given a host and a port


@pytest.mark.parametrize("order", ["host-first", "port-first"])
def test_sound_client_given_host_and_port_listens_once_there(order: str) -> None:
    """``-send "sc-host ..." -send "sc-port N"`` (either order): the client listens once, on N at that host. Given
    the host first it used to listen on 9103 first (``listen failed: Address already in use`` beside a rig)."""
    port = free_port()
    sends = ["sc-host symbol 127.0.0.2", f"sc-port {port}"]
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=sends if order == "host-first" else sends[::-1],
                   prefix=own_network())
    try:
        pd.wait_for(lambda _: any(f"listen {port} 127.0.0.2" in line for line in pd.lines))
    finally:
        pd.stop()
    assert pd.printed("batteur-listen") == [["listen", str(port), "127.0.0.2"]], "\n".join(pd.lines)
    assert pd.errors() == [], "\n".join(pd.lines)


def test_sound_client_moved_by_osc_after_start_listens_on_the_new_port() -> None:
    """``/pd/port N`` to a running client still moves it at once (the start-up deferral must not hold it)."""
    first, second = free_ports(2)
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=[f"sc-port {first}"])
    try:
        pd.wait_for(lambda _: any(f"listen {first}" in line for line in pd.lines))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.sendto(encode_raw("/pd/port", [second]), ("127.0.0.1", first))
        pd.wait_for(lambda _: any(f"listen {second}" in line for line in pd.lines))
    finally:
        pd.stop()
    assert pd.printed("batteur-listen") == [["listen", str(first), "127.0.0.1"], ["listen", str(second), "127.0.0.1"]]
