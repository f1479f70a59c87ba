"""Deployer: the tasks of one process, their connections, and their collective lifecycle.

Tasks are kept in the order they were added: ``configure_all``/``start_all`` walk that
order, ``stop_all``/``cleanup_all`` the reverse. Used as a context manager it stops and
cleans up everything on exit. ``serve()`` exposes the tasks over gRPC (implemented in
:mod:`dataflow.remote.server`, imported only when called).
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any

from .errors import DeploymentError, NotFoundError
from .policy import ConnPolicy
from .ports import Connection, InputPort, OutputPort
from .task import TaskContext, TaskState

if TYPE_CHECKING:  # the remote layer is imported only when serving
    from .remote.security import Security
    from .remote.server import DeployerServer

__all__ = ["Deployer"]

log = logging.getLogger(__name__)


class Deployer:
    """Holds the tasks of a process (unique names). Thread-safe for add/lookup."""

    def __init__(self) -> None:
        self._tasks: dict[str, TaskContext] = {}
        self._lock = threading.Lock()

    def add(self, task: TaskContext) -> TaskContext:
        """Add ``task``; returns it. Raises ``DeploymentError`` if its name is taken."""
        with self._lock:
            if task.name in self._tasks:
                raise DeploymentError(f"a task named {task.name!r} is already deployed")
            self._tasks[task.name] = task
        return task

    def task(self, name: str) -> TaskContext:
        """The task called ``name``; raises ``NotFoundError`` listing the deployed names."""
        try:
            return self._tasks[name]
        except KeyError:
            raise NotFoundError(f"no task {name!r}; deployed: {self.names() or 'none'}") from None

    def tasks(self) -> list[TaskContext]:
        """The tasks in the order they were added."""
        return list(self._tasks.values())

    def names(self) -> list[str]:
        """Task names in the order they were added."""
        return list(self._tasks)

    def _port(self, ref: str) -> Any:
        task_name, dot, port_name = ref.rpartition(".")
        if not dot or not task_name or not port_name:
            raise DeploymentError(f"expected 'task.port', got {ref!r}")
        return self.task(task_name).port(port_name)

    def connect(self, source: str, target: str, policy: ConnPolicy | None = None) -> Connection:
        """Connect output ``"a.out"`` to input ``"b.in"``; raises NotFound/PortType/DeploymentError."""
        out, inp = self._port(source), self._port(target)
        if not isinstance(out, OutputPort):
            raise DeploymentError(f"{source} is not an output port")
        if not isinstance(inp, InputPort):
            raise DeploymentError(f"{target} is not an input port")
        return out.connect_to(inp, policy if policy is not None else ConnPolicy())

    def configure_all(self) -> None:
        """Configure every task that is not running (PRE_OPERATIONAL or STOPPED), in order.

        Raises ``DeploymentError`` naming the first task that refused and why; tasks after
        it are left as they are.
        """
        for task in self.tasks():
            if task.is_running():
                continue
            if not task.configure():
                reason = (
                    "configure_hook vetoed"
                    if task.state is TaskState.PRE_OPERATIONAL
                    else f"it is in state {task.state.name}"
                )
                raise DeploymentError(f"task {task.name} failed to configure: {reason}")

    def start_all(self) -> None:
        """Start every STOPPED task, in order; raises ``DeploymentError`` naming a task that refused."""
        for task in self.tasks():
            if task.is_running():
                continue
            if not task.start():
                raise DeploymentError(
                    f"task {task.name} failed to start (state {task.state.name})"
                )

    def stop_all(self) -> None:
        """Stop every running task, in reverse order. Never raises for a task; idempotent."""
        for task in reversed(self.tasks()):
            if task.is_running():
                task.stop()

    def cleanup_all(self) -> None:
        """Clean up every STOPPED task, in reverse order (after ``stop_all``). Idempotent."""
        for task in reversed(self.tasks()):
            if task.state is TaskState.STOPPED:
                task.cleanup()

    def serve(self, address: str = "127.0.0.1:0", ns: str | None = None, *, lease_seconds: float | None = None,
              heartbeat_ms: int = 500, max_workers: int = 64, security: Security | None = None) -> DeployerServer:
        """Serve these tasks over gRPC at ``address``; returns the running server once it
        listens (does not block). The one public way to serve a deployer.

        ``ns=None`` embeds a name service in the server; otherwise the tasks are registered
        with the name service at ``ns`` under a lease of ``lease_seconds`` (default
        ``dataflow.remote.defaults.DEFAULT_LEASE``; renewed by heartbeats every third of it). ``heartbeat_ms``: idle interval of subscription
        heartbeats; ``max_workers``: concurrent RPCs; ``security``: TLS and tokens, for this
        server and for its calls to the name service and other deployers (see
        :mod:`dataflow.remote.security`; default: plaintext, no tokens, loopback only). Raises
        :class:`dataflow.remote.AlreadyRegisteredError` for a name held by another live
        deployer, :class:`dataflow.remote.UnavailableError` when nothing answers at ``ns``
        or ``address`` cannot be bound. See :mod:`dataflow.remote.server`."""
        from dataflow.remote.defaults import DEFAULT_LEASE
        from dataflow.remote.server import DeployerServer

        return DeployerServer(self, address, ns=ns, lease_seconds=lease_seconds or DEFAULT_LEASE,
                              heartbeat_ms=heartbeat_ms, max_workers=max_workers, security=security)

    def __enter__(self) -> Deployer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop_all()
        self.cleanup_all()
