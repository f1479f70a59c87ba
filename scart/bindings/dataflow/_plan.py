"""How ``binding.dataflow`` maps interface operations to ports, and its static checks.

Private to :mod:`scart.bindings.dataflow.binding` (whose docstring documents the XML forms).
A *plan* maps each operation to ``(kind, port, type_name)``: ``kind`` is ``"write"``
(reference, one argument → input port), ``"read"`` (reference, no argument and a return
value → output port) or ``"deliver"`` (service, one argument ← output port).
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dataflow import ConnPolicy
from dataflow.policy import one_of, transport_names
from scart.bindings.dataflow._host import PortInfo, class_ports, remote_ports, type_name_of
from scart.bindings.dataflow.settings import DataflowSettings
from scart.spi import SCART_NS, Binding, CheckContext, InterfaceInfo, parse_host_port, parse_xml, port_in_range

if TYPE_CHECKING:
    import zenoh

    from scart_wire.security import Security

#: Problem codes.
DF_ATTRIBUTE = "SCART-D001"  # missing/invalid attribute or mapping
DF_PORT = "SCART-D002"  # operation maps to no port / wrong direction / wrong shape
DF_TYPE = "SCART-D003"  # interface type differs from the port type


@dataclass(frozen=True)
class Step:
    """One operation's mapping."""

    operation: str
    kind: str  # "write" | "read" | "deliver"
    port: str
    type_name: str | None  # the interface's type for it (None: not checkable)
    explicit: bool


@dataclass(frozen=True)
class Attributes:
    """The attributes of one binding element, parsed."""

    component: str
    ns: str | None
    policy: ConnPolicy
    period: float | None
    mapping: dict[str, str]
    problems: tuple[str, ...]
    #: Where the task is looked up instead of a name service (its Zenoh liveliness tokens).
    zenoh: ZenohEnd | None = None


@dataclass(frozen=True)
class ZenohEnd:
    """The ``zenoh``, ``zenoh-ns`` and ``zenoh-insecure`` attributes of an element: the
    endpoint a Zenoh client session connects to, the key namespace, and whether routable
    endpoints and deployers announced at routable addresses are allowed."""

    endpoint: str
    ns: str = "default"
    insecure: bool = False

    def open(self, security: Security | None = None) -> zenoh.Session:
        """A client session to the endpoint, presenting ``security``'s token if it has one;
        ``UnavailableError`` naming it when Zenoh cannot open one."""
        from dataflow.remote.errors import UnavailableError
        from dataflow.transports.zenoh import open_session

        try:
            return open_session(connect=[self.endpoint], mode="client", insecure=self.insecure, security=security)
        except Exception as exc:  # noqa: BLE001 - Zenoh's own error: not reachable (yet)
            raise UnavailableError(f"Zenoh {self.endpoint}: {exc}", "UNAVAILABLE", self.endpoint) from None


def parse_zenoh(attributes: Mapping[str, str], problems: list[str], what: str,
                key: tuple[str, ...] = ("x",)) -> ZenohEnd | None:
    """The element's :class:`ZenohEnd` (None without ``zenoh``); a bad endpoint, a
    namespace or ``key`` (component[, port]) that is no Zenoh key, or ``ns`` given as well
    is added to ``problems`` (prefixed with ``what``) and None returned."""
    endpoint = (attributes.get("zenoh") or "").strip()
    if not endpoint:
        return None
    from dataflow.transports.zenoh import check_endpoint, key_of  # no Zenoh import

    end = ZenohEnd(endpoint, (attributes.get("zenoh-ns") or "default").strip(),
                   (attributes.get("zenoh-insecure") or "").strip().lower() in ("true", "1"))
    found = len(problems)
    if (attributes.get("ns") or "").strip():
        problems.append(f"{what}give either ns (a scart name service) or zenoh (Zenoh), not both")
    try:
        check_endpoint(end.endpoint, end.insecure)
        key_of(end.ns, *key)
    except ValueError as exc:
        problems.append(f"{what}zenoh={end.endpoint!r} zenoh-ns={end.ns!r}: {exc}")
    return end if len(problems) == found else None


