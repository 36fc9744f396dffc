"""A render keeps the kit file it played and every warning it said at its start.

* ``batteur evaluate DIR`` could not find a kit file given by a relative path (report.json kept it as typed,
  relative to where the render ran), and read the file as it is now, edited since: the render copies the kit file
  into DIR as ``played-kit.yaml`` (``kit.yaml`` until 7 Dec replaced a song folder's own kit file), report.json
  says the copy (``kit_copy``) and the file's absolute path (``kit_file``), and evaluate judges on the copy,
  saying so when the file has changed since.
* The kit's load warnings (an instrument out of reach) were printed and not kept: report.json's ``warnings`` has
  them, and the warning for hands in a grip the gestures are not planned with (american, traditional), which the
  rig's physics node logged and a render did not say at all.
"""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import pytest

from batteur import evaluate, render
from common.kit import load_kit, save_kit
from tests.far_kits import china_at

SCORE = "tempo 120\nmeter 4/4\nSN |x.x.|\n"
MINE = "# my own kit, edited by hand\n"


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A render of two snares on the default kit with its china out of reach (kits/far.yaml given relative to the
    folder the render runs in), the hands in the traditional grip."""
    folder = tmp_path_factory.mktemp("kitcopy")
    (folder / "kits").mkdir()
    save_kit(china_at(load_kit("default", warn=False), 1.3), folder / "kits" / "far.yaml")
    (folder / "snare.txt").write_text(SCORE)
    (folder / "out").mkdir()
    (folder / "out" / "kit.yaml").write_text(MINE)  # the folder's own kit, hand-edited, no render's
    here = Path.cwd()
    os.chdir(folder)  # --kit given relative to it
    try:
        assert render.main(["snare.txt", "-o", "out", "--quiet", "--kit", "kits/far.yaml",
                            "--grip", "traditional"]) == 0
    finally:
        os.chdir(here)
    return folder / "out"


def test_the_kit_file_is_copied_and_its_absolute_path_kept(rendered: Path) -> None:
    report = json.loads((rendered / "report.json").read_text())
    kit = rendered.parent / "kits" / "far.yaml"
    assert report["kit"] == "kits/far.yaml"  # as given, as before
    assert report["kit_file"] == str(kit.resolve()) and report["kit_copy"] == "played-kit.yaml"
    assert (rendered / "played-kit.yaml").read_bytes() == kit.read_bytes()


def test_a_file_no_render_wrote_is_never_replaced(rendered: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Until 7 Dec the copy was ``kit.yaml``: a render into a song folder replaced the folder's own kit file; and a
    score copy replaced a ``score.txt`` of the user's: refused now, before the render, the file left as it was."""
    assert (rendered / "kit.yaml").read_text() == MINE
    folder = rendered.parent / "song"
    folder.mkdir()
    (folder / "score.txt").write_text("tempo 90\nSN |x...|\n")  # the user's own, another score
    capsys.readouterr()
    assert render.main([str(rendered.parent / "snare.txt"), "-o", str(folder), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert f"{folder / 'score.txt'} is not a file an earlier render wrote there" in err, err
    assert (folder / "score.txt").read_text() == "tempo 90\nSN |x...|\n" and not (folder / "report.json").exists()
    (folder / "report.json").write_text(json.dumps({"scene": "drummer", "score": "x/score.txt"}))
    render.check_copies(folder, rendered.parent / "snare.txt", None)  # an earlier render's copy: replaced
    (folder / "report.json").unlink()
    (folder / "score.txt").write_text(SCORE)
    render.check_copies(folder, rendered.parent / "snare.txt", None)  # the same score: nothing lost


def test_the_start_warnings_are_in_the_report(rendered: Path) -> None:
    warnings = json.loads((rendered / "report.json").read_text())["warnings"]
    assert any(w.startswith("kit file 'kits/far.yaml': china: out of both hands' reach") for w in warnings), warnings
    assert ("the drummer's hands hold the traditional grip; the gestures are planned with the german grip (the "
            "gesture database has french and german units only)") in warnings, warnings


def test_evaluate_finds_the_kit_from_elsewhere_and_judges_on_the_copy(
        rendered: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)  # kits/far.yaml is not here: until 7 Dec "no kit file 'kits/far.yaml'"
    result = evaluate.evaluate_render_dir(rendered / "score.txt", rendered)
    assert result.notes == 2 and capsys.readouterr().err == ""
    kit = rendered.parent / "kits" / "far.yaml"
    original = kit.read_text()
    try:  # the snare's notes moved to the high tom since: judged on the file, both would be missed
        kit.write_text(original.replace("SNARE:\n    object: snare", "SNARE:\n    object: hightom"))
        assert load_kit(kit, warn=False).events["SNARE"].object == "hightom"
        again = evaluate.evaluate_render_dir(rendered / "score.txt", rendered)
        assert again.summary()["f_measure"] == result.summary()["f_measure"]
        assert again.missed_by_reason == result.missed_by_reason
        err = capsys.readouterr().err
        assert f"{kit.resolve()} has changed since {rendered} was rendered; judged on the kit it played" in err, err
    finally:
        kit.write_text(original)


def test_a_render_without_the_kit_kept_says_where_the_path_is_from(
        rendered: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    old = tmp_path / "old"
    old.mkdir()
    for name in ("score.txt", "impacts.csv"):
        (old / name).write_bytes((rendered / name).read_bytes())
    report = json.loads((rendered / "report.json").read_text())
    del report["kit_file"], report["kit_copy"]  # as a render before 7 Dec wrote it
    (old / "report.json").write_text(json.dumps(report))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileNotFoundError, match="relative to where the render ran; run batteur evaluate from there"):
        evaluate.evaluate_render_dir(old / "score.txt", old)
    monkeypatch.chdir(rendered.parent)  # from there, as before
    assert evaluate.evaluate_render_dir(old / "score.txt", old).notes == 2


def test_a_later_render_removes_the_copy_never_the_kit_itself(tmp_path: Path) -> None:
    (tmp_path / "played-kit.yaml").write_text("x")
    (tmp_path / "report.json").write_text(json.dumps({"scene": "drummer", "kit_copy": "played-kit.yaml",
                                                      "kit_file": str(tmp_path / "elsewhere.yaml")}))
    assert "played-kit.yaml" in render.earlier_outputs(tmp_path)  # a copy: another render's kit
    (tmp_path / "report.json").write_text(json.dumps({"scene": "drummer", "kit_copy": "played-kit.yaml",
                                                      "kit_file": str(tmp_path / "played-kit.yaml")}))
    assert "played-kit.yaml" not in render.earlier_outputs(tmp_path)  # the kit rendered beside its own file


def test_a_later_render_leaves_a_7_dec_renders_kit_yaml_in_place(tmp_path: Path) -> None:
    """A render of 7 Dec copied the kit file it played into DIR as ``kit.yaml`` (report.json's ``kit_copy``); the
    user may have edited it since, or put their own kit there: a later render removed it. What that render wrote
    is not known (no digest of it is kept), so a ``kit.yaml`` is never removed; its other files are."""
    save_kit(load_kit("default", warn=False), tmp_path / "kit.yaml")  # as the render copied a kit file
    edited = (tmp_path / "kit.yaml").read_text() + "# user edit\n"
    (tmp_path / "kit.yaml").write_text(edited)
    (tmp_path / "score.txt").write_text(SCORE)
    report = {"scene": "drummer", "score": "snare.txt", "kit_copy": "kit.yaml", "kit_file": "/elsewhere/a.yaml"}
    (tmp_path / "report.json").write_text(json.dumps(report))
    with render.Staging(tmp_path) as staging:  # a render of a MIDI file on another kit file
        for name in ("performance.wav", "impacts.csv", "performance.bvh", "score.mid", "played-kit.yaml",
                     "report.json"):
            (staging.path / name).write_text("new")
        staging.commit()
    assert (tmp_path / "kit.yaml").read_text() == edited
    assert not (tmp_path / "score.txt").exists()  # the earlier render's score copy: removed, as before
    (tmp_path / "report.json").write_text(json.dumps({**report, "kit_copy": "kit.json", "kit_file": "/x/a.json"}))
    assert "kit.json" not in render.earlier_outputs(tmp_path)  # the old name with any suffix


def test_reuse_needs_the_kit_file_as_it_was(rendered: Path) -> None:
    report = json.loads((rendered / "report.json").read_text())
    kit = rendered.parent / "kits" / "far.yaml"
    assert evaluate.same_kit_file(rendered, report, str(kit))
    original = kit.read_text()
    try:
        kit.write_text(original + "\n# moved the ride\n")
        assert not evaluate.same_kit_file(rendered, report, str(kit))
    finally:
        kit.write_text(original)
    assert not evaluate.same_kit_file(rendered, report, str(rendered / "kit.yaml"))  # another file
    assert evaluate.same_kit_file(rendered, report, "default")


def test_kept_warnings_are_still_shown_once(capsys: pytest.CaptureFixture[str],
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(logging.root, "handlers", [])  # as on the command line: logging's last resort showed them
    kept: list[str] = []
    logger = logging.getLogger("common.kit")
    with render.kept_warnings(kept):
        logger.warning("kit file %r: out of reach", "x.yaml")
        logger.info("not a warning")
    assert kept == ["kit file 'x.yaml': out of reach"]
    assert capsys.readouterr().err == "kit file 'x.yaml': out of reach\n"
    logger.warning("after")  # the handler is gone: logging's own again
    assert kept == ["kit file 'x.yaml': out of reach"]


def test_the_grip_warning_is_for_hands_the_gestures_are_not_planned_with() -> None:
    assert render.grip_warning("german") is None and render.grip_warning("french") is None
    assert render.grip_warning(None) is None  # the default grip, german
    said = render.grip_warning("american")
    assert said is not None and said.startswith("the drummer's hands hold the american grip; the gestures are "
                                                 "planned with the german grip")


def test_a_fit_from_the_render_finds_its_kit_file_from_elsewhere(
        rendered: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # until 7 Dec "kits/far.yaml", which --fit-calibration then could not load here
    name = evaluate.fit_kit_name([rendered], None)
    assert name == str(rendered / "played-kit.yaml")  # the kit it played: the file may be edited since
    assert load_kit(name, warn=False).events
    # the render and a score playing the same file are one kit (the copy's file is not another kit)
    (tmp_path / "s.txt").write_text(f"kit {(rendered.parent / 'kits' / 'far.yaml').resolve()}\n{SCORE}")
    assert evaluate.fit_kit_name([rendered, tmp_path / "s.txt"], None) == name


def test_reuse_takes_the_kit_file_however_typed(rendered: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--reuse`` compared report.json's ``kit`` as typed: ``./kits/far.yaml`` rendered again what
    ``kits/far.yaml`` had rendered; the file is compared now (``kit_file``)."""
    monkeypatch.chdir(rendered.parent)
    score = rendered.parent / "snare.txt"
    assert evaluate.reusable(rendered, score, render.RenderOptions(kit="./kits/far.yaml", grip="traditional"))
    assert not evaluate.reusable(rendered, score, render.RenderOptions(kit="default", grip="traditional"))
    report = json.loads((rendered / "report.json").read_text())
    assert evaluate.same_kit(report, "kits/../kits/far.yaml") and not evaluate.same_kit(report, "kits/other.yaml")
