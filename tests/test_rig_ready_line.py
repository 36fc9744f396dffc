"""What ``batteur rig`` says once its services are up without ``--score``: where to send what to play.

Review of 6c221a4 (7 Dec): with ``--host 0.0.0.0`` the line named 127.0.0.1 alone (right on this machine, but not
from another, where the performer's controller may be); and a rig without physics (``--services sound,graphics``,
physics on another machine) said "ready" with no word of where physics is. :func:`batteur.rig.up_line` builds the
line; no network is used.
"""

from __future__ import annotations

import pytest

from batteur import rig

UP = {"physics": 1.5, "sound": 1.2}
"""Role -> rig time it answered, seconds."""
SEND = "send /batteur/score/load NAME or /batteur/score/note"


def line(plans: list[rig.ServicePlan], environ: dict[str, str] | None = None) -> str:
    return rig.up_line(plans, UP, 2.25, None, environ={} if environ is None else environ)


def test_on_loopback_the_line_names_physics_address_alone() -> None:
    said = line([rig.ServicePlan("physics", 9101, ["--host", "127.0.0.1"]), rig.ServicePlan("sound", 9103, [])])
    assert said == ("batteur rig: services up 2.2 s after launch (rig time 1.5 s): ready; "
                    f"{SEND} to physics at 127.0.0.1:9101 (docs/live-control.md)\n")


@pytest.mark.parametrize(("host", "loopback"), [("0.0.0.0", "127.0.0.1:9101"), ("::", "[::1]:9101")])
def test_on_every_interface_the_line_says_so_beside_loopback(host: str, loopback: str) -> None:
    said = line([rig.ServicePlan("physics", 9101, ["--host", host]), rig.ServicePlan("sound", 9103, [])])
    assert said.endswith(f": ready; {SEND} to physics at {loopback} (from another machine, this machine's address: "
                         f"--host {host} listens on every interface; docs/live-control.md)\n"), said


def test_physics_elsewhere_is_named_where_the_services_send_to_it() -> None:
    """Physics on another machine, named by ``BATTEUR_PEERS`` (a node without ``--peer`` reads it) or a
    ``--ROLE-arg '--peer physics=...'``."""
    sound = rig.ServicePlan("sound", 9103, ["--host", "0.0.0.0"])
    said = line([sound], {"BATTEUR_PEERS": "physics=192.0.2.7:9101"})
    assert said.endswith(f": ready; physics is not started by this rig: {SEND} to it at 192.0.2.7:9101 (sound's "
                         "static peer, BATTEUR_PEERS; docs/live-control.md)\n"), said
    given = rig.ServicePlan("sound", 9103, ["--peer", "graphics=127.0.0.1:9104", "--peer", "physics=192.0.2.8:9101"])
    said = line([given], {"BATTEUR_PEERS": "physics=192.0.2.7:9101"})  # the first physics of its --peer
    assert "to it at 192.0.2.8:9101 (sound's static peer, --peer;" in said, said


def test_physics_in_batteur_peers_beside_the_rigs_peers_is_named() -> None:
    """``BATTEUR_PEERS=physics=... batteur rig --services sound,graphics``: the rig gives sound ``--peer graphics=...``,
    which replaced the variable in sound's settings until 8 Dec: sound never sent to that physics, and the line said
    "physics is not started by this rig" with no address. The rig now adds the variable's peers to its own."""
    environ = {"BATTEUR_PEERS": "physics=192.0.2.7:9101"}
    opts = rig.build_parser().parse_args(["--services", "sound,graphics"])
    plans = rig.plan_rig(opts, epoch=0.0, environ=environ)
    sound = next(plan for plan in plans if plan.role == "sound")
    assert rig.option_values(sound.args, "--peer") == ["graphics=127.0.0.1:9104", "physics=192.0.2.7:9101"]
    said = line(plans, environ)
    assert said.endswith(f": ready; physics is not started by this rig: {SEND} to it at 192.0.2.7:9101 (sound's "
                         "static peer, BATTEUR_PEERS; docs/live-control.md)\n"), said


def test_physics_nowhere_known_is_said_not_started_by_the_rig() -> None:
    said = line([rig.ServicePlan("sound", 9103, []), rig.ServicePlan("graphics", 9104, [])])
    assert said.endswith(": ready; physics is not started by this rig (batteur ls lists the nodes it finds)\n"), said
