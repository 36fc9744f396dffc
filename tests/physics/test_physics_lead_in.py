"""A performance starts clean: the hands' moves from the rest posture to the first notes touch nothing."""

from __future__ import annotations

from pathlib import Path

from batteur.render import RenderOptions, prepare
from common.kit import Limb, load_kit
from common.messages import Contact
from services.physics.core import PhysicsCore

# a flam on the snare: the right hand's first note is on the snare, its rest is over the hi-hat
FLAM = """tempo 300
meter 4/4
SN |XX..............|
"""


def test_the_right_hand_goes_from_the_hihat_to_the_snare_without_touching_the_hihat(tmp_path: Path) -> None:
    score = tmp_path / "flam.txt"
    score.write_text(FLAM)
    kit = load_kit()
    opts = RenderOptions()
    _, _, plan = prepare(score, kit, opts)
    assert [s.limb for s in plan.strokes] == [Limb.LEFT_HAND, Limb.RIGHT_HAND]
    core = PhysicsCore(scene="drummer", kit=kit)
    core.load_plan(plan, opts.settle_s)
    offset = opts.settle_s - plan.start_time
    end = plan.strokes[-1].time + offset + 0.1
    contacts = [o.message for k in range(1, round(end * 1000)) for o in core.step(k / 1000)
                if isinstance(o.message, Contact)]
    core.close()
    assert not [c for c in contacts if c.instrument == "hihat" and c.part.endswith("stick_tip")]
    right = [c.time for c in contacts if c.instrument == "snare" and c.part.startswith("right_stick")]
    assert right and abs(right[0] - (plan.strokes[1].time + offset)) < 0.01

