"""What the data-flow extension adds to ``scart run``, ``validate`` and ``graph`` (its
:class:`~scart.spi.LaunchProvider`, the ``dataflow`` entry point of ``scart.launch``):

==================  ===========================================================================
hook                what it does
==================  ===========================================================================
options             ``--remap FROM=TO`` (every verb); ``--ns HOST:PORT`` (``run``: where the
                    embedded name service listens, or the running one to join; ``validate``:
                    the one ``--online`` asks); ``--listen HOST:PORT`` (``run``: where the
                    data-flow server listens); ``--foxglove [HOST:]PORT`` and
                    ``--foxglove-control [TOKEN_FILE]``, ``--ros-master URI`` and
                    ``--ros-name NAME``, ``--yarp-server HOST:PORT`` (``run``)
settings            a :class:`~scart.bindings.dataflow.settings.DataflowSettings` (``--ns``,
                    else ``SCART_NS``; ``serve`` for ``run``)
names               a task runs under its remapped name
graph               ``scart:connect`` links and bridge inputs as bold edges between tasks (a
                    task of another deployer as an ellipse), ``binding.dataflow`` as dotted
                    edges to the task it names
launch              ``scart run``: the services endpoint registered with the name service
                    (found by name by ``scart services`` / ``scart call``), and the Foxglove
                    server of ``--foxglove``
==================  ===========================================================================

This module imports nothing heavy: the name service and Foxglove are imported when a run
starts them.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from dataflow.launch import ros as ros_args
from dataflow.launch import yarp as yarp_args
from scart.bindings.dataflow.settings import DataflowSettings, Remap
from scart.errors import ScartError
from scart.spi import (
    AssemblyView, Binding, Bound, GraphEdge, GraphNode, LaunchContext, Launched, LaunchProvider, Settings, Verb,
)
from scart_wire.defaults import DEFAULT_NS_ADDRESS, NS_ENV

if TYPE_CHECKING:
    from dataflow.foxglove.server import FoxgloveLive

__all__ = ["DataflowLaunch"]

TASK_KIND = "implementation.task"


class DataflowLaunch(LaunchProvider):
    """The data-flow extension's part in the composite verbs (see the module docstring)."""

    name = "dataflow"

    def add_arguments(self, parser: argparse.ArgumentParser, verb: Verb) -> None:
        """``--remap``; ``--ns`` for ``run`` and ``validate``; ``--foxglove*`` and ``--ros-*``
        for ``run``."""
        parser.add_argument("--remap", action="append", default=[], metavar="FROM=TO",
                            help="rename a data-flow task or port at launch (FROM:=TO too; TASK.PORT=NAME for one "
                                 "task's port; __ns=NAMESPACE puts every task under NAMESPACE/), or a ROS topic or "
                                 "service (/FROM:=/TO, as on a ROS command line); repeatable")
        if verb == "run":
            parser.add_argument("--ns", default=None, metavar="HOST:PORT",
                                help="name service of data-flow tasks and SCA services: where the embedded one "
                                     f"listens, or the running one to join (default: ${NS_ENV}, else "
                                     f"{DEFAULT_NS_ADDRESS})")
            parser.add_argument("--listen", default=None, metavar="HOST:PORT",
                                help="where the data-flow server listens (as scart deploy --listen; default: the "
                                     "name service's address when this run embeds it, else a free loopback port)")
            parser.add_argument("--foxglove", default=None, metavar="[HOST:]PORT",
                                help="also serve the data-flow tasks live to the Foxglove app here (as `scart "
                                     "foxglove`: ports, properties, operations; 0: a free port; a routable HOST needs "
                                     "--insecure); read-only unless --foxglove-control")
            parser.add_argument("--foxglove-control", nargs="?", const="", default=None, metavar="TOKEN_FILE",
                                help="make --foxglove writable (set properties, call operations), acting with the "
                                     "'operate' token in TOKEN_FILE (needed when the runtime checks tokens; never "
                                     "the runtime's own)")
            ros_args.add_arguments(parser)
            yarp_args.add_arguments(parser)
            ros_args.add_params(parser)
        elif verb == "validate":
            parser.add_argument("--ns", default=None, metavar="HOST:PORT",
                                help=f"name service for --online (default: ${NS_ENV}, else {DEFAULT_NS_ADDRESS})")

    def settings(self, args: argparse.Namespace, verb: Verb, environ: Mapping[str, str]) -> DataflowSettings:
        """``--ns`` (else ``SCART_NS``), ``--remap``, ``--foxglove*``; ``serve`` for ``run``.
        Raises ``ValueError`` naming the option or variable."""
        rules, topics = ros_args.split_remaps(getattr(args, "remap", None) or [])  # /topic:=/other: ROS's
        if verb == "run":  # the process's ROS node defaults; a bad URI, name, parameter or topic raises
            ros_args.apply(args, ros_args.split_params(getattr(args, "ros_params", None) or [])[1], topics)
            ros_args.exit_on_shutdown("scart")
            yarp_args.apply(args)  # the process's YARP name server; a bad address raises
        fields: dict[str, object] = {"remap": Remap.parse(rules), "serve": verb == "run",
                                     "foxglove": getattr(args, "foxglove", None),
                                     "foxglove_control": getattr(args, "foxglove_control", None)}
        listen = getattr(args, "listen", None)
        if listen:
            try:
                fields["listen"] = DataflowSettings(listen=listen).listen
            except ValueError as exc:
                raise ValueError(f"--listen {listen!r}: expected HOST:PORT (port 0..65535)") from exc
        ns = getattr(args, "ns", None)
        if ns:
            try:
                return DataflowSettings.from_env(environ, ns=ns, **fields)
            except ValueError as exc:
                raise ValueError(f"--ns {ns!r}: {str(exc).partition(': ')[2]}") from None
        return DataflowSettings.from_env(environ, **fields)

    def from_env(self, environ: Mapping[str, str]) -> DataflowSettings:
        """``ns`` from ``SCART_NS``."""
        return DataflowSettings.from_env(environ)

    def names(self, assembly: AssemblyView, settings: Settings) -> Mapping[str, str]:
        """Every task's path to the name it runs under (remapped)."""
        remap = DataflowSettings.of(settings).remap
        return {path: remap.component(path) for path, node in assembly.nodes.items() if node.kind == TASK_KIND}

    def graph(self, assembly: AssemblyView, settings: Settings) -> Sequence[GraphNode | GraphEdge]:
        """``binding.dataflow`` edges, then links and bridge inputs (see the module docstring)."""
        return _binding_edges(assembly) + _link_edges(assembly, DataflowSettings.of(settings).remap)

    def launch(self, context: LaunchContext) -> Launched:
        """The name-service entry of the services endpoint, and the Foxglove server."""
        return DataflowLaunched(context)


