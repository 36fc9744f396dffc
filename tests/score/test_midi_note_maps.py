"""MIDI files not laid out as General MIDI: a note map (``--drum-map``, a JSON or TOML file or the shipped
``roland-td``) gives their notes the drums they mean; the reader names General MIDI percussion it plays on a kit
piece standing in for it, and its warnings give note names, stay short and name the file."""

from __future__ import annotations

import io
import re
from pathlib import Path

import mido
import pytest

from common.kit import EventType as E
from common.score.gm import DRUM_MAP, midi_note_name, pitch_label
from common.score.midi import read_midi
from common.score.midi_notes import ROLAND_TD, DrumMapError, load_drum_map
from common.score.midi_options import add_midi_arguments, midi_read_kwargs


def drum_file(path: Path, pitches: list[int], channel: int = 9) -> Path:
    """A type 0 file at ``path``: each of ``pitches`` a quarter note after the one before, on ``channel``."""
    track = mido.MidiTrack()
    for k, pitch in enumerate(pitches):
        track.append(mido.Message("note_on", note=pitch, velocity=100, channel=channel, time=480 if k else 0))
        track.append(mido.Message("note_off", note=pitch, velocity=0, channel=channel, time=0))
    mid = mido.MidiFile(type=0, ticks_per_beat=480)
    mid.tracks.append(track)
    buf = io.BytesIO()
    mid.save(file=buf)
    path.write_bytes(buf.getvalue())
    return path


def played(path: Path, **kwargs: object) -> list[tuple[E, int | None]]:
    return [(e.event, e.pitch) for e in read_midi(path, **kwargs).events]  # type: ignore[arg-type]


# -- note map files -----------------------------------------------------------------------------------------------


def test_a_json_map_rescues_notes_the_reader_did_not_know(tmp_path: Path) -> None:
    """EZdrummer-style hats (25 half-open, 60 open, 3 pedal): unknown or a bongo without the map."""
    mid = drum_file(tmp_path / "ezd.mid", [25, 60, 3, 36])
    plain = read_midi(mid)
    assert [n.pitch for n in plain.unknown] == [25, 3]
    (tmp_path / "ezd.json").write_text('{"description": "EZD hats", "notes": {"25": 46, "60": "HIHATOPEN", '
                                       '"3": "hihatpedal"}}')
    assert played(mid, note_map=load_drum_map(str(tmp_path / "ezd.json"))) == [
        (E.HIHATOPEN, 46), (E.HIHATOPEN, 46), (E.HIHATPEDAL, 44), (E.BASS, 36)]


def test_a_toml_map_reads_as_a_json_one(tmp_path: Path) -> None:
    (tmp_path / "m.toml").write_text('description = "x"\n[notes]\n25 = 42\n61 = "RIDE"\n')
    assert load_drum_map(str(tmp_path / "m.toml")) == {25: 42, 61: 51}


def test_an_event_name_plays_the_kits_first_piece_not_a_second_one(tmp_path: Path) -> None:
    """A name stands for its type's first GM pitch (RIDE 51, CRASH 49): the double pedal kit's ride2 (59) and
    crash2 (57) are chosen by their pitches, never by a name."""
    (tmp_path / "m.json").write_text('{"notes": {"59": "RIDE", "57": "crash", "41": "FLOORTOM"}}')
    assert load_drum_map(str(tmp_path / "m.json")) == {59: 51, 57: 49, 41: 43}


