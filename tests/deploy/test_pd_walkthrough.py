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
    the patch's digest in the picture). pd-control.png used to show the panel's old default camera (20 deg,
    3.2 m) after make_control.py changed it."""
    render_patch = _pd_module("render_patch")
    pictures = re.findall(r"\]\((img/pd-[\w-]+\.png)\)", (ROOT / "docs" / "pd.md").read_text(encoding="utf-8"))
    assert len(pictures) == 3, pictures
    for picture in pictures:
        patch = PD_DIR / (Path(picture).stem.removeprefix("pd-") + ".pd")
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
