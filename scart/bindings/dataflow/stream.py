"""The ``<scart:stream>`` composite element: a task's port joined to a named topic of a
transport (RTT's ``ConnPolicy.name_id``; ``scart stream`` on the command line)::

    <scart:stream port="youBotDriver.jointStatus" transport="zenoh" topic="robot/status"
                  policy="data" connect="tcp/127.0.0.1:7447"/>
    <scart:stream port="youBotDriver.jointStatus" transport="ros1" topic="/joint_states"
                  type="sensor_msgs/JointState"/>

An output port publishes on the topic; an input port is fed from it (each sample checked
as any from outside). Every attribute besides ``port``, ``transport``, ``topic``,
``policy`` and ``name`` is handed to the transport as an option (``type``, ``converter``,
``connect``...; ``msgs`` files are taken from the composite's folder). Checked at load
(the port, the transport, the topic, the policy, and with a converting transport such as
``ros1`` whether the port's type maps onto the topic's: ``SCART-T006``, naming both
types and the fields that do not fit; a ``converter="module:function"`` is imported then,
with the composite's paths, and its annotations checked); made when the composite starts,
undone when it stops; listed by ``scart links`` with its drops.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dataflow import ConnPolicy, DataflowError
from dataflow.transports import TransportError, load, names
from scart.bindings.dataflow._host import TASK_KIND, class_ports, host_of
from scart.bindings.dataflow._plan import parse_policy
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Participant, Problem

if TYPE_CHECKING:
    from dataflow.ports import Port

__all__ = ["StreamElement", "StreamParticipant"]

log = logging.getLogger("scart.dataflow")

STREAM_CODE = "SCART-T005"  #: a scart:stream that cannot be made (port, transport, topic, policy)
STREAM_TYPE_CODE = "SCART-T006"  #: a scart:stream whose port's type does not convert to its topic's (ROS)
_OWN = ("port", "transport", "topic", "policy", "name")
_FILE_OPTIONS = frozenset({"msgs"})  #: options naming files: relative to the composite's folder (ROS .msg/.srv)


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


def _files(value: str, el: Element) -> str:
    """Comma-separated file paths, each relative one taken from the composite's folder."""
    folder = Path(el.loc.path).parent
    return ",".join(str(folder / p.strip()) if p.strip() and not Path(p.strip()).is_absolute() else p.strip()
                    for p in value.split(","))


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
    options = tuple(sorted((k, _files(v, el) if k in _FILE_OPTIONS else v) for k, v in a.items()
                           if k not in _OWN and ":" not in k))
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
                out += self._check_stream(stream, el, assembly, context)
        return out

    @staticmethod
    def _check_stream(stream: Stream, el: Element, assembly: AssemblyView, context: CheckContext) -> list[Problem]:
        def problem(msg: str, code: str = STREAM_CODE, warning: bool = False) -> Problem:
            return Problem(code, msg, el.loc.path, el.loc.line, "warning" if warning else "error")

        node = assembly.nodes.get(stream.task)
        if node is None or node.kind != TASK_KIND:
            tasks = [p for p, n in assembly.nodes.items() if n.kind == TASK_KIND]
            return [problem(f"<scart:stream> port: {stream.task!r} is no task of this composite; tasks: "
                            f"{', '.join(tasks) or 'none'}")]
        template = _template(node.ctype.cls, stream.port)
        if template is None:
            ports = class_ports(node.ctype.cls)
            return [problem(f"<scart:stream> port: task {stream.task!r} has no port {stream.port!r}; ports: "
                            f"{', '.join(sorted(ports)) or 'none'}")]
        try:
            transport = load(stream.policy.transport)
        except TransportError as exc:
            return [problem(f"<scart:stream> {exc}")]
        options = dict(stream.options)
        converter = options.get("converter", "")
        if converter:  # imported here, with the contribution's paths: a stream itself never imports code
            try:
                context.import_object(converter)
            except Exception as exc:  # noqa: BLE001 - whatever importing raises is the composite's problem
                return [problem(f"<scart:stream> converter={converter!r} cannot be imported: "
                                f"{type(exc).__name__}: {exc}", STREAM_TYPE_CODE)]
        found = transport.check_stream(template, stream.policy.topic, options)
        return [problem(f"<scart:stream> {stream.task}.{stream.port}: {p.message}",
                        STREAM_TYPE_CODE if p.types else STREAM_CODE, p.warning) for p in found]

    def activate(self, host: Host) -> StreamParticipant:
        streams = [s for prefix, el in host.assembly.elements_of(self.name) if (s := _parse(prefix, el)[0])]
        return StreamParticipant(streams, host)


def _template(cls: type, port: str) -> Port[object] | None:
    """The port ``port`` a TaskContext class declares (its template), or None."""
    return next((p for p in getattr(cls, "_port_templates", {}).values() if p.name == port), None)


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
            options = dict(stream.options)
            try:
                if options.get("converter"):  # imported by the check already; the stream never imports
                    self.host.assembly.import_object(options["converter"])
                made = deployer.stream(f"{task}.{port}", stream.policy, options, stream.name)
            except (DataflowError, ValueError, ImportError, AttributeError) as exc:
                self.stop()
                raise DataflowError(f"stream {task}.{port} ({stream.where}): {exc}") from exc
            self._made.append(made.name)
            log.info("stream %s: %s -> %s", made.name, made.source, made.sink)

    def stop(self) -> None:
        deployer = host_of(self.host).deployer
        made, self._made = self._made, []
        for name in reversed(made):
            deployer.unstream(name)