def _task_of(assembly: AssemblyView, path: str, binding: Binding) -> str | None:
    """The task component a ``binding.dataflow`` of component ``path`` names, when it is in
    this composite (a sibling in the same nested composite first, then a top-level one)."""
    if binding.kind != "binding.dataflow" or binding.attributes.get("ns"):
        return None
    name = binding.attributes.get("component", "")
    prefix = path.rpartition("/")[0]
    for candidate in (f"{prefix}/{name}" if prefix else name, name):
        node = assembly.nodes.get(candidate)
        if node is not None and node.kind == TASK_KIND:
            return candidate
    return None


def _binding_edges(assembly: AssemblyView) -> list[GraphNode | GraphEdge]:
    """A reference's ``binding.dataflow`` writes and reads the ports of a task; on a
    service, the task's samples drive its operations."""
    out: list[GraphNode | GraphEdge] = []
    for path, node in assembly.nodes.items():
        for ref, eps in node.references.items():
            for ep in eps:
                if not isinstance(ep, Bound):
                    continue
                task = _task_of(assembly, path, ep.binding)
                if task is not None:
                    out.append(GraphEdge(f"{path}.{ref}:{ep.binding.kind}", task, "ports", style="dotted"))
        for service, models in node.service_bindings.items():
            for model in models:
                task = _task_of(assembly, path, model)
                if task is not None:
                    out.append(GraphEdge(task, path, f"samples -> {service}", style="dotted"))
    return out


def _link_edges(assembly: AssemblyView, remap: Remap) -> list[GraphNode | GraphEdge]:
    """``scart:connect`` links and ``scart:bridge`` inputs as bold edges between tasks (a
    task of another deployer as an ellipse), labelled with the ports; names as they run."""
    out: list[GraphNode | GraphEdge] = []
    remote: set[str] = set()
    bridges = {prefix + el.attributes.get("name", "") for prefix, el in assembly.elements_of("bridge")}

    def end(prefix: str, ref: str) -> tuple[str, str] | None:
        comp, dot, port = ref.strip().rpartition(".")
        if not dot or not comp or not port:
            return None
        path = prefix + comp
        task, shown_port = remap.endpoint(path, port)
        if path in assembly.nodes:
            return path, shown_port
        if path in bridges:
            return "bridge:" + path, shown_port
        node_id = "task:" + task
        if node_id not in remote:
            remote.add(node_id)
            out.append(GraphNode(node_id, task, shape="ellipse"))
        return node_id, shown_port

    for prefix, el in assembly.elements_of("bridge"):
        name = prefix + el.attributes.get("name", "")
        bid = "bridge:" + name
        outputs = [c.attributes.get("name", "") for c in el.children if c.kind == "output"]
        out.append(GraphNode(bid, remap.component(name) + " (bridge)", shape="hexagon"))
        for child in el.children:
            source = end(prefix, child.attributes.get("from", "")) if child.kind == "input" else None
            if source is not None:
                label = f"{source[1]} -> {remap.port(name, child.attributes.get('name', ''))}"
                out.append(GraphEdge(source[0], bid, label, style="bold", color="blue"))
        for output in outputs:
            out.append(GraphNode(bid, xlabel=remap.port(name, output)))
    for prefix, el in assembly.elements_of("connect"):
        source, sink = end(prefix, el.attributes.get("from", "")), end(prefix, el.attributes.get("to", ""))
        if source is not None and sink is not None:
            policy = el.attributes.get("policy", "data")
            label = f"{source[1]} -> {sink[1]} [{policy}]"
            out.append(GraphEdge(source[0], sink[0], label, style="bold", color="blue"))
    return out


