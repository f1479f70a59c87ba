"""``scart deploy``: host data-flow tasks in a served Deployer (``scart nameserver`` is
its standalone name service).

``scart deploy pkg.mod:Class [pkg.mod:Other@name ...] --name X --period 0.01`` imports
each class, creates the task (``Class(name)``; without a name, the class's own default
name when its ``__init__`` has one, else the class name), gives it a PeriodicActivity when
``--period`` is set, configures and starts everything, serves it over gRPC and waits
for SIGINT/SIGTERM; then it stops serving, stops the tasks and cleans them up in
reverse order. Without ``--ns``/``SCART_NS`` it embeds a name service and listens on
``127.0.0.1:7850`` (the default name-service port) unless ``--listen`` says otherwise;
with one, it joins the name service answering there (listening on a free port), or,
when nothing answers, embeds one at that address.

Readiness: one stderr line ``scart deploy: serving NAMES on HOST:PORT (name service
HOST:PORT)``. Exit codes: 0 clean stop, 1 failure (import, configure, bind, duplicate
name), 2 usage.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from dataflow.activities import freeze_heap
from dataflow.launch import ros as ros_args
from dataflow.launch import yarp as yarp_args
from dataflow.launch import zenoh as zenoh_args
from scart_wire.console import listen_arg
from scart_wire.defaults import DEFAULT_LEASE, DEFAULT_NS_ADDRESS, NS_ENV
from scart_wire.security import add_arguments as add_arguments_security
from scart_wire.security import from_args

if TYPE_CHECKING:
    from types import FrameType

    import zenoh

    from dataflow import TaskContext
    from dataflow.deployer import Server
    from dataflow.transports.zenoh import ZenohPublisher
    from scart_wire.security import Security


HELP = "host data-flow tasks in a served Deployer until Ctrl-C"


def add_arguments(deploy: argparse.ArgumentParser) -> None:
    """The classes to host and how to serve them."""
    deploy.add_argument("classes", nargs="+", metavar="pkg.mod:Class[@name]",
                        help="TaskContext classes to host (the current folder is on the import path, as for python "
                             "-m); also _TASK/PROPERTY:=VALUE, a task's property set at launch as a ROS parameter")
    deploy.add_argument("--name", default=None, help="task name (one class only; default: the class's own)")
    deploy.add_argument("--period", type=float, default=None, help="run each task periodically (s)")
    deploy.add_argument("--listen", default=None, help="HOST:PORT to serve on (default: see above)")
    deploy.add_argument("--advertise", default=None, metavar="HOST[:PORT]",
                        help="the address registered in the name service and announced on Zenoh (default: "
                             "the one listened on; this host's name when listening on every interface)")
    deploy.add_argument("--ns", default=None, type=listen_arg, metavar="HOST:PORT", help=f"name service HOST:PORT (or ${NS_ENV}): joined when one answers there, else embedded there; "
                        "default: embed one")
    deploy.add_argument("--lease", type=float, default=DEFAULT_LEASE, help="name-service lease (s)")
    deploy.add_argument("--heartbeat-ms", type=int, default=500, help="idle heartbeat of subscriptions (ms)")
    deploy.add_argument("--no-start", action="store_true", help="configure only, do not start the tasks")
    deploy.add_argument(
        "--connect", nargs=2, action="append", default=[], metavar=("A.out", "B.in"),
        help="connect a hosted output port to an input port here or in another deployer (repeatable)",
    )
    deploy.add_argument("--policy", default="data", help="policy of --connect: data | buffer:N | circular:N")
    zenoh_args.add_arguments(deploy, "also publish every output port on Zenoh (scart/NS/TASK/PORT) and announce "
                                     "the tasks with liveliness tokens")
    ros_args.add_arguments(deploy)
    yarp_args.add_arguments(deploy)
    ros_args.take_params(deploy, "classes")
    add_arguments_security(deploy, server=True)


def main(args: argparse.Namespace) -> int:
    """Run ``scart deploy``; returns the exit code."""
    return cmd_deploy(args)


def _err(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _stop_event() -> threading.Event:
    """An Event set by SIGINT/SIGTERM (handlers installed in the main thread)."""
    event = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        event.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return event


def _load(spec: str) -> tuple[type, str | None]:
    """``pkg.mod:Class[@name]`` → (class, name or None); raises ValueError/ImportError."""
    target, _, name = spec.partition("@")
    module_name, colon, attr = target.partition(":")
    if not colon or not module_name or not attr:
        raise ValueError(f"expected pkg.mod:Class[@name], got {spec!r}")
    here = os.getcwd()
    if here not in sys.path and "" not in sys.path:  # the current folder first, as `python -m` puts it
        sys.path.insert(0, here)
    module = importlib.import_module(module_name)
    try:
        cls = getattr(module, attr)
    except AttributeError:
        raise ValueError(f"module {module_name} has no {attr!r}") from None
    return cls, name or None


def _make_tasks(args: argparse.Namespace) -> list[TaskContext]:
    from dataflow import PeriodicActivity, TaskContext

    if args.name and len(args.classes) > 1:
        raise ValueError("--name works with one class only; use pkg.mod:Class@name for several")
    tasks = []
    for spec in args.classes:
        cls, name = _load(spec)
        if not (isinstance(cls, type) and issubclass(cls, TaskContext)):
            raise ValueError(f"{spec} is not a TaskContext subclass")
        name = name or args.name
        make: Callable[..., TaskContext] = cls  # with no name only when it has a default one
        task = make(name) if name else (make() if _has_default_name(cls) else make(cls.__name__))
        if args.period is not None and not task.set_activity(PeriodicActivity(args.period)):
            raise ValueError(f"{task.name}: refused a periodic activity of {args.period} s")
        tasks.append(task)
    return tasks


def _has_default_name(cls: type) -> bool:
    """True when ``cls(...)`` can be called without a name (its ``__init__`` has a default
    for its first parameter, or takes none)."""
    import inspect

    try:
        params = list(inspect.signature(cls).parameters.values())
    except (TypeError, ValueError):
        return False
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if not positional:
        return not any(p.kind is p.VAR_POSITIONAL for p in params)
    return positional[0].default is not inspect.Parameter.empty


class _Failed(Exception):
    """A step of ``scart deploy`` failed: the message is its one stderr line."""


def cmd_deploy(args: argparse.Namespace) -> int:
    """Run ``scart deploy``; returns the exit code."""
    from dataflow import DataflowError

    try:
        security = from_args(args)
        args.classes, params = ros_args.split_params(args.classes)
        if not args.classes:
            raise ValueError("no TaskContext class to host (pkg.mod:Class)")
        ros_args.apply(args, params)
        ros_args.exit_on_shutdown("scart deploy")
        yarp_args.apply(args)
        ns, listen = _where(args, security)
    except (DataflowError, ValueError) as exc:
        _err(f"scart deploy: {exc}")
        return 1
    except _Failed as exc:
        _err(f"scart deploy: {exc}")
        return 1
    stop = _stop_event()
    hosted = _Hosted(args, security)
    try:
        try:
            hosted.start(listen, ns)
        except _Failed as exc:
            _err(f"scart deploy: {exc}")
            return 1
        _err(hosted.readiness(ns))
        while not stop.wait(1.0):
            pass
        _err("scart deploy: stopping")
    finally:
        hosted.close()
    return 0


def _where(args: argparse.Namespace, security: Security) -> tuple[str | None, str]:
    """``(name service to join or None to embed one, address to listen on)``: nothing
    answering at ``--ns``/``SCART_NS`` means embedding the name service there, as ``scart
    run`` does. Raises :class:`_Failed` when ``--listen`` says otherwise."""
    from dataflow.remote.naming import name_service_answers

    ns = args.ns or os.environ.get(NS_ENV) or None
    listen = args.listen
    if ns is not None and not name_service_answers(ns, security=security):
        if listen and listen != ns:
            raise _Failed(f"no name service answers at {ns}; start one with `scart nameserver --listen {ns}`, "
                          "or drop --listen to embed it there")
        listen, ns = ns, None
    return ns, listen or ("127.0.0.1:0" if ns else DEFAULT_NS_ADDRESS)


class _Hosted:
    """What ``scart deploy`` runs: the deployer and its tasks, its server, and the Zenoh
    session and publisher of ``--zenoh``. :meth:`close` undoes whatever was started."""

    def __init__(self, args: argparse.Namespace, security: Security) -> None:
        from dataflow import Deployer

        self.args, self.security = args, security
        self.deployer = Deployer()
        self.server: Server | None = None
        self.zenoh_session: zenoh.Session | None = None
        self.zenoh_listen: list[str] = []
        self.publisher: ZenohPublisher | None = None

    def start(self, listen: str, ns: str | None) -> None:
        """Open Zenoh (before any task starts: a bad endpoint stops nothing running), host,
        start and serve the tasks, make the ``--connect`` links, publish on Zenoh. Raises
        :class:`_Failed` with what went wrong."""
        from dataflow import DataflowError

        args = self.args
        if args.insecure:
            _open_ros2()
        if args.zenoh:
            try:
                self.zenoh_session, self.zenoh_listen = zenoh_args.session_of(args, serve=True, security=self.security)
            except Exception as exc:  # noqa: BLE001 - Zenoh's own errors (a bad endpoint) say what is wrong
                raise _Failed(f"--zenoh: {zenoh_args.plain_error(str(exc))}") from None
            from dataflow.transports.zenoh import use_session

            use_session(self.zenoh_session)  # streams asked of this deployer (scart stream ... zenoh:KEY) use it
        try:
            for task in _make_tasks(args):
                self.deployer.add(task)
            ros_args.attach(self.deployer)  # launch-time parameters set; told so, the ROS node is made
            self.deployer.configure_all()
            if not args.no_start:
                self.deployer.start_all()
            self.server = self.deployer.serve(listen, ns=ns, lease_seconds=args.lease, heartbeat_ms=args.heartbeat_ms,
                                              security=self.security, advertise=args.advertise)
        except (ImportError, ValueError, DataflowError) as exc:
            raise _Failed(str(exc)) from None
        try:
            _connect_at_start(self.server, args)
        except (ValueError, DataflowError) as exc:
            raise _Failed(f"--connect: {exc}") from None
        if self.zenoh_session is not None:
            self._publish()
        try:
            ros_args.hold()  # told it is a ROS node (--ros-*, _TASK/PROP:=VALUE): its node now
        except DataflowError as exc:
            raise _Failed(str(exc)) from None
        freeze_heap()  # what start-up built is never walked by the collector again: no 20 ms pauses

    def _publish(self) -> None:
        assert self.server is not None and self.zenoh_session is not None  # published once served, with a session
        try:
            from dataflow.transports.zenoh import ZenohPublisher

            self.publisher = ZenohPublisher(self.deployer, self.zenoh_session, self.args.zenoh_ns,
                                            served=(self.server.advertised, self.server.boot_id),
                                            auth=self.security.auth_table())
        except Exception as exc:  # noqa: BLE001 - Zenoh's own errors say what is wrong
            raise _Failed(f"--zenoh: {zenoh_args.plain_error(str(exc))}") from None

    def readiness(self, ns: str | None) -> str:
        """The one line scripts wait for: what is served where."""
        server, publisher = self.server, self.publisher
        assert server is not None  # said once served
        where = "embedded" if ns is None else "joined"
        on_zenoh = "" if publisher is None else (
            f"; Zenoh: {len(publisher.keys)} port(s) under scart/{self.args.zenoh_ns}/, listening on "
            f"{' '.join(self.zenoh_listen)}")  # the same line: scripts wait for one
        reach = "" if server.advertised == server.listen_address else f", reached as {server.advertised}"
        return (f"scart deploy: serving {', '.join(self.deployer.names())} on {server.listen_address} "
                f"(name service {server.ns_address}, {where}{reach}){on_zenoh}")

    def close(self) -> None:
        """Stop publishing, close Zenoh, stop serving, stop and clean up the tasks (reverse order)."""
        try:
            if self.publisher is not None:
                self.publisher.close()
            if self.zenoh_session is not None:
                from dataflow.transports.zenoh import use_session

                use_session(None)
                self.zenoh_session.close()
        except Exception as exc:  # noqa: BLE001 - Zenoh failing to close never keeps the tasks running
            _err(f"scart deploy: closing Zenoh: {exc}")
        if self.server is not None:
            self.server.stop()
        self.deployer.stop_all()
        self.deployer.cleanup_all()
        ros_args.detach(self.deployer)
        ros_args.unhold()


def _open_ros2() -> None:
    """``--insecure``: this process's ROS 2 streams on the network, not loopback only (a
    process without Cyclone DDS has none: nothing to open)."""
    from dataflow.transports import TransportError, load

    try:
        configure = getattr(load("ros2"), "configure", None)
    except TransportError:
        return
    if configure is not None:
        configure(insecure=True)
        _err("scart deploy: --insecure: ROS 2 streams are open to the network (DDS authenticates no one)")


def _connect_at_start(server: Server, args: argparse.Namespace) -> None:
    """Make the ``--connect`` links (a remote sink not registered yet is waited for)."""
    from dataflow import ConnPolicy
    from dataflow.remote.api import split_port

    policy = ConnPolicy.parse(args.policy)
    for source, sink in args.connect:
        (st, sp), (kt, kp) = split_port(source), split_port(sink)
        server.connect_ports(st, sp, kt, kp, policy, defer=True)
