"""The ``<scart:rosservice>`` composite element: a ROS 1 or ROS 2 service answered by a
task's operation or by an SCA service's operation (rtt_rosservice's ``connect``)::

    <scart:rosservice service="/youbot/reset" type="std_srvs/Trigger" operation="youBotDriver.reset"/>
    <scart:rosservice service="/youbot/period" type="my_msgs/SetPeriod"
                      target="SCAYouBotDriver/SettingPeriod.set_period" timeout="2"/>
    <scart:rosservice transport="ros2" service="/youbot/reset" type="std_srvs/srv/Trigger"
                      operation="youBotDriver.reset" domain="7"/>

``operation`` names ``TASK.OPERATION`` of a task of this composite, ``target``
``COMPONENT/SERVICE.operation`` of an SCA component (one of the two). Request fields
become the arguments by name, the result the response (see
:mod:`dataflow.transports.ros1.calls` for the rules, the ``std_srvs`` success/message
convention included); ``converter="module:function"`` (``function(request, call)``)
replaces them (ROS 1 only). ``msgs`` (``.srv``/``.msg`` files, from the composite's
folder) adds types; ``master``, ``node``, ``__ns``, ``insecure`` are the ROS 1 node's, as
for streams. ``transport="ros2"`` (default ``ros1``) serves it over DDS instead (the rules
of :mod:`dataflow.transports.ros2`, type names ``pkg/srv/Type``, ``msgs`` named
``.../pkg/srv/Type.srv`` or ``.../pkg/msg/Type.msg``), with the participant's options
``domain``, ``insecure``, ``interface``, ``peers``.
Checked at load (the operation, the types, request fields against parameters and the
return type against the response: ``SCART-T007``, file:line); served when the composite
starts (after every component's ``@init``), withdrawn when it stops.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dataflow import DataflowError
from dataflow.transports import TransportError
from dataflow.transports._rosplan import signature_of
from dataflow.transports.ros1.transport import NODE_OPTIONS
from scart.bindings.dataflow._elements import Served, Serving, check_each
from scart.bindings.dataflow._host import TASK_KIND, host_of
from scart.bindings.dataflow.settings import DataflowSettings
from scart_ros2.errors import Ros2Error
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Problem

__all__ = ["RosServiceElement", "RosServiceParticipant"]

log = logging.getLogger("scart.dataflow")

ROSSERVICE_CODE = "SCART-T007"  #: a scart:rosservice that cannot be made (what it names, its types)
_OWN = ("service", "type", "operation", "target", "converter", "timeout", "msgs", "transport")
TRANSPORTS = ("ros1", "ros2")


@dataclass(frozen=True)
class RosService:
    """One ``<scart:rosservice>`` as read."""

    service: str
    type: str
    transport: str  # ros1 or ros2
    operation: str  # TASK.OPERATION, or "" for an SCA target
    target: str  # COMPONENT/SERVICE.operation, or ""
    converter: str
    timeout: float
    options: tuple[tuple[str, str], ...]
    msgs: tuple[str, ...]
    where: str


def _parse(prefix: str, el: Element) -> tuple[RosService | None, list[str]]:
    a, problems = el.attributes, []
    transport = (a.get("transport") or "ros1").strip()
    if transport not in TRANSPORTS:
        problems.append(f"<scart:rosservice> transport={transport!r}: expected one of {', '.join(TRANSPORTS)}")
    network = _network_options(transport)
    if transport == "ros2" and a.get("converter"):
        problems.append("<scart:rosservice> converter: ROS 1 services only (a ROS 2 service maps by field names)")
    service, type_name = (a.get("service") or "").strip(), (a.get("type") or "").strip()
    operation, target = (a.get("operation") or "").strip(), (a.get("target") or "").strip()
    if not service or not type_name:
        problems.append("<scart:rosservice> needs service and type (e.g. service=\"/reset\" type=\"std_srvs/Trigger\")")
    if bool(operation) == bool(target):
        problems.append("<scart:rosservice> needs one of operation=\"TASK.OPERATION\" or "
                        "target=\"COMPONENT/SERVICE.operation\"")
    if operation and "." not in operation:
        problems.append(f"<scart:rosservice> operation={operation!r}: expected TASK.OPERATION")
    if target and ("/" not in target or "." not in target.rpartition("/")[2]):
        problems.append(f"<scart:rosservice> target={target!r}: expected COMPONENT/SERVICE.operation")
    try:
        timeout = float(a.get("timeout") or 5.0)
        if not 0 < timeout <= 3600:
            raise ValueError
    except ValueError:
        problems.append(f"<scart:rosservice> timeout={a.get('timeout')!r}: seconds, more than 0, at most 3600")
        timeout = 5.0
    unknown = sorted(k for k in a if k not in _OWN and k not in network and ":" not in k)
    if unknown:
        problems.append(f"<scart:rosservice>: unknown attribute(s) {', '.join(unknown)}")
    if problems:
        return None, problems
    folder = Path(el.loc.path).parent
    msgs = tuple(str(folder / p.strip()) for p in (a.get("msgs") or "").split(",") if p.strip())
    options = tuple(sorted((k, v) for k, v in a.items() if k in network))
    task_op = f"{prefix}{operation}" if operation else ""
    return RosService(service, type_name, transport, task_op, target, (a.get("converter") or "").strip(), timeout,
                      options, msgs, str(el.loc)), []


class RosServiceElement(ElementProvider):
    """The ``scart:rosservice`` composite element (see the module docstring)."""

    name = "rosservice"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        return check_each(elements, _parse, lambda rs: _check(rs, assembly, context), ROSSERVICE_CODE)

    def activate(self, host: Host) -> RosServiceParticipant:
        found = [s for prefix, el in host.assembly.elements_of(self.name) if (s := _parse(prefix, el)[0])]
        return RosServiceParticipant(found, host)


def _network_options(transport: str) -> frozenset[str] | tuple[str, ...]:
    """The options of the process's ROS 1 node or ROS 2 participant an element may set."""
    if transport == "ros2":
        from dataflow.transports.ros2 import NETWORK_OPTIONS  # no Cyclone DDS needed to read it

        return NETWORK_OPTIONS
    return NODE_OPTIONS