class DataflowLaunched(Launched):
    """What ``scart run`` serves for the data-flow extension beside the composite: the
    services endpoint in the name service (when served), the Foxglove server (with
    ``--foxglove``). :meth:`start` raises naming ``--foxglove`` when that server cannot
    start (the entry in the name service is then taken out again)."""

    def __init__(self, context: LaunchContext) -> None:
        from scart.bindings.dataflow._announce import Announcement

        self.context = context
        self.own = DataflowSettings.of(context.settings)
        address = context.services_address
        self.announcement = Announcement(context.served, context.settings, address) if address else None
        self.foxglove: FoxgloveLive | None = None

    def start(self) -> None:
        """Register the services endpoint (never raises), make the ROS node a process told
        it is one has, then serve Foxglove."""
        if self.announcement is not None:
            self.announcement.start()
        try:
            ros_args.hold()  # once the composite's own streams made theirs (they may name it)
        except Exception as exc:  # noqa: BLE001 - no node could be made: said, all stopped
            self.stop()
            raise ScartError(f"--ros-*: {exc}") from None
        spec = self.own.foxglove
        if spec is None:
            return
        try:
            self.foxglove = _serve_foxglove(self.context, spec, self.own.foxglove_control)
        except Exception as exc:  # noqa: BLE001 - bad address, port taken, no tasks: said, all stopped
            self.stop()
            raise ScartError(f"--foxglove {spec}: {exc}") from None

    def stop(self) -> None:
        """Stop Foxglove, take the services out of the name service. Idempotent."""
        foxglove, self.foxglove = self.foxglove, None
        if foxglove is not None:
            foxglove.stop()
        ros_args.unhold()
        if self.announcement is not None:
            self.announcement.stop()

    def addresses(self) -> dict[str, str]:
        """Where Foxglove is served."""
        live = self.foxglove
        if live is None:
            return {}
        return {"Foxglove": f"{live.url} ({live.channels} channel(s), {'writable' if live.writable else 'read-only'})"}

    def notes(self) -> list[str]:
        """What the name service said (embedded, or why the services are not in it)."""
        return [self.announcement.note] if self.announcement is not None and self.announcement.note else []

    def services_option(self) -> str | None:
        """``--ns HOST:PORT`` (or nothing, for the default) when the services are registered."""
        if self.announcement is None or not self.announcement.registered:
            return None
        return self.announcement.ns_option

    def service_name(self, name: str) -> str:
        """``NS/name`` under ``--remap __ns=NS``: how the name service finds it."""
        namespace = self.own.remap.namespace
        return f"{namespace}/{name}" if namespace else name


def _serve_foxglove(context: LaunchContext, spec: str, control: str | None = None) -> FoxgloveLive:
    """A started Foxglove server at ``[HOST:]PORT`` showing the tasks of the name service
    the runtime serves or joined: read-only (on this process's credentials), or with
    ``control`` (``--foxglove-control [TOKEN_FILE]``) writable, acting with that file's
    token (see :func:`dataflow.foxglove.server.control_token`). Raises when the composite
    serves no tasks, the control token is refused or the server cannot start."""
    host, _, port = spec.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    if not port.isdigit() or int(port) > 65535:
        raise ValueError("expected [HOST:]PORT with PORT in 0..65535")
    where = context.served.get("name service")
    if where is None:
        raise ScartError("this composite serves no data-flow tasks to show")
    from dataflow.foxglove.server import FoxgloveLive, control_token
    from dataflow.remote import connect

    security = context.settings.security
    writer = None
    if control is not None:
        token = control_token(control or None, security, "--foxglove-control", ns=where.split()[0])
        writer = connect(where.split()[0], security=dataclasses.replace(security, token=token))
    system = connect(where.split()[0], security=security)
    try:
        live = FoxgloveLive(system, host, int(port), insecure_host=security.insecure, owns_system=True,
                            control=writer, auth_file=security.auth_file)
    except BaseException:
        system.close()
        if writer is not None:
            writer.close()
        raise
    live.start()  # its stop (also when start raises) closes the clients
    return live
