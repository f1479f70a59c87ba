"""``scart:connect``: a link between two data-flow ports, declared in the composite.

``<scart:connect from="a.out" to="b.in" policy="buffer:8"/>`` (a child of
``<composite>``; ``policy`` in ``ConnPolicy.parse`` short form, default ``data``;
``transport`` auto | ipc | shm | grpc for ends in two processes, default auto;
optional ``ns`` = name service; optional ``name``: the link's name for ``scart links``,
``reroute`` and ``disconnect``, default ``a.out->b.in``) connects an output port to an input port. Both ends in
this composite: connected in-process when the second task is added. One end not in this
composite: it is a task of another deployer, resolved through the name service (``ns``,
else the runtime's, see :class:`~scart.bindings.dataflow._host.DataflowHost`) at start or
whenever it appears; the connection is re-made when that deployer restarts (a new
registration). Cross-deployer connections need this runtime's tasks served (the
settings' ``serve``, as ``scart run`` does). Static errors (``file:line``): malformed
``comp.port``, a component of this composite that is not a task, an unknown port (the
message lists the ports), wrong direction, a bad policy, type mismatch (for a remote
end: with ``settings.online`` when its name service answers at load time, else checked
when connecting and logged), neither end in this composite. An end naming no task of this
composite is an error ("did you mean") unless it is declared ``<scart:external task="..."/>``
(:mod:`~scart.bindings.dataflow.external`) or ``ns`` says where to look; with
``settings.online`` one that no name service knows is an error. ``scart run`` says once
what a link waits for.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dataflow import ConnPolicy, DataflowError, Deployer, InputPort, PortTypeError
from scart.bindings.dataflow._checks import remote_end
from scart.bindings.dataflow._host import TASK_KIND, PortInfo, Watcher, class_ports, host_of
from scart.bindings.dataflow._plan import ZenohEnd, parse_policy, parse_zenoh
from scart.bindings.dataflow.settings import DataflowSettings, Remap
from scart.errors import Severity
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Participant, Problem

if TYPE_CHECKING:
    import zenoh

    from dataflow.introspection import LinkDescription
    from dataflow.remote.naming import NameClient
    from dataflow.transports.zenoh import ZenohInput
    from scart.bindings.dataflow._host import DataflowHost

__all__ = ["TASK_CONNECT", "TASK_CONNECT_TYPE", "ConnectElement", "ConnectParticipant", "Link", "bridge_ends",
           "connect_present", "links_of", "runtime_links"]

log = logging.getLogger("scart.dataflow")

#: Problem codes of this module.
TASK_CONNECT = "SCART-T002"  # scart:connect names no component/port, wrong direction, bad policy
TASK_CONNECT_TYPE = "SCART-T003"  # scart:connect between ports of different types

@dataclass(frozen=True)
class Link:
    """One ``scart:connect``: source and sink as (task name, port), policy, local flags."""

    source: tuple[str, str]
    sink: tuple[str, str]
    policy: ConnPolicy
    ns: str | None
    where: str
    name: str | None = None  # the link's name (``scart links``); default "a.out->b.in"
    zenoh: ZenohEnd | None = None  # the source is read from its Zenoh key

    @property
    def text(self) -> str:
        """``a.out -> b.in [policy]``."""
        return f"{'.'.join(self.source)} -> {'.'.join(self.sink)} [{self.policy}]"


def _split(ref: str) -> tuple[str, str] | None:
    comp, dot, port = ref.strip().rpartition(".")
    return (comp, port) if dot and comp and port else None


def _parse_link(prefix: str, el: Element) -> tuple[Link | None, list[str]]:
    """The link of an element and the problems found reading it (messages only)."""
    problems: list[str] = []
    ends = []
    for attr in ("from", "to"):
        raw = el.attributes.get(attr, "")
        parsed = _split(raw)
        if parsed is None:
            problems.append(f"<scart:connect> {attr}={raw!r}: expected COMPONENT.PORT")
        else:
            ends.append((prefix + parsed[0], parsed[1]))
    policy = parse_policy(el.attributes, problems, "<scart:connect>: ")
    zenoh = parse_zenoh(el.attributes, problems, "<scart:connect>: ", ends[0] if len(ends) == 2 else ("x",))
    if problems:
        return None, problems
    return Link(ends[0], ends[1], policy, el.attributes.get("ns"), str(el.loc), el.attributes.get("name") or None,
                zenoh), []


def links_of(elements: list[tuple[str, Element]], remap: Remap | None = None) -> list[Link]:
    """The well-formed links among ``elements``, their ends renamed by ``remap``."""
    links = [link for prefix, el in elements if (link := _parse_link(prefix, el)[0]) is not None]
    if not remap:
        return links
    return [dataclasses.replace(lk, source=remap.endpoint(*lk.source), sink=remap.endpoint(*lk.sink)) for lk in links]


class ConnectElement(ElementProvider):
    """The ``scart:connect`` composite element (see the module docstring)."""

    name = "connect"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        """Static problems of every connect element."""
        out: list[Problem] = []
        for prefix, el in elements:
            def add(code: str, msg: str, _el: Element = el, severity: Severity = "error") -> None:
                out.append(Problem(code, msg, _el.loc.path, _el.loc.line, severity))

            link, problems = _parse_link(prefix, el)
            for msg in problems:
                add(TASK_CONNECT, msg)
            if link is not None:
                self._check_link(link, assembly, context, add)
        return out

    def _check_link(self, link: Link, assembly: AssemblyView, context: CheckContext,
                    add: Callable[..., None]) -> None:
        ends: list[PortInfo | None] = []
        local = 0
        bridges = bridge_ends(assembly)
        if link.zenoh is not None and (link.source[0] in assembly.nodes or link.source[0] in bridges):
            add(TASK_CONNECT, f"<scart:connect zenoh=...> from: {link.source[0]!r} is in this composite; with zenoh "
                "the source is a task of another deployer, read from its Zenoh key (scart deploy --zenoh)")
            return
        if not {link.source[0], link.sink[0]} & (set(assembly.nodes) | set(bridges)) and link.zenoh is None:
            known = [p for p, n in assembly.nodes.items() if n.kind == TASK_KIND]
            add(TASK_CONNECT, f"<scart:connect>: neither {link.source[0]!r} nor {link.sink[0]!r} is a task of this "
                f"composite; tasks: {', '.join(known) or 'none'}")
            return
        for (comp, port), want, role in ((link.source, "out", "from"), (link.sink, "in", "to")):
            node = assembly.nodes.get(comp)
            if node is None and link.zenoh is not None:  # the Zenoh source: nothing to look at before start
                ends.append(None)
                continue
            if node is None and comp in bridges:  # a bridge of this composite: its ports are its inputs and output
                local += 1
                inputs, output = bridges[comp]
                ok = port == output if want == "out" else port in inputs
                if not ok:
                    add(TASK_CONNECT, f"<scart:connect> {role}: bridge {comp!r} has no {'output' if want == 'out' else 'input'}"
                        f" port {port!r}; its output: {output}, inputs: {', '.join(inputs) or 'none'}")
                ends.append(None)
                continue
            if node is None:
                # a task of another deployer runs under its remapped name
                remap = DataflowSettings.of(context.settings).remap
                ports = remote_end(comp, f"<scart:connect> {role}", link.ns, assembly, context,
                                   lambda msg, severity: add(TASK_CONNECT, msg, severity=severity))
                ends.append(_port_or_problem(ports, comp, remap.port(comp, port), want, role, add)
                            if ports is not None else None)
                continue
            local += 1
            if node.kind != TASK_KIND:
                add(TASK_CONNECT, f"<scart:connect> {role}: component {comp!r} is not an implementation.task")
                ends.append(None)
                continue
            ends.append(_port_or_problem(class_ports(node.ctype.cls), comp, port, want, role, add))
        if local == 0:
            known = [p for p, n in assembly.nodes.items() if n.kind == TASK_KIND]
            add(TASK_CONNECT, f"<scart:connect>: neither {link.source[0]!r} nor {link.sink[0]!r} is a task of this "
                f"composite; tasks: {', '.join(known) or 'none'}")
        src, dst = ends
        if src is not None and dst is not None and src.type_name != dst.type_name:
            add(TASK_CONNECT_TYPE, f"<scart:connect> {link.text}: type mismatch: {src.type_name} -> {dst.type_name}")

    def activate(self, host: Host) -> ConnectParticipant:
        """Makes the links at start (cross-deployer ones in the background)."""
        remap = DataflowSettings.of(host.settings).remap
        return ConnectParticipant(links_of(host.assembly.elements_of(self.name), remap), host)


def _port_or_problem(
    ports: dict[str, PortInfo], comp: str, port: str, want: str, role: str, add: Callable[[str, str], None]
) -> PortInfo | None:
    info = ports.get(port)
    if info is None:
        add(TASK_CONNECT, f"<scart:connect> {role}: task {comp!r} has no port {port!r}; ports: "
            f"{', '.join(f'{p.name} ({p.direction})' for p in ports.values()) or 'none'}")
        return None
    if info.direction != want:
        need = "an output" if want == "out" else "an input"
        add(TASK_CONNECT, f"<scart:connect> {role}: {comp}.{port} is not {need} port")
        return None
    return info


def bridge_ends(assembly: AssemblyView) -> dict[str, tuple[list[str], str]]:
    """The bridges of the composite (their written names): input names and output name."""
    out: dict[str, tuple[list[str], str]] = {}
    for prefix, el in assembly.elements_of("bridge"):
        inputs = [c.attributes.get("name", "") for c in el.children if c.kind == "input"]
        output = next((c.attributes.get("name", "") for c in el.children if c.kind == "output"), "")
        out[prefix + el.attributes.get("name", "")] = (inputs, output)
    return out


def connect_present(runtime: Host, task_name: str) -> None:
    """Make the in-process links of ``task_name`` whose other end is already deployed."""
    deployer = host_of(runtime).deployer
    names = set(deployer.names())
    for link in runtime_links(runtime):
        if task_name in (link.source[0], link.sink[0]) and link.source[0] in names and link.sink[0] in names:
            deployer.connect(".".join(link.source), ".".join(link.sink), link.policy, name=link.name)


def runtime_links(runtime: Host) -> list[Link]:
    """Every link declared in ``runtime``'s assembly."""
    return links_of(runtime.assembly.elements_of(ConnectElement.name), DataflowSettings.of(runtime.settings).remap)


