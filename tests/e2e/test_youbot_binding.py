"""The second variant of the proxy: ``BoundYouBotDriver`` wired to the driver task by
``binding.dataflow`` (no client-library code in the component), in one runtime."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from support import ROOT, wait_until

import scart

PROBE = ROOT / "tests" / "data" / "youbot" / "probe-binding.composite"
DEMO = ROOT / "composites" / "youbot" / "youbot-binding.composite"


@pytest.fixture
def rt() -> Iterator[scart.Runtime]:
    with scart.Runtime.from_file(PROBE) as runtime:
        yield runtime


def test_refresh_and_newest_sample(rt: scart.Runtime) -> None:
    probe = rt.service("Probe")
    probe.register()
    wait_until(lambda: probe.refreshes() > 10, 10, message="no refresh through the binding")
    task: Any = rt._managers["youBotDriver"].instance()
    wait_until(lambda: task._sequence - probe.status()["sequence"] <= 3, 5)
    info = probe.info()
    assert info["state"] == "RUNNING" and info["connected"] is True
    wait_until(lambda: 85 <= probe.info()["measured_rate"] <= 115, 5)


def test_command_busy_idle_and_period(rt: scart.Runtime) -> None:
    probe = rt.service("Probe")
    target = [-0.3, 0.4, 0.2, -0.4, 0.5]
    probe.command(target)
    wait_until(lambda: any(e[0] == "idle" for e in probe.events()), 10, message=str(probe.events()))
    assert probe.events() == [["busy", "[-0.300, 0.400, 0.200, -0.400, 0.500]"], ["idle", ""]]
    assert all(abs(p - t) <= 0.02 for p, t in zip(probe.register(), target))
    assert probe.set_period(0.02) == {"accepted": True, "period": 0.02, "message": "accepted 0.02 s"}
    refused = probe.set_period(0)
    assert refused["accepted"] is False and refused["period"] == 0.02
    wait_until(lambda: 40 <= probe.info()["measured_rate"] <= 55, 5)


def test_locomotor_and_monitor_on_the_binding_variant() -> None:
    with scart.Runtime.from_file(DEMO) as runtime:
        loc = runtime.service("Locomotor")
        stats = runtime.service("YouBotMonitor")
        wait_until(lambda: stats.statistics()["published"] > 5, 10)
        loc.move_to_pose("wave")
        wait_until(lambda: not loc.is_busy(), 15)
        assert loc.target_reached()