def _types_of(rs: RosService) -> Any:
    """The transport's message types, with the element's ``msgs`` added. Raises
    TransportError, ImportError (ros2 without ``scart[ros2]``), ValueError, OSError."""
    if rs.transport == "ros1":
        from dataflow.transports.ros1.calls import ros1_transport

        types = ros1_transport().types
        for path in rs.msgs:
            types.add_file(path)
        return types
    from dataflow.transports.ros2 import add_type_file, ros2_transport

    types = ros2_transport().types
    for path in rs.msgs:
        add_type_file(types, path, kinds=("srv", "msg"))
    return types


def _check(rs: RosService, assembly: AssemblyView, context: CheckContext) -> list[str]:
    try:
        types = _types_of(rs)
        if rs.converter:
            context.import_object(rs.converter)
    except (TransportError, Ros2Error, ValueError, OSError, ImportError, AttributeError) as exc:
        return [f"<scart:rosservice> {rs.service}: {exc}"]
    try:
        fn, what = _callable_of(rs, assembly)
    except LookupError as exc:
        return [f"<scart:rosservice> {exc}"]
    params, returns = signature_of(fn, skip_self=True)
    if rs.transport == "ros2":
        from dataflow.transports.ros2 import check_service as check_ros2

        problems = check_ros2(types, rs.type, params, returns)
    else:
        from dataflow.transports.ros1.calls import check_service

        problems = check_service(types, rs.type, params, returns, rs.converter)
    return [f"<scart:rosservice> {rs.service} ({rs.type}) by {what}: {p}" for p in problems]


def _callable_of(rs: RosService, assembly: AssemblyView) -> tuple[Callable[..., object], str]:
    """The function a service will call, as declared on its class (for the check)."""
    if rs.operation:
        task, _, op = rs.operation.rpartition(".")
        node = assembly.nodes.get(task)
        if node is None or node.kind != TASK_KIND:
            tasks = [p for p, n in assembly.nodes.items() if n.kind == TASK_KIND]
            raise LookupError(f"operation: {task!r} is no task of this composite; tasks: {', '.join(tasks) or 'none'}")
        attrs = getattr(node.ctype.cls, "_operation_attrs", {})
        if op not in attrs:
            raise LookupError(f"operation: task {task!r} has no operation {op!r}; operations: "
                              f"{', '.join(sorted(attrs)) or 'none'}")
        return getattr(node.ctype.cls, attrs[op]), f"operation {rs.operation}"
    component, _, rest = rs.target.partition("/")
    service, _, op = rest.rpartition(".")
    node = assembly.nodes.get(component)
    services = getattr(getattr(node, "ctype", None), "services", None) or {}
    if service not in services:
        raise LookupError(f"target: {component!r} has no service {service!r}; services: "
                          f"{', '.join(sorted(services)) or 'none'}")
    info = services[service]
    if op not in info.operations or info.python_type is None:
        raise LookupError(f"target: service {component}/{service} has no operation {op!r}; operations: "
                          f"{', '.join(sorted(info.operations)) or 'none'}")
    return getattr(info.python_type, op), f"{rs.target}"


class RosServiceParticipant(Serving[RosService]):
    """Serves the ROS services of one runtime at start, withdraws them at stop."""

    failures = (DataflowError, Ros2Error, ValueError, LookupError, ImportError, OSError)

    def what(self, rs: RosService) -> str:
        return f"ROS service {rs.service} ({rs.where})"

    def serve(self, rs: RosService) -> Served:
        made = self._serve(rs)
        log.info("ROS service %s (%s, %s) answered by %s", made.name, rs.type, rs.transport, made.label)
        return made

    def _serve(self, rs: RosService) -> Any:
        """Serve ``rs`` over its transport, answered by its operation or SCA target."""
        lib: Any  # the transport's serve and serve_operation
        if rs.transport == "ros2":
            from dataflow.transports import ros2 as lib

            how: dict[str, object] = dict(options=dict(rs.options))
        else:
            from dataflow.transports.ros1 import calls as lib

            how = dict(converter=rs.converter, options=dict(rs.options))
        if rs.msgs:
            _types_of(rs)
        if rs.converter:
            self.host.assembly.import_object(rs.converter)
        if rs.operation:
            task, _, op = rs.operation.rpartition(".")
            remap = DataflowSettings.of(self.host.settings).remap
            real = host_of(self.host).deployer.task(remap.component(task) if remap else task)
            return lib.serve_operation(real, op, rs.service, rs.type, timeout=rs.timeout, **how)
        component, _, rest = rs.target.partition("/")
        service, _, op = rest.rpartition(".")
        fn = self.host.endpoint(f"{component}/{service}").method(op)
        return lib.serve(fn, rs.service, rs.type, label=rs.target, **how)
