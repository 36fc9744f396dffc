"""``batteur rig`` and the left-handed drummer: physics' own ``--left-handed`` given through ``--physics-arg`` mirrored
the kit physics strikes while graphics drew it, interaction mapped it and sound voiced it unmirrored (until 7 Dec
accepted): refused, pointing to the rig's ``--kit left_handed``. The ``--kit`` help of render, evaluate, the rig and
graphics names the shipped kits, read from the kits folder, and where the kit format is documented."""

from __future__ import annotations

import argparse

import pytest

from batteur import evaluate, render, rig
from common.kit import KITS_DIR
from common.kit_help import KITS_DOC, shipped_kits
from common.runtime import build_parser as service_parser
from services.graphics.node import GraphicsNodeSettings


def _plans(*argv: str) -> dict[str, rig.ServicePlan]:
    opts = rig.build_parser().parse_args(["--no-discovery", *argv])
    return {plan.role: plan for plan in rig.plan_services(opts, epoch=0.0)}


@pytest.mark.parametrize("given", [["--physics-arg=--left-handed"], ["--physics-arg=--le"],
                                   ["--physics-arg", "--log-level INFO --left-handed"]])
def test_a_left_handed_physics_alone_is_refused(given: list[str]) -> None:
    with pytest.raises(rig.UsageError) as refused:
        _plans(*given)
    said = str(refused.value)
    assert said.startswith("--physics-arg: --") and "would mirror the kit physics plays" in said, said
    assert "--kit left_handed" in said, said


@pytest.mark.parametrize("value", ["1", "true", "Yes"])
def test_a_left_handed_physics_from_the_environment_is_refused(value: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """BATTEUR_LEFT_HANDED in the rig's environment reached physics alone (every service inherits it; only physics
    reads it): refused as the --physics-arg is, and by ``batteur rig`` before any service starts."""
    monkeypatch.setenv("BATTEUR_LEFT_HANDED", value)
    with pytest.raises(rig.UsageError, match=f"BATTEUR_LEFT_HANDED={value} in the rig's environment would mirror"):
        _plans()
    monkeypatch.setenv("BATTEUR_LEFT_HANDED", "0")
    assert "physics" in _plans()


def test_not_mirroring_and_the_mirrored_kit_for_every_service_are_accepted() -> None:
    plans = _plans("--physics-arg=--no-left-handed")
    assert "--no-left-handed" in plans["physics"].args
    plans = _plans("--kit", "left_handed")
    assert {role: rig.option_values(plan.args, "--kit") for role, plan in plans.items()} == {
        role: ["left_handed"] for role in plans}


def _help(parser: argparse.ArgumentParser, flag: str = "--kit") -> str:
    return " ".join(str(parser._option_string_actions[flag].help).split())


def test_the_kit_help_names_the_shipped_kits_and_the_format() -> None:
    names = sorted(path.stem for path in KITS_DIR.glob("*.yaml"))
    assert [kit.split(" ")[0] for kit in shipped_kits()] == names and "left_handed" in names
    graphics = service_parser("graphics", settings_cls=GraphicsNodeSettings)
    for parser in (render.build_parser(), evaluate.build_parser(), rig.build_parser(), graphics):
        said = _help(parser)
        assert all(name in said for name in names), said
        assert "left_handed (mirrored, for a left-handed drummer)" in said and KITS_DOC in said, said
    assert "physics --left-handed" in _help(rig.build_parser())
