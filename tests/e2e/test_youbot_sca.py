"""The paper's interaction, in one process over real gRPC on 127.0.0.1:

a Deployer hosts the dummy ``YouBotDriver`` (fast ``PeriodicActivity``) and serves it with
an embedded name service on port 0; an SCA runtime runs the hand-written proxy
``SCAYouBotDriver``, a probe recording its callbacks, and the ``Locomotor``
(``tests/data/youbot/probe.composite``) — plus the workstation composite with the monitor.
"""

from __future__ import annotations

import json
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from support import ROOT, free_port, wait_until
from support.youbot import post_json

import scart
from dataflow import Deployer, PeriodicActivity
from driver import YouBotDriver

PROBE = ROOT / "tests" / "data" / "youbot" / "probe.composite"
WORKSTATION = ROOT / "composites" / "youbot" / "workstation.composite"


class Robot:
    """A served deployer with the dummy driver (fast joints, so moves take ~0.3 s)."""

    def __init__(self, address: str = "127.0.0.1:0", period: float = 0.01) -> None:
        self.deployer = Deployer()
        self.driver = self.deployer.add(YouBotDriver("youBotDriver", period))
        self.driver.max_velocity = 6.0
        self.deployer.configure_all()
        self.deployer.start_all()
        self.server = self.deployer.serve(address)
        self.address: str = self.server.address
        self._stopped = False

    def stop(self) -> None:
        """Stop serving and tear the deployer down; a second call does nothing."""
        if self._stopped:
            return
        self._stopped = True
        self.server.stop()
        self.deployer.stop_all()
        self.deployer.cleanup_all()


@pytest.fixture
def robot() -> Iterator[Robot]:
    r = Robot()
    try:
        yield r
    finally:
        r.stop()


def runtime_for(path: Path, ns: str, **extra: str) -> scart.Runtime:
    overrides = {"SCAYouBotDriver.name_service": ns, **extra}
    return scart.Runtime.from_file(path, overrides=overrides)


@pytest.fixture
def probe_rt(robot: Robot) -> Iterator[scart.Runtime]:
    with runtime_for(PROBE, robot.address) as rt:
        wait_until(lambda: rt.service("Probe").info()["connected"], 10, message="proxy never connected")
        yield rt


def test_data_produces_refresh_and_newest_positions(probe_rt: scart.Runtime, robot: Robot) -> None:
    probe = probe_rt.service("Probe")
    probe.register()  # any call through a bidirectional interface registers the caller
    wait_until(lambda: probe.refreshes() > 10, 10, message="no refresh callbacks")
    status = probe.status()
    assert status is not None and len(status["joints"]) == 5
    json.dumps(status)  # JSON-able
    # the newest sample: its sequence is (at most a couple of periods) behind the driver's
    wait_until(lambda: robot.driver._sequence - probe.status()["sequence"] <= 3, 5)
    positions = probe.register()  # the arm stands still (no command): positions are exact
    assert positions == [j["position"] for j in probe.status()["joints"]] == robot.driver.positions


def test_command_produces_busy_then_idle(probe_rt: scart.Runtime, robot: Robot) -> None:
    probe = probe_rt.service("Probe")
    target = [0.3, 0.2, -0.2, 0.4, -0.3]
    probe.command(target)  # one-way: returns at once
    wait_until(lambda: [e[0] for e in probe.events()].count("idle") == 1, 10, message=str(probe.events()))
    events = [e for e in probe.events() if e[0] in ("busy", "idle")]
    assert [e[0] for e in events] == ["busy", "idle"]
    assert events[1][1] == ""  # reached, not timeout
    positions = probe.register()
    assert all(abs(p - t) <= 0.02 for p, t in zip(positions, target))
    assert all(abs(p - t) <= 0.02 for p, t in zip(robot.driver.positions, target))


def test_malformed_command_is_refused_with_idle(probe_rt: scart.Runtime) -> None:
    probe = probe_rt.service("Probe")
    probe.command([1.0, 2.0])
    wait_until(lambda: any(e[0] == "idle" for e in probe.events()), 10)
    busy, idle = [e for e in probe.events() if e[0] in ("busy", "idle")]
    assert busy[0] == "busy" and idle[0] == "idle" and idle[1].startswith("rejected: expected 5")


def test_set_period_accepted_and_refused(probe_rt: scart.Runtime, robot: Robot) -> None:
    probe = probe_rt.service("Probe")
    answer = probe.set_period(0.02)
    assert answer == {"accepted": True, "period": 0.02, "message": "accepted 0.02 s"}
    assert robot.driver.accepted_period == 0.02
    assert isinstance(robot.driver.activity, PeriodicActivity) and robot.driver.activity.period == 0.02
    refused = probe.set_period(3.0)
    assert refused["accepted"] is False and refused["period"] == 0.02
    assert "must be in [0.001, 1] s" in refused["message"]
    wait_until(lambda: probe.info()["period"] == 0.02, 5)
    wait_until(lambda: 40 <= probe.info()["measured_rate"] <= 55, 5, message="rate does not follow 20 ms")


