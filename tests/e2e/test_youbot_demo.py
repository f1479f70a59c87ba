"""The youBot demo composites as the README runs them: ``scart run`` subprocesses, each
with its own name service (``--ns 127.0.0.1:<free port>``), stopped by SIGINT or SIGTERM."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys

import pytest

from support import free_port, wait_until
from support.youbot import ROOT, YOUBOT, Demo, env, monitor_state, post_json, start_serving

from locomotor import POSES


def _running(url: str) -> dict:
    state = monitor_state(url)
    ok = state.get("status") and state["driver"]["state"] == "RUNNING" and state["driver"]["connected"]
    return state if ok else {}


@pytest.mark.parametrize(
    ("composite", "sig"),
    [("youbot.composite", signal.SIGINT), ("youbot.composite", signal.SIGTERM),
     ("youbot-binding.composite", signal.SIGINT)],
    ids=["SIGINT", "SIGTERM", "binding-SIGINT"],
)
def test_one_process_demo_starts_serves_and_stops(composite: str, sig: int) -> None:
    demo = start_serving(composite)
    try:
        url = demo.monitor_url()
        first = wait_until(lambda: _running(url), 20, 0.05, "monitor never showed a running driver")
        seq = first["status"]["sequence"]
        wait_until(lambda: monitor_state(url)["status"]["sequence"] > seq + 20, 10, 0.05)
        if composite == "youbot.composite" and sig == signal.SIGINT:
            _introspection_from_another_terminal(demo.ns, url)
    finally:
        code = demo.stop(sig)
    assert code == 0, demo.output()
    assert "scart: stopped" in demo.output()
    assert "Traceback" not in demo.output()


def _scart(ns: str, *args: str) -> str:
    done = subprocess.run([sys.executable, "-m", "scart", *args, "--ns", ns], capture_output=True, text=True,
                          env=env(), cwd=ROOT, timeout=30)
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    return done.stdout


def _introspection_from_another_terminal(ns: str, url: str) -> None:
    """What a user looks at first: ls, describe, echo, hz, write the period port, prop get."""
    assert re.search(r"youBotDriver\s+RUNNING", _scart(ns, "ls"))
    described = _scart(ns, "describe", "youBotDriver")
    assert "jointStatus" in described and "set_period" in described
    sample = json.loads(_scart(ns, "echo", "youBotDriver.jointStatus", "-n", "1", "--json").splitlines()[0])
    assert "joints" in json.dumps(sample)
    assert _scart(ns, "hz", "youBotDriver.jointStatus", "-n", "30")
    _scart(ns, "write", "youBotDriver.period", "0.05")
    wait_until(lambda: monitor_state(url)["driver"]["period"] == 0.05, 5, 0.05, "the monitor missed the period")
    assert json.loads(_scart(ns, "prop", "get", "youBotDriver", "accepted_period", "--json")) == 0.05


def test_two_processes_robot_and_workstation() -> None:
    robot = start_serving("robot.composite")
    ns = robot.ns
    workstation = None
    try:
        workstation = Demo("workstation.composite", ns)  # no task: it only uses the name service
        url = workstation.monitor_url()
        wait_until(lambda: _running(url), 20, 0.05, "workstation never saw the robot's driver")
        assert post_json(url + "api/pose", {"pose": "folded"}) == {"ok": True, "message": "moving to folded"}
        target = POSES["folded"]

        def converged() -> bool:
            joints = monitor_state(url)["status"]["joints"]
            return all(abs(j["position"] - t) < 0.02 for j, t in zip(joints, target))

        wait_until(converged, 15, 0.05, "the arm never reached 'folded'")
        events = wait_until(lambda: [e["name"] for e in monitor_state(url)["events"] if e["name"] == "reached"], 5)
        assert events == ["reached"]
        answer = post_json(url + "api/period", {"seconds": 0.02})
        assert answer["ok"] is True and "20 ms" in answer["message"], answer
        wait_until(lambda: monitor_state(url)["driver"]["period"] == 0.02, 5, 0.05)

        assert robot.stop(signal.SIGINT) == 0  # the robot goes away: the workstation notices ...
        wait_until(lambda: not monitor_state(url)["driver"]["connected"], 10, 0.05, "outage not shown")
        assert monitor_state(url)["driver"]["state"] == "OFFLINE"  # not the last known RUNNING
        answer = post_json(url + "api/period", {"seconds": 0.02})
        assert answer["ok"] is False and answer["message"].startswith("driver offline"), answer
        robot = Demo("robot.composite", ns)  # ... and picks the restarted one up by itself
        wait_until(lambda: _running(url), 20, 0.05, "the workstation did not reconnect")
        seq = monitor_state(url)["status"]["sequence"]
        wait_until(lambda: monitor_state(url)["status"]["sequence"] > seq + 20, 10, 0.05, "samples did not resume")
    finally:
        codes = [workstation.stop(signal.SIGTERM) if workstation else 0, robot.stop(signal.SIGINT)]
    assert codes == [0, 0], (robot.output(), workstation.output() if workstation else "")


def test_composites_validate() -> None:
    names = ("youbot.composite", "robot.composite", "workstation.composite", "youbot-binding.composite")
    files = [str(YOUBOT / f) for f in names]
    result = subprocess.run([sys.executable, "-m", "scart", "validate", *files], capture_output=True, text=True,
                            env=env(), cwd=ROOT, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.count(": ok") == len(names)


def test_stop_during_a_move_is_clean_and_prompt() -> None:
    """Ctrl-C while the arm moves: the SCA side stops before the driver it uses, so the
    proxy's one-way command never waits out its command_timeout."""
    demo = start_serving("youbot.composite")
    try:
        url = demo.monitor_url()
        wait_until(lambda: _running(url), 20, 0.05, "monitor never showed a running driver")
        assert post_json(url + "api/pose", {"pose": "folded"})["ok"] is True
        wait_until(lambda: any(e["name"] == "busy" for e in monitor_state(url)["events"]), 5, 0.02,
                   "the move never started")
    finally:
        code = demo.stop(signal.SIGINT, timeout=9.0)  # generous; before the fix: > 10 s
    out = demo.output()
    assert code == 0, out
    assert "not reached: timeout" not in out and "still running after" not in out, out
    assert "scart: stopped" in out


