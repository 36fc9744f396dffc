"""An independent mDNS implementation sees every node: avahi inside a test namespace.

dbus-daemon and avahi-daemon run inside the namespace, in a private mount namespace (their
/run is a tmpfs of their own), on the namespace's veth only. The rig's four services run in the
same namespace with discovery on that veth; ``avahi-browse`` must list and resolve each node's
``_osc._udp`` record (TXT: role, proto, node_id, port) and its OSCQuery ``_oscjson._tcp`` record,
whose port serves the namespace.
"""

from __future__ import annotations

import shutil
import sys
import time
from pathlib import Path

import pytest

from tests.deploy.twohosts import wait_line
from tests.netns import NetnsLab, netns_lab  # noqa: F401  (fixture)

DBUS_CONF = """<!DOCTYPE busconfig PUBLIC "-//freedesktop//DTD D-BUS Bus Configuration 1.0//EN"
 "http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd">
<busconfig>
  <type>system</type>
  <listen>unix:path=/run/dbus/system_bus_socket</listen>
  <auth>EXTERNAL</auth>
  <policy context="default">
    <allow user="*"/>
    <allow own="*"/>
    <allow send_type="method_call"/>
    <allow send_destination="*"/>
    <allow receive_sender="*"/>
  </policy>
</busconfig>
"""

AVAHI_CONF = """[server]
use-ipv4=yes
use-ipv6=no
allow-interfaces={interface}
enable-dbus=yes
ratelimit-interval-usec=0
[publish]
disable-publishing=yes
[reflector]
[rlimits]
"""

SCRIPT = """set -e
mount -t tmpfs tmpfs /run
mkdir -p /run/dbus /run/avahi-daemon
dbus-daemon --config-file={dir}/dbus.conf --fork --nopidfile
export DBUS_SYSTEM_BUS_ADDRESS=unix:path=/run/dbus/system_bus_socket
avahi-daemon -f {dir}/avahi.conf --no-drop-root --no-chroot --no-rlimits -D
sleep 1
for attempt in 1 2 3 4 5 6 7 8; do
  avahi-browse -a -r -t -p -k > {dir}/browse.txt 2>{dir}/browse.err || true
  if [ "$(grep -c '^=.*_oscjson._tcp' {dir}/browse.txt)" -ge {count} ] && \
     [ "$(grep -c '^=.*_osc._udp' {dir}/browse.txt)" -ge {count} ]; then break; fi
  sleep 2
done
avahi-daemon -k || true
echo '{{"event": "done"}}'
"""


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_avahi_sees_every_node_and_its_oscquery_service(netns_lab: NetnsLab, tmp_path: Path) -> None:  # noqa: F811
    for tool in ("avahi-daemon", "avahi-browse", "dbus-daemon", "unshare"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not installed (Debian: apt-get install avahi-daemon avahi-utils dbus)")
    ns = netns_lab.namespace("avahi")
    other = netns_lab.namespace("peer")
    addr, _ = netns_lab.veth(ns, other)
    interface = next(line.split()[1] for line in ns.ip("-o", "-4", "addr", "show").stdout.splitlines() if addr in line)
    base = ["--host", "0.0.0.0", "--allow", "10.0.0.0/8", "--interface", addr, "--log-level", "INFO"]
    nodes = {
        "physics": ns.python("-m", "batteur", "physics", *base, "--scene", "strike", "--node-id", "physics-1"),
        "interaction": ns.python("-m", "batteur", "interaction", *base, "--interaction-config", "none",
                                 "--node-id", "interaction-1"),
        "sound": ns.python("-m", "batteur", "sound", *base, "--device", "none", "--node-id", "sound-1"),
        "graphics": ns.python("-m", "batteur", "graphics", *base, "--http-port", "0", "--node-id", "graphics-1"),
    }
    for proc in nodes.values():
        wait_line(proc, lambda s: "registered as" in s, 60)
    (tmp_path / "dbus.conf").write_text(DBUS_CONF)
    (tmp_path / "avahi.conf").write_text(AVAHI_CONF.format(interface=interface))
    script = SCRIPT.format(dir=tmp_path, count=len(nodes))
    avahi = ns.popen("unshare", "-m", "sh", "-c", script)
    avahi.expect(lambda e: e.get("event") == "done", timeout=120)
    records = [line.split(";") for line in (tmp_path / "browse.txt").read_text().splitlines()
               if line.startswith("=")]
    osc = {r[3]: r for r in records if r[4] == "_osc._udp"}
    oscjson = {r[3]: r for r in records if r[4] == "_oscjson._tcp"}
    detail = (tmp_path / "browse.txt").read_text() + (tmp_path / "browse.err").read_text()
    for role, proc in nodes.items():
        node_id = f"{role}-1"
        name = f"{role}-{node_id}"
        assert name in osc, detail
        assert name in oscjson, detail
        rec = osc[name]
        assert rec[7] == addr
        txt = rec[9]
        assert f'"role={role}"' in txt and f'"node_id={node_id}"' in txt and '"proto=1"' in txt, txt
        assert f'"port={rec[8]}"' in txt
        # the OSCQuery service answers on the advertised port with the node's namespace
        port = oscjson[name][8]
        fetch = ns.run(sys.executable, "-c", "import json, urllib.request as u; "
                       f"d = json.load(u.urlopen('http://{addr}:{port}/?HOST_INFO', timeout=10)); "
                       "print(d['NAME'], d['OSC_PORT'])", check=False, timeout=30)
        assert fetch.stdout.split() == [node_id, rec[8]], fetch.stderr
        assert proc.popen.poll() is None
    time.sleep(0.1)
