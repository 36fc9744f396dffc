"""The kit's load warning names the drummer the user asked for: ``batteur render --height 1.4`` warns of an
instrument beyond a 1.40 m drummer's reach, with that drummer's reach, once; the default drummer's warning reads as
before."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from batteur import render
from common.kit import load_kit, save_kit
from tests.far_kits import china_at


def _edge_kit(tmp_path: Path, distance_m: float = 1.10) -> Path:
    """A kit file: the default kit with its china ``distance_m`` from the default drummer's right shoulder
    (:func:`tests.far_kits.china_at`)."""
    path = tmp_path / "edge.yaml"
    save_kit(china_at(load_kit("default"), distance_m), path)
    return path


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING and r.name == "common.kit"]


def test_the_load_warning_names_the_drummers_height_and_reach(tmp_path: Path,
                                                              caplog: pytest.LogCaptureFixture) -> None:
    path = _edge_kit(tmp_path)
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        load_kit(path)
        assert _warnings(caplog) == []  # the default drummer reaches it
        load_kit(path, height_m=1.4)
    said = _warnings(caplog)
    assert len(said) == 1 and said[0].startswith(f"kit file {str(path)!r}: china: out of both hands' reach (")
    assert "a 1.4 m drummer's hand reaching 1.02 m" in said[0]
    far = _edge_kit(tmp_path, 1.25)  # beyond the default drummer too: its warning reads as it did
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        load_kit(far)
    assert len(_warnings(caplog)) == 1 and ", a hand reaching 1.15 m)" in _warnings(caplog)[0]


def test_a_render_of_a_small_drummer_warns_of_its_own_reach_once(tmp_path: Path,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    score = tmp_path / "snare.txt"
    score.write_text("tempo 120\nmeter 4/4\nSN |x...|\n")
    kit = _edge_kit(tmp_path)
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        assert render.main([str(score), "-o", str(tmp_path / "out"), "--quiet", "--kit", str(kit),
                            "--height", "1.4"]) == 0
    said = _warnings(caplog)  # the command line prints them on stderr (logging's last resort)
    assert len(said) == 1 and "china: out of both hands' reach" in said[0]  # was: none (1.75 m reaches it)
    assert "a 1.4 m drummer's hand reaching 1.02 m" in said[0]


def test_the_physics_node_warns_of_its_drummers_reach_once(tmp_path: Path, caplog: pytest.LogCaptureFixture,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse

    from services.physics.node import PhysicsNodeSettings, make_core

    monkeypatch.delenv("BATTEUR_CONFIG", raising=False)
    kit = _edge_kit(tmp_path)
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        core = make_core(PhysicsNodeSettings(discovery=False, kit=str(kit), height_m=1.4), argparse.Namespace())
        core.close()
    said = _warnings(caplog)  # was: twice (the node's check, the core's load), with the 1.75 m drummer's reach
    assert len(said) == 1 and "a 1.4 m drummer's hand reaching 1.02 m" in said[0]


def test_evaluate_warns_of_the_kit_once_with_the_drummer_it_rendered(tmp_path: Path,
                                                                     caplog: pytest.LogCaptureFixture) -> None:
    from batteur import evaluate

    score = tmp_path / "snare.txt"
    score.write_text("tempo 120\nmeter 4/4\nSN |x...|\n")
    kit = _edge_kit(tmp_path, 1.25)  # beyond any drummer's reach: every load of it warns
    with caplog.at_level(logging.WARNING, logger="common.kit"):
        assert evaluate.main([str(score), "--quiet", "--kit", str(kit), "--height", "1.4"]) == 0
    said = _warnings(caplog)  # was also the evaluation's own load of the kit: a second line, a 1.75 m drummer's
    assert len(said) == 1 and "a 1.4 m drummer's hand reaching 1.02 m" in said[0]
