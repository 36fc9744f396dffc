"""Graphics controls a new user got wrong: a tip-height plot whose lowest height is above its highest was taken and
quietly clamped (the page's plot went blank), and ``/batteur/graphics/camera top`` was refused for lacking the six
numbers a preset does not use (and ``camera top 0 0 0 0 0 0`` for a distance it ignores)."""

from __future__ import annotations

import asyncio
import socket

import pytest

from batteur.tools import send
from common.messages import DropReason, MessageError, OscMessage, decode
from common.messages.graphics import GraphicsCamera, GraphicsPlot, GraphicsRejected
from common.transport import UdpEndpoint
from services.graphics.camera import PRESETS, camera_for
from services.graphics.core import GraphicsCore, GraphicsSettings
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(60)

FREE = ["free", 30.0, 20.0, 2.5, 0.0, 0.25, 0.75]


def _node_answers(messages: list[tuple[str, list[int | float | str]]]) -> tuple[list[OscMessage], int, int]:
    """Send ``messages`` to a graphics-role endpoint; what it answered, its valid messages and its drops."""

    async def main() -> tuple[list[OscMessage], int, int]:
        node = await UdpEndpoint.open("127.0.0.1", role="graphics")
        client = await UdpEndpoint.open("127.0.0.1")
        got: list[OscMessage] = []
        client.set_handler(lambda message, _: got.append(message))
        taken: list[OscMessage] = []
        node.set_handler(lambda message, _: taken.append(message))
        try:
            for address, args in messages:
                client.send_raw(address, args, node.local_address)
            client.send_raw("/batteur/graphics/latency", ["soon"], node.local_address)  # sentinel: refused last
            await wait_for(lambda: any(getattr(m, "address", "") == "/batteur/graphics/latency" for m in got), 10.0)
            await asyncio.sleep(0)
            return got[:-1], node.stats.messages_in, node.stats.dropped_total - 1
        finally:
            client.close()
            node.close()

    return asyncio.run(main())


# --- the plot --------------------------------------------------------------------------------------------------
def test_a_plot_whose_lowest_height_is_above_its_highest_is_refused_by_the_node_and_counted() -> None:
    got, taken, dropped = _node_answers([("/batteur/graphics/plot", [2.0, 1.5, 0.5])])
    assert (taken, dropped) == (0, 1)
    assert len(got) == 1 and isinstance(got[0], GraphicsRejected)
    assert got[0].address == "/batteur/graphics/plot"
    assert got[0].reason == "out_of_range: /batteur/graphics/plot: z_max 0.5 must be above z_min 1.5 (metres)"


