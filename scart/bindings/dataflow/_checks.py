"""What ``scart run`` would refuse at start, checked before anything starts (so that
``scart validate`` says it, at the same ``file:line``, with the same message):

* a task property's value against its declaration — type, bounds (``ge``/``le``...),
  finiteness and its ``check`` (a read-only property refuses any value) —
  :func:`property_problems`;
* the names tasks, bridges and their ports run under after ``--remap``: no task name
  with a ``.`` (it would read as ``TASK.PORT``), no two tasks under one name, no port
  renamed onto a name its task already has — :func:`remap_problems`;
* a data-flow end (``scart:connect``, a bridge input) that names no task of the
  composite: an error ("did you mean") unless the task is declared external
  (``<scart:external>``) or the element names its ``ns``; those are looked up in the
  name service when the composite runs, and with ``settings.online`` an error when no
  name service knows them — :func:`remote_end`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

from dataflow import DataflowError
from scart.errors import ASM_PROPERTY_VALUE, Severity
from scart.bindings.dataflow._host import TASK_KIND, PortInfo, class_ports
from scart.bindings.dataflow.settings import DataflowSettings, Remap
from scart.spi import DEFAULT, AssemblyView, CheckContext, Node, Problem, did_you_mean

__all__ = ["TASK_REMAP", "property_problems", "remap_problems", "remote_end"]

TASK_REMAP = "SCART-T004"  # --remap gives a task a dotted name, two tasks one name, or two ports of a task one name
#: How long a load-time look-up in the name service may take (``settings.online`` only).
LOOKUP_TIMEOUT_S = 0.5

#: ``add(message, severity)``: report a problem where the element being checked stands.
Add = Callable[[str, Severity], None]


def property_problems(nodes: list[Node]) -> list[Problem]:
    """Each task property value the task would refuse on ``set_property`` (ASM50027, where
    the value was given)."""
    problems: list[Problem] = []
    for node in nodes:
        declared = getattr(node.ctype.cls, "_property_decls", {})
        for name, value in node.properties.items():
            if value is DEFAULT or name not in declared:
                continue
            try:
                declared[name].validate(value, node.path)
            except DataflowError as exc:  # PropertyValueError, PortTypeError: said without "task.prop: "
                why = str(exc).removeprefix(f"{node.path}.{name}: ")
                loc = node.property_locations.get(name, node.model.loc)
                problems.append(Problem(ASM_PROPERTY_VALUE, f"component {node.path!r} property {name!r}: {why}",
                                        loc.path, loc.line))
    return problems


def _named(nodes: list[Node], assembly: AssemblyView) -> Iterator[tuple[str, str, list[str], str, int]]:
    """``(kind, written name, port names, path, line)`` of each task, then each bridge."""
    for node in nodes:
        yield "task", node.path, list(class_ports(node.ctype.cls)), node.model.loc.path, node.model.loc.line
    for prefix, el in assembly.elements_of("bridge"):
        ports = [c.attributes.get("name", "") for c in el.children if c.kind in ("input", "output")]
        yield "bridge", prefix + el.attributes.get("name", ""), ports, el.loc.path, el.loc.line


def remap_problems(nodes: list[Node], assembly: AssemblyView, remap: Remap) -> list[Problem]:
    """The names ``--remap`` gives tasks, bridges and ports that they could not run under
    (see the module docstring); none without rules."""
    if not remap:
        return []
    problems: list[Problem] = []
    runs_as: dict[str, str] = {}
    for kind, written, ports, path, line in _named(nodes, assembly):
        name = remap.component(written)
        if "." in name:
            problems.append(Problem(TASK_REMAP, f"--remap: {kind} {written!r} would run as {name!r}: a task name "
                                    "has no '.' (TASK.PORT would not say which is which)", path, line))
        elif name in runs_as and runs_as[name] != written:
            problems.append(Problem(TASK_REMAP, f"--remap: {runs_as[name]!r} and {kind} {written!r} would both "
                                    f"run as {name!r}", path, line))
        runs_as.setdefault(name, written)
        why = _port_clash(written, ports, remap)
        if why:
            problems.append(Problem(TASK_REMAP, f"--remap: {kind} {written!r}: {why}", path, line))
    return problems


def _port_clash(task: str, ports: list[str], remap: Remap) -> str:
    """Why renaming ``ports`` one by one, as a task does at start, fails ("" when it does not)."""
    taken = set(ports)
    for old in ports:
        new = remap.port(task, old)
        if new == old:
            continue
        if not new or new in taken:
            return f"port {old!r} would be renamed {new!r}, the name of another of its ports"
        taken.discard(old)
        taken.add(new)
    return ""


def local_names(assembly: AssemblyView) -> list[str]:
    """The tasks and bridges of the composite, by their written names."""
    tasks = [path for path, node in assembly.nodes.items() if node.kind == TASK_KIND]
    return tasks + [prefix + el.attributes.get("name", "") for prefix, el in assembly.elements_of("bridge")]


def remote_end(comp: str, what: str, ns: str | None, assembly: AssemblyView, context: CheckContext,
               add: Add) -> dict[str, PortInfo] | None:
    """The ports of ``comp``, a data-flow end that is no task of the composite (``what``
    names the end in messages; ``ns`` the name service the element names, if any), when
    ``settings.online`` lets a name service say; else None. An end that is neither
    declared external (:mod:`~scart.bindings.dataflow.external`) nor given an ``ns`` is an
    error ("did you mean"): a typo would wait forever; online, one no name service knows
    (or whose name service does not answer) is an error."""
    from scart.bindings.dataflow.external import externals

    near = did_you_mean(comp, local_names(assembly))
    declared = externals(assembly)
    settings = context.settings
    if ns is None and comp not in declared:
        add(f"{what}: {comp!r} is no task of this composite{near}; a task another process serves is declared "
            f"<scart:external task=\"{comp}\"/>", "error")
        return None
    if not settings.online:
        return None
    address = ns or declared.get(comp) or DataflowSettings.of(settings).ns_address
    runs_as = DataflowSettings.of(settings).remap.component(comp)
    names, ports = _lookup(address, runs_as, settings)
    if names is None:
        add(f"{what}: {comp!r} is no task of this composite, and the name service at {address} does not answer "
            "(--online)", "error")
    elif ports is None:
        add(f"{what}: no task {runs_as!r} in this composite nor in the name service at {address}"
            f"{near or did_you_mean(runs_as, names)}; it knows: {', '.join(sorted(names)[:20]) or 'none'}", "error")
    return ports


def _lookup(address: str, component: str, settings: object) -> tuple[list[str] | None, dict[str, PortInfo] | None]:
    """``(names the name service knows, ports of component)``; ``(None, None)`` when it does
    not answer, ports None when it does not know the component. Never raises."""
    from dataflow.remote import Security, connect

    security = getattr(settings, "security", None) or Security()
    try:
        system = connect(address, timeout=LOOKUP_TIMEOUT_S, security=security)
    except DataflowError:
        return None, None
    try:
        names = system.component_names()
        if component not in names:
            return names, None
        ports = system.component(component).describe().ports
        return names, {p.name: PortInfo(p.name, p.direction, p.type_name) for p in ports}
    except DataflowError:
        return None, None
    finally:
        system.close()
