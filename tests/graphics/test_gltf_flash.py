"""``batteur render SCORE --gltf`` shows the strikes: one thin emissive disc per struck kit object, on its head,
whose scale is keyed from a speck (HIDDEN_SCALE, "dark") to its full size at each of that object's impacts
(performance.wav's clock, as the rest of the file) and back about 0.15 s later (STEP keys: portable, no glTF
extension)."""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation

from common.kit import load_kit
from services.graphics.export import write_gltf
from services.graphics.export.gltf_flash import FLASH_S, HIDDEN_SCALE, MIN_GAP_S
from services.graphics.figure import synthetic_performance
from tests.graphics.gltf_reading import accessor, load
from tests.graphics.physics_poses import posed_frames
from tests.graphics.test_gltf_skin import validate

ROOT = Path(__file__).resolve().parents[2]
SCORE = ROOT / "tests" / "graphics" / "tiny_score.txt"


@pytest.fixture(scope="module")
def rendered(tiny_gltf_render: Path) -> Path:
    """``SCORE`` rendered with ``--gltf`` (and the BVH on the WAV's clock, the default): tests/conftest.py's one
    render, read only."""
    return tiny_gltf_render


def strikes(out: Path) -> dict[str, list[float]]:
    """Kit object id -> its impacts' times on performance.wav's clock (rig time + latency_s), seconds."""
    latency = json.loads((out / "report.json").read_text())["latency_s"]
    times: dict[str, list[float]] = defaultdict(list)
    with (out / "impacts.csv").open(newline="") as f:
        for row in csv.DictReader(f):
            times[row["instrument"]].append(float(row["time"]) + latency)
    return dict(times)


def scale_keys(gltf: pygltflib.GLTF2, node: int) -> tuple[np.ndarray, np.ndarray, str]:
    """(key times (N,), scales (N, 3), interpolation) of ``node``'s scale channel."""
    animation = gltf.animations[0]
    channels = [c for c in animation.channels if c.target.node == node and c.target.path == "scale"]
    assert len(channels) == 1
    sampler = animation.samplers[channels[0].sampler]
    return accessor(gltf, sampler.input)[:, 0], accessor(gltf, sampler.output), sampler.interpolation


def lit(scale: np.ndarray) -> bool:
    """Whether a flash of this scale (3,) shows: as wide as a head (radius over 5 cm)."""
    return bool(scale[0] > 0.05 and scale[1] > 0.05 and scale[2] > 0)


def dark(scale: np.ndarray) -> bool:
    """Whether a flash of this scale (3,) is hidden: a speck of at most HIDDEN_SCALE."""
    return bool(np.all(scale <= HIDDEN_SCALE * 1.0001))


def scale_at(times: np.ndarray, scales: np.ndarray, t: float) -> np.ndarray:
    """The STEP-interpolated scale at time ``t``: the last key at or before it."""
    return scales[max(int(np.searchsorted(times, t, side="right")) - 1, 0)]


def test_one_flash_per_struck_object_lit_at_each_of_its_impacts(rendered: Path) -> None:
    gltf = load(rendered / "performance.glb")
    assert gltf is not None
    report = json.loads((rendered / "report.json").read_text())
    frame = 1.0 / report["bvh_rate_hz"]
    struck = strikes(rendered)
    assert len(struck) >= 2 and sum(map(len, struck.values())) >= 4  # the score strikes several objects
    flashes = {n.name: k for k, n in enumerate(gltf.nodes) if (n.name or "").startswith("flash_")}
    assert sorted(flashes) == sorted(f"flash_{obj}" for obj in struck)
    for obj, heard in struck.items():
        node = flashes[f"flash_{obj}"]
        assert gltf.nodes[node].mesh is not None
        material = gltf.materials[gltf.meshes[gltf.nodes[node].mesh].primitives[0].material]
        assert max(material.emissiveFactor) > 0.5  # it glows
        times, scales, interpolation = scale_keys(gltf, node)
        assert interpolation == "STEP"
        assert dark(scales[0])  # before the first strike
        for t in heard:  # lit within one frame of each strike, full size (its head's radius)
            rises = [k for k in range(1, len(times)) if abs(times[k] - t) <= frame and lit(scales[k])]
            assert rises, f"{obj}: no flash at {t:.3f} s"
            assert lit(scale_at(times, scales, t + frame))
        for a, b in zip([0.0, *heard], [*heard, times[-1] + 1.0], strict=True):
            if b - a > 0.4:  # well between two strikes (or before the first, after the last): dark
                assert dark(scale_at(times, scales, a + 0.2)), f"{obj}: lit at {a + 0.2:.3f} s"
                assert dark(scale_at(times, scales, b - 0.05)), f"{obj}: lit at {b - 0.05:.3f} s"
        assert dark(scales[-1])  # after the last


