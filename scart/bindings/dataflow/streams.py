"""The ``<scart:stream>`` composite element: a task's port joined to a named topic of a
transport (RTT's ``ConnPolicy.name_id``; ``scart stream`` on the command line)::

    <scart:stream port="youBotDriver.jointStatus" transport="zenoh" topic="robot/status"
                  policy="data" connect="tcp/127.0.0.1:7447"/>
    <scart:stream port="youBotDriver.jointStatus" transport="ros1" topic="/joint_states"
                  type="sensor_msgs/JointState"/>

An output port publishes on the topic; an input port is fed from it (each sample checked
as any from outside). Every attribute besides ``port``, ``transport``, ``topic``,
``policy`` and ``name`` is handed to the transport as an option (``type``, ``connect``...).
Checked at load (the port, the transport, the topic, the policy); made when the
composite starts, undone when it stops; listed by ``scart links`` with its drops.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from dataflow import ConnPolicy, DataflowError
from dataflow.transports import TransportError, load, names
from scart.bindings.dataflow._host import TASK_KIND, class_ports, host_of
from scart.bindings.dataflow._plan import parse_policy
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Participant, Problem

__all__ = ["StreamElement", "StreamParticipant"]

log = logging.getLogger("scart.dataflow")

STREAM_CODE = "SCART-T005"  #: a scart:stream that cannot be made (port, transport, topic, policy)
_OWN = ("port", "transport", "topic", "policy", "name")


@dataclass(frozen=True)
class Stream:
    """One ``<scart:stream>`` as read: ``task.port``, its policy (transport and topic
    in it), the transport's options, its name, and where it was written."""

    task: str
    port: str
    policy: ConnPolicy
    options: tuple[tuple[str, str], ...]
    name: str | None
    where: str


def _parse(prefix: str, el: Element) -> tuple[Stream | None, list[str]]:
    problems: list[str] = []
    a = el.attributes
    task, dot, port = (a.get("port") or "").rpartition(".")
    if not dot or not task or not port:
        problems.append(f"<scart:stream> port={a.get('port', '')!r}: expected COMPONENT.PORT")
    transport, topic = (a.get("transport") or "").strip(), (a.get("topic") or "").strip()
    if not transport or not topic:
        problems.append("<scart:stream> needs transport and topic (e.g. transport=\"zenoh\" topic=\"robot/status\")")
        return None, problems
    if transport not in names():
        problems.append(f"<scart:stream> transport={transport!r}: known transports: {', '.join(names())}")
        return None, problems
    policy = parse_policy({k: v for k, v in a.items() if k != "transport"}, problems, "<scart:stream>: ")
    try:
        policy = policy.with_(transport=transport, topic=topic)
    except ValueError as exc:
        problems.append(f"<scart:stream>: {exc}")
    options = tuple(sorted((k, v) for k, v in a.items() if k not in _OWN and ":" not in k))
    if problems:
        return None, problems
    return Stream(prefix + task, port, policy, options, a.get("name") or None, str(el.loc)), []


class StreamElement(ElementProvider):
    """The ``scart:stream`` composite element (see the module docstring)."""

    name = "stream"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        out: list[Problem] = []
        for prefix, el in elements:
            def add(msg: str, _el: Element = el) -> None:
                out.append(Problem(STREAM_CODE, msg, _el.loc.path, _el.loc.line))

            stream, problems = _parse(prefix, el)
            for msg in problems:
                add(msg)
            if stream is not None:
                self._check_stream(stream, assembly, add)
        return out

    @staticmethod
    def _check_stream(stream: Stream, assembly: AssemblyView, report: Callable[[str], None]) -> None:
        node = assembly.nodes.get(stream.task)
        if node is None or node.kind != TASK_KIND:
            tasks = [p for p, n in assembly.nodes.items() if n.kind == TASK_KIND]
            report(f"<scart:stream> port: {stream.task!r} is no task of this composite; tasks: "
                   f"{', '.join(tasks) or 'none'}")
            return
        ports = class_ports(node.ctype.cls)
        if stream.port not in ports:
            report(f"<scart:stream> port: task {stream.task!r} has no port {stream.port!r}; ports: "
                   f"{', '.join(sorted(ports)) or 'none'}")
        try:
            transport = load(stream.policy.transport)
        except TransportError as exc:
            report(f"<scart:stream> {exc}")
            return
        if not transport.topics:
            report(f"<scart:stream> transport {transport.name!r} carries links and subscriptions, not topics")

    def activate(self, host: Host) -> StreamParticipant:
        streams = [s for prefix, el in host.assembly.elements_of(self.name) if (s := _parse(prefix, el)[0])]
        return StreamParticipant(streams, host)


class StreamParticipant(Participant):
    """Makes the streams of one runtime at start, undoes them at stop."""

    def __init__(self, streams: list[Stream], host: Host) -> None:
        self.streams = streams
        self.host = host
        self._made: list[str] = []

    def start(self) -> None:
        deployer = host_of(self.host).deployer
        remap = DataflowSettings.of(self.host.settings).remap
        for stream in self.streams:
            task, port = remap.endpoint(stream.task, stream.port) if remap else (stream.task, stream.port)
            try:
                made = deployer.stream(f"{task}.{port}", stream.policy, dict(stream.options), stream.name)
            except (DataflowError, ValueError) as exc:
                self.stop()
                raise DataflowError(f"stream {task}.{port} ({stream.where}): {exc}") from exc
            self._made.append(made.name)
            log.info("stream %s: %s -> %s", made.name, made.source, made.sink)

    def stop(self) -> None:
        deployer = host_of(self.host).deployer
        made, self._made = self._made, []
        for name in reversed(made):
            deployer.unstream(name)
