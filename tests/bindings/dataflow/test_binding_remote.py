"""binding.dataflow and scart:connect across processes: a ``scart run`` subprocess hosts the
thermostat task (robot side); an in-process runtime (workstation side) reaches it through
the name service embedded in the robot process."""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from support import ROOT, free_port, wait_until
from support.cli import finish, read_until, run
from support.sca import composite, line_of, write

import scart
from dataflow.remote import connect
from scart.bindings.dataflow import DataflowServiceBinding, DataflowSettings, bindings_of


BRIDGE = ROOT / "composites" / "bridge"


class Robot:
    """A ``scart run thermostat.composite --ns ADDRESS`` subprocess (restartable)."""

    def __init__(self, ns: str, composite_file: Path = BRIDGE / "thermostat.composite") -> None:
        self.ns = ns
        self.file = composite_file
        self.proc: subprocess.Popen[bytes] | None = None
        self.output = ""

    def start(self) -> str:
        env = {k: v for k, v in os.environ.items() if k != "SCART_NS"}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "scart", "run", str(self.file), "--ns", self.ns],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0, env=env,
        )
        self.output = read_until(self.proc, "started")
        return self.output

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            finish(self.proc)
        self.proc = None

    def stop(self) -> tuple[str, str]:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGINT)
        out = finish(self.proc)
        self.proc = None
        return out


def field(output: str, label: str) -> str:
    """The address after ``label`` in the start summary."""
    line = next(ln for ln in output.splitlines() if label in ln)
    return line.split(label, 1)[1].split()[0]


@pytest.fixture
def robot(monkeypatch: pytest.MonkeyPatch) -> Iterator[Robot]:
    ns = f"127.0.0.1:{free_port()}"
    monkeypatch.setenv("SCART_NS", ns)
    r = Robot(ns)
    try:
        yield r
    finally:
        r.kill()


def test_run_serves_tasks_with_embedded_name_service(robot: Robot) -> None:
    out = robot.start()
    assert field(out, "scart: name service at ") == robot.ns and "(embedded)" in out
    server = field(out, "scart: dataflow server at ")
    assert server == robot.ns  # the embedded name service lives in the deployer's server
    ls = subprocess.run([sys.executable, "-m", "scart", "ls", "--ns", robot.ns], capture_output=True, text=True,
                        timeout=60)
    assert "thermostat" in ls.stdout and "RUNNING" in ls.stdout, ls.stdout + ls.stderr
    with connect(robot.ns) as system:
        proxy = system.component("thermostat")
        assert proxy.get_property("gain") == 0.5
    out, err = robot.stop()
    assert "scart: stopped" in err, err  # scart's own lines: stderr


def test_binding_writes_receives_and_survives_restart(robot: Robot, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="scart.dataflow")
    robot.start()
    with scart.Runtime.from_file(BRIDGE / "bridge-binding.composite") as rt:
        ctl = rt.service("Controller/Controller")
        service = next(b for b in bindings_of(rt) if isinstance(b, DataflowServiceBinding))
        wait_until(lambda: service.connected, message="never subscribed")
        ctl.set_target(30.0)
        assert wait_until(lambda: ctl.temperatures() == [25.0] and ctl.temperatures())
        assert wait_until(lambda: ctl.latest() == 25.0)

        robot.kill()
        with pytest.raises(scart.ScartError):
            ctl.set_target(31.0)  # the task is gone: the call fails, naming it
        robot.start()  # a new process, a new deployer, same name service address
        wait_until(lambda: service.connected, timeout=20, message="never re-subscribed")

        def attempt() -> bool:
            try:
                ctl.set_target(40.0)
            except scart.ScartError:
                return False
            return True

        wait_until(attempt, timeout=20)
        assert wait_until(lambda: 30.0 in ctl.temperatures() and ctl.temperatures(), timeout=20)
    logs = caplog.text
    assert "task thermostat connected" in logs
    assert "task thermostat gone" in logs or "restarted" in logs


def test_binding_waits_for_a_task_that_appears_later(robot: Robot) -> None:
    with scart.Runtime.from_file(BRIDGE / "bridge-binding.composite") as rt:  # nothing answers yet
        ctl = rt.service("Controller/Controller")
        with pytest.raises(scart.ScartError, match="thermostat"):
            ctl.set_target(30.0)
        robot.start()
        service = next(b for b in bindings_of(rt) if isinstance(b, DataflowServiceBinding))
        wait_until(lambda: service.connected, timeout=20)
        ctl.set_target(30.0)
        assert wait_until(lambda: ctl.temperatures() == [25.0] and ctl.temperatures())


def drive(ctl: scart.ServiceProxy, targets: list[float]) -> list[float]:
    """Send each target, waiting for its sample before the next (deterministic sequence)."""
    for i, t in enumerate(targets, 1):
        ctl.set_target(t)
        wait_until(lambda i=i: len(ctl.temperatures()) >= i, message=f"no sample for target {t}")
    return ctl.temperatures()


