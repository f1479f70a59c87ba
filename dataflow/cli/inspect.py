"""Introspection of a running data-flow system: ``scart ls | describe | echo | hz | write |
call | prop | state | connect | links | reroute | disconnect``.

Every verb finds the system through a name service: ``--ns HOST:PORT``, else the
``SCART_NS`` environment variable, else ``127.0.0.1:7850``. Data goes to stdout (with
``--json``: JSON, one document — or one line per sample for ``echo``/``hz`` streams),
diagnostics to stderr. ``--timeout`` is the deadline of each remote call.
What ``echo --json`` prints, ``write`` accepts.

Exit codes: 0 success, 1 a failure (nothing answers, unknown name, wrong type, refused
transition), 2 usage.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import statistics
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from dataflow.cli import _zenoh as zenoh_args
from dataflow.remote.api import TRANSITIONS
from dataflow.remote.defaults import DEFAULT_NS_ADDRESS, NS_ENV
from dataflow.remote.security import add_arguments, from_args


def register(subparsers: argparse._SubParsersAction) -> None:  # noqa: SLF001
    """Add the inspection verbs."""
    def verb(name: str, help_: str, func: Callable[[argparse.Namespace], int]) -> argparse.ArgumentParser:
        p = subparsers.add_parser(name, help=help_)
        p.add_argument("--ns", default=None, help=f"name service HOST:PORT (default ${NS_ENV} or {DEFAULT_NS_ADDRESS})")
        p.add_argument("--json", action="store_true", help="JSON on stdout")
        p.add_argument("--timeout", type=float, default=3.0, help="deadline of each remote call (s)")
        add_arguments(p, server=False)
        p.set_defaults(func=lambda a: _guard(func, a))
        return p

    p = verb("ls", "list components: name, state, period, measured rate, deployer", cmd_ls)
    p.add_argument("--sample", type=float, default=0.25, help="time over which the rate is measured (s)")
    zenoh_args.add_arguments(p, "list what Zenoh announces (liveliness tokens), no name service needed")
    p = verb("describe", "properties, operations and ports of a component", cmd_describe)
    p.add_argument("component")
    p = verb("echo", "print samples of an output port", cmd_echo)
    p.add_argument("port", metavar="COMP.PORT")
    p.add_argument("-n", type=int, default=None, help="stop after N samples")
    p.add_argument("--policy", default="data", help="data | buffer:N | circular:N (default data)")
    p.add_argument("--period", type=float, default=None, help="poll at this period instead of push")
    zenoh_args.add_arguments(p, "take the samples from Zenoh (scart/NS/COMP/PORT), no name service needed")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--field", default=None, metavar="PATH",
                   help="print only this part of each sample: joints[2].position, joints[*].position")
    p = verb("hz", "measure the rate of an output port", cmd_hz)
    p.add_argument("port", metavar="COMP.PORT")
    p.add_argument("-n", type=int, default=None, help="stop after N samples (prints one report)")
    p.add_argument("--window", type=int, default=10000, help="periods kept for the statistics")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p = verb("write", "write one value (JSON) to an input port", cmd_write)
    p.add_argument("port", metavar="COMP.PORT")
    p.add_argument("value", help="JSON value (a bare word is taken as a string)")
    p = verb("call", "call a task's operation, with --at an SCA service's, or a ROS service (ros1:/name), with "
                     "JSON arguments", cmd_call)
    p.add_argument("operation", metavar="COMP.OP|COMPONENT/SERVICE.op|ros1:/service")
    p.add_argument("args", nargs="*", help="JSON arguments (a ROS service: one object of its request's fields)")
    p.add_argument("--at", default=None, metavar="HOST:PORT",
                   help="call an SCA service served there (scart run prints it: 'SCA services at ...'; "
                        "or $SCART_SERVICES)")
    p.add_argument("--type", default=None, metavar="pkg/Srv",
                   help="a ROS service's type (default: asked of the service, as rosservice does)")
    from dataflow.cli import _ros as ros_args

    ros_args.add_arguments(p)
    from dataflow.cli.services import cmd_services

    p = verb("services", "list the SCA services a scart run serves (--at HOST:PORT)", cmd_services)
    p.add_argument("--at", default=None, metavar="HOST:PORT", help="where (scart run prints it), or $SCART_SERVICES")
    p = verb("prop", "list, get or set properties", cmd_prop)
    p.add_argument("action", choices=["list", "get", "set"])
    p.add_argument("component")
    p.add_argument("name", nargs="?")
    p.add_argument("value", nargs="?", help="JSON value (set)")
    p = verb("state", "show or change a component's lifecycle state", cmd_state)
    p.add_argument("component")
    p.add_argument("transition", nargs="?", choices=TRANSITIONS)
    p = verb("connect", "connect an output port to an input port (any deployers)", cmd_connect)
    p.add_argument("source", metavar="A.out")
    p.add_argument("sink", metavar="B.in")
    p.add_argument("--policy", default="data", help="data | buffer:N | circular:N (default data)")
    p.add_argument("--name", default=None, help="the link's name (default A.out->B.in)")
    p.add_argument("--transport", default="auto", type=_transport,
                   help="across processes: auto (default: ipc on one host, else grpc), ipc (same-host fast path; "
                        "shm is the same), grpc, or an installed plug-in's name")
    p = verb("stream", "join a port to a topic of a transport (zenoh, ros1, ros2...): a stream", cmd_stream)
    p.add_argument("port", metavar="COMP.PORT")
    p.add_argument("topic", metavar="TRANSPORT:TOPIC")
    p.add_argument("--policy", default="data", help="data | buffer:N | circular:N (default data)")
    p.add_argument("--type", default=None, help="the topic's message type, for a transport with its own (ROS)")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="what the transport needs besides (e.g. connect=tcp/127.0.0.1:7447 for zenoh)")
    p.add_argument("--name", default=None, help="the stream's name (default COMP.PORT~TRANSPORT:TOPIC)")
    p = verb("links", "list links and streams: name, ends, policy, transport, state, measured rate, drops",
             cmd_links)
    p.add_argument("--sample", type=float, default=0.25, help="time over which the rate is measured (s)")
    p.add_argument("--subscriptions", "-s", action="store_true",
                   help="list the subscriptions the deployers serve instead: port, subscriber, policy, transport, "
                        "the port's measured write rate, drops")
    p = verb("reroute", "point a link at another input port (made before the old one goes)", cmd_reroute)
    p.add_argument("name", metavar="LINK")
    p.add_argument("sink", metavar="C.in")
    p = verb("disconnect", "disconnect a link (by its name, or by its two ports)", cmd_disconnect)
    p.add_argument("source", metavar="LINK|A.out")
    p.add_argument("sink", metavar="B.in", nargs="?")
    from dataflow.cli import record

    record.register(verb, subparsers)
    from dataflow.cli.foxglove import cmd_foxglove

    p = verb("foxglove", "serve every output port live to the Foxglove app (WebSocket protocol)", cmd_foxglove)
    p.add_argument("--host", default="127.0.0.1", help="where to listen (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8765, help="port (default 8765; 0: a free one)")
    p.add_argument("--refresh", type=float, default=2.0, help="look for new tasks every this many seconds")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--insecure-host", action="store_true", help="allow a routable --host (no authentication!)")


# ---- shared plumbing -------------------------------------------------------------------
def ns_address(args: argparse.Namespace) -> str:
    """The name service to use: ``--ns``, else ``$SCART_NS``, else the default."""
    return args.ns or os.environ.get(NS_ENV) or DEFAULT_NS_ADDRESS


def _err(message: str) -> None:
    print(f"scart {message}", file=sys.stderr, flush=True)


def _out(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _dump(obj: Any) -> str:
    return json.dumps(obj, ensure_ascii=False)


def _jsonable(value: Any) -> Any:
    from dataflow import registry

    return registry.to_jsonable(value)


def _parse_json(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text  # a bare word is a string


def _guard(func: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """Run a verb: connect, map errors to one stderr line and exit code 1."""
    from dataflow import DataflowError
    from dataflow.cli.services import at
    from dataflow.remote import connect
    from dataflow.remote.errors import RemoteTimeoutError, UnavailableError

    if getattr(args, "zenoh", False):  # Zenoh: no name service involved
        if args.command == "echo" and (args.policy != "data" or args.period is not None):
            _err("echo: --policy and --period are for the name service's subscriptions, not --zenoh")
            return 1
        try:
            security = from_args(args)
        except DataflowError as exc:  # unusable security files
            _err(f"{args.command}: {exc}")
            return 1
        try:
            args.zenoh_session, _ = zenoh_args.session_of(args, security=security)
        except (ValueError, DataflowError) as exc:  # ours: a bad endpoint, namespace or auth file, a missing package
            _err(f"{args.command}: --zenoh: {exc}")
            return 1
        except Exception as exc:  # noqa: BLE001 - Zenoh's own errors: nothing reached, perhaps refused
            _err(f"{args.command}: --zenoh: {exc}{zenoh_args.refusal_hint(security)}")
            return 1
        try:
            if not zenoh_args.peers(args.zenoh_session):
                _err(f"{args.command}: --zenoh: no Zenoh peer reached; give --zenoh-connect ENDPOINT "
                     f"(scart deploy --zenoh prints where it listens){zenoh_args.refusal_hint(security)}")
                if args.command == "ls":
                    return 1
            return func(args)
        except Exception as exc:  # noqa: BLE001 - Zenoh's own errors too: one line, exit 1
            _err(f"{args.command}: {exc}")
            return 1
        finally:
            args.zenoh_session.close()
    if at(args) is not None or _ros_call(args):  # SCA services, ROS services: no name service involved
        try:
            return func(args)
        except (DataflowError, ValueError) as exc:
            _err(f"{args.command}: {exc}")
            return 1
    address = ns_address(args)
    source = "--ns" if args.ns else (f"${NS_ENV}" if os.environ.get(NS_ENV) else "the default")
    try:
        system = connect(address, timeout=args.timeout, security=from_args(args))
    except (UnavailableError, RemoteTimeoutError) as exc:
        _err(
            f"{args.command}: no name service answers at {address} (from {source}): {exc}\n"
            f"  start one with `scart nameserver --listen {address}`, or host tasks with "
            f"`scart deploy pkg.mod:Class` (embeds one on {DEFAULT_NS_ADDRESS}),\n"
            f"  or point --ns / {NS_ENV} at a running name service or deployer."
        )
        return 1
    except DataflowError as exc:  # credentials refused, unusable security files
        _err(f"{args.command}: {exc}")
        return 1
    try:
        args.system = system
        return func(args)
    except (DataflowError, ValueError) as exc:
        _err(f"{args.command}: {exc}")
        return 1
    finally:
        system.close()


def _ros_call(args: argparse.Namespace) -> bool:
    """``scart call ros1:/service ...``: a ROS service, found through the ROS master."""
    return args.command == "call" and str(getattr(args, "operation", "")).startswith("ros1:")


def _split(text: str, what: str = "PORT") -> tuple[str, str]:
    from dataflow.remote.api import split_port

    return split_port(text, what)


@contextlib.contextmanager
def _stopped_by_signals(done: threading.Event) -> Iterator[None]:
    """SIGINT and SIGTERM set ``done`` inside the block (then the former handlers again):
    set before a subscription starts printing, so a Ctrl-C after its first line stops it."""
    def handler(signum: int, frame: Any) -> None:
        done.set()

    old = [signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)]
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old[0])
        signal.signal(signal.SIGTERM, old[1])


def _wait_until_stopped(done: threading.Event, duration: float | None, tick: float = 1.0,
                        on_tick: Callable[[], None] | None = None) -> None:
    """Block until ``done``, SIGINT/SIGTERM, or ``duration`` s; call ``on_tick`` every ``tick`` s."""
    with _stopped_by_signals(done):
        deadline = None if duration is None else time.monotonic() + duration
        while not done.is_set():
            wait = tick if deadline is None else min(tick, max(0.0, deadline - time.monotonic()))
            if done.wait(wait):
                break
            if deadline is not None and time.monotonic() >= deadline:
                break
            if on_tick is not None:
                on_tick()


def _with_rates(listing: Callable[[], list[Any]], count: Callable[[Any], int], sample: float) -> list[tuple[Any, float]]:
    """Each item of ``listing()`` with its rate (count per second) measured over ``sample`` s:
    listed twice, ``sample`` s apart; an item that appeared in between has rate 0."""
    first = {item.name: (count(item), time.monotonic()) for item in listing()}
    if sample > 0:
        threading.Event().wait(sample)
    out = []
    for item in listing():
        count0, t0 = first.get(item.name, (count(item), time.monotonic()))
        dt = time.monotonic() - t0
        out.append((item, round((count(item) - count0) / dt, 2) if dt > 0 else 0.0))
    return out


# ---- verbs -----------------------------------------------------------------------------
def cmd_ls(args: argparse.Namespace) -> int:
    """``scart ls``: one line per component; rate measured over ``--sample`` s (``--zenoh``:
    the components and output ports Zenoh's liveliness tokens announce)."""
    if getattr(args, "zenoh", False):
        from dataflow.transports.zenoh import discover

        found = discover(args.zenoh_session, args.zenoh_ns, timeout=max(args.timeout / 3, 0.2))
        if args.json:
            _out(_dump([{"name": name, "ports": ports} for name, ports in found.items()]))
            return 0
        _out(f"{'NAME':<24} PORTS (on Zenoh: scart/{args.zenoh_ns}/NAME/PORT)")
        for name, ports in found.items():
            _out(f"{name:<24} {' '.join(ports) or '-'}")
        return 0
    rows = [{"name": c.name, "state": c.state, "activity": c.activity, "period": c.period, "rate": rate,
             "cycles": c.cycles, "overruns": c.overruns, "deployer": c.address}
            for c, rate in _with_rates(args.system.components, lambda c: c.cycles, args.sample)]
    if args.json:
        _out(_dump(rows))
        return 0
    _out(f"{'NAME':<24} {'STATE':<16} {'PERIOD':>9} {'RATE(Hz)':>9}  DEPLOYER")
    for r in rows:
        period = f"{r['period']:g}" if r["period"] else "-"
        _out(f"{r['name']:<24} {r['state']:<16} {period:>9} {r['rate']:>9.1f}  {r['deployer']}")
    return 0


def cmd_describe(args: argparse.Namespace) -> int:
    """``scart describe COMP``."""
    proxy = args.system.component(args.component)
    desc, last = proxy.describe_with_values()
    if args.json:
        doc = desc.model_dump(mode="json")
        for port in doc["ports"]:
            if port["name"] in last:
                port["last_value"] = _jsonable(last[port["name"]])
        _out(_dump(doc))
        return 0
    period = f", period {desc.period:g} s" if desc.period else ""
    _out(f"{desc.name}: {desc.state} ({desc.activity}{period}, {desc.cycles} cycles, {desc.overruns} overruns)")
    _out("properties:")
    for p in desc.properties:
        bounds = f" [{p.bounds}]" if p.bounds else ""
        _out(f"  {p.name}: {p.type_name}{bounds} = {_dump(p.value)}" + (f"  # {p.doc}" if p.doc else ""))
    _out("operations:")
    for o in desc.operations:
        _out(f"  {o.signature or o.name}" + (f"  # {o.doc}" if o.doc else ""))
    _out("ports:")
    for p in desc.ports:
        bounds = f" [{p.bounds}]" if p.bounds else ""
        line = f"  {p.direction:<3} {p.name}: {p.type_name}{bounds}, {p.connections} connection(s)"
        if p.name in last:
            text = _dump(_jsonable(last[p.name]))
            line += f", last = {text if len(text) <= 120 else text[:117] + '...'}"
        _out(line + (f"  # {p.doc}" if p.doc else ""))
        for s in p.streams:
            _out("      " + _stream_line(s))
    return 0


def _stream_line(s: Any) -> str:
    """A stream under its port: ``stream NAME: transport:topic (type), state[, UNAUTHENTICATED]``
    and, when samples were refused, how many and why the last one was."""
    kind = f" ({s.type_name})" if s.type_name else ""
    line = f"stream {s.name}: {s.topic}{kind}, {s.state}"
    if s.unauthenticated:
        line += ", UNAUTHENTICATED (anyone who reaches it may publish)"
    if s.refused or s.refusal:
        line += f"; {s.refused} refused" + (f", last: {s.refusal}" if s.refusal else "")
    return line


def _policy(text: str) -> Any:
    from dataflow import ConnPolicy

    return ConnPolicy.parse(text)


def _transport(text: str) -> str:
    """``--transport``: a name a policy accepts, checked by the policy (plug-ins are looked
    up only for a name that is not scart's own)."""
    from dataflow import ConnPolicy

    try:
        return ConnPolicy(transport=text).transport
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def cmd_echo(args: argparse.Namespace) -> int:
    """``scart echo COMP.PORT [-n N] [--field PATH]``: each sample (or the part ``--field``
    names): readable, over several lines for a structure (``--- [sequence]`` first), or one
    JSON line with ``--json``."""
    from dataflow.fields import apply_path, parse_path

    component, port = _split(args.port)
    path = parse_path(args.field) if args.field is not None else None
    if args.field is not None and path is None:
        raise ValueError(f"--field {args.field!r}: expected a path such as joints[2].position or joints[*].position")
    proxy = None if getattr(args, "zenoh", False) else args.system.component(component)
    done = threading.Event()
    count = [0]
    lock = threading.Lock()

    def observer(event: Any) -> None:
        with lock:
            if done.is_set():
                return
            data = _jsonable(event.value)
            if path is not None:
                try:
                    data = apply_path(data, path)
                except (KeyError, IndexError, TypeError, AttributeError):
                    _err(f"echo: sample {event.sequence} has no {args.field}")
                    data = None
            if args.json:
                _out(_dump(data))
            elif isinstance(data, (dict, list)) and data:
                _out(f"--- [{event.sequence}]\n{json.dumps(data, ensure_ascii=False, indent=2)}")
            else:
                _out(f"[{event.sequence}] {_dump(data)}")
            count[0] += 1
            if args.n is not None and count[0] >= args.n:
                done.set()

    with _stopped_by_signals(done):  # before the first sample can be printed
        if getattr(args, "zenoh", False):
            from dataflow.transports.zenoh import ZenohSubscription

            sub: Any = ZenohSubscription(args.zenoh_session, component, port, observer, args.zenoh_ns)
        else:
            assert proxy is not None
            sub = proxy.subscribe(port, observer, policy=_policy(args.policy), period=args.period)
        try:
            _wait_until_stopped(done, args.duration)
        finally:
            sub.close()
    if sub.dropped and getattr(args, "zenoh", False):
        _err(f"echo: {sub.dropped} sample(s) lost on Zenoh or not decodable")
    elif sub.dropped:
        _err(f"echo: {sub.dropped} sample(s) dropped by the policy {args.policy}")
    return 0


def hz_stats(stamps: list[float]) -> dict[str, float]:
    """``ros2 topic hz`` statistics from sample times (s): rate, min, max, std_dev, and window
    (the number of periods measured)."""
    periods = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    if not periods:
        return {"rate": 0.0, "min": 0.0, "max": 0.0, "std_dev": 0.0, "window": 0}
    mean = statistics.fmean(periods)
    return {
        "rate": 1.0 / mean if mean > 0 else math.inf,
        "min": min(periods),
        "max": max(periods),
        "std_dev": statistics.pstdev(periods),
        "window": len(periods),  # intervals measured: `hz -n 100` reports 100
    }


def cmd_hz(args: argparse.Namespace) -> int:
    """``scart hz COMP.PORT [-n N]``: rate statistics from the samples' source times."""
    from dataflow import ConnPolicy

    component, port = _split(args.port)
    proxy = args.system.component(component)
    done = threading.Event()
    stamps: list[float] = []
    lock = threading.Lock()
    target = None if args.n is None else args.n + 1  # n periods need n+1 samples

    def observer(event: Any) -> None:
        with lock:
            stamps.append(event.source_time)
            del stamps[: max(0, len(stamps) - args.window - 1)]  # window periods need window + 1 samples
            if target is not None and len(stamps) >= target:
                done.set()

    def report() -> None:
        with lock:
            stats = hz_stats(list(stamps))
        if args.json:
            _out(_dump(stats))
        else:
            _out(f"average rate: {stats['rate']:.3f}\n\tmin: {stats['min']:.6f}s max: {stats['max']:.6f}s "
                 f"std dev: {stats['std_dev']:.6f}s window: {stats['window']}")

    with _stopped_by_signals(done):  # a Ctrl-C while subscribing stops it too
        sub = proxy.subscribe(port, observer, policy=ConnPolicy.buffer(1000))
        try:
            _wait_until_stopped(done, args.duration, on_tick=report if args.n is None else None)
        finally:
            sub.close()
    report()
    return 0


def cmd_write(args: argparse.Namespace) -> int:
    """``scart write COMP.PORT VALUE``."""
    component, port = _split(args.port)
    status = args.system.component(component).write_json(port, _parse_json(args.value))
    _out(_dump({"status": status.name}) if args.json else status.name)
    return 0 if status.name == "WRITE_SUCCESS" else 1


def cmd_call(args: argparse.Namespace) -> int:
    """``scart call COMP.OP ARGS...`` (a task's operation), or with ``--at`` an SCA
    service's: prints the result."""
    from dataflow.cli.services import at, call

    if _ros_call(args):
        from dataflow.cli import _ros as ros_args

        _out(_dump(ros_args.call(args, [_parse_json(a) for a in args.args])))
        return 0
    address = at(args)
    if address is not None:
        _out(_dump(call(address, args.operation, [_parse_json(a) for a in args.args], args)))
        return 0
    component, op = _split(args.operation, "OPERATION")
    result = args.system.component(component).call_json(op, [_parse_json(a) for a in args.args], timeout=args.timeout)
    _out(_dump(_jsonable(result)))
    return 0


def cmd_prop(args: argparse.Namespace) -> int:
    """``scart prop list|get|set COMP [NAME] [VALUE]``."""
    proxy = args.system.component(args.component)
    if args.action == "list":
        props = list(proxy.properties().values())
        if args.json:
            _out(_dump([p.model_dump(mode="json") for p in props]))
        else:
            for p in props:
                _out(f"{p.name}: {p.type_name} = {_dump(p.value)}" + (f"  # {p.doc}" if p.doc else ""))
        return 0
    if not args.name:
        raise ValueError(f"prop {args.action} needs a property NAME")
    if args.action == "get":
        _out(_dump(_jsonable(proxy.get_property(args.name))))
        return 0
    if args.value is None:
        raise ValueError("prop set needs a VALUE (JSON)")
    _out(_dump(proxy.set_property_json(args.name, _parse_json(args.value))))
    return 0


def cmd_state(args: argparse.Namespace) -> int:
    """``scart state COMP [TRANSITION]``."""
    proxy = args.system.component(args.component)
    accepted = True
    if args.transition:
        accepted = proxy.change_state(args.transition)
    state = proxy.state
    if args.json:
        doc: dict[str, Any] = {"component": args.component, "state": state}
        if args.transition:
            doc.update(transition=args.transition, accepted=accepted)
        _out(_dump(doc))
    else:
        _out(state)
    if not accepted:
        _err(f"state: {args.component} refused {args.transition} (state {state})")
        return 1
    return 0


def cmd_connect(args: argparse.Namespace) -> int:
    """``scart connect A.out B.in [--policy P]``."""
    policy = _policy(args.policy).with_(transport=args.transport)
    note = args.system.connect_ports(args.source, args.sink, policy, name=args.name)
    name = args.name or next((lk.name for lk in args.system.links()
                              if (lk.source, lk.sink) == (args.source, args.sink)), f"{args.source}->{args.sink}")
    doc = {"name": name, "source": args.source, "sink": args.sink, "policy": str(policy), "connected": True,
           "note": note}
    _out(_dump(doc) if args.json else f"connected {args.source} -> {args.sink} ({policy}) as {name}"
         + (f": {note}" if note else ""))
    return 0


def cmd_stream(args: argparse.Namespace) -> int:
    """``scart stream COMP.PORT TRANSPORT:TOPIC``: the port's deployer joins it to the topic."""
    transport, colon, topic = args.topic.partition(":")
    if not colon or not topic:
        raise ValueError(f"{args.topic!r}: expected TRANSPORT:TOPIC, e.g. zenoh:robot/status or ros1:/joint_states")
    options = dict(_option(o) for o in args.option)
    if args.type:
        options["type"] = args.type
    policy = _policy(args.policy).with_(transport=transport, topic=topic)
    link = args.system.stream(args.port, policy, options, name=args.name)
    _out(_dump(link.model_dump()) if args.json else f"streaming {link.source} -> {link.sink} ({link.policy}) "
         f"as {link.name}")
    return 0


def _option(text: str) -> tuple[str, str]:
    key, eq, value = text.partition("=")
    if not eq or not key:
        raise ValueError(f"--option {text!r}: expected KEY=VALUE")
    return key, value


def cmd_links(args: argparse.Namespace) -> int:
    """``scart links``: one line per link; rate measured over ``--sample`` s
    (``--subscriptions``: one line per subscription served: which port goes to whom, over
    which transport (what ``auto`` picked), at what rate, losing how many)."""
    if args.subscriptions:
        return _rated_table(args, args.system.subscriptions, (
            ("source", "SOURCE", "<28"), ("subscriber", "SUBSCRIBER", "<28"), ("policy", "POLICY", "<12"),
            ("transport", "TRANSPORT", "<9"), ("rate", "RATE(Hz)", ">9.1f"), ("dropped", "DROPPED", ">8"),
            ("name", "DEPLOYER", "")))
    return _rated_table(args, args.system.links, (
        ("name", "NAME", "<28"), ("source", "SOURCE", "<28"), ("sink", "SINK", "<28"), ("policy", "POLICY", "<12"),
        ("transport", "TRANSPORT", "<9"), ("state", "STATE", "<9"), ("rate", "RATE(Hz)", ">9.1f"),
        ("dropped", "DROPPED", ">8")))


def _rated_table(args: argparse.Namespace, listing: Callable[[], list[Any]],
                 columns: tuple[tuple[str, str, str], ...]) -> int:
    """Each item of ``listing()`` (links, subscriptions) with the rate its ``samples`` grow
    at over ``--sample`` s: JSON rows, or a table of ``columns`` (``(key, header, format)``)."""
    rows = [{**item.model_dump(), "name": item.name, "rate": rate}
            for item, rate in _with_rates(listing, lambda item: item.samples, args.sample)]
    if args.json:
        _out(_dump(rows))
        return 0
    _out(" ".join(f"{header:{spec.split('.')[0]}}" for _, header, spec in columns))
    for r in rows:
        _out(" ".join(f"{r[key]:{spec}}" for key, _, spec in columns))
    return 0


def cmd_reroute(args: argparse.Namespace) -> int:
    """``scart reroute LINK C.in``."""
    link = args.system.reroute(args.name, args.sink)
    _out(_dump(link.model_dump()) if args.json else f"{link.name}: {link.source} -> {link.sink} ({link.policy})")
    return 0


def cmd_disconnect(args: argparse.Namespace) -> int:
    """``scart disconnect A.out B.in`` or ``scart disconnect LINK``."""
    if args.sink is None:
        done = args.system.disconnect_link(args.source)
        doc = {"name": args.source, "disconnected": done}
    else:
        done = args.system.disconnect_ports(args.source, args.sink)
        doc = {"source": args.source, "sink": args.sink, "disconnected": done}
    _out(_dump(doc) if args.json else ("disconnected" if done else "were not connected"))
    return 0 if done else 1
