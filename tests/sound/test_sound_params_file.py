"""Sound parameters files: what the /batteur/sound/... controls set is written at a node's stop and read back at
start (``--sound-params``, ``--sound-params-out``), the same sound; a bad entry is refused naming it."""

from __future__ import annotations

import asyncio
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from sound_helpers import impact

from common.exit_status import InputError
from common.kit import load_kit
from common.messages.sound import (
    SoundAirLoading,
    SoundDamping,
    SoundLevel,
    SoundModel,
    SoundModes,
    SoundRadius,
    SoundRejected,
    SoundResonances,
    SoundTension,
)
from common.transport import UdpEndpoint
from services.sound import core as sound_core
from services.sound import node as sound_node
from services.sound.core import SoundCore, SoundSettings
from services.sound.node import SoundNodeSettings, make_core, save_params
from services.sound.params_file import (
    apply_sound_params,
    check_against_kit,
    current_values,
    load_sound_params,
    write_sound_params,
)
from tests.ports import free_port

ROOT = Path(__file__).resolve().parents[2]
NODE = [sys.executable, "-m", "services.sound.node", "--no-discovery", "--no-oscquery", "--clock-master", "self",
        "--device", "none", "--channels", "1"]
CHANGES = [
    SoundTension(instrument="snare", value=3200.0),
    SoundLevel(instrument="kick", gain_db=-4.5),
    SoundAirLoading(instrument="snare", value=0.4),
    SoundModes(instrument="hightom", value=60),
    SoundDamping(instrument="floortom", sigma0=12.0, sigma1=2e-5),
    SoundResonances(instrument="snare", gains=(1.0, 0.5, 2.0)),
    SoundRadius(instrument="kick", value=0.3),
    SoundModel(instrument="ride", model="synth"),
]


def _core() -> SoundCore:
    return SoundCore(SoundSettings(use_pyo=False, latency=0.0))


def _play(core: SoundCore) -> np.ndarray:
    for n, name in enumerate(("snare", "kick", "hightom", "floortom", "ride")):
        core.handle(impact(n, 0.05 * n, name), core.now, "t")
    return core.render(0.4)


def test_what_the_controls_set_is_written_and_read_back_to_the_same_sound(tmp_path: Path) -> None:
    live = _core()
    for message in CHANGES:
        assert live.handle(message, live.now, "panel") == []
    path = tmp_path / "sound.yaml"
    written = write_sound_params(live, path)
    data = yaml.safe_load(path.read_text())
    assert data == {"instruments": written}
    # only what changed, keyed by the controls' addresses' last part, one value alone
    assert written["snare"] == {"air": 0.4, "resonances": [1.0, 0.5, 2.0], "tension": 3200.0}
    assert written["kick"] == {"level": -4.5, "radius": pytest.approx(0.3)}
    assert written["hightom"] == {"modes": 60}
    assert written["floortom"] == {"damping": {"sigma0": 12.0, "sigma1": pytest.approx(2e-5)}}
    assert written["ride"] == {"model": "synth"}
    assert set(written) == {"snare", "kick", "hightom", "floortom", "ride"}

    restarted = _core()
    apply_sound_params(restarted, load_sound_params(path), path)
    for inst_id, inst in live.instruments.instruments.items():
        assert current_values(restarted.instruments.instruments[inst_id]) == current_values(inst), inst_id
    assert np.array_equal(_play(restarted), _play(live))
    fresh = _core()
    assert not np.array_equal(_play(fresh), _play(_core_with(path)))  # the file does change the sound


def _core_with(path: Path) -> SoundCore:
    core = _core()
    apply_sound_params(core, load_sound_params(path), path)
    return core


def test_json_is_read_and_written_too(tmp_path: Path) -> None:
    live = _core()
    live.handle(SoundTension(instrument="snare", value=2000.0), live.now, "panel")
    path = tmp_path / "sound.json"
    write_sound_params(live, path)
    messages = load_sound_params(path)
    assert messages == [SoundTension(instrument="snare", value=2000.0)]


@pytest.mark.parametrize(("text", "said"), [
    ("instruments: {snare: {tensoin: 3000}}", "instruments.snare.tensoin: no such sound parameter (the file takes: "
     "air, damping, density, level, model, modes, openness, position, radius, resonances, second_head, snares, "
     "stick, tension, thickness"),
    ("instruments: {snare: {tension: 5}}", "instruments.snare.tension (/batteur/sound/tension): must be at least "
     "10, got 5"),
    ("instruments: {snare: {damping: 14}}", "instruments.snare.damping: give its fields as a mapping "
     "({sigma0: ..., sigma1: ...}, as /batteur/sound/damping takes them), got 14"),
    ("instruments: {snare: {damping: {sigma0: 14}}}", "instruments.snare.damping (/batteur/sound/damping): sigma1: "
     "Field required"),
    ("instruments: {snare: {model: granular}}", "instruments.snare.model (/batteur/sound/model): must be 'modal', "
     "'sample' or 'synth', got 'granular'"),
    ("instrument: {snare: {tension: 3000}}", "instrument"),
    ("instruments: {snare: [1]}", "instruments.snare"),
    ("instruments: {snare: {tension: 3000}", "not valid YAML"),
])
def test_a_bad_entry_is_refused_naming_it(tmp_path: Path, text: str, said: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ValueError) as caught:
        load_sound_params(path)
    assert str(caught.value).startswith(f"--sound-params {path}: ")
    assert said in str(caught.value)


