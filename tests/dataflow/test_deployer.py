"""Deployer: unique names, connect by name, ordering, configure failure reporting."""

from __future__ import annotations

import pytest

from dataflow import (
    ConnPolicy,
    DeploymentError,
    Deployer,
    FlowStatus,
    InputPort,
    NotFoundError,
    OutputPort,
    PortTypeError,
    SlaveActivity,
    TaskContext,
    TaskState,
)

log: list[str] = []


class Node(TaskContext):
    inp = InputPort(float)
    out = OutputPort(float)

    def __init__(self, name: str, refuse: bool = False) -> None:
        super().__init__(name, TaskState.PRE_OPERATIONAL)
        self.refuse = refuse
        self.set_activity(SlaveActivity())

    def configure_hook(self):
        log.append(f"configure {self.name}")
        return not self.refuse

    def start_hook(self):
        log.append(f"start {self.name}")
        return True

    def stop_hook(self):
        log.append(f"stop {self.name}")

    def cleanup_hook(self):
        log.append(f"cleanup {self.name}")


def test_ordering_and_context_manager():
    log.clear()
    with Deployer() as d:
        for n in ("a", "b", "c"):
            d.add(Node(n))
        assert d.names() == ["a", "b", "c"]
        d.configure_all()
        d.start_all()
        assert all(t.state is TaskState.RUNNING for t in d.tasks())
    assert log == [
        "configure a", "configure b", "configure c",
        "start a", "start b", "start c",
        "stop c", "stop b", "stop a",
        "cleanup c", "cleanup b", "cleanup a",
    ]
    d.stop_all()  # idempotent
    d.cleanup_all()


def test_unique_names_and_lookup():
    d = Deployer()
    a = d.add(Node("a"))
    assert d.task("a") is a
    with pytest.raises(DeploymentError, match="'a'"):
        d.add(Node("a"))
    with pytest.raises(NotFoundError, match="a"):
        d.task("zzz")


def test_connect_by_name():
    d = Deployer()
    a, b = d.add(Node("a")), d.add(Node("b"))
    conn = d.connect("a.out", "b.inp", ConnPolicy.buffer(2))
    assert conn.policy == ConnPolicy.buffer(2)
    a.out.write(1.5)
    assert b.inp.read() == (FlowStatus.NEW_DATA, 1.5)
    with pytest.raises(NotFoundError):
        d.connect("a.nope", "b.inp")
    with pytest.raises(DeploymentError):
        d.connect("a.inp", "b.inp")
    with pytest.raises(DeploymentError):
        d.connect("a", "b.inp")

    class S(TaskContext):
        s = InputPort(str)

    d.add(S("s"))
    with pytest.raises(PortTypeError):
        d.connect("a.out", "s.s")


def test_configure_failure_names_task_and_reason():
    d = Deployer()
    d.add(Node("ok"))
    d.add(Node("bad", refuse=True))
    with pytest.raises(DeploymentError, match="bad.*veto"):
        d.configure_all()


def test_serve_is_lazy_import():
    import subprocess
    import sys

    code = "import sys, dataflow; d = dataflow.Deployer(); print('dataflow.remote.server' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "False", out.stderr