def test_the_file_with_flashes_passes_the_khronos_validator(rendered: Path) -> None:
    report = validate(rendered / "performance.glb")
    assert (report["numErrors"], report["numWarnings"]) == (0, 0), report["messages"]


def test_close_strikes_keep_the_keys_increasing_and_moving_objects_carry_their_flash(tmp_path: Path) -> None:
    """Two snare strikes 0.5 ms apart light one flash; a strike before (or as) the last one's flash is over puts it out
    just before; a strike before time 0 shows at 0; an id not in the kit draws nothing. The ride's and the
    hi-hat's flashes ride their links (physics' frames carry them), above the drawn plate."""
    sequence = posed_frames([{}] * 4)
    path = tmp_path / "flash.glb"
    impacts = [(0.0105, "snare"), (0.01, "snare"), (0.1, "snare"), (0.3, "ride"), (-1.0, "hihat"), (0.2, "gong"),
               (7.7, "kick"), (7.8500001, "kick")]  # a hair over FLASH_S apart: as float32 the same key
    info = write_gltf(sequence, path, kit=load_kit("default"), impacts=impacts)
    assert info.flashes == 4
    gltf = load(path)
    assert gltf is not None
    flashes = {n.name: k for k, n in enumerate(gltf.nodes) if (n.name or "").startswith("flash_")}
    assert sorted(flashes) == ["flash_hihat", "flash_kick", "flash_ride", "flash_snare"]
    parent = {c: gltf.nodes[k].name for k, n in enumerate(gltf.nodes) for c in n.children or []}
    assert (parent[flashes["flash_ride"]], parent[flashes["flash_hihat"]]) == ("kit.ride", "kit.hihat.top")
    ride_lift, hihat_lift = (gltf.nodes[flashes[f"flash_{o}"]].translation[2] for o in ("ride", "hihat"))
    assert 0 < ride_lift < 0.01 < hihat_lift < 0.02  # on the cymbal's top face; above the top plate drawn 1 cm up
    times, scales, _ = scale_keys(gltf, flashes["flash_snare"])
    np.testing.assert_allclose(times, [0.0, 0.01, 0.1 - MIN_GAP_S, 0.1, 0.1 + FLASH_S], atol=1e-6)
    assert [lit(s) for s in scales] == [False, True, False, True, False]
    assert all(dark(s) for s in scales[::2])
    np.testing.assert_allclose(scales[1], [0.178, 0.178, scales[1][2]], atol=1e-6)  # the snare's radius
    times, scales, _ = scale_keys(gltf, flashes["flash_hihat"])
    assert times[0] == 0 and lit(scales[0])
    for sampler in gltf.animations[0].samplers:
        assert np.all(np.diff(accessor(gltf, sampler.input)[:, 0]) > 0)
    report = validate(path)
    assert (report["numErrors"], report["numWarnings"]) == (0, 0), report["messages"]


def test_a_static_kits_flash_lies_on_its_head(tmp_path: Path) -> None:
    """Without kit links (a body-only sequence) the kit is static: the flash hangs from the root, on the head's
    face (its cylinder's top, along the drum's tilted axis), just above it."""
    kit = load_kit("default")
    path = tmp_path / "static.glb"
    write_gltf(synthetic_performance(duration=0.5)[0], path, kit=kit, impacts=[(0.2, "snare")])
    gltf = load(path)
    assert gltf is not None
    names = {n.name: k for k, n in enumerate(gltf.nodes)}
    flash, drum = gltf.nodes[names["flash_snare"]], gltf.nodes[names["kit_snare"]]
    assert names["flash_snare"] in gltf.nodes[gltf.scenes[0].nodes[0]].children
    np.testing.assert_allclose(flash.rotation, drum.rotation, atol=1e-6)
    axis = Rotation.from_quat(drum.rotation).apply([0.0, 0.0, 1.0])
    lift = np.asarray(flash.translation) - np.asarray(drum.translation)
    assert 0 < lift @ axis < 0.005 and np.linalg.norm(lift - (lift @ axis) * axis) < 1e-6
    report = validate(path)
    assert (report["numErrors"], report["numWarnings"]) == (0, 0), report["messages"]