def test_an_entry_the_kit_cannot_take_is_refused_naming_the_addresses(tmp_path: Path) -> None:
    kit = load_kit("default")
    path = tmp_path / "p.yaml"
    path.write_text("instruments: {gong: {level: -3}}")
    with pytest.raises(ValueError, match=r"instruments.gong: the kit 'default' has no instrument 'gong' \(it has: "
                       r"china, cowbell, crash, floortom, hightom, hihat, kick, midtom, ride, snare, splash\)"):
        check_against_kit(load_sound_params(path), kit, path)
    path.write_text("instruments: {ride: {tension: 3000}}")
    with pytest.raises(ValueError) as caught:
        check_against_kit(load_sound_params(path), kit, path)
    said = str(caught.value)
    assert "instruments.ride.tension: cymbal instrument 'ride' takes no /batteur/sound/tension (it takes: " in said
    assert "/batteur/sound/thickness" in said and "n_modes" not in said and "air_loading" not in said


def test_a_value_an_instrument_refuses_when_applied_names_the_entry(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("instruments: {hightom: {tension: 100000, density: 0.011, radius: 0.021}}")
    with pytest.raises(ValueError, match=r"instruments.hightom.radius: hightom: every mode would be above"):
        apply_sound_params(_core(), load_sound_params(path), path)


def test_the_node_starts_from_the_file_and_writes_what_it_holds(tmp_path: Path) -> None:
    start = tmp_path / "start.yaml"
    start.write_text("instruments: {snare: {tension: 2500, level: -2}}\n")
    out = tmp_path / "out.yaml"
    settings = SoundNodeSettings(device="none", sound_params=start, sound_params_out=out)
    core = make_core(settings)
    try:
        snare = core.instruments.instruments["snare"]
        assert snare.p.tension == 2500.0 and snare.p.level_db == -2.0
        core.handle(SoundLevel(instrument="kick", gain_db=-6.0), core.now, "panel")  # computed at once
        core.handle(SoundModes(instrument="snare", value=40), core.now, "panel")  # in the background
        save_params(core, out)  # waits for the change being computed
    finally:
        core.close()
    assert yaml.safe_load(out.read_text())["instruments"] == {
        "kick": {"level": -6.0}, "snare": {"level": -2.0, "modes": 40, "tension": 2500.0}}


def test_the_node_refuses_a_bad_file_before_it_starts(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("instruments: {snare: {tension: 5}}")
    with pytest.raises(InputError, match=r"instruments.snare.tension \(/batteur/sound/tension\)"):
        make_core(SoundNodeSettings(device="none", sound_params=path))
    with pytest.raises(InputError, match="no such file"):
        make_core(SoundNodeSettings(device="none", sound_params=tmp_path / "none.yaml"))
    with pytest.raises(InputError, match="--sound-params-out .*is a directory"):
        make_core(SoundNodeSettings(device="none", sound_params_out=tmp_path))


def test_a_running_node_writes_what_its_controls_set_when_it_stops(tmp_path: Path) -> None:
    start = tmp_path / "sound.yaml"
    start.write_text("instruments: {snare: {tension: 2500}}\n")
    port = free_port()
    err = (tmp_path / "node.err").open("w")
    # the same file in and out: the designer's file, kept up to date at each stop
    proc = subprocess.Popen([*NODE, "--port", str(port), "--sound-params", str(start), "--sound-params-out",
                             str(start)], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=err,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    got: list[SoundRejected] = []

    async def tweak() -> None:
        client = await UdpEndpoint.open("127.0.0.1")
        client.set_handler(lambda message, _: got.append(message) if isinstance(message, SoundRejected) else None)
        try:
            deadline = time.monotonic() + 90.0
            while not got:  # until the node answers (it is listening, and has applied what came before)
                assert proc.poll() is None and time.monotonic() < deadline, (tmp_path / "node.err").read_text()
                client.send_raw("/batteur/sound/level", ["kick", -6.0], ("127.0.0.1", port))
                client.send_raw("/batteur/sound/tension", ["ride", 800.0], ("127.0.0.1", port))  # refused
                await asyncio.sleep(0.2)
        finally:
            client.close()

    try:
        asyncio.run(tweak())
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "cymbal instrument 'ride' takes no /batteur/sound/tension" in got[0].reason
    assert yaml.safe_load(start.read_text())["instruments"] == {"kick": {"level": -6.0}, "snare": {"tension": 2500.0}}


class _ClosingSink:
    """A sink that says when the core closes it (the WAV file's place)."""

    def __init__(self) -> None:
        self.closed = threading.Event()

    def __call__(self, block: np.ndarray) -> None:
        pass

    def close(self) -> None:
        self.closed.set()


def _change_in_flight_until(monkeypatch: pytest.MonkeyPatch, event: threading.Event) -> None:
    """Rebuilds in the worker wait for ``event`` first: a change still being computed when the core closes."""
    real = sound_core._apply_changes  # noqa: SLF001

    def slow(*args: Any) -> Any:
        event.wait(60)
        return real(*args)

    monkeypatch.setattr(sound_core, "_apply_changes", slow)


def test_a_change_still_being_computed_at_the_stop_is_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The file was written after the core closed, its rebuilds abandoned: the change was lost without a word."""
    out = tmp_path / "out.yaml"
    monkeypatch.setattr(sound_node, "SAVE_WAIT_S", 60.0)  # no race: the change ends once the take is closed
    core = make_core(SoundNodeSettings(device="none", sound_params_out=out))
    take = _ClosingSink()
    core.sinks.append(take)
    _change_in_flight_until(monkeypatch, take.closed)
    core.handle(SoundModes(instrument="snare", value=40), core.now, "panel")
    assert core.rebuilding
    core.close()  # as the node's stop does: the take closed first, then the change waited for, then written
    assert take.closed.is_set() and not core.rebuilding
    assert yaml.safe_load(out.read_text())["instruments"] == {"snare": {"modes": 40}}


def test_a_change_not_computed_in_time_is_warned_of(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    caplog: pytest.LogCaptureFixture) -> None:
    out = tmp_path / "out.yaml"
    monkeypatch.setattr(sound_node, "SAVE_WAIT_S", 0.0)
    core = make_core(SoundNodeSettings(device="none", sound_params_out=out))
    never = threading.Event()
    _change_in_flight_until(monkeypatch, never)
    try:
        core.handle(SoundLevel(instrument="kick", gain_db=-6.0), core.now, "panel")  # computed at once
        core.handle(SoundModes(instrument="snare", value=40), core.now, "panel")
        core.close()
    finally:
        never.set()
    assert f"--sound-params-out {out}: a parameter change was still being computed after 0 s: it is not saved" \
        in caplog.text
    assert yaml.safe_load(out.read_text())["instruments"] == {"kick": {"level": -6.0}}  # the rest is kept


def test_a_core_that_failed_to_start_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "out.yaml"
    core = make_core(SoundNodeSettings(device="none", sound_params_out=out), keep_params=lambda: False)
    core.handle(SoundLevel(instrument="kick", gain_db=-6.0), core.now, "panel")
    core.close()
    assert not out.exists()


@pytest.mark.parametrize("name", ["take.wav", "take.wav.json"])
def test_the_file_may_not_be_the_take(tmp_path: Path, name: str) -> None:
    """Given --wav's take (or its .json) the node stopped by replacing the recording with YAML."""
    wav = tmp_path / "take.wav"
    (tmp_path / "sub").mkdir()  # the same file by another path
    with pytest.raises(InputError, match=rf"--sound-params-out .*{name} is --wav's take.*: the parameters would "
                       "replace it"):
        make_core(SoundNodeSettings(device="none", wav=wav, sound_params_out=tmp_path / "sub" / ".." / name))
    assert not wav.exists()


@pytest.mark.parametrize("name", ["p.toml", "p.txt", "params"])
def test_a_file_name_whose_format_it_does_not_write_is_refused(tmp_path: Path, name: str) -> None:
    """A p.toml was written as YAML, then refused by --sound-params at the next start (read as TOML)."""
    with pytest.raises(InputError, match=r"--sound-params-out .*: give a file ending in .yaml, .yml or .json"):
        make_core(SoundNodeSettings(device="none", sound_params_out=tmp_path / name))
    with pytest.raises(ValueError, match="ends in .yaml, .yml or .json"):
        write_sound_params(_core(), tmp_path / name)


@pytest.mark.parametrize("name", ["p.yaml", "p.yml", "p.json", "P.JSON"])
def test_what_is_written_is_read_back(tmp_path: Path, name: str) -> None:
    live = _core()
    try:
        live.handle(SoundLevel(instrument="kick", gain_db=-4.5), live.now, "t")
        write_sound_params(live, tmp_path / name)
    finally:
        live.close()
    assert load_sound_params(tmp_path / name) == [SoundLevel(instrument="kick", gain_db=-4.5)]