@pytest.mark.parametrize(("text", "words"), [
    ('{"notes": {"200": 36}}', "notes: entry 200: '200' is not a MIDI pitch (0 to 127)"),
    ('{"notes": {"x": 36}}', "entry x: 'x' is not a MIDI pitch"),
    ('{"notes": {"25": 90}}', "entry 25: 90 is not a drum pitch Batteur plays"),
    ('{"notes": {"25": "tambourine"}}', "entry 25: 'tambourine' is neither a General MIDI drum pitch"),
    ('{"notes": {"25": true}}', "entry 25: True is neither"),
    ('{"notes": {"25": 42, "26": 7}}', "entry 26: 7 is not"),
    ('{"notes": {}}', "notes: the map has no notes"),  # was pydantic's "Dictionary should have at least 1 item"
    ('{"notes": {"25": 42}, "note": 1}', "note: "),
    ('{"25": 42}', "notes: "),
    ('[1, 2]', 'an object with a "notes" table'),
    ('{"notes": ', "not valid JSON"),
])
def test_a_bad_map_is_refused_naming_the_file_and_the_entry(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(DrumMapError) as caught:
        load_drum_map(str(path))
    assert str(caught.value).startswith(f"{path}: ") and words in str(caught.value), caught.value


def test_every_bad_entry_is_named_at_once(tmp_path: Path) -> None:
    (tmp_path / "bad.toml").write_text("[notes]\n25 = 42\n200 = 36\n61 = 'bongo'\n")
    with pytest.raises(DrumMapError, match="entry 200: .*; entry 61: 'bongo'"):
        load_drum_map(str(tmp_path / "bad.toml"))


def test_a_missing_map_or_a_wrong_name_says_what_is_wanted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(DrumMapError, match=r"roland: does not exist \(did you mean roland-td\?\); .*shipped map's "
                       r"name \(roland-td\)"):
        load_drum_map("roland")
    assert load_drum_map("ROLAND-TD") == load_drum_map("Roland-TD ") == ROLAND_TD  # until 7 Dec "does not exist"
    with pytest.raises(DrumMapError, match=r"^gm\.json: does not exist; give"):  # nothing near: no suggestion
        load_drum_map("gm.json")
    (tmp_path / "map.txt").write_text("25 42")
    with pytest.raises(DrumMapError, match="a note map is a .json or .toml file"):
        load_drum_map(str(tmp_path / "map.txt"))


# -- Roland's TD-series layout -------------------------------------------------------------------------------------


def test_roland_td_plays_rims_and_edges_on_their_pads(tmp_path: Path) -> None:
    """Tom 3's rim (58), the crash edges (55, 52) and the ride's edge (59): General MIDI's vibraslap (china),
    splash, china and second ride without the map; the pad's head or bow with it."""
    mid = drum_file(tmp_path / "td.mid", [58, 55, 52, 59, 22, 26])
    assert played(mid) == [(E.CHINA, 58), (E.SPLASH, 55), (E.CHINA, 52), (E.RIDE, 59), (E.HIHATCLOSED, 22),
                           (E.HIHATOPEN, 26)]
    assert played(mid, note_map=load_drum_map("roland-td")) == [
        (E.FLOORTOM, 43), (E.CRASH, 49), (E.CRASH, 57), (E.RIDE, 51), (E.HIHATCLOSED, 22), (E.HIHATOPEN, 26)]


def test_roland_td_agrees_with_the_td11_pitches_the_default_map_knows() -> None:
    """docs/score-format.md: the TD-11 adds 22 (closed edge) and 26 (open edge) to General MIDI; every pad of the
    layout plays its own kind of drum."""
    kinds = {pitch: DRUM_MAP[gm] for pitch, gm in ROLAND_TD.items()}
    assert kinds[22] == DRUM_MAP[22] == E.HIHATCLOSED and kinds[26] == DRUM_MAP[26] == E.HIHATOPEN
    assert {p for p, k in kinds.items() if k is E.CRASH} == {49, 55, 57, 52}
    assert {p for p, k in kinds.items() if k is E.RIDE} == {51, 59}
    assert kinds[58] == kinds[43] == E.FLOORTOM and kinds[50] == kinds[48] == E.HIGHTOM
    assert kinds[47] == kinds[45] == E.MIDTOM and kinds[40] == kinds[38] == E.SNARE and kinds[37] == E.RIM


# -- warnings ------------------------------------------------------------------------------------------------------


def test_unknown_notes_have_note_names_the_file_and_the_remedy(tmp_path: Path) -> None:
    mid = drum_file(tmp_path / "u.mid", [25, 25, 3, 36])
    [warning] = read_midi(mid).warnings
    assert warning.startswith(f"{mid}: 3 notes have no drum event type and are not played: "
                              "pitch 25 (C#0) x2, pitch 3 (D#-2) x1 (note names with middle C = C3)")
    assert "--drum-map" in warning and "roland-td" in warning


def test_a_long_list_of_unknown_pitches_is_cut_short(tmp_path: Path) -> None:
    """A keyboard-mapped sample kit: 68 unknown pitches listed 8, the most played first."""
    pitches = [36, 0, 0, 0, *range(1, 22), *range(82, 128)]
    [warning] = read_midi(drum_file(tmp_path / "keys.mid", pitches)).warnings
    listed = re.findall(r"pitch (\d+) \(", warning)
    assert listed[0] == "0" and len(listed) == 8 and "pitch 0 (C-2) x3" in warning
    assert ", ... and 60 more pitches (note names" in warning


def test_stand_ins_for_percussion_a_kit_does_not_have_are_named_once_a_pitch(tmp_path: Path) -> None:
    mid = drum_file(tmp_path / "latin.mid", [60, 60, 54, 58, 36, 52, 55, 42])
    [warning] = read_midi(mid).warnings
    assert warning.startswith(f"{mid}: General MIDI percussion a drum kit does not have is played on the kit piece")
    assert ("pitch 60 (Hi Bongo, C3) played as high tom x2, pitch 54 (Tambourine, F#2) played as open hi-hat x1, "
            "pitch 58 (Vibraslap, A#2) played as china x1;") in warning
    assert "--drum-map" in warning
    assert "pitch 52" not in warning and "pitch 55" not in warning  # the china and the splash are kit pieces


def test_no_stand_in_notice_for_a_mapped_pitch_or_a_kit_file(tmp_path: Path) -> None:
    mid = drum_file(tmp_path / "m.mid", [60, 58, 36, 38, 42, 46, 49, 51, 52, 55])
    assert not read_midi(mid, note_map={60: 46, 58: 43}).warnings


def test_warnings_name_their_file_among_several(tmp_path: Path) -> None:
    """``batteur evaluate a.mid b.mid``: each file's warnings say which file they are about."""
    a, b = drum_file(tmp_path / "a.mid", [25]), drum_file(tmp_path / "b.mid", [61])
    assert read_midi(a).warnings[0].startswith(f"{a}: 1 note has no drum event type and is not played: pitch 25")
    assert read_midi(b).warnings[0].startswith(f"{b}: General MIDI percussion")


def test_note_names_count_middle_c_as_c3() -> None:
    assert [midi_note_name(p) for p in (0, 25, 59, 60, 127)] == ["C-2", "C#0", "B2", "C3", "G8"]
    assert pitch_label(3) == "pitch 3 (D#-2)" and pitch_label(26) == "pitch 26 (Hi-Hat Edge Open (TD-11), D0)"


# -- the command lines ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("module", ["batteur.render", "batteur.evaluate", "batteur.compare"])
def test_the_batteur_command_lines_take_a_drum_map(module: str, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    build_parser = __import__(module, fromlist=["build_parser"]).build_parser
    argv = {"batteur.render": ["s.mid", "-o", str(tmp_path / "out")], "batteur.evaluate": ["s.mid"],
            "batteur.compare": ["s.mid", "t.mid"]}
    args = build_parser().parse_args([*argv[module], "--drum-map", "roland-td"])
    assert midi_read_kwargs(args)["note_map"] == ROLAND_TD
    (tmp_path / "bad.json").write_text('{"notes": {"25": 99}}')
    with pytest.raises(SystemExit) as caught:
        build_parser().parse_args([*argv[module], "--drum-map", str(tmp_path / "bad.json")])
    assert caught.value.code == 2
    assert "entry 25: 99 is not a drum pitch" in capsys.readouterr().err


def test_score_inspection_reads_with_the_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from common.score.__main__ import main

    mid = drum_file(tmp_path / "td.mid", [58, 55])
    assert main([str(mid), "--drum-map", "roland-td"]) == 0
    out = capsys.readouterr().out
    assert "CRASH        1" in out and "FLOORTOM     1" in out and "warning" not in out
    assert main([str(mid)]) == 0
    assert "CHINA        1" in capsys.readouterr().out


def test_no_map_given_leaves_the_reader_its_default() -> None:
    import argparse

    parser = argparse.ArgumentParser()
    add_midi_arguments(parser)
    assert "note_map" not in midi_read_kwargs(parser.parse_args([]))


def test_a_render_directorys_score_is_judged_with_its_map(tmp_path: Path) -> None:
    """report.json holds the map a render read its score with (``drum_map``); ``batteur evaluate`` of the
    directory reads the score with it, and refuses one that is not a map."""
    from batteur.evaluate import report_midi_kwargs
    from common.score.midi_notes import note_map_json

    held = note_map_json(ROLAND_TD)
    assert held is not None and held["58"] == 43
    where = tmp_path / "report.json"
    assert report_midi_kwargs({"drum_map": held}, where) == {"note_map": ROLAND_TD}
    assert report_midi_kwargs({"drum_map": held, "drum_channels": [1]}, where) == {
        "note_map": ROLAND_TD, "drum_channels": (1,)}
    assert report_midi_kwargs({"drum_map": None}, where) == {}
    with pytest.raises(ValueError, match=r"report.json: drum_map is not a note map \(entry 58: 7 is not"):
        report_midi_kwargs({"drum_map": {"58": 7}}, where)


def test_reuse_takes_no_render_read_with_another_map(tmp_path: Path) -> None:
    """``batteur evaluate --reuse --drum-map roland-td``: a render read as General MIDI plays other drums."""
    from batteur import evaluate, render
    from common.score.midi_notes import note_map_json
    from tests.render.test_render_inputs import TINY, _fake_render

    score = tmp_path / "tiny.txt"
    score.write_text(TINY)
    mapped = render.RenderOptions(midi={"note_map": ROLAND_TD})
    assert not evaluate.reusable(_fake_render(tmp_path / "gm"), score, mapped)
    assert evaluate.reusable(_fake_render(tmp_path / "td", drum_map=note_map_json(ROLAND_TD)), score, mapped)
    assert evaluate.reusable(tmp_path / "gm", score, render.RenderOptions())
    assert not evaluate.reusable(tmp_path / "td", score, render.RenderOptions())


def test_a_render_of_unknown_notes_only_says_why_naming_the_file_once(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from batteur import render

    mid = drum_file(tmp_path / "keys.mid", [25, 25])
    assert render.main([str(mid), "-o", str(tmp_path / "out"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.count(str(mid)) == 1 and "no drum events to play (2 notes have no drum event type" in err
    assert "pitch 25 (C#0) x2" in err and "--drum-map" in err


def test_compare_reads_an_e_kit_take_with_its_own_map(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A General MIDI exercise and a Roland take: ``--take-drum-map roland-td`` maps the take alone (the crash's
    edge, 55, and tom 3's rim, 58, were a splash and a china played instead of the crash and the floor tom)."""
    from batteur import compare

    exercise = drum_file(tmp_path / "ex.mid", [36, 49, 43, 38, 36, 38])
    take = drum_file(tmp_path / "take.mid", [36, 55, 58, 38, 36, 38])
    assert compare.main([str(exercise), str(take)]) == 0
    assert "4 of 6 written notes played, 2 played on another drum" in capsys.readouterr().out
    assert compare.main([str(exercise), str(take), "--take-drum-map", "roland-td"]) == 0
    captured = capsys.readouterr()
    assert "6 of 6 written notes played, 0 missed" in captured.out and "warning" not in captured.err