@pytest.mark.parametrize("z", [(1.5, 0.5), (1.0, 1.0)])
def test_the_model_refuses_it_so_batteur_send_says_the_same(z: tuple[float, float],
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(MessageError) as caught:
        GraphicsPlot.from_args([2.0, *z])
    assert caught.value.reason is DropReason.OUT_OF_RANGE
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as node:
        node.bind(("127.0.0.1", 0))
        code = send.main(["/batteur/graphics/plot", "2", *map(str, z), "--to", f"127.0.0.1:{node.getsockname()[1]}"])
    assert code == 2
    assert f"z_max {z[1]:g} must be above z_min {z[0]:g} (metres)" in capsys.readouterr().err


def test_a_plot_in_order_is_shown_as_sent() -> None:
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(GraphicsPlot.from_args([2.0, 1.0, 1.02]), 0.0, "127.0.0.1:9")
    assert core.view.plot == {"window": 2.0, "z_min": 1.0, "z_max": 1.02}  # was widened to 1.05 behind its back


# --- the camera ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("preset", [p for p in PRESETS])
def test_a_preset_alone_is_taken_and_its_own_numbers_apply(preset: str) -> None:
    message = GraphicsCamera.from_args([preset])
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    assert core.handle(message, 0.0, "127.0.0.1:9") == []
    view = PRESETS[preset]  # type: ignore[index]
    assert core.view.camera == {"preset": preset, "azimuth_deg": view.azimuth_deg, "elevation_deg": view.elevation_deg,
                                "distance": view.distance, "target": list(view.target)}
    assert len(message.to_args()) == 7  # on the wire as before: Pd's and older nodes' decoders take it


def test_numbers_sent_with_a_preset_are_not_judged() -> None:
    message = GraphicsCamera.from_args(["top", 0, 0, 0, 0, 0, 0])  # distance 0: out of range for free
    core = GraphicsCore(GraphicsSettings(latency=0.0, clock="rig"))
    core.handle(message, 0.0, "127.0.0.1:9")
    assert core.view.camera == camera_for("top", 0.0, 0.0, 1.0, (0.0, 0.0, 0.0))
    kept = GraphicsCamera.from_args(["side", 45.0, 10.0, 2.0, 0.5, 0.5, 0.5])  # in range: kept as sent
    assert kept.to_args() == ["side", 45.0, 10.0, 2.0, 0.5, 0.5, 0.5]


def test_free_still_needs_its_numbers_and_says_which() -> None:
    with pytest.raises(MessageError) as alone:
        GraphicsCamera.from_args(["free"])
    assert alone.value.reason is DropReason.WRONG_ARITY
    assert "free needs the 6 numbers after it: AZIMUTH_DEG ELEVATION_DEG DISTANCE TARGET_X TARGET_Y TARGET_Z" in str(
        alone.value)
    with pytest.raises(MessageError) as short:
        GraphicsCamera.from_args(["free", 30.0, 20.0])
    assert short.value.reason is DropReason.WRONG_ARITY and "got 2" in str(short.value)
    with pytest.raises(MessageError) as out:
        GraphicsCamera.from_args(["free", 30.0, 20.0, 0.0, 0.0, 0.0, 0.0])
    assert out.value.reason is DropReason.OUT_OF_RANGE and "distance" in str(out.value)
    assert GraphicsCamera.from_args(FREE).to_args() == FREE  # the seven arguments, unchanged


def test_a_preset_with_some_numbers_or_none_at_all_is_wrong_arity() -> None:
    for args in ([], ["top", 30.0]):
        with pytest.raises(MessageError) as caught:
            GraphicsCamera.from_args(args)
        assert caught.value.reason is DropReason.WRONG_ARITY
        assert "or the preset alone" in str(caught.value)


def test_the_node_takes_a_preset_alone_and_refuses_free_alone() -> None:
    got, taken, dropped = _node_answers([("/batteur/graphics/camera", ["top"]),
                                         ("/batteur/graphics/camera", ["top", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
                                         ("/batteur/graphics/camera", ["free"])])
    assert (taken, dropped) == (2, 1)
    assert len(got) == 1 and isinstance(got[0], GraphicsRejected) and "free needs the 6 numbers" in got[0].reason


def test_batteur_send_sends_a_preset_alone(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as node:
        node.bind(("127.0.0.1", 0))
        to = f"127.0.0.1:{node.getsockname()[1]}"
        assert send.main(["/batteur/graphics/camera", "top", "--to", to]) == 0
        sent = decode(node.recv(65536)).messages[0]
        assert send.main(["/batteur/graphics/camera", "free", "--to", to]) == 2
    assert isinstance(sent, GraphicsCamera) and sent.preset == "top"
    err = capsys.readouterr().err
    assert "free needs the 6 numbers after it" in err and "takes PRESET AZIMUTH_DEG" in err


def test_a_preset_alone_carries_the_front_presets_numbers() -> None:
    front = PRESETS["front"]
    assert GraphicsCamera.PRESET_NUMBERS == {
        "azimuth_deg": front.azimuth_deg, "elevation_deg": front.elevation_deg, "distance": front.distance,
        "target_x": front.target[0], "target_y": front.target[1], "target_z": front.target[2]}
