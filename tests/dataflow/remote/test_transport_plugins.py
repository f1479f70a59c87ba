"""Transports are plug-ins found by entry point (``scart.transports``), as a third-party
package would install one: a policy naming it gets it, for links and subscriptions; a
plug-in that cannot be loaded is named in the error, and ``auto`` goes on without it."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from dataflow.policy import transport_names
from dataflow.transports import candidates, names

ROOT = Path(__file__).resolve().parents[3]

PLUGIN = '''
from dataflow import ConnPolicy
from dataflow.transports.grpc import GrpcTransport

#: a plug-in may name itself in a policy as it is imported (the registry is loading it then)
DEFAULT = ConnPolicy.data().with_(transport="tap")


class Tap(GrpcTransport):
    """gRPC streams under another name, counting the connections it carried."""

    name = "tap"
    rank = None  # only when a policy names it
    opened = 0

    def link(self, end, peer):
        Tap.opened += 1
        return super().link(end, peer)

    def subscribe(self, end, peer):
        Tap.opened += 1
        return super().subscribe(end, peer)


class Faulty(GrpcTransport):
    """Ranked before scart's own, and broken: every connection it is offered raises."""

    name = "faulty"
    rank = 5

    def link(self, end, peer):
        raise RuntimeError("a bug in the plug-in")

    def subscribe(self, end, peer):
        raise RuntimeError("a bug in the plug-in")
'''

ENTRY_POINTS = """[scart.transports]
tap = scart_tap:Tap
broken = scart_no_such_module:Transport
faulty = scart_tap:Faulty
Not-A-Name = scart_tap:Tap
"""

SCRIPT = '''
import logging
from support import wait_until
from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext
from dataflow.policy import transport_names
from dataflow.remote import connect
from dataflow.transports import TransportError, candidates

logging.basicConfig(level=logging.WARNING)


class Counter(TaskContext):
    out = OutputPort(int)


class Collector(TaskContext):
    inp = InputPort(int)


def until(predicate, what):
    wait_until(predicate, timeout=10, message=what)


print("names", " ".join(transport_names()))
try:
    ConnPolicy(transport="a-very-long-transport-name-" + "x" * 40)
except ValueError as exc:
    print("long:", exc)
try:
    candidates("broken")
except TransportError as exc:
    print("broken:", exc)
print("auto", " ".join(t.name for t in candidates("auto")))

d1, d2 = Deployer(), Deployer()
src, sink, other = d1.add(Counter("src")), d2.add(Collector("sink")), d2.add(Collector("other"))
s1 = d1.serve("127.0.0.1:0")
s2 = d2.serve("127.0.0.1:0", ns=s1.address)
got = []


def _drain(port):
    for _ in range(1000):
        status, value = port.read()
        if status.name != "NEW_DATA":
            return
        got.append(value)


sink.inp.add_data_callback(_drain)

try:
    with connect(s1.address, timeout=5.0) as system:
        system.connect_ports("src.out", "sink.inp", ConnPolicy.buffer(100).with_(transport="tap"), name="l")
        until(lambda: any(lk.transport == "tap" for lk in system.links()), "the link on tap")
        for k in range(20):
            src.out.write(k)
        until(lambda: len(got) == 20, "20 samples over the link")
        seen = []
        sub = system.component("src").subscribe("out", lambda e: seen.append(e.value),
                                                ConnPolicy.buffer(100).with_(transport="tap"))
        src.out.write(20)
        until(lambda: 20 in seen, "a sample to the subscription")
        import scart_tap  # loaded by the registry already

        print("link", got[:20] == list(range(20)), "subscription", sub.transport, "opened", scart_tap.Tap.opened)
        sub.close()
        # auto passes over the ranked plug-in that raises (said once) to scart's own
        system.connect_ports("src.out", "other.inp", ConnPolicy.buffer(100), name="a")
        until(lambda: any(lk.name == "a" and lk.transport == "ipc" for lk in system.links()), "the auto link on ipc")
        plain = system.component("src").subscribe("out", lambda e: None, ConnPolicy.buffer(10))
        print("auto-link ipc auto-subscription", plain.transport)
        plain.close()
        try:
            system.component("src").subscribe("out", seen.append, ConnPolicy.data().with_(transport="broken"))
        except TransportError as exc:
            print("subscribe-broken:", type(exc).__name__)
finally:
    s2.stop()
    s1.stop()
'''


def _install_plugin(folder: Path) -> None:
    """A package with its metadata, as ``pip install`` leaves it in site-packages."""
    (folder / "scart_tap.py").write_text(PLUGIN)
    info = folder / "scart_tap-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: scart-tap\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)


def test_a_plugin_transport_carries_links_and_subscriptions(tmp_path: Path) -> None:
    _install_plugin(tmp_path)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT), str(ROOT / "tests")]))
    result = subprocess.run([sys.executable, "-c", textwrap.dedent(SCRIPT)], env=env, cwd=tmp_path,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr
    lines = dict(line.split(" ", 1) for line in result.stdout.splitlines())
    assert lines["names"].split() == ["auto", "ipc", "shm", "grpc", "broken", "faulty", "ros1", "ros2", "tap", "yarp",
                                      "zenoh"]  # Not-A-Name ignored
    assert "transport entry point 'Not-A-Name'" in result.stderr and "a lower-case word" in result.stderr
    assert "must be auto, ipc, shm, grpc, broken, faulty, ros1, ros2, tap, yarp or zenoh" in lines["long:"]
    # the broken plug-in is named with its entry point and what failed
    assert "'broken'" in lines["broken:"] and "scart_no_such_module:Transport" in lines["broken:"]
    assert "ModuleNotFoundError" in lines["broken:"]
    # auto: by rank; the broken one skipped (said once), the unranked one not tried
    assert lines["auto"].split() == ["faulty", "shm", "ipc", "grpc"]
    assert "transport 'broken'" in result.stderr and "auto goes without it" in result.stderr
    assert lines["link"] == "True subscription tap opened 2"
    assert lines["subscribe-broken:"] == "TransportError"  # at once, not after the connect timeout
    # a ranked plug-in that raises never keeps auto from the transports that work; said once
    assert lines["auto-link"] == "ipc auto-subscription ipc"
    assert result.stderr.count("transport 'faulty' failed") == 1 and "a bug in the plug-in" in result.stderr


def test_scart_own_transports_are_entry_points() -> None:
    assert {"ipc", "shm", "grpc"} <= set(names())
    assert [t.name for t in candidates("auto")][:3] == ["shm", "ipc", "grpc"]
    assert transport_names()[:4] == ("auto", "ipc", "shm", "grpc")