MIN_PERIOD_S = 0.001  # smallest polling period of a service binding


def parse_policy(attributes: dict[str, str], problems: list[str], what: str = "") -> ConnPolicy:
    """The ``policy`` (``ConnPolicy.parse`` short form, default ``data``) and ``transport``
    (auto | ipc | shm | grpc, default auto) attributes of an element as one policy; a bad
    value is added to ``problems`` (prefixed with ``what``) and the default used."""
    try:
        policy = ConnPolicy.parse(attributes.get("policy", "data"))
    except ValueError as exc:
        problems.append(f"{what}{exc}")
        policy = ConnPolicy.data()
    try:
        return policy.with_(transport=attributes.get("transport", "auto"))
    except ValueError as exc:
        del exc  # its wording is the Python API's
        problems.append(f"{what}transport={attributes.get('transport')!r}: expected {one_of(transport_names())}")
        return policy


def attributes(model: Binding) -> Attributes:
    """Parse attributes and ``<scart:map>`` children (problems as messages, never raises)."""
    a = model.attributes
    problems: list[str] = []
    component = (a.get("component") or "").strip()
    if not component:
        problems.append("binding.dataflow needs a 'component' attribute (the task name)")
    policy = parse_policy(a, problems)
    period = None
    if a.get("period") is not None:
        try:
            period = float(a["period"])
            if not period > 0:
                raise ValueError
        except ValueError:
            problems.append(f"period {a.get('period')!r}: expected seconds > 0")
            period = None
        else:
            if period < MIN_PERIOD_S:  # polling faster than this is a busy loop
                problems.append(f"period {a.get('period')!r}: at least {MIN_PERIOD_S} s")
                period = None
    mapping: dict[str, str] = {}
    for item in (a.get("ports") or "").split(","):
        if item.strip():
            op, eq, port = item.partition("=")
            if not eq or not op.strip() or not port.strip():
                problems.append(f"ports={a['ports']!r}: expected 'operation=port,...'")
                continue
            mapping[op.strip()] = port.strip()
    for child in model.children:
        if child.kind == "map":
            op, port = child.attributes.get("operation", ""), child.attributes.get("port", "")
            if op and port:
                mapping[op] = port
    ns = (a.get("ns") or "").strip() or None
    if ns is not None:
        parsed = parse_host_port(ns)
        if parsed is None or not port_in_range(parsed[1]):
            problems.append(f'ns {ns!r}: expected the name service as "host:port" (port 1..65535)')
            ns = None
    zenoh = parse_zenoh(a, problems, "")
    return Attributes(component, ns, policy, period, mapping, tuple(problems), zenoh)


def _signature(iface: InterfaceInfo, op: str) -> tuple[list[object], object] | None:
    """(parameter annotations, return annotation) of ``op``; None if not introspectable."""
    cls = iface.python_type
    fn = getattr(cls, op, None) if cls is not None else None
    if fn is None:
        return None
    try:
        hints = typing.get_type_hints(fn)
    except Exception:  # noqa: BLE001 - unresolvable forward refs: fall back to raw annotations
        hints = dict(getattr(fn, "__annotations__", {}))
    params = [p for p in inspect.signature(fn).parameters.values() if p.name != "self"]
    return [hints.get(p.name, p.annotation) for p in params], hints.get("return", inspect.Parameter.empty)


def plan(iface: InterfaceInfo, side: str, s: Attributes) -> tuple[list[Step], list[str]]:
    """The steps of an interface (reference or service side) and shape problems."""
    steps: list[Step] = []
    problems = [f"<scart:map operation={op!r}>: interface {iface.name} has no such operation"
                for op in s.mapping if op not in iface.operations]
    for name, op in iface.operations.items():
        sig = _signature(iface, name)
        nargs = len(sig[0]) if sig is not None else (0 if op.returns_value else 1)
        port = s.mapping.get(name, name)
        explicit = name in s.mapping
        if side == "reference":
            if nargs == 1:
                steps.append(Step(name, "write", port, type_name_of(sig[0][0]) if sig else None, explicit))
            elif nargs == 0 and op.returns_value:
                steps.append(Step(name, "read", port, type_name_of(sig[1]) if sig else None, explicit))
            else:
                problems.append(f"operation {name!r}: binding.dataflow needs one argument (written to an input "
                                "port) or none and a return value (the latest sample of an output port)")
        elif nargs == 1:
            steps.append(Step(name, "deliver", port, type_name_of(sig[0][0]) if sig else None, explicit))
        elif explicit:
            problems.append(f"operation {name!r}: a data-driven operation takes exactly one argument (the sample)")
    return steps, problems


