"""``--drum-channels``, ``--drum-map`` and ``--hihat-cc4`` beyond ``batteur render``: ``batteur rig`` takes them,
reads its ``--score`` with them and gives them to physics (its ``--score`` and score library) and graphics (its
``--preview-score``), which take them as settings of the same names. Until 7 Dec those three read every MIDI file
with the reader's defaults while the reader's warnings advised the options.

Tested on the command lines the rig builds (:func:`batteur.rig.plan_services`: no service starts), a strike-scene
core's score player and the graphics node's core."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from batteur import rig
from common.exit_status import InputError
from common.runtime import build_parser
from services.graphics.node import GraphicsNodeSettings
from services.graphics.node import make_core as make_graphics
from services.physics.core import PhysicsCore, PhysicsSettings
from services.physics.node import PhysicsNodeSettings
from services.physics.node import make_core as make_physics
from tests.cli.test_drum_channels_cli import drums_and_wood_block
from tests.ports import free_ports
from tests.test_rig_inputs import no_rig, refused  # noqa: F401 - no_rig is a fixture
from tests.test_rig_options import Recorder


def _plans(*argv: str) -> dict[str, rig.ServicePlan]:
    opts = rig.build_parser().parse_args(["--no-discovery", *argv])
    return {plan.role: plan for plan in rig.plan_services(opts, epoch=0.0)}


def test_the_rig_reads_its_score_as_physics_will_and_gives_both_readers_the_options(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    opts = rig.build_parser().parse_args(["--score", str(path), "--drum-channels", "1"])
    assert {e.pitch for e in rig.check_score(opts).events} == {36, 38}  # no wood block: as physics plays it
    notes = tmp_path / "map.json"
    notes.write_text(json.dumps({"notes": {"76": 38}}))
    monkeypatch.chdir(tmp_path)  # the map by a relative name: given to the services as an absolute path
    plans = _plans("--score", str(path), "--drum-channels", "1,16", "--drum-map", "map.json", "--hihat-cc4")
    given = ["--drum-channels", "1,16", "--drum-map", str(notes.resolve()), "--hihat-cc4"]
    for role in ("physics", "graphics"):
        args = plans[role].args
        start = args.index("--drum-channels")
        assert args[start:start + 5] == given, (role, args)
    assert all("--drum-channels" not in plans[role].args for role in ("interaction", "sound"))
    assert "--drum-map" not in _plans("--score", str(path))["physics"].args  # none given: the readers' defaults
    assert rig.option_values(_plans("--drum-map", "roland-td")["graphics"].args, "--drum-map") == ["roland-td"]


def test_the_services_take_the_options_the_rig_gives_them() -> None:
    for role, settings in (("physics", PhysicsNodeSettings), ("graphics", GraphicsNodeSettings)):
        args = build_parser(role, settings_cls=settings).parse_args(
            ["--drum-channels", "1,16", "--drum-map", "roland-td", "--hihat-cc4"])
        assert (args.drum_channels, args.drum_map, args.hihat_cc4) == ("1,16", "roland-td", True), role


@pytest.mark.parametrize(("given", "written", "instead"), [
    (["--drum-channels", "1", "--physics-arg", "--drum-channels 2"], "--physics-arg: --drum-channels 2 would",
     "use batteur rig --drum-channels 2"),
    (["--drum-map", "roland-td", "--graphics-arg=--drum-m=x.json"],
     "--graphics-arg: --drum-m (--drum-map, as argparse takes it abbreviated) x.json would",
     "use batteur rig --drum-map x.json"),
    (["--hihat-cc4", "--physics-arg=--no-hihat-cc4"], "--physics-arg: --no-hihat-cc4 would turn off the hi-hat",
     "drop batteur rig --hihat-cc4"),
])
def test_a_role_arg_overriding_the_rigs_options_is_refused(given: list[str], written: str, instead: str,
                                                           no_rig: None,  # noqa: F811
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(["--no-discovery", *given], capsys, 2)
    assert err.startswith(f"batteur rig: error: {written} "), err
    assert instead in err, err


def test_without_the_rigs_own_a_services_own_stays_allowed() -> None:
    plans = _plans("--physics-arg", "--drum-channels 2 --no-hihat-cc4")
    assert plans["physics"].args[-3:] == ["--drum-channels", "2", "--no-hihat-cc4"]
    assert rig.option_values(["--no-hihat-cc4", "x"], "--no-hihat-cc4") == [""]  # a flag takes no value


def test_physics_reads_its_scores_with_its_options(tmp_path: Path) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    core = PhysicsCore(PhysicsSettings(scene="strike", mode="live"))
    try:
        player = core.score_player
        assert {e.pitch for e in player.load(path, trusted=True).events} == {36, 38, 76}
        player.midi = {"drum_channels": (1,)}  # as make_core sets it from --drum-channels 1
        assert {e.pitch for e in player.load(path, trusted=True).events} == {36, 38}
    finally:
        core.close()


@pytest.mark.parametrize(("setting", "error", "says"), [
    ({"drum_channels": "0"}, ValueError, "--drum-channels: '0': channel 0 is not a MIDI channel"),
    ({"drum_map": "missing.json"}, InputError, "--drum-map: missing.json: does not exist"),
])
def test_a_bad_option_stops_a_service_before_it_builds_anything(setting: dict[str, str], error: type[Exception],
                                                                says: str) -> None:
    with pytest.raises(error, match=says):
        make_physics(PhysicsNodeSettings(**setting), SimpleNamespace())  # type: ignore[arg-type]
    with pytest.raises(error, match=says):
        make_graphics(GraphicsNodeSettings(**setting), SimpleNamespace())  # type: ignore[arg-type]


def test_graphics_previews_the_score_as_read_with_its_options(tmp_path: Path) -> None:
    path = drums_and_wood_block(tmp_path / "take.mid")
    core = make_graphics(GraphicsNodeSettings(preview_score=str(path), drum_channels="1"),
                         SimpleNamespace())  # type: ignore[arg-type]
    assert core.preview_score is not None and {e.pitch for e in core.preview_score.events} == {36, 38}


# --------------------------------------------------------------------------- options no score is read with

def _unread(*argv: str, environ: dict[str, str] | None = None) -> str | None:
    opts = rig.build_parser().parse_args(["--no-discovery", *argv])
    return rig.unread_midi_options(opts, rig.plan_services(opts, epoch=0.0), environ or {})


def test_options_without_a_score_to_read_are_said_once_at_start(monkeypatch: pytest.MonkeyPatch,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    # until 7 Dec given to physics and graphics in silence: a user expected them to act (on live notes, say)
    monkeypatch.setattr(rig, "Rig", Recorder)
    assert rig.main(["--no-discovery", "--drum-channels", "1", "--hihat-cc4", "--drum-map", "roland-td",
                     "--base-port", str(free_ports(4)[0])]) == 0
    err = capsys.readouterr().err
    assert err.count("warning:") == 1, err
    # not --drum-map: live notes follow it (since c6f810b; until 7 Dec it was named here too)
    assert "batteur rig: warning: --drum-channels 1, --hihat-cc4 act on no score: they say how MIDI " \
           "files are read, and this rig reads none" in err
    assert "--physics-arg '--score-dir DIR'" in err and "/batteur/score/note" in err
    assert "--drum-channels" in Recorder.started[0].args  # still given: a config file may give a library


@pytest.mark.parametrize(("argv", "environ"), [
    (["--hihat-cc4", "--services", "sound,interaction"], {}),  # no reader at all
    (["--drum-channels", "1", "--graphics-arg", "--preview out.npz"], {}),  # a pose sequence, not a score
    # blank values give no library, preview or config (until 7 Dec they silenced the warning)
    (["--drum-channels", "1", "--physics-arg=--score-dir="], {}),
    (["--drum-channels", "1", "--physics-arg", "--score-dir ' , '"], {}),
    (["--drum-channels", "1", "--graphics-arg=--preview-score="], {}),
    (["--drum-channels", "1", "--physics-arg=--config="], {}),
    (["--drum-channels", "1"], {"BATTEUR_SCORE_DIR": " , ", "BATTEUR_CONFIG": " "}),
])
def test_options_are_said_unused_wherever_no_score_is_read(argv: list[str], environ: dict[str, str]) -> None:
    said = _unread(*argv, environ=environ)
    assert said is not None and said.startswith(f"{argv[0]} {'acts' if argv[0] == '--hihat-cc4' else '1 acts'}")
    # one option: "it says" (until 7 Dec "they say" for one as for several)
    assert "acts on no score: it says how MIDI files are read" in said
    assert "live notes (/batteur/score/note) are read without it" in said


def test_drum_map_acts_on_live_notes_and_is_never_said_unused(tmp_path: Path) -> None:
    """Since c6f810b physics reads live notes (/batteur/score/note) with --drum-map: a rig with no MIDI score said it
    acted on nothing and that live notes were read as General MIDI pitches without it, until 7 Dec."""
    text = tmp_path / "groove.txt"
    text.write_text("tempo 120\nmeter 4/4\nSN |....x.......x...|\n", encoding="utf-8")
    assert _unread("--drum-map", "roland-td") is None
    assert _unread("--score", str(text), "--drum-map", "roland-td") is None
    said = _unread("--drum-map", "roland-td", "--hihat-cc4")
    assert said is not None and said.startswith("--hihat-cc4 acts on no score") and "--drum-map" not in said
    group = " ".join(rig.build_parser().format_help().split())
    assert "--drum-map also maps live notes' pitches (/batteur/score/note, General MIDI without it)" in group
    assert "live notes (/batteur/score/note) are read as General MIDI pitches without them" not in group


def test_the_rigs_kit_reaches_a_text_scores_kit_object_ids(tmp_path: Path) -> None:
    """A text score names kit objects by id (c6f810b): ``batteur rig --kit double_pedal --score`` of a score without
    a ``kit`` line looked ``crash2`` up in the default kit, and refused it, until 7 Dec."""
    score = tmp_path / "second_crash.txt"
    score.write_text("tempo 100\nSN |x...|\ncrash2 |..x.|\n", encoding="utf-8")
    opts = rig.build_parser().parse_args(["--score", str(score), "--kit", "double_pedal"])
    read = rig.check_score(opts)
    assert read is not None and len(read.events) == 2
    with pytest.raises(ValueError, match="crash2"):  # the default kit has no second crash
        rig.check_score(rig.build_parser().parse_args(["--score", str(score)]))
    with pytest.raises(ValueError, match="^--kit nosuchkit: "):
        rig.check_score(rig.build_parser().parse_args(["--score", str(score), "--kit", "nosuchkit"]))


def test_options_beside_a_text_score_are_said_to_act_only_on_midi_files(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    # a text score is read without them: until 7 Dec nothing was said, as for a MIDI --score
    text = tmp_path / "groove.txt"
    text.write_text("tempo 120\nmeter 4/4\nSN |....x.......x...|\n", encoding="utf-8")
    said = _unread("--score", str(text), "--drum-channels", "1", "--hihat-cc4")
    assert said is not None
    assert said.startswith(f"--drum-channels 1, --hihat-cc4 act only on MIDI files, and --score {text} is a text "
                           "score, read without them: of this rig's scores only MIDI files /batteur/score/load may "
                           "load from its folder would be read with them")
    assert _unread("--score", str(text), "--drum-channels", "1", "--physics-arg", "--score-dir /tmp/s") is None
    named = tmp_path / "take.txt"  # a MIDI file by a text name is read as MIDI: nothing to say
    named.write_bytes(drums_and_wood_block(tmp_path / "take.mid").read_bytes())
    assert _unread("--score", str(named), "--drum-channels", "1") is None
    monkeypatch.setattr(rig, "Rig", Recorder)
    monkeypatch.chdir(tmp_path)  # no file named demo here: the demo groove, a text score
    capsys.readouterr()
    assert rig.main(["--no-discovery", "--score", "demo", "--hihat-cc4", "--base-port", str(free_ports(4)[0])]) == 0
    err = capsys.readouterr().err
    assert err.count("warning:") == 1 and "--hihat-cc4 acts only on MIDI files" in err, err


@pytest.mark.parametrize(("argv", "environ"), [
    ([], {}),  # none given
    (["--score", "SCORE"], {}),
    (["--physics-arg", "--score-dir /tmp/scores"], {}),  # /batteur/score/load reads with them
    (["--physics-arg=--score-d=/tmp/scores"], {}),  # as physics' parser takes it abbreviated
    (["--graphics-arg", "--preview-score take.mid"], {}),
    (["--physics-arg", "--config rig.yaml"], {}),  # a config file may give either: the services read it
    ([], {"BATTEUR_SCORE_DIR": "/tmp/scores"}),
    ([], {"BATTEUR_PREVIEW_SCORE": "take.mid"}),
    ([], {"BATTEUR_CONFIG": "rig.yaml"}),
])
def test_options_a_score_is_read_with_are_not_said_unused(argv: list[str], environ: dict[str, str],
                                                          tmp_path: Path) -> None:
    take = drums_and_wood_block(tmp_path / "take.mid")
    given = [] if not argv and not environ else ["--drum-channels", "1"]
    argv = [str(take) if arg == "SCORE" else arg for arg in argv]
    assert _unread(*given, *argv, environ=environ) is None
    if given:  # the same rig without what reads a score says so
        assert _unread(*given) is not None
