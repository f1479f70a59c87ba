"""The verbs ``scart deploy`` (host data-flow tasks in a served Deployer) and
``scart nameserver`` (a standalone name service).

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
from typing import Any

from dataflow.cli import _ros as ros_args
from dataflow.cli import _zenoh as zenoh_args
from dataflow.remote.defaults import DEFAULT_LEASE, DEFAULT_NS_ADDRESS, NS_ENV
from dataflow.remote.security import add_arguments, from_args


def register(subparsers: argparse._SubParsersAction) -> None:  # noqa: SLF001
    """Add ``deploy`` and ``nameserver``."""
    deploy = subparsers.add_parser("deploy", help="host data-flow tasks in a served Deployer until Ctrl-C")
    deploy.add_argument("classes", nargs="+", metavar="pkg.mod:Class[@name]", help="TaskContext classes to host")
    deploy.add_argument("--name", default=None, help="task name (one class only; default: the class's own)")
    deploy.add_argument("--period", type=float, default=None, help="run each task periodically (s)")
    deploy.add_argument("--listen", default=None, help="HOST:PORT to serve on (default: see above)")
    deploy.add_argument("--advertise", default=None, metavar="HOST[:PORT]",
                        help="the address registered in the name service and announced on Zenoh (default: "
                             "the one listened on; this host's name when listening on every interface)")
    deploy.add_argument("--ns", default=None, help=f"name service HOST:PORT (or ${NS_ENV}): joined when one answers there, else embedded there; "
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
    add_arguments(deploy, server=True)
    deploy.set_defaults(func=cmd_deploy)

    names = subparsers.add_parser("nameserver", help="run a standalone name service until Ctrl-C")
    names.add_argument("--listen", default=DEFAULT_NS_ADDRESS, help=f"HOST:PORT (default {DEFAULT_NS_ADDRESS})")
    names.add_argument("--lease", type=float, default=DEFAULT_LEASE, help="default lease (s)")
    add_arguments(names, server=True, client=False)
    names.set_defaults(func=cmd_nameserver)


def _err(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _stop_event() -> threading.Event:
    """An Event set by SIGINT/SIGTERM (handlers installed in the main thread)."""
    event = threading.Event()

    def handler(signum: int, frame: Any) -> None:
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
    module = importlib.import_module(module_name)
    try:
        cls = getattr(module, attr)
    except AttributeError:
        raise ValueError(f"module {module_name} has no {attr!r}") from None
    return cls, name or None


def _make_tasks(args: argparse.Namespace) -> list[Any]:
    from dataflow import PeriodicActivity, TaskContext

    if args.name and len(args.classes) > 1:
        raise ValueError("--name works with one class only; use pkg.mod:Class@name for several")
    tasks = []
    for spec in args.classes:
        cls, name = _load(spec)
        if not (isinstance(cls, type) and issubclass(cls, TaskContext)):
            raise ValueError(f"{spec} is not a TaskContext subclass")
        name = name or args.name
        task = cls(name) if name else (cls() if _has_default_name(cls) else cls(cls.__name__))
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


def cmd_deploy(args: argparse.Namespace) -> int:
    """Run ``scart deploy``; returns the exit code."""
    from dataflow import DataflowError, Deployer
    from dataflow.remote.naming import name_service_answers

    try:
        security = from_args(args)
        ros_args.apply(args)
    except (DataflowError, ValueError) as exc:
        _err(f"scart deploy: {exc}")
        return 1
    ns = args.ns or os.environ.get(NS_ENV) or None
    if ns is not None and not name_service_answers(ns, security=security):
        # Nothing answers at --ns/SCART_NS: embed the name service there, as `scart run` does.
        if args.listen and args.listen != ns:
            _err(f"scart deploy: no name service answers at {ns}; start one with "
                 f"`scart nameserver --listen {ns}`, or drop --listen to embed it there")
            return 1
        args.listen, ns = ns, None
    listen = args.listen or ("127.0.0.1:0" if ns else DEFAULT_NS_ADDRESS)
    stop = _stop_event()
    deployer = Deployer()
    server = None
    serving = False
    zenoh_session: Any = None
    zenoh_listen: list[str] = []
    publisher: Any = None
    try:
        if args.zenoh:  # before any task starts: a bad endpoint or a missing package stops nothing running
            try:
                zenoh_session, zenoh_listen = zenoh_args.session_of(args, serve=True, security=security)
            except Exception as exc:  # noqa: BLE001 - Zenoh's own errors (a bad endpoint) say what is wrong
                _err(f"scart deploy: --zenoh: {exc}")
                return 1
        try:
            for task in _make_tasks(args):
                deployer.add(task)
            deployer.configure_all()
            if not args.no_start:
                deployer.start_all()
            server = deployer.serve(listen, ns=ns, lease_seconds=args.lease, heartbeat_ms=args.heartbeat_ms,
                                    security=security, advertise=args.advertise)
        except (ImportError, ValueError, DataflowError) as exc:
            _err(f"scart deploy: {exc}")
            return 1
        try:
            _connect_at_start(server, args)
        except (ValueError, DataflowError) as exc:
            _err(f"scart deploy: --connect: {exc}")
            return 1
        if zenoh_session is not None:
            try:
                from dataflow.transports.zenoh import ZenohPublisher

                publisher = ZenohPublisher(deployer, zenoh_session, args.zenoh_ns,
                                           served=(server.advertised, server.boot_id))
            except Exception as exc:  # noqa: BLE001 - Zenoh's own errors say what is wrong
                _err(f"scart deploy: --zenoh: {exc}")
                return 1
        where = "embedded" if ns is None else "joined"
        on_zenoh = "" if publisher is None else (
            f"; Zenoh: {len(publisher.keys)} port(s) under scart/{args.zenoh_ns}/, listening on "
            f"{' '.join(zenoh_listen)}")  # the same line: scripts wait for one
        reach = "" if server.advertised == server.listen_address else f", reached as {server.advertised}"
        _err(f"scart deploy: serving {', '.join(deployer.names())} on {server.listen_address} "
             f"(name service {server.ns_address}, {where}{reach}){on_zenoh}")
        serving = True
        while not stop.wait(1.0):
            pass
    finally:
        if serving:
            _err("scart deploy: stopping")
        try:
            if publisher is not None:
                publisher.close()
            if zenoh_session is not None:
                zenoh_session.close()
        except Exception as exc:  # noqa: BLE001 - Zenoh failing to close never keeps the tasks running
            _err(f"scart deploy: closing Zenoh: {exc}")
        if server is not None:
            server.stop()
        deployer.stop_all()
        deployer.cleanup_all()
    return 0


def _connect_at_start(server: Any, args: argparse.Namespace) -> None:
    """Make the ``--connect`` links (a remote sink not registered yet is waited for)."""
    from dataflow import ConnPolicy
    from dataflow.remote.api import split_port

    policy = ConnPolicy.parse(args.policy)
    for source, sink in args.connect:
        (st, sp), (kt, kp) = split_port(source), split_port(sink)
        server.connect_ports(st, sp, kt, kp, policy, defer=True)


def cmd_nameserver(args: argparse.Namespace) -> int:
    """Run ``scart nameserver``; returns the exit code."""
    from dataflow import DataflowError
    from dataflow.remote.naming import serve_nameserver

    stop = _stop_event()
    try:
        server = serve_nameserver(args.listen, default_lease=args.lease, security=from_args(args))
    except DataflowError as exc:
        _err(f"scart nameserver: {exc}")
        return 1
    _err(f"scart nameserver: serving on {server.listen_address}")
    try:
        while not stop.wait(1.0):
            pass
    finally:
        server.stop()
    return 0
