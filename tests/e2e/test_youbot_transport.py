"""The youBot workstation's driver proxy on each transport (issue 12, transports as plug-ins).

The robot is the real ``robot.composite`` in a ``scart run`` subprocess (its own name
service on a free 127.0.0.1 port); the workstation composite runs in this process with
``SCAYouBotDriver.transport`` set, so its subscription can be asked what it really uses.
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from typing import Any

import pytest
from support import wait_until
from support.youbot import YOUBOT, Demo, ns_address, start_serving

import scart
from dataflow.transports.ipc import _wire as _ipc

WORKSTATION = YOUBOT / "workstation.composite"

pytestmark = pytest.mark.subprocess


@pytest.fixture(scope="module")
def robot() -> Iterator[Demo]:
    demo = start_serving("robot.composite")
    try:
        yield demo
    finally:
        assert demo.stop(signal.SIGINT) == 0, demo.output()


def _workstation(ns: str, transport: str) -> scart.Runtime:
    overrides = {"SCAYouBotDriver.name_service": ns, "SCAYouBotDriver.transport": transport}
    return scart.Runtime.from_file(WORKSTATION, overrides=overrides)


@pytest.mark.parametrize(("asked", "used"), [
    ("grpc", "grpc"),
    pytest.param("ipc", "ipc", marks=pytest.mark.skipif(not _ipc.available(), reason="ipc needs Linux")),
    pytest.param("auto", "ipc", marks=pytest.mark.skipif(not _ipc.available(), reason="ipc needs Linux")),
])
def test_workstation_proxy_receives_on_the_transport_asked_for(robot: Demo, asked: str, used: str) -> None:
    with _workstation(robot.ns, asked) as rt:
        proxy: Any = rt._managers["SCAYouBotDriver"].instance()
        status = rt.service("SCAYouBotDriver/RetrievingStatus")
        wait_until(lambda: status.get_driver_info()["connected"], 15, message="proxy never connected")
        start = proxy.received
        wait_until(lambda: proxy.received >= start + 20, 10, message=f"no samples over {asked}")
        assert proxy._subscription.transport == used
        assert proxy._subscription.policy.transport == asked
        info = status.get_driver_info()
        assert info["transport"] == used and info["transport_policy"] == asked
        first = status.get_joints_status()["sequence"]
        wait_until(lambda: status.get_joints_status()["sequence"] > first + 5, 10, message="samples stopped")
        monitor = rt.service("YouBotMonitor")  # the demo above the proxy runs unchanged
        wait_until(lambda: monitor.statistics()["published"] > 5, 10, message="the monitor got no samples")


def test_bad_transport_fails_at_start_naming_the_property() -> None:
    runtime = _workstation(ns_address(), "tcp")  # never contacted: the check comes first
    with pytest.raises(scart.ScartError, match=r"component SCAYouBotDriver: property transport='tcp': .*"
                                               r"auto, ipc.*grpc"):  # the accepted names
        runtime.start()


def test_bad_transport_on_the_command_line_is_a_start_failure(robot: Demo) -> None:
    demo = Demo("workstation.composite", robot.ns, "--set", "SCAYouBotDriver.transport=tcp")
    try:
        wait_until(lambda: demo.proc.poll() is not None, 30, 0.02, message="a bad transport did not stop the start")
    finally:
        code = demo.stop()
    assert code == 1, demo.output()
    assert "start failed" in demo.output() and "property transport='tcp'" in demo.output(), demo.output()
    assert "youBot Monitor:" not in demo.output()
