"""The ``<scart:yarprpc>`` composite element: a component's operations answered on a YARP
RPC port, as ``yarp rpc /scart/COMP/rpc`` calls them (the command's first word names the
operation, the other items are its arguments; the reply is a bottle)::

    <scart:yarprpc component="youBotDriver"/>                    <!-- a task's operations -->
    <scart:yarprpc component="Locomotor" port="/robot/locomotor/rpc"/>   <!-- an SCA component's services -->

``component`` is a task of this composite (its ``@operation``\\ s) or an SCA component (the
operations of every service it offers; an operation two services share is asked for as
``Service.op``). ``port`` defaults to ``/scart/COMPONENT/rpc``; ``server`` (the name
server, ``HOST:PORT``) and ``insecure`` are the ``yarp`` transport's options; ``timeout``
(s) bounds a task's ``own_thread`` operation. Checked at load (the component and its
operations: ``SCART-T008``, file:line); served when the composite starts, withdrawn when it
stops. Arguments pass the same check as on every other entry point.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dataflow.transports import TransportError
from scart.bindings.dataflow._elements import Serving, check_each
from scart.bindings.dataflow._host import TASK_KIND, host_of
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Node, Problem

if TYPE_CHECKING:
    from dataflow.transports.yarp.rpc import RpcPort

__all__ = ["YarpRpcElement", "YarpRpcParticipant"]

log = logging.getLogger("scart.dataflow")

YARPRPC_CODE = "SCART-T008"  #: a scart:yarprpc that cannot be made (its component, port or options)
_OWN = ("component", "port", "timeout")
_NETWORK = ("server", "insecure")


@dataclass(frozen=True)
class YarpRpc:
    """One ``<scart:yarprpc>`` as read."""

    component: str
    port: str
    timeout: float
    options: tuple[tuple[str, str], ...]
    where: str


def _parse(prefix: str, el: Element) -> tuple[YarpRpc | None, list[str]]:
    from dataflow.transports.yarp.rpc import check_port_name, rpc_port_name

    a, problems = el.attributes, []
    component = (a.get("component") or "").strip()
    if not component:
        problems.append('<scart:yarprpc> needs component="TASK or COMPONENT"')
    port = (a.get("port") or "").strip() or rpc_port_name(prefix + component)
    try:
        check_port_name(port)
    except ValueError as exc:
        problems.append(f"<scart:yarprpc> port: {exc}")
    try:
        timeout = float(a.get("timeout") or 5.0)
        if not 0 < timeout <= 3600:
            raise ValueError
    except ValueError:
        problems.append(f"<scart:yarprpc> timeout={a.get('timeout')!r}: seconds, more than 0, at most 3600")
        timeout = 5.0
    unknown = sorted(k for k in a if k not in _OWN and k not in _NETWORK and ":" not in k)
    if unknown:
        problems.append(f"<scart:yarprpc>: unknown attribute(s) {', '.join(unknown)}; attributes: "
                        f"{', '.join(_OWN + _NETWORK)}")
    if problems:
        return None, problems
    options = tuple(sorted((k, v) for k, v in a.items() if k in _NETWORK))
    return YarpRpc(prefix + component, port, timeout, options, str(el.loc)), []


def _sca_operations(node: Node | None) -> dict[str, tuple[str, str]]:
    """``{word: (service, operation)}`` of an SCA component: ``op``, or ``Service.op`` for
    an operation two of its services share."""
    services = getattr(getattr(node, "ctype", None), "services", None) or {}
    found: dict[str, list[tuple[str, str]]] = {}
    for service, info in services.items():
        for op in info.operations:
            found.setdefault(op, []).append((service, op))
    words: dict[str, tuple[str, str]] = {}
    for op, where in found.items():
        for service, name in where:
            words[op if len(where) == 1 else f"{service}.{name}"] = (service, name)
    return words


class YarpRpcElement(ElementProvider):
    """The ``scart:yarprpc`` composite element (see the module docstring)."""

    name = "yarprpc"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        return check_each(elements, _parse, lambda rpc: _check(rpc, assembly), YARPRPC_CODE)

    def activate(self, host: Host) -> YarpRpcParticipant:
        found = [r for prefix, el in host.assembly.elements_of(self.name) if (r := _parse(prefix, el)[0])]
        return YarpRpcParticipant(found, host)


def _check(rpc: YarpRpc, assembly: AssemblyView) -> list[str]:
    from dataflow.transports import load

    try:
        load("yarp").settings(dict(rpc.options))  # type: ignore[attr-defined]  # the yarp transport's own
    except (ValueError, TransportError) as exc:
        return [f"<scart:yarprpc> {exc}"]
    node = assembly.nodes.get(rpc.component)
    if node is None:
        return [f"<scart:yarprpc> component: {rpc.component!r} is in no composite here; components: "
                f"{', '.join(sorted(assembly.nodes)) or 'none'}"]
    if node.kind == TASK_KIND:
        ops = getattr(node.ctype.cls, "_operation_attrs", {})
    else:
        ops = _sca_operations(node)
    if not ops:
        return [f"<scart:yarprpc> component {rpc.component!r} has no operation to answer"]
    return []


class YarpRpcParticipant(Serving[YarpRpc]):
    """Serves the YARP RPC ports of one runtime at start, withdraws them at stop."""

    def what(self, rpc: YarpRpc) -> str:
        return f"YARP RPC port {rpc.port} ({rpc.where})"

    def serve(self, rpc: YarpRpc) -> RpcPort:
        from dataflow.transports.yarp.rpc import serve_calls, serve_task

        node = self.host.assembly.nodes.get(rpc.component)
        if node is not None and node.kind == TASK_KIND:
            remap = DataflowSettings.of(self.host.settings).remap
            task = host_of(self.host).deployer.task(remap.component(rpc.component) if remap else rpc.component)
            return serve_task(task, rpc.port, dict(rpc.options), rpc.timeout)
        calls = {word: self.host.endpoint(f"{rpc.component}/{service}").method(op)
                 for word, (service, op) in _sca_operations(node).items()}
        return serve_calls(calls, rpc.port, rpc.component, dict(rpc.options))
