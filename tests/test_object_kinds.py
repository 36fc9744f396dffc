"""Every kind of instrument a kit file may name (``common.kit.ObjectKind``, struck: ``common.kit.STRUCK_KINDS``) is
handled by each layer that dispatches on ``kind``: physics builds it a body, interaction takes its contacts as
impacts, the sound service has an instrument and controls for it, the video and the web view draw it. Each layer
passes over a kind it does not know: a kind added to ``ObjectKind`` and ``STRUCK_KINDS`` alone loads, is planned,
and then has no body, no impact and no sound, without a word (docs/contributing.md, "Adding a kit piece", lists the
places)."""

from __future__ import annotations

from pathlib import Path
from typing import get_args

import numpy as np
import pytest

from common.kit import STRUCK_KINDS, Kit, KitObject, ObjectKind

HARDWARE = frozenset({"pedal", "throne", "stand"})
"""The kinds that are no instruments: a footboard is pressed (by a foot, a kit's BASS and HIHATPEDAL), the throne
is sat on, a stand holds."""
KINDS = sorted(set(get_args(ObjectKind)) - HARDWARE)
WEB_VIEW = Path(__file__).resolve().parents[1] / "services" / "graphics" / "web" / "src" / "app.js"


def _one_of_each() -> Kit:
    """A kit of one object of every instrument kind, side by side (ids: the kinds)."""
    objects = [KitObject(id=kind, kind=kind, position=(0.5 * k - 1.0, 0.6, 0.9), radius=0.1,  # type: ignore[arg-type]
                         depth=0.1) for k, kind in enumerate(KINDS)]
    return Kit(name="one_of_each", objects=objects, events={})


def test_every_kind_is_an_instrument_or_hardware() -> None:
    """A new kind is either struck (an instrument: add it to STRUCK_KINDS and the layers below) or hardware
    (add it to HARDWARE here, and say in docs/score-format.md, "Kits", what it is)."""
    assert set(KINDS) == STRUCK_KINDS, (f"ObjectKind's instruments {KINDS} are not STRUCK_KINDS "
                                        f"{sorted(STRUCK_KINDS)} (common/kit.py)")
    assert HARDWARE <= set(get_args(ObjectKind))


def test_the_score_readers_and_the_planner_share_the_one_list() -> None:
    """One definition (it was two: a tuple in common/score/text.py, a frozenset in common/score/limbs.py)."""
    from common.score import limbs, text

    assert text.STRUCK_KINDS is STRUCK_KINDS and limbs.STRUCK_KINDS is STRUCK_KINDS


@pytest.mark.parametrize("kind", KINDS)
def test_interaction_takes_its_contacts_as_impacts(kind: str) -> None:
    from services.interaction.features import PLAYABLE_KINDS

    assert kind in PLAYABLE_KINDS, f"services/interaction/features.py PLAYABLE_KINDS lacks {kind!r}"


@pytest.mark.parametrize("kind", KINDS)
def test_the_sound_service_has_an_instrument_for_it(kind: str) -> None:
    from services.sound.instruments import INSTRUMENT_CLASSES, KIND_PARAMS

    assert kind in INSTRUMENT_CLASSES, f"services/sound/instruments.py INSTRUMENT_CLASSES lacks {kind!r}"
    assert INSTRUMENT_CLASSES[kind].KIND == kind
    assert kind in KIND_PARAMS, f"services/sound/instruments.py KIND_PARAMS lacks {kind!r}"


def test_physics_builds_a_body_for_each() -> None:
    from services.physics import kitbodies
    from services.physics.world import World

    world = World()
    try:
        kb = kitbodies.build_kit(world, _one_of_each())
    finally:
        world.close()
    missing = set(KINDS) - set(kb.instrument_of.values())
    assert not missing, f"services/physics/kitbodies.py build_kit makes no body for {sorted(missing)}"


def test_the_video_draws_each() -> None:
    from services.graphics.video import TinyRendererScene

    scene = TinyRendererScene([], np.zeros((0, 7)), _one_of_each())
    try:
        missing = sorted(kind for kind in KINDS if not scene.parts.get(kind))
    finally:
        scene.close()
    assert not missing, f"services/graphics/video.py TinyRendererScene._kit_object draws nothing for {missing}"


def test_the_web_view_draws_each() -> None:
    """The web view's source (built into services/graphics/static/ by ``npm run build``) has a branch for it."""
    source = WEB_VIEW.read_text(encoding="utf-8")
    missing = [kind for kind in KINDS if f'obj.kind === "{kind}"' not in source]
    assert not missing, f"{WEB_VIEW.relative_to(WEB_VIEW.parents[4])} draws nothing for {missing}"