def check_ports(steps: list[Step], ports: dict[str, PortInfo], component: str) -> tuple[list[Step], list[tuple[str, str]]]:
    """Steps usable against ``ports`` and (code, message) problems. A service step that was
    not mapped explicitly and names no port is dropped silently (not data-driven)."""
    good: list[Step] = []
    problems: list[tuple[str, str]] = []
    listing = ", ".join(f"{p.name} ({p.direction} {p.type_name})" for p in ports.values()) or "none"
    for st in steps:
        info = ports.get(st.port)
        want = "in" if st.kind == "write" else "out"
        if info is None or info.direction != want:
            if st.kind == "deliver" and not st.explicit:
                continue
            need = "input" if want == "in" else "output"
            what = f"has no {need} port" if info is None else f"port is an {info.direction}put, not an {need}:"
            problems.append((DF_PORT, f"operation {st.operation!r}: task {component!r} {what} {st.port!r}; "
                             f"ports: {listing}"))
            continue
        if st.type_name is not None and st.type_name != info.type_name:
            problems.append((DF_TYPE, f"operation {st.operation!r}: interface type {st.type_name} does not match "
                             f"port {component}.{st.port} of type {info.type_name}"))
            continue
        good.append(st)
    if steps and not good and not problems and all(s.kind == "deliver" for s in steps):
        problems.append((DF_PORT, f"no operation matches an output port of task {component!r}; ports: {listing}"))
    return good, problems


def local_task_class(context: CheckContext, component: str) -> type | None:
    """The class of an ``implementation.task`` component named ``component`` in the
    contribution's composites (root first); None if there is none."""
    folder, root_file = context.folder, context.root_file
    files = [Path(root_file)] + sorted(p for p in folder.glob("*.composite") if p.resolve() != Path(root_file).resolve())
    leaf = component.rpartition("/")[2]
    for file in files:
        root = parse_xml(str(file), [])
        if root is None:
            continue
        for el in root.iter():
            if not isinstance(el.tag, str) or not el.tag.endswith("}component") or el.get("name") != leaf:
                continue
            impl = el.find(f"{{{SCART_NS}}}implementation.task")
            if impl is not None:
                try:
                    return context.import_object(impl.get("class", ""))  # type: ignore[return-value]  # checked by its user
                except Exception:  # noqa: BLE001 - implementation.task reports it
                    return None
    return None


def static_ports(s: Attributes, context: CheckContext) -> tuple[dict[str, PortInfo] | None, str]:
    """Ports to check against at load time and where they came from ("" when unknown):
    the task class of this contribution, else (only with ``settings.online``) the task as
    the name service knows it."""
    if s.ns is None and s.zenoh is None:
        cls = local_task_class(context, s.component)
        if cls is not None:
            return class_ports(cls), "local"
    if not context.settings.online or s.zenoh is not None:  # a Zenoh lookup is made when the binding starts
        return None, ""
    ns = s.ns or DataflowSettings.of(context.settings).ns_address
    remap = DataflowSettings.of(context.settings).remap  # the task runs under its remapped name, its ports too
    ports = remote_ports(ns, remap.component(s.component), timeout=0.5, security=context.settings.security)
    if ports is not None and remap:
        back = {remap.port(s.component, name): name for name in ports}  # ports by the names the composite uses
        ports = {back.get(name, name): info for name, info in ports.items()}
    return ports, (f"name service {ns}" if ports is not None else "")