def test_second_demo_on_the_same_name_service_prints_no_url() -> None:
    first = start_serving("youbot.composite")
    try:
        first.monitor_url()
        second = Demo("youbot.composite", first.ns)
        try:
            code = second.proc.wait(60)
        finally:
            second.stop()
        out = second.output()
        assert code == 1 and "start failed" in out, out
        assert "youBot Monitor:" not in out, out
        assert "--ns HOST:PORT" in out and "--remap __ns=NAME" in out, out  # the error says how to fix it
    finally:
        assert first.stop() == 0


def test_two_demos_remapped_side_by_side_on_one_name_service() -> None:
    """``--remap`` renames the driver (and its status port) at launch: two demos share one
    name service, each monitor sees its own driver, the CLI sees both by their new names."""
    left = start_serving("youbot.composite", "--remap", "youBotDriver=left/youBotDriver",
                         "--remap", "jointStatus:=joint_states")
    try:
        assert "component youBotDriver (runs as left/youBotDriver)" in left.output()
        right = Demo("youbot.composite", left.ns, "--remap", "__ns=right")
        try:
            urls = [demo.monitor_url() for demo in (left, right)]
            for url in urls:
                wait_until(lambda u=url: _running(u), 20, 0.05, "a monitor never showed a running driver")
            listed = _scart(left.ns, "ls")
            assert re.search(r"left/youBotDriver\s+RUNNING", listed) and re.search(r"right/youBotDriver\s+RUNNING",
                                                                                    listed), listed
            assert "joint_states" in _scart(left.ns, "describe", "left/youBotDriver")
            assert "jointStatus" in _scart(left.ns, "describe", "right/youBotDriver")
            _scart(left.ns, "write", "right/youBotDriver.period", "0.05")  # one driver only
            wait_until(lambda: monitor_state(urls[1])["driver"]["period"] == 0.05, 5, 0.05, "right missed its period")
            assert monitor_state(urls[0])["driver"]["period"] == 0.01
        finally:
            assert right.stop() == 0, right.output()
    finally:
        assert left.stop() == 0, left.output()


def test_the_arm_summary_bridge_merges_status_and_busy_flag() -> None:
    """youbot.composite's armSummary bridge: the driver's status and the Locomotor's busy
    flag, merged into one ArmSummary that the monitor shows and the CLI describes."""
    demo = start_serving("youbot.composite")
    try:
        url = demo.monitor_url()
        first = wait_until(lambda: (monitor_state(url).get("summary") or {}), 20, 0.05, "no summary shown")
        assert len(first["positions"]) == 5 and first["busy"] is False
        described = _scart(demo.ns, "describe", "armSummary")
        assert "status.age" in described and "busy.samples" in described
        links = {lk["name"]: lk for lk in json.loads(_scart(demo.ns, "links", "--json"))}
        assert links["youBotDriver.jointStatus->armSummary.status"]["rate"] > 0
        assert post_json(url + "api/pose", {"pose": "candle"})["ok"]
        wait_until(lambda: monitor_state(url)["summary"]["busy"] is True, 10, 0.02, "the busy flag never crossed")
        done = wait_until(lambda: (s := monitor_state(url)["summary"])["busy"] is False and s, 30, 0.05,
                          "the move never ended")
        assert abs(done["positions"][1] - 1.1) < 0.05  # candle's second joint
    finally:
        assert demo.stop() == 0, demo.output()


def test_a_move_ordered_by_scart_call_shows_in_the_monitor() -> None:
    """``scart call Locomotor.move_to_pose folded`` (found by name, no ``--at``): the monitor
    shows busy, idle and reached as for a move from its own page."""
    demo = start_serving("youbot.composite")
    try:
        url = demo.monitor_url()
        wait_until(lambda: _running(url), 20, 0.05, "monitor never showed a running driver")
        assert json.loads(_scart(demo.ns, "call", "Locomotor.move_to_pose", "folded")) == "moving to folded"

        def moves() -> list[tuple[str, str]]:
            return [(e["name"], e["detail"]) for e in monitor_state(url)["events"]
                    if e["name"] in ("busy", "idle", "reached") and e["detail"] != "arm ready"]

        seen = wait_until(lambda: (m := moves()) and m[-1][0] == "reached" and m, 20, 0.05,
                          f"the monitor did not follow the move: {moves()}")
        assert seen == [("busy", "moving to folded"), ("idle", "at folded"), ("reached", "folded")]
    finally:
        assert demo.stop(signal.SIGINT) == 0, demo.output()


def test_a_taken_monitor_port_is_named() -> None:
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        demo = Demo("youbot.composite", f"127.0.0.1:{free_port()}", "--set", f"YouBotMonitor.port={port}")
        try:
            wait_until(lambda: demo.proc.poll() is not None, 30, 0.05, "scart run did not stop")
        finally:
            code = demo.stop()
    assert code == 1
    assert f"the monitor cannot listen on 127.0.0.1:{port}: Address already in use" in demo.output()
    assert "Traceback" not in demo.output()