class ConnectParticipant(Participant):
    """Runs the links of one runtime: in-process ones at start, remote ones by a connector
    thread that (re)connects whenever the remote end (re)appears in the name service."""

    def __init__(self, links: list[Link], runtime: Host, local: Callable[[str], bool] | None = None) -> None:
        self.runtime = runtime
        self.links = links
        remap = DataflowSettings.of(runtime.settings).remap
        tasks = {remap.component(n) for n in runtime.assembly.nodes} | {remap.component(b) for b in bridge_ends(runtime.assembly)}
        self._local = local or (lambda name: name in tasks)  # is this task (as it runs) in this runtime?
        self._remote = [lk for lk in links if not self._is_local(lk) and lk.zenoh is None]
        self._on_zenoh = [lk for lk in links if lk.zenoh is not None]
        self._sessions: dict[str, zenoh.Session] = {}  # Zenoh endpoint -> session
        self._inputs: list[ZenohInput] = []  # one for each link read from Zenoh
        self._made: dict[Link, str] = {}  # link -> boot id of the remote end it was made with
        self._watcher: Watcher | None = None
        self._clients: dict[str, NameClient] = {}
        self._waiting_logged: set[Link] = set()
        self._link_ns: dict[Link, str] = {}  # the name service each made link was made through
        from scart.bindings.dataflow.external import externals

        self._externals = {remap.component(name): ns for name, ns in externals(runtime.assembly).items()}

    def _is_local(self, link: Link) -> bool:
        return self._local(link.source[0]) and self._local(link.sink[0])

    def start(self) -> None:
        """Connect local links (idempotent); start the connector for remote ones."""
        deployer = host_of(self.runtime).deployer
        names = set(deployer.names())
        for link in self.links:  # an end not deployed yet (a bridge) connects when it is added
            if self._is_local(link) and link.source[0] in names and link.sink[0] in names:
                deployer.connect(".".join(link.source), ".".join(link.sink), link.policy, name=link.name)
        try:
            for link in self._on_zenoh:
                self._read_zenoh(link, deployer)
        except BaseException:
            self._close_zenoh()
            raise
        if self._remote:
            self._watcher = Watcher("scart-connect", self._step, interval=0.25)
            self._watcher.start()

    def _read_zenoh(self, link: Link, deployer: Deployer) -> None:
        """Feed the link's input port from the source's Zenoh key (samples come whenever the
        source publishes; Zenoh matches them when it appears)."""
        from dataflow.transports.zenoh import ZenohInput

        zenoh = link.zenoh
        assert zenoh is not None
        comp, port = link.sink
        target = deployer.task(comp).ports().get(port) if comp in deployer.names() else None
        if not isinstance(target, InputPort):  # InputPort is the one port with is_input
            raise DataflowError(f"connect {link.text} ({link.where}): {comp}.{port} is no input port of this runtime")
        try:
            session = self._sessions.get(zenoh.endpoint)
            if session is None:
                session = self._sessions[zenoh.endpoint] = zenoh.open(self.runtime.settings.security)
            feed = ZenohInput(session, *link.source, target, link.policy, zenoh.ns)
            self._inputs.append(feed)
            name = link.name or f"zenoh:{feed.key}->{target.qualname}"
            deployer.add_stream(name, _Described(feed, name))  # listed with the links, with its drops
        except DataflowError as exc:  # the session (it names the endpoint)
            raise DataflowError(f"connect {link.text} ({link.where}): {exc}") from exc
        except Exception as exc:  # noqa: BLE001 - Zenoh's own errors: say which link and endpoint
            raise DataflowError(f"connect {link.text} ({link.where}): Zenoh {zenoh.endpoint}: {exc}") from exc
        log.info("connect %s: reading %s.%s from Zenoh %s", link.text, *link.source, zenoh.endpoint)

    def _client(self, ns: str) -> NameClient:
        from dataflow.remote.naming import NameClient

        if ns not in self._clients:
            self._clients[ns] = NameClient(ns, timeout=self.runtime.settings.timeout,
                                            security=self.runtime.settings.security)
        return self._clients[ns]

    def _step(self) -> None:
        host = host_of(self.runtime)
        if host.server is None:
            return  # not served (yet): scart run serves right after start
        for link in self._remote:
            remote = link.sink[0] if self._local(link.source[0]) else link.source[0]
            ns = link.ns or self._externals.get(remote) or host.ns_address
            try:
                entry = self._client(ns).resolve(remote)
            except DataflowError:
                if link in self._made:
                    log.info("connect %s: %s is gone from the name service %s", link.text, remote, ns)
                    del self._made[link]
                elif link not in self._waiting_logged:  # once: a typo would be silent otherwise
                    self._waiting_logged.add(link)
                    log.warning("connect %s (%s): waiting for %s in name service %s (%s)", link.text, link.where,
                                remote, ns, "declared external: linked when it appears" if remote in self._externals
                                else "linked when it appears")
                continue
            self._waiting_logged.discard(link)
            if self._made.get(link) == entry.boot_id:
                continue
            try:
                self._connect(host, link, ns)
            except PortTypeError as exc:  # retrying cannot help until that deployer changes
                log.error("connect %s (%s): %s", link.text, link.where, exc)
            except DataflowError as exc:
                log.info("connect %s: not yet: %s", link.text, exc)
                continue
            self._made[link] = entry.boot_id
            self._link_ns[link] = ns

    def _disconnect(self, link: Link, ns: str) -> None:
        from dataflow.remote.client import GrpcSystem

        try:
            system = GrpcSystem(ns, timeout=self.runtime.settings.timeout, security=self.runtime.settings.security)
        except Exception as exc:  # noqa: BLE001 - stopping: log and go on
            log.info("connect %s: not disconnected at stop: %s", link.text, exc)
            return
        try:
            system.disconnect_ports(".".join(link.source), ".".join(link.sink))
            log.info("connect %s: disconnected at stop", link.text)
        except Exception as exc:  # noqa: BLE001 - the other end may be gone already
            log.info("connect %s: not disconnected at stop: %s", link.text, exc)
        finally:
            system.close()

    def _connect(self, host: DataflowHost, link: Link, ns: str) -> None:
        from dataflow.remote.client import GrpcSystem

        if host.server is None:
            raise DataflowError(f"connect {link.text}: this runtime's tasks are not served (use scart run)")
        system = GrpcSystem(ns, timeout=self.runtime.settings.timeout, security=self.runtime.settings.security)
        try:
            system.connect_ports(".".join(link.source), ".".join(link.sink), link.policy, name=link.name)
        finally:
            system.close()
        log.info("connect %s: connected across deployers", link.text)

    def stop(self) -> None:
        """Stop the connector, undo the remote links it made, close its clients (idempotent)."""
        if self._watcher is not None:
            self._watcher.stop()
        made, self._made = dict(self._made), {}
        for link in made:
            self._disconnect(link, self._link_ns.get(link) or link.ns or host_of(self.runtime).ns_address)
        for client in self._clients.values():
            client.close()
        self._clients.clear()
        self._close_zenoh()

    def _close_zenoh(self) -> None:
        """Stop reading from Zenoh, then close its sessions (idempotent)."""
        inputs, self._inputs = self._inputs, []
        deployer = host_of(self.runtime).deployer
        for name, stream in deployer.streams().items():
            if isinstance(stream, _Described):
                deployer.remove_stream(name)
        for inp in inputs:
            inp.close()
        sessions, self._sessions = dict(self._sessions), {}
        for session in sessions.values():
            session.close()


class _Described:
    """A Zenoh-fed input as the deployer lists it (its stream name kept)."""

    def __init__(self, feed: ZenohInput, name: str) -> None:
        self.feed, self.name = feed, name

    def describe(self) -> LinkDescription:
        return self.feed.describe(self.name)

    def close(self) -> None:
        """Undo it (``scart unstream``, the deployer's ``unstream``): the feed stops reading."""
        self.feed.close()
