"""Every inspection verb as a real subprocess against real deployer processes: text and
``--json`` output, JSON round trips (what echo/get print, write/set accept), errors."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from support import free_port, wait_until
from support.remote import address_of, start_scart, stop_process, subprocess_env

ROBOT = ["driver:YouBotDriver", "support.remote:Pinger@pinger", "support.remote:Echo@echo"]


@pytest.fixture(scope="module")
def system():
    """A deployer (youBot driver + pinger, embedded name service) and a second one joining it."""
    ns = f"127.0.0.1:{free_port()}"
    robot, _ = start_scart(["deploy", *ROBOT, "--period", "0.01", "--listen", ns])
    try:
        far, line = start_scart(["deploy", "support.remote:Pinger@far", "--period", "0.01", "--ns", ns])
    except BaseException:
        stop_process(robot)
        raise
    try:
        yield ns, address_of(line)
    finally:
        rc = (stop_process(far), stop_process(robot))
        assert rc == (0, 0)


def scart(ns: str | None, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    out = subprocess.run(
        [sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60, env=subprocess_env(ns)
    )
    if check:
        assert out.returncode == 0, f"scart {' '.join(args)} failed ({out.returncode}): {out.stderr}"
    return out


def test_ls_text_and_json(system) -> None:
    ns, far = system
    rows = json.loads(scart(ns, "ls", "--json").stdout)
    by_name = {r["name"]: r for r in rows}
    assert set(by_name) == {"youBotDriver", "pinger", "echo", "far"}
    driver = by_name["youBotDriver"]
    assert driver["state"] == "RUNNING" and driver["period"] == 0.01 and driver["deployer"] == ns
    assert 30 < driver["rate"] < 200
    assert by_name["far"]["deployer"] == far
    text = scart(None, "ls", "--ns", ns).stdout
    assert "youBotDriver" in text and "RUNNING" in text and ns in text


def test_describe_text_and_json(system) -> None:
    ns, _ = system
    doc = json.loads(scart(ns, "describe", "youBotDriver", "--json").stdout)
    ports = {p["name"]: p for p in doc["ports"]}
    assert ports["commands"]["direction"] == "in" and ports["commands"]["type_name"] == "float64[]"
    assert ports["jointStatus"]["type_name"] == "YouBotStatus"
    assert len(ports["jointStatus"]["last_value"]["joints"]) == 5
    assert {p["name"] for p in doc["properties"]} >= {"max_velocity", "noise", "accepted_period"}
    assert any(o["signature"] == "set_period(seconds: float64) -> bool" for o in doc["operations"])
    text = scart(ns, "describe", "youBotDriver").stdout
    assert "set_period(seconds: float64) -> bool" in text
    assert "out jointStatus: YouBotStatus" in text and "last = " in text
    assert "max_velocity: float64 [0 <= x <= 10, finite] = 1.0" in text  # its bounds shown
    # reading and describing attach nothing to the task: untouched ports show no connection
    # (an ended echo's stream is closed by the server shortly after the client left)
    scart(ns, "echo", "pinger.ticks", "-n", "1")

    def counts() -> dict[str, int]:
        pinger = json.loads(scart(ns, "describe", "pinger", "--json").stdout)
        return {p["name"]: p["connections"] for p in pinger["ports"]}

    wait_until(lambda: counts() == {"input": 0, "samples": 0, "output": 0, "ticks": 0}, timeout=30, interval=0.1)
    assert "ticks: int64, 0 connection(s)" in scart(ns, "describe", "pinger").stdout


def test_echo_json_lines_and_round_trip_into_write(system) -> None:
    ns, _ = system
    lines = scart(ns, "echo", "youBotDriver.jointStatus", "-n", "3", "--json").stdout.splitlines()
    assert len(lines) == 3
    assert all(len(json.loads(line)["joints"]) == 5 for line in lines)
    scart(ns, "write", "pinger.input", "2.5")
    echoed = scart(ns, "echo", "pinger.output", "-n", "1", "--json").stdout.strip()
    assert json.loads(echoed) == 2.5
    assert json.loads(scart(ns, "write", "pinger.input", echoed, "--json").stdout) == \
        {"status": "WRITE_SUCCESS", "port": "pinger.input", "accepted_by": "port"}
    text = scart(ns, "echo", "pinger.ticks", "-n", "2").stdout.splitlines()
    assert len(text) == 2 and text[0].startswith("[")


def _echo_json(ns: str, port: str) -> object:
    return json.loads(scart(ns, "echo", port, "-n", "1", "--json").stdout.strip())


def test_echo_json_round_trip_of_float_list_and_model(system) -> None:
    """What ``echo --json`` prints for a float list and a pydantic model, ``write`` accepts."""
    ns, _ = system
    sent = [1.5, -2.25, 3e-05, 0.0]
    assert scart(ns, "write", "echo.floats", json.dumps(sent)).stdout.startswith("WRITE_SUCCESS: the port took it")
    wait_until(lambda: _echo_json(ns, "echo.floats_out") == sent, timeout=30, interval=0.1)
    line = scart(ns, "echo", "echo.floats_out", "-n", "1", "--json").stdout.strip()
    assert scart(ns, "write", "echo.floats", line).stdout.startswith("WRITE_SUCCESS")  # echo → write
    status_line = scart(ns, "echo", "youBotDriver.jointStatus", "-n", "1", "--json").stdout.strip()
    status = json.loads(status_line)
    assert len(status["joints"]) == 5
    assert scart(ns, "write", "echo.status", status_line).stdout.startswith("WRITE_SUCCESS")
    wait_until(lambda: _echo_json(ns, "echo.status_out") == status, timeout=30, interval=0.1)
    bad = scart(ns, "write", "echo.status", json.dumps({"joints": "many"}), check=False)
    assert bad.returncode == 1 and "echo.status expects YouBotStatus" in bad.stderr


def test_hz(system) -> None:
    ns, _ = system
    stats = json.loads(scart(ns, "hz", "youBotDriver.jointStatus", "-n", "30", "--json").stdout.splitlines()[-1])
    assert set(stats) == {"rate", "min", "max", "std_dev", "window"}
    assert 50 < stats["rate"] < 200 and stats["window"] == 30  # -n 30: thirty periods measured
    assert 0 < stats["min"] <= stats["max"]
    assert "average rate:" in scart(ns, "hz", "pinger.ticks", "-n", "5").stdout


def test_write_and_wrong_type(system) -> None:
    ns, _ = system
    assert scart(ns, "write", "youBotDriver.commands", "[0.1, 0.2, 0.3, 0.4, 0.5]").stdout.strip() == \
        "WRITE_SUCCESS: youBotDriver checked it and accepted it (5 finite joint set-points)"
    bad = scart(ns, "write", "youBotDriver.commands", '"fast"', check=False)
    assert bad.returncode == 1 and bad.stdout == ""
    assert "youBotDriver.commands expects float64[]" in bad.stderr


def test_call_and_prop_round_trip(system) -> None:
    ns, _ = system
    assert json.loads(scart(ns, "call", "pinger.add", "1", "2.5").stdout) == 3.5
    assert json.loads(scart(ns, "call", "youBotDriver.set_period", "0.02").stdout) is True
    assert json.loads(scart(ns, "prop", "get", "youBotDriver", "accepted_period").stdout) == 0.02
    scart(ns, "call", "youBotDriver.set_period", "0.01")
    props = json.loads(scart(ns, "prop", "list", "youBotDriver", "--json").stdout)
    noise = next(p for p in props if p["name"] == "noise")
    assert noise["type_name"] == "float64"
    got = scart(ns, "prop", "get", "pinger", "gain", "--json").stdout.strip()
    assert scart(ns, "prop", "set", "pinger", "gain", got).stdout.strip() == got
    assert scart(ns, "prop", "set", "pinger", "label", "hello").stdout.strip() == '"hello"'
    assert "label: string" in scart(ns, "prop", "list", "pinger").stdout
    missing = scart(ns, "call", "pinger.nope", check=False)
    assert missing.returncode == 1 and "add" in missing.stderr and "reset" in missing.stderr


def test_state(system) -> None:
    ns, _ = system
    assert scart(ns, "state", "pinger", "stop").stdout.strip() == "STOPPED"
    refused = scart(ns, "state", "pinger", "stop", "--json", check=False)
    assert refused.returncode == 1
    assert json.loads(refused.stdout) == {"component": "pinger", "state": "STOPPED", "transition": "stop", "accepted": False}
    assert scart(ns, "state", "pinger", "start").stdout.strip() == "RUNNING"
    assert json.loads(scart(ns, "state", "pinger", "--json").stdout)["state"] == "RUNNING"


def test_connect_and_disconnect_across_deployers(system) -> None:
    ns, _ = system
    out = json.loads(scart(ns, "connect", "pinger.output", "far.input", "--policy", "buffer:8", "--json").stdout)
    assert out == {"name": "pinger.output->far.input", "source": "pinger.output", "sink": "far.input", "policy": "buffer:8",
                   "transport": "auto", "connected": True, "note": ""}
    scart(ns, "write", "pinger.input", "7.0")
    # far echoes what arrived from the other deployer (DATA subscription: last written value first)
    assert json.loads(scart(ns, "echo", "far.output", "-n", "1", "--json").stdout) == 7.0
    assert json.loads(scart(ns, "disconnect", "pinger.output", "far.input", "--json").stdout)["disconnected"] is True
    again = scart(ns, "disconnect", "pinger.output", "far.input", check=False)
    assert again.returncode == 1 and "were not connected" in again.stdout


def test_named_links_listed_rerouted_and_disconnected(system) -> None:
    ns, _ = system
    scart(ns, "connect", "echo.floats_out", "far.samples", "--name", "floats", "--policy", "buffer:4")
    scart(ns, "connect", "far.output", "pinger.input", "--name", "byGrpc", "--transport", "grpc")
    rows = {r["name"]: r for r in json.loads(scart(ns, "links", "--json", "--sample", "0").stdout)}
    assert rows["floats"]["sink"] == "far.samples" and rows["floats"]["transport"] == "ipc"  # one host: the fast path
    assert rows["byGrpc"]["transport"] == "grpc"  # as asked
    scart(ns, "disconnect", "byGrpc")
    assert rows["floats"]["policy"] == "buffer:4" and {"rate", "dropped", "samples"} <= set(rows["floats"])
    table = scart(ns, "links", "--sample", "0").stdout
    assert table.splitlines()[0].split()[:4] == ["NAME", "SOURCE", "SINK", "POLICY"] and "floats" in table
    assert "floats: echo.floats_out -> pinger.samples (buffer:4)" in scart(ns, "reroute", "floats", "pinger.samples").stdout
    rows = {r["name"]: r for r in json.loads(scart(ns, "links", "--json", "--sample", "0").stdout)}
    assert (rows["floats"]["sink"], rows["floats"]["transport"]) == ("pinger.samples", "local")
    wrong = scart(ns, "reroute", "floats", "pinger.input", check=False)  # float, not list[float]
    assert wrong.returncode == 1 and "types differ" in wrong.stderr
    assert json.loads(scart(ns, "disconnect", "floats", "--json").stdout) == {"name": "floats", "disconnected": True,
                                                                            "undelivered": 0}
    gone = scart(ns, "disconnect", "floats", check=False)
    assert gone.returncode == 1 and "no link 'floats'" in gone.stderr


def test_links_lists_the_subscriptions_served_with_their_transport(system) -> None:
    """``scart links --subscriptions``: each subscription a deployer serves, with the
    transport it came over (what ``auto`` picked), its policy and the subscriber's address;
    gone from the listing once closed."""
    from dataflow import ConnPolicy
    from dataflow.remote import connect

    ns, _ = system
    mine = {"policy": "buffer:7", "source": "pinger.ticks"}
    with connect(ns) as client:
        pinger = client.component("pinger")
        subs = [pinger.subscribe("ticks", lambda event: None, policy=ConnPolicy.buffer(7).with_(transport=transport))
                for transport in ("grpc", "auto")]
        try:
            wait_until(lambda: all(sub.delivered for sub in subs), timeout=30, message="no sample arrived")
            rows = [r for r in json.loads(scart(ns, "links", "--subscriptions", "--json", "--sample", "0.3").stdout)
                    if {k: r[k] for k in mine} == mine]
            assert sorted(r["transport"] for r in rows) == ["grpc", "ipc"]  # auto on one host: the fast path
            for row in rows:
                assert row["subscriber"].startswith(("ipv4:127.0.0.1:", "ipv6:")) and row["deployer"] == ns
                assert row["rate"] > 10 and row["samples"] > 0 and row["dropped"] >= 0  # the pinger runs at 100 Hz
            assert len({r["id"] for r in rows}) == 2
            table = scart(ns, "links", "-s", "--sample", "0").stdout.splitlines()
            assert table[0].split()[:4] == ["SOURCE", "SUBSCRIBER", "POLICY", "TRANSPORT"]
            assert sum("pinger.ticks" in line and "buffer:7" in line for line in table) == 2
        finally:
            for sub in subs:
                sub.close()
        wait_until(lambda: not [s for s in client.subscriptions() if s.policy == "buffer:7"], timeout=30,
                   message="closed subscriptions still listed")


def test_echo_picks_a_field_and_reads_well(system) -> None:
    ns, _ = system
    one = json.loads(scart(ns, "echo", "youBotDriver.jointStatus", "-n", "1", "--json", "--field",
                           "joints[2].position").stdout)
    assert isinstance(one, float)
    every = json.loads(scart(ns, "echo", "youBotDriver.jointStatus", "-n", "1", "--json", "--field",
                             "joints[*].temperature").stdout)
    assert len(every) == 5 and all(isinstance(t, float) for t in every)
    text = scart(ns, "echo", "youBotDriver.jointStatus", "-n", "1").stdout
    assert text.startswith("--- [") and '\n  "joints": [' in text  # a structure over several lines
    bad = scart(ns, "echo", "youBotDriver.jointStatus", "-n", "1", "--field", "joints[", check=False)
    assert bad.returncode == 1 and "--field 'joints['" in bad.stderr


def test_unknown_component_names_the_known_ones(system) -> None:
    ns, _ = system
    out = scart(ns, "describe", "ghost", check=False)
    assert out.returncode == 1 and "ghost" in out.stderr and "youBotDriver" in out.stderr


def test_no_name_service_error_names_address_and_remedy() -> None:
    address = f"127.0.0.1:{free_port()}"
    for args, env_ns in ((["ls", "--ns", address], None), (["describe", "x"], address)):
        out = scart(env_ns, *args, "--timeout", "1", check=False)
        assert out.returncode == 1 and out.stdout == ""
        assert f"no name service answers at {address}" in out.stderr
        assert "scart nameserver" in out.stderr and "scart deploy" in out.stderr
    assert "$SCART_NS" in out.stderr


def test_standalone_nameserver_verb() -> None:
    address = f"127.0.0.1:{free_port()}"
    proc, line = start_scart(["nameserver", "--listen", address])
    try:
        assert address in line
        assert json.loads(scart(address, "ls", "--json", "--sample", "0").stdout) == []
    finally:
        assert stop_process(proc, signal.SIGTERM) == 0


def test_echo_until_sigint(system) -> None:
    import selectors

    ns, _ = system
    proc = subprocess.Popen(
        [sys.executable, "-m", "scart", "echo", "pinger.ticks", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=subprocess_env(ns),
    )
    try:
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        assert sel.select(timeout=30), "echo printed nothing"
        assert isinstance(json.loads(proc.stdout.readline()), int)
        sel.close()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=15) == 0
    finally:
        stop_process(proc, signal.SIGKILL)


def test_connect_refuses_an_unknown_transport_before_connecting() -> None:
    from support.cli import run

    result = run("connect", "a.out", "b.in", "--transport", "nope", "--ns", "127.0.0.1:1")
    assert result.returncode == 2
    assert ("--transport: ConnPolicy.transport must be auto, ipc, shm, grpc, ros1, ros2, yarp or zenoh, got 'nope'"
            in result.stderr)


def test_deploy_advertises_what_it_is_told_and_refuses_a_malformed_address() -> None:
    ns = f"127.0.0.1:{free_port()}"
    proc, line = start_scart(["deploy", "support.remote:Pinger@adv", "--listen", ns, "--advertise", "localhost"])
    try:
        port = ns.rpartition(":")[2]
        assert f"reached as localhost:{port}" in line
        rows = json.loads(scart(ns, "ls", "--json").stdout)  # dials the advertised address
        assert [(r["name"], r["deployer"]) for r in rows] == [("adv", f"localhost:{port}")]
        assert rows[0]["state"] == "RUNNING"  # reached there
    finally:
        assert stop_process(proc) == 0
    bad = scart(None, "deploy", "support.remote:Pinger", "--advertise", "robot:0", check=False)
    assert bad.returncode == 1 and "advertise 'robot:0'" in bad.stderr and "1 to 65535" in bad.stderr


# ---- issue 25: nothing that reports success for a failure; what ROS hands know ----------

def test_write_reports_the_tasks_verdict_and_exits_1_when_refused(system) -> None:
    """The driver refuses a period of 5 s and a command of three joints: the writer hears it
    (exit 1, the driver's reason), nothing is printed as a success."""
    ns, _ = system
    for port, value, why in (("youBotDriver.period", "5", "the period must be in [0.001, 1] s"),
                             ("youBotDriver.commands", "[1,2,3]", "expected 5 finite values, got 3")):
        out = scart(ns, "write", port, value, check=False)
        assert out.returncode == 1 and out.stdout == "", out
        assert why in out.stderr and len(out.stderr.strip().splitlines()) == 1 and "Traceback" not in out.stderr
    accepted = scart(ns, "write", "youBotDriver.period", "0.01").stdout
    assert accepted.strip() == "WRITE_SUCCESS: youBotDriver checked it and accepted it (a period in [0.001, 1] s)"
    plain = scart(ns, "write", "pinger.input", "1.5").stdout
    assert plain.startswith("WRITE_SUCCESS: the port took it within its bounds (finite); pinger declares no check")
    missing = scart(ns, "write", "pinger.ticks", "1", check=False)
    assert missing.returncode == 1 and "pinger has no input port 'ticks'; inputs: input, samples" in missing.stderr


def test_write_takes_yaml_like_ros2_topic_pub_and_repeats_at_a_rate(system) -> None:
    ns, _ = system
    scart(ns, "write", "echo.status", "joints: []\ntimestamp: 1.5\nsequence: 77")  # block YAML
    wait_until(lambda: _echo_json(ns, "echo.status_out")["sequence"] == 77, timeout=30, interval=0.1)
    scart(ns, "write", "echo.floats", "[1, 2.5, -3]")
    wait_until(lambda: _echo_json(ns, "echo.floats_out") == [1.0, 2.5, -3.0], timeout=30, interval=0.1)

    def writes() -> int:
        doc = json.loads(scart(ns, "describe", "pinger", "--json").stdout)
        return next(p["writes"] for p in doc["ports"] if p["name"] == "output")

    before = writes()
    repeated = scart(ns, "write", "pinger.input", "2.0", "-r", "50", "-t", "5")
    assert repeated.stdout.splitlines()[-1] == "wrote 5 sample(s) to pinger.input"
    wait_until(lambda: writes() - before == 5, timeout=30, interval=0.1, message="5 writes did not all arrive")
    usage = scart(ns, "write", "pinger.input", "2.0", "-t", "5", check=False)
    assert usage.returncode == 2 and "give -r RATE" in usage.stderr


def test_ros_names_and_echo_once_and_hz_window(system) -> None:
    ns, _ = system
    for name in ("/youBotDriver/jointStatus", "youBotDriver/jointStatus"):
        lines = scart(ns, "echo", name, "--once", "--json").stdout.splitlines()
        assert len(lines) == 1 and len(json.loads(lines[0])["joints"]) == 5
    stats = [json.loads(line) for line in scart(ns, "hz", "/pinger/ticks", "-w", "5", "--duration", "2.5",
                                                 "--json").stdout.splitlines()]
    assert stats and all(s["window"] <= 5 for s in stats) and stats[-1]["window"] == 5
    assert 50 < stats[-1]["rate"] < 200


def test_topics_lists_every_port_with_type_direction_rate_and_connections(system) -> None:
    ns, _ = system
    rows = {r["name"]: r for r in json.loads(scart(ns, "topics", "--json").stdout)}
    status = rows["youBotDriver.jointStatus"]
    assert (status["type"], status["direction"], status["component"]) == ("YouBotStatus", "out", "youBotDriver")
    assert 80 < status["rate"] < 120 and isinstance(status["connections"], int)  # a 100 Hz task
    assert rows["youBotDriver.commands"]["direction"] == "in" and rows["youBotDriver.commands"]["rate"] is None
    assert "far.ticks" in rows  # every deployer's
    listed = scart(ns, "ports", "-t").stdout.splitlines()  # the alias, and ros2 topic list -t's form
    assert "youBotDriver.jointStatus [YouBotStatus]" in listed and "pinger.input [float64]" in listed
    table = scart(ns, "topics").stdout.splitlines()
    assert table[0].split() == ["NAME", "TYPE", "DIR", "RATE(Hz)", "CONNECTIONS"]


def test_ls_and_topics_measure_a_10_hz_task_as_hz_does() -> None:
    """A 10 Hz task: counting its cycles in a 0.25 s window says 8 or 12; timing them by the
    task's own cycle stamps (hz's estimator) says 10."""
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.remote:Pinger@slow", "--period", "0.1", "--listen", ns])
    try:
        rates = [json.loads(scart(ns, "ls", "--json").stdout)[0]["rate"] for _ in range(6)]
        assert all(9.0 <= r <= 11.0 for r in rates), rates
        ticks = [r for r in json.loads(scart(ns, "topics", "--json").stdout) if r["name"] == "slow.ticks"]
        assert 9.0 <= ticks[0]["rate"] <= 11.0, ticks
    finally:
        assert stop_process(proc) == 0


def test_deploy_imports_from_the_current_folder(tmp_path) -> None:
    """``scart deploy mytasks:Source`` in the module's own folder, through the console script
    (whose sys.path has the script's folder, not the current one)."""
    import shutil

    (tmp_path / "mytasks.py").write_text(
        "from dataflow import OutputPort, TaskContext\n\n"
        "class Source(TaskContext):\n    out = OutputPort(int)\n\n    def update_hook(self) -> None:\n"
        "        self.out.write(1)\n", encoding="utf-8")
    script = shutil.which("scart", path=str(Path(sys.executable).parent))
    assert script, "the scart console script is not installed next to this interpreter"
    ns = f"127.0.0.1:{free_port()}"
    env = subprocess_env()
    env.pop("PYTHONPATH", None)
    proc = subprocess.Popen([script, "deploy", "mytasks:Source", "--listen", ns], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_until(lambda: proc.poll() is not None or "Source" in scart(ns, "ls", "--timeout", "1",
                                                                          check=False).stdout,
                   timeout=30, interval=0.2)
        assert proc.poll() is None, proc.communicate(timeout=10)
    finally:
        assert stop_process(proc) == 0


def test_a_zenoh_error_carries_no_rust_source_path() -> None:
    """Zenoh's own error text names the Rust file and line it came from; the user gets the
    words without it."""
    out = scart(None, "echo", "a.b", "--zenoh", "--zenoh-connect", "tcp/[::1:3", "--timeout", "1", check=False)
    assert out.returncode == 1 and "Unable to connect" in out.stderr, out.stderr
    assert ".rs:" not in out.stderr and ".cargo" not in out.stderr and len(out.stderr.strip().splitlines()) == 1
    from dataflow.launch.zenoh import plain_error

    assert plain_error("Bad thing! at /x/y/src/net/z.rs:447.") == "Bad thing!"
    assert plain_error("[zenoh/src/a.rs:12]: refused") == "refused"