def test_proxy_way_and_binding_way_behave_the_same(robot: Robot) -> None:
    robot.start()
    targets = [30.0, 30.0, 10.0, 22.5]
    results = []
    with connect(robot.ns) as system:
        thermostat = system.component("thermostat")
        for name in ("bridge-proxy.composite", "bridge-binding.composite"):
            thermostat.call("reset", 20.0)
            with scart.Runtime.from_file(BRIDGE / name) as rt:
                ctl = rt.service("Controller/Controller")
                if name == "bridge-binding.composite":
                    wait_until(lambda rt=rt: all(b.connected for b in bindings_of(rt)
                                                 if isinstance(b, DataflowServiceBinding)))
                results.append((drive(ctl, targets), ctl.latest()))
    assert results[0] == results[1] == ([25.0, 27.5, 18.75, 20.625], 20.625)


def test_remote_type_mismatch_is_a_static_error_online_only(robot: Robot, tmp_path: Path) -> None:
    """Loading is offline: the remote port is checked against the running name service only
    with ``Settings(online=True)`` (``scart validate --online``), else when it connects."""
    robot.start()
    (tmp_path / "wrong.py").write_text(
        "from typing import Protocol\nimport scart\n\n"
        "class Ports(Protocol):\n    def setpoint(self, value: str) -> None: ...\n\n"
        "@scart.component\nclass User:\n    t: Ports = scart.reference()\n", encoding="utf-8")
    text = composite(f"""
        <component name="u"><scart:implementation.python class="wrong:User"/>
          <reference name="t"><scart:binding.dataflow component="thermostat" ns="{robot.ns}"/></reference>
        </component>
    """)
    path = write(tmp_path, {"w.composite": text}, with_components=False)
    scart.Runtime.from_file(path)  # offline: nothing to check against, no error
    cli = run("validate", str(path))
    assert cli.returncode == 0, cli.stderr
    online = run("validate", "--online", str(path))
    assert online.returncode == 2 and "SCART-D003" in online.stderr and robot.ns in online.stderr
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path, settings=scart.Settings(online=True))
    (problem,) = err.value.errors
    assert (problem.code, problem.line) == ("SCART-D003", line_of(text, "binding.dataflow"))
    assert "interface type string does not match port thermostat.setpoint of type float64" in problem.message
    assert f"name service {robot.ns}" in problem.message


MIXED_TASKS = '''
from __future__ import annotations

from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, OutputPort, TaskContext, operation


class Logger(TaskContext):
    """Keeps every temperature it receives (fed by a cross-deployer scart:connect)."""

    temps = InputPort(float, event=True)
    last = OutputPort(float)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.seen: list[float] = []

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, v = self.temps.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.seen.append(v)
            self.last.write(v)

    @operation
    def logged(self) -> list[float]:
        return list(self.seen)


class Info(Protocol):
    def temperature_now(self) -> float: ...


class TaskOps(Protocol):
    def current_temperature(self) -> float: ...


@scart.component(services=[Info])
class InfoImpl:
    """Robot side: an SCA service (exported with binding.grpc) wired locally to the task."""

    thermostat: TaskOps = scart.reference()

    def temperature_now(self) -> float:
        return self.thermostat.current_temperature()


class Logged(Protocol):
    def logged(self) -> list[float]: ...


class ThermostatPorts(Protocol):
    def setpoint(self, value: float) -> None: ...


class Panel(Protocol):
    def heat(self, value: float) -> None: ...
    def history(self) -> list[float]: ...
    def remote_now(self) -> float: ...


@scart.component(services=[Panel])
class PanelImpl:
    logger: Logged = scart.reference()          # local wire to a task component
    thermostat: ThermostatPorts = scart.reference()  # binding.dataflow to the remote task
    info: Info = scart.reference()              # binding.grpc to the robot's SCA service

    def heat(self, value: float) -> None:
        self.thermostat.setpoint(value)

    def history(self) -> list[float]:
        return self.logger.logged()

    def remote_now(self) -> float:
        return self.info.temperature_now()


@scart.component
class Front:
    panel: Panel = scart.reference()

    def go(self, value: float) -> list[float]:
        self.panel.heat(value)
        return self.panel.history()
'''


ROBOT = """
    <component name="thermostat"><scart:implementation.task class="thermostat:Thermostat"/></component>
    <component name="info"><scart:implementation.python class="mixed:InfoImpl"/>
      <service name="Info"><scart:binding.grpc address="127.0.0.1:{port}"/></service>
      <reference name="thermostat" target="thermostat"/>
    </component>
"""


