"""What a Pd user runs, as docs/pd.md writes it: the sound client started on its own port or address."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.deploy.pdrun import PD_DIR, PdProcess, own_network
from tests.ports import free_port

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[2]


def test_sound_client_started_on_another_port_listens_there_first() -> None:
    """``pd -send "sc-port N" sound-client.pd`` beside a sound service on 9103 (the pyo service of
    ``batteur rig``, another client): the client listens on N, never on 9103. It used to listen on 9103
    first (its loadbang ran before the -send messages), which printed ``netreceive: listen failed: Address
    already in use`` when 9103 was taken."""
    port = free_port()
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=[f"sc-port {port}"])
    try:
        pd.wait_for(lambda lines: any(f"listen {port}" in line for line in lines))
        assert pd.printed("batteur-listen") == [["listen", str(port), "127.0.0.1"]], pd.lines
        assert pd.errors() == [], "\n".join(pd.lines)
    finally:
        pd.stop()


def test_sound_client_started_on_the_lan_does_not_listen_on_loopback_first() -> None:
    """compose's pd-sound (``-send "sc-host symbol 0.0.0.0"``): its first listen is on that address.
    127.0.0.2 stands for the LAN address."""
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=["sc-host symbol 127.0.0.2"], prefix=own_network())
    try:
        pd.wait_for(lambda lines: bool(pd.printed("batteur-listen")))
        assert pd.printed("batteur-listen")[0] == ["listen", "9103", "127.0.0.2"], pd.lines
    finally:
        pd.stop()


def test_a_refused_port_at_start_leaves_the_client_on_the_default_port() -> None:
    """A bad ``sc-port`` at start is refused (batteur-bad) and the client still listens, on 9103."""
    pd = PdProcess(PD_DIR / "sound-client.pd", sends=["sc-port 99999"], prefix=own_network())
    try:
        pd.wait_for(lambda lines: bool(pd.printed("batteur-listen")))
        assert pd.printed("batteur-listen") == [["listen", "9103", "127.0.0.1"]], pd.lines
        assert [b[:2] for b in pd.printed("batteur-bad")] == [["1", "port"]], pd.lines
    finally:
        pd.stop()


def _pd_module(name: str) -> Any:
    sys.path.insert(0, str(PD_DIR))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(PD_DIR))


def test_the_pictures_in_docs_pd_are_drawn_from_the_patches_as_they_are() -> None:
    """Each ``img/pd-NAME.png`` of docs/pd.md was drawn from ``pd/NAME.pd`` as it is now (render_patch.py keeps
    the patch's digest in the picture); ``img/pd-NAME-CANVAS.png``, the sub-patch ``[pd CANVAS]`` of
    ``pd/NAME.pd`` (``--canvas``: the panel's SOUND window). pd-control.png used to show the panel's old default
    camera (20 deg, 3.2 m) after make_control.py changed it."""
    render_patch = _pd_module("render_patch")
    pictures = re.findall(r"\]\((img/pd-[\w-]+\.png)\)", (ROOT / "docs" / "pd.md").read_text(encoding="utf-8"))
    assert len(pictures) == 4, pictures
    for picture in pictures:
        name = Path(picture).stem.removeprefix("pd-")
        patch = PD_DIR / (name + ".pd")
        if not patch.exists():  # a sub-patch's picture
            patch = PD_DIR / (name.rsplit("-", 1)[0] + ".pd")
        assert render_patch.drawn_from(ROOT / "docs" / picture) == render_patch.patch_digest(patch), (
            f"docs/{picture} is stale: run python pd/render_patch.py {patch.relative_to(ROOT)} docs/{picture}")


def test_render_patch_check_says_whether_a_picture_is_stale(tmp_path: Path) -> None:
    patch = tmp_path / "p.pd"
    patch.write_text("#N canvas 0 0 400 300 12;\n#X obj 10 10 loadbang;\n", encoding="utf-8")
    picture = tmp_path / "p.png"
    script = str(PD_DIR / "render_patch.py")
    assert subprocess.run([sys.executable, script, str(patch), str(picture)], check=False).returncode == 0
    fresh = subprocess.run([sys.executable, script, "--check", str(patch), str(picture)], capture_output=True,
                           text=True, check=False)
    assert fresh.returncode == 0 and "up to date" in fresh.stdout, fresh.stderr
    patch.write_text(patch.read_text(encoding="utf-8") + "#X obj 10 40 print x;\n", encoding="utf-8")
    stale = subprocess.run([sys.executable, script, "--check", str(patch), str(picture)], capture_output=True,
                           text=True, check=False)
    assert stale.returncode == 1 and "stale" in stale.stderr, stale.stdout + stale.stderr


def test_render_patch_draws_a_sub_patch_alone(tmp_path: Path) -> None:
    """``--canvas NAME`` draws the sub-patch ``[pd NAME]`` in its own window's size (its boxes only, not the
    main canvas's), keeping the patch file's digest; a name the patch has no sub-patch for is refused."""
    from PIL import Image

    patch = tmp_path / "p.pd"
    patch.write_text("#N canvas 0 0 300 200 12;\n#X obj 10 10 loadbang;\n#N canvas 40 40 700 500 inner 0;\n"
                     "#X obj 600 480 print inner;\n#X restore 10 40 pd inner;\n#X connect 0 0 1 0;\n",
                     encoding="utf-8")
    script = str(PD_DIR / "render_patch.py")
    main, inner = tmp_path / "main.png", tmp_path / "inner.png"
    assert subprocess.run([sys.executable, script, str(patch), str(main)], check=False).returncode == 0
    assert subprocess.run([sys.executable, script, "--canvas", "inner", str(patch), str(inner)],
                          check=False).returncode == 0
    with Image.open(main) as picture:
        assert picture.size == (300, 200)  # the main canvas: its window, its two boxes inside
    with Image.open(inner) as picture:
        assert picture.size[0] >= 700 and picture.size[1] > 500  # the sub-patch's window, and its box at 600 480
    render_patch = _pd_module("render_patch")
    assert render_patch.drawn_from(inner) == render_patch.patch_digest(patch)
    missing = subprocess.run([sys.executable, script, "--canvas", "other", str(patch), str(tmp_path / "x.png")],
                             capture_output=True, text=True, check=False)
    assert missing.returncode == 2 and "no sub-patch [pd other]" in missing.stderr, missing.stderr


VOICE_PATCH = """#N canvas 0 0 600 400 12;
#X obj 10 10 loadbang;
#X obj 10 40 t b b b;
#X msg 300 70 bang;
#X msg 100 100 5 0 3 1 \\, 5 0 3 1 \\, 6 0 3 2;
#X obj 100 130 batteur-voice snare 190 120 0.8 180 1500 1.5;
#X obj 300 160 catch~ batteur-out;
#X obj 300 200 tabwrite~ voicebuf;
#X obj 10 160 del 500;
#X obj 10 250 array max voicebuf;
#X obj 10 280 print peak;
#X msg 10 310 \\; pd quit;
#X msg 400 70 \\; pd dsp 1;
#X obj 300 250 table voicebuf 22050;
#X obj 10 190 t b b;
#X connect 0 0 1 0;
#X connect 1 2 11 0;
#X connect 1 1 2 0;
#X connect 2 0 6 0;
#X connect 1 0 3 0;
#X connect 1 0 7 0;
#X connect 3 0 4 0;
#X connect 5 0 6 0;
#X connect 7 0 13 0;
#X connect 13 1 8 0;
#X connect 8 0 9 0;
#X connect 13 0 10 0;
"""


def test_a_voice_in_a_patch_of_ones_own_plays_into_catch_batteur_out(tmp_path: Path) -> None:
    """docs/pd.md: ``[batteur-voice NAME ...]`` (pd/ on Pd's path) takes ``SECONDS FRACTION VELOCITY SEQ`` and plays
    into ``[throw~ batteur-out]``: a patch with one ``[catch~ batteur-out]`` hears the strike; the same list again
    is a copy, not played. Run with ``-batch`` (no real time); the sound goes to a table, whose peak is printed
    (a [writesf~] take is written by a thread that Pd's quit in -batch can cut short)."""
    patch = tmp_path / "mine.pd"
    patch.write_text(VOICE_PATCH, encoding="utf-8")
    pd = PdProcess(patch, extra=["-batch", "-path", str(PD_DIR)])
    try:
        pd.popen.wait(timeout=60)
        pd.wait_for(lambda lines: True, timeout=1)
    finally:
        pd.stop()
    assert pd.errors() == [], "\n".join(pd.lines)
    assert pd.printed("batteur-impact") == [["snare", "5", "0", "3"], ["snare", "6", "0", "3"]], pd.lines
    peak = pd.printed("peak")
    assert len(peak) == 1 and 0.1 < float(peak[0][0]) < 1.0, pd.lines


def test_a_client_that_cannot_listen_says_so_only_through_pds_error() -> None:
    """docs/pd.md: ``batteur-listen`` says where the client asked to listen, not that it could; on a port already
    taken Pd's ``listen failed`` error comes just before it (the client then hears nothing)."""
    import socket

    port = free_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", port))
        pd = PdProcess(PD_DIR / "sound-client.pd", sends=[f"sc-port {port}"])
        try:
            pd.wait_for(lambda lines: bool(pd.printed("batteur-listen")))
        finally:
            pd.stop()
    listen = next(k for k, line in enumerate(pd.lines) if line.startswith("batteur-listen"))
    assert listen > 0 and "listen failed: Address already in use" in pd.lines[listen - 1], pd.lines