def test_locomotor_reaches_a_pose(probe_rt: scart.Runtime) -> None:
    loc = probe_rt.service("Locomotor")
    assert "candle" in loc.poses()
    assert loc.move_to_pose("candle") == "moving to candle"
    assert loc.is_busy()
    wait_until(lambda: not loc.is_busy(), 10, message="Locomotor stayed busy")
    assert loc.target_reached()
    locomotor: Any = probe_rt._managers["Locomotor"].instance()
    assert locomotor.last_report == "target candle reached"
    with pytest.raises(ValueError, match="unknown pose 'dance'; known: home"):
        loc.move_to_pose("dance")
    with pytest.raises(ValueError, match="joint 2"):
        loc.move_to([0.0, 3.0, 0.0, 0.0, 0.0])


def test_polling_subscription_at_most_half_the_period(robot: Robot) -> None:
    with runtime_for(PROBE, robot.address, **{"SCAYouBotDriver.poll_period": "0.5"}) as rt:
        probe = rt.service("Probe")
        wait_until(lambda: probe.info()["connected"], 10)
        proxy: Any = rt._managers["SCAYouBotDriver"].instance()
        assert proxy._subscription.period == pytest.approx(0.005)  # clamped to period / 2
        probe.register()
        wait_until(lambda: probe.refreshes() > 10, 10)
        assert probe.set_period(0.02)["accepted"]
        assert proxy._subscription.period == pytest.approx(0.01)  # follows: half the new period
        probe.command([0.1, 0.1, 0.1, 0.1, 0.1])
        wait_until(lambda: any(e[0] == "idle" for e in probe.events()), 10)
        assert [e[0] for e in probe.events() if e[0] in ("busy", "idle")] == ["busy", "idle"]


def test_proxy_connects_when_the_driver_comes_up_later() -> None:
    address = f"127.0.0.1:{free_port()}"
    with runtime_for(PROBE, address) as rt:  # @init does not wait for the driver
        probe = rt.service("Probe")
        assert probe.register() == [] and probe.status() is None
        assert probe.info()["connected"] is False
        assert probe.set_period(0.02)["accepted"] is False
        late = Robot(address)
        try:
            wait_until(lambda: probe.info()["connected"], 10, message="no reconnection")
            wait_until(lambda: probe.refreshes() > 3, 10)
            assert ["connected", f"youBotDriver at {address}"] in probe.events()
        finally:
            late.stop()


def test_workstation_monitor_receives_and_serves(robot: Robot) -> None:
    with runtime_for(WORKSTATION, robot.address) as rt:
        stats = rt.service("YouBotMonitor")
        wait_until(lambda: stats.statistics()["published"] > 20, 10, message="monitor got no samples")
        url = stats.statistics()["url"]
        with urllib.request.urlopen(url + "api/state", timeout=5) as reply:
            state = json.load(reply)
        assert state["status"]["joints"] and "candle" in state["poses"]
        assert post_json(url + "api/pose", {"pose": "folded"}) == {"ok": True, "message": "moving to folded"}
        wait_until(lambda: ["reached", "folded"] in stats.statistics()["events"], 10)
        for pose in ("candle", "reach"):  # the second supersedes the first: the page is told
            assert post_json(url + "api/pose", {"pose": pose})["ok"] is True
        wait_until(lambda: ["reached", "reach"] in stats.statistics()["events"], 10)
        assert ["idle", "candle superseded"] in stats.statistics()["events"]
        answer = post_json(url + "api/period", {"seconds": 2})
        assert answer["ok"] is False and "must be in [0.001, 1] s" in answer["message"]
        latencies = stats.statistics()["latencies"]
        assert latencies and sorted(latencies)[len(latencies) // 2] < 0.1


def test_proxy_survives_the_robot_restarting() -> None:
    address = f"127.0.0.1:{free_port()}"
    first = Robot(address)
    with runtime_for(PROBE, address) as rt:
        probe = rt.service("Probe")
        try:
            wait_until(lambda: probe.info()["connected"], 10)
            probe.register()
            wait_until(lambda: probe.refreshes() > 3, 10)
        finally:
            first.stop()
        wait_until(lambda: not probe.info()["connected"], 10, message="outage not noticed")
        # the info flag is set just before the event is broadcast: wait for it, do not race it
        wait_until(lambda: ["disconnected", f"youBotDriver at {address}"] in probe.events(), 10,
                   message=f"no disconnected event: {probe.events()}")
        second = Robot(address)
        try:
            wait_until(lambda: probe.info()["connected"], 15, message="no reconnection")
            before = probe.refreshes()
            wait_until(lambda: probe.refreshes() > before + 5, 15, message="samples did not resume")
            probe.command([0.2, 0.2, 0.2, 0.2, 0.2])
            wait_until(lambda: any(e == ["idle", ""] for e in probe.events()), 10, message=str(probe.events()))
        finally:
            second.stop()


def test_a_waiting_command_ends_at_once_when_the_driver_goes_away() -> None:
    address = f"127.0.0.1:{free_port()}"
    robot = Robot(address)
    robot.driver.max_velocity = 0.05  # the move would take ~20 s; command_timeout is 10 s
    try:
        with runtime_for(PROBE, address) as rt:
            probe = rt.service("Probe")
            wait_until(lambda: probe.info()["connected"], 10)
            probe.command([1.0, 1.0, 1.0, 1.0, 1.0])
            wait_until(lambda: any(e[0] == "busy" for e in probe.events()), 5, message=str(probe.events()))
            robot.stop()
            idle = wait_until(lambda: [e for e in probe.events() if e[0] == "idle"], 8, message=str(probe.events()))
            assert idle == [["idle", "disconnected"]]
    finally:
        robot.stop()