def test_composite_mixing_wire_binding_dataflow_task_connect_and_grpc(robot: Robot, tmp_path: Path) -> None:
    port = free_port()
    robot_dir = tmp_path / "robot"
    robot_dir.mkdir()
    (robot_dir / "thermostat.py").write_text((BRIDGE / "thermostat.py").read_text(encoding="utf-8"), encoding="utf-8")
    robot.file = write(robot_dir, {"robot.composite": composite(ROBOT.format(port=port)), "mixed.py": MIXED_TASKS},
                       with_components=False)
    robot.start()
    text = composite(f"""
        <component name="logger"><scart:implementation.task class="mixed:Logger"/></component>
        <scart:external task="thermostat"/>
        <scart:connect from="thermostat.temperature" to="logger.temps" policy="buffer:16"/>
        <component name="panel"><scart:implementation.python class="mixed:PanelImpl"/>
          <reference name="logger" target="logger"/>
          <reference name="thermostat"><scart:binding.dataflow component="thermostat"/></reference>
          <reference name="info"><scart:binding.grpc address="127.0.0.1:{port}" service="info/Info"/></reference>
        </component>
        <component name="front"><scart:implementation.python class="mixed:Front"/>
          <reference name="panel" target="panel"/></component>
    """)
    path = write(tmp_path, {"m.composite": text, "mixed.py": MIXED_TASKS}, with_components=False)
    # as scart run --ns does: joins the robot's name service
    rt = scart.Runtime.from_file(path, settings=DataflowSettings(ns=robot.ns, serve=True).apply())
    from scart.bindings.dataflow import host_of

    with rt:
        assert rt.served()["name service"] == f"{robot.ns} (joined)"
        with connect(robot.ns) as system:
            assert "logger" in system.component_names()
        front = rt.service("front")

        def fed() -> bool:
            front.go(30.0)
            return bool(rt.service("panel").history())

        wait_until(fed, timeout=20, interval=0.1, message="no sample crossed the deployers")
        history = rt.service("panel").history()
        assert all(20.0 < t < 30.0 for t in history) and history == sorted(history)
        assert host_of(rt).server is not None
        panel = rt.service("panel")  # binding.grpc -> SCA -> local wire -> task, vs the connected logger
        wait_until(lambda: panel.remote_now() == panel.history()[-1], message="logger and task disagree")

        # the robot restarts: a new deployer (and name service) at the same address; the
        # cross-deployer connection is made again and the binding writes again
        before = len(panel.history())
        robot.kill()
        robot.start()

        def fed_again() -> bool:
            try:
                front.go(30.0)
            except scart.ScartError:
                return False
            return len(panel.history()) > before

        wait_until(fed_again, timeout=30, interval=0.2, message="the connection was not re-made after the restart")


def test_second_scart_run_joins_the_name_service_and_clashes_are_refused(robot: Robot, tmp_path: Path) -> None:
    robot.start()
    folder = tmp_path / "second"
    folder.mkdir()
    (folder / "thermostat.py").write_text((BRIDGE / "thermostat.py").read_text(encoding="utf-8"), encoding="utf-8")
    second = Robot(robot.ns, write(folder, {"second.composite": composite(
        '<component name="thermo2"><scart:implementation.task class="thermostat:Thermostat" period="0.02"/>'
        "</component>")}, with_components=False))
    try:
        out = second.start()
        assert f"scart: name service at {robot.ns} (joined)" in out
        assert field(out, "scart: dataflow server at ") != robot.ns
        with connect(robot.ns) as system:
            assert system.component_names() == ["thermo2", "thermostat"]
            assert system.component("thermo2").describe().period == 0.02
        out, err = second.stop()  # SIGINT: clean stop, names unregistered
        assert "scart: stopped" in err, err
        with connect(robot.ns) as system:
            wait_until(lambda: system.component_names() == ["thermostat"])
    finally:
        second.kill()
    clash = subprocess.run(
        [sys.executable, "-m", "scart", "run", str(BRIDGE / "thermostat.composite"), "--ns", robot.ns],
        capture_output=True, text=True, timeout=60,
    )
    assert clash.returncode == 1 and "thermostat" in clash.stderr and "start failed" in clash.stderr


def test_type_mismatch_found_when_the_task_connects_later(
    robot: Robot, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="scart.dataflow")
    (tmp_path / "late.py").write_text(
        "from typing import Protocol\nimport scart\n\n"
        "class Ports(Protocol):\n    def setpoint(self, value: str) -> None: ...\n\n"
        "class Sink(Protocol):\n    def temperature(self, value: int) -> None: ...\n\n"
        "@scart.component(services=[Sink])\nclass User:\n    t: Ports = scart.reference()\n"
        "    def temperature(self, value: int) -> None: ...\n", encoding="utf-8")
    text = composite("""
        <component name="u"><scart:implementation.python class="late:User"/>
          <service name="Sink"><scart:binding.dataflow component="thermostat"/></service>
          <reference name="t"><scart:binding.dataflow component="thermostat"/></reference>
        </component>
    """)
    path = write(tmp_path, {"l.composite": text}, with_components=False)
    with scart.Runtime.from_file(path):  # nothing answers at load time: the composite starts
        robot.start()
        wait_until(lambda: "interface type string does not match port thermostat.setpoint" in caplog.text
                   and "interface type int64 does not match port thermostat.temperature" in caplog.text,
                   timeout=20, message=caplog.text)
